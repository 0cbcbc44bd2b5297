"""How Babylon.js's own SH of a panorama converges on lightprobe's as its cube grows (not a timing).

    python benchmarks/babylon_convergence.py

Babylon samples a panorama at the nearest pixel when it makes its cube, so a small sun is missed or over-counted
until the cube has more texels than the panorama has pixels. For each probe, Babylon 9.35 in Node computes its
SphericalPolynomial from the file with 256², 512², 1024² and 2048² faces; the table gives how far the irradiance it
computes from ours is from its own, toward the brightest background direction and away from it (the engine tests
use 2048² where 256² → 512² moves by over 3 %). Needs `bash setup.sh --test` (Node packages).
"""

from __future__ import annotations

import sys

from common import SHARED, require  # sets the environment first

import numpy as np

from lightprobe_engines.runtimes import babylon, babylon_irradiance_over_pi, missing_engines, relative
from lightprobe.maps import read_envmap
from lightprobe.exports.sh import export
from lightprobe.sh.basis import project

SIZES = (256, 512, 1024, 2048)
PROBES = ("rooitou_park_1k", "venice_sunset_1k", "st_fagans_interior_1k")


def main() -> int:
    paths = [SHARED / "polyhaven_1k" / f"{name}.hdr" for name in PROBES]
    if not require(*paths):
        return 2
    if missing_engines():
        print(f"needs {', '.join(missing_engines())}: run 'bash setup.sh --test'", file=sys.stderr)
        return 2
    print(f"{'probe':24s} {'faces':>6s} {'E toward':>9s} {'E away':>8s}")
    for name, path in zip(PROBES, paths):
        jobs = {str(n): {"panorama": str(path), "size": n} for n in SIZES}
        jobs["ours"] = {"export": export(project(read_envmap(path), 2), "babylon")}
        answer = babylon(jobs)
        mine = np.array(answer["ours"]["preScaledHarmonics"])
        sun = np.array(answer["512"]["brightest"])
        for n in SIZES:
            own = np.array(answer[str(n)]["preScaledHarmonics"])
            toward, away = (relative(babylon_irradiance_over_pi(mine, d), babylon_irradiance_over_pi(own, d))
                            for d in (sun, -sun))
            print(f"{name:24s} {n:5d}² {100 * toward:8.2f}% {100 * away:7.2f}%")
    return 0


if __name__ == "__main__":
    sys.exit(main())
