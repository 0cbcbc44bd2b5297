"""The project's own rules: the README's two commands, CI running exactly the test one, imports flowing one way."""

from __future__ import annotations

import ast
import re

import numpy as np

from conftest import ROOT

# Each folder of src/lightprobe is one capability on a floor; a folder imports only from folders on lower floors (and
# from itself). The papers' folders share a floor and import nothing of each other.
FLOORS = {
    "util": 0, "data": 0,            # errors, names, limits, atomic files, numba; the shipped probe
    "maps": 1,                       # EnvMap, layouts, frames, image files, resampling
    "sh": 2,                         # paper 1: SH, irradiance, design
    "lights": 3, "glossy": 3,        # paper 3: area lights + ambient; paper 2: BRDFs, radiance maps, RS-IBR
    "exports": 4,                    # what engines load
    "render": 5,                     # scenes, the renderer, Mitsuba's ground truth
    "bake": 5,                       # every engine's files from one working form
    "viewer": 6, "batch": 6,         # the WebGL viewer; datasets
    "warmup": 6,                     # compiling the kernels once
    "report": 7,                     # the demo
    "cli": 8,                        # the command line
    "__init__": 9,
}


def _folder_of(path, package) -> str:
    rel = path.relative_to(package)
    return rel.parts[0] if len(rel.parts) > 1 else rel.stem


def _imported_folder(path, package, node) -> str | None:
    """The top folder of src/lightprobe that an import names, or None for anything outside the package."""
    if isinstance(node, ast.ImportFrom) and node.level >= 1:
        base = path.parent.relative_to(package).parts
        base = base[:len(base) - (node.level - 1)] if node.level > 1 else base
        parts = [*base, *(node.module.split(".") if node.module else [])]
        if not parts:  # from . import x (at the top): each name is a folder or module of its own
            return None
        return parts[0]
    if isinstance(node, ast.ImportFrom) and node.level == 0 and node.module and node.module.startswith("lightprobe."):
        return node.module.split(".")[1]
    return None


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
    folders = {_folder_of(path, package) for path in package.rglob("*.py")}
    assert folders == set(FLOORS), f"give each folder a floor in tests/test_project.py: {folders ^ set(FLOORS)}"
    for path in package.rglob("*.py"):
        here = _folder_of(path, package)
        for node in ast.walk(ast.parse(path.read_text())):
            there = _imported_folder(path, package, node)
            if there is None or there == here or there not in FLOORS:
                continue
            assert FLOORS[there] < FLOORS[here], \
                f"{path.relative_to(ROOT)}: {here} (floor {FLOORS[here]}) imports {there} (floor {FLOORS[there]})"


def test_the_floor_check_sees_an_upward_import(tmp_path):
    """The check above can fail: an import from a higher floor, written as the package writes its imports."""
    package = tmp_path / "lightprobe"
    (package / "maps").mkdir(parents=True)
    module = package / "maps" / "envmap.py"
    module.write_text("from ..report.demo import run_demo\nfrom .layouts import LAYOUTS\n")
    found = [_imported_folder(module, package, node) for node in ast.walk(ast.parse(module.read_text()))
             if isinstance(node, ast.ImportFrom)]
    assert found == ["report", "maps"] and FLOORS["report"] > FLOORS["maps"]


def test_nothing_in_the_package_reaches_outside_it():
    """The installed package finds nothing through the checkout: no path climbs out of its own folder, no module
    of the development harness (engines/) is imported at a module's top, and no file names ../shared."""
    package = ROOT / "src" / "lightprobe"
    for path in package.rglob("*.py"):
        text = path.read_text()
        assert not re.search(r"parents\[[2-9]\]", text), f"{path}: a path out of the package"
        assert "shared/SPEC" not in text, f"{path}: cite docs/spec.md, which ships with the docs"
        for node in ast.parse(text).body:
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                names = [a.name for a in node.names] if isinstance(node, ast.Import) else [node.module or ""]
                assert not any(n.startswith("lightprobe_engines") for n in names), \
                    f"{path}: the harness may only be imported where it is optional (inside a function)"


def test_every_module_with_kernels_keys_the_numba_cache():
    """The numba cache folder is keyed by the modules holding kernels and what they import (lightprobe's
    KERNEL_MODULES): a module with a kernel missing from that list would keep stale compiled code."""
    import lightprobe

    package = ROOT / "src" / "lightprobe"
    with_kernels = {str(p.relative_to(package)) for p in package.rglob("*.py")
                    if re.search(r"^\s*@njit\(|= njit\(", p.read_text(), re.M)}
    assert with_kernels <= set(lightprobe.KERNEL_MODULES) | {"util/jit.py"}, with_kernels - set(lightprobe.KERNEL_MODULES)
    sources = lightprobe._kernel_sources(str(package))
    assert "maps/resampling/fused.py" in sources and "util/errors.py" in sources
    assert not any(s.startswith(("cli/", "report/", "viewer/", "batch/")) for s in sources), sources


def test_no_module_is_longer_than_a_thousand_lines():
    """One concept per module, each under a thousand lines. The one exception is the resampler's compiled kernel,
    fused.py: one pass over each target pixel's subsamples, rim samples, lookups and taps, whose kernels are mostly
    inlined into one another and are read together."""
    long = {str(p.relative_to(ROOT)): n for p in (ROOT / "src" / "lightprobe").rglob("*.py")
            if (n := len(p.read_text().splitlines())) > 1000}
    assert set(long) <= {"src/lightprobe/maps/resampling/fused.py"}, long


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
                if top in sys.stdlib_module_names or top in ("lightprobe", "lightprobe_engines"):  # the harness: optional
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
              "from lightprobe.sh.basis import project\n"
              "env = lp.EnvMap(np.ones((4, 8, 3), np.float32), lp.layout('latlong'))\n"
              "print(project(env, 2, compiled=True).coeffs[0, 0])\n")
    env = {**os.environ, "XDG_CACHE_HOME": str(tmp_path)}
    env.pop("NUMBA_CACHE_DIR", None)
    res = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=300)
    assert res.returncode == 0, res.stderr
    cached = list((tmp_path / "lightprobe" / "numba").rglob("*.nbi"))
    assert any("latlong_row_sums_sh9" in p.name for p in cached), cached


def test_the_numba_cache_folder_follows_the_kernels_and_what_they_import(tmp_path, monkeypatch):
    """A changed helper module that a kernel module imports gets a fresh cache folder even though the kernel's own
    file is unchanged (numba would check only that file); a changed command-line module keeps the folder, so
    editing a help string compiles nothing again."""
    import os
    import shutil

    import lightprobe

    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    tree = tmp_path / "pkg"
    shutil.copytree(ROOT / "src" / "lightprobe", tree, ignore=shutil.ignore_patterns("__pycache__", "vendor"))
    first = lightprobe._numba_cache_dir(str(tree))
    assert first == lightprobe._numba_cache_dir(str(tree))
    assert os.path.dirname(first) == str(tmp_path / "cache" / "lightprobe" / "numba")
    for rel in ("cli/convert.py", "report/demo.py", "viewer/server.py"):
        (tree / rel).write_text((tree / rel).read_text() + "\n# edited\n")
    assert lightprobe._numba_cache_dir(str(tree)) == first
    helper = tree / "maps" / "layouts.py"  # no kernel of its own; fused.py imports it
    helper.write_text(helper.read_text() + "\n# edited\n")
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
              "import numba, lightprobe.sh.row_sums as rows\n"  # the module of the kernel that project ran
              "print(rows.prange is numba.prange)\n")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["False", "False", "False", f"{round(float(np.sqrt(4 * np.pi)), 6)}", "True"], out


def test_the_command_lines_names_are_the_implementations_tables():
    """lightprobe.util.names (numpy-free, for --help) lists exactly the names each implementing table has, in order."""
    from importlib import import_module

    export, frames, layouts, names, sh, tonemap, methods = (import_module(f"lightprobe.{m}") for m in (
        "exports.sh", "maps.frames", "maps.layouts", "util.names", "sh.basis", "maps.tonemap", "render.methods"))

    assert names.LAYOUTS == tuple(layouts.LAYOUTS)
    assert names.FRAMES == tuple(frames.FRAMES)
    assert names.WINDOWS == sh.WINDOWS and names.CURVES == tonemap.CURVES
    assert names.EXPORT_TARGETS == export.TARGETS == tuple(export.DEFAULT_FRAMES)
    assert names.RENDER_METHODS == tuple(methods.all_methods())


def test_sh_and_info_load_neither_the_resampler_nor_other_commands(tmp_path):
    """`lightprobe sh` and `lightprobe info` on a lat-long file build only their own parser and never load the
    resampler (lightprobe.maps's resampling names load on first use): together 10–25 ms of a ~200 ms command, the
    start-up bounded at 3× `import numpy`. A name of the resampler still resolves from lightprobe.maps."""
    import subprocess
    import sys

    from lightprobe.maps.images import write_image

    path = tmp_path / "map.exr"
    write_image(path, np.ones((16, 32, 3), np.float32))
    script = ("import sys, contextlib, io\nfrom lightprobe.cli import main\n"
              "with contextlib.redirect_stdout(io.StringIO()):\n"
              f"    codes = [main(['sh', {str(path)!r}]), main(['info', {str(path)!r}])]\n"
              "loaded = [m for m in ('lightprobe.maps.resampling.resampler', 'lightprobe.cli.batch', 'lightprobe.cli.render',\n"
              "                      'lightprobe.cli.convert', 'numba') if m in sys.modules]\n"
              "from lightprobe.maps import resample, Resampler\n"
              "print(codes, loaded, resample.__module__, Resampler.__module__)\n")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["[0,", "0]", "[]", "lightprobe.maps.resampling.resampler", "lightprobe.maps.resampling.cached"], out


def test_help_loads_no_numpy():
    """`lightprobe --help` and every command's --help list their choices without importing numpy ."""
    import subprocess
    import sys

    script = ("import sys, contextlib, io\nfrom lightprobe.cli import main, COMMANDS\n"
              "with contextlib.redirect_stdout(io.StringIO()):\n"
              "    codes = [main(['--help'])] + [main([c, '--help']) for c in COMMANDS]\n"
              "print(codes, 'numpy' in sys.modules)\n")
    from lightprobe.cli import COMMANDS

    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True).stdout
    assert out.strip() == f"{[0] * (len(COMMANDS) + 1)} False"
