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
* ``parameters``: every parameter of the search (:class:`lightprobe.lights.LightParams`), ``method``;
* ``timings`` (seconds) and ``source`` (the map, or null).
"""

from __future__ import annotations

import dataclasses
import json

import numpy as np

from .frames import WORLD
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
