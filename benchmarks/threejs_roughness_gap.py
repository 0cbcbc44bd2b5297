"""Whether our three.js bake's gap from three.js's own PMREM at roughness 0.1 closes as the cube grows (not a timing).

    python benchmarks/threejs_roughness_gap.py [--canvas 64] [--probe st_fagans_interior_1k]

The engine test (tests/test_bake_threejs.py) renders spheres from our 64² ``environment.ktx2`` beside three.js
r187's own ``PMREMGenerator.fromEquirectangular`` of the same panorama (512² faces) and finds them 10 % apart at
roughness 0.1. Here the same spheres are drawn (three.js in headless Chromium, the test's page
engines/three_bake.html) from our bake at 64², 128² and 256² faces, against three.js's own PMREM at 512² and at
256² (its smallest): mean |Δ| over the sphere relative to the reference's mean, per sphere. The last rows give
three.js's own 256² → 512² spread and our 256² against its 256², whose levels sit at the same roughnesses.

Why the size matters (three.js's own source): PMREMGenerator.js fills mip ``lod`` of a cube of ``size`` with GGX
at roughness ``1 − √(1 − lod/maxLod)``, maxLod = log₂(size) − 3, by GGX importance sampling (256 samples, the
source mip picked by each sample's solid angle; no Gaussian blur of a sigma per mip any more) and, for its three
roughest levels, a weighted sum over a 16² source. The shader reads roughness r at mip maxLod · r(2 − r)
(envmap_common_pars_fragment.glsl.js) and blends the two nearest mips. Roughness 0.1 is mip 0.57 of a 64² cube
(maxLod 3): 43 % of the mirror image and 57 % of the r = 0.18 level; of a 512² cube (maxLod 6) mip 1.14, between
r = 0.087 and r = 0.18. The two blends are different lobes whatever the filtering, and a 64² mirror holds less
detail than a 512² one. Needs `bash setup.sh --test` (Node packages, Chromium).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

from common import SHARED, require  # sets the environment first

import numpy as np

from lightprobe_engines.runtimes import Browser, Server, missing_engines

SIZES = (64, 128, 256)
ROUGHNESSES = (0.1, 0.3, 0.6, 0.9)
EYE = [0.3, 0.45, 0.85]  # the engine test's camera (three.js direction)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--canvas", type=int, default=64, help="image size (the engine test's is 64)")
    parser.add_argument("--probe", default="st_fagans_interior_1k", help="a Poly Haven 1k probe of the data")
    args = parser.parse_args()
    path = SHARED / "polyhaven_1k" / f"{args.probe}.hdr"
    if not require(path):
        return 2
    if missing_engines():
        print(f"needs {', '.join(missing_engines())}: run 'bash setup.sh --test'", file=sys.stderr)
        return 2
    from lightprobe.bake import BakeOptions, bake
    from lightprobe.maps import read_envmap
    from lightprobe.maps.images import write_image
    from lightprobe.maps.layouts import LATLONG

    env = read_envmap(path)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for rows in (512, 1024):  # three.js's PMREM of a panorama 4·face wide: 256² and 512² faces
            write_image(folder / f"pano-{rows}.hdr", env.to(LATLONG, rows).data)
        for size in SIZES:
            out = bake(env, folder / f"bake-{size}", BakeOptions(("threejs",), size=size, skybox_size=16))
            (folder / f"ours-{size}.ktx2").write_bytes((out["threejs"] / "environment.ktx2").read_bytes())
        server = Server(folder)
        browser = Browser(server)
        try:
            page = browser.page("three_bake.html")

            def spheres(source, name):
                images = page.evaluate("([s, u, e, r, n]) => window.lightprobe.spheres(s, u, e, r, n)",
                                       [source, f"{server.url}/files/{name}", EYE, list(ROUGHNESSES), args.canvas])
                return [np.asarray(i, np.float64).reshape(args.canvas, args.canvas) for i in images]

            own = {512: spheres("pmrem", "pano-1024.hdr"), 256: spheres("pmrem", "pano-512.hdr")}
            ours = {size: spheres("ours", f"ours-{size}.ktx2") for size in SIZES}
            if browser.errors:
                print(f"three.js reported: {browser.errors}", file=sys.stderr)
                return 1
        finally:
            browser.close()
            server.close()

    def row(label, images, reference):
        figures = [np.abs(i - o)[o > 0].mean() / o[o > 0].mean() for i, o in zip(images, reference)]
        print(f"| {label} | " + " | ".join(f"{100 * f:.1f} %" for f in figures) + " |")

    print(f"\nthree.js r187, {args.probe}, {args.canvas}² canvas: mean |Δ| / mean over the sphere")
    print("| spheres | diffuse | " + " | ".join(f"r {r}" for r in ROUGHNESSES) + " |")
    print("|---|" + "---|" * (len(ROUGHNESSES) + 1))
    for size in SIZES:
        row(f"ours {size}² vs three.js PMREM 512²", ours[size], own[512])
    row("three.js PMREM 256² vs its 512² (its spread)", own[256], own[512])
    row("ours 256² vs three.js PMREM 256² (same levels)", ours[256], own[256])
    return 0


if __name__ == "__main__":
    sys.exit(main())
