"""Report section on rendering: a scene by each lighting method beside the Mitsuba 3 ground truth."""

from __future__ import annotations

import html
import time

from ..maps.tonemap import auto_exposure
from ..util.errors import LightprobeError
from .page import Report, data_folder, table


def _demo_scene(rep: Report):
    """The bunny on a ground plane if ../shared/data is beside the project (Stanford data may not be shipped),
    else the built-in sphere-and-torus scene; the environment turned so the sun is behind the camera's left."""
    from ..render.scene import builtin_scene, mesh_scene

    bunny = data_folder() / "meshes" / "stanford" / "bun_zipper.ply"
    if bunny.is_file():
        return mesh_scene(bunny, rep.env, 192, 192), "the Stanford bunny (69k triangles) on a grey ground plane"
    return builtin_scene(rep.env, 192, 192), "the built-in sphere and torus (the bunny lives in ../shared/data)"


def section_render(rep: Report) -> str:
    """Every lighting method against Mitsuba's ground truth on a real mesh: SH and brute force (no shadows), the
    area lights with soft shadows (with and without shadowed ambient) and median cut with as many point lights."""
    from ..render.compare import compare, error_heatmap
    from ..render.methods import method
    from ..render.raycast import Tracer
    from ..render.renderer import render

    scene, what = _demo_scene(rep)
    tracer = Tracer(scene)
    from ..render.reference import mitsuba, reference_render

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
