"""How far a bake's approximations are from their brute-force integrals, as the manifest reports them.

* The diffuse term (nine SH coefficients): irradiance E(n) from the SH against the direct sum of L(ω)(n·ω)⁺ over
  every pixel of the probe reduced (energy-preserving) to REFERENCE_ROWS rows, at REFERENCE_NORMALS normals spread
  evenly over the sphere; irradiance is smooth, so the reduction moves the reference by far less than the error.
* The specular chain: each level's texels against :func:`lightprobe.glossy.prefilter.brute_force_prefiltered` over
  every pixel of the probe as a lat-long of at most REFERENCE_LATLONG_ROWS rows (the probe itself when it is a
  lat-long that small; else reduced, energy-preserving), at CHAIN_TEXELS texels picked at random (fixed seed) per
  level, their directions taken to the world frame. The reference is the probe, not the cube the chain is drawn
  in: a sun the cube's texels smear is the chain's error, and is measured. A level whose lobe is narrower than two
  of the reference's pixels is not measured (the reference would be its own pixels' blur): it says so.

Errors are relative, on Rec. 709 luminance: |got − reference| / reference, as the median and the worst.
"""

from __future__ import annotations

import numpy as np

from ..glossy.prefilter import PrefilteredCube, brute_force_prefiltered
from ..maps import EnvMap
from ..maps.layouts import CUBE, LATLONG
from ..sh.basis import SHCoeffs
from ..sh.irradiance import brute_irradiance, reference_normals

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
REFERENCE_ROWS = 128  # the lat-long the irradiance reference sums over (256×128)
REFERENCE_NORMALS = 400
REFERENCE_LATLONG_ROWS = 256  # the lat-long the chain's reference sums over (512×256)
CHAIN_TEXELS = 32
SEED = 7


def _relative(got: np.ndarray, reference: np.ndarray) -> dict:
    got, reference = got @ LUMINANCE, reference @ LUMINANCE
    error = np.abs(got - reference) / np.maximum(np.abs(reference), 1e-30)
    return {"median": float(np.median(error)), "worst": float(error.max())}


def sh_accuracy(env: EnvMap, sh: SHCoeffs) -> dict:
    """The irradiance of ``sh`` (bands 0–2) against brute force over ``env``, in both of the paper's measures.

    Parameters
    ----------
    env : EnvMap
        The radiance the coefficients describe (world frame).
    sh : SHCoeffs
        Radiance coefficients of ``env`` (any frame; compared in the world frame).

    Returns
    -------
    dict
        ``relative_median``/``relative_worst`` (|E − E_ref| / E_ref per normal, luminance), ``of_total_mean``/
        ``of_total_worst`` (|E − E_ref| / ∫L dω: Ramamoorthi & Hanrahan's measure), ``negative_fraction`` (normals
        where the SH irradiance is negative: ringing), ``normals`` and ``reference`` (what was summed).
    """
    from ..maps.frames import WORLD
    from ..sh.irradiance import error_report

    normals = reference_normals(REFERENCE_NORMALS)
    reduced = env.to(LATLONG, REFERENCE_ROWS)
    reference = brute_irradiance(reduced, normals)
    coeffs = sh.to_frame(WORLD).truncated(2)
    got = coeffs.to_irradiance().evaluate(normals)
    report = error_report(reduced, 2, normals=normals, reference=reference, sh=coeffs)
    return {"relative_median": _relative(got, reference)["median"], "relative_worst": report.relative_max,
            "of_total_mean": report.paper_mean, "of_total_worst": report.paper_max,
            "negative_fraction": report.negative_fraction, "normals": REFERENCE_NORMALS,
            "reference": f"Σ L (n·ω)⁺ Δω over a {2 * REFERENCE_ROWS}×{REFERENCE_ROWS} lat-long of the probe"}


def chain_accuracy(env: EnvMap, chain: PrefilteredCube) -> dict:
    """Each level of ``chain`` against brute-force prefiltering of ``env``.

    Parameters
    ----------
    env : EnvMap
        The radiance the chain was prefiltered from (world frame).
    chain : PrefilteredCube
        The chain, in its frame.

    Returns
    -------
    dict
        ``levels``: one entry per level — ``roughness_alpha``, and ``median``/``worst`` relative error on luminance,
        or ``measured: false`` with the reason (the mirror level; a lobe narrower than the reference's texels);
        ``texels_per_level`` and ``reference``.
    """
    small = env.layout is LATLONG and env.grid[0] <= REFERENCE_LATLONG_ROWS
    source = env if small else env.to(LATLONG, REFERENCE_LATLONG_ROWS)
    rows = source.grid[0]
    texel = np.pi / rows  # a reference pixel's angular height, radians
    rng = np.random.default_rng(SEED)
    levels = []
    for i, (level, alpha) in enumerate(zip(chain.levels, chain.alphas)):
        entry = {"level": i, "roughness_alpha": float(alpha)}
        if alpha == 0:
            entry.update(measured=False, reason="the mirror: the probe resampled into the cube")
        elif alpha < texel:  # the reflected lobe's half-width is about 2α: under two texels
            entry.update(measured=False, reason=f"the lobe is narrower than two pixels of the {2 * rows}×{rows} "
                                                "reference")
        else:
            s = level.shape[1]
            r = CUBE.directions(CUBE.grid_shape(s)).reshape(-1, 3)
            pick = rng.choice(len(r), min(CHAIN_TEXELS, len(r)), replace=False)
            got = level.reshape(-1, 3)[pick].astype(np.float64)
            world = chain.frame.to_world(r[pick])
            entry.update(measured=True, **_relative(got, brute_force_prefiltered(source, world, alpha)))
        levels.append(entry)
    return {"levels": levels, "texels_per_level": CHAIN_TEXELS,
            "reference": f"Σ over every pixel of a {2 * rows}×{rows} lat-long of the probe, normal = view = r"}
