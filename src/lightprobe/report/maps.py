"""Report sections on maps: the probe, every layout, and the resampler's speed, energy and memory."""

from __future__ import annotations

import functools
import html
import time

import numpy as np

from ..maps import EnvMap, to_image
from ..maps.images import write_image
from ..maps.layouts import LAYOUTS
from ..maps.tonemap import heatmap
from ..sh.basis import project
from .page import HARNESS, Report, table


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
        size = 128 if lay_name in ("cube", "cross", "hcross") else 256  # a face edge, or the image's height
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

    from ..maps import Resampler, resample
    from ..maps.layouts import CUBE, LATLONG

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
             f"not measured (it needs {HARNESS})" if memory is None else f"{memory:.0f} MiB",
             "most of it the libraries (numpy, OpenImageIO, numba's LLVM); its kernels linked "
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


def _convert_peak_memory(env, folder) -> float | None:
    """Peak resident memory (MiB) of ``lightprobe convert`` of ``env`` into a cube in a fresh process, measured by
    the development harness (``lightprobe_engines.peak``); None where it is not installed."""
    import sys

    try:
        from lightprobe_engines.peak import run_measured
    except ImportError:
        return None

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
    from ..maps import Resampler
    from ..maps.frames import rotation_from_ypr
    from ..maps.layouts import layout

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
    from ..maps import Resampler
    from ..maps.layouts import layout

    src = layout("latlong")
    return Resampler(src, src.grid_shape(256), layout(target), 128).without_flux_correction().energy_gains()


def _gain_pictures(rep: Report) -> str:
    """Heat maps of |gain| over the source's pixels: a mirror ball into an angular map at one rate for the whole
    map (as before) and at each pixel's own, a cube into a lat-long (what is left), and what a cube's texel balance
    removes."""
    from ..maps import Resampler
    from ..maps.envmap import pixel_solid_angles
    from ..maps.layouts import layout
    from ..maps.resampling import balance
    from ..maps.resampling.resampler import supersampling

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
    from ..maps.layouts import LATLONG

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
    from ..maps.envmap import pixel_directions
    from ..maps.layouts import layout

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
