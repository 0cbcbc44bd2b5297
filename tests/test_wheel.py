"""The wheel works anywhere: built from this checkout, installed into a fresh virtual environment outside it, with
no engines/ and no ../shared beside it, every command a user starts with runs — `view --export` too, whose three.js
modules travel inside the package. A missing extra is one line naming it."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import numpy as np
import pytest

from conftest import ROOT

# One worker builds the wheel: `pip wheel .` builds inside the checkout (build/, the egg-info), and two builds at
# once in one tree break each other.
pytestmark = pytest.mark.xdist_group("wheel")

# The extras' modules, which a core-only installation lacks: each must be reported as the extra to install.
MISSING_EXTRAS = [
    (["render", "-o", "{out}.png", "--size", "8x8"], "trimesh", "render"),
    (["batch", "{probe}", "--out", "{out}"], "pyarrow", "batch"),
    (["view", "--mesh", "{mesh}", "--export", "{out}"], "trimesh", "viewer"),
]


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """A wheel of this checkout, built as `pip wheel .` builds it (isolated; setup.py copies three.js in), from a
    copy of the tree: setuptools builds inside the source folder (build/, the egg-info), where an earlier or a
    parallel build's leftovers break it."""
    import shutil

    out, tree = tmp_path_factory.mktemp("wheel"), tmp_path_factory.mktemp("tree") / "lightprobe"
    anywhere = shutil.ignore_patterns(".git", ".venv", "node_modules", "*.egg-info", "__pycache__", ".pytest_cache",
                                      ".hypothesis")

    def ignore(folder, names):  # build/ and dist/ only at the top: three.js has a build/ folder of its own
        top = {"build", "dist", "site", "lightprobe-demo"} if os.path.samefile(folder, ROOT) else set()
        return set(anywhere(folder, names)) | (top & set(names))

    shutil.copytree(ROOT, tree, ignore=ignore)
    res = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--disable-pip-version-check", "-q",
                          "-w", str(out), str(tree)], capture_output=True, text=True, timeout=900)
    assert res.returncode == 0, res.stderr[-3000:]
    (built,) = out.glob("lightprobe-*.whl")
    return built


@pytest.fixture(scope="module")
def installed(wheel, tmp_path_factory) -> Path:
    """A fresh virtual environment with the wheel installed; the core dependencies come from this environment's
    site-packages (a path in a .pth file: its own .pth files, and so this checkout's editable install, are not
    read), so nothing is downloaded and the test does not depend on a network."""
    venv = tmp_path_factory.mktemp("venv")
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, timeout=300)
    python = venv / "bin" / "python"
    site = subprocess.run([str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                          capture_output=True, text=True, check=True).stdout.strip()
    (Path(site) / "core-dependencies.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    res = subprocess.run([str(python), "-m", "pip", "install", "--no-deps", "--disable-pip-version-check", "-q",
                          str(wheel)], capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr[-3000:]
    return venv


def test_the_wheel_carries_the_viewer_and_the_probe_and_nothing_of_the_checkout(wheel):
    names = zipfile.ZipFile(wheel).namelist()
    assert "lightprobe/viewer/vendor/three/build/three.module.js" in names
    assert "lightprobe/viewer/vendor/three/examples/jsm/controls/OrbitControls.js" in names
    assert "lightprobe/viewer/static/index.html" in names and "lightprobe/data/rooitou_park_512.hdr" in names
    assert not [n for n in names if n.startswith(("lightprobe_engines", "tests/", "engines/", "benchmarks/"))]
    lock = json.loads((ROOT / "engines" / "package-lock.json").read_text())
    version = zipfile.ZipFile(wheel).read("lightprobe/viewer/vendor/three/VERSION").decode().strip()
    assert version == lock["packages"]["node_modules/three"]["version"]


def test_every_first_command_runs_from_the_installed_wheel(wheel, installed, tmp_path):
    """info, convert, sh, export, view --export and view, in a folder outside the repository, on a probe made here.

    The kernels run as plain Python (NUMBA_DISABLE_JIT): a fresh install's first compile is minutes of numba, the
    same for any installation and measured by the benchmarks; what this test proves is that the wheel's own files
    do the work. The viewer's bake is made first by this checkout (the same code, its kernels already compiled) into
    the cache folder, where the installed ``view`` finds it by its content key and writes or serves the page from
    the wheel's own files — three.js included."""
    import http.client
    import signal

    work = tmp_path / "elsewhere"
    work.mkdir()
    python, exe = installed / "bin" / "python", installed / "bin" / "lightprobe"
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "LIGHTPROBE_SHARED_DATA")}
    env.update(LIGHTPROBE_PROGRESS="0", XDG_CACHE_HOME=str(tmp_path / "cache"), NUMBA_DISABLE_JIT="1")
    where = subprocess.run([str(python), "-c", "import lightprobe; print(lightprobe.__file__)"], cwd=work, env=env,
                           capture_output=True, text=True, check=True).stdout.strip()
    assert where.startswith(str(installed)), where  # the wheel's copy, not the checkout's
    probe = work / "probe.exr"
    img = np.random.default_rng(1).random((16, 32, 3), dtype=np.float32)
    img[4, 9] = 300.0
    from lightprobe.maps.images import write_image

    write_image(probe, img)

    def run(*argv):
        res = subprocess.run([str(exe), *map(str, argv)], cwd=work, capture_output=True, text=True, env=env,
                             timeout=600)
        assert res.returncode == 0, (argv, res.stderr[-2000:])
        assert "Traceback" not in res.stderr, res.stderr
        return res.stdout

    assert "latlong" in run("info", probe)
    run("convert", probe, work / "cube.exr", "--to", "cube", "--size", "8")
    assert (work / "cube.exr").stat().st_size > 0
    sh = json.loads(run("sh", probe, "--json"))
    assert sh["format"] == "lightprobe.sh" and len(sh["coefficients"]) == 9
    run("export", probe, "--to", "threejs", "-o", work / "probe.threejs.json")
    assert json.loads((work / "probe.threejs.json").read_text())

    view = ["--views", "12", "--map-size", "16", "--brdf", "none", "--cache", tmp_path / "view-cache"]
    from lightprobe.cli import main

    assert main(["view", str(probe), *map(str, view), "--export", str(tmp_path / "checkout-site")]) == 0
    run("view", probe, *view, "--export", work / "site")
    site = work / "site"
    assert (site / "index.html").is_file() and (site / "bake" / "bake.json").is_file()
    three = site / "modules" / "three" / "build" / "three.module.js"
    assert three.read_bytes() == zipfile.ZipFile(wheel).read("lightprobe/viewer/vendor/three/build/three.module.js")

    server = subprocess.Popen([str(exe), "view", str(probe), *map(str, view)], cwd=work, env=env, text=True,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        line = server.stdout.readline()
        assert "http://127.0.0.1:" in line, (line, server.stderr.read() if server.poll() is not None else "")
        port = int(line.split("http://127.0.0.1:")[1].split("/")[0])
        conn = http.client.HTTPConnection("127.0.0.1", port, timeout=30)
        conn.request("GET", "/modules/three/build/three.module.js")
        answer = conn.getresponse()
        assert answer.status == 200 and answer.read() == three.read_bytes()
        server.send_signal(signal.SIGINT)
        _, err = server.communicate(timeout=60)
    finally:
        if server.poll() is None:
            server.kill()
    assert server.returncode == 0 and "Traceback" not in err, err
    assert not list(work.glob(".*tmp*"))


@pytest.mark.parametrize("argv, module, extra", MISSING_EXTRAS)
def test_a_missing_extra_is_one_line_naming_it(tmp_path, capsys, monkeypatch, argv, module, extra):
    """With the extra's module absent (as in a core-only install), the command names the extra and exits 2."""
    from lightprobe.cli import main
    from lightprobe.maps.images import write_image

    probe, mesh = tmp_path / "probe.exr", tmp_path / "tri.obj"
    write_image(probe, np.ones((8, 16, 3), np.float32))
    mesh.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    for name in [m for m in sys.modules if m == module or m.startswith(module + ".")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, module, None)  # `import module` now raises ModuleNotFoundError
    filled = [a.format(out=tmp_path / "out", probe=probe, mesh=mesh) for a in argv]
    assert main(filled) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"pip install 'lightprobe[{extra}]'" in err[0] and module in err[0], err
