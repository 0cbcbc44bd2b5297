"""Lighting design with SH coefficients (paper §3.3, Figure 4): edit coefficients, see the result on spheres.

Spheres are drawn orthographically as a camera standing in the world frame sees an object in front of it: image
right = +X, up = +Y, and the visible hemisphere faces back toward the camera (+Z). A ``back`` view shows the other
hemisphere (the camera turned around). Rendered values are radiance of a white Lambertian sphere, E(n)/π.
"""

from __future__ import annotations

import re

import numpy as np
import OpenImageIO as oiio

from ..util.errors import LightprobeError
from .basis import SHCoeffs, basis, degree_order, n_coeffs, name
from ..maps.tonemap import tonemap

_EDIT = re.compile(r"^L(\d+)(-?\d+)=(.+)$")
MAX_VALUE = 1e9  # |coefficient| an edit may set
MAX_FACTOR = 1e6  # |factor| a band may be scaled by


def parse_set(text: str) -> tuple[tuple[int, int], np.ndarray]:
    """``L1-1=-0.4`` (all channels) or ``L20=0.1,0.2,0.3`` (RGB) → ((l, m), rgb).

    Parameters
    ----------
    text : str
        One ``--set`` edit, ``L<l><m>=<value>`` or ``L<l><m>=<r>,<g>,<b>``; spaces are ignored. |m| ≤ l, and each
        value finite with |V| ≤ :data:`MAX_VALUE`.

    Returns
    -------
    tuple of ((int, int), numpy.ndarray)
        (l, m) and the (3,) float64 RGB value (one value repeated for every channel).

    Raises
    ------
    LightprobeError
        The text is not an edit of that form, |m| > l, there are neither one nor three values, or a value is not
        finite or over :data:`MAX_VALUE`.
    """
    match = _EDIT.match(text.replace(" ", ""))
    if not match:
        raise LightprobeError(f"cannot read the edit {text[:40]!r}; write it like L1-1=-0.4 or L20=0.1,0.2,0.3")
    l, m = int(match.group(1)), int(match.group(2))
    if abs(m) > l:
        raise LightprobeError(f"{text[:40]!r}: |m| must not exceed l")
    try:
        values = [float(v) for v in match.group(3).split(",")]
    except ValueError:
        raise LightprobeError(f"cannot read the value of {text[:40]!r}") from None
    if len(values) not in (1, 3):
        raise LightprobeError(f"{text[:40]!r}: give one value or three (R,G,B)")
    if not all(np.isfinite(v) and abs(v) <= MAX_VALUE for v in values):
        raise LightprobeError(f"{text[:40]!r}: values must be finite numbers with |V| ≤ {MAX_VALUE:g}")
    return (l, m), np.broadcast_to(np.array(values), (3,)).copy()


def parse_scale(text: str) -> tuple[int, float]:
    """``2=0.5`` → (band 2, factor 0.5).

    Parameters
    ----------
    text : str
        One ``--scale-band`` edit, ``<band>=<factor>``: band a whole number ≥ 0, factor finite with
        |F| ≤ :data:`MAX_FACTOR`.

    Returns
    -------
    tuple of (int, float)
        The band and the factor.

    Raises
    ------
    LightprobeError
        The text is not of that form, the band is negative, or the factor is not finite or over
        :data:`MAX_FACTOR`.
    """
    try:
        band, factor = text.split("=")
        band, factor = int(band), float(factor)
    except ValueError:
        raise LightprobeError(f"cannot read the band scale {text[:40]!r}; write it like 2=0.5") from None
    if band < 0 or not (np.isfinite(factor) and abs(factor) <= MAX_FACTOR):
        raise LightprobeError(f"{text[:40]!r}: the band must be ≥ 0 and the factor finite with |F| ≤ {MAX_FACTOR:g}")
    return band, factor


def edit(sh: SHCoeffs, sets: list[str] = (), scales: list[str] = ()) -> SHCoeffs:
    """Apply ``--scale-band`` edits, then ``--set`` edits, to radiance coefficients.

    Parameters
    ----------
    sh : SHCoeffs
        The coefficients to edit (radiance L_lm, in their own frame: an edit's L_lm is in that frame).
    sets : list of str, default ()
        ``--set`` edits, applied in order after the scales (:func:`parse_set`).
    scales : list of str, default ()
        ``--scale-band`` edits, applied in order first (:func:`parse_scale`).

    Returns
    -------
    SHCoeffs
        The edited coefficients, same frame, quantity and window.

    Raises
    ------
    LightprobeError
        An edit cannot be read, or names a band above the coefficients' order.
    """
    for text in scales:
        band, factor = parse_scale(text)
        if band > sh.l_max:
            raise LightprobeError(f"band {band} is above the coefficients' order {sh.l_max}")
        sh = sh.scaled_band(band, factor)
    for text in sets:
        (l, m), rgb = parse_set(text)
        if l > sh.l_max:
            raise LightprobeError(f"L{l}{m} is above the coefficients' order {sh.l_max}")
        sh = sh.with_coefficient((l, m), rgb)
    return sh


def sphere_normals(size: int, back: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """World normals of an orthographic sphere image (size × size) and its coverage mask.

    The front view faces the camera (+Z at the centre, image right +X, up +Y); ``back`` turns the camera around
    (−Z at the centre, image right −X).

    Parameters
    ----------
    size : int
        Image width and height in pixels.
    back : bool, default False
        Show the other hemisphere.

    Returns
    -------
    normals : numpy.ndarray
        (size, size, 3) float64 world-frame unit normals (row 0 at the top); outside the disc they are not unit
        vectors and mean nothing.
    inside : numpy.ndarray
        (size, size) bool: the pixels whose centres lie on the disc.
    """
    c = (np.arange(size) + 0.5) / size * 2 - 1
    x, y = np.meshgrid(c, -c)
    r2 = x * x + y * y
    inside = r2 <= 1
    z = np.sqrt(np.clip(1 - r2, 0, None))
    n = np.stack([x, y, z], axis=-1) if not back else np.stack([-x, y, -z], axis=-1)
    return n, inside


def lit_sphere(sh: SHCoeffs, size: int, back: bool = False, background: float = 0.0) -> np.ndarray:
    """Radiance E(n)/π of a white Lambertian sphere under ``sh`` (radiance coefficients).

    Parameters
    ----------
    sh : SHCoeffs
        Radiance coefficients L_lm, any order and frame.
    size : int
        Image width and height in pixels (see :func:`sphere_normals`).
    back : bool, default False
        Show the back hemisphere instead of the front.
    background : float, default 0.0
        The value of every channel outside the sphere.

    Returns
    -------
    numpy.ndarray
        (size, size, 3) float32 linear radiance E(n)/π (not tone-mapped).

    Raises
    ------
    UsageError
        ``sh`` holds irradiance, not radiance.
    """
    n, inside = sphere_normals(size, back)
    e = sh.to_irradiance().evaluate(n) / np.pi
    return np.where(inside[..., None], e, background).astype(np.float32)


def basis_sphere(l: int, m: int, size: int) -> np.ndarray:
    """Display colours of Y_lm on a sphere: orange where positive, blue where negative (linear RGB).

    The front view of :func:`sphere_normals` (world frame), scaled so that the largest |Y_lm| on the sphere is 1.

    Parameters
    ----------
    l : int
        The band, ≥ 0.
    m : int
        The order, −l ≤ m ≤ l.
    size : int
        Image width and height in pixels.

    Returns
    -------
    numpy.ndarray
        (size, size, 3) float32 linear RGB in [0, 1]; grey 0.12 outside the sphere.
    """
    n, inside = sphere_normals(size)
    i = l * (l + 1) + m
    v = basis(l, n)[..., i]
    v = v / max(np.abs(v[inside]).max(), 1e-12)
    pos, neg = np.array([1.0, 0.45, 0.05]), np.array([0.05, 0.35, 1.0])
    rgb = np.where(v[..., None] >= 0, v[..., None] * pos, -v[..., None] * neg)
    return np.where(inside[..., None], rgb, 0.12).astype(np.float32)


def design_figure(original: SHCoeffs, edited: SHCoeffs, size: int = 128, exposure: float | None = None) -> np.ndarray:
    """Display-referred figure (sRGB values in [0, 1]): the SH basis, then the original and edited lighting.

    The basis functions of bands ≤ 2 (top row), then front and back views of the original and the edited
    lighting on white spheres, with one shared exposure; labelled.

    Parameters
    ----------
    original : SHCoeffs
        Radiance coefficients before the edit.
    edited : SHCoeffs
        Radiance coefficients after the edit.
    size : int, default 128
        Each panel's width and height in pixels.
    exposure : float, optional
        Exposure in stops of the ACES-tone-mapped spheres; default: the one that maps the largest 99th percentile
        of the four spheres' lit values to 0.8.

    Returns
    -------
    numpy.ndarray
        (2·size + 2·caption height, 9·size, 3) float32 display values: nine basis panels (L00 … L22), a caption
        strip, the four lit spheres (with gaps), another caption strip; the caption height is max(14, size // 6).

    Raises
    ------
    UsageError
        A coefficient set holds irradiance, or ``exposure`` is outside the tone mapper's range.
    """
    bases = [basis_sphere(*degree_order(i), size) for i in range(n_coeffs(2))]
    spheres = [lit_sphere(s, size, back) for s in (original, edited) for back in (False, True)]
    if exposure is None:
        peak = max(float(np.percentile(s[s > 0], 99)) if (s > 0).any() else 1.0 for s in spheres)
        exposure = float(np.log2(0.8 / max(peak, 1e-12)))
    lit = [tonemap(s, exposure, "aces") for s in spheres]
    gap = np.full((size, size, 3), 0.12, np.float32)
    top = np.concatenate([tonemap_display(b) for b in bases], axis=1)
    bottom = np.concatenate(lit[:2] + [gap] + lit[2:] + [gap] * 4, axis=1)
    captions_top = [(i * size, label) for i, label in enumerate(labels())]
    captions_bottom = [(0, "original, front"), (size, "original, back"), (3 * size, "edited, front"),
                       (4 * size, "edited, back")]
    return np.concatenate([top, caption_strip(top.shape[1], captions_top, size),
                           bottom, caption_strip(top.shape[1], captions_bottom, size)], axis=0)


def caption_strip(width: int, captions: list[tuple[int, str]], panel: int) -> np.ndarray:
    """A dark strip with each caption centred under its panel (display values).

    Parameters
    ----------
    width : int
        The strip's width in pixels.
    captions : list of tuple of (int, str)
        (x, text) per caption: x the left edge of its panel in pixels.
    panel : int
        The panels' width in pixels; the strip's height is max(14, panel // 6).

    Returns
    -------
    numpy.ndarray
        (max(14, panel // 6), width, 3) float32 display values: grey 0.12 with light grey text.
    """
    height = max(14, panel // 6)
    buf = oiio.ImageBuf(oiio.ImageSpec(width, height, 3, "float"))
    oiio.ImageBufAlgo.fill(buf, (0.12, 0.12, 0.12))
    font = max(9, int(height * 0.7))
    for x, text in captions:
        oiio.ImageBufAlgo.render_text(buf, x + panel // 2, int(height * 0.78), text, font, "", (0.9, 0.9, 0.9),
                                      alignx="center")
    return np.asarray(buf.get_pixels(oiio.FLOAT), dtype=np.float32).reshape(height, width, 3)


def tonemap_display(rgb: np.ndarray) -> np.ndarray:
    """Linear colours in [0, 1] → sRGB display values.

    Parameters
    ----------
    rgb : numpy.ndarray
        (..., 3) linear RGB; values above 1 clip, NaN and negative values show as black.

    Returns
    -------
    numpy.ndarray
        (..., 3) float32 sRGB-encoded values in [0, 1] (no exposure change).
    """
    return tonemap(rgb, 0.0, "srgb")


def labels() -> list[str]:
    """The names of the nine coefficients of bands ≤ 2, the figure's top-row captions.

    Returns
    -------
    list of str
        ``L00``, ``L1-1``, ``L10``, ``L11``, ``L2-2``, ``L2-1``, ``L20``, ``L21``, ``L22``.
    """
    return [name(i) for i in range(9)]
