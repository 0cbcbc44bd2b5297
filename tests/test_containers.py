"""Engines' environment containers (lightprobe.exports.containers): RGBD, Babylon .env and glTF EXT_lights_image_based.

These check the files' structure and numbers against the formats as the engines read them; that Babylon itself
loads and renders them as its own panorama is tests/test_engines.py."""

from __future__ import annotations

import base64
import io
import json
import struct

import numpy as np
import pytest
from PIL import Image

from conftest import shared
from lightprobe.exports.containers import ENV_MAGIC, GAMMA, babylon_env, glb, gltf_embedded, gltf_ibl, read_env_manifest, rgbd_clipped, rgbd_decode, rgbd_encode
from lightprobe.maps import read_envmap
from lightprobe.exports.sh import babylon_polynomial, gltf_coefficients
from lightprobe.glossy.prefilter import babylon_alphas, prefilter_cube
from lightprobe.maps.frames import BABYLON
from lightprobe.sh.basis import project


@pytest.fixture(scope="module")
def probe():
    env = read_envmap(shared("polyhaven_1k/venice_sunset_1k.hdr"))
    return env, project(env, 2)


def png_rgba(data: bytes) -> np.ndarray:
    image = Image.open(io.BytesIO(data))
    assert image.format == "PNG" and image.mode == "RGBA"
    return np.asarray(image)


def test_rgbd_encode_is_babylons_to_rgbd():
    """Babylon: D = clamp(floor(max(255/max, 1))/255, 0, 1), rgb = (c D)^(1/2.2); values ≤ 1 keep D = 1."""
    assert rgbd_encode(np.array([0.5, 0.25, 0.0])).tolist() == [round(255 * 0.5 ** (1 / GAMMA)),
                                                                round(255 * 0.25 ** (1 / GAMMA)), 0, 255]
    # 10: D = floor(25.5)/255 = 25/255, c D = 250/255
    assert rgbd_encode(np.array([10.0, 0.0, 0.0])).tolist() == [round(255 * (250 / 255) ** (1 / GAMMA)), 0, 0, 25]
    assert rgbd_encode(np.array([1e6, 0, 0])).tolist() == [255, 0, 0, 1]  # clamped at 255
    assert rgbd_encode(np.array([np.nan, -1.0, 0.0])).tolist() == [0, 0, 0, 255]


def test_rgbd_round_trip_within_eight_bit_precision():
    rng = np.random.default_rng(0)
    values = np.exp(rng.uniform(np.log(0.02), np.log(250), size=(5000, 1))) * rng.uniform(0.5, 1, size=(5000, 3))
    error = np.abs(rgbd_decode(rgbd_encode(values)) - values).max(axis=1) / values.max(axis=1)
    assert error.max() < 0.03 and np.median(error) < 0.01, (error.max(), np.median(error))


def test_env_file_is_babylons_layout(probe):
    env, sh = probe
    data = babylon_env(env, sh, 16)
    assert data[:8] == ENV_MAGIC
    manifest = read_env_manifest(data)
    assert manifest["version"] == 2 and manifest["width"] == 16 and manifest["imageType"] == "image/png"
    assert manifest["specular"]["lodGenerationScale"] == 0.8
    mips = manifest["specular"]["mipmaps"]
    assert len(mips) == 6 * 5  # Babylon refuses any other count (CreateRadianceImageDataArrayBufferViews)
    start = manifest["binaryDataPosition"]
    assert mips[0]["position"] == 0 and start + mips[-1]["position"] + mips[-1]["length"] == len(data)
    for a, b in zip(mips, mips[1:]):
        assert a["position"] + a["length"] == b["position"]
    polynomial = babylon_polynomial(sh, BABYLON)
    for key, value in manifest["irradiance"].items():
        assert np.allclose(value, polynomial[key], rtol=1e-12)
    chain = prefilter_cube(env, 16, babylon_alphas(16, 0.8), BABYLON)
    for i, m in enumerate(mips):
        level, face = divmod(i, 6)
        rgba = png_rgba(data[start + m["position"]:start + m["position"] + m["length"]])
        assert rgba.shape == (16 >> level, 16 >> level, 4)
        decoded = rgbd_decode(rgba[::-1])  # stored bottom row first (Babylon uploads with invertY)
        expected = np.minimum(chain.levels[level][face], 255)
        assert np.abs(decoded - expected).max() <= 0.02 * max(expected.max(), 1e-3) + 1e-3, (level, face)


def test_glb_holds_a_loadable_ibl(probe):
    env, sh = probe
    data = glb(*gltf_ibl(env, sh, 8))
    magic, version, length = struct.unpack_from("<III", data)
    assert (magic, version, length) == (0x46546C67, 2, len(data))
    json_length, json_type = struct.unpack_from("<II", data, 12)
    assert json_type == 0x4E4F534A and json_length % 4 == 0
    document = json.loads(data[20:20 + json_length])
    bin_length, bin_type = struct.unpack_from("<II", data, 20 + json_length)
    assert bin_type == 0x004E4942 and 28 + json_length + bin_length == len(data)
    blob = data[28 + json_length:]
    light = document["extensions"]["EXT_lights_image_based"]["lights"][0]
    assert document["scenes"][document["scene"]]["extensions"]["EXT_lights_image_based"]["light"] == 0
    assert light["specularImageSize"] == 8 and len(light["specularImages"]) == 4
    assert np.allclose(light["irradianceCoefficients"], gltf_coefficients(sh, "irradiance", BABYLON))
    chain = prefilter_cube(env, 8, babylon_alphas(8, 1.0), BABYLON)
    for level, faces in enumerate(light["specularImages"]):
        for face, index in enumerate(faces):
            view = document["bufferViews"][document["images"][index]["bufferView"]]
            assert view["byteOffset"] % 4 == 0
            rgba = png_rgba(blob[view["byteOffset"]:view["byteOffset"] + view["byteLength"]])
            # gamma space for Babylon's loader: the decoded texel is L^(1/2.2)
            decoded = rgbd_decode(rgba[::-1]) ** GAMMA
            expected = chain.levels[level][face]
            assert np.allclose(decoded, expected, rtol=0.06, atol=1e-3 * expected.max()), (level, face)


def test_embedded_gltf_holds_the_same_images(probe):
    env, sh = probe
    document, images = gltf_ibl(env, sh, 4)
    text = json.loads(gltf_embedded(document, images))
    assert "uri" not in document["images"][0]  # the caller's document is not changed
    for image, png in zip(text["images"], images):
        assert image["uri"] == "data:image/png;base64," + base64.b64encode(png).decode()


def test_clipped_share_of_a_sunny_probe_is_reported():
    env = read_envmap(shared("polyhaven_1k/rooitou_park_1k.hdr"))
    chain = prefilter_cube(env, 16)
    assert 0 < rgbd_clipped(chain) < 1
    assert rgbd_clipped(prefilter_cube(read_envmap(shared("polyhaven_1k/st_fagans_interior_1k.hdr")), 16)) == 0


# ---- the command -----------------------------------------------------------------------------------------------
def run(capsys, *argv):
    from lightprobe.cli import main

    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("name", ["probe.env", "probe.glb", "probe.gltf"])
def test_export_writes_each_container(tmp_path, capsys, name):
    target = "babylon-env" if name.endswith(".env") else "gltf"
    out = tmp_path / name
    code, text, err = run(capsys, "export", shared("polyhaven_1k/st_fagans_interior_1k.hdr"), "--to", target,
                          "-o", out, "--specular-size", "8")
    assert code == 0 and "wrote" in text and err == "", err
    data = out.read_bytes()
    if name.endswith(".env"):
        assert read_env_manifest(data)["width"] == 8
    elif name.endswith(".glb"):
        assert data[:4] == b"glTF"
    else:
        assert json.loads(data)["extensions"]["EXT_lights_image_based"]["lights"][0]["specularImageSize"] == 8
    assert [p.name for p in tmp_path.iterdir()] == [name]  # nothing else left behind


def test_export_warns_when_rgbd_clips_a_sun(tmp_path, capsys):
    code, _, err = run(capsys, "export", "--to", "babylon-env", "-o", tmp_path / "sun.env", "--specular-size", "64")
    assert code == 0 and err.count("\n") == 1 and "clipped" in err and "SH lighting keep all" in err, err


def test_export_gltf_from_coefficients_is_the_light_fragment(tmp_path, capsys):
    sh_file = tmp_path / "sh.json"
    assert run(capsys, "sh", "--order", "2", "--json", "-o", sh_file)[0] == 0
    code, _, err = run(capsys, "export", "--sh", sh_file, "--to", "gltf", "-o", tmp_path / "light.json")
    assert code == 0, err
    light = json.loads((tmp_path / "light.json").read_text())["extensions"]["EXT_lights_image_based"]["lights"][0]
    assert "specularImages" not in light and len(light["irradianceCoefficients"]) == 9


@pytest.mark.parametrize("argv, words", [
    (["--to", "babylon-env", "--specular-size", "48"], ["power of two"]),
    (["--to", "gltf", "--specular-size", "1024"], ["within 1..512"]),
    (["--to", "babylon-env", "--sh", "SH"], ["give the map"]),
])
def test_export_container_refusals(tmp_path, capsys, argv, words):
    sh_file = tmp_path / "sh.json"
    run(capsys, "sh", "--order", "2", "--json", "-o", sh_file)
    argv = [str(sh_file) if a == "SH" else a for a in argv]
    code, _, err = run(capsys, "export", *argv, "-o", tmp_path / "out.env")
    assert code == 2 and len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert all(w in err for w in words), err
    assert not (tmp_path / "out.env").exists()
