"""Report section on paper 3: the probe's area lights and ambient remainder."""

from __future__ import annotations

import time

import numpy as np

from .page import Report, table


def section_lights(rep: Report) -> str:
    """The probe as area lights plus an ambient remainder (Arbree, Walter & Bala 2005): what was found, and the
    energy bookkeeping."""
    from ..lights.decompose import decompose, preview
    from ..maps.tonemap import luminance

    t0 = time.perf_counter()
    dec = decompose(rep.env)
    rep.timings["area-light decomposition"] = time.perf_counter() - t0
    total = float(luminance(dec.total))
    rows = []
    for i, light in enumerate(dec.lights, 1):
        yaw, elevation = light.yaw_elevation_deg
        rows.append([i, f"{yaw:+.1f}°", f"{elevation:+.1f}°", f"{np.degrees(light.radius):.1f}°",
                     f"{100 * float(luminance(light.power)) / total:.1f} %"])
    balance = float(np.abs(dec.light_power + dec.ambient.integral() - dec.total).max() / dec.total.max())
    pictures = (rep.display_picture("lights_preview", preview(rep.env, dec.lights),
                                    "the probe with each light's cap outlined")
                + rep.picture("lights_ambient", dec.ambient.to("latlong", 256).data, "the ambient map: the probe "
                              "with the lights' pixels taken out"))
    return ("<h2>Area lights + ambient (Arbree, Walter &amp; Bala 2005)</h2>"
            f"<p>The centre–surround search of the paper with its parameters found {len(dec.lights)} light(s) in "
            f"{rep.timings['area-light decomposition']:.1f} s, holding "
            f"{100 * float(luminance(dec.light_power)) / total:.0f} % of the luminance power; energy is only "
            f"moved: Σ lights + ∫ ambient dω equals ∫ map dω to {balance:.0e}. The lights render with soft shadows "
            "in the last section, against Mitsuba.</p>" + pictures
            + table(["light", "yaw", "elevation", "radius", "share of the power"], rows))
