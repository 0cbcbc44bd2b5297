"""The renderer and its Mitsuba 3 ground truth: same camera, geometry and environment orientation; brute force equal
to Mitsuba on an unshadowed sphere; SH's error against Mitsuba equal to its error against brute force."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import shared
from lightprobe.maps import EnvMap, box_reduce, read_envmap
from lightprobe.util.errors import InputError, LightprobeError
from lightprobe.maps.layouts import LATLONG
from lightprobe.render.compare import compare, mare, relative_mse
from lightprobe.render.methods import method
from lightprobe.render.raycast import Tracer
from lightprobe.render.reference import mitsuba_latlong, reference_coverage, reference_render
from lightprobe.render.renderer import render
from lightprobe.render.scenefile import load_scene
from lightprobe.render.scene import Camera, Material, Scene, ground_plane, mesh_instance, mesh_scene, sphere, sphere_scene, with_key_light_at, key_light_azimuth
from test_envmap import spot_map


def spot_environment(direction, ambient: float = 0.02) -> EnvMap:
    env = spot_map("latlong", direction, width_deg=8.0, size=64)
    return EnvMap(env.data + ambient, LATLONG)


# ---- camera and rays ------------------------------------------------------------------------------------------------
def test_camera_rays():
    cam = Camera(eye=(0, 0, 5), target=(0, 0, 0), fov=60, width=3, height=3)
    _, d = cam.rays()
    assert np.allclose(d[1, 1, 0], [0, 0, -1])  # centre pixel looks at the target
    assert d[0, 1, 0, 1] > 0 and d[1, 2, 0, 0] > 0  # row 0 is the top, column right is +X
    top_edge = Camera(eye=(0, 0, 5), target=(0, 0, 0), fov=60, width=1, height=1_000)
    _, d = top_edge.rays()
    angle = np.degrees(np.arccos(-d[0, 0, 0, 2]))
    assert abs(angle - 30) < 0.1  # half the vertical field of view at the top row


def test_sphere_hits_have_exact_normals_and_face_the_viewer():
    s = Scene((sphere(0.5, (0.2, 0.1, -0.3), subdivisions=5),), Camera(eye=(0, 0, 3), target=(0.2, 0.1, -0.3)),
              spot_environment([0, 1, 0]))
    tracer = Tracer(s)
    o, d = s.camera.rays()
    hits = tracer.first_hits(o.reshape(-1, 3), d.reshape(-1, 3))
    radial = (hits.position - [0.2, 0.1, -0.3]) / 0.5
    assert np.abs(np.linalg.norm(radial, axis=1) - 1).max() < 2e-3  # on the sphere (tessellation)
    assert np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", hits.normal, radial / np.linalg.norm(radial, axis=1,
                                                                                                 keepdims=True)), -1, 1))).max() < 1.0
    assert (np.einsum("ij,ij->i", hits.normal, d.reshape(-1, 3)[hits.ray]) < 0).all()


def test_shadow_rays():
    """A light above a sphere resting on a plane: the plane under the sphere is occluded, far from it it is not."""
    s = Scene((sphere(0.5, (0, 0.5, 0)), ground_plane(10.0, 0.0)), Camera(), spot_environment([0, 1, 0]))
    tracer = Tracer(s)
    o, d = np.array([[0.0, 3.0, 0.0], [3.0, 3.0, 0.0]]), np.array([[0.0, -1.0, 0.0], [0.0, -1.0, 0.0]])
    hits = tracer.first_hits(o, d)
    assert np.allclose(hits.position[:, 1], [1.0, 0.0], atol=1e-3)  # the sphere's top, then the plane
    under = np.array([[0.0, 0.0, 0.0]]) + [0, 1e-4, 0]
    assert tracer.occluded(under, [[0.0, 1.0, 0.0]]).tolist() == [True]
    assert tracer.occluded(tracer.shadow_origins(hits)[1:], [[0.0, 1.0, 0.0]]).tolist() == [False]
    assert tracer.occluded(tracer.shadow_origins(hits)[:1], [[0.0, 1.0, 0.0]]).tolist() == [False]  # no self-hit


# ---- agreement with Mitsuba -----------------------------------------------------------------------------------------
def luminance_centroid(image: np.ndarray) -> np.ndarray:
    lum = image @ [0.2126, 0.7152, 0.0722]
    rows, cols = np.indices(lum.shape)
    return np.array([(lum * rows).sum(), (lum * cols).sum()]) / lum.sum()


@pytest.mark.parametrize("direction", [[0.8, 0.35, 0.45], [-0.3, -0.5, 0.8], [0.1, 0.9, -0.4]])
def test_a_bright_spot_lights_the_same_side_of_a_sphere_in_both_renderers(direction):
    env = spot_environment(direction)
    s = sphere_scene(env, 40)
    s = Scene(s.meshes, s.camera, env, background=False)
    ours = render(s, method("brute"), spp=2).image
    theirs = reference_render(s, spp=64).image
    a, b = luminance_centroid(ours), luminance_centroid(theirs)
    assert np.linalg.norm(a - b) < 1.0, (a, b)
    # and it is the side the light is on: right for +x, top for +y (image rows grow downward)
    centre = np.array([19.5, 19.5])
    expected = np.sign([-direction[1], direction[0]])
    assert (np.sign(a - centre) == expected).all()


def test_silhouettes_match():
    """Camera and geometry agree: with no background, the pixels Mitsuba lights are the pixels we hit."""
    env = spot_environment([0.0, 1.0, 0.5], ambient=0.3)
    scene = mesh_scene(shared("meshes/stanford/bun_zipper_res3.ply"), env, 64, 64, ground=False,
                       turn_to_key_light=False)
    ours = render(scene, method("sh"), spp=8).coverage
    theirs = reference_coverage(scene, spp=256)
    assert np.abs(ours - theirs).mean() < 0.01  # edge pixels agree to their sampling noise
    assert (np.abs(ours - theirs) < 0.25).mean() > 0.99


@pytest.fixture(scope="module")
def unshadowed():
    """An unshadowed sphere under Grace and under a Poly Haven probe: brute force, SH9 and Mitsuba."""
    out = {}
    for name, path in (("grace", "debevec/angular/grace_probe.hdr"), ("rooitou", "polyhaven_1k/rooitou_park_1k.hdr")):
        env = box_reduce(read_envmap(shared(path)))
        scene = sphere_scene(env, 40)
        out[name] = (render(scene, method("brute"), spp=2), render(scene, method("sh"), spp=2),
                     reference_render(scene, spp=4096))
    return out


@pytest.mark.parametrize("probe", ["grace", "rooitou"])
def test_brute_force_equals_mitsuba_on_an_unshadowed_sphere(unshadowed, probe):
    brute, _, reference = unshadowed[probe]
    inside = brute.coverage == 1
    assert relative_mse(brute.image, reference.image, np.broadcast_to(inside[..., None], brute.image.shape)) < 1e-3


@pytest.mark.parametrize("probe", ["grace", "rooitou"])
def test_sh_error_against_mitsuba_is_its_error_against_brute_force(unshadowed, probe):
    """The per-pixel SH error measured against Mitsuba equals the SH-vs-brute irradiance error (within MC noise):
    both the renderer and the SH code are cross-checked."""
    brute, sh, reference = unshadowed[probe]
    inside = brute.coverage == 1
    lum = lambda im: (im @ [0.2126, 0.7152, 0.0722])[inside]  # noqa: E731
    err_ref = (lum(sh.image) - lum(reference.image)) / lum(reference.image)
    err_brute = (lum(sh.image) - lum(brute.image)) / lum(brute.image)
    noise = np.abs(lum(brute.image) - lum(reference.image)) / lum(reference.image)
    assert np.abs(err_ref - err_brute).mean() < 1.5 * noise.mean() + 1e-3
    assert np.abs(err_brute).mean() > 2 * noise.mean()  # the SH error is real, above the noise


def test_per_vertex_sh_is_close_to_per_pixel_on_a_fine_sphere():
    env = box_reduce(read_envmap(shared("debevec/angular/grace_probe.hdr")))
    scene = sphere_scene(env, 48)
    a = render(scene, method("sh"), spp=1).image
    b = render(scene, method("sh", per_vertex=True), spp=1).image
    assert mare(b, a) < 0.01


def test_mitsuba_environment_is_a_half_turn():
    env = spot_environment([0, 0, -1])  # the front
    rolled = mitsuba_latlong(env)
    row = rolled[32] @ [1, 1, 1]
    assert abs(int(np.argmax(row)) - 0) <= 1 or abs(int(np.argmax(row)) - 127) <= 1  # Mitsuba's u = 0 is −Z


def test_textures_land_the_same_way_in_both_renderers():
    """An asymmetric texture (red top-left quadrant) on a quad facing the camera: a v or u flip would show."""
    texture = np.full((8, 8, 3), 0.2, np.float32)
    texture[:4, :4] = [0.9, 0.1, 0.1]  # top-left of the image = uv (0, 1) in OBJ convention
    quad = mesh_instance([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], [[0, 1, 2], [0, 2, 3]],
                         Material((0.5, 0.5, 0.5), texture), normals=np.tile([0, 0, 1.0], (4, 1)),
                         uv=[[0, 0], [1, 0], [1, 1], [0, 1]])
    white = EnvMap(np.ones((16, 32, 3), np.float32), LATLONG)
    scene = Scene((quad,), Camera(eye=(0, 0, 4), target=(0, 0, 0), fov=30, width=32, height=32), white, False)
    ours = render(scene, method("brute"), spp=2).image
    theirs = reference_render(scene, spp=64).image
    assert ours[9, 9, 0] > 2 * ours[9, 9, 1] and ours[22, 22, 0] < 1.5 * ours[22, 22, 1]  # red at top-left only
    inner = (slice(6, 26), slice(6, 26))
    assert relative_mse(ours[inner], theirs[inner]) < 5e-3


def test_global_illumination_adds_light():
    env = box_reduce(read_envmap(shared("polyhaven_1k/studio_small_03_1k.hdr")))
    scene = mesh_scene(shared("meshes/stanford/bun_zipper_res4.ply"), env, 24, 24)
    direct = reference_render(scene, spp=32).image.mean()
    full = reference_render(scene, spp=32, global_illumination=True).image.mean()
    assert full > direct


# ---- metrics ------------------------------------------------------------------------------------------------------
def test_metrics():
    rng = np.random.default_rng(0)
    ref = rng.random((16, 16, 3)) + 0.5
    m = compare(ref, ref)
    assert m.relative_mse == 0 and m.mare == 0 and m.flip < 1e-6
    scaled = compare(ref * 1.1, ref)
    assert abs(scaled.mare - 0.1) < 2e-3 and abs(scaled.relative_mse - 0.01) < 5e-4 and scaled.flip > 0


# ---- scenes -------------------------------------------------------------------------------------------------------
def test_scene_files(tmp_path):
    (tmp_path / "s.yaml").write_text(
        f"camera: {{eye: [0, 0.5, 2.5], target: [0, 0.3, 0], fov: 30, width: 32, height: 24}}\n"
        f"meshes:\n  - {{file: {shared('meshes/stanford/bun_zipper_res4.ply')}, fit: 0.8, albedo: [0.7, 0.6, 0.5]}}\n"
        f"  - {{shape: sphere, radius: 0.2, center: [0.6, 0.2, 0]}}\nground: {{albedo: [0.4, 0.4, 0.4]}}\n")
    scene = load_scene(tmp_path / "s.yaml")
    assert len(scene.meshes) == 3 and scene.camera.width == 32
    bunny = scene.meshes[0]
    assert abs(np.ptp(bunny.vertices, axis=0).max() - 0.8) < 1e-9 and abs(bunny.vertices[:, 1].min()) < 1e-9
    (tmp_path / "s.json").write_text(json.dumps({"meshes": [{"shape": "torus"}], "ground": False}))
    assert [m.name for m in load_scene(tmp_path / "s.json").meshes] == ["torus"]


@pytest.mark.parametrize("text,words", [
    ("meshes: [{file: nope.ply}]", "no such file"),
    ("meshes: [{shape: sphere, albedo: [2, 0, 0]}]", "albedo"),
    ("camera: {width: 0}", "camera.width must be within 1..16384"),
    ("meshes: [{}]", "needs a file or a shape"),
    ("camera: {eye: [0, 0, 0], target: [0, 0, 0]}", "collinear"),
    ("meshes: {{{", "cannot read scene"),
    ("[1, 2]", "mapping"),
])
def test_bad_scenes_are_clean_errors(tmp_path, text, words):
    (tmp_path / "bad.yaml").write_text(text)
    with pytest.raises(LightprobeError, match=words):
        load_scene(tmp_path / "bad.yaml", spot_environment([0, 1, 0]))


def test_key_light_turn():
    env = spot_environment([1.0, 0.3, 0.0])  # light at azimuth +90°
    assert abs(key_light_azimuth(env) - 90) < 3
    assert abs(key_light_azimuth(with_key_light_at(env, -135.0)) + 135) < 3


def test_render_cli(tmp_path, capsys):
    from test_cli import run

    from lightprobe.maps.images import read_image

    code, out, _ = run(capsys, "render", "-o", tmp_path / "r.exr", "--size", "24x16", "--spp", 1)
    assert code == 0 and read_image(tmp_path / "r.exr").shape == (16, 24, 3)
    code, out, _ = run(capsys, "render", "-o", tmp_path / "m.exr", "--size", "24x16", "-m", "reference", "--spp", 16)
    assert code == 0
    code, out, _ = run(capsys, "compare", tmp_path / "r.exr", tmp_path / "m.exr", "--json", "--heatmap",
                       tmp_path / "h.png")
    metrics = json.loads(out)
    assert code == 0 and set(metrics) == {"relative_mse", "mare", "flip", "pixels"} and (tmp_path / "h.png").exists()
    with pytest.raises(InputError):
        from lightprobe.render.scene import load_mesh
        load_mesh(tmp_path / "r.exr")


@pytest.mark.parametrize("name, content, words", [
    ("binary.obj", bytes(range(256)) * 8, "not a text OBJ file (bytes that are not UTF-8 at offset 128)"),
    ("hole.obj", b"v 1 2 3\nf 1 2 3\n", "a face names a vertex that is not in the file"),
    ("short.ply", b"ply\nformat ascii 1.0\nelement vertex 3\nend_header\n", "malformed PLY"),
    ("empty.obj", b"", "cannot read mesh"),
])
def test_a_bad_mesh_file_is_one_line_that_says_what_is_wrong(tmp_path, capsys, name, content, words):
    """trimesh's own messages name its internals (a missing encoding guesser, an index out of bounds); the
    command says what is wrong with the file instead, in one line, exit 2."""
    from test_cli import run

    (tmp_path / name).write_bytes(content)
    code, _, err = run(capsys, "render", tmp_path / name, "-o", tmp_path / "r.exr", "--size", "16x16")
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and words in lines[0] and "module" not in lines[0], lines
    assert not (tmp_path / "r.exr").exists()


@pytest.mark.parametrize("chunk", [1, 3, 7, 87, 1 << 20])
def test_the_utf8_check_names_the_first_bad_byte_whatever_the_chunks(tmp_path, chunk):
    from lightprobe.render.scene import _check_utf8

    for junk in (b"\xff", "é".encode()[:1] + b"A"):  # a bad byte; a character cut short
        data = b"v 1 2 3\n" * 10 + "é".encode() * 3 + junk
        (tmp_path / "m.obj").write_bytes(data)
        with pytest.raises(InputError, match=r"at offset 86\)"):
            _check_utf8(tmp_path / "m.obj", chunk=chunk)
    (tmp_path / "m.obj").write_bytes(b"v 1 2 3\n" + "é".encode() * 5)
    _check_utf8(tmp_path / "m.obj", chunk=chunk)  # multi-byte characters across chunks are fine
