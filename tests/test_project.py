"""The project's own rules: the README's two commands, CI running exactly the test one, imports flowing one way."""

from __future__ import annotations

import ast
import re

import numpy as np

from conftest import ROOT

# Each module's floor; a module may import only from its own floor or below.
FLOORS = {
    "errors": 0, "names": 0, "progress": 0, "kernels": 0, "jit": 0, "tonemap": 0, "frames": 0, "files": 0, "limits": 0, "peak": 0, "io": 1,
    "layouts": 1, "data": 0, "envmap": 2, "sh": 3, "brdf": 3, "irradiance": 4, "lights": 4, "baselines": 4, "lightsfile": 5, "radiancefile": 6, "rsibr": 6, "hybrid": 5, "radiance": 5, "shfile": 4, "prefilter": 3, "export": 5, "lightexport": 6, "design": 5, "containers": 6, "render": 8,
    "engines": 9, "viewer": 9, "batch": 9, "warmup": 9, "demo": 9, "cli": 10, "__init__": 10,
}


def readme_commands() -> list[str]:
    text = (ROOT / "README.md").read_text()
    block = re.match(r"```sh\n(.*?)```", text, re.S)
    assert block, "the README must open with a sh code block"
    return [line for line in block.group(1).splitlines() if line.strip()]


def test_readme_opens_with_exactly_two_commands():
    demo, tests = readme_commands()
    assert "lightprobe demo" in demo and ".venv" in demo
    assert "pytest" in tests and ".venv" in tests


def test_ci_runs_the_readme_test_command_and_nothing_else():
    ci = [line for line in (ROOT / ".ci" / "run").read_text().splitlines()
          if line.strip() and not line.startswith("#") and not line.startswith(("set ", "cd "))]
    assert ci == [readme_commands()[1]]


def test_imports_flow_one_way():
    package = ROOT / "src" / "lightprobe"
    for path in package.rglob("*.py"):
        name = path.stem if path.parent == package else path.parent.name
        assert name in FLOORS, f"{path.relative_to(ROOT)}: give the module a floor in tests/test_project.py"
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.level >= 1 and node.module:
                target = node.module.split(".")[0]
                if target in FLOORS:
                    assert FLOORS[target] <= FLOORS[name], f"{name} imports {target}, which is above it"


# Import names whose distribution is named otherwise (llvmlite comes with numba, dask with distributed).
DISTRIBUTIONS = {"PIL": "pillow", "yaml": "pyyaml", "OpenImageIO": "openimageio", "flip_evaluator": "flip-evaluator",
                 "llvmlite": "numba", "dask": "distributed"}


def test_every_package_the_source_imports_is_installed_with_it():
    """Each third-party module ``src/lightprobe`` imports is a dependency of the package, or of an extra that a
    feature names (reference, engines, dask) — never of the ``test`` extra alone: CI installs that extra, a user's
    ``setup.sh`` does not. scipy was ``test``-only while a lat-long → lat-long ``convert`` imported scipy.sparse,
    which then failed in the README's own set-up with a traceback."""
    import sys
    import tomllib

    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    extras = {name: reqs for name, reqs in project["optional-dependencies"].items() if name not in ("test", "bench")}
    declared = {re.split(r"[<>=!~\[ ;]", req, maxsplit=1)[0].lower()
                for req in project["dependencies"] + [r for reqs in extras.values() for r in reqs]}
    missing = set()
    for path in (ROOT / "src" / "lightprobe").rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module] if isinstance(node, ast.ImportFrom) and node.level == 0 else [])
            for name in names:
                top = name.split(".")[0]
                if top in sys.stdlib_module_names or top == "lightprobe":
                    continue
                if DISTRIBUTIONS.get(top, top).lower() not in declared:
                    missing.add(f"{top} ({path.relative_to(ROOT)})")
    assert not missing, f"imported but not a dependency: {sorted(missing)}"


def test_compiled_kernels_are_cached_in_the_user_cache_folder(tmp_path):
    """numba's cache goes to $XDG_CACHE_HOME/lightprobe/numba, not beside the package (which may be read-only)."""
    import os
    import subprocess
    import sys

    script = ("import numpy as np, lightprobe as lp\n"
              "from lightprobe.sh import project\n"
              "env = lp.EnvMap(np.ones((4, 8, 3), np.float32), lp.layout('latlong'))\n"
              "print(project(env, 2, compiled=True).coeffs[0, 0])\n")
    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path)}
    env.pop("NUMBA_CACHE_DIR", None)
    res = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=300)
    assert res.returncode == 0, res.stderr
    cached = list((tmp_path / "lightprobe" / "numba").rglob("*.nbi"))
    assert any("latlong_row_sums_sh9" in p.name for p in cached), cached


def test_the_numba_cache_folder_follows_every_source_file(tmp_path, monkeypatch):
    """A changed helper module gets a fresh cache folder even though the kernel inlining it is unchanged (numba
    would check only the kernel's own file); an unchanged tree keeps its folder."""
    import os

    import lightprobe

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    tree = tmp_path / "pkg"
    (tree / "sub").mkdir(parents=True)
    (tree / "kernel.py").write_text("x = 1\n")
    (tree / "sub" / "helper.py").write_text("y = 2\n")
    first = lightprobe._numba_cache_dir(str(tree))
    assert first == lightprobe._numba_cache_dir(str(tree))
    assert os.path.dirname(first) == str(tmp_path / "cache" / "lightprobe" / "numba")
    (tree / "sub" / "helper.py").write_text("y = 3\n")
    os.utime(tree / "sub" / "helper.py", ns=(1, 1))
    assert lightprobe._numba_cache_dir(str(tree)) != first


def test_stale_cache_folders_are_pruned_and_recent_ones_kept(tmp_path, monkeypatch):
    import os

    from lightprobe.warmup import prune_stale_caches

    base = tmp_path / "lightprobe" / "numba"
    current, old, recent, own = base / "0000cafe", base / "0badf00d", base / "12345678", base / "mine"
    for folder in (current, old, recent, own):
        folder.mkdir(parents=True)
    os.utime(old, (1, 1))
    os.utime(own, (1, 1))
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(current))
    assert prune_stale_caches() == [str(old)]
    assert current.is_dir() and recent.is_dir() and own.is_dir() and not old.exists()
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "elsewhere"))
    assert prune_stale_caches() == []


def test_import_and_help_stay_light():
    """`import lightprobe` loads neither numba nor OpenImageIO (PEP 562: names load on first use), and neither does
    `lightprobe --help`; the README's names resolve; a kernel compiles on first call with numba's prange."""
    import subprocess
    import sys

    script = ("import sys, contextlib, io\n"
              "import lightprobe as lp\n"
              "print('numba' in sys.modules, 'OpenImageIO' in sys.modules)\n"
              "from lightprobe.cli import main\n"
              "with contextlib.redirect_stdout(io.StringIO()):\n"
              "    try:\n"
              "        main(['--help'])\n"
              "    except SystemExit:\n"
              "        pass\n"
              "print('numba' in sys.modules)\n"
              "names = [lp.read_envmap, lp.EnvMap, lp.project, lp.SHCoeffs, lp.export, lp.irradiance_map, lp.layout,\n"
              "         lp.decompose, lp.LightParams]\n"
              "import numpy as np\n"
              "env = lp.EnvMap(np.ones((8, 16, 3), np.float32), lp.layout('latlong'))\n"
              "print(round(float(lp.project(env, 2, compiled=True).coeffs[0, 0]), 6))\n"
              "import numba, lightprobe.sh as sh\n"
              "print(sh.prange is numba.prange)\n")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["False", "False", "False", f"{round(float(np.sqrt(4 * np.pi)), 6)}", "True"], out


def test_the_command_lines_names_are_the_implementations_tables():
    """lightprobe.names (numpy-free, for --help) lists exactly the names each implementing table has, in order."""
    from importlib import import_module

    export, frames, layouts, names, sh, tonemap, methods = (import_module(f"lightprobe.{m}") for m in (
        "export", "frames", "layouts", "names", "sh", "tonemap", "render.methods"))

    assert names.LAYOUTS == tuple(layouts.LAYOUTS)
    assert names.FRAMES == tuple(frames.FRAMES)
    assert names.WINDOWS == sh.WINDOWS and names.CURVES == tonemap.CURVES
    assert names.EXPORT_TARGETS == export.TARGETS == tuple(export.DEFAULT_FRAMES)
    assert names.RENDER_METHODS == tuple(methods.all_methods())


def test_sh_and_info_load_neither_the_resampler_nor_other_commands(tmp_path):
    """`lightprobe sh` and `lightprobe info` on a lat-long file build only their own parser and never load the
    resampler (lightprobe.envmap's resampling names load on first use): together 10–25 ms of a ~200 ms command, the
    start-up issue 9 bounds at 3× `import numpy`. A name of the resampler still resolves from lightprobe.envmap."""
    import subprocess
    import sys

    from lightprobe.io import write_image

    path = tmp_path / "map.exr"
    write_image(path, np.ones((16, 32, 3), np.float32))
    script = ("import sys, contextlib, io\nfrom lightprobe.cli import main\n"
              "with contextlib.redirect_stdout(io.StringIO()):\n"
              f"    codes = [main(['sh', {str(path)!r}]), main(['info', {str(path)!r}])]\n"
              "loaded = [m for m in ('lightprobe.envmap.resampling', 'lightprobe.cli.batch', 'lightprobe.cli.render',\n"
              "                      'lightprobe.cli.convert', 'numba') if m in sys.modules]\n"
              "from lightprobe.envmap import resample, Resampler\n"
              "print(codes, loaded, resample.__module__, Resampler.__module__)\n")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["[0,", "0]", "[]", "lightprobe.envmap.resampling", "lightprobe.envmap.resampling"], out


def test_help_loads_no_numpy():
    """`lightprobe --help` and every command's --help list their choices without importing numpy (issue 9)."""
    import subprocess
    import sys

    script = ("import sys, contextlib, io\nfrom lightprobe.cli import main, COMMANDS\n"
              "with contextlib.redirect_stdout(io.StringIO()):\n"
              "    codes = [main(['--help'])] + [main([c, '--help']) for c in COMMANDS]\n"
              "print(codes, 'numpy' in sys.modules)\n")
    from lightprobe.cli import COMMANDS

    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True).stdout
    assert out.strip() == f"{[0] * (len(COMMANDS) + 1)} False"
