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
    """``L1-1=-0.4`` (all channels) or ``L20=0.1,0.2,0.3`` (RGB) → ((l, m), rgb)."""
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
    """``2=0.5`` → (band 2, factor 0.5)."""
    try:
        band, factor = text.split("=")
        band, factor = int(band), float(factor)
    except ValueError:
        raise LightprobeError(f"cannot read the band scale {text[:40]!r}; write it like 2=0.5") from None
    if band < 0 or not (np.isfinite(factor) and abs(factor) <= MAX_FACTOR):
        raise LightprobeError(f"{text[:40]!r}: the band must be ≥ 0 and the factor finite with |F| ≤ {MAX_FACTOR:g}")
    return band, factor


def edit(sh: SHCoeffs, sets: list[str] = (), scales: list[str] = ()) -> SHCoeffs:
    """Apply ``--scale-band`` edits, then ``--set`` edits, to radiance coefficients."""
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
    """World normals of an orthographic sphere image (size × size) and its coverage mask."""
    c = (np.arange(size) + 0.5) / size * 2 - 1
    x, y = np.meshgrid(c, -c)
    r2 = x * x + y * y
    inside = r2 <= 1
    z = np.sqrt(np.clip(1 - r2, 0, None))
    n = np.stack([x, y, z], axis=-1) if not back else np.stack([-x, y, -z], axis=-1)
    return n, inside


def lit_sphere(sh: SHCoeffs, size: int, back: bool = False, background: float = 0.0) -> np.ndarray:
    """Radiance E(n)/π of a white Lambertian sphere under ``sh`` (radiance coefficients)."""
    n, inside = sphere_normals(size, back)
    e = sh.to_irradiance().evaluate(n) / np.pi
    return np.where(inside[..., None], e, background).astype(np.float32)


def basis_sphere(l: int, m: int, size: int) -> np.ndarray:
    """Display colours of Y_lm on a sphere: orange where positive, blue where negative (linear RGB)."""
    n, inside = sphere_normals(size)
    i = l * (l + 1) + m
    v = basis(l, n)[..., i]
    v = v / max(np.abs(v[inside]).max(), 1e-12)
    pos, neg = np.array([1.0, 0.45, 0.05]), np.array([0.05, 0.35, 1.0])
    rgb = np.where(v[..., None] >= 0, v[..., None] * pos, -v[..., None] * neg)
    return np.where(inside[..., None], rgb, 0.12).astype(np.float32)


def design_figure(original: SHCoeffs, edited: SHCoeffs, size: int = 128, exposure: float | None = None) -> np.ndarray:
    """Display-referred figure (sRGB values in [0, 1]): the basis functions of bands ≤ 2 (top row), then front and
    back views of the original and the edited lighting on white spheres, with one shared exposure; labelled."""
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
    """A dark strip with each caption centred under its panel (display values)."""
    height = max(14, panel // 6)
    buf = oiio.ImageBuf(oiio.ImageSpec(width, height, 3, "float"))
    oiio.ImageBufAlgo.fill(buf, (0.12, 0.12, 0.12))
    font = max(9, int(height * 0.7))
    for x, text in captions:
        oiio.ImageBufAlgo.render_text(buf, x + panel // 2, int(height * 0.78), text, font, "", (0.9, 0.9, 0.9),
                                      alignx="center")
    return np.asarray(buf.get_pixels(oiio.FLOAT), dtype=np.float32).reshape(height, width, 3)


def tonemap_display(rgb: np.ndarray) -> np.ndarray:
    """Linear colours in [0, 1] → sRGB display values."""
    return tonemap(rgb, 0.0, "srgb")


def labels() -> list[str]:
    return [name(i) for i in range(9)]
