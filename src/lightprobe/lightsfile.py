"""lightprobe's lights JSON file, written by ``lightprobe lights`` (and, later, read by the light exports).

Schema ``{"format": "lightprobe.lights", "version": 1, ...}``:

* ``frame``: ``world`` (SPEC §1: +Y up, front −Z, right +X) — every direction below is in it;
* ``lights``: in the order found, each ``direction`` (unit [x, y, z]), ``yaw_deg`` (0 at the front −Z, positive
  towards +X) and ``elevation_deg`` (above the horizon), ``angular_radius_deg``, ``solid_angle_sr`` of its cap
  (2π(1 − cos radius)), ``power`` (RGB ∫L dω over the pixels it took: radiance × sr, the unit of ``lightprobe
  info``'s integral), ``radiance`` (power / solid angle: the cap's mean RGB radiance) and ``response`` (the
  filter response that chose it);
* ``ambient``: ``power`` (RGB ∫ ambient dω) and ``sh`` — the ambient map's **radiance** SH coefficients in lightprobe's
  SH schema (:mod:`lightprobe.shfile`, world frame), to be used as SH irradiance for everything the lights do not
  carry;
* ``total_power`` (RGB ∫ map dω) and ``shares``: the fractions of the total luminance power in the lights and in
  the ambient (they sum to 1; Σ light power + ambient power = total power per channel, to float rounding);
* ``parameters``: every parameter of the search (:class:`lightprobe.lights.LightParams`), ``method``
  (``arbree2005``; or ``mediancut``, whose point lights have radius and solid angle 0, radiance and response null,
  and ``ambient`` null: they carry the whole map; its parameters are ``count`` and ``working_rows``);
* ``timings`` (seconds) and ``source`` (the map, or null).
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np

from .frames import WORLD
from .baselines import PointLight
from .lights import Decomposition
from .sh import SHCoeffs
from .shfile import sh_document
from .tonemap import luminance

FORMAT, VERSION = "lightprobe.lights", 1


def lights_document(dec: Decomposition, ambient_sh: SHCoeffs, source: str | None = None) -> dict:
    """The schema's object for a decomposition and its ambient's radiance SH."""
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
    return json.dumps(lights_document(dec, ambient_sh, source), indent=1, allow_nan=False) + "\n"


def point_lights_document(lights: list[PointLight], total: np.ndarray, method: str, parameters: dict,
                          timings: dict, source: str | None = None) -> dict:
    """The schema's object for point lights (a baseline such as median cut): each light's radius and solid angle
    are 0, its radiance and response null; there is no separate ambient (``ambient`` null): the lights carry the
    whole map."""
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
