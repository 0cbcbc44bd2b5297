"""The one working form every engine's files are made from: the probe (scaled), its SH, its lights, its GGX chains.

Each quantity is computed once per bake and shared, whatever the number of engines: the radiance SH (world frame,
bands 0–2), the decomposition into area lights (when asked), the GGX-prefiltered cube chains, cached by what
determines them (face size, the α of each level, the frame), and the SH's accuracy against brute-force irradiance,
cached by the map it describes (the probe or the ambient remainder): engines whose SH differs only in frame or scale
write the same nine world-frame coefficients converted at the edge, so one measure holds for all of them. Engines
convert these at the edge — frame, face order, encoding, units — and never filter anew.
"""

from __future__ import annotations

import hashlib
import time
from dataclasses import dataclass, field

import numpy as np

from ..glossy.prefilter import PrefilteredCube, prefilter_cube
from ..lights.lightsfile import LightSet
from ..maps import EnvMap
from ..maps.frames import WORLD, Frame
from ..sh.basis import SHCoeffs, project
from .accuracy import sh_accuracy
from .options import BakeOptions


@dataclass
class BakeSource:
    """The probe as every engine of a bake reads it.

    Attributes
    ----------
    env : EnvMap
        Linear RGB radiance, world frame, already multiplied by ``options.intensity``.
    name : str
        The probe as the manifest names it (its path, or "(shipped probe)").
    sha256 : str
        SHA-256 (hex) of the probe file's bytes, or of the map's float32 pixels when it came from memory.
    options : BakeOptions
        The bake's options.
    timings : dict of str to float
        Seconds spent on each shared quantity, for the manifest.
    """

    env: EnvMap
    name: str
    sha256: str
    options: BakeOptions
    timings: dict[str, float] = field(default_factory=dict)
    _sh: SHCoeffs | None = None
    _lights: tuple | None = None
    _chains: dict = field(default_factory=dict)
    _sh_accuracy: dict = field(default_factory=dict)

    @classmethod
    def from_map(cls, env: EnvMap, options: BakeOptions, name: str = "(in memory)",
                 sha256: str | None = None) -> "BakeSource":
        """The working form of ``env``, scaled by ``options.intensity``.

        Parameters
        ----------
        env : EnvMap
            Linear RGB radiance, world frame, any layout.
        options : BakeOptions
            The bake's options.
        name : str, default "(in memory)"
            How the manifest names the probe.
        sha256 : str, optional
            The probe file's SHA-256; default: that of the map's float32 pixels and layout.

        Returns
        -------
        BakeSource
            The probe, scaled, with nothing computed yet.
        """
        if sha256 is None:
            h = hashlib.sha256(env.layout.name.encode())
            h.update(np.ascontiguousarray(env.data, np.float32).tobytes())
            sha256 = h.hexdigest()
        scaled = env if options.intensity == 1.0 else EnvMap((env.data * np.float32(options.intensity)), env.layout)
        return cls(scaled, name, sha256, options)

    def sh(self) -> SHCoeffs:
        """Radiance SH of the probe, bands 0–2, world frame (computed once).

        Returns
        -------
        SHCoeffs
            (9, 3) radiance coefficients L_lm, real orthonormal basis without the Condon–Shortley phase.
        """
        if self._sh is None:
            t0 = time.perf_counter()
            self._sh = project(self.env, 2)
            self.timings["sh"] = time.perf_counter() - t0
        return self._sh

    def decomposition(self):
        """The probe as area lights plus the ambient map (Arbree, Walter & Bala 2005), found once.

        Returns
        -------
        lightprobe.lights.decompose.Decomposition
            The lights (world frame) and the ambient map: the probe with the lights' pixels taken out.
        """
        self._find_lights()
        return self._lights[0]

    def lights(self) -> LightSet:
        """The probe's area lights and the ambient remainder's radiance SH (bands 0–2), found once.

        Returns
        -------
        LightSet
            World-frame unit directions, angular radii (radians), RGB powers ∫L dω, the ambient's SH.
        """
        self._find_lights()
        return self._lights[1]

    def _find_lights(self) -> None:
        if self._lights is None:
            from ..lights.decompose import decompose
            from ..lights.lightsfile import lights_json, read_lights_json

            t0 = time.perf_counter()
            dec = decompose(self.env)
            # through the versioned schema, so a bake's lights are exactly what 'lightprobe lights' would write
            self._lights = (dec, read_lights_json(lights_json(dec, project(dec.ambient, 2), self.name)))
            self.timings["lights"] = time.perf_counter() - t0

    def diffuse(self) -> tuple[EnvMap, SHCoeffs]:
        """What an engine's diffuse term and specular chain hold: the ambient remainder when the bake finds lights
        (the lights being the engine's own lights, nothing is counted twice), else the probe.

        Returns
        -------
        EnvMap
            Linear RGB radiance, world frame: :meth:`decomposition`'s ambient map, or :attr:`env`.
        SHCoeffs
            Its radiance SH, bands 0–2, world frame: the lights file's ambient SH, or :meth:`sh`.
        """
        if self.options.lights:
            from ..exports.lights import ambient_sh

            return self.decomposition().ambient, ambient_sh(self.lights(), [])
        return self.env, self.sh()

    def sh_accuracy(self, whole_probe: bool = False) -> dict:
        """The SH's irradiance against brute force over the map it describes (computed once per map).

        Parameters
        ----------
        whole_probe : bool, default False
            Measure the probe's own SH over the probe, even when the bake finds lights (engines whose diffuse term is
            always the whole probe's); default: the map of :meth:`diffuse`.

        Returns
        -------
        dict
            :func:`lightprobe.bake.accuracy.sh_accuracy` of the map and its world-frame radiance SH.
        """
        env, sh = (self.env, self.sh()) if whole_probe else self.diffuse()
        if id(env) not in self._sh_accuracy:
            t0 = time.perf_counter()
            self._sh_accuracy[id(env)] = sh_accuracy(env, sh)
            self.timings["sh accuracy" + (" (ambient)" if env is not self.env else "")] = time.perf_counter() - t0
        return self._sh_accuracy[id(env)]

    def chain(self, size: int, alphas: tuple[float, ...], frame: Frame = WORLD,
              env: EnvMap | None = None) -> PrefilteredCube:
        """The GGX chain of a ``size`` cube with roughness ``alphas[i]`` on level i, in ``frame`` (computed once).

        Parameters
        ----------
        size : int
            Face edge of level 0 (a power of two).
        alphas : tuple of float
            α = roughness² of each level, log₂(size) + 1 of them (0 for the mirror).
        frame : Frame, default WORLD
            The frame of the cube's texel directions.
        env : EnvMap, optional
            The map to prefilter: the probe (default) or the ambient remainder of :meth:`decomposition`.

        Returns
        -------
        PrefilteredCube
            ``levels[i]``: (6, size >> i, size >> i, 3) float32 radiance, OpenGL face orientation.
        """
        env = self.env if env is None else env
        key = (id(env), size, tuple(float(a) for a in alphas), frame.name, frame.to_frame.tobytes())
        if key not in self._chains:
            t0 = time.perf_counter()
            self._chains[key] = prefilter_cube(env, size, list(alphas), frame, samples=self.options.samples)
            self.timings[f"prefilter {size} ({frame.name})"] = time.perf_counter() - t0
        return self._chains[key]

    def describe(self) -> dict:
        """The probe as the manifest records it.

        Returns
        -------
        dict
            ``name``, ``sha256``, ``layout``, ``grid`` (the map's array shape without channels) and ``integral``
            (∫L dω per channel after the intensity).
        """
        return {"name": self.name, "sha256": self.sha256, "layout": self.env.layout.name,
                "grid": list(self.env.grid), "integral": [float(v) for v in self.env.integral()]}
