"""The BRDF/DFG lookup tables (lightprobe.glossy.dfg) and their files (lightprobe.exports.dfg), against brute-force
quadrature over the hemisphere, analytic limits, and the tables three.js and Babylon.js ship in their npm packages."""

from __future__ import annotations

import base64
import functools
import io
import re
from pathlib import Path

import numpy as np
import OpenImageIO as oiio
import pytest
from PIL import Image

from conftest import ROOT
from lightprobe.exports.dfg import engine_luts, png16_bytes, write_lut
from lightprobe.glossy import dfg
from lightprobe.maps.images import read_image
from lightprobe.util.errors import InputError, UsageError

POINTS = [(0.9, 0.3), (0.5, 0.5), (0.2, 0.7), (0.05, 1.0)]  # (n·v, roughness): lobes the quadrature below resolves
QUADRATURE_STEPS = 200  # polar steps of the brute-force grid (twice as many in azimuth over the half-circle)
SMOOTH_LIMIT_TOLERANCE = 1e-3  # r = 0.01 (α = 10⁻⁴): what is left of the lobe's width and of Smith's G
# three.js's table is 4096 samples per texel drawn ∝ D(n·h): at its grazing row (n·v = 1/32) it is ~1.4·10⁻² off
# (ours is within GGX_TOLERANCE of quadrature there); elsewhere its noise and half floats leave < 6·10⁻³.
THREE_GRAZING_TOLERANCE, THREE_TOLERANCE, THREE_MEDIAN_TOLERANCE = 0.02, 6e-3, 1e-4
# Babylon's table is 8-bit RGBD (rgb^2.2 / a): a step of 2.2/255 of a value near 1 is ~9·10⁻³; its grazing column
# carries the ~2·10⁻² noise of the D(n·h) estimator like three.js's.
BABYLON_P99_TOLERANCE, BABYLON_MEDIAN_TOLERANCE = 8e-3, 2.5e-3
# Karis's analytic fit (UE4 mobile; three.js's DFGApprox before r180) of his separable table: a rough fit, whose own
# error against the table it fits is up to ~0.17 near grazing views; checked for that size, not as ground truth.
KARIS_FIT_MAX, KARIS_FIT_MEDIAN = 0.2, 0.025
NODE_MODULES = ROOT / "engines" / "node_modules"
if not NODE_MODULES.is_dir():  # a worktree shares the main checkout's installed engines
    NODE_MODULES = Path("/work/main/engines/node_modules")


# ---- an independent brute force: midpoint quadrature over (θ_l, φ_l), the BRDF written from Λ -----------------
@functools.lru_cache(maxsize=1)
def _hemisphere(n=QUADRATURE_STEPS):
    t = (np.arange(n) + 0.5) / n * (np.pi / 2)
    p = (np.arange(2 * n) + 0.5) / (2 * n) * np.pi  # φ ∈ (0, π), doubled: the view lies in the x–z plane
    t, p = np.meshgrid(t, p, indexing="ij")
    l = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], axis=-1)
    return l, 2 * (np.pi / 2 / n) * (np.pi / (2 * n)) * np.sin(t)


def _lam(c, a):
    return 0.5 * (np.sqrt(1 + a * a * (1 - c * c) / (c * c)) - 1)


@functools.lru_cache(maxsize=None)
def _brute(mu, r, kind):
    a = r * r
    l, dw = _hemisphere()
    v = np.array([np.sqrt(1 - mu * mu), 0.0, mu])
    h = (l + v) / np.linalg.norm(l + v, axis=-1, keepdims=True)
    nl, nh, vh = l[..., 2], h[..., 2], h @ v
    if kind in ("neubelt", "charlie"):
        d = (2 + 1 / a) * np.clip(1 - nh * nh, 0, None) ** (0.5 / a) / (2 * np.pi)
        if kind == "neubelt":
            vis = 1 / (4 * (nl + mu - nl * mu))
        else:
            vis = 1 / ((1 + _charlie_lam(mu, a) + _charlie_lam(nl, a)) * 4 * mu * nl)
        return np.sum(d * vis * nl * dw)
    d = a * a / (np.pi * (nh * nh * (a * a - 1) + 1) ** 2)
    if kind == "separable":
        k = a / 2
        g = mu / (mu * (1 - k) + k) * nl / (nl * (1 - k) + k)
    else:
        g = 1 / (1 + _lam(mu, a) + _lam(nl, a))
    f = d * g / (4 * mu * nl) * nl * dw
    fc = (1 - vh) ** 5
    return np.array([np.sum(f * (1 - fc)), np.sum(f * fc)])


def _charlie_lam(c, a):
    """Estevez & Kulla 2017's fitted Λ, written from the paper's table 1 (interpolated in (1 − α)²)."""
    t = (1 - a) ** 2
    q = [x0 + (x1 - x0) * t for x0, x1 in ((21.5473, 25.3245), (3.82987, 3.32435), (0.19823, 0.16801),
                                            (-1.97760, -1.27393), (-4.32054, -4.85967))]

    def fit(x):
        return q[0] / (1 + q[1] * x ** q[2]) + q[3] * x + q[4]

    return np.where(c < 0.5, np.exp(fit(c)), np.exp(2 * fit(0.5) - fit(1 - np.minimum(c, 1))))


# ---- accuracy ---------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("visibility", dfg.VISIBILITIES)
def test_split_sum_matches_brute_force_quadrature(visibility):
    mu, r = np.array(POINTS).T
    ours = dfg.split_sum(mu, r, visibility)
    for (m, rr), value in zip(POINTS, ours):
        np.testing.assert_allclose(value, _brute(m, rr, visibility), atol=dfg.GGX_TOLERANCE, rtol=0)


@pytest.mark.parametrize("visibility", dfg.SHEEN_VISIBILITIES)
def test_sheen_albedo_matches_brute_force_quadrature(visibility):
    mu, r = np.array(POINTS).T
    ours = dfg.sheen_albedo(mu, r, visibility)
    for (m, rr), value in zip(POINTS, ours):
        assert abs(value - _brute(m, rr, visibility)) < dfg.SHEEN_TOLERANCE, (m, rr)


def test_the_two_sheen_visibilities_differ():
    """The check above can tell them apart: at a wide lobe their albedos differ by far more than its tolerance."""
    assert abs(dfg.sheen_albedo(0.5, 0.5, "neubelt") - dfg.sheen_albedo(0.5, 0.5, "charlie")) > 20 * dfg.SHEEN_TOLERANCE


def test_a_smooth_surface_reflects_schlicks_fresnel_at_the_view():
    """r → 0: the lobe is the mirror direction, h = n, so A → 1 − (1 − μ)⁵ and B → (1 − μ)⁵."""
    mu = np.array([0.15, 0.3, 0.6, 0.95])
    for visibility in dfg.VISIBILITIES:
        a, b = np.moveaxis(dfg.split_sum(mu, 0.01, visibility), -1, 0)
        np.testing.assert_allclose(b, (1 - mu) ** 5, atol=SMOOTH_LIMIT_TOLERANCE)
        np.testing.assert_allclose(a, 1 - (1 - mu) ** 5, atol=SMOOTH_LIMIT_TOLERANCE)


def test_compensated_white_ggx_reflects_everything():
    """White furnace: the single-scattering albedo by quadrature, times the table's compensation for F0 = 1, is 1."""
    mu, r = np.array(POINTS).T
    dfg2 = dfg.split_sum(mu, r).sum(axis=-1)
    brute = np.array([_brute(m, rr, "height-correlated").sum() for m, rr in POINTS])
    assert (brute < 0.99).all()  # real energy loss, which the compensation must restore
    np.testing.assert_allclose(brute * dfg.energy_compensation(dfg2, 1.0), 1.0, atol=2 * dfg.GGX_TOLERANCE)


def test_compensation_never_adds_energy():
    table = dfg.multiscatter_lut(8, sheen=False, samples=512)
    for f0 in np.linspace(0, 1, 6):
        energy = ((1 - f0) * table[..., 0] + f0 * table[..., 1]) * dfg.energy_compensation(table[..., 1], f0)
        assert (energy <= 1 + 1e-12).all()


# ---- the tables' layout -----------------------------------------------------------------------------------------
def test_rows_are_roughness_and_columns_are_n_dot_v_at_texel_centres():
    size = 4
    table = dfg.split_sum_lut(size, samples=256)
    centres = dfg.texel_centres(size)
    np.testing.assert_array_equal(centres, [0.125, 0.375, 0.625, 0.875])
    for j in range(size):
        for i in range(size):
            np.testing.assert_array_equal(table[j, i], dfg.split_sum(centres[i], centres[j], samples=256))
    assert table[0, -1, 0] > 0.99 and table[-1, 0, 0] < 0.9  # smooth at a normal view: all of F0


def test_multiscatter_channels_are_the_split_sum_terms():
    ab = dfg.split_sum_lut(6, samples=256)
    table = dfg.multiscatter_lut(6, samples=256)
    np.testing.assert_array_equal(table[..., 0], ab[..., 1])
    np.testing.assert_array_equal(table[..., 1], ab[..., 0] + ab[..., 1])
    np.testing.assert_array_equal(table[..., 2], dfg.sheen_lut(6, samples=256))


def test_the_shipped_default_table_holds_the_sums_at_every_texel_we_check(monkeypatch):
    """multiscatter_lut() at its defaults reads the package's table: it must be the bits split_sum and
    sheen_albedo give at the same texel centres (a stale or wrong file fails here), and no kernel runs for it."""
    rng = np.random.default_rng(7)
    j, i = rng.integers(0, dfg.DEFAULT_SIZE, (2, 40))
    centres = dfg.texel_centres(dfg.DEFAULT_SIZE)
    ab = dfg.split_sum(centres[i], centres[j])
    sheen = dfg.sheen_albedo(centres[i], centres[j])

    def not_summed(*args):
        raise AssertionError("the default table was summed, not read")

    monkeypatch.setattr(dfg, "split_sum_lut", not_summed)
    table = dfg.multiscatter_lut()
    assert table.shape == (dfg.DEFAULT_SIZE, dfg.DEFAULT_SIZE, 3) and table.dtype == np.float64
    np.testing.assert_array_equal(table[j, i, 0], ab[:, 1])
    np.testing.assert_array_equal(table[j, i, 1], ab[:, 0] + ab[:, 1])
    np.testing.assert_array_equal(table[j, i, 2], sheen)
    table[0, 0, 0] = -1.0  # a copy: the caller may write into it
    assert dfg.multiscatter_lut()[0, 0, 0] != -1.0


def test_tables_are_the_same_bits_every_run():
    first = dfg.multiscatter_lut(12, samples=300)
    assert first.tobytes() == dfg.multiscatter_lut(12, samples=300).tobytes()


def test_bad_arguments_are_refused():
    for call in (lambda: dfg.split_sum(0.5, 0.5, "smith"), lambda: dfg.sheen_albedo(0.5, 0.5, "ashikhmin"),
                 lambda: dfg.split_sum(0.0, 0.5), lambda: dfg.split_sum(0.5, 1.5), lambda: dfg.split_sum(np.nan, 0.5),
                 lambda: dfg.split_sum_lut(0), lambda: dfg.split_sum_lut(8, samples=0),
                 lambda: dfg.texel_centres(2.5), lambda: dfg.energy_compensation(0.0, 0.5),
                 lambda: engine_luts("unity")):
        with pytest.raises(UsageError):
            call()


# ---- the engines' own tables ------------------------------------------------------------------------------------
def _three_table() -> np.ndarray:
    path = NODE_MODULES / "three" / "src" / "renderers" / "shaders" / "DFGLUTData.js"
    if not path.is_file():
        pytest.skip("three.js's DFGLUTData.js is not installed (engines/node_modules)")
    text = path.read_text()
    body = text[text.index("new Uint16Array( ["):]
    words = [int(x, 16) for x in re.findall(r"0x([0-9a-fA-F]{4})", body[:body.index("] )")])]
    return np.array(words, dtype=np.uint16).view(np.float16).astype(np.float64).reshape(16, 16, 2)


def test_three_js_shipped_table_is_ours_height_correlated_and_transposed():
    three = _three_table()
    ours = engine_luts("three")["dfg"][..., :2]
    error = np.abs(ours - three)
    assert error[0].max() < THREE_GRAZING_TOLERANCE
    assert error[1:].max() < THREE_TOLERANCE and np.median(error) < THREE_MEDIAN_TOLERANCE
    # the layout and the visibility matter: the untransposed table, or the separable G, are far off
    assert np.abs(ours.transpose(1, 0, 2) - three).max() > 0.3
    separable = dfg.split_sum_lut(16, "separable").transpose(1, 0, 2)
    assert np.abs(separable - three).max() > 0.2


def _babylon_table() -> np.ndarray:
    path = NODE_MODULES / "@babylonjs" / "core" / "Misc" / "brdfTextureTools.js"
    if not path.is_file():
        pytest.skip("Babylon.js's brdfTextureTools.js is not installed (engines/node_modules)")
    found = re.search(r'_environmentBRDFBase64Texture = "data:image/png;base64,([^"]+)"', path.read_text())
    rgbd = np.asarray(Image.open(io.BytesIO(base64.b64decode(found.group(1)))).convert("RGBA"), dtype=np.float64)
    rgbd /= 255.0
    return rgbd[..., :3] ** 2.2 / rgbd[..., 3:]  # Babylon's fromRGBD: toLinearSpace (γ 2.2) over D


def test_babylon_shipped_table_is_ours_one_texel_off_in_roughness():
    """Babylon's 256² table matches ours with its row j holding our row j + 1 — the roughness (j + 1.5)/N of
    Filament's cmgen, which evaluates a row one texel off — in the GGX channels (DFG1, DFG2)."""
    babylon = _babylon_table()
    rows, columns = np.arange(0, 255, 8), np.arange(4, 256, 8)  # a 32 × 32 subset, away from the grazing column
    centres = dfg.texel_centres(256)
    mu, r = np.meshgrid(centres[columns], centres[rows + 1], indexing="xy")
    a, b = np.moveaxis(dfg.split_sum(mu, r, samples=1024), -1, 0)
    error = np.abs(np.stack([b, a + b], axis=-1) - babylon[rows][:, columns, :2])
    assert np.percentile(error, 99) < BABYLON_P99_TOLERANCE and np.median(error) < BABYLON_MEDIAN_TOLERANCE
    mu, r = np.meshgrid(centres[columns], centres[255 - rows], indexing="xy")
    ours = dfg.split_sum(mu, r, samples=1024)
    flipped = np.abs(np.stack([ours[..., 1], ours.sum(axis=-1)], axis=-1) - babylon[rows][:, columns, :2])
    assert np.median(flipped) > 10 * BABYLON_MEDIAN_TOLERANCE  # row 0 is roughness 0 in Babylon's file too


def test_karis_analytic_fit_is_near_the_separable_table():
    centres = dfg.texel_centres(16)
    r, mu = np.meshgrid(centres, centres, indexing="ij")
    c0, c1 = np.array([-1, -0.0275, -0.572, 0.022]), np.array([1, 0.0425, 1.04, -0.04])
    q = r[..., None] * c0 + c1
    a004 = np.minimum(q[..., 0] ** 2, 2 ** (-9.28 * mu)) * q[..., 0] + q[..., 1]
    fit = np.stack([-1.04 * a004 + q[..., 2], 1.04 * a004 + q[..., 3]], axis=-1)
    error = np.abs(fit - dfg.split_sum_lut(16, "separable"))
    assert error.max() < KARIS_FIT_MAX and np.median(error) < KARIS_FIT_MEDIAN


# ---- files ------------------------------------------------------------------------------------------------------
def test_engine_luts_name_and_arrange_each_engines_files():
    gltf = engine_luts("gltf", size=8, samples=256)
    assert set(gltf) == {"lut_ggx", "lut_charlie", "lut_sheen_E"}
    np.testing.assert_array_equal(gltf["lut_ggx"][..., :2], dfg.split_sum_lut(8, samples=256))
    np.testing.assert_array_equal(gltf["lut_charlie"][..., 2], dfg.sheen_lut(8, "neubelt", samples=256))
    np.testing.assert_array_equal(gltf["lut_sheen_E"][..., 0], dfg.sheen_lut(8, "charlie", samples=256))
    assert not gltf["lut_ggx"][..., 2].any() and not gltf["lut_charlie"][..., :2].any()
    three = engine_luts("three", size=8, samples=256)["dfg"]
    np.testing.assert_array_equal(three, gltf["lut_ggx"].transpose(1, 0, 2))
    filament = engine_luts("filament", size=8, samples=256)["dfg"]
    np.testing.assert_array_equal(filament, dfg.multiscatter_lut(8, samples=256))
    assert set(engine_luts("babylon", size=4, samples=64)) == {"environment_brdf"}


def test_png_is_16_bit_rgb_without_colour_chunks(tmp_path):
    table = dfg.multiscatter_lut(8, samples=256)
    table[0, 0, 2] = 3.0  # sheen > 1 at grazing smooth views: a PNG clips it
    path = write_lut(tmp_path / "dfg.png", table)
    data = path.read_bytes()
    kinds, at = [], 8
    while at < len(data):
        length = int.from_bytes(data[at:at + 4], "big")
        kinds.append(data[at + 4:at + 8])
        at += 12 + length
    assert kinds == [b"IHDR", b"IDAT", b"IEND"] and data[24:26] == bytes([16, 2])
    back = oiio.ImageBuf(str(path)).get_pixels(oiio.UINT16)  # OpenImageIO's libpng decoder, not ours
    np.testing.assert_array_equal(back, np.round(np.clip(table, 0, 1) * 65535).astype(np.uint16))


def test_exr_holds_the_table_as_float32_row_0_on_top(tmp_path):
    table = dfg.split_sum_lut(8, samples=256)
    back = read_image(write_lut(tmp_path / "lut.exr", table))
    np.testing.assert_array_equal(back[..., :2], table.astype(np.float32))
    assert not back[..., 2].any()
    grey = read_image(write_lut(tmp_path / "sheen.exr", dfg.sheen_lut(8, samples=256), half=True))
    np.testing.assert_allclose(grey[..., 0], dfg.sheen_lut(8, samples=256), rtol=1e-3)
    np.testing.assert_array_equal(grey[..., 0], grey[..., 2])


def test_bad_files_are_refused(tmp_path):
    with pytest.raises(InputError):
        write_lut(tmp_path / "lut.jpg", np.zeros((4, 4, 2)))
    with pytest.raises(UsageError):
        write_lut(tmp_path / "lut.png", np.zeros((4, 4, 4)))
    with pytest.raises(UsageError):
        png16_bytes(np.full((2, 2, 3), np.nan))
    assert not list(tmp_path.iterdir())
