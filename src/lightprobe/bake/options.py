"""What a bake is asked for: the engines and the sizes, counts, encodings and scale every engine's files share.

Quantities: ``intensity`` multiplies the probe's radiance before anything is baked (every file of every engine
carries the scaled values; the manifest records the factor). Sizes are texels: ``size`` the edge of the specular
cube's level 0, ``skybox_size`` the edge of a skybox cube face (a panorama skybox is ``2 × skybox_size`` wide and
``skybox_size`` high), ``irradiance_size`` the edge of an irradiance cube face where an engine takes one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from ..glossy.prefilter import DEFAULT_SAMPLES, MAX_SIZE
from ..util.errors import UsageError
from ..util.names import BAKE_ENGINES

MIN_SIZE = 16  # the smallest specular cube a bake writes: below it the roughest mips are a texel or two
MAX_SKYBOX = 4096  # skybox face edge (a 8192×4096 panorama): past it no engine here loads the texture
MAX_INTENSITY = 1e6  # a scale past this is a unit mistake, not an exposure


@dataclass(frozen=True)
class BakeOptions:
    """The parameters of one bake, shared by every engine (each engine maps them onto its own files).

    Attributes
    ----------
    engines : tuple of str
        Engine names from :data:`lightprobe.util.names.BAKE_ENGINES`, in that order, no repeats.
    size : int
        Edge of the specular cube's level 0, texels: a power of two from MIN_SIZE (16) to MAX_SIZE (1024).
    mips : int or None
        Specular mip levels written; None: the full chain down to 1 texel (log₂ size + 1). Engines whose loader
        needs the full chain (Babylon's ``.env``, glTF's ``specularImages``) refuse fewer.
    skybox_size : int
        Edge of the skybox's cube faces (a panorama skybox: its height), a power of two up to MAX_SKYBOX.
    irradiance_size : int
        Edge of an irradiance cube's faces, for engines that take one (Unity, custom renderers).
    intensity : float
        Factor applied to the radiance before baking (> 0, finite).
    lights : bool
        Also find the map's area lights (Arbree, Walter & Bala 2005) and write them as the engine's directional
        lights, with the ambient remainder's SH as the diffuse term.
    samples : int
        GGX samples per texel on the prefiltered levels that are sampled (:func:`lightprobe.glossy.prefilter
        .prefilter_cube`).
    encodings : dict of str to str
        An engine's encoding where it offers a choice (``{"threejs": "rgb9e5"}``); absent engines take their
        default.
    """

    engines: tuple[str, ...]
    size: int = 256
    mips: int | None = None
    skybox_size: int = 1024
    irradiance_size: int = 32
    intensity: float = 1.0
    lights: bool = False
    samples: int = DEFAULT_SAMPLES
    encodings: dict[str, str] = field(default_factory=dict)

    def __post_init__(self):
        check_options(self)

    @property
    def levels(self) -> int:
        """The number of specular mip levels written: ``mips``, or the full chain (log₂ size + 1)."""
        return self.full_chain if self.mips is None else self.mips

    @property
    def full_chain(self) -> int:
        """log₂(size) + 1: the levels from ``size`` down to one texel."""
        return int(math.log2(self.size)) + 1

    def as_dict(self) -> dict:
        """The options as a manifest records them (plain JSON values).

        Returns
        -------
        dict
            Every attribute; ``engines`` as a list, ``mips`` as the number of levels written.
        """
        return {"engines": list(self.engines), "size": self.size, "mips": self.levels,
                "skybox_size": self.skybox_size, "irradiance_size": self.irradiance_size,
                "intensity": self.intensity, "lights": self.lights, "samples": self.samples,
                "encodings": dict(sorted(self.encodings.items()))}


def parse_engines(text: str) -> tuple[str, ...]:
    """Engine names from ``--for``'s comma-separated list (``all`` for every engine), in the canonical order.

    Parameters
    ----------
    text : str
        ``"threejs,babylon"``, ``"all"``, …; spaces around names are ignored.

    Returns
    -------
    tuple of str
        The distinct names, in the order of :data:`~lightprobe.util.names.BAKE_ENGINES`.

    Raises
    ------
    UsageError
        An unknown name, or none at all.
    """
    names = [n.strip().lower() for n in str(text).split(",") if n.strip()]
    if names == ["all"]:
        return BAKE_ENGINES
    unknown = [n for n in names if n not in BAKE_ENGINES]
    if unknown or not names:
        raise UsageError(f"unknown engine {unknown[0] if unknown else repr(text)} for --for: choose from "
                         f"{', '.join(BAKE_ENGINES)}, or all")
    return tuple(n for n in BAKE_ENGINES if n in names)


def _power_of_two(value, name: str, low: int, high: int) -> None:
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high or value & (value - 1):
        raise UsageError(f"{name} must be a power of two from {low} to {high}, got {value!r}")


def check_options(options: BakeOptions) -> None:
    """Refuse options no engine can bake, in one line.

    Parameters
    ----------
    options : BakeOptions
        The options to check.

    Raises
    ------
    UsageError
        No engine or an unknown one; a size that is not a power of two in range; a mip count outside
        1..log₂(size)+1; an intensity that is not finite and positive; an encoding for an engine not baked, or one
        the engine does not offer; fewer than 1 sample.
    """
    if not options.engines:
        raise UsageError("give at least one engine to bake for (--for)")
    unknown = [e for e in options.engines if e not in BAKE_ENGINES]
    if unknown or len(set(options.engines)) != len(options.engines):
        raise UsageError(f"engines must be distinct names from {', '.join(BAKE_ENGINES)}, got "
                         f"{', '.join(options.engines)}")
    _power_of_two(options.size, "the specular size", MIN_SIZE, MAX_SIZE)
    _power_of_two(options.skybox_size, "the skybox size", 1, MAX_SKYBOX)
    _power_of_two(options.irradiance_size, "the irradiance size", 1, 256)
    if options.mips is not None and (isinstance(options.mips, bool) or not isinstance(options.mips, int)
                                     or not 1 <= options.mips <= options.full_chain):
        raise UsageError(f"a {options.size} cube has 1 to {options.full_chain} mip levels, got {options.mips!r}")
    if not (isinstance(options.intensity, (int, float)) and math.isfinite(options.intensity)
            and 0 < options.intensity <= MAX_INTENSITY):
        raise UsageError(f"the intensity must be a positive number up to {MAX_INTENSITY:g}, got {options.intensity!r}")
    if not isinstance(options.samples, int) or not 1 <= options.samples <= 4096:
        raise UsageError(f"samples must be a whole number from 1 to 4096, got {options.samples!r}")
    from .engines import ENCODINGS

    for engine, encoding in options.encodings.items():
        if engine not in options.engines:
            raise UsageError(f"an encoding is given for {engine}, which is not baked")
        if encoding not in ENCODINGS.get(engine, ()):
            offered = ENCODINGS.get(engine, ())
            raise UsageError(f"{engine} takes {', '.join(offered) if offered else 'no choice of'} encoding"
                             f"{'s' if len(offered) != 1 else ''}, not {encoding}")
