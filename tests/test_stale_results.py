"""Results that were silently stale or wrong: each now follows its inputs or is refused with one line.

A bake is keyed by everything it reads; a batch gives every input path its own row, hashes the bytes it processed and
never ingests its own artifacts or loops through symbolic links; exports refuse numbers whose engine form is not
finite; BRDF parameters and radiance sets that cannot give a correct map are refused or warned about.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from lightprobe.maps.images import write_image

EXE = str(Path(sys.executable).with_name("lightprobe"))


def lightprobe(*argv, timeout=120) -> subprocess.CompletedProcess:
    """The installed command in a fresh process."""
    return subprocess.run([EXE, *map(str, argv)], capture_output=True, text=True, timeout=timeout,
                          env={**os.environ, "LIGHTPROBE_PROGRESS": "0"})


def clean_failure(res: subprocess.CompletedProcess, *words: str) -> None:
    lines = res.stderr.splitlines()
    assert res.returncode == 2 and len(lines) == 1 and lines[0].startswith("lightprobe: error: "), res.stderr[:2000]
    for w in words:
        assert w in res.stderr, res.stderr


def small_map(path: Path, value: float = 1.0, sun: float = 0.0) -> Path:
    img = np.full((8, 16, 3), value, np.float32)
    img[2, 5] += sun
    return write_image(path, img)


# ---- the viewer's bake cache ---------------------------------------------------------------------------------------
def test_the_bake_cache_key_follows_the_probes_layout(tmp_path):
    from lightprobe.viewer.bake import BakeOptions, cache_folder

    probe = small_map(tmp_path / "probe.exr")
    keys = {cache_folder(probe, None, BakeOptions(), tmp_path, layout) for layout in (None, "latlong", "cross")}
    assert len(keys) == 3


def test_the_bake_cache_key_follows_every_file_a_gltf_or_obj_mesh_loads(tmp_path):
    from lightprobe.viewer.bake import BakeOptions, cache_folder

    probe = small_map(tmp_path / "probe.exr")
    (tmp_path / "my mesh.bin").write_bytes(b"\0" * 36)
    (tmp_path / "tex.png").write_bytes(b"png 1")
    gltf = tmp_path / "mesh.gltf"
    gltf.write_text(json.dumps({"asset": {"version": "2.0"}, "buffers": [{"uri": "my%20mesh.bin", "byteLength": 36}],
                                "images": [{"uri": "tex.png"}, {"uri": "data:image/png;base64,AA=="}]}))
    (tmp_path / "mesh.mtl").write_text("newmtl m\nmap_Kd -s 1 1 1 wood.png\n")
    (tmp_path / "wood.png").write_bytes(b"wood 1")
    obj = tmp_path / "mesh.obj"
    obj.write_text("mtllib mesh.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl m\nf 1 2 3\n")
    for mesh, changed in ((gltf, "my mesh.bin"), (gltf, "tex.png"), (obj, "mesh.mtl"), (obj, "wood.png")):
        before = cache_folder(probe, mesh, BakeOptions(), tmp_path)
        (tmp_path / changed).write_bytes((tmp_path / changed).read_bytes() + b" changed")
        assert cache_folder(probe, mesh, BakeOptions(), tmp_path) != before, changed
