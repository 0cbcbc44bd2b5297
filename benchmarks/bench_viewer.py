"""The viewer's frame times: each method at 512² in headless Chromium (SwiftShader WebGL2, this machine's 2 cores),
beside the Python renderer's time for the same frame (same method, camera, size and bake), in one run.

    python benchmarks/bench_viewer.py [--size 512] [--mesh bun_zipper.ply] [--frames 5] [--screenshots DIR]

The Python side renders the bunny scene the page shows (1 sample per pixel, after a warm-up that fills its caches:
the radiance maps, the decomposition) — for the glossy methods the bunny alone on both sides, as the Python glossy
methods shade a Lambertian ground by brute force (exact, and far slower than eq. 13); the page's time is the median of ``--frames`` frames drawn to a size² canvas
and tone mapped (the shadow maps drawn once before, as the page does when the environment does not turn).
SwiftShader is a software rasteriser: a GPU is one to three orders of magnitude faster; the ratio is the figure.
With ``--screenshots DIR`` the page is also photographed in each state a person would try (drag, method switch,
slider), through real mouse and keyboard events.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from dataclasses import replace
from pathlib import Path

from common import SHARED, best_of, require  # sets the environment first

from lightprobe.glossy.brdf import parse_brdf
from lightprobe.data import default_probe_path
from lightprobe.maps import read_envmap
from lightprobe.render.methods import method as make_method
from lightprobe.render.renderer import render
from lightprobe.render.scene import Material, mesh_scene
from lightprobe.viewer.bake import BakeOptions, bake
from lightprobe_engines.viewer_page import ViewerPage

GOLD = "ggx:alpha=0.2,conductor=gold"
PYTHON = {  # page method → the Python renderer's method and whether the objects are the glossy material
    "sh": (lambda: make_method("sh"), False),
    "sh-vertex": (lambda: make_method("sh", per_vertex=True), False),
    "threejs": (lambda: make_method("sh"), False),
    "lights": (lambda: make_method("lights", light_samples=16), False),
    "rsibr": (lambda: make_method("rsibr", map_size=128), True),
    "rsibr-pixel": (lambda: make_method("rsibr", map_size=128, per_pixel_view=True), True),
    "splitsum": (lambda: make_method("splitsum"), True),
}


def glossy(scene):
    """The scene's objects in gold, without the ground."""
    brdf = parse_brdf(GOLD)
    return replace(scene, meshes=tuple(replace(m, material=Material(brdf=brdf)) for m in scene.meshes
                                       if m.name != "ground"))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--mesh", default="bun_zipper.ply")
    parser.add_argument("--frames", type=int, default=5)
    parser.add_argument("--screenshots", type=Path)
    args = parser.parse_args()
    mesh = SHARED / "meshes" / "stanford" / args.mesh
    if not require(mesh):
        return 2
    env = read_envmap(default_probe_path())
    with tempfile.TemporaryDirectory() as temp:
        t0 = time.perf_counter()
        doc = bake(env, Path(temp) / "bake", mesh, BakeOptions(brdfs=(GOLD,)))
        print(f"bake: {time.perf_counter() - t0:.1f} s ({doc['meshes'][0]['triangles']} triangles, "
              f"{doc['lights']['count']} lights, 12 radiance maps 128²)")
        scene = mesh_scene(mesh, env, args.size, args.size, turn_to_key_light=False)
        rows = []
        with ViewerPage(Path(temp) / "bake", width=args.size + 320, height=args.size + 20) as page:
            for name, (make, is_glossy) in PYTHON.items():
                s = glossy(scene) if is_glossy else scene
                m = make()
                render(replace(s, camera=replace(s.camera, width=16, height=16)), m)  # warm-up: caches, kernels
                python = best_of(lambda: render(s, m), 2) * 1000
                page.frame_time(name, args.size, 1, ground=not is_glossy)  # compiles the shaders (+ shadow maps)
                gpu = page.frame_time(name, args.size, args.frames, ground=not is_glossy)
                rows.append((name + (" (bunny only)" if is_glossy else ""), gpu, python))
                print(f"  {name}: page {gpu:.1f} ms, Python {python:.0f} ms", flush=True)
            if args.screenshots:
                person(page, args.screenshots)
    print(f"\nframe {args.size}² — {args.mesh}, shipped probe, headless Chromium (SwiftShader) vs lightprobe.render")
    print(f"{'method':<26}{'page ms':>10}{'page fps':>10}{'Python ms':>12}{'Python / page':>15}")
    for name, gpu, python in rows:
        print(f"{name:<26}{gpu:>10.1f}{1000 / gpu:>10.1f}{python:>12.0f}{python / gpu:>14.1f}×")
    return 0


def person(page: ViewerPage, folder: Path) -> None:
    """What a person does: drag the view, switch methods, move a slider, turn the environment — each through the
    page's own controls, each photographed."""
    folder.mkdir(parents=True, exist_ok=True)
    p = page.page
    p.evaluate("window.lightprobe.setState({method: 'sh', ground: true})")
    p.screenshot(path=str(folder / "1-opened.png"))
    box = p.locator("#canvas").bounding_box()
    cx, cy = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    p.mouse.move(cx, cy)
    p.mouse.down()
    p.mouse.move(cx - 120, cy - 30, steps=8)
    p.mouse.up()
    p.wait_for_timeout(300)
    p.screenshot(path=str(folder / "2-dragged.png"))
    p.select_option("#method", "lights")
    p.wait_for_timeout(1500)
    p.screenshot(path=str(folder / "3-method-lights.png"))
    p.select_option("#method", "sh")
    p.locator("#design input").nth(1).fill("3")
    p.wait_for_timeout(500)
    p.screenshot(path=str(folder / "4-slider-L1-1.png"))
    p.select_option("#method", "rsibr")
    p.locator("#rotation").fill("90")
    p.wait_for_timeout(1500)
    p.screenshot(path=str(folder / "5-rsibr-rotated.png"))
    print(f"screenshots of a person's session in {folder}")


if __name__ == "__main__":
    raise SystemExit(main())
