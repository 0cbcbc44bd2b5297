"""lightprobe's lights JSON file, written by ``lightprobe lights`` and read by the light exports (``export --lights``).

Schema ``{"format": "lightprobe.lights", "version": 1, ...}``:

* ``frame``: ``world`` (docs/spec.md §1: +Y up, front −Z, right +X) — every direction below is in it;
* ``lights``: in the order found, each ``direction`` (unit [x, y, z]), ``yaw_deg`` (0 at the front −Z, positive
  towards +X) and ``elevation_deg`` (above the horizon), ``angular_radius_deg``, ``solid_angle_sr`` of its cap
  (2π(1 − cos radius)), ``power`` (RGB ∫L dω over the pixels it took: radiance × sr, the unit of ``lightprobe
  info``'s integral), ``radiance`` (power / solid angle: the cap's mean RGB radiance) and ``response`` (the
  filter response that chose it);
* ``ambient``: ``power`` (RGB ∫ ambient dω) and ``sh`` — the ambient map's **radiance** SH coefficients in lightprobe's
  SH schema (:mod:`lightprobe.sh.shfile`, world frame), to be used as SH irradiance for everything the lights do not
  carry;
* ``total_power`` (RGB ∫ map dω) and ``shares``: the fractions of the total luminance power in the lights and in
  the ambient (they sum to 1; Σ light power + ambient power = total power per channel, to float rounding);
* ``parameters``: every parameter of the search (:class:`lightprobe.lights.decompose.LightParams`), ``method``
  (``arbree2005``; or ``mediancut``, whose point lights have radius and solid angle 0, radiance and response null,
  and ``ambient`` null: they carry the whole map; its parameters are ``count`` and ``working_rows``);
* ``timings`` (seconds) and ``source`` (the map, or null).
"""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np

from ..maps.frames import WORLD
from .baselines import PointLight
from .decompose import Decomposition
from ..sh.basis import SHCoeffs
from ..sh.shfile import sh_document
from ..maps.tonemap import luminance

FORMAT, VERSION = "lightprobe.lights", 1


def lights_document(dec: Decomposition, ambient_sh: SHCoeffs, source: str | None = None) -> dict:
    """The schema's object for a decomposition and its ambient's radiance SH.

    Parameters
    ----------
    dec : Decomposition
        The lights found (world frame) and the ambient map (:func:`lightprobe.lights.decompose.decompose`).
    ambient_sh : SHCoeffs
        Radiance SH of ``dec.ambient``, any order; stated in the world frame in the file.
    source : str, optional
        The map the lights came from; null in the file when None.

    Returns
    -------
    dict
        The ``lightprobe.lights`` version 1 object, method ``arbree2005`` (see the module docstring), ready for
        ``json.dumps``.
    """
    total_y = float(luminance(dec.total))
    light_y = float(luminance(dec.light_power))
    lights = []
    for light in dec.lights:
        yaw, elevation = light.yaw_elevation_deg
        lights.append({"direction": [float(v) for v in light.direction], "yaw_deg": yaw, "elevation_deg": elevation,
                       "angular_radius_deg": float(np.degrees(light.radius)), "solid_angle_sr": light.solid_angle,
                       "power": [float(v) for v in light.power], "radiance": [float(v) for v in light.radiance],
                       "response": light.response})
    share = light_y / total_y if total_y > 0 else 0.0
    return {"format": FORMAT, "version": VERSION, "frame": WORLD.name, "frame_description": WORLD.description,
            "method": "arbree2005", "lights": lights,
            "ambient": {"power": [float(v) for v in dec.ambient.integral()], "sh": sh_document(ambient_sh, WORLD)},
            "total_power": [float(v) for v in dec.total], "shares": {"lights": share, "ambient": 1.0 - share},
            "parameters": dataclasses.asdict(dec.params), "timings": dict(dec.timings), "source": source}


def lights_json(dec: Decomposition, ambient_sh: SHCoeffs, source: str | None = None) -> str:
    """The schema's JSON text for a decomposition (:func:`lights_document`, indented, ending in a newline).

    Parameters
    ----------
    dec : Decomposition
        What to write, as for :func:`lights_document`.
    ambient_sh : SHCoeffs
        The ambient's radiance SH, as for :func:`lights_document`.
    source : str, optional
        The probe the lights were found in (its path as the user gave it), or None.

    Returns
    -------
    str
        The ``lightprobe.lights`` text a lights export reads back (:func:`read_lights_json`): strict JSON, no NaN
        or infinity, indented by one space, with a final newline.
    """
    return json.dumps(lights_document(dec, ambient_sh, source), indent=1, allow_nan=False) + "\n"


def point_lights_document(lights: list[PointLight], total: np.ndarray, method: str, parameters: dict,
                          timings: dict, source: str | None = None) -> dict:
    """The schema's object for point lights (a baseline such as median cut), which carry the whole map.

    Each light's radius and solid angle are 0, its radiance and response null; there is no separate ambient (``ambient``
    null): the lights carry the whole map.

    Parameters
    ----------
    lights : list of PointLight
        The lights, world frame, RGB power ∫L dω each.
    total : numpy.ndarray
        (3,) RGB ∫ map dω, for ``total_power`` and the shares.
    method : str
        The method's name in the file (e.g. ``mediancut``).
    parameters : dict
        The method's parameters (e.g. ``count`` and ``working_rows``).
    timings : dict
        Named durations in seconds.
    source : str, optional
        The map the lights came from; null in the file when None.

    Returns
    -------
    dict
        The ``lightprobe.lights`` version 1 object, ready for ``json.dumps``.
    """
    total_y = float(luminance(total))
    powers = np.sum([light.power for light in lights], axis=0) if lights else np.zeros(3)
    share = float(luminance(powers)) / total_y if total_y > 0 else 0.0
    out = []
    for light in lights:
        yaw, elevation = light.yaw_elevation_deg
        out.append({"direction": [float(v) for v in light.direction], "yaw_deg": yaw, "elevation_deg": elevation,
                    "angular_radius_deg": 0.0, "solid_angle_sr": 0.0, "power": [float(v) for v in light.power],
                    "radiance": None, "response": None})
    return {"format": FORMAT, "version": VERSION, "frame": WORLD.name, "frame_description": WORLD.description,
            "method": method, "lights": out, "ambient": None, "total_power": [float(v) for v in total],
            "shares": {"lights": share, "ambient": 1.0 - share}, "parameters": dict(parameters),
            "timings": dict(timings), "source": source}


# ---- reading --------------------------------------------------------------------------------------------------------
MAX_BYTES = 16 << 20
MAX_LIGHTS = 10_000


@dataclasses.dataclass(frozen=True)
class LightSet:
    """What the exports need of a lights file: each light's ``direction`` (world, unit), angular ``radius``
    (radians; 0 for a point light) and RGB ``power`` (∫L dω), and the ambient's radiance SH (world frame; None when
    the lights carry the whole map)."""

    directions: np.ndarray  # (n, 3)
    radii: np.ndarray  # (n,)
    powers: np.ndarray  # (n, 3)
    ambient: SHCoeffs | None
    method: str


def read_lights_json(text: str | bytes, what: str = "lights file") -> LightSet:
    """The lights of a ``lightprobe.lights`` v1 document; every field the exports use is checked.

    Anything wrong raises one clear :class:`~lightprobe.util.errors.InputError`. Directions are normalised (scaled
    by their largest component first, so that no finite direction overflows or underflows to zero); a
    radius must be within 0°..90°, powers finite and non-negative.

    Parameters
    ----------
    text : str or bytes
        The document, at most :data:`MAX_BYTES` (16 MiB) and :data:`MAX_LIGHTS` lights.
    what : str, default "lights file"
        What is read, for messages (e.g. the file's name).

    Returns
    -------
    LightSet
        Unit directions (n, 3) in the world frame, radii (n,) in radians, RGB powers (n, 3) ∫L dω, the ambient's
        radiance SH (None when ``ambient`` is null) and the method.

    Raises
    ------
    InputError
        The text is not such a document, its frame is not ``world``, or a field the exports use is missing or
        wrong (the method, a light's direction, radius or power, the ambient's SH document, which must be
        radiance).
    """
    from ..sh.shfile import read_sh_json, versioned_document

    doc, fail = versioned_document(text, what, FORMAT, VERSION, MAX_BYTES)
    if doc.get("frame") != WORLD.name:
        fail("frame must be world")
    method = doc.get("method")
    if not isinstance(method, str) or len(method) > 64:
        fail("method must be a short text")
    lights = doc.get("lights")
    if not isinstance(lights, list) or len(lights) > MAX_LIGHTS:
        fail(f"lights must be a list of at most {MAX_LIGHTS}")
    directions, radii, powers = [], [], []
    for i, light in enumerate(lights):
        if not isinstance(light, dict):
            fail(f"light {i} is not an object")
        d, r, p = light.get("direction"), light.get("angular_radius_deg"), light.get("power")
        if not _numbers(d, 3) or not np.all(np.isfinite(d)) or max(abs(float(v)) for v in d) == 0:
            fail(f"light {i}: direction must be three finite numbers, not all zero")
        if not _number(r) or not 0 <= r <= 90:
            fail(f"light {i}: angular_radius_deg must be a number within 0..90")
        if not _numbers(p, 3) or not np.all(np.isfinite(p)) or min(p) < 0:
            fail(f"light {i}: power must be three finite numbers ≥ 0")
        d = np.asarray(d, dtype=np.float64) / np.max(np.abs(d))  # within [-1, 1] first: its norm cannot overflow
        directions.append(d / np.linalg.norm(d))
        radii.append(np.radians(float(r)))
        powers.append(np.asarray(p, dtype=np.float64))
    ambient = doc.get("ambient")
    sh = None
    if ambient is not None:
        if not isinstance(ambient, dict) or not isinstance(ambient.get("sh"), dict):
            fail("ambient must be null or an object with an sh document")
        sh = read_sh_json(json.dumps(ambient["sh"]), f"{what}'s ambient")
        if sh.quantity != "radiance":
            fail("the ambient's SH must be radiance")
    return LightSet(np.array(directions).reshape(-1, 3), np.array(radii), np.array(powers).reshape(-1, 3), sh,
                    method)


def _number(v) -> bool:
    """A finite JSON number (a bool is not one; an integer too big for a float is not finite)."""
    if not isinstance(v, (int, float)) or isinstance(v, bool):
        return False
    try:
        return math.isfinite(float(v))
    except OverflowError:
        return False


def _numbers(v, n: int) -> bool:
    return isinstance(v, list) and len(v) == n and all(_number(x) for x in v)
