"""BRDFs: white furnace, closed forms, Fresnel limits, reciprocity, sampling consistency, the spec parser."""

from __future__ import annotations

import math

import numpy as np
import pytest

from conftest import random_directions
from lightprobe.glossy.brdf import CONDUCTORS, GGX, BlinnPhong, Conductor, Dielectric, Lambert, Phong, Schlick, parse_brdf
from lightprobe.glossy.brdf_sums import directional_albedo
from lightprobe.glossy.layered import Coat
from lightprobe.util.errors import UsageError

SPECS = ["lambert", "phong:n=50", "phong:n=3", "blinn:n=50", "blinn:n=5", "ggx:alpha=0.05", "ggx:alpha=0.2",
         "ggx:alpha=1", "ggx:alpha=0.2,conductor=gold", "ggx:alpha=0.3,ior=1.5", "ggx:alpha=0.2,f0=0.04",
         "coat:alpha=0.1,ior=1.5,albedo=1", "coat:alpha=0.6,albedo=0.9/0.5/0.1", "plastic:alpha=0.1,albedo=1",
         "plastic:alpha=0.4,ior=1.6,albedo=0.8/0.3/0.1"]
VIEWS = np.array([1.0, 0.8, 0.5, 0.25, 0.1, 0.02])


@pytest.mark.parametrize("spec", SPECS)
def test_white_furnace_no_brdf_reflects_more_than_comes_in(spec):
    """Under a uniform sky of radiance 1 the reflected radiance (the directional albedo) is ≤ 1 at every view,
    normal to grazing (importance-sampled, 16 384 stratified samples: 0.5 % allowed for its noise)."""
    albedo = directional_albedo(parse_brdf(spec), VIEWS, 16384)
    assert (albedo <= 1.005).all(), albedo
    assert (albedo >= 0).all()


def test_white_furnace_where_energy_is_conserved():
    """Lambert reflects exactly its albedo at every view; GGX without Fresnel loses only what single scattering
    loses — nothing for a near-mirror at normal view, 1 − ln 2 at α = 1 (where D = 1/π and G1(wi) = 2μ/(1 + μ)
    give ∫ μ/(1 + μ) dμ); Blinn–Phong with its exact normalisation reflects exactly ks at normal view."""
    np.testing.assert_allclose(directional_albedo(Lambert(), VIEWS), 1.0, atol=1e-12)
    np.testing.assert_allclose(directional_albedo(Lambert((0.2, 0.5, 0.9)), VIEWS), [[0.2, 0.5, 0.9]] * len(VIEWS),
                               atol=1e-12)
    assert directional_albedo(GGX(0.02), np.array([1.0]), 16384)[0, 0] == pytest.approx(1.0, abs=0.003)
    assert directional_albedo(GGX(1.0), np.array([1.0]), 65536)[0, 0] == pytest.approx(1 - math.log(2), abs=0.002)
    for n in (0.0, 5.0, 80.0):
        assert directional_albedo(BlinnPhong(n, 0.7), np.array([1.0]), 65536)[0, 0] == pytest.approx(0.7, abs=0.004)
    # the same numbers from an estimator that does not use the BRDFs' own sampling: uniform hemisphere quadrature
    for brdf in (GGX(0.3), Phong(20.0), Coat(0.3), BlinnPhong(10.0)):
        assert _uniform_albedo(brdf, 0.6) == pytest.approx(directional_albedo(brdf, np.array([0.6]), 65536)[0, 0],
                                                           abs=0.004)


def _uniform_albedo(brdf, cos_view: float, side: int = 800) -> float:
    """∫ f cos dω over the hemisphere by the midpoint rule in (cos θ, φ) (uniform in solid angle)."""
    mu = (np.arange(side) + 0.5) / side
    phi = (np.arange(2 * side) + 0.5) / (2 * side) * 2 * np.pi
    m, p = np.meshgrid(mu, phi, indexing="ij")
    s = np.sqrt(1 - m * m)
    wi = np.stack([s * np.cos(p), s * np.sin(p), m], -1)
    wo = np.array([math.sqrt(1 - cos_view ** 2), 0.0, cos_view])
    f = brdf.eval(wi, wo, np.array([0.0, 0.0, 1.0]))[..., 0]
    return float((f * m).sum() * (1 / side) * (2 * np.pi / (2 * side)))


@pytest.mark.parametrize("spec", SPECS)
def test_reciprocity(spec):
    brdf = parse_brdf(spec)
    n = np.array([0.0, 0.0, 1.0])
    a, b = random_directions(3000, seed=1), random_directions(3000, seed=2)
    a[:, 2], b[:, 2] = np.abs(a[:, 2]), np.abs(b[:, 2])
    np.testing.assert_allclose(brdf.eval(a, b, n), brdf.eval(b, a, n), rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("spec", SPECS)
def test_below_the_surface_there_is_nothing(spec):
    brdf = parse_brdf(spec)
    n = np.array([0.0, 0.0, 1.0])
    a, b = random_directions(500, seed=3), random_directions(500, seed=4)
    a[:, 2], b[:, 2] = -np.abs(a[:, 2]), np.abs(b[:, 2])
    assert (brdf.eval(a, b, n) == 0).all() and (brdf.eval(b, a, n) == 0).all()


@pytest.mark.parametrize("spec", [s for s in SPECS if not s.startswith("lambert")])
def test_sampling_pdf_is_the_pdf_and_integrates_to_at_most_one(spec):
    """sample() returns pdf() of what it drew, and pdf() over the whole sphere integrates to ≤ 1 (mass below the
    surface is dropped), ≈ 1 for the lobes that stay above it at normal view."""
    brdf = parse_brdf(spec)
    n = np.array([0.0, 0.0, 1.0])
    wo = np.array([0.6, 0.0, 0.8])
    u = np.random.default_rng(0).random((4000, 2))
    wi, pdf = brdf.sample(wo, n, u)
    np.testing.assert_allclose(np.linalg.norm(wi, axis=-1), 1.0, atol=1e-9)
    np.testing.assert_allclose(pdf, brdf.pdf(wi, wo, n), rtol=1e-9)
    d = random_directions(400_000, seed=9)
    total = float(np.mean(brdf.pdf(d, wo, n)) * 4 * np.pi)
    assert total <= 1.01


def test_fresnel_limits():
    cos = np.array([1.0, 0.5, 1e-9])
    np.testing.assert_allclose(Schlick()(cos), 1.0)
    assert Dielectric(1.5)(np.array([1.0]))[0, 0] == pytest.approx(0.04)
    np.testing.assert_allclose(Conductor((1.5, 1.5, 1.5), (0.0, 0.0, 0.0))(cos), Dielectric(1.5)(cos), atol=1e-12)
    eta, k = np.array(CONDUCTORS["gold"][0]), np.array(CONDUCTORS["gold"][1])
    np.testing.assert_allclose(Conductor(*CONDUCTORS["gold"])(np.array([1.0]))[0],
                               ((eta - 1) ** 2 + k * k) / ((eta + 1) ** 2 + k * k), rtol=1e-12)
    for fresnel in (Dielectric(1.5), Conductor(*CONDUCTORS["silver"]), Schlick(0.04)):
        np.testing.assert_allclose(fresnel(np.array([0.0]))[0], 1.0, atol=1e-6)  # everything mirrors at grazing


def test_specs_read_back_to_the_same_brdf():
    for spec in SPECS + ["ggx:alpha=0.2,eta=0.2/0.4/1.4,k=4/2.4/1.6", "blinn:n=7,ks=0.5", "lambert:albedo=0.5"]:
        brdf = parse_brdf(spec)
        again = parse_brdf(brdf.spec())
        d = random_directions(200, seed=5)
        d[:, 2] = np.abs(d[:, 2])
        np.testing.assert_array_equal(brdf.eval(d, d[::-1], np.array([0.0, 0.0, 1.0])),
                                      again.eval(d, d[::-1], np.array([0.0, 0.0, 1.0])))
    assert parse_brdf("ggx:alpha=0.2,conductor=gold").spec() == "ggx:alpha=0.2,conductor=gold"
    assert isinstance(parse_brdf("ggx:alpha=0.2,ior=1.5").fresnel, Dielectric)


@pytest.mark.parametrize("spec, message", [
    ("velvet", "unknown BRDF 'velvet'"),
    ("ggx:alpha=0", "alpha must be in [0.01, 1]"),
    ("ggx:alpha=1.5", "alpha must be in [0.01, 1]"),
    ("ggx:alpha=nan", "must be finite"),
    ("ggx:roughness=0.2", "ggx has no parameter 'roughness'"),
    ("ggx:alpha=0.2,conductor=unobtainium", "unknown conductor"),
    ("ggx:alpha=0.2,f0=0.04,conductor=gold", "one Fresnel"),
    ("ggx:alpha=0.2,eta=0.2", "needs both eta and k"),
    ("ggx:alpha", "key=value"),
    ("ggx:alpha=0.1,alpha=0.2", "given twice"),
    ("phong:n=-1", "exponent n must be in"),
    ("lambert:albedo=1.2", "albedo must be in [0, 1]"),
    ("coat:albedo=0.5/0.5", "one number or three"),
    ("ggx:alpha=0.2,f0=2", "f0 must be in [0, 1]"),
    ("ggx:alpha=0.2,ior=0.5", "eta must be in [1, 10]"),
])
def test_bad_specs_get_one_clear_message(spec, message):
    with pytest.raises(UsageError, match=message.replace("(", r"\(").replace(")", r"\)").replace("[", r"\[")
                       .replace("]", r"\]")):
        parse_brdf(spec)


@pytest.mark.parametrize("spec", SPECS)
def test_the_compiled_evaluation_is_the_numpy_one(spec):
    """brdf_times_cosine (the compiled sums' evaluation, Fresnel read from a 16384-step table) equals eval · n·wi."""
    from lightprobe.glossy.brdf_sums import compiled_eval_cosine

    brdf = parse_brdf(spec)
    n = random_directions(5000, seed=6)
    wi, wo = random_directions(5000, seed=7), random_directions(5000, seed=8)
    wo = np.where((np.sum(wo * n, axis=1) < 0)[:, None], -wo, wo)
    expected = brdf.eval(wi, wo, n) * np.maximum(np.sum(wi * n, axis=1), 0.0)[:, None]
    np.testing.assert_allclose(compiled_eval_cosine(brdf, wi, wo, n), expected, rtol=1e-5,
                               atol=1e-9 * np.abs(expected).max())
