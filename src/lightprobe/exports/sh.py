"""SH irradiance for engines: every target's frame, sign convention, order and scaling, converted explicitly.

Input is always :class:`~lightprobe.sh.basis.SHCoeffs` of **radiance** (L_lm, the paper's basis without Condon–Shortley
phase, l_max ≥ 2). Each exporter states, at its function, what its numbers are. Notation used below:

* ``K_i``: the positive constant of basis function i as a polynomial: 0.282095; 0.488603 (y, z, x);
  1.092548 (xy, yz, xz); 0.315392 (3z²−1); 0.546274 (x²−y²).
* Condon–Shortley (CS) phase: engines built on Sloan's "Stupid SH tricks" basis (Filament, Babylon) define
  Y1−1, Y11, Y2−1, Y21 with a minus sign; their coefficients for those four are the negatives of ours.
* ``E`` is irradiance, ``E/π`` the outgoing radiance of a white Lambertian surface.

The scaling steps are one small named function each (as in Babylon's sphericalPolynomial.ts), so a conversion is
never applied twice by accident.
"""

from __future__ import annotations

import functools
import json
from math import pi

import numpy as np

from ..util.names import EXPORT_TARGETS, GLTF_SCALINGS
from ..util.errors import InputError, UsageError
from ..sh.irradiance import C1, C2, C3, C4, C5
from ..maps.frames import BABYLON, FILAMENT, THREEJS, UNITY, WORLD, Frame, frame as frame_named
from ..sh.basis import SHCoeffs, a_hat_per_coefficient, name
from ..sh.shfile import sh_json

TARGETS = EXPORT_TARGETS
DEFAULT_FRAMES = {"json": WORLD, "threejs": THREEJS, "filament": FILAMENT, "unity": UNITY, "gltf": BABYLON,
                  "babylon": BABYLON, "glsl": WORLD}

BASIS_CONSTANTS = np.array([0.5 * np.sqrt(1 / pi)] + [0.5 * np.sqrt(3 / pi)] * 3
                           + [0.5 * np.sqrt(15 / pi)] * 2 + [0.25 * np.sqrt(5 / pi)] + [0.5 * np.sqrt(15 / pi)]
                           + [0.25 * np.sqrt(15 / pi)])  # K_i, i = 0..8
CS_SIGNS = np.array([1, -1, 1, -1, 1, -1, 1, -1, 1], dtype=np.float64)  # (−1)^m for l ≤ 2


FLOAT32_MAX = float(np.finfo(np.float32).max)  # engines hold SH in 32-bit floats (uniforms, C# float literals)


def check_engine_values(values, target: str, limit: float = FLOAT32_MAX):
    """``values`` unchanged when an engine can hold every one: finite, and within ±``limit``.

    Finite inputs can overflow on the way to an engine's form (1e308 × π, a frame's rotation); such a form would be
    written as ``Infinity``/``NaN`` (not JSON) or an out-of-range C# literal, or read by the engine as infinity.

    Parameters
    ----------
    values : array-like, or dict of array-like
        The engine's numbers (a dict's values are checked).
    target : str
        The engine, named in the message.
    limit : float, default FLOAT32_MAX
        The largest magnitude allowed: :data:`FLOAT32_MAX` (3.4·10³⁸, what engines hold); ``inf`` for 64-bit files.

    Returns
    -------
    array-like or dict
        ``values``, unchanged.

    Raises
    ------
    InputError
        A value is not finite or its magnitude is over ``limit``: the input's numbers are too large for ``target``.
    """
    arrays = values.values() if isinstance(values, dict) else [values]
    with np.errstate(invalid="ignore"):
        if not all(np.all(np.abs(np.asarray(a, dtype=np.float64)) <= limit) for a in arrays):
            raise InputError(f"refusing the export: the numbers are too large for {target} (not finite"
                             f"{' in 32-bit floats' if limit < np.inf else ''} there; scale the input down)")
    return values


def _engine_form(target: str, limit: float = FLOAT32_MAX):
    """Compute a target's numbers without numpy's overflow warnings, then :func:`check_engine_values` them."""
    def wrap(f):
        @functools.wraps(f)
        def checked(*args, **kwargs):
            with np.errstate(over="ignore", invalid="ignore"):
                return check_engine_values(f(*args, **kwargs), target, limit)
        return checked
    return wrap


# ---- scaling steps (each one named, each applied once) ---------------------------------------------------------------
def _nine(sh: SHCoeffs, target_frame: Frame) -> np.ndarray:
    """Radiance L_lm, bands ≤ 2, stated in ``target_frame``: (9, 3)."""
    if sh.quantity != "radiance":
        raise UsageError(f"exports start from radiance coefficients, got {sh.quantity}")
    if sh.l_max < 2:
        raise UsageError("engine exports need coefficients up to band 2")
    with np.errstate(over="ignore", invalid="ignore"):
        return check_engine_values(sh.truncated(2).to_frame(target_frame).coeffs.copy(),
                                   f"the {target_frame.name} frame")


def radiance_to_irradiance(c: np.ndarray) -> np.ndarray:
    """L_lm → E_lm = Â_l L_lm (cosine convolution, paper eq. 7).

    Parameters
    ----------
    c : numpy.ndarray
        (9, 3) radiance coefficients L_lm of bands ≤ 2, flat order, RGB columns, in any frame and either sign
        convention (Â_l depends on the band only).

    Returns
    -------
    numpy.ndarray
        (9, 3) irradiance coefficients E_lm (E not divided by π).
    """
    return c * a_hat_per_coefficient(2)[:, None]


def irradiance_to_lambertian(c: np.ndarray) -> np.ndarray:
    """E → E/π (outgoing radiance of a white Lambertian surface).

    Parameters
    ----------
    c : numpy.ndarray
        Irradiance coefficients E_lm, any shape (here (9, 3)).

    Returns
    -------
    numpy.ndarray
        The same coefficients divided by π: E/π.
    """
    return c / pi


def premultiply_basis_constants(c: np.ndarray) -> np.ndarray:
    """c_i → c_i K_i: the shader then evaluates bare polynomials (1, y, z, x, xy, yz, 3z²−1, xz, x²−y²).

    Parameters
    ----------
    c : numpy.ndarray
        (9, 3) coefficients of bands ≤ 2 in flat order, RGB columns; any quantity (Filament and Unity pass E/π).

    Returns
    -------
    numpy.ndarray
        (9, 3): row i times :data:`BASIS_CONSTANTS` K_i.
    """
    return c * BASIS_CONSTANTS[:, None]


def to_condon_shortley(c: np.ndarray) -> np.ndarray:
    """Our basis → a CS-phase basis: negate the m = ±1 coefficients (L1−1, L11, L2−1, L21).

    The same negation takes CS-phase coefficients back to our basis.

    Parameters
    ----------
    c : numpy.ndarray
        (9, 3) our-basis coefficients of bands ≤ 2 (or CS-phase ones, to go back), any quantity.

    Returns
    -------
    numpy.ndarray
        (9, 3) with rows 1, 3, 5 and 7 negated (:data:`CS_SIGNS`).
    """
    return c * CS_SIGNS[:, None]


def times_pi(c: np.ndarray) -> np.ndarray:
    """c → π c: the glTF ``pi-radiance`` scaling of radiance coefficients (π L_lm).

    Parameters
    ----------
    c : numpy.ndarray
        Coefficients, any shape (here (9, 3) radiance L_lm).

    Returns
    -------
    numpy.ndarray
        The same coefficients times π.
    """
    return c * pi


def _lambertian_nine(sh: SHCoeffs, frame: Frame) -> np.ndarray:
    """K_i Â_l L_lm / π of bands 0–2 in ``frame``: the nine numbers whose bare polynomial gives E/π (Filament's and
    Unity's shaders read the same ones, each in its own frame)."""
    return premultiply_basis_constants(irradiance_to_lambertian(radiance_to_irradiance(_nine(sh, frame))))


# ---- targets --------------------------------------------------------------------------------------------------------
def export_json(sh: SHCoeffs, frame: Frame = WORLD) -> str:
    """lightprobe's own SH JSON (:mod:`lightprobe.sh.shfile`): radiance L_lm in the paper's basis (no CS phase).

    Any order, flat order, stated in ``frame``.

    Parameters
    ----------
    sh : SHCoeffs
        Radiance coefficients, any order (written whole; the file records their quantity and window).
    frame : Frame, default WORLD
        The frame the file states them in.

    Returns
    -------
    str
        The ``lightprobe.sh`` JSON text (no ``source``).
    """
    with np.errstate(over="ignore", invalid="ignore"):
        check_engine_values(sh.to_frame(frame).coeffs, "JSON", np.inf)
    return sh_json(sh, frame)


@_engine_form("three.js")
def threejs_coefficients(sh: SHCoeffs, frame: Frame = THREEJS) -> np.ndarray:
    """three.js ``SphericalHarmonics3``: radiance L_lm without the CS phase, in the frame of three.js's background.

    Radiance L_lm (no CS phase; its getAt/getIrradianceAt use +0.488603 y etc.), order L00, L1−1, L10, L11, L2−2, L2−1,
    L20, L21, L22, in the frame three.js shows an equirectangular background in (:data:`lightprobe.maps.frames.THREEJS`:
    (−z, y, x) of world), so light comes from where the background shows it. ``getIrradianceAt`` returns E; the shader
    multiplies by the Lambert BRDF (÷π).

    Parameters
    ----------
    sh : SHCoeffs
        Radiance coefficients, l_max ≥ 2 (bands above 2 are dropped), in any frame: they are converted.
    frame : Frame, default THREEJS
        The frame to state them in; the default is the one three.js shows an equirectangular background in.

    Returns
    -------
    numpy.ndarray
        (9, 3) radiance L_lm, RGB columns: row-major, the 27 floats of ``SphericalHarmonics3.fromArray``.

    Raises
    ------
    UsageError
        ``sh`` holds irradiance, or its order is below 2.
    """
    return _nine(sh, frame)


def export_threejs(sh: SHCoeffs, frame: Frame = THREEJS) -> str:
    """A ``LightProbe`` in three.js JSON object format (``ObjectLoader``), ``sh`` = 27 floats, RGB per coefficient.

    Parameters
    ----------
    sh : SHCoeffs
        Radiance coefficients, l_max ≥ 2, any frame.
    frame : Frame, default THREEJS
        The frame of the coefficients in the file (:func:`threejs_coefficients`).

    Returns
    -------
    str
        The JSON text: an identity-matrix ``LightProbe`` of intensity 1 holding radiance L_lm.

    Raises
    ------
    UsageError
        ``sh`` holds irradiance, or its order is below 2.
    """
    c = threejs_coefficients(sh, frame)
    return json.dumps({
        "metadata": {"version": 4.6, "type": "Object", "generator": "lightprobe"},
        "object": {
            "uuid": "5b0c0f0e-1a1b-4c2d-8e3f-000000000001",
            "type": "LightProbe",
            "name": "lightprobe irradiance (radiance SH L_lm, three.js frame)",
            "layers": 1,
            "matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1],
            "up": [0, 1, 0],
            "color": 16777215,
            "intensity": 1,
            "sh": [float(v) for v in c.reshape(-1)],
        },
    }, indent=1, allow_nan=False)


@_engine_form("Filament")
def filament_coefficients(sh: SHCoeffs, frame: Frame = FILAMENT) -> np.ndarray:
    """Filament ``IndirectLight::Builder::irradiance(3, sh)``: K_i Â_l L_lm / π, whose bare polynomial gives E/π.

    sh[i] = L_lm · (1/π) · A_lm · Ĉ_l as IndirectLight.h tabulates it (A_lm the CS-signed basis constants, L_lm
    Filament's CS-phase coefficients — the two signs cancel), i.e. K_i Â_l L_lm / π with our L_lm: the shader's bare
    polynomial gives E/π. Filament frame (= world).

    Parameters
    ----------
    sh : SHCoeffs
        Radiance L_lm to convert; order ≥ 2 (only bands 0–2 are kept), any frame.
    frame : Frame, default FILAMENT
        The target frame: Filament's world (right-handed, +Y up, camera along −Z: the world frame).

    Returns
    -------
    numpy.ndarray
        (9, 3) K_i Â_l L_lm / π, RGB columns, in Filament's order L00, L1−1, L10, L11, L2−2, L2−1, L20, L21, L22.

    Raises
    ------
    UsageError
        ``sh`` holds irradiance, or its order is below 2.
    """
    return _lambertian_nine(sh, frame)


def export_filament(sh: SHCoeffs, frame: Frame = FILAMENT) -> str:
    """``sh.txt`` exactly as cmgen writes it: one line per coefficient, 15 decimals.

    Each line reads ``( r,  g,  b); // L00, irradiance, pre-scaled base``.

    Parameters
    ----------
    sh : SHCoeffs
        The radiance SH cmgen would have computed, order ≥ 2.
    frame : Frame, default FILAMENT
        Passed to :func:`filament_coefficients`, which makes the nine values.

    Returns
    -------
    str
        Nine lines of K_i Â_l L_lm / π (the shader gives E/π).

    Raises
    ------
    UsageError
        ``sh`` holds irradiance, or its order is below 2.
    """
    c = filament_coefficients(sh, frame)
    return "".join(f"({', '.join(f'{v: .15f}' for v in row)}); // {name(i)}, irradiance, pre-scaled base\n"
                   for i, row in enumerate(c))


@_engine_form("Unity")
def unity_coefficients(sh: SHCoeffs, frame: Frame = UNITY) -> np.ndarray:
    """Unity ``SphericalHarmonicsL2`` as its shaders read it: K_i Â_l L_lm / π in Unity's frame, giving E/π.

    The shaders' unity_SHAr… are built from sh[c, 0..8]: coefficient i of channel c is K_i Â_l L_lm / π with L_lm stated
    in Unity's left-handed frame (x, y, −z of world), order L00, L1−1 (y), L10 (z), L11 (x), L2−2, L2−1, L20, L21, L22.
    ShadeSH9 then returns E/π, which Unity multiplies by the albedo. (Unity does not document this layout; it follows
    from unity_SHAr = (sh[3], sh[1], sh[2], sh[0] − sh[6]), unity_SHBr = (sh[4], sh[5], 3 sh[6], sh[7]), unity_SHC =
    sh[8].)

    Parameters
    ----------
    sh : SHCoeffs
        Radiance SH of order 2 or more (truncated to 2), stated in whatever frame.
    frame : Frame, default UNITY
        Where the coefficients end up: by default Unity's left-handed frame, (x, y, −z) of world.

    Returns
    -------
    numpy.ndarray
        (9, 3): row i, column c is ``sh[c, i]`` of ``SphericalHarmonicsL2``.

    Raises
    ------
    UsageError
        ``sh`` holds irradiance, or its order is below 2.
    """
    return _lambertian_nine(sh, frame)


def export_unity(sh: SHCoeffs, frame: Frame = UNITY, csharp: bool = True) -> str:
    """A C# method returning the ``SphericalHarmonicsL2`` (``csharp``), or JSON ``{"sh": [[9 r], [9 g], [9 b]]}``.

    Parameters
    ----------
    sh : SHCoeffs
        The ambient as radiance SH (order 2 or more).
    frame : Frame, default UNITY
        Passed to :func:`unity_coefficients`; the JSON form records its name.
    csharp : bool, default True
        Write the C# class ``LightprobeAmbient`` with ``Create()``; False writes the JSON, which also names the
        frame and the scaling.

    Returns
    -------
    str
        The C# source or the JSON text; values K_i Â_l L_lm / π (ShadeSH9 gives E/π).

    Raises
    ------
    UsageError
        ``sh`` holds irradiance, or its order is below 2.
    """
    c = unity_coefficients(sh, frame)
    if not csharp:
        return json.dumps({"format": "UnityEngine.Rendering.SphericalHarmonicsL2", "frame": frame.name,
                           "scaling": "K_i * A_l * L_lm / pi (ShadeSH9 gives E/pi)",
                           "sh": [[float(c[i, ch]) for i in range(9)] for ch in range(3)]}, indent=1,
                          allow_nan=False)
    lines = [f"        sh[{ch}, {i}] = {c[i, ch]:.9g}f;  // {'RGB'[ch]} {name(i)}"
             for ch in range(3) for i in range(9)]
    return ("// lightprobe export: ambient SH for Unity (frame: Unity's left-handed +Y up, +Z forward).\n"
            "// Values are K_i * A_l * L_lm / pi, the layout ShadeSH9 / unity_SHAr.. expect (E/pi).\n"
            "using UnityEngine.Rendering;\n\npublic static class LightprobeAmbient\n{\n"
            "    public static SphericalHarmonicsL2 Create()\n    {\n        var sh = new SphericalHarmonicsL2();\n"
            + "\n".join(lines) + "\n        return sh;\n    }\n}\n")


@_engine_form("glTF")
def gltf_coefficients(sh: SHCoeffs, scaling: str = "irradiance", frame: Frame = BABYLON) -> np.ndarray:
    """``EXT_lights_image_based.irradianceCoefficients`` (9 × RGB), CS-phase basis.

    The extension calls them "irradiance" but fixes neither the basis, nor the π, nor the frame; lightprobe follows
    its reference consumer, Babylon.js's loader, which reads them as irradiance E_lm (``FromArray``), divides by π
    (``convertIrradianceToLambertianRadiance``) and builds its polynomial with ``FromHarmonics`` — the same steps its
    own panorama path takes after convolving — and applies no handedness change to them, so they are stated in
    Babylon's frame (x, y, −z). ``scaling``: ``irradiance`` (default) E_lm = Â_l L_lm; ``pi-radiance``: π L_lm, the
    old default, which Babylon's loader renders with the cosine lobe missing (kept for files made that way).

    Parameters
    ----------
    sh : SHCoeffs
        Radiance coefficients with at least bands 0–2 (higher ones are ignored), from any frame.
    scaling : str, default "irradiance"
        ``irradiance`` or ``pi-radiance`` (:data:`lightprobe.util.names.GLTF_SCALINGS`), as above.
    frame : Frame, default BABYLON
        The frame of the result: Babylon's (x, y, −z) by default, as its loader takes them without a change.

    Returns
    -------
    numpy.ndarray
        (9, 3) coefficients with the Condon–Shortley phase, flat order, RGB columns.

    Raises
    ------
    UsageError
        ``sh`` holds irradiance, its order is below 2, or ``scaling`` is unknown.
    """
    c = to_condon_shortley(_nine(sh, frame))
    if scaling == "irradiance":
        return radiance_to_irradiance(c)
    if scaling == "pi-radiance":
        return times_pi(c)
    raise UsageError(f"unknown glTF scaling {scaling!r}; choose {', '.join(GLTF_SCALINGS)}")


def export_gltf(sh: SHCoeffs, scaling: str = "irradiance", frame: Frame = BABYLON) -> str:
    """The ``EXT_lights_image_based`` light object with ``irradianceCoefficients``, to merge into a glTF.

    The prefiltered specular images come from the radiance-map part of lightprobe.

    Parameters
    ----------
    sh : SHCoeffs
        Radiance coefficients, l_max ≥ 2, any frame.
    scaling : str, default "irradiance"
        ``irradiance`` or ``pi-radiance`` (see :func:`gltf_coefficients`).
    frame : Frame, default BABYLON
        The frame of the coefficients.

    Returns
    -------
    str
        JSON with ``extensionsUsed`` and the extension's one light (no specular images); ``extras`` names the
        scaling, the basis and the frame.

    Raises
    ------
    UsageError
        ``sh`` holds irradiance, its order is below 2, or ``scaling`` is unknown.
    """
    c = gltf_coefficients(sh, scaling, frame)
    return json.dumps({
        "extensionsUsed": ["EXT_lights_image_based"],
        "extensions": {"EXT_lights_image_based": {"lights": [{
            "name": "lightprobe",
            "intensity": 1.0,
            "rotation": [0.0, 0.0, 0.0, 1.0],
            "irradianceCoefficients": [[float(v) for v in row] for row in c],
            "extras": {"lightprobe": {"scaling": scaling, "basis": "Condon-Shortley phase", "frame": frame.name}},
        }]}},
    }, indent=1, allow_nan=False)


def babylon_polynomial_from_harmonics(h: np.ndarray) -> dict[str, np.ndarray]:
    """Babylon's ``SphericalPolynomial.FromHarmonics`` with exact constants, for harmonics ``h`` in our basis.

    ``h`` has no CS phase (Babylon's signs on x, y, yz, zx cancel its CS phase): the cosine convolution and ÷π of eq.
    13, the constant c4 h00 − c5 h20 spread over xx + yy + zz (= 1 on the sphere). (Babylon's 0.886277 is a misprint of
    c4 = 0.886227.) Its ``FromPolynomial`` inverts this exactly, giving ``h`` back.

    Parameters
    ----------
    h : numpy.ndarray
        (9, 3) harmonics of bands ≤ 2 in our basis (no CS phase), flat order, RGB columns; Babylon passes its E/π
        harmonics (:func:`babylon_polynomial`).

    Returns
    -------
    dict of str to numpy.ndarray
        The nine terms ``x``, ``y``, ``z``, ``xx``, ``yy``, ``zz``, ``yz``, ``zx``, ``xy``, each (3,) RGB.
    """
    L = irradiance_to_lambertian(h)  # noqa: N806 - the paper's notation, /π folded in
    const = C4 * L[0] - C5 * L[6]
    return {
        "x": 2 * C2 * L[3], "y": 2 * C2 * L[1], "z": 2 * C2 * L[2],
        "xx": const + C1 * L[8], "yy": const - C1 * L[8], "zz": const + C3 * L[6],
        "yz": 2 * C1 * L[5], "zx": 2 * C1 * L[7], "xy": 2 * C1 * L[4],
    }


@_engine_form("Babylon")
def babylon_harmonics(sh: SHCoeffs, frame: Frame = BABYLON) -> np.ndarray:
    """The harmonics Babylon lights with: E/π SH (Â_l L_lm / π), CS phase, Babylon's frame.

    They are what its cube path holds after ``convertIncidentRadianceToIrradiance`` and
    ``convertIrradianceToLambertianRadiance``, and what ``preScaledHarmonics`` (= ``FromPolynomial``) recovers for the
    default PBR shader (which evaluates E/π).

    Parameters
    ----------
    sh : SHCoeffs
        The radiance SH to light with (l_max ≥ 2; bands past 2 left out), any frame.
    frame : Frame, default BABYLON
        The frame the harmonics are stated in; default Babylon's left-handed scene frame, (x, y, −z) of world.

    Returns
    -------
    numpy.ndarray
        (9, 3) Â_l L_lm / π with the CS phase, flat order, RGB columns.

    Raises
    ------
    UsageError
        ``sh`` holds irradiance, or its order is below 2.
    """
    return to_condon_shortley(irradiance_to_lambertian(radiance_to_irradiance(_nine(sh, frame))))


@_engine_form("Babylon")
def babylon_polynomial(sh: SHCoeffs, frame: Frame = BABYLON) -> dict[str, np.ndarray]:
    """Babylon.js ``SphericalPolynomial`` (x, y, z, xx, yy, zz, yz, zx, xy; RGB each) in Babylon's frame.

    Made as Babylon itself makes it from a panorama: ``FromHarmonics`` of the E/π harmonics (:func:`babylon_harmonics`).
    Babylon's default PBR path turns it back into those harmonics and renders E/π; evaluated directly as a polynomial it
    would be convolved twice (Babylon's own convention, not a second step of ours).

    Parameters
    ----------
    sh : SHCoeffs
        Radiance SH to turn into a polynomial: l_max of 2 or more (the rest unused), any frame.
    frame : Frame, default BABYLON
        The polynomial's frame (x, y, z are its axes); default Babylon's, (x, y, −z) of world.

    Returns
    -------
    dict of str to numpy.ndarray
        ``x`` … ``xy`` (:func:`babylon_polynomial_from_harmonics`), each (3,) RGB.

    Raises
    ------
    UsageError
        ``sh`` holds irradiance, or its order is below 2.
    """
    e_over_pi = irradiance_to_lambertian(radiance_to_irradiance(_nine(sh, frame)))
    return babylon_polynomial_from_harmonics(e_over_pi)


def export_babylon(sh: SHCoeffs, frame: Frame = BABYLON) -> str:
    """Babylon.js JSON: the irradiance ``polynomial``, the ``harmonics`` it lights with and the radiance harmonics.

    The ``polynomial`` (for ``SphericalPolynomial.FromArray``, order x, y, z, xx, yy, zz, yz, zx, xy), the
    ``harmonics`` Babylon lights with (E/π, CS phase, for ``SphericalHarmonics.FromArray``) and, for tools that
    want them, the ``radiance_harmonics`` (L_lm, CS phase), all in ``frame``.

    Parameters
    ----------
    sh : SHCoeffs
        Radiance coefficients, l_max ≥ 2, any frame.
    frame : Frame, default BABYLON
        The frame of everything in the file (named in it).

    Returns
    -------
    str
        The JSON text (``format`` ``BABYLON.SphericalPolynomial``, with a ``note`` on what each part is).

    Raises
    ------
    UsageError
        ``sh`` holds irradiance, or its order is below 2.
    """
    poly = babylon_polynomial(sh, frame)
    order = ["x", "y", "z", "xx", "yy", "zz", "yz", "zx", "xy"]
    return json.dumps({
        "format": "BABYLON.SphericalPolynomial", "frame": frame.name,
        "polynomial_order": order,
        "polynomial": [[float(v) for v in poly[k]] for k in order],
        "harmonics": [[float(v) for v in row] for row in babylon_harmonics(sh, frame)],
        "radiance_harmonics": [[float(v) for v in row] for row in to_condon_shortley(_nine(sh, frame))],
        "note": "polynomial as Babylon's own panorama path makes it (FromHarmonics of E/pi harmonics); harmonics "
                "are E/pi SH in Babylon's CS-phase basis (its preScaledHarmonics before the basis constants); "
                "radiance_harmonics are L_lm, CS phase",
    }, indent=1, allow_nan=False)


def export_glsl(sh: SHCoeffs, frame: Frame = WORLD) -> str:
    """A GLSL snippet of eq. 13: nine radiance coefficients L_lm (no CS phase, ``frame``) and the constants c1..c5.

    ``lightprobeIrradiance(n)`` returns E(n) (divide by π for a Lambertian surface).

    Parameters
    ----------
    sh : SHCoeffs
        The lighting as radiance coefficients, at least up to band 2 (the snippet holds nine), any frame.
    frame : Frame, default WORLD
        The frame of the coefficients, and so of the normal ``n`` the shader function takes.

    Returns
    -------
    str
        GLSL source: ``const vec3`` coefficients ``L00`` … ``L22`` (``L1m1`` for L1−1), ``const float`` c1..c5
        and ``vec3 lightprobeIrradiance(vec3 n)``.

    Raises
    ------
    UsageError
        ``sh`` holds irradiance, or its order is below 2.
    """
    c = _nine(sh, frame)
    coeffs = "\n".join(f"const vec3 L{name(i)[1:].replace('-', 'm')} = vec3({', '.join(f'{v:.9g}' for v in row)});"
                       f"  // {name(i)}" for i, row in enumerate(c))
    return f"""// lightprobe: irradiance environment map, Ramamoorthi & Hanrahan 2001, eq. 13.
// Radiance SH coefficients L_lm (basis without Condon-Shortley phase), frame: {frame.name}.
// lightprobeIrradiance(n) returns irradiance E(n) for a unit normal n in that frame; a Lambertian surface of
// albedo rho reflects rho * E / pi.
{coeffs}
const float c1 = {C1:.9f};  // (pi/4) * 0.546274            (band 2, x^2-y^2 and 2*c1 for xy, yz, xz)
const float c2 = {C2:.9f};  // (2pi/3) * 0.488603 / 2        (band 1, used as 2*c2)
const float c3 = {C3:.9f};  // (pi/4) * 0.315392 * 3         (band 2, z^2)
const float c4 = {C4:.9f};  // pi * 0.282095                 (band 0)
const float c5 = {C5:.9f};  // (pi/4) * 0.315392             (band 2, constant part of L20)

vec3 lightprobeIrradiance(vec3 n) {{
    return c1 * L22 * (n.x * n.x - n.y * n.y) + c3 * L20 * n.z * n.z + c4 * L00 - c5 * L20
         + 2.0 * c1 * (L2m2 * n.x * n.y + L21 * n.x * n.z + L2m1 * n.y * n.z)
         + 2.0 * c2 * (L11 * n.x + L1m1 * n.y + L10 * n.z);
}}
"""


def export(sh: SHCoeffs, target: str, frame: str | Frame | None = None, gltf_scaling: str = "irradiance",
           csharp: bool = True) -> str:
    """Text of ``sh`` for ``target`` (one of :data:`TARGETS`), in the target's frame unless ``frame`` is given.

    Parameters
    ----------
    sh : SHCoeffs
        Radiance coefficients; l_max ≥ 2 for every target but ``json``, which writes any order.
    target : str
        ``json``, ``threejs``, ``filament``, ``unity``, ``gltf``, ``babylon`` or ``glsl``.
    frame : str or Frame, optional
        A frame name of :data:`lightprobe.maps.frames.FRAMES` or a :class:`~lightprobe.maps.frames.Frame`;
        default the target's own (:data:`DEFAULT_FRAMES`).
    gltf_scaling : str, default "irradiance"
        The ``gltf`` target's scaling: ``irradiance`` or ``pi-radiance`` (:func:`gltf_coefficients`).
    csharp : bool, default True
        The ``unity`` target: C# (True) or JSON (False).

    Returns
    -------
    str
        The file's text, as the target's exporter writes it.

    Raises
    ------
    UsageError
        ``target``, ``frame`` or ``gltf_scaling`` is unknown, or ``sh`` does not fit the target (irradiance, or
        order below 2).
    """
    if target not in TARGETS:
        raise UsageError(f"unknown export target {target!r}; choose one of {', '.join(TARGETS)}")
    f = frame_named(frame) if frame is not None else DEFAULT_FRAMES[target]
    if target == "json":
        return export_json(sh, f)
    if target == "threejs":
        return export_threejs(sh, f)
    if target == "filament":
        return export_filament(sh, f)
    if target == "unity":
        return export_unity(sh, f, csharp)
    if target == "gltf":
        return export_gltf(sh, gltf_scaling, f)
    if target == "babylon":
        return export_babylon(sh, f)
    return export_glsl(sh, f)
