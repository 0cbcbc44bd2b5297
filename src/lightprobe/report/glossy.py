"""Report section on paper 2: radiance maps of glossy BRDFs, RS-IBR and the split sum, rendered."""

from __future__ import annotations

import html
import time
from dataclasses import replace

import numpy as np

from ..maps.tonemap import auto_exposure
from ..util.errors import LightprobeError
from .page import Report, data_folder, table

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
    from ..glossy.brdf import parse_brdf
    from ..glossy.radiance import geodesic_views, prepare, radiance_map
    from ..glossy.radiancefile import radiance_set
    from ..glossy.rsibr import synthesize
    from ..render.compare import compare, error_heatmap
    from ..render.methods import method
    from ..render.raycast import Tracer
    from ..render.reference import mitsuba, reference_render
    from ..render.renderer import render

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
    from ..render.scene import mesh_scene, sphere_scene

    objects = [("sphere", sphere_scene(rep.env, 64))]
    meshes = data_folder() / "meshes"
    for name, path in (("teapot", meshes / "teapot" / "teapot.obj"),
                       ("bunny", meshes / "stanford" / "bun_zipper_res2.ply")):
        if path.is_file():
            objects.append((name, mesh_scene(path, rep.env, 64, 64, ground=False, turn_to_key_light=False)))
    return objects


def _glossy_caption(objects: list) -> str:
    names = [name for name, _ in objects]
    found = "A sphere" if len(names) == 1 else "A sphere, " + " and ".join(f"the {n}" for n in names[1:])
    return found + ("" if len(names) > 1 else " (the teapot and the bunny live in ../shared/data)")
