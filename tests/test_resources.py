"""Hangs and resources: a peer that is not Dask, a FIFO where a part should be, and inputs whose size is known from
their headers (radiance-map sets, JSON files, mesh files) refused before they are read, each in one line."""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

from lightprobe.maps.images import write_image
from lightprobe.util.errors import BudgetError
from test_cli import assert_clean_failure, run

EXE = str(Path(sys.executable).with_name("lightprobe"))
SPARSE_BYTES = 64 << 30  # a sparse file this long costs nothing on disk; reading it whole could not be allocated


def lightprobe(*argv, timeout: float = 60, **kwargs) -> subprocess.CompletedProcess:
    return subprocess.run([EXE, *map(str, argv)], capture_output=True, text=True, timeout=timeout,
                          env={**os.environ, "LIGHTPROBE_PROGRESS": "0"}, **kwargs)


def one_line_failure(res: subprocess.CompletedProcess, *words: str) -> None:
    lines = res.stderr.splitlines()
    assert res.returncode == 2 and len(lines) == 1 and lines[0].startswith("lightprobe: error: "), res.stderr[-2000:]
    for w in words:
        assert w in res.stderr, res.stderr


def sparse(path: Path) -> Path:
    with open(path, "wb") as f:
        f.truncate(SPARSE_BYTES)
    return path


# ---- batch ---------------------------------------------------------------------------------------------------------
class PlainServer:
    """A TCP server on 127.0.0.1 that is not Dask: it accepts and says nothing, or answers every request as HTTP."""

    def __init__(self, http: bool):
        self.http, self.conns = http, []
        self.sock = socket.create_server(("127.0.0.1", 0))
        self.port = self.sock.getsockname()[1]
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self):
        while True:
            try:
                conn, _ = self.sock.accept()
            except OSError:
                return
            self.conns.append(conn)
            if self.http:
                try:
                    conn.recv(4096)
                    conn.sendall(b"HTTP/1.1 200 OK\r\nContent-Type: text/plain\r\nContent-Length: 2\r\n\r\nok")
                except OSError:
                    pass

    def close(self):
        for s in (self.sock, *self.conns):
            s.close()


@pytest.mark.parametrize("http", [False, True], ids=["silent", "http"])
def test_batch_scheduler_that_is_not_dask_fails_in_one_line_within_its_timeout(tmp_path, http):
    server = PlainServer(http)
    try:
        probe = write_image(tmp_path / "p.exr", np.ones((4, 8, 3), np.float32))
        # before: the silent server held the client for ever; the HTTP one gave "out of memory" (its reply read
        # as a frame length)
        res = lightprobe("batch", probe, "--out", tmp_path / "out", "--scheduler", f"tcp://127.0.0.1:{server.port}",
                         "--timeout", "1")
    finally:
        server.close()
    one_line_failure(res, "cannot reach the Dask scheduler", "within 1 s")
    assert not (tmp_path / "out").exists()


def test_batch_resume_refuses_a_fifo_in_parts_without_opening_it(tmp_path):
    probe = write_image(tmp_path / "p.exr", np.ones((4, 8, 3), np.float32))
    out = tmp_path / "out"
    args = ("batch", probe, "--out", out, "--jobs", "sh", "--workers", "1")
    assert lightprobe(*args).returncode == 0
    fifo = out / "parts" / "rows-000009-0123abcd.parquet"
    os.mkfifo(fifo)
    proc = subprocess.Popen([EXE, *map(str, args), "--resume"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env={**os.environ, "LIGHTPROBE_PROGRESS": "0"})
    try:
        _, err = proc.communicate(timeout=30)
    except subprocess.TimeoutExpired:  # blocked on the FIFO (the old behaviour): SIGTERM must still end it
        proc.send_signal(signal.SIGTERM)
        try:
            _, err = proc.communicate(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.communicate()
            pytest.fail("batch --resume blocked on a FIFO in parts/ and ignored SIGTERM")
        pytest.fail(f"batch --resume blocked on a FIFO in parts/ (SIGTERM: {proc.returncode}, {err.strip()})")
    one_line_failure(subprocess.CompletedProcess(proc.args, proc.returncode, "", err), str(fifo),
                     "not a regular file")
    assert fifo.exists() and sorted(p.name for p in (out / "parts").iterdir())[-1] == fifo.name


# ---- radiance ------------------------------------------------------------------------------------------------------
def hand_made_set(folder: Path, size: int, files: list[str]) -> Path:
    """A 12-view set's manifest naming ``files`` (one per view, repeated as needed), with no maps written."""
    from lightprobe.glossy.radiance import geodesic_views, view_frame

    views, triangles = geodesic_views(12)
    folder.mkdir()
    doc = {"format": "lightprobe.radiance", "version": 1, "frame": "world", "quantity": "radiance",
           "layout": "sphere", "size": size, "brdf": {"spec": "lambert"},
           "views": [{"file": files[i % len(files)], "direction": list(v), "frame": view_frame(v).T.tolist()}
                     for i, v in enumerate(views)],
           "triangles": triangles.tolist()}
    (folder / "manifest.json").write_text(json.dumps(doc))
    return folder


@pytest.fixture
def no_pixels_read(monkeypatch):
    """read_image fails the test: the refusals below must come from the headers alone."""
    def refuse(path, *args, **kwargs):
        raise AssertionError(f"pixels of {path} were read")

    monkeypatch.setattr("lightprobe.maps.images.read_image", refuse)


def test_synthesize_refuses_a_map_named_by_many_views_before_reading_pixels(tmp_path, capsys, no_pixels_read):
    rset = hand_made_set(tmp_path / "set", 64, ["one.exr"])
    write_image(rset / "one.exr", np.zeros((64, 64, 3), np.float32))
    code, _, err = run(capsys, "radiance", rset, "--synthesize", "0.1,0.2,1", "-o", tmp_path / "new.exr")
    assert_clean_failure(code, err, "one.exr", "views[0]")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["set"]


def test_synthesize_checks_the_sets_memory_from_its_headers_before_reading_pixels(tmp_path, capsys, monkeypatch,
                                                                                 no_pixels_read):
    files = [f"view_{i:03d}.exr" for i in range(12)]
    rset = hand_made_set(tmp_path / "set", 1024, files)
    write_image(rset / files[0], np.zeros((1024, 1024, 3), np.float32))  # a few kB on disk, 12 MB as pixels
    for name in files[1:]:
        shutil.copy(rset / files[0], rset / name)
    monkeypatch.setenv("LIGHTPROBE_MAX_MEMORY", "300M")
    code, _, err = run(capsys, "radiance", rset, "--synthesize", "0.1,0.2,1", "-o", tmp_path / "new.exr")
    assert_clean_failure(code, err, "refusing the 12 maps of 1024²", "LIGHTPROBE_MAX_MEMORY")


def test_radiance_set_over_the_memory_budget_is_refused_before_it_starts(tmp_path, capsys, monkeypatch):
    def started(*args, **kwargs):
        raise AssertionError("the work started")

    monkeypatch.setattr("lightprobe.glossy.radiance.prepare", started)
    monkeypatch.setenv("LIGHTPROBE_MAX_MEMORY", "1G")
    code, _, err = run(capsys, "radiance", "--brdf", "ggx:alpha=0.2", "--views", 162, "--size", 2048, "-o",
                       tmp_path / "set")
    assert_clean_failure(code, err, "refusing 162 radiance maps of 2048²", "GiB", "LIGHTPROBE_MAX_MEMORY")
    assert not (tmp_path / "set").exists()


def test_the_radiance_estimate_counts_every_map_and_one_at_work():
    from lightprobe.glossy.radiance import radiance_set_bytes

    assert radiance_set_bytes(162, 2048) > 8 << 30  # 162 float32 RGB maps of 2048² alone are 8.2 GB
    assert radiance_set_bytes(12, 256) < 100 << 20


# ---- JSON inputs ---------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("reader", ["sh", "lights", "radiance", "scene", "batch"])
def test_a_json_input_over_its_limit_is_refused_before_it_is_read(tmp_path, capsys, reader):
    """A sparse 64 GB file: read whole, it could not even be allocated ("out of memory" before)."""
    if reader == "radiance":
        (tmp_path / "set").mkdir()
        sparse(tmp_path / "set" / "manifest.json")
        argv = ("radiance", tmp_path / "set", "--synthesize", "0,0,1", "-o", tmp_path / "o.exr")
    elif reader == "scene":
        argv = ("render", sparse(tmp_path / "scene.json"), "-o", tmp_path / "o.exr", "--size", "8x8")
    elif reader == "batch":
        (tmp_path / "out").mkdir()
        sparse(tmp_path / "out" / "batch.json")
        argv = ("batch", tmp_path / "p.exr", "--out", tmp_path / "out", "--resume")
    else:
        argv = ("export", f"--{reader}", sparse(tmp_path / "in.json"), "--to", "threejs", "-o", tmp_path / "o.json")
    code, _, err = run(capsys, *argv)
    assert_clean_failure(code, err, "over the limit")


def test_the_view_cache_passes_over_a_huge_manifest_without_reading_it(tmp_path):
    from lightprobe.viewer.bake import read_manifest

    sparse(tmp_path / "bake.json")
    assert read_manifest(tmp_path) is None


def test_a_fifo_json_input_is_refused_not_waited_on(tmp_path, capsys):
    os.mkfifo(tmp_path / "sh.json")
    code, _, err = run(capsys, "export", "--sh", tmp_path / "sh.json", "--to", "threejs", "-o", tmp_path / "o.json")
    assert_clean_failure(code, err, "not a regular file")


# ---- meshes --------------------------------------------------------------------------------------------------------
MESH_KINDS = ["ply", "stl", "obj", "off", "glb", "gltf"]


@pytest.fixture
def loads(monkeypatch):
    """Count trimesh.load calls (each still loads)."""
    import trimesh

    calls, real = [], trimesh.load

    def counted(*args, **kwargs):
        calls.append(args[0])
        return real(*args, **kwargs)

    monkeypatch.setattr(trimesh, "load", counted)
    return calls


def icosphere(tmp_path: Path, kind: str, name: str = "ball") -> Path:
    import trimesh

    path = tmp_path / f"{name}.{kind}"
    trimesh.creation.icosphere(2).export(path)  # 320 triangles
    return path


@pytest.mark.parametrize("kind", MESH_KINDS)
def test_a_mesh_over_the_triangle_limit_is_refused_from_its_header_before_loading(tmp_path, monkeypatch, loads,
                                                                                  kind):
    from lightprobe.render.scene import load_mesh

    path = icosphere(tmp_path, kind)
    monkeypatch.setenv("LIGHTPROBE_MAX_TRIANGLES", "100")
    with pytest.raises(BudgetError, match="320 triangles"):
        load_mesh(path)
    assert loads == []


@pytest.mark.parametrize("kind", MESH_KINDS)
def test_a_mesh_files_header_gives_its_triangle_count(tmp_path, kind):
    from lightprobe.render.scene import mesh_triangles

    assert mesh_triangles(icosphere(tmp_path, kind)) == 320


def test_a_scenes_meshes_are_counted_against_the_limit_before_each_is_loaded(tmp_path, monkeypatch, loads):
    from lightprobe.render.scenefile import load_scene

    first, second = icosphere(tmp_path, "ply", "a"), icosphere(tmp_path, "obj", "b")
    (tmp_path / "scene.json").write_text(json.dumps({"meshes": [{"file": first.name}, {"file": second.name}]}))
    monkeypatch.setenv("LIGHTPROBE_MAX_TRIANGLES", "500")
    with pytest.raises(BudgetError, match="640 triangles"):
        load_scene(tmp_path / "scene.json")
    assert loads == [str(first)]
