"""``lightprobe view``: the page in a real Chromium (SwiftShader WebGL2) against the Python renderer and three.js,
and the server against hostile requests.

One bake (Grace, the bunny at res3, gold GGX α 0.2 with 48² maps) and one page load for every browser check; each
check is a read-back of linear radiance from the page's float render targets."""

from __future__ import annotations

import http.client
import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import shared
from lightprobe.cli import main
from lightprobe.maps import EnvMap, read_envmap
from lightprobe.maps.layouts import Sphere
from lightprobe.viewer.bake import BakeOptions, bake, cache_folder, read_manifest
from lightprobe.viewer.server import ViewServer, safe_file

pytestmark = pytest.mark.xdist_group("viewer")  # one worker: one bake, one browser
LUMA = np.array([0.2126, 0.7152, 0.0722])
BRDF = "ggx:alpha=0.2,conductor=gold"
OPTIONS = BakeOptions(brdfs=(BRDF,), views=12, map_size=48)
SIZE = 96


@pytest.fixture(scope="module")
def inputs():
    return shared("ict_lowres/grace.hdr"), shared("meshes/stanford/bun_zipper_res3.ply")


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("view-cache")


@pytest.fixture(scope="module")
def baked(inputs, cache):
    probe, mesh = inputs
    folder = cache_folder(probe, mesh, OPTIONS, cache)
    doc = bake(read_envmap(probe), folder, mesh, OPTIONS, source=probe.name)
    return folder, doc


@pytest.fixture(scope="module")
def page(baked):
    from lightprobe_engines.viewer_page import ViewerPage

    with ViewerPage(baked[0]) as p:
        yield p
        assert not [e for e in p.errors if "favicon" not in e and "404" not in e], p.errors


@pytest.fixture(scope="module")
def scene(inputs):
    from lightprobe.render.scene import mesh_scene

    probe, mesh = inputs
    return mesh_scene(mesh, read_envmap(probe), SIZE, SIZE, turn_to_key_light=False)


def interior(alpha: np.ndarray) -> np.ndarray:
    """Covered pixels whose 3×3 neighbours all show the same surface (silhouettes sample other surfaces)."""
    ids = np.pad(np.rint(alpha), 1, mode="edge")
    same = np.ones(alpha.shape, bool)
    for dy in range(3):
        for dx in range(3):
            same &= ids[dy:dy + alpha.shape[0], dx:dx + alpha.shape[1]] == np.rint(alpha)
    return same & (alpha > 0.5)


def mean_relative(a: np.ndarray, b: np.ndarray, where: np.ndarray) -> float:
    """Mean over ``where`` of |a − b| / b on luminance."""
    ya, yb = a[where] @ LUMA, b[where] @ LUMA
    return float(np.mean(np.abs(ya - yb) / np.maximum(yb, 1e-12)))


# ---- the page against the Python renderer and three.js ------------------------------------------------------------
@pytest.mark.parametrize("per_vertex", [False, True])
def test_eq13_in_webgl_equals_python_sh_render(page, scene, per_vertex):
    from lightprobe.render.methods import SHMethod
    from lightprobe.render.renderer import render

    gpu = page.render("sh-vertex" if per_vertex else "sh", width=SIZE, height=SIZE)
    python = render(scene, SHMethod(2, per_vertex=per_vertex))
    where = interior(gpu[..., 3]) & (python.coverage == 1)
    assert where.sum() > 0.3 * SIZE * SIZE
    err = mean_relative(gpu[..., :3], python.image, where)
    print(f"eq. 13 {'per vertex' if per_vertex else 'per pixel'}: WebGL vs Python mean relative error {err:.4%}")
    assert err < 0.02


def test_threejs_lightprobe_equals_our_eq13_shader(page):
    ours = page.render("sh", width=SIZE, height=SIZE)
    three = page.render("threejs", width=SIZE, height=SIZE)
    where = interior(ours[..., 3]) & (three[..., 3] > 0.5)
    err = mean_relative(three[..., :3], ours[..., :3], where)
    print(f"three.js LightProbe (threejs export) vs lightprobe's eq. 13 shader: {err:.4%}")
    assert where.sum() > 0.3 * SIZE * SIZE and err < 0.01
    # and the export is what makes it so: a mirrored frame lights the other side, far off
    turned = page.render("threejs", width=SIZE, height=SIZE, rotation=180)
    assert mean_relative(turned[..., :3], ours[..., :3], where) > 0.05


def test_environment_rotation_turns_every_method_alike(page):
    ours = page.render("sh", width=64, height=64, rotation=70)
    three = page.render("threejs", width=64, height=64, rotation=70)
    where = interior(ours[..., 3]) & (three[..., 3] > 0.5)
    assert mean_relative(three[..., :3], ours[..., :3], where) < 0.01


def test_gpu_synthesised_radiance_map_equals_radiance_synthesize(page, baked, tmp_path):
    from lightprobe.glossy.brdf import parse_brdf
    from lightprobe.glossy.radiancefile import RadianceSet, write_radiance_set

    folder, doc = baked
    part = doc["brdfs"][0]
    n, s = part["maps"]["shape"][:2]
    maps = np.fromfile(folder / part["maps"]["file"], dtype="<f4").reshape(n, s, s, 3)
    frames = np.array(part["frames"])
    rset = RadianceSet(parse_brdf(part["spec"]), np.array(part["views"]), frames,
                       tuple(EnvMap(m, Sphere(f)) for m, f in zip(maps, frames)), np.array(part["triangles"]), {})
    write_radiance_set(tmp_path / "set", rset)
    valid = Sphere().valid_mask((s, s))
    for view in ([0.3, 0.4, 0.85], [-0.8, -0.2, 0.3]):
        v = np.array(view) / np.linalg.norm(view)
        assert main(["radiance", str(tmp_path / "set"), "--synthesize=" + ",".join(map(str, v)),
                     "-o", str(tmp_path / "synth.exr")]) == 0
        python = read_envmap(tmp_path / "synth.exr", "sphere").data
        gpu = page.synthesize(v)
        err = float(np.mean(np.abs(gpu[valid] - python[valid]).sum(-1)) / np.mean(python[valid].sum(-1)))
        print(f"GPU synthesis (tessellated disc, one vertex per texel) vs lightprobe radiance --synthesize, view "
              f"{np.round(v, 2)}: relative L1 {err:.1e}")
        assert err < 0.01
        coarse = page.synthesize(v, stride=4)  # the disc tessellated every 4th texel: the paper's coarser mesh
        print(f"  every 4th texel: {np.mean(np.abs(coarse[valid] - python[valid]).sum(-1)) / np.mean(python[valid].sum(-1)):.4%}")


@pytest.mark.parametrize("name, options, tolerance", [
    # the page synthesises as the paper does (the smooth part warped with the rest): so is the Python renderer here
    ("rsibr", {"views": 12, "map_size": 48, "smooth": False}, 0.02),
    ("rsibr-pixel", {"views": 12, "map_size": 48, "per_pixel_view": True, "smooth": False}, 0.02),
    ("splitsum", {}, 0.05)])
def test_glossy_methods_in_webgl_equal_the_python_renderer(page, scene, name, options, tolerance):
    """The bunny in gold alone (no ground): the page's method against lightprobe.render's of the same name."""
    from dataclasses import replace

    from lightprobe.glossy.brdf import parse_brdf
    from lightprobe.render.methods import method
    from lightprobe.render.renderer import render
    from lightprobe.render.scene import Material

    gold = replace(scene, meshes=tuple(replace(m, material=Material(brdf=parse_brdf(BRDF))) for m in scene.meshes
                                       if m.name != "ground"))
    python = render(gold, method("splitsum" if name == "splitsum" else "rsibr", **options))
    gpu = page.render(name, width=SIZE, height=SIZE, ground=False)
    where = interior(gpu[..., 3]) & (python.coverage == 1)
    err = mean_relative(gpu[..., :3], python.image, where)
    print(f"{name}: WebGL vs Python mean relative error {err:.3%} over {where.sum()} px")
    assert where.sum() > 0.15 * SIZE * SIZE and err < tolerance


def test_glossy_methods_draw_the_material(page):
    for method in ("rsibr", "rsibr-pixel", "splitsum"):
        img = page.render(method, width=64, height=64)
        objects = img[..., 3] == 1
        gold = img[objects, :3].mean(0)
        assert objects.sum() > 200 and gold[0] > gold[2] * 1.5, (method, gold)  # gold reflects red over blue


def test_soft_shadow_of_the_bunny_where_the_python_lights_render_has_it(page, scene):
    from dataclasses import replace

    from lightprobe.render.methods import LightsMethod
    from lightprobe.render.renderer import render

    method = LightsMethod(light_samples=32)
    python = render(scene, method).image
    ground_only = replace(scene, meshes=tuple(m for m in scene.meshes if m.name == "ground"))
    python_lit = render(ground_only, method).image
    gpu = page.render("lights", width=SIZE, height=SIZE)
    gpu_lit = page.render("lights", width=SIZE, height=SIZE, shadows=False)
    ground = interior(gpu[..., 3]) & (np.rint(gpu[..., 3]) == 2)
    f_python = (python @ LUMA) / np.maximum(python_lit @ LUMA, 1e-12)
    f_gpu = (gpu[..., :3] @ LUMA) / np.maximum(gpu_lit[..., :3] @ LUMA, 1e-12)
    shadow_python, shadow_gpu = ground & (f_python < 0.8), ground & (f_gpu < 0.8)
    overlap = (shadow_python & shadow_gpu).sum() / max((shadow_python | shadow_gpu).sum(), 1)
    lit = ground & (f_python > 0.97)
    ratio_python = (python[shadow_python] @ LUMA).mean() / (python[lit] @ LUMA).mean()
    ratio_gpu = (gpu[shadow_python, :3] @ LUMA).mean() / (gpu[lit, :3] @ LUMA).mean()
    print(f"shadow on the ground: {shadow_python.sum()} px (Python) vs {shadow_gpu.sum()} px (WebGL), overlap "
          f"{overlap:.2f}; shadowed/unshadowed {ratio_python:.3f} (Python) vs {ratio_gpu:.3f} (WebGL)")
    assert shadow_python.sum() > 50 and overlap > 0.6
    assert abs(ratio_gpu / ratio_python - 1) < 0.10


def test_frame_times_are_measured(page):
    times = {m: page.frame_time(m, size=128, frames=2) for m in ("sh", "lights", "rsibr", "rsibr-pixel")}
    print("frame time at 128² under SwiftShader (ms): " + ", ".join(f"{k} {v:.1f}" for k, v in times.items()))
    assert all(np.isfinite(v) and v > 0 for v in times.values())


def test_screenshot_shows_the_page(page, tmp_path):
    shot = page.screenshot(tmp_path / "s.png", method="basis", basis=2)
    from PIL import Image

    image = np.asarray(Image.open(shot).convert("RGB"), dtype=float)
    assert image.shape[0] > 100 and image.std() > 10


# ---- the server -----------------------------------------------------------------------------------------------------
@pytest.fixture
def server(tmp_path):
    bake_dir = tmp_path / "bake"
    (bake_dir / "sub").mkdir(parents=True)
    (bake_dir / "bake.json").write_text("{}")
    (bake_dir / "sub" / "a.f32").write_bytes(b"\0" * 8)
    (bake_dir / ".hidden").write_text("x")
    (tmp_path / "secret.txt").write_text("secret")
    (bake_dir / "link").symlink_to(tmp_path / "secret.txt")
    (bake_dir / "sublink").symlink_to(tmp_path)
    with ViewServer(bake_dir) as s:
        yield s


def request(server, method: str, path: str):
    conn = http.client.HTTPConnection(*server.address, timeout=10)
    conn.putrequest(method, path, skip_accept_encoding=True)
    conn.endheaders()
    res = conn.getresponse()
    body = res.read()
    conn.close()
    return res.status, dict(res.getheaders()), body


def test_server_binds_loopback_only(server):
    assert server.address[0] == "127.0.0.1" and server.url.startswith("http://127.0.0.1:")
    assert server.httpd.socket.getsockname()[0] == "127.0.0.1"


def test_server_serves_the_page_with_csp_and_mime_types(server):
    for path, kind in (("/", "text/html"), ("/static/viewer.js", "text/javascript"),
                       ("/static/viewer.css", "text/css"), ("/bake/bake.json", "application/json"),
                       ("/bake/sub/a.f32", "application/octet-stream"),
                       ("/modules/three/build/three.module.js", "text/javascript")):
        status, headers, _ = request(server, "GET", path)
        assert status == 200 and headers["Content-Type"].startswith(kind), (path, status, headers)
        assert "default-src 'none'" in headers["Content-Security-Policy"]
        assert headers["X-Content-Type-Options"] == "nosniff"
    status, headers, body = request(server, "HEAD", "/bake/bake.json")
    assert status == 200 and body == b"" and headers["Content-Length"] == "2"


@pytest.mark.parametrize("path", [
    "/bake/../secret.txt", "/bake/%2e%2e/secret.txt", "/bake/%2E%2E%2Fsecret.txt", "/bake/..%2fsecret.txt",
    "/bake/sub/../../secret.txt", "/bake//etc/passwd", "/bake/%2fetc%2fpasswd", "/bake/%5c..%5csecret.txt",
    "/bake/link", "/bake/sublink/secret.txt", "/bake/.hidden", "/bake/", "/bake/sub", "/bake/sub/",
    "/static/", "/static/../server.py", "/static/%2e%2e/server.py", "/modules/three/package.json",
    "/modules/three/../../package.json", "/modules/", "/etc/passwd", "//etc/passwd", "/bake/bake.json%00.png",
    "http://example.com/bake/bake.json", "*"])
def test_server_refuses_traversal_listings_and_strays(server, path):
    status, headers, body = request(server, "GET", path)
    expected = 421 if path.startswith("http://") else 404  # an absolute URL names its host: another one here
    assert status == expected and b"secret" not in body and b"<a href" not in body, (path, status)


@pytest.mark.parametrize("method", ["POST", "PUT", "DELETE", "PATCH", "OPTIONS"])
def test_server_answers_get_and_head_only(server, method):
    status, headers, _ = request(server, method, "/bake/bake.json")
    assert status == 405 and headers["Allow"] == "GET, HEAD"


def test_safe_file_needs_a_regular_file_inside(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "f").write_text("x")
    assert safe_file(tmp_path, "a/f") == (tmp_path / "a" / "f").resolve()
    for rel in ("a", "a/", "", "../a/f", "a/../a/f", "a\\f", "a/f\x00", "/a/f"):
        assert safe_file(tmp_path, rel) is None, rel


# ---- the command ----------------------------------------------------------------------------------------------------
def test_view_refuses_oversized_inputs_before_baking(inputs, tmp_path, monkeypatch, capsys):
    probe, mesh = inputs
    monkeypatch.setenv("LIGHTPROBE_VIEW_MAX_TRIANGLES", "100")
    assert main(["view", str(probe), "--mesh", str(mesh), "--cache", str(tmp_path / "c")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "triangles is over its limit" in err[0]
    monkeypatch.delenv("LIGHTPROBE_VIEW_MAX_TRIANGLES")
    monkeypatch.setenv("LIGHTPROBE_VIEW_MAX_PIXELS", "1000")
    assert main(["view", str(probe), "--cache", str(tmp_path / "c")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "pixels is over its limit" in err[0]
    assert not (tmp_path / "c").exists()


def test_view_refuses_bad_options(inputs, tmp_path, capsys):
    probe, _ = inputs
    for argv in (["--views", "13"], ["--brdf", "ggx:alpha=-1"], ["--port", "70000"], ["--mesh", str(tmp_path)]):
        assert main(["view", str(probe), "--cache", str(tmp_path / "c"), *argv]) == 2, argv
        assert len(capsys.readouterr().err.strip().splitlines()) == 1
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "x").write_text("x")
    assert main(["view", str(probe), "--export", str(tmp_path / "full")]) == 2


def _argv(inputs, cache):
    probe, mesh = inputs
    return [str(probe), "--mesh", str(mesh), "--brdf", BRDF, "--map-size", "48", "--cache", str(cache)]


def test_view_export_writes_a_static_folder(baked, inputs, cache, tmp_path):
    out = tmp_path / "site"
    assert main(["view", *_argv(inputs, cache), "--export", str(out)]) == 0
    for rel in ("index.html", "static/viewer.js", "static/shaders.js", "modules/three/build/three.module.js",
                "modules/three/examples/jsm/controls/OrbitControls.js", "bake/bake.json", "bake/mesh.glb"):
        assert (out / rel).is_file(), rel
    assert "Content-Security-Policy" in (out / "index.html").read_text()
    assert read_manifest(out / "bake") is not None
    assert not list(tmp_path.glob(".site.tmp-*"))


def _start_view(argv) -> subprocess.Popen:
    """``lightprobe view`` as a terminal starts it: SIGINT at its default action, whatever this runner inherited (a
    runner started as a background job, or an xdist worker, may ignore SIGINT, and Python then keeps ignoring it)."""
    env = {**os.environ, "LIGHTPROBE_PROGRESS": "0"}
    return subprocess.Popen([str(Path(sys.executable).parent / "lightprobe"), "view", *argv], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


@pytest.mark.parametrize("moment", ["at-once", "after-a-request", "twice"])
def test_view_serves_until_ctrl_c(baked, inputs, cache, moment):
    """Ctrl-C at any moment once the URL is shown — at once, after a request, twice in a row — stops the server:
    status 0, "stopped", no traceback."""
    proc = _start_view(_argv(inputs, cache))
    try:
        line = proc.stdout.readline()
        assert "http://127.0.0.1:" in line, (line, proc.stderr.read() if proc.poll() is not None else "")
        if moment == "after-a-request":
            host, port = line.split()[2].split("//")[1].rstrip("/").split(":")
            conn = http.client.HTTPConnection(host, int(port), timeout=60)
            conn.request("GET", "/bake/bake.json")
            assert json.loads(conn.getresponse().read())["format"] == "lightprobe.view"
        proc.send_signal(signal.SIGINT)
        if moment == "twice":
            proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0 and err.strip().endswith("lightprobe view: stopped"), (proc.returncode, err)
    assert "Traceback" not in err


def test_view_ctrl_c_while_baking_is_an_interruption_that_leaves_no_partial_bake(inputs, tmp_path):
    """Before the URL, Ctrl-C interrupts: status 130, one line, and the cache holds no partial bake."""
    probe, mesh = inputs
    cache = tmp_path / "cache"
    proc = _start_view([str(probe), "--mesh", str(mesh), "--brdf", BRDF, "--map-size", "256", "--views", "42",
                        "--cache", str(cache)])
    try:
        line = proc.stderr.readline()
        while line and not line.startswith("baking into "):
            line = proc.stderr.readline()
        assert line.startswith("baking into "), proc.stderr.read()
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=600)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130 and err.strip().splitlines() == ["lightprobe: error: interrupted"], err
    assert out == ""
    folder = Path(line[len("baking into "):].rsplit(" ", 1)[0])
    assert folder.parent == cache
    assert not folder.exists() or read_manifest(folder) is not None  # nothing, or a whole bake
    assert not list(cache.glob(".*tmp-*"))


def test_bake_is_cached_by_content(baked, inputs, cache):
    probe, mesh = inputs
    folder, doc = baked
    assert cache_folder(probe, mesh, OPTIONS, cache) == folder
    assert cache_folder(probe, None, OPTIONS, cache) != folder
    assert cache_folder(probe, mesh, BakeOptions(brdfs=(), map_size=48), cache) != folder
    assert doc["format"] == "lightprobe.view" and doc["lights"]["count"] >= 1
    assert not list(cache.glob(".*tmp-*"))


def test_a_person_can_drag_switch_and_slide(page):
    """The page's own controls, through real mouse and keyboard events: each changes what the canvas shows."""
    p = page.page
    canvas = p.locator("#canvas")

    def shot():  # once the frame the last event asked for is drawn (the page draws on demand)
        p.wait_for_function("!window.lightprobe.viewer.pending", timeout=120000)
        return canvas.screenshot()

    p.select_option("#method", "sh")
    before = shot()
    box = canvas.bounding_box()
    x, y = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    p.mouse.move(x, y)
    p.mouse.down()
    p.mouse.move(x - 80, y - 20, steps=5)
    p.mouse.up()
    dragged = shot()
    assert dragged != before
    p.select_option("#method", "lights")
    assert shot() != dragged
    p.select_option("#method", "sh")
    plain = shot()
    p.locator("#design input").nth(2).fill("-2")  # L10 × −2
    assert shot() != plain
    assert p.locator("#readout").inner_text().startswith("sh:") and "ms/frame" in p.locator("#readout").inner_text()
    p.click("#reset")
    p.locator("#rotation").fill("45")
    assert shot() != plain
    p.locator("#rotation").fill("0")


def test_fuzz_paths_never_leave_the_bake(tmp_path_factory):
    from hypothesis import given, settings, strategies as st

    root = tmp_path_factory.mktemp("fuzz-root")
    (root / "bake").mkdir()
    (root / "bake" / "ok.json").write_text("{}")
    (root / "outside.txt").write_text("x")
    (root / "bake" / "out").symlink_to(root / "outside.txt")
    alphabet = st.sampled_from(["..", ".", "/", "%2e", "%2f", "%5c", "\\", "\x00", "ok.json", "out", "bake", "~",
                                "a", "%", "%00", "//", "%252e"])

    @given(st.lists(alphabet, max_size=8))
    @settings(max_examples=300, deadline=None)
    def check(parts):
        from urllib.parse import unquote

        got = safe_file(root / "bake", unquote("".join(parts)))
        assert got is None or got == (root / "bake" / "ok.json").resolve()

    check()


def test_fuzz_manifest_reader_never_raises(tmp_path_factory):
    from hypothesis import given, settings, strategies as st

    folder = tmp_path_factory.mktemp("fuzz-manifest")

    @given(st.one_of(st.binary(max_size=200), st.text(max_size=200).map(str.encode),
                     st.recursive(st.none() | st.booleans() | st.integers() | st.text(max_size=8),
                                  lambda c: st.lists(c, max_size=3) | st.dictionaries(st.text(max_size=8), c, max_size=3),
                                  max_leaves=8).map(lambda v: json.dumps(v).encode())))
    @settings(max_examples=200, deadline=None)
    def check(data):
        (folder / "bake.json").write_bytes(data)
        assert read_manifest(folder) is None

    check()
