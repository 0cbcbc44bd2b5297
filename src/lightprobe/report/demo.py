"""``lightprobe demo``: the main job. Runs what lightprobe does on one probe and writes an HTML report.

The report is a list of sections (:data:`SECTIONS`); each is a function ``(Report) → html`` that may save pictures
through :meth:`Report.picture`. Later capabilities add their sections to the list.

Nothing of the user's is lost: the report is written into a fresh temporary folder beside ``out`` and moved into
place only when complete (a report failing halfway leaves nothing); an existing ``out`` is replaced only when it is
a previous report (it holds :data:`MARKER`) or is empty, or with ``force``. Timings are of warm kernels: the
one-time compilation of the numba kernels is measured first and reported on its own line.
"""

from __future__ import annotations

import contextlib
import functools
import html
import os
import secrets
import shutil
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from .design import design_figure, edit
from .envmap import EnvMap, to_image
from .errors import InputError, LightprobeError
from .export import TARGETS, export
from .files import sweep_stale_temporaries, write_text
from .io import write_image
from .irradiance import brute_irradiance, error_report, irradiance_map, reference_normals
from .layouts import LAYOUTS
from .progress import track
from .sh import SHCoeffs, name, project
from .tonemap import auto_exposure, heatmap


@dataclass
class Report:
    """What sections share: the probe, the output folder, a fixed exposure, and timings."""

    env: EnvMap
    out: Path
    probe_name: str
    exposure: float = 0.0
    timings: dict[str, float] = field(default_factory=dict)
    shared: dict = field(default_factory=dict)  # results later sections reuse (SH coefficients, references)

    def sh(self, l_max: int = 6) -> SHCoeffs:
        """Radiance SH of the probe up to ``l_max`` (computed once)."""
        if self.shared.get("sh") is None or self.shared["sh"].l_max < l_max:
            t0 = time.perf_counter()
            self.shared["sh"] = project(self.env, l_max)
            self.timings[f"SH projection, order {l_max}"] = time.perf_counter() - t0
        return self.shared["sh"].truncated(l_max)

    def display_picture(self, name: str, display: np.ndarray, caption: str, width: int | None = None) -> str:
        """Save display-encoded RGB as ``name``.png and return an HTML figure."""
        write_image(self.out / f"{name}.png", display, encoded=True)
        return figure(name, caption, width)

    def picture(self, name: str, rgb: np.ndarray, caption: str, exposure: float | None = None,
                curve: str = "aces", width: int | None = None) -> str:
        """Save linear RGB as ``name``.png (tone-mapped) and return an HTML figure for it (``width`` in CSS px)."""
        write_image(self.out / f"{name}.png", rgb, exposure=self.exposure if exposure is None else exposure,
                    curve=curve)
        return figure(name, caption, width)


def figure(name: str, caption: str, width: int | None = None) -> str:
    """An HTML figure for ``name``.png; small pictures are shown enlarged (pixelated, so nothing is invented)."""
    style = f' style="width:{width}px;max-height:none;image-rendering:pixelated"' if width else ""
    return (f'<figure><img src="{name}.png" alt="{html.escape(caption)}"{style}>'
            f"<figcaption>{html.escape(caption)}</figcaption></figure>")


def table(header: list[str], rows: list[list], fmt: str = "{:.6g}") -> str:
    """A small HTML table; floats are formatted with ``fmt``."""
    def cell(v):
        return html.escape(fmt.format(v) if isinstance(v, float) else str(v))

    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{cell(v)}</td>" for v in r) + "</tr>" for r in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


# ---- sections -----------------------------------------------------------------------------------------------------
def section_probe(rep: Report) -> str:
    s = rep.env.stats()
    rows = [[k, "  ".join(f"{x:.5g}" for x in v) if isinstance(v, list) else v] for k, v in s.items()]
    return ("<h2>The probe</h2>"
            f"<p>{html.escape(rep.probe_name)}; radiance is linear RGB, directions in the world frame "
            "(+Y up, front −Z, right +X). <code>mean</code> is ∫L dω / 4π.</p>"
            + rep.picture("probe", to_image(rep.env), "the probe as read") + table(["statistic", "value"], rows))


def section_layouts(rep: Report) -> str:
    """The probe in every layout, with ∫L dω after each conversion (it must not change)."""
    base = rep.env.integral()
    figures, rows = [], []
    for lay_name, lay in LAYOUTS.items():
        size = 256 if lay_name in ("latlong", "angular", "sphere") else 128
        t0 = time.perf_counter()
        converted = rep.env.to(lay, size)
        seconds = rep.timings[f"convert to {lay_name} {size}"] = time.perf_counter() - t0
        change = converted.integral() / base - 1
        rows.append([lay_name, size, "×".join(map(str, converted.grid)), *(f"{100 * c:+.3f} %" for c in change),
                     f"{1000 * seconds:.0f} ms"])
        figures.append(rep.picture(f"layout_{lay_name}", to_image(converted), f"{lay_name} ({converted.size})"))
    return ("<h2>Every layout</h2><p>The probe converted into each layout by footprint-aware resampling. The same "
            "direction is at the same place of the sphere in every picture: no mirror, no rotation slips in. "
            "The table gives the change of ∫L dω per channel (the issue's bound is 0.5 %).</p>"
            '<div class="grid">' + "".join(figures) + "</div>"
            + table(["layout", "size", "grid", "ΔR", "ΔG", "ΔB", "time"], rows))


def section_speed(rep: Report) -> str:
    """Conversion and projection speed as ratios measured here, and the energy a one-pixel sun keeps."""
    from concurrent.futures import ThreadPoolExecutor

    from .envmap import Resampler, resample
    from .layouts import CUBE, LATLONG

    big = rep.env.to(LATLONG, 1024)  # 2048×1024, the size the benchmarks use
    timed = {}

    def best(name, fn, repeat=3):
        times = []
        for _ in range(repeat):
            t0 = time.perf_counter()
            result = fn()
            times.append(time.perf_counter() - t0)
        timed[name] = min(times)
        return result

    direct = best("direct", lambda: resample(big, CUBE, 512), repeat=2)
    conv = best("build", lambda: Resampler(LATLONG, big.grid, CUBE, 512), repeat=1)
    cached = best("cached", lambda: conv(big))
    agree = float(np.abs(cached.data - direct.data).max() / direct.data.max())
    out = np.empty_like(big.data)
    best("pass", lambda: np.multiply(big.data, 1.0, out=out), repeat=5)
    for l_max in (2, 8, 16):
        project(big, l_max, compiled=True)
        best(f"sh{l_max}", lambda: project(big, l_max, compiled=True), repeat=5)
    # the memory figure's convert runs in its own process beside the accuracy figures below (its peak is its own;
    # nothing timed runs meanwhile)
    with ThreadPoolExecutor(1) as beside:
        memory = beside.submit(_convert_peak_memory, big, rep.out)
        sun_map = _one_pixel_sun(big.grid, np.ones(3) / np.sqrt(3))  # on a cube corner
        sun_error = float(np.abs(conv(sun_map).integral() / sun_map.integral() - 1).max())
        polar = _polar_sun_errors()
        pole_rows = _pole_row_targets()
        pole_detail = _pole_detail()
        every_pixel = _every_pixel_gains()
        gain_pictures = _gain_pictures(rep)
        memory = memory.result()
    rep.timings.update({f"speed {k}": v for k, v in timed.items()})
    rows = [["lat-long 2048×1024 → cube 6×512², one compiled pass (each footprint read for its 8 images under "
             "the cube's symmetries)", f"{1000 * timed['direct']:.0f} ms",
             f"{timed['direct'] / timed['pass']:.1f}× one numpy pass over the source (the benchmark: 2.75–2.9× a "
             "plain numpy nearest-pixel resampler)"],
            ["the same with its footprint weights cached (built once: "
             f"{1000 * timed['build']:.0f} ms, {conv.nbytes / 2**20:.0f} MiB)", f"{1000 * timed['cached']:.0f} ms",
             f"{timed['direct'] / timed['cached']:.1f}× faster than direct; equal to {agree:.0e} of the maximum"],
            *[[f"SH projection, order {l}", f"{1000 * timed[f'sh{l}']:.1f} ms",
               f"{timed[f'sh{l}'] / timed['pass']:.1f}× one numpy pass over the pixels"] for l in (2, 8, 16)],
            ["peak resident memory of lightprobe convert, that map into a cube, in a fresh process",
             f"{memory:.0f} MiB", "most of it the libraries (numpy, OpenImageIO, numba's LLVM); its kernels linked "
             "on a small map first, then LLVM's pages let go. A 4096×2048 map in a fresh install: 270 MiB into a "
             "cube, 271 into an angular map, 2.8× (tests/test_limits.py holds them within 3×). A map of this size "
             "into a disc is flux-corrected: the stencil, built once per pair of grids, takes it to ~390 MiB and "
             "5–8 s (into an angular map of 1634)"]]
    return ("<h2>Speed</h2><p>Measured now, on this machine, as ratios (the benchmarks compare with peers: "
            "<code>benchmarks/bench_peers.py</code>). A batch of maps of one size converts with cached footprint "
            "weights: one gather per map. The accuracy is the same: a sun in one pixel on a cube corner, holding "
            f"10× the sky's power, keeps ∫L dω to {100 * sun_error:.3f} % (plain nearest-pixel and bilinear "
            "converters lose or double it: 46–60 % in the benchmark).</p>"
            + table(["work", "time", "ratio"], rows)
            + "<p>Near a lat-long pole one target pixel spans many source columns; the rows there are read from "
              "their reductions in azimuth (2<sup>ℓ</sup> columns averaged, exactly energy-preserving) so the "
              "lookups never skip a column. A one-pixel sun at each angle from the pole (256×128 → cube 64, "
              "worst of two azimuths), ∫L dω error:</p>"
            + table(["from the pole", *polar], [["error", *(f"{100 * e:.3f} %" for e in polar.values())]])
            + "<p>A width that is not a multiple of a high power of two halves only so far; past its last halving "
              "a row is reduced by exact overlaps (each reduced column the mean of the columns it covers, by their "
              "shares). Such rows used to be read as their whole row's mean, flat in azimuth: a smooth field "
              "L = 1 + ½ x (1 ± 0.1 within 12° of a pole) into a cube of 128 came out up to 0.10 off there from "
              "806 and 805 rows, 0.058 from 1000 (and into a cube of 512 0.058 from 3000×1500, 0.028 from "
              "6000×3000). Worst |error| within 12° of the poles now:</p>"
            + table(["source", *pole_detail], [["error", *(f"{e:.4f}" for e in pole_detail.values())]])
            + "<p>In the first row (within 180°/H of the pole) the plain cubic B-spline reflected across the "
              "pole weighs a row 1.25× its own solid angle; near the poles its weights are made rational, so "
              "every row keeps its solid angle within 0.05 % (0.1–0.17 % on sources of 48–95 rows, which small "
              "targets no longer reduce below). A target pixel over the pole reads the rows its subsamples crowd "
              "as their whole row's mean, and a lat-long target on the source's rows is computed as two sparse "
              "products, exact in θ. A sun in the first row, into:</p>"
            + table(["target", *pole_rows], [["error", *(f"{100 * e:.3f} %" for e in pole_rows.values())]])
            + "<p>Every source pixel as the sun, exactly: the conversion is linear, so the energy a sun in pixel "
              "s comes out with is its column of the weights times the target's solid angles "
              "(<code>Resampler.energy_gains</code>). Pixels within 25° of a disc's rim direction left out, but "
              "for the rows with no margin: a disc's rim direction is corrected like the rest, as target and as "
              "source.</p>"
            + table(["conversion", "worst", "pixels over 0.2 %"],
                    [[label, f"{100 * worst:.3f} %", f"{100 * share:.1f} %"]
                     for label, (worst, share) in every_pixel.items()])
            + '<div class="grid">' + gain_pictures + "</div>"
            + "<p>Where a target pixel's rate differs from its neighbours', its cells are graded so the lookups' "
              "spacing does not jump (it left rings of pixels up to ~1 % off), and target pixels round a cube "
              "source's vertices, read across a jump where three faces meet, take 16 subsamples a side. A cube "
              "source is read through its texel balance: each texel blended with its row and column neighbours "
              "(by at most 2.2 % from 32 texels a side) so that its B-spline carries exactly its solid angle — "
              "its edge texels carried up to 0.8 % too much at 64 texels a side, and 0.26 % at any size where "
              "the padding copies the next face's texels. What the target's quadrature still loses is then "
              "corrected for each pair of grids (<code>envmap/flux.py</code>): the conversion's adjoint gives "
              "every source pixel's delivered energy, and a flow of it along the source's edges — built top-down "
              "on a quadtree of each face, exact to float rounding — becomes a pre-filter that blends each pixel "
              "with its four neighbours (by 0.5–4 % at the worst pixel), so a sun in any pixel of a cube, "
              "angular or mirror-ball source keeps its energy (a cube's corner texels into a lat-long of 32 rows "
              "were off by 2.4 %). A lat-long source holds 0.2 % into lat-long and cube targets by its own "
              "construction, and into discs by its rates (lookups 0.4 pixels apart into an angular map, up to 32 "
              "a side by a mirror ball's rim: 0.27 / 0.40 % → 0.11 / 0.08 % at full size; closer by an angular map's "
              "rim direction, where a pixel's solid angle per area changes by its own size across it: 4096×2048 → "
              "angular 3268, 0.26 → 0.15 %); one read as up to "
              "65 536 pixels into a disc (a 16–64-pixel one) is flux-corrected too, where its rim rings span "
              "20–40° and no rate helps (0.26–0.74 % before) (<code>benchmarks/bench_energy.py</code>).</p>")


def _convert_peak_memory(env, folder) -> float:
    """Peak resident memory (MiB) of ``lightprobe convert`` of ``env`` into a cube in a fresh process, measured by
    :func:`lightprobe.peak.run_measured`."""
    import sys

    from .io import write_image
    from .peak import run_measured

    src, dst = folder / "convert_memory.exr", folder / "convert_memory_out.exr"
    write_image(src, env.data)
    command = "import sys\nfrom lightprobe.cli import main\nsys.exit(main(sys.argv[1:]))\n"
    res, peak = run_measured([sys.executable, "-c", command, "convert", str(src), str(dst), "--to", "cube"],
                             env={"LIGHTPROBE_PROGRESS": "0"})
    if res.returncode:
        raise RuntimeError(f"convert for the memory figure failed: {res.stderr.strip()[-300:]}")
    src.unlink()
    dst.unlink()
    return peak


@functools.lru_cache(maxsize=4)
def _pair_gains(source: str, size: int, target: str, out_size: int, margin: float | None,
                turn: tuple[float, float, float] | None = None, uncorrected: bool = False) -> np.ndarray:
    """Resampler.energy_gains(rim_margin=margin) of a pair, the target turned by ``turn`` (yaw, pitch, roll in
    degrees) if given, without the flux correction if ``uncorrected``, read-only: a table row and a heat map share
    it."""
    from .envmap import Resampler
    from .frames import rotation_from_ypr
    from .layouts import layout

    src = layout(source)
    rotation = None if turn is None else rotation_from_ypr(*turn)
    resampler = Resampler(src, src.grid_shape(size), layout(target), out_size, rotation=rotation)
    if uncorrected:
        resampler = resampler.without_flux_correction()
    gains = resampler.energy_gains(rim_margin=margin)
    gains.setflags(write=False)
    return gains


def _every_pixel_gains() -> dict[str, tuple[float, float]]:
    """(worst |gain|, share over 0.2 %) of a one-pixel sun in every source pixel, for a few conversions."""
    cases = (("lat-long 128 → cube 32", "latlong", 128, "cube", 32),
             ("angular 128 → lat-long 64 (was 15.5 %; 0.3 % before the flux correction)", "angular", 128,
              "latlong", 64),
             ("mirror ball 128 → angular 64 (was 74 %; 0.6 % before the flux correction)", "sphere", 128,
              "angular", 64),
             ("mirror ball 128 → angular 16 (was 18.8 %: halved to 64 for so small a target)", "sphere", 128,
              "angular", 16),
             ("lat-long 128 → mirror ball 32 (0.73 % before the flux correction)", "latlong", 128, "sphere", 32),
             ("lat-long 746×373 → cube 352 (an odd height: +2920 % by the poles before a row's last halving could "
              "leave an odd width)", "latlong", 373, "cube", 352),
             ("lat-long 202×101 → cube 27, no margin (+0.275 % on the cube's vertices before the edge terms)",
              "latlong", 101, "cube", 27, None),
             ("lat-long 256×128 → lat-long 39 turned (yaw 104°, pitch 133°, roll −39°) (+0.52 % on the target's "
              "poles before their cells vanished there; 0.07 % there now)", "latlong", 128, "latlong", 39, None,
              {"turn": (104, 133, -39)}),
             ("lat-long 512×256 → cube 50 turned (yaw 30°, pitch 40°, roll 50°) (+0.46 % in the source's pole rows "
              "before the cells of its coarsest polar rows were balanced)", "latlong", 256, "cube", 50, None,
              {"turn": (30, 40, 50)}),
             ("lat-long 256 → angular 128 (0.10 % by its rates alone before lat-longs up to 2048×1024 were "
              "flux-corrected; 0.27 % at 0.5 pixels between lookups)", "latlong", 256, "angular", 128),
             ("cube 64 → cube 64 (corner texels: was 4.6 %; 0.86 % before the texel balance, 0.13 % before the "
              "flux correction)", "cube", 64, "cube", 64),
             ("cube 64 → lat-long 32 (2.4 % before the flux correction)", "cube", 64, "latlong", 32),
             ("cube 128 → lat-long 256 (at 256 → 512: 1.6 % before graded cells, 0.40 % before the texel balance, "
              "0.30 % before the flux correction)", "cube", 128, "latlong", 256),
             ("cube 64 → mirror ball 64, no margin (was 40 % within 25° of the ball's rim direction)", "cube", 64,
              "sphere", 64, None),
             ("lat-long 128 → mirror ball 64, no margin (was 55 % there)", "latlong", 128, "sphere", 64, None),
             ("lat-long 256 → mirror ball 128, no margin (33 % by the rim direction before its rim pixels were "
              "sampled round it, 0.19 % by them alone, before its flux correction)", "latlong", 256, "sphere", 128,
              None),
             ("lat-long 512×256 → angular 408, no margin, its rows alone (without its flux correction: the ratio of "
              "a 4k lat-long into its default angular map, 3268, which is not corrected; 0.27 % by the rim "
              "direction before the pixels just inside took lookups closer there)", "latlong", 256, "angular", 408,
              None, {"uncorrected": True}),
             ("lat-long 256 → angular 128, no margin (0.46 % by the rim direction before its rim pixels were "
              "sampled round it, 0.09 % by them alone)", "latlong", 256, "angular", 128, None),
             ("angular 256 → lat-long 128, no margin (was 555 % within 2° of the angular map's rim direction, left "
              "uncorrected within 20° until the pixels there were read round it)", "angular", 256, "latlong", 128,
              None),
             ("mirror ball 256 → angular 64, no margin (its ring read round its rim direction)", "sphere", 256,
              "angular", 64, None))
    out = {}
    for label, source, size, target, out_size, *options in cases:  # the margin (25° unless given), then _pair_gains'
        margin, settings = (options + [25.0, {}][len(options):])[:2]  # keyword settings (turn, uncorrected), if any
        gains = _pair_gains(source, size, target, out_size, margin, **settings)
        gains = np.abs(gains[np.isfinite(gains)])
        out[label] = (float(gains.max()), float((gains > 2e-3).mean()))
    return out


def _rows_alone(target: str) -> np.ndarray:
    """Gains of lat-long 256 → ``target`` 128 with no margin before its flux correction: what the rates and rim rows
    hold alone, as a 4k lat-long (too large to be corrected) has them."""
    from .envmap import Resampler
    from .layouts import layout

    src = layout("latlong")
    return Resampler(src, src.grid_shape(256), layout(target), 128).without_flux_correction().energy_gains()


def _gain_pictures(rep: Report) -> str:
    """Heat maps of |gain| over the source's pixels: a mirror ball into an angular map at one rate for the whole
    map (as before) and at each pixel's own, a cube into a lat-long (what is left), and what a cube's texel balance
    removes."""
    from .envmap import Resampler, balance
    from .envmap.map import pixel_solid_angles
    from .envmap.resampling import supersampling
    from .layouts import layout

    ball, angular, cube, latlong = layout("sphere"), layout("angular"), layout("cube"), layout("latlong")
    k, _ = supersampling(ball, ball.grid_shape(128), angular, angular.grid_shape(64), None, None)
    one_rate = Resampler(ball, ball.grid_shape(128), angular, 64, samples=k).energy_gains(rim_margin=25.0)
    own_rate = Resampler(ball, ball.grid_shape(128), angular, 64).without_flux_correction()
    own_rate = own_rate.energy_gains(rim_margin=25.0)
    cube_gains = Resampler(cube, cube.grid_shape(64), latlong, 64).without_flux_correction().energy_gains()
    strip = np.concatenate(list(cube_gains), axis=1)  # the six faces side by side, as a cube file is
    into_ball = Resampler(cube, cube.grid_shape(64), layout("sphere"), 64).without_flux_correction().energy_gains()
    ball_strip = np.concatenate(list(into_ball), axis=1)
    surplus = balance.face_texel_integrals(64) / pixel_solid_angles(cube, cube.grid_shape(64))[0] - 1
    big_to_ball = _rows_alone("sphere")  # what a 4k lat-long, not flux-corrected, keeps
    back = big_to_ball[128 - 43:128 + 43, 256 - 43:256 + 43]  # ±30° round the ball's rim direction (−Z)
    big_to_angular = _rows_alone("angular")  # the same for an angular map's (+Z: the seam)
    front = np.roll(big_to_angular, 256, axis=1)[128 - 43:128 + 43, 256 - 43:256 + 43]
    scale = "black 0, white 1 % or more; grey: no sphere, or within 25° of a rim direction"
    return (rep.display_picture("energy_ball_one_rate", heatmap(np.abs(one_rate), 0.01),
                                f"mirror ball 128 → angular 64, one rate k = {k}: |gain| of a sun in each pixel "
                                f"({scale})", width=256)
            + rep.display_picture("energy_ball_own_rate", heatmap(np.abs(own_rate), 0.01),
                                  f"the same, each target pixel its own rate, before the flux correction (after it, "
                                  f"black: every pixel exact) ({scale})", width=256)
            + rep.display_picture("energy_cube_latlong", heatmap(np.abs(strip), 0.002),
                                  "cube 64 → lat-long 64, faces +X −X +Y −Y +Z −Z, through the texel balance, "
                                  "before the flux correction (what it removes): faint rings where a target "
                                  "pixel's rate differs from its neighbours' (black 0, white 0.2 % or more; before "
                                  "the balance the edge texels were 0.5–0.8 %)",
                                  width=768)
            + rep.display_picture("energy_cube_ball_rim", heatmap(np.abs(ball_strip), 0.05),
                                  "cube 64 → mirror ball 64, every pixel with no margin, before the flux correction: "
                                  "the spot on −Z (faces +X −X +Y −Y +Z −Z) is what the ball's rim reads, its rim "
                                  "direction spread over a ring, up to 40 % off; it used to be left so, and is now "
                                  "corrected like the faint rest (≤ 1.5 %): after it every pixel is exact (black 0, "
                                  "white 5 % or more)", width=768)
            + rep.display_picture("energy_latlong_ball_rim", heatmap(np.abs(back), 0.002),
                                  "lat-long 256 → mirror ball 128 before its flux correction (what a 4k lat-long, "
                                  "too large for one, keeps), every pixel with no margin, the lat-long's ±30° round "
                                  "the ball's rim direction: its rim pixels are sampled round that direction; with "
                                  "even cells in the image this was a moiré up to 33 %; corrected, every pixel is "
                                  "exact (black 0, white 0.2 %, the bar, or more)", width=256)
            + rep.display_picture("energy_latlong_angular_rim", heatmap(np.abs(front), 0.002),
                                  "lat-long 256 → angular 128, the same way round the angular map's rim direction, "
                                  "before its flux correction: "
                                  "its pixels that the rim crosses are sampled round it; with even cells the four "
                                  "source pixels at the centre were 0.46 % over (black 0, white 0.2 % or more)",
                                  width=256)
            + rep.display_picture("energy_cube_surplus", heatmap(np.abs(surplus), 0.008),
                                  "what the balance removes: one face of a 64-texel cube, each texel's B-spline "
                                  "integral against its solid angle, whatever the target (black 0, white 0.8 %): "
                                  "the edges (the density's kink), dots along the second row (the padding copying "
                                  "the next face's nearest texel), a faint centre (−0.07 %)", width=256))


def _one_pixel_sun(grid: tuple[int, int], d: np.ndarray) -> EnvMap:
    """A latlong sky of 0.05 with a one-pixel sun holding 10× the sky's power in the pixel of direction d."""
    from .layouts import LATLONG

    sun = np.full(grid + (3,), 0.05, np.float32)
    _, x, y = LATLONG.pixel_coords(d / np.linalg.norm(d), grid)
    row, col = int(np.clip(np.rint(y), 0, grid[0] - 1)), int(np.rint(x)) % grid[1]
    sun[row, col] += 10 * 0.05 * 4 * np.pi / LATLONG.row_solid_angles(grid)[row]
    return EnvMap(sun, LATLONG)


def _polar_sun_errors() -> dict[str, float]:
    """Worst |∫L dω error| of a one-pixel sun at angles from a lat-long pole, converted to a cube."""
    errors = {}
    angles = (("first row (0.2°)", 0.2), ("2°", 2.0), ("3°", 3.0), ("5°", 5.0), ("10°", 10.0), ("20°", 20.0),
              ("45°", 45.0), ("90°", 90.0))
    for label, theta in angles:
        worst = 0.0
        for azimuth in (0.6, 2.2):
            t = np.radians(theta)
            sun = _one_pixel_sun((128, 256), np.array([np.sin(t) * np.sin(azimuth), np.cos(t),
                                                      -np.sin(t) * np.cos(azimuth)]))
            worst = max(worst, float(np.abs(sun.to("cube", 64).integral() / sun.integral() - 1).max()))
        errors[label] = worst
    return errors


def _pole_detail() -> dict[str, float]:
    """Worst |error| within 12° of the poles of a smooth field (L = 1 + ½ x, 1 ± 0.1 there) converted from lat-longs
    of several widths into a cube of 128, against the field at each texel's centre."""
    from .envmap.map import pixel_directions
    from .layouts import layout

    src, cube = layout("latlong"), layout("cube")
    errors = {}
    for label, rows in (("1612×806 (W = 4 × 403)", 806), ("1610×805 (odd height)", 805),
                        ("2000×1000 (W = 16 × 125)", 1000), ("2048×1024 (W = 2¹¹)", 1024)):
        d = pixel_directions(src, src.grid_shape(rows))
        field = EnvMap(np.repeat(1 + 0.5 * d[..., :1], 3, axis=-1).astype(np.float32), src)
        out = field.to("cube", 128)
        dt = pixel_directions(cube, out.grid)
        by_pole = np.abs(dt[..., 1]) > np.cos(np.radians(12))
        errors[label] = float(np.abs(out.data[..., 0] - (1 + 0.5 * dt[..., 0]))[by_pole].max())
    return errors


def _pole_row_targets() -> dict[str, float]:
    """|∫L dω error| of a one-pixel sun in a 128-row lat-long's first row, converted to several targets."""
    sun = _one_pixel_sun((128, 256), np.array([0.001, 1.0, 0.002]))
    targets = (("cube 64", "cube", 64), ("cube 8", "cube", 8), ("angular 32", "angular", 32),
               ("mirror ball 64", "sphere", 64), ("lat-long 64", "latlong", 64))
    return {label: float(np.abs(sun.to(name, size).integral() / sun.integral() - 1).max())
            for label, name, size in targets}


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
        from .tonemap import luminance

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


def section_exports(rep: Report) -> str:
    """The nine coefficients for every engine, written next to the report."""
    folder = rep.out / "exports"
    folder.mkdir(exist_ok=True)
    suffix = {"json": "json", "threejs": "json", "filament": "txt", "unity": "cs", "gltf": "json",
              "babylon": "json", "glsl": "glsl"}
    links = []
    for target in TARGETS:
        path = folder / f"{target}.{suffix[target]}"
        write_text(path, export(rep.sh(2), target, csharp=suffix[target] == "cs"))
        links.append(f'<li><a href="exports/{path.name}">{target}</a></li>')
    return ("<h2>Exports</h2><p>The same nine coefficients converted to each engine's frame, sign convention and "
            "scaling (each checked in the test suite with that engine's own reconstruction formula against a "
            "white furnace and an analytic point light):</p><ul>" + "".join(links) + "</ul>")


def _three_figures(page, url: str, ours_json: str) -> tuple[dict, dict]:
    """three.js's own SH of the panorama at ``url`` and its reading of our LightProbe JSON, with the figures."""
    from .engines import LUMINANCE, band1_angle, coefficient_difference, relative

    engine = np.array(page.evaluate("([u, n]) => window.lightprobe.shFromPanorama(u, n)", [url, 512])).reshape(9, 3)
    mine = np.array(page.evaluate("t => window.lightprobe.probeFromJSON(t)", ours_json)).reshape(9, 3)
    sun = mine[[3, 1, 2]].T @ LUMINANCE  # three.js: coefficients 3, 1, 2 are x, y, z
    sun /= np.linalg.norm(sun)
    e = {k: np.array(page.evaluate("([c, n]) => window.lightprobe.irradiance(c, n)",
                                   [c.reshape(-1).tolist(), [sun.tolist(), (-sun).tolist()]]))
         for k, c in (("ours", mine), ("engine", engine))}
    figures = {"coefficients": coefficient_difference(mine, engine), "angle": band1_angle(mine, engine, (3, 1, 2)),
               "toward": relative(e["ours"][0], e["engine"][0]), "away": relative(e["ours"][1], e["engine"][1])}
    return {"ours": mine, "three.js": engine, "peak": float(e["engine"][0] @ LUMINANCE)}, figures


def _babylon_figures(panorama: Path, ours_json: str) -> dict:
    """Babylon.js's own polynomial of the panorama file against ours, both through its default shader path."""
    from .engines import LUMINANCE, babylon, babylon_irradiance_over_pi, band1_angle, coefficient_difference, relative

    answer = babylon({"engine": {"panorama": str(panorama.resolve()), "size": 512}, "ours": {"export": ours_json}})
    engine, mine = (np.array(answer[k]["preScaledHarmonics"]) for k in ("engine", "ours"))
    sun = np.array(answer["engine"]["brightest"])
    return {"coefficients": coefficient_difference(mine, engine),
            "angle": band1_angle(mine, engine, (3, 1, 2), (-1, -1, 1)),
            "toward": relative(babylon_irradiance_over_pi(mine, sun), babylon_irradiance_over_pi(engine, sun)),
            "away": relative(babylon_irradiance_over_pi(mine, -sun), babylon_irradiance_over_pi(engine, -sun)),
            "sun": sun, "peak": float(babylon_irradiance_over_pi(engine, sun) @ LUMINANCE)}


def section_engines(rep: Report) -> str:
    """The exports in the engines' own code: three.js in headless Chromium draws a white sphere lit by our
    LightProbe and by the LightProbe it computes itself from the same panorama file; Babylon.js in Node computes its
    own polynomial from that file and reads ours."""
    import base64
    import json

    from .engines import Browser, Server, missing_engines
    from .envmap import read_envmap
    from .files import write_bytes

    title = "<h2>Exports in the engines themselves</h2>"
    missing = missing_engines()
    if missing:  # only a missing engine is excused; a failing one fails the report
        return title + f"<p>Not run here: it needs {html.escape(', '.join(missing))} (<code>bash setup.sh</code> " \
                       "installs them).</p>"
    folder = rep.out / "engines"
    folder.mkdir()
    latlong = rep.env if rep.env.layout.name == "latlong" else rep.env.to("latlong")
    panorama = write_image(folder / "probe.hdr", latlong.data)  # the one file both the engine and lightprobe read
    sh = project(read_envmap(panorama), 2)
    server = Server(folder)
    browser = Browser(server)
    try:
        page = browser.page("three.html")
        version = page.evaluate("window.lightprobe.version")
        lights, three = _three_figures(page, f"{server.url}/files/probe.hdr", export(sh, "threejs"))
        exposure = 0.55 / max(lights["peak"] / np.pi, 1e-9)
        pictures = []
        for back in (False, True):
            for label in ("ours", "three.js"):
                url = page.evaluate("([c, s, e, b]) => window.lightprobe.renderSphere(c, s, e, b)",
                                    [lights[label].reshape(-1).tolist(), 256, exposure, back])
                name = f"engine_three_{'ours' if label == 'ours' else 'own'}_{'back' if back else 'front'}"
                write_bytes(rep.out / f"{name}.png", base64.b64decode(url.split(",", 1)[1]))
                side = "−Z" if back else "+Z"
                lit = "our export" if label == "ours" else "its own SH"
                pictures.append(figure(name, f"three.js r{version}: {lit}, from {side}", 200))
        babylon = _babylon_figures(panorama, export(sh, "babylon"))
        page = browser.page("babylon.html")
        polynomial = json.loads(export(sh, "babylon"))["polynomial"]
        # toward the light, away from it, and the container spheres' view, all from one load of each environment
        eyes = (babylon["sun"], -babylon["sun"], CONTAINER_EYE_LIFT + 0.6 * babylon["sun"])
        views = [{"eye": eye.tolist(), "exposure": 0.5 / babylon["peak"], "roughness": None} for eye in eyes]
        shots = {"ours": page.evaluate("([p, v]) => window.lightprobe.views('polynomial', [p], v, true)",
                                       [polynomial, views[:2]]),
                 "Babylon": page.evaluate("([u, v]) => window.lightprobe.views('panorama', [u, 512], v, true)",
                                          [f"{server.url}/files/probe.hdr", views])}
        for away in (False, True):
            for label in ("ours", "Babylon"):
                name = f"engine_babylon_{'ours' if label == 'ours' else 'own'}_{'away' if away else 'toward'}"
                write_bytes(rep.out / f"{name}.png", base64.b64decode(shots[label][away].split(",", 1)[1]))
                lit = "our polynomial" if label == "ours" else "its own HDRCubeTexture"
                pictures.append(figure(name, f"Babylon.js PBR: {lit}, {'away from' if away else 'toward'} the light",
                                       200))
        containers, container_text = _babylon_containers(rep, page, server, folder, sh, babylon, shots["Babylon"][2])
        pictures += _filament_spheres(rep, browser, server, folder, sh, babylon["sun"] * np.array([1, 1, -1]))
    finally:
        browser.close()
        server.close()
    rows = [[name, f"{100 * f['coefficients']:.2f} %", f"{f['angle']:.2f}°", f"{100 * f['toward']:.2f} %",
             f"{100 * f['away']:.2f} %"] for name, f in ((f"three.js r{version} (Chromium)", three),
                                                       ("Babylon.js 9.35 (Node, default SH path)", babylon))]
    return (title + "<p>Each engine reads the probe's panorama file the way its users load it and computes its own "
            "lighting; lightprobe's export of the same file is read by the engine too. Spheres: three.js draws a "
            "white Lambertian sphere with a <code>LightProbe</code> — ours, then its own, seen from three.js's +Z and −Z; "
            "Babylon's default PBR shader draws a white diffuse sphere from our polynomial and from its own "
            "<code>HDRCubeTexture</code> of the file, seen from the light and from the opposite side. The "
            "table gives the largest coefficient difference (relative to L00), the angle between the band-1 "
            "directions, and the irradiance the engine computes toward the light and away from it (the suite "
            "requires 3 %, 3° on five probes). Babylon samples panoramas at the nearest pixel, which under-counts "
            "a small sun; three.js decodes RGBE mantissas /255, a +0.4 % of its own. Filament's web build "
            "(WebAssembly, gltfio's shader) draws the sphere from our <code>sh.txt</code>; it has no panorama → SH "
            "path of its own (that is the native cmgen), so the suite holds it to what the numbers mean: E/π "
            "toward and away from the light within 3 %.</p>"
            '<div class="grid">' + "".join(pictures) + "</div>"
            + table(["engine", "coefficients", "band-1 angle", "E toward the light", "E away"], rows)
            + container_text + '<div class="grid">' + "".join(containers) + "</div>")


CONTAINER_EYE_LIFT = np.array([0.0, 0.4, 0.0])  # the container spheres are seen from 0.6 × the light's side + this
CONTAINER_SIZE = 64  # the report's .env and .glb (as the engine tests'): Babylon's own GPU prefilter of the
# panorama, beside which the metal sphere is shown, takes ~6 s in SwiftShader at 128² and keeps the demo over a minute


def _filament_spheres(rep: Report, browser, server, folder: Path, sh, sun: np.ndarray) -> list[str]:
    """Filament's web build drawing a white rough sphere lit by our sh.txt, from the light and from the opposite
    side (Filament's web build has no panorama → SH path of its own: that is its native cmgen)."""
    import base64

    from .engines import white_sphere_glb
    from .export import filament_coefficients

    white_sphere_glb(folder / "sphere.glb")
    page = browser.page("filament.html")
    page.evaluate("u => window.lightprobe.setup(u)", f"{server.url}/files/sphere.glb")
    coefficients = filament_coefficients(sh)
    peak = float(sh.to_irradiance().evaluate(sun[None])[0].max() / np.pi)
    pictures = []
    for away in (False, True):
        eye = (-sun if away else sun).tolist()
        canvas = page.evaluate("([s, e]) => window.lightprobe.render(s, e)",
                               [(0.8 / peak * coefficients).reshape(-1).tolist(), eye])
        rgba = np.frombuffer(base64.b64decode(canvas), np.uint8).reshape(128, 128, 4)[::-1]
        linear = rgba[..., :3].astype(np.float32) / 255  # Filament's output without post-processing is linear
        name = f"engine_filament_ours_{'away' if away else 'toward'}"
        write_image(rep.out / f"{name}.png", linear)  # sRGB-encoded for display, as every picture of the report
        pictures.append(figure(name, f"Filament 1.53: our sh.txt, {'away from' if away else 'toward'} the light", 200))
    return pictures


def _babylon_containers(rep: Report, page, server, folder: Path, sh, babylon: dict,
                        own_diffuse: str) -> tuple[list[str], str]:
    """Our .env and .glb of the probe in Babylon: a white metal sphere (roughness 0.3) from our .env's mips beside
    one from Babylon's own GPU prefilter of the panorama, and the diffuse sphere from our .glb through its glTF
    loader beside ``own_diffuse``, the one from its own HDRCubeTexture (a PNG data URL, drawn with the section's
    other views of that texture)."""
    import base64
    import io
    import warnings

    from PIL import Image

    from .containers import babylon_env, glb, gltf_ibl
    from .envmap import read_envmap
    from .files import write_bytes
    from .prefilter import prefilter_cube
    from .tonemap import srgb_decode

    env = read_envmap(folder / "probe.hdr")
    with warnings.catch_warnings():  # the sun's RGBD clipping is said in the text below
        warnings.simplefilter("ignore")
        env_bytes = babylon_env(env, sh, CONTAINER_SIZE)
        glb_bytes = glb(*gltf_ibl(env, sh, CONTAINER_SIZE))
    exports = rep.out / "exports"
    exports.mkdir(exist_ok=True)
    for name, data in (("probe.env", env_bytes), ("probe.glb", glb_bytes)):
        write_bytes(exports / name, data)
        write_bytes(folder / name, data)
    url = f"{server.url}/files/"
    peak = float(prefilter_cube(env, 32, [0] + [0.09] * 5).levels[1].max())
    eye = (CONTAINER_EYE_LIFT + 0.6 * babylon["sun"]).tolist()
    shots, pictures, images = [
        ("engine_babylon_env_metal", "env", [url + "probe.env"], 0.3, "our .env, metal roughness 0.3"),
        ("engine_babylon_own_metal", "prefiltered", [url + "probe.hdr", CONTAINER_SIZE], 0.3,
         "its own prefilter, metal roughness 0.3"),
        ("engine_babylon_glb_diffuse", "gltf", [url + "probe.glb"], None, "our .glb through its glTF loader"),
        ("engine_babylon_own_diffuse", None, None, None, "its own HDRCubeTexture")], [], {}
    for name, source, args, roughness, caption in shots:
        exposure = 0.6 / peak if roughness is not None else 0.5 / babylon["peak"]
        call = "([s, a, e, x, r]) => window.lightprobe.sphere(s, a, e, x, r, true)"
        data_url = own_diffuse if source is None else page.evaluate(call, [source, args, eye, exposure, roughness])
        png = base64.b64decode(data_url.split(",", 1)[1])
        write_bytes(rep.out / f"{name}.png", png)
        pictures.append(figure(name, f"Babylon.js PBR: {caption}", 200))
        images[name] = srgb_decode(np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), np.float32) / 255).mean(-1)

    def difference(a, b):
        inside = images[b] > 0
        return float(np.abs(images[a] - images[b])[inside].mean() / images[b][inside].mean())

    text = (f"<p>The environment itself in Babylon's containers (<a href=\"exports/probe.env\">probe.env</a>, "
            f"<a href=\"exports/probe.glb\">probe.glb</a>, {CONTAINER_SIZE}² GGX-prefiltered mips in RGBD beside the "
            "SH): Babylon loads each the way its users do. Metal sphere from our mips against Babylon's own GPU "
            f"prefilter of the panorama: mean |Δ| {100 * difference('engine_babylon_env_metal', 'engine_babylon_own_metal'):.1f} %"
            " of the mean; diffuse sphere through its glTF loader against its own panorama: "
            f"{100 * difference('engine_babylon_glb_diffuse', 'engine_babylon_own_diffuse'):.1f} %. RGBD stops at 255, "
            "so the sharpest mips clip the sun (the blurrier mips and the SH keep it).</p>")
    return pictures, text


def _shared_data() -> Path:
    """The test-data folder beside the repository (``LIGHTPROBE_SHARED_DATA`` overrides it); it may be absent, and
    its Stanford meshes may not be shipped, so sections use it when it is there and fall back when it is not."""
    return Path(os.environ.get("LIGHTPROBE_SHARED_DATA", Path(__file__).resolve().parents[3] / "shared" / "data"))


def _demo_scene(rep: Report):
    """The bunny on a ground plane if ../shared/data is beside the project (Stanford data may not be shipped),
    else the built-in sphere-and-torus scene; the environment turned so the sun is behind the camera's left."""
    from .render.scene import builtin_scene, mesh_scene

    bunny = _shared_data() / "meshes" / "stanford" / "bun_zipper.ply"
    if bunny.is_file():
        return mesh_scene(bunny, rep.env, 192, 192), "the Stanford bunny (69k triangles) on a grey ground plane"
    return builtin_scene(rep.env, 192, 192), "the built-in sphere and torus (the bunny lives in ../shared/data)"


def section_render(rep: Report) -> str:
    """Every lighting method against Mitsuba's ground truth on a real mesh: SH and brute force (no shadows), the
    area lights with soft shadows (with and without shadowed ambient) and median cut with as many point lights."""
    from .render.compare import compare, error_heatmap
    from .render.methods import method
    from .render.raycast import Tracer
    from .render.renderer import render

    scene, what = _demo_scene(rep)
    tracer = Tracer(scene)
    from .render.reference import mitsuba, reference_render

    try:
        mitsuba()
    except LightprobeError as e:  # only a missing Mitsuba (or a variant that does not start) is tolerated
        return (f"<h2>Rendering against ground truth</h2><p>The Mitsuba reference is not available "
                f"({html.escape(str(e))}); install it with <code>pip install 'lightprobe[reference]'</code>.</p>")
    lights = method("lights", light_samples=16)
    t0 = time.perf_counter()
    found = len(lights.decomposition(scene).lights)
    rep.timings["area lights of the turned probe"] = time.perf_counter() - t0
    count = max(found, 1)  # the baseline gets as many point lights as the area lights found
    methods = {"sh": (method("sh"), 2), "brute": (method("brute"), 1), "lights": (lights, 1),
               "lights --ao": (method("lights", light_samples=16, ao=True, ao_samples=16), 1),
               "mediancut": (method("mediancut", count=count), 2)}
    results = {name: render(scene, m, spp, tracer) for name, (m, spp) in methods.items()}
    results["reference"] = reference_render(scene, spp=256)
    for label, r in results.items():
        rep.timings[f"render 192² {label}"] = sum(r.seconds.values())
    ref = results["reference"].image
    exposure = auto_exposure(ref) + 0.5
    figures = [rep.picture(f"render_{n.replace(' --', '_')}", r.image, f"{n}: {r.method}", exposure, width=256)
               for n, r in results.items()]
    compared = [n for n in results if n != "reference"]
    heat = [rep.display_picture(f"render_{n.replace(' --', '_')}_error", error_heatmap(results[n].image, ref, 0.5),
                                f"{n} vs reference: relative error, black 0 → white ≥ 50 %", width=256)
            for n in compared]
    rows = []
    for n in compared:
        m = compare(results[n].image, ref)
        rows.append([n, results[n].method, f"{m.relative_mse:.4f}", f"{m.mare:.3f}", f"{m.flip:.3f}",
                     f"{1000 * rep.timings[f'render 192² {n}']:.0f} ms"])
    rows.append(["reference", results["reference"].method, "—", "—", "—",
                 f"{1000 * rep.timings['render 192² reference']:.0f} ms"])
    return ("<h2>Rendering against ground truth</h2>"
            f"<p>{html.escape(what)} under the probe, rendered by lightprobe's renderer (Embree rays) and "
            "path-traced by Mitsuba 3 (direct lighting, the papers' assumption) as the ground truth. "
            "<strong>SH9 and brute-force irradiance have no shadows:</strong> both light every normal with the whole "
            "environment, so the bunny casts no shadow and its underside is lit by the ground below the horizon, "
            "which the ground plane hides in reality. <em>lights</em> is the paper's answer: the ambient as SH "
            f"irradiance plus the {found} area light(s) found in the turned probe, each sampled over its disc with "
            "16 stratified shadow rays (soft penumbrae). Its ambient is still unshadowed — the paper's own "
            "weakness — so <em>lights --ao</em> weights the ambient by brightness-weighted occlusion rays. "
            f"<em>mediancut</em> is what users do today: {count} point light{'s' if count > 1 else ''} carrying "
            "the whole map, hard shadows (as many as the area lights found).</p>"
            '<div class="grid">' + "".join(figures) + "</div>" + '<div class="grid">' + "".join(heat) + "</div>"
            + table(["method", "what", "relative MSE", "MARE", "HDR-FLIP", "time"], rows))


def section_lights(rep: Report) -> str:
    """The probe as area lights plus an ambient remainder (Arbree, Walter & Bala 2005): what was found, and the
    energy bookkeeping."""
    from .lights import decompose, preview
    from .tonemap import luminance

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


GLOSSY_DEMO = ("ggx:alpha=0.3,conductor=gold", "plastic:alpha=0.2,albedo=0.6/0.08/0.05")  # gold, a red plastic


def _contact_sheet(maps, columns: int = 6) -> np.ndarray:
    """Maps (square, same size) tiled in rows of ``columns`` with a 2-texel gap."""
    size = maps[0].data.shape[0]
    rows = -(-len(maps) // columns)
    sheet = np.zeros((rows * (size + 2), columns * (size + 2), 3), np.float32)
    for i, m in enumerate(maps):
        r, c = divmod(i, columns)
        sheet[r * (size + 2):r * (size + 2) + size, c * (size + 2):c * (size + 2) + size] = m.data
    return sheet


def section_glossy(rep: Report) -> str:
    """Glossy reflection (Cabral, Olano & Nemec 1999): the 12 source radiance maps, a synthesised map beside the
    map computed directly, and a glossy sphere by RS-IBR (per frame and per pixel), the split sum and Mitsuba."""
    from .brdf import parse_brdf
    from .radiance import geodesic_views, prepare, radiance_map
    from .radiancefile import radiance_set
    from .render.compare import compare, error_heatmap
    from .render.methods import method
    from .render.raycast import Tracer
    from .render.reference import mitsuba, reference_render
    from .render.renderer import render
    from .rsibr import synthesize

    t0 = time.perf_counter()
    lighting = prepare(rep.env)
    gold = parse_brdf(GLOSSY_DEMO[0])
    rset = radiance_set(lighting, gold, *geodesic_views(12), 40)
    maps = rset.maps
    rep.timings["12 radiance maps 40² (gold)"] = time.perf_counter() - t0
    new_view = np.array([0.35, 0.45, 0.82]) / np.linalg.norm([0.35, 0.45, 0.82])
    t0 = time.perf_counter()
    synthesised = synthesize(rset, new_view)
    rep.timings["synthesis of one map 40²"] = time.perf_counter() - t0
    paper = synthesize(rset, new_view, smooth=False)
    direct = radiance_map(lighting, gold, new_view, 40)
    disc = direct.valid_mask()
    rel_rmse, rel_rmse_paper = (float(np.sqrt(np.mean((m.data[disc] - direct.data[disc]) ** 2)
                                              / np.mean(direct.data[disc] ** 2))) for m in (synthesised, paper))
    exposure = auto_exposure(direct.data[disc])
    html_maps = (rep.picture("glossy_sources", _contact_sheet(maps), "the 12 source maps (icosahedron views) of "
                             "GGX gold α = 0.3, 40² each", exposure)
                 + '<div class="grid">'
                 + rep.picture("glossy_synthesised", synthesised.data, "synthesised for a new view", exposure,
                               width=192)
                 + rep.picture("glossy_direct", direct.data, "computed directly for that view", exposure, width=192)
                 + rep.display_picture("glossy_synthesis_error", error_heatmap(synthesised.data, direct.data, 0.25),
                                       "relative error, black 0 → white ≥ 25 %", width=192)
                 + rep.display_picture("glossy_synthesis_error_paper", error_heatmap(paper.data, direct.data, 0.25),
                                       "the paper's synthesis (smooth part warped too): its error", width=192)
                 + "</div>")
    try:
        mitsuba()
    except LightprobeError as e:
        return (f"<h2>Glossy reflection (Cabral, Olano &amp; Nemec 1999)</h2>{html_maps}<p>The Mitsuba reference "
                f"is not available ({html.escape(str(e))}).</p>")
    rows, pictures = [], []
    objects = _glossy_objects(rep)
    # one set of methods for every object: each caches its bake per environment and BRDF, so a material's radiance
    # maps and prefiltered cube are made once, not once per object
    rsibr = method("rsibr", map_size=32)
    shared = {"rsibr": rsibr, "rsibr --per-pixel-view": method("rsibr", map_size=32, per_pixel_view=True),
              "splitsum": method("splitsum", cube_size=32)}
    shared["rsibr --per-pixel-view"].radiance_set = rsibr.radiance_set  # one bake for both
    for (obj, base), spec in ((o, spec) for o in objects for spec in GLOSSY_DEMO):
        mesh = base.meshes[0]
        scene = replace(base, meshes=(replace(mesh, material=replace(mesh.material, brdf=parse_brdf(spec))),))
        tracer = Tracer(scene)
        # the split sum is GGX's (engines add a separate diffuse term for a plastic)
        methods = {name: m for name, m in shared.items() if name != "splitsum" or spec.startswith("ggx")}
        results = {name: render(scene, m, 2, tracer) for name, m in methods.items()}
        results["reference"] = reference_render(scene, spp=96)
        ref = results["reference"].image
        shown = auto_exposure(ref) + 0.5
        tag = obj + "_" + (spec.split(":")[0] if spec.startswith("plastic") else spec.split(",")[-1].replace("=", ""))
        for name, r in results.items():
            pictures.append(rep.picture(f"glossy_{tag}_{name.replace(' --', '_')}", r.image,
                                        f"{obj}, {spec}: {name}", shown, width=160))
        for name in methods:
            m = compare(results[name].image, ref)
            rows.append([obj, spec, name, f"{m.relative_mse:.4f}", f"{m.flip:.3f}",
                         f"{1000 * sum(results[name].seconds.values()):.0f} ms"])
        pictures.append(rep.display_picture(f"glossy_{tag}_error", error_heatmap(results["rsibr --per-pixel-view"]
                                                                                 .image, ref, 0.5),
                                            f"{obj}, {spec}: rsibr --per-pixel-view vs reference (black 0 → white "
                                            "≥ 50 %)", width=160))
    return ("<h2>Glossy reflection (Cabral, Olano &amp; Nemec 1999)</h2>"
            "<p>Radiance environment maps hold, for one view, the light every surface normal sends toward the eye "
            "through a BRDF; lightprobe computes them exactly (a compiled sum over a pyramid level fine enough for "
            f"the lobe, the sun's texels as point sources: 12 maps in {rep.timings['12 radiance maps 40² (gold)']:.1f}"
            " s) and synthesises any other view from the three around it by the paper's warp and spherical "
            "barycentric blend — beyond the paper, the smooth part of the new view's map (the probe at 16² faces) "
            "summed exactly and only the finer detail warped, since the warp's error is where the surface's "
            f"horizon cuts the lobe ({1000 * rep.timings['synthesis of one map 40²']:.0f} ms; relative RMSE "
            f"{100 * rel_rmse:.1f} % against the direct map for this view, {100 * rel_rmse_paper:.1f} % by the "
            "paper's synthesis alone).</p>" + html_maps
            + f"<p>{_glossy_caption(objects)} of each material under the probe: <em>rsibr</em> one "
            "synthesised map per frame (the paper's orthographic approximation), <em>rsibr --per-pixel-view</em> "
            "each pixel blended for its own view, <em>splitsum</em> the prefiltered-map approximation engines "
            "ship (for GGX), and Mitsuba 3's roughconductor and roughplastic as the reference. None of the methods "
            "knows of the mesh's own occlusion (the teapot's spout and handle, the bunny's ears: the reference's "
            "shadows and interreflections there are what they miss); on the sphere there is none.</p>"
            '<div class="grid">' + "".join(pictures) + "</div>"
            + table(["object", "material", "method", "relative MSE", "HDR-FLIP", "time"], rows))


def _glossy_objects(rep: Report) -> list:
    """(name, scene) of the glossy renders, 64² and without ground: a sphere (no self-occlusion), and the Newell
    teapot and the Stanford bunny when ../shared/data is beside the project (neither is shipped)."""
    from .render.scene import mesh_scene, sphere_scene

    objects = [("sphere", sphere_scene(rep.env, 64))]
    meshes = _shared_data() / "meshes"
    for name, path in (("teapot", meshes / "teapot" / "teapot.obj"),
                       ("bunny", meshes / "stanford" / "bun_zipper_res2.ply")):
        if path.is_file():
            objects.append((name, mesh_scene(path, rep.env, 64, 64, ground=False, turn_to_key_light=False)))
    return objects


def _glossy_caption(objects: list) -> str:
    names = [name for name, _ in objects]
    found = "A sphere" if len(names) == 1 else "A sphere, " + " and ".join(f"the {n}" for n in names[1:])
    return found + ("" if len(names) > 1 else " (the teapot and the bunny live in ../shared/data)")


VIEWER_STATES = [  # (file name, caption, page state): what the viewer section shows, each taken from the live page
    ("viewer-sh", "eq. 13 per pixel (Ramamoorthi & Hanrahan)", {"method": "sh"}),
    ("viewer-sh-vertex", "eq. 13 per vertex, the paper's hardware path", {"method": "sh-vertex"}),
    ("viewer-threejs", "three.js's own LightProbe fed the threejs export", {"method": "threejs"}),
    ("viewer-lights", "area lights with PCSS soft shadows + ambient SH (Arbree et al.)", {"method": "lights"}),
    ("viewer-rsibr", "RS-IBR: one map per frame synthesised on the GPU, gold GGX α 0.3", {"method": "rsibr"}),
    ("viewer-rsibr-pixel", "RS-IBR, each pixel's own view", {"method": "rsibr-pixel"}),
    ("viewer-splitsum", "split sum, gold GGX α 0.3", {"method": "splitsum"}),
    ("viewer-basis", "the basis function Y10 on the objects", {"method": "basis", "basis": 2}),
    ("viewer-design", "lighting design: L1−1 ×3 and L11 ×−1 (the sliders), the environment turned 120°",
     {"method": "sh", "design": [1, 3, 1, -1, 1, 1, 1, 1, 1], "rotation": 120}),
]


def _viewer_bake(rep: Report) -> dict:
    """The viewer's bake of the probe (SH, lights, 12 radiance maps, split sum: compiled kernels) exported as a static
    site into ``viewer/`` beside the report; returns the bake's document."""
    import tempfile

    from .viewer.bake import BakeOptions, bake
    from .viewer.server import export_static

    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(dir=rep.out) as temp:
        doc = bake(rep.env, Path(temp) / "bake", None, BakeOptions(brdfs=(GLOSSY_DEMO[0],), map_size=32),
                   source=rep.probe_name)
        export_static(Path(temp) / "bake", rep.out / "viewer")
    rep.timings["viewer bake (SH, lights, 12 radiance maps 32², split sum) and static export"] = \
        time.perf_counter() - t0
    return doc


def _viewer_shots(rep: Report) -> tuple[list[str], list[list]]:
    """A screenshot of each of VIEWER_STATES from the exported site in headless Chromium, and its frame time: the
    figures and the table rows. Chromium and file serving only, no compiled kernel, so it may run in a thread of its
    own."""
    from .viewer.page import ViewerPage

    t0 = time.perf_counter()
    figures, rows = [], []
    with ViewerPage(site=rep.out / "viewer", width=600, height=330) as page:
        exposure = round(rep.exposure, 1)
        for name, caption, state in VIEWER_STATES:
            full = {"brdf": 0, "rotation": 0, "design": [1] * 9, "exposure": exposure, **state}
            shot = page.page.locator("#view") if name != "viewer-sh" else page.page
            page.page.evaluate("(s) => window.lightprobe.setState(s)", full)
            shot.screenshot(path=str(rep.out / f"{name}.png"))
            ms = page.page.evaluate("window.lightprobe.viewer.frameMs")
            rows.append([caption, f"{ms:.0f} ms"])
            figures.append(figure(name, caption))
        errors = [e for e in page.errors if "404" not in e]
    if errors:
        raise LightprobeError(f"the viewer's page reported an error: {errors[0].splitlines()[0]}")
    rep.timings["viewer screenshots (headless Chromium, SwiftShader)"] = time.perf_counter() - t0
    return figures, rows


def _viewer_started(rep: Report, beside) -> tuple:
    """The viewer's bake here, then its screenshots submitted to the executor ``beside``: (the bake's document, the
    screenshots' future)."""
    doc = _viewer_bake(rep)
    return doc, beside.submit(_viewer_shots, rep)


def section_viewer(rep: Report, started: tuple | None = None) -> str:
    """``lightprobe view``: the bake exported as a static folder beside the report, opened through a plain static
    server in headless Chromium, and a screenshot of each method and control state taken from the live page.
    ``started``: :func:`_viewer_started`'s (bake, screenshots under way), when the report took them beside the
    engines section."""
    from .engines import missing_engines

    title = "<h2>The viewer: <code>lightprobe view</code></h2>"
    missing = missing_engines()
    if missing:
        return title + f"<p>Not run here: it needs {html.escape(', '.join(missing))} (<code>bash setup.sh</code>).</p>"
    doc, shots = started if started is not None else (_viewer_bake(rep), None)
    figures, rows = shots.result() if shots is not None else _viewer_shots(rep)
    return (title + "<p>The page (WebGL2; three.js from npm for the scene and the loop, lightprobe's own shaders "
            "for the lighting) with the bake of this probe — "
            f"{doc['lights']['count']} area lights, 12 radiance maps of {html.escape(doc['brdfs'][0]['spec'])} — "
            "exported by "
            "<code>lightprobe view --export</code> into <code>viewer/</code> beside this report. Module scripts "
            "need HTTP: serve it with <code>python3 -m http.server -d viewer</code> and open the address it prints. "
            "Each picture below is that exported page, served by a plain static server and drawn by headless "
            "Chromium's SwiftShader (a software rasteriser: the frame times are a floor, a GPU is far faster"
            + ("; taken while the engines section drove its own Chromium beside it" if started is not None else "")
            + "). The first shows the whole page with its controls; the tests read the same page's float render "
            "targets back and compare them with the Python renderer, three.js and "
            "<code>lightprobe radiance --synthesize</code>.</p>"
            + "".join(figures) + table(["state", "frame (300×330 canvas)"], rows))


def _demo_probes(rep: Report, folder: Path) -> tuple[list[str], str]:
    """Every probe file of ../shared/data beside the repository, or (without it) the shipped probe and seven
    rotated copies of it written into ``folder``."""
    shared = _shared_data()
    found = sorted(str(p) for sub in ("debevec", "ict_lowres", "polyhaven_1k") for p in (shared / sub).rglob("*")
                   if p.suffix.lower() in (".hdr", ".exr") and p.is_file())
    if found:
        return found, f"every probe in {shared} ({len(found)} files)"
    paths = []
    for k in range(8):
        path = folder / f"shipped_turned_{45 * k:03d}.exr"
        (rep.env if k == 0 else rep.env.rotated((45.0 * k, 0.0, 0.0))).save(path)
        paths.append(str(path))
    return paths, "the shipped probe and seven copies turned by 45° steps (../shared/data is not here)"


def section_batch(rep: Report) -> str:
    """``lightprobe batch`` over the test probes: SH and a thumbnail each, on a local pool of the machine's cores,
    into ``batch/`` beside the report (results.parquet, errors.parquet, report.html)."""
    import tempfile

    from .batch.report import write_report
    from .batch.runner import LocalPool, run_batch
    from .batch.task import JobOptions

    with tempfile.TemporaryDirectory(dir=rep.out) as temp:
        inputs, what = _demo_probes(rep, Path(temp))
        pool = LocalPool(os.cpu_count() or 1)
        summary = run_batch(inputs, rep.out / "batch", JobOptions(jobs=("sh", "thumbnail"), order=2), pool)
    write_report(rep.out / "batch")
    sheet = _thumbnail_sheet(rep.out / "batch")
    rep.timings[f"batch of {len(inputs)} probes (SH + thumbnail, {summary.workers} workers)"] = summary.seconds
    rows = [["inputs", what], ["done / failed", f"{summary.done} / {summary.failed}"],
            ["throughput", f"{summary.throughput:.2f} maps/s on {summary.workers} worker processes "
                           f"(start-up included)"],
            ["peak memory per worker", f"{summary.peak_rss / 2**20:.0f} MiB"]]
    return ("<h2>Dataset scale: <code>lightprobe batch</code></h2><p>The same API calls as the single-file "
            "commands, one row per input in <a href='batch/results.parquet'>batch/results.parquet</a> (pandas, "
            "polars and DuckDB read it directly), failures in <code>batch/errors.parquet</code>, committed in chunks "
            "so a killed run resumes with <code>--resume</code>; the batch's own page is "
            "<a href='batch/report.html'>batch/report.html</a>.</p>" + table(["", ""], rows)
            + rep.display_picture("batch_thumbnails", sheet, "the batch's thumbnails (tone-mapped latlong "
                                  "128×64 each, as the workers wrote them), in path order"))


def _thumbnail_sheet(folder: Path, columns: int = 6) -> np.ndarray:
    """The batch's thumbnail PNGs (display-encoded, all 128×64) tiled in path order with a 2-pixel gap."""
    import pyarrow.parquet as pq
    from PIL import Image

    rows = [r for r in pq.read_table(folder / "results.parquet", columns=["thumbnail"]).to_pylist() if r["thumbnail"]]
    tiles = [np.asarray(Image.open(folder / r["thumbnail"]).convert("RGB"), dtype=np.float32) / 255 for r in rows]
    h, w = tiles[0].shape[:2]
    sheet = np.ones((-(-len(tiles) // columns) * (h + 2), columns * (w + 2), 3), np.float32)
    for i, tile in enumerate(tiles):
        r, c = divmod(i, columns)
        sheet[r * (h + 2):r * (h + 2) + h, c * (w + 2):c * (w + 2) + w] = tile
    return sheet


SECTIONS = [section_probe, section_layouts, section_speed, section_sh, section_irradiance, section_errors,
            section_lights, section_design, section_exports, section_engines, section_render, section_glossy,
            section_viewer, section_batch]

_STYLE = """body{font:15px/1.45 system-ui,sans-serif;max-width:1100px;margin:2em auto;padding:0 1em;color:#222}
h1{font-size:1.6em}h2{margin-top:2em;border-bottom:1px solid #ccc}table{border-collapse:collapse;margin:1em 0}
td,th{border:1px solid #ccc;padding:3px 8px;text-align:right;font-variant-numeric:tabular-nums}
td:first-child,th:first-child{text-align:left}figure{display:inline-block;margin:0 1em 1em 0;vertical-align:top}
figure img{max-width:100%;max-height:300px}.grid figure img{max-height:220px}figcaption{font-size:.85em;color:#555}
"""


MARKER = ".lightprobe-report"  # the file that makes a folder a previous report, safe to replace


def _sections_html(rep: Report) -> str:
    """Every section of SECTIONS, in order. The viewer's screenshots are taken in a thread while the engines section
    runs: both mostly wait on their own headless Chromium (~0.7 of a core each), and the screenshots run no compiled
    kernel (the viewer's bake runs first, in this thread). Nothing the speed section times runs meanwhile."""
    from concurrent.futures import ThreadPoolExecutor

    from .engines import missing_engines

    parts, viewer = [], None
    with ThreadPoolExecutor(1) as beside:
        for section in track(SECTIONS, "writing the report", total=len(SECTIONS)):
            if section is section_engines and section_viewer in SECTIONS and not missing_engines():
                viewer = _viewer_started(rep, beside)
            parts.append(section_viewer(rep, viewer) if section is section_viewer else section(rep))
    return "".join(parts)


def warm_up() -> float:
    """Run every compiled kernel the report uses once on tiny inputs (:func:`lightprobe.warmup.compile_kernels`), so
    the sections' timings are warm; returns the seconds it took (compilation, or loading the kernels from numba's
    cache, which ``setup.sh`` fills)."""
    from .warmup import compile_kernels

    return compile_kernels()


def check_report_folder(out: Path, force: bool = False) -> None:
    """Refuse an ``out`` that is a file, or a non-empty folder that is not a previous report (unless ``force``)."""
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise InputError(f"cannot write the report into {out}: it is a file, not a folder")
    if out.is_dir() and not force and not (out / MARKER).exists() and any(out.iterdir()):
        raise InputError(f"refusing to write the report into {out}: the folder holds files that are not a "
                         "lightprobe report (choose another --out, or --force to replace the folder)")
    parent = out.parent if str(out.parent) else Path(".")
    if not parent.is_dir():
        raise InputError(f"cannot write the report into {out}: folder {parent} does not exist")


def _move_into_place(built: Path, out: Path) -> None:
    """Put the finished folder ``built`` at ``out``; an old ``out`` is moved aside first and removed last."""
    old = None
    if out.exists():
        old = out.with_name(f".{out.name}.lp{os.getpid()}-{secrets.token_hex(4)}.tmp")
        os.replace(out, old)
    try:
        os.replace(built, out)
    except OSError:
        if old is not None:
            os.replace(old, out)
        raise
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def run_demo(env: EnvMap, out: Path, probe_name: str | None = None, force: bool = False) -> Path:
    """Write the report for ``env`` into folder ``out`` (see the module docstring); returns the path of index.html."""
    out = Path(out)
    check_report_folder(out, force)
    parent = out.parent if str(out.parent) else Path(".")
    sweep_stale_temporaries(parent)
    building = parent / f".{out.name}.lp{os.getpid()}-{secrets.token_hex(4)}.tmp"
    building.mkdir()
    try:
        (building / MARKER).write_text("a lightprobe demo report; lightprobe demo may replace this folder\n")
        _write_report(env, building, probe_name)
        _move_into_place(building, out)
    finally:
        with contextlib.suppress(OSError):
            shutil.rmtree(building)
    return out / "index.html"


def _write_report(env: EnvMap, out: Path, probe_name: str | None) -> None:
    rep = Report(env, out, probe_name or "the shipped probe: Poly Haven “Rooitou Park” (CC0), 512×256 latlong",
                 exposure=auto_exposure(env.data, env.solid_angles()))
    t0 = time.perf_counter()
    compile_seconds = warm_up()
    body = _sections_html(rep)
    rows = [["compiling the numba kernels, or loading them from numba's cache (setup.sh compiles them)",
             f"{1000 * compile_seconds:.1f} ms"]]
    rows += [[k, f"{1000 * v:.1f} ms"] for k, v in rep.timings.items()]
    page = (f"<!doctype html><html><head><meta charset='utf-8'><title>lightprobe report</title>"
            f"<style>{_STYLE}</style></head><body><h1>lightprobe report</h1>{body}"
            f"<h2>Timings</h2><p>Each step timed warm, after the kernels were compiled.</p>"
            f"{table(['step', 'time'], rows)}"
            f"<p><small>Made in {time.perf_counter() - t0:.1f} s.</small></p></body></html>")
    write_text(out / "index.html", page)
