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

    from ..maps import resample
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
    out = np.empty_like(big.data)
    best("pass", lambda: np.multiply(big.data, 1.0, out=out), repeat=5)
    for l_max in (2, 8, 16):
        project(big, l_max, compiled=True)
        best(f"sh{l_max}", lambda: project(big, l_max, compiled=True), repeat=3)
    # the memory figure's convert runs in its own process beside the accuracy figures below (its peak is its own;
    # nothing timed runs meanwhile)
    with ThreadPoolExecutor(1) as beside:
        memory = beside.submit(_convert_peak_memory, big, rep.out)
        sun_map = _one_pixel_sun(big.grid, np.ones(3) / np.sqrt(3))  # on a cube corner
        sun_error = float(np.abs(resample(sun_map, CUBE, 512).integral() / sun_map.integral() - 1).max())
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
            "<code>benchmarks/bench_peers.py</code>; a batch of maps of one size converts with cached footprint "
            "weights, a <code>Resampler</code>, one gather per map, in the same benchmark). "
            "Accuracy at that speed: a sun in one pixel on a cube corner, holding "
            f"10× the sky's power, keeps ∫L dω to {100 * sun_error:.3f} % (plain nearest-pixel and bilinear "
            "converters lose or double it: 46–60 % in the benchmark).</p>"
            + table(["work", "time", "ratio"], rows)
            + "<p>Near a lat-long pole one target pixel spans many source columns; those rows are read from their "
              "reductions in azimuth (exact averages of 2<sup>ℓ</sup> columns, or of the overlapped columns where "
              "the width stops halving), so no column is skipped. A one-pixel sun at each angle from the pole "
              "(256×128 → cube 64, worst of two azimuths), ∫L dω error:</p>"
            + table(["from the pole", *polar], [["error", *(f"{100 * e:.3f} %" for e in polar.values())]])
            + "<p>A smooth field L = 1 + ½ x (1 ± 0.1 within 12° of a pole) into a cube of 128: worst |error| "
              "within 12° of the poles:</p>"
            + table(["source", *pole_detail], [["error", *(f"{e:.4f}" for e in pole_detail.values())]])
            + "<p>Near the poles the reconstruction's weights are rational, so every source row keeps its solid "
              "angle; a target pixel over the pole reads the rows its subsamples crowd as their whole row's mean. "
              "A sun in the first row, into:</p>"
            + table(["target", *pole_rows], [["error", *(f"{100 * e:.3f} %" for e in pole_rows.values())]])
            + "<p>Every source pixel as the sun, exactly: the conversion is linear, so the energy a sun in pixel "
              "s comes out with is its column of the weights times the target's solid angles "
              "(<code>Resampler.energy_gains</code>). Pixels within 25° of a disc's rim direction are left out "
              "unless the row says no margin. Cube sources are read through their texel balance (each texel's "
              "reconstruction carries exactly its solid angle), and what a target's quadrature still loses is "
              "corrected per pair of grids by a flux pre-filter (docs: <em>resampling</em>; "
              "<code>benchmarks/bench_energy.py</code> has the full table).</p>"
            + table(["conversion", "worst", "pixels over 0.2 %"],
                    [[label, f"{100 * worst:.3f} %", f"{100 * share:.1f} %"]
                     for label, (worst, share) in every_pixel.items()])
            + '<div class="grid">' + gain_pictures + "</div>")


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
             ("angular 128 → lat-long 64", "angular", 128, "latlong", 64),
             ("mirror ball 128 → angular 64", "sphere", 128, "angular", 64),
             ("lat-long 128 → mirror ball 32", "latlong", 128, "sphere", 32),
             ("lat-long 256×128 → lat-long 39, turned (yaw 104°, pitch 133°, roll −39°), no margin", "latlong", 128,
              "latlong", 39, None, {"turn": (104, 133, -39)}),
             ("cube 64 → cube 64", "cube", 64, "cube", 64),
             ("cube 64 → lat-long 32", "cube", 64, "latlong", 32),
             ("cube 64 → mirror ball 64, no margin", "cube", 64, "sphere", 64, None),
             ("lat-long 256 → angular 128, no margin", "latlong", 256, "angular", 128, None),
             ("angular 256 → lat-long 128, no margin", "angular", 256, "latlong", 128, None))
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
    """Heat maps of |gain| over the source's pixels, before the flux correction (after it every pixel is exact): a
    mirror ball into an angular map, a cube into a lat-long, and a lat-long round an angular map's rim direction."""
    from ..maps import Resampler
    from ..maps.layouts import layout

    ball, angular, cube, latlong = layout("sphere"), layout("angular"), layout("cube"), layout("latlong")
    own_rate = Resampler(ball, ball.grid_shape(128), angular, 64).without_flux_correction()
    own_rate = own_rate.energy_gains(rim_margin=25.0)
    cube_gains = Resampler(cube, cube.grid_shape(64), latlong, 64).without_flux_correction().energy_gains()
    strip = np.concatenate(list(cube_gains), axis=1)  # the six faces side by side, as a cube file is
    big_to_angular = _rows_alone("angular")
    front = np.roll(big_to_angular, 256, axis=1)[128 - 43:128 + 43, 256 - 43:256 + 43]  # ±30° round +Z
    scale = "black 0, white 1 % or more; grey: no sphere, or within 25° of a rim direction"
    return (rep.display_picture("energy_ball_own_rate", heatmap(np.abs(own_rate), 0.01),
                                f"mirror ball 128 → angular 64, each target pixel at its own rate: |gain| of a sun "
                                f"in each pixel before the flux correction ({scale})", width=256)
            + rep.display_picture("energy_cube_latlong", heatmap(np.abs(strip), 0.002),
                                  "cube 64 → lat-long 64, faces +X −X +Y −Y +Z −Z, through the texel balance, "
                                  "before the flux correction: faint rings where a target pixel's rate differs "
                                  "from its neighbours' (black 0, white 0.2 % or more)", width=768)
            + rep.display_picture("energy_latlong_angular_rim", heatmap(np.abs(front), 0.002),
                                  "lat-long 256 → angular 128 round the angular map's rim direction, before its flux "
                                  "correction (what a 4k lat-long, too large for one, keeps): its pixels that the "
                                  "rim crosses are sampled round it (black 0, white 0.2 % or more)", width=256))


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
    for label, rows in (("1610×805 (odd height)", 805), ("2048×1024 (W = 2¹¹)", 1024)):
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
