"""Hash a fixed set of lightprobe's outputs, to prove a refactor changes no value.

Runs the command line in-process on small inputs made here (and the shipped probe) and prints one line per output:
``sha256  name``. Run it before and after a change and compare the two lists; they must be equal.

    python tools/golden_outputs.py OUT.txt
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import re
import sys
import tempfile
from pathlib import Path

import numpy as np

LAYOUT_SIZES = {"latlong": (32, 64), "angular": (48, 48), "sphere": (48, 48), "cube": (16, 96),
                "cross": (64, 48), "hcross": (48, 64)}
# Fields that name the run, not the values: paths, times, versions.
VOLATILE = re.compile(r'"(source|path|created|generated|elapsed|seconds|time|version_lightprobe|lightprobe_version|'
                      r'input|file|probe|made_with|tool)"\s*:\s*("[^"]*"|[0-9.e+-]+)')


STOPWATCH = {"timings", "seconds", "elapsed", "created"}  # keys whose values are how long a run took, or when


def _steady(doc):
    """A JSON document without the fields that measure the run rather than its result."""
    if isinstance(doc, dict):
        return {k: _steady(v) for k, v in doc.items() if k not in STOPWATCH}
    if isinstance(doc, list):
        return [_steady(v) for v in doc]
    return doc


def _digest(path: Path, tmp: Path) -> str:
    """sha256 of what a file holds: an image's pixels (its header names the writer and the time), a text's content
    with the run's temporary folder and volatile fields blanked."""
    if path.suffix in (".exr", ".hdr", ".pfm"):
        import lightprobe as lp

        pixels = np.ascontiguousarray(lp.read_image(path))
        return hashlib.sha256(str(pixels.shape).encode() + pixels.tobytes()).hexdigest()
    data = path.read_bytes()
    if path.suffix == ".json" or path.name.startswith(("lights", "manifest")):
        try:
            doc = json.loads(data.decode().replace(str(tmp), "<tmp>"))
        except ValueError:
            doc = None
        if doc is not None:
            return hashlib.sha256(json.dumps(_steady(doc), sort_keys=True).encode()).hexdigest()
    if path.suffix in (".json", ".txt", ".cs", ".js", ".csv", ".md"):
        text = data.decode().replace(str(tmp), "<tmp>")
        data = VOLATILE.sub(r'"\1": "*"', text).encode()
    return hashlib.sha256(data).hexdigest()


def _run(argv: list[str]) -> str:
    from lightprobe.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main(argv)
    if code != 0:
        raise SystemExit(f"{' '.join(argv)} → {code}: {err.getvalue()}")
    return out.getvalue()


def main(out_file: str) -> None:
    import lightprobe as lp

    write_image = lp.write_image

    lines = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        rng = np.random.default_rng(7)
        sources = {}
        for name, (h, w) in LAYOUT_SIZES.items():
            img = rng.random((h, w, 3), dtype=np.float32) * 2
            img[h // 3, w // 5] = 400.0  # a sun
            sources[name] = tmp / f"src_{name}.exr"
            write_image(sources[name], img)

        def record(name, path):
            lines.append(f"{_digest(path, tmp)}  {name}")

        for a in LAYOUT_SIZES:
            for b in LAYOUT_SIZES:
                out = tmp / f"{a}_to_{b}.exr"
                _run(["convert", str(sources[a]), str(out), "--to", b, "--size", "24", "--layout", a])
                record(out.name, out)
        out = tmp / "turned.exr"
        _run(["convert", str(sources["latlong"]), str(out), "--to", "cube", "--size", "20", "--rotate", "30,40,50"])
        record(out.name, out)
        for order in (2, 8):
            for window in ("none", "hanning"):
                text = _run(["sh", str(sources["latlong"]), "--order", str(order), "--window", window, "--json"])
                p = tmp / f"sh_{order}_{window}.json"
                p.write_text(text)
                record(p.name, p)
        text = _run(["sh", str(sources["angular"]), "--order", "4", "--json", "--frame", "rh2001"])
        (tmp / "sh_angular.json").write_text(text)
        record("sh_angular.json", tmp / "sh_angular.json")
        lights = tmp / "lights.json"
        _run(["lights", str(sources["latlong"]), "-o", str(lights), "--ambient", str(tmp / "ambient.exr")])
        record("lights.json", lights)
        record("ambient.exr", tmp / "ambient.exr")
        for method in ("mediancut", "varmin"):
            p = tmp / f"lights_{method}.json"
            _run(["lights", str(sources["latlong"]), "-o", str(p), "--method", method, "--count", "8"])
            record(p.name, p)
        from lightprobe.cli.export import CONTAINERS

        try:
            from lightprobe.util.names import EXPORT_TARGETS as TARGETS
        except ImportError:
            from lightprobe.util.names import EXPORT_TARGETS as TARGETS
        for target in TARGETS:
            p = tmp / f"export_{target}"
            _run(["export", str(sources["latlong"]), "--to", target, "-o", str(p)])
            record(p.name, p)
            p2 = tmp / f"export_lights_{target}"
            try:
                _run(["export", "--lights", str(lights), "--to", target, "-o", str(p2)])
                record(p2.name, p2)
            except SystemExit:
                pass
        for target in CONTAINERS:
            p = tmp / f"container_{target}"
            _run(["export", str(sources["latlong"]), "--to", target, "-o", str(p), "--specular-size", "16"])
            record(p.name, p)
        for method in ("sh", "brute", "hybrid"):
            p = tmp / f"irr_{method}.exr"
            _run(["irradiance", str(sources["latlong"]), "-o", str(p), "--method", method, "--size", "16x8"])
            record(p.name, p)
        text = _run(["error", str(sources["latlong"]), "--json", "--normals", "64"])
        (tmp / "error.json").write_text(text)
        record("error.json", tmp / "error.json")
        _run(["design", str(sources["latlong"]), "-o", str(tmp / "design.png"), "--set", "L1-1=0.5", "--size", "32",
              "--json", str(tmp / "design.json")])
        record("design.png", tmp / "design.png")
        record("design.json", tmp / "design.json")
        rad = tmp / "radiance"
        _run(["radiance", str(sources["latlong"]), "-o", str(rad), "--size", "16", "--brdf", "phong:n=8"])
        for p in sorted(rad.rglob("*")):
            if p.is_file():
                record(f"radiance/{p.relative_to(rad)}", p)
        for method in ("sh", "lights", "brute", "splitsum", "rsibr"):
            p = tmp / f"render_{method}.exr"
            try:
                _run(["render", "--probe", str(sources["latlong"]), "--method", method, "-o", str(p), "--size",
                      "24x24", "--spp", "1", "--map-size", "16"])
            except SystemExit as e:
                lines.append(f"failed  render_{method}: {e}")
                continue
            record(p.name, p)
    Path(out_file).write_text("\n".join(lines) + "\n")
    print(f"{len(lines)} outputs hashed into {out_file}")


if __name__ == "__main__":
    main(sys.argv[1])
