"""Report sections on paper 1: SH coefficients, irradiance maps, their error, lighting design."""

from __future__ import annotations

import time

import numpy as np

from ..maps.tonemap import auto_exposure, heatmap
from ..sh.basis import name
from ..sh.design import design_figure, edit
from ..sh.irradiance import (
    brute_irradiance,
    error_report,
    irradiance_map,
    reference_normals,
)
from .page import Report, table


def section_sh(rep: Report) -> str:
    """The nine coefficients in the world frame and in the paper's frame."""
    world = rep.sh(2)
    paper = world.to_frame("rh2001")
    rows = [[name(i), *(f"{v:+.4f}" for v in world.coeffs[i]), *(f"{v:+.4f}" for v in paper.coeffs[i])]
            for i in range(9)]
    return ("<h2>Spherical harmonics (Ramamoorthi &amp; Hanrahan 2001)</h2>"
            "<p>Radiance coefficients L<sub>lm</sub> (real SH without Condon–Shortley phase, flat order l(l+1)+m). "
            "World frame: +Y up, front −Z; <code>rh2001</code> is the paper's frame (z negated), in which its "
            "Figure 2 is printed — the test suite reproduces that figure for all five Debevec files to 0.01.</p>"
            + table(["coefficient", "R world", "G world", "B world", "R rh2001", "G rh2001", "B rh2001"], rows))


def section_irradiance(rep: Report) -> str:
    """SH against brute-force irradiance maps, with the error where a person sees it."""
    size = 64
    t0 = time.perf_counter()
    brute = irradiance_map(rep.env, "latlong", size, "brute")
    t_brute = time.perf_counter() - t0
    t0 = time.perf_counter()
    sh9 = irradiance_map(rep.env, "latlong", size, "sh", 2, sh=rep.sh(2))
    t_sh = time.perf_counter() - t0
    auto = irradiance_map(rep.env, "latlong", size, "sh", 2, "auto", sh=rep.sh(2))
    auto_label = rep.sh(2).windowed("auto").window
    rep.timings["irradiance map 128×64, brute force"] = t_brute
    rep.timings["irradiance map 128×64, SH9"] = t_sh
    exposure = auto_exposure(brute.data)

    def rel_error(m):
        from ..maps.tonemap import luminance

        return np.abs(luminance(m.data) - luminance(brute.data)) / np.maximum(luminance(brute.data), 1e-9)

    figures = [
        rep.picture("irr_brute", brute.data, "brute force (exact)", exposure, width=320),
        rep.picture("irr_sh9", sh9.data, "SH, 9 coefficients", exposure, width=320),
        rep.display_picture("irr_sh9_error", heatmap(rel_error(sh9), 1.0),
                            "|E_SH − E| / E, black 0 → white ≥ 100 %", width=320),
        rep.picture("irr_sh9_auto", auto.data, f"SH, 9 coefficients, {auto_label}", exposure, width=320),
        rep.display_picture("irr_auto_error", heatmap(rel_error(auto), 1.0),
                            "relative error with the auto window (same scale)", width=320),
    ]
    negative = float((sh9.data < 0).any(axis=-1).mean())
    return ("<h2>Irradiance maps: SH against brute force</h2>"
            f"<p>Irradiance E(n) for every normal of a 128×64 lat-long map. Brute force integrates all "
            f"{rep.env.valid_mask().sum()} pixels for each normal ({t_brute:.2f} s); SH9 evaluates nine terms "
            f"({1000 * t_sh:.1f} ms, {t_brute / max(t_sh, 1e-9):.0f}× faster). The heat maps show the relative "
            f"error a person sees: small in the bright half, large on the dark side opposite the sun, where SH9 "
            f"rings (negative irradiance in some channel on {100 * negative:.1f} % of the map without a window; "
            f"the auto window removes it at the price of blur).</p>"
            '<div class="grid">' + "".join(figures) + "</div>")


def section_errors(rep: Report) -> str:
    """Both error measures for orders 2, 4, 6 and every window."""
    normals = reference_normals(1500)
    t0 = time.perf_counter()
    reference = brute_irradiance(rep.env, normals)
    rep.timings["brute-force reference, 1500 normals"] = time.perf_counter() - t0
    sh = rep.sh(6)
    rows = []
    for l_max in (2, 4, 6):
        for window in ("none", "hanning", "lanczos", "auto"):
            r = error_report(rep.env, l_max, window, normals, reference, sh)
            rows.append([l_max, r.window, f"{100 * r.paper_mean:.2f} %", f"{100 * r.paper_max:.2f} %",
                         f"{100 * r.relative_mean:.1f} %", f"{100 * r.relative_max:.1f} %",
                         f"{100 * r.negative_fraction:.1f} %"])
    return ("<h2>How wrong is SH irradiance?</h2>"
            "<p>Luminance over 1500 uniformly spread normals against the brute-force reference. <em>Paper</em>: "
            "|E − E<sub>ref</sub>| as a fraction of ∫L dω (the measure of the paper: under 1 % mean, 5 % max on "
            "Debevec's probes). <em>Relative</em>: |E − E<sub>ref</sub>| / E<sub>ref</sub> per normal, the error "
            "on the dark side. Windows trade accuracy for freedom from ringing; <code>auto</code> takes the "
            "widest window that keeps irradiance non-negative.</p>"
            + table(["order", "window", "paper mean", "paper max", "relative mean", "relative max", "E < 0"], rows))


def section_design(rep: Report) -> str:
    """Paper §3.3 / Figure 4: the basis functions and an edit."""
    original = rep.sh(2)
    edited = edit(original, [], ["1=0.3"])
    figure = rep.display_picture("design", design_figure(original, edited, 96),
                                 "SH basis functions (orange +, blue −); lighting on white spheres before and "
                                 "after scaling band 1 by 0.3")
    return ("<h2>Lighting design</h2><p>Editing the nine numbers edits the lighting (paper §3.3): here band 1, "
            "the directional part, is scaled by 0.3, so the spheres' bright and dark sides even out. "
            "<code>lightprobe design --set L1-1=-0.4 --scale-band 2=0.5 -o out.png</code> does the same from the "
            "command line.</p>" + figure)
