"""The environment itself in engines' own containers, so the background and the lighting travel in one file.

* Babylon.js ``.env`` (its ``EnvironmentTextureTools`` format, version 2): 8 magic bytes, a JSON manifest ended by
  a NUL, then one PNG per cube face and mip. The manifest carries the irradiance as Babylon's
  ``SphericalPolynomial`` (:func:`lightprobe.exports.sh.babylon_polynomial`, E/π in Babylon's frame) and the specular
  mips' byte ranges with their ``lodGenerationScale``; the PNGs are RGBD-encoded GGX-prefiltered radiance
  (:mod:`lightprobe.glossy.prefilter`, Babylon's roughness per mip).
* glTF ``EXT_lights_image_based``: the same RGBD mips as ``specularImages`` beside ``irradianceCoefficients``
  (:func:`lightprobe.exports.sh.gltf_coefficients`), as a ``.glb`` or a ``.gltf`` with embedded images. The extension
  fixes neither the image encoding nor the roughness per mip; lightprobe follows its reference consumer, Babylon's
  loader: RGBD PNGs, and a full chain (levels = log₂ size + 1), which that loader reads with
  lodGenerationScale = (levels − 1)/log₂ size = 1, so mip i holds α = 2^i/size.

Quantity in both: **radiance** in the map's units, RGBD-encoded — rgb = (L·D)^(1/2.2) and alpha D, D = ⌊255/max⌋/255
clamped to [1/255, 1], as Babylon's ``toRGBD`` — so values above 255 are clamped (said by :func:`rgbd_clipped`). The
cube faces are OpenGL-ordered (+X, −X, +Y, −Y, +Z, −Z) in Babylon's frame (x, y, −z) of world, the frame its
HDRCubeTexture shows a panorama in (checked in Babylon's own renderer by the engine tests).
"""

from __future__ import annotations

import base64
import io
import json
import struct
import warnings

import numpy as np

from ..maps import EnvMap
from ..util.errors import InputError, LightprobeWarning, UsageError
from .sh import babylon_polynomial, gltf_coefficients
from ..maps.frames import BABYLON, Frame
from ..glossy.prefilter import PrefilteredCube, babylon_alphas, prefilter_cube
from ..sh.basis import SHCoeffs

ENV_MAGIC = bytes([0x86, 0x16, 0x87, 0x96, 0xF6, 0xD6, 0x96, 0x36])  # Babylon's .env signature
ENV_VERSION = 2
ENV_LOD_GENERATION_SCALE = 0.8  # Babylon's own HDRFiltering and .env files
RGBD_MAX = 255.0  # Babylon's rgbdMaxRange: the largest radiance an RGBD texel holds
GAMMA = 2.2  # Babylon's toGammaSpace / toLinearSpace approximation, used by its RGBD encode and decode
POLYNOMIAL_KEYS = ("x", "y", "z", "xx", "yy", "zz", "yz", "zx", "xy")


# ---- RGBD ---------------------------------------------------------------------------------------------------------
def rgbd_encode(radiance: np.ndarray) -> np.ndarray:
    """Linear RGB radiance (..., 3) → RGBD bytes (..., 4), exactly Babylon's ``toRGBD`` then 8-bit rounding.

    Parameters
    ----------
    radiance : numpy.ndarray
        (..., 3) linear RGB radiance in the map's units; NaN counts as 0, +∞ as 255 and negative values as 0.
        Values above :data:`RGBD_MAX` (255) are clamped.

    Returns
    -------
    numpy.ndarray
        (..., 4) uint8: rgb = (L·D)^(1/2.2) and alpha D, D = ⌊255/max⌋/255 clamped to [1/255, 1].
    """
    c = np.maximum(np.nan_to_num(np.asarray(radiance, np.float64), nan=0.0, posinf=RGBD_MAX), 0.0)
    peak = np.maximum(c.max(axis=-1), 1e-7)
    d = np.clip(np.floor(np.maximum(RGBD_MAX / peak, 1.0)) / 255.0, 0.0, 1.0)
    rgb = np.clip(c * d[..., None], 0.0, 1.0) ** (1 / GAMMA)
    return np.rint(np.concatenate([rgb, d[..., None]], axis=-1) * 255).astype(np.uint8)


def rgbd_decode(rgbd: np.ndarray) -> np.ndarray:
    """RGBD bytes (..., 4) → linear radiance (..., 3), as Babylon's ``fromRGBD``.

    Parameters
    ----------
    rgbd : numpy.ndarray
        (..., 4) RGBD values 0..255 (uint8 as :func:`rgbd_encode` makes them); a D below 1 counts as 1.

    Returns
    -------
    numpy.ndarray
        (..., 3) float64 linear radiance: (rgb/255)^2.2 / (D/255).
    """
    x = np.asarray(rgbd, np.float64) / 255.0
    return (x[..., :3] ** GAMMA) / np.maximum(x[..., 3:], 1 / 255)


def rgbd_clipped(cube: PrefilteredCube, level: int = 0) -> float:
    """Share of a mip's power lost to the RGBD clamp at 255.

    The power is RGB summed over texels; cube texels differ in solid angle by at most 5.2×, so this is the order of
    the ∫L dω share.

    Parameters
    ----------
    cube : PrefilteredCube
        The GGX mip chain (radiance).
    level : int, default 0
        The mip (0: the mirror level, the sharpest and brightest).

    Returns
    -------
    float
        Σ max(L − 255, 0) / Σ L over the mip's texels and channels, in [0, 1].
    """
    values = cube.levels[level].astype(np.float64)
    return float(np.maximum(values - RGBD_MAX, 0).sum() / max(values.sum(), 1e-300))


def warn_if_clipped(cube: PrefilteredCube) -> None:
    """Warn when RGBD's clamp at 255 loses over 0.1 % of the mirror mip's power.

    The warning gives the share clipped of mip 0 (and of mip 1 if any) and the first mip from which nothing is
    clipped; the SH lighting is not affected.

    Parameters
    ----------
    cube : PrefilteredCube
        The GGX mip chain (radiance) about to be RGBD-encoded.

    Warns
    -----
    LightprobeWarning
        More than 0.1 % of mip 0's power lies above 255.
    """
    shares = [rgbd_clipped(cube, i) for i in range(len(cube.levels))]
    if shares[0] > 1e-3:
        kept = next((i for i, share in enumerate(shares) if share == 0), len(shares))
        warnings.warn(LightprobeWarning(
            f"RGBD holds radiance up to {RGBD_MAX:g}: {100 * shares[0]:.1f} % of the mirror mip's power is clipped"
            + (f", {100 * shares[1]:.1f} % of mip 1's" if len(shares) > 1 and shares[1] > 0 else "")
            + f"; mips {kept} and up and the SH lighting keep all of it"), stacklevel=3)


def png_bytes(rgba: np.ndarray) -> bytes:
    """An RGBA image as the bytes of a PNG file (8 bits a channel, zlib level 6).

    Parameters
    ----------
    rgba : numpy.ndarray
        (H, W, 4) uint8, row 0 at the top of the PNG.

    Returns
    -------
    bytes
        The PNG file.
    """
    from PIL import Image

    buffer = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(rgba), "RGBA").save(buffer, format="PNG", compress_level=6)
    return buffer.getvalue()


def face_pngs(cube: PrefilteredCube, gamma_space: bool = False) -> list[list[bytes]]:
    """RGBD PNGs of every mip (outer) and face (inner, +X −X +Y −Y +Z −Z), each face's rows bottom to top.

    Babylon uploads them with invertY, so the PNG's first row becomes the face's last (checked against its own
    skybox).

    ``gamma_space``: encode L^(1/2.2) instead of L, for a reader that marks the decoded texture as gamma space and
    so raises it to 2.2 once more (Babylon's glTF loader: its RawCubeTexture keeps the default gammaSpace = true).

    Parameters
    ----------
    cube : PrefilteredCube
        The GGX mip chain (radiance, OpenGL face order, in the cube's frame); negative values are encoded as 0.
    gamma_space : bool, default False
        Encode L^(1/2.2) instead of L, as above (True for glTF, False for ``.env``).

    Returns
    -------
    list of list of bytes
        ``pngs[level][face]``: one PNG per mip level (largest first) and face.
    """
    def encoded(face):
        return rgbd_encode(face ** (1 / GAMMA) if gamma_space else face)

    return [[png_bytes(encoded(np.maximum(level[f][::-1], 0))) for f in range(6)] for level in cube.levels]


# ---- Babylon .env ------------------------------------------------------------------------------------------------
def babylon_env(env: EnvMap, sh: SHCoeffs, size: int = 256, frame: Frame = BABYLON) -> bytes:
    """A Babylon.js ``.env`` file of ``env`` (radiance): GGX mips of a ``size`` cube and the irradiance polynomial.

    The mips use Babylon's roughness per mip (lodGenerationScale 0.8); the irradiance polynomial is that of ``sh``
    (radiance L_lm, l ≥ 2); both are in ``frame``. Warns (:func:`warn_if_clipped`) when RGBD clips the mirror
    mip.

    Parameters
    ----------
    env : EnvMap
        The environment: linear RGB radiance, any layout.
    sh : SHCoeffs
        Radiance coefficients of ``env``, l_max ≥ 2 (:func:`lightprobe.exports.sh.babylon_polynomial`).
    size : int, default 256
        The cube's face edge in texels: a power of two, at most 1024.
    frame : Frame, default BABYLON
        The frame of the cube's directions and of the polynomial: Babylon's, (x, y, −z) of world.

    Returns
    -------
    bytes
        The ``.env`` file (version 2, PNG images).

    Raises
    ------
    UsageError
        ``size`` is not a power of two up to 1024, or ``sh`` holds irradiance or stops below band 2.
    """
    cube = prefilter_cube(env, size, babylon_alphas(size, ENV_LOD_GENERATION_SCALE), frame)
    warn_if_clipped(cube)
    return env_file(cube, babylon_polynomial(sh, frame))


def env_file(cube: PrefilteredCube, polynomial: dict[str, np.ndarray]) -> bytes:
    """Pack a prefiltered chain and a Babylon polynomial as a ``.env`` (version 2, PNG images).

    Parameters
    ----------
    cube : PrefilteredCube
        The GGX mip chain (radiance), with the roughness per mip Babylon expects at lodGenerationScale 0.8.
    polynomial : dict of str to numpy.ndarray
        The ``SphericalPolynomial`` terms :data:`POLYNOMIAL_KEYS`, each (3,) RGB, in the cube's frame
        (:func:`lightprobe.exports.sh.babylon_polynomial`).

    Returns
    -------
    bytes
        :data:`ENV_MAGIC`, the JSON manifest (irradiance, each image's byte range, lodGenerationScale, generator)
        and a NUL, then the RGBD PNGs level by level, face by face.
    """
    pngs = [png for level in face_pngs(cube) for png in level]
    positions = np.concatenate([[0], np.cumsum([len(p) for p in pngs])])
    manifest = {
        "version": ENV_VERSION, "width": cube.size, "imageType": "image/png",
        "irradiance": {k: [float(v) for v in polynomial[k]] for k in POLYNOMIAL_KEYS},
        "specular": {"mipmaps": [{"length": len(p), "position": int(pos)} for p, pos in zip(pngs, positions)],
                     "lodGenerationScale": ENV_LOD_GENERATION_SCALE},
        "generator": _generator(),
    }
    header = json.dumps(manifest, allow_nan=False, separators=(",", ":")).encode("ascii")
    return ENV_MAGIC + header + b"\0" + b"".join(pngs)


def read_env_manifest(data: bytes) -> dict:
    """The JSON manifest of a ``.env`` file, with ``binaryDataPosition`` (where its images start) added.

    Anything else raises :class:`~lightprobe.util.errors.InputError` in one line.

    Parameters
    ----------
    data : bytes
        The file's bytes (at least the signature and the manifest).

    Returns
    -------
    dict
        The manifest, plus ``binaryDataPosition``: the offset of the first image, just past the NUL.

    Raises
    ------
    InputError
        The signature is not Babylon's, the manifest has no NUL within 16 MiB, or it is not a JSON object.
    """
    if data[:8] != ENV_MAGIC:
        raise InputError("not a Babylon .env file (wrong signature)")
    end = data.find(b"\0", 8, 8 + (16 << 20))
    if end < 0:
        raise InputError("Babylon .env file: manifest not terminated within 16 MiB")
    try:
        manifest = json.loads(data[8:end].decode("ascii"))
    except (UnicodeDecodeError, ValueError, RecursionError) as e:
        raise InputError(f"Babylon .env file: manifest is not JSON ({type(e).__name__})") from None
    if not isinstance(manifest, dict):
        raise InputError("Babylon .env file: manifest is not a JSON object")
    manifest["binaryDataPosition"] = end + 1
    return manifest


# ---- glTF EXT_lights_image_based ---------------------------------------------------------------------------------
def gltf_ibl(env: EnvMap, sh: SHCoeffs, size: int = 256, scaling: str = "irradiance",
             frame: Frame = BABYLON) -> tuple[dict, list[bytes]]:
    """A glTF document (dict) with one ``EXT_lights_image_based`` light used by its scene, and its PNG images.

    The images are in order (``images[i]`` of the document): ``specularImages`` are a full GGX chain of a ``size``
    cube of ``env`` (α = 2^i/size, as Babylon's loader reads a full chain), ``irradianceCoefficients`` from ``sh``
    (see :func:`lightprobe.exports.sh.gltf_coefficients` for ``scaling``), both in ``frame``. Warns
    (:func:`warn_if_clipped`) when RGBD clips the mirror mip.

    Parameters
    ----------
    env : EnvMap
        The environment: linear RGB radiance, any layout.
    sh : SHCoeffs
        Radiance coefficients of ``env``, l_max ≥ 2.
    size : int, default 256
        The specular cube's face edge in texels: a power of two, at most 1024.
    scaling : str, default "irradiance"
        ``irradiance`` or ``pi-radiance``.
    frame : Frame, default BABYLON
        The frame of the cube's directions and of the coefficients.

    Returns
    -------
    document : dict
        The glTF 2.0 JSON document; its ``images`` have a MIME type but no data yet.
    images : list of bytes
        The RGBD PNGs (encoded for a gamma-space texture, see :func:`face_pngs`), six per mip, in the order of
        the document's ``images``: for :func:`glb` or :func:`gltf_embedded`.

    Raises
    ------
    UsageError
        ``size`` is not a power of two up to 1024, ``scaling`` is unknown, or ``sh`` holds irradiance or stops
        below band 2.
    """
    return gltf_ibl_document(prefilter_cube(env, size, gltf_alphas(size), frame), sh, scaling)


def gltf_alphas(size: int) -> list[float]:
    """The α of each mip of a ``size`` cube as Babylon's glTF loader reads a full ``specularImages`` chain.

    Parameters
    ----------
    size : int
        Face size of level 0, a power of two.

    Returns
    -------
    list of float
        α_i = 2^i/size (lodGenerationScale 1), the first 0 (the mirror).
    """
    return babylon_alphas(size, 1.0)


def gltf_ibl_document(cube: PrefilteredCube, sh: SHCoeffs, scaling: str = "irradiance") -> tuple[dict, list[bytes]]:
    """The glTF document and PNGs of :func:`gltf_ibl` for a chain already prefiltered.

    Parameters
    ----------
    cube : PrefilteredCube
        The full GGX chain at :func:`gltf_alphas`, in the frame of the coefficients.
    sh : SHCoeffs
        Radiance coefficients, l_max ≥ 2.
    scaling : str, default "irradiance"
        ``irradiance`` or ``pi-radiance``.

    Returns
    -------
    document : dict
        The glTF 2.0 JSON document; its ``images`` have a MIME type but no data yet.
    images : list of bytes
        The RGBD PNGs, six per mip, in the order of the document's ``images``.
    """
    size, frame = cube.size, cube.frame
    warn_if_clipped(cube)
    pngs = face_pngs(cube, gamma_space=True)
    indices = [[6 * i + f for f in range(6)] for i in range(len(pngs))]
    light = {
        "name": "lightprobe", "intensity": 1.0, "rotation": [0.0, 0.0, 0.0, 1.0],
        "irradianceCoefficients": [[float(v) for v in row] for row in gltf_coefficients(sh, scaling, frame)],
        "specularImageSize": size, "specularImages": indices,
        "extras": {"lightprobe": {"scaling": scaling, "basis": "Condon-Shortley phase", "frame": frame.name,
                                  "specular": "GGX-prefiltered radiance, RGBD PNG, mip i at alpha = 2^i/size"}},
    }
    document = {
        "asset": {"version": "2.0", "generator": _generator()},
        "extensionsUsed": ["EXT_lights_image_based"],
        "extensions": {"EXT_lights_image_based": {"lights": [light]}},
        "scene": 0,
        "scenes": [{"name": "lightprobe environment", "extensions": {"EXT_lights_image_based": {"light": 0}}}],
        "images": [{"mimeType": "image/png"} for _ in range(6 * len(pngs))],
    }
    return document, [png for level in pngs for png in level]


def gltf_embedded(document: dict, images: list[bytes]) -> str:
    """A ``.gltf`` text with every image as a base64 data URI.

    Parameters
    ----------
    document : dict
        A glTF document whose ``images`` match ``images`` one for one (as :func:`gltf_ibl` returns them); it is not
        changed.
    images : list of bytes
        The PNG files.

    Returns
    -------
    str
        The JSON text, each image with a ``data:image/png;base64,…`` ``uri``.
    """
    doc = json.loads(json.dumps(document))
    for image, png in zip(doc["images"], images):
        image["uri"] = "data:image/png;base64," + base64.b64encode(png).decode("ascii")
    return json.dumps(doc, allow_nan=False, indent=1)


def glb(document: dict, images: list[bytes]) -> bytes:
    """A binary glTF (``.glb``): the JSON chunk and one BIN chunk holding every image through a buffer view.

    Parameters
    ----------
    document : dict
        A glTF document whose ``images`` match ``images`` one for one; it is not changed.
    images : list of bytes
        The PNG files, each stored 4-byte aligned in the BIN chunk.

    Returns
    -------
    bytes
        The ``.glb`` file (glTF binary version 2).
    """
    doc = json.loads(json.dumps(document))
    blob, views = bytearray(), []
    for image, png in zip(doc["images"], images):
        image["bufferView"] = len(views)
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(png)})
        blob += png + b"\0" * (-len(png) % 4)  # 4-byte alignment of every view
    doc["bufferViews"] = views
    doc["buffers"] = [{"byteLength": len(blob)}]
    text = json.dumps(doc, allow_nan=False, separators=(",", ":")).encode("utf-8")
    text += b" " * (-len(text) % 4)
    chunks = struct.pack("<II", len(text), 0x4E4F534A) + text + struct.pack("<II", len(blob), 0x004E4942) + blob
    return struct.pack("<III", 0x46546C67, 2, 12 + len(chunks)) + chunks


def check_specular_size(size: int) -> int:
    """A specular cube size: a power of two from 1 to 1024.

    Parameters
    ----------
    size : int
        The ``--specular-size`` asked for: the cube's face edge in texels.

    Returns
    -------
    int
        ``size`` itself.

    Raises
    ------
    UsageError
        ``size`` is not a power of two from 1 to 1024.
    """
    if not (1 <= size <= 1024) or size & (size - 1):
        raise UsageError(f"--specular-size must be a power of two, got {size}")
    return size


def _generator() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return f"lightprobe {version('lightprobe')}"
    except PackageNotFoundError:  # pragma: no cover - running from a source tree
        return "lightprobe"
