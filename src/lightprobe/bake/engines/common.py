"""What several engines' bakes share: the roughness of a level, the full-chain rule, the panorama skybox."""

from __future__ import annotations

import numpy as np

from ...maps.layouts import LATLONG
from ...util.errors import UsageError
from ..folder import EngineFolder
from ..options import BakeOptions
from ..source import BakeSource


def perceptual_roughness(alphas) -> np.ndarray:
    """The engines' perceptual roughness of each α (α = roughness²).

    Parameters
    ----------
    alphas : sequence of float
        GGX α of each level.

    Returns
    -------
    numpy.ndarray
        √α per level, float64.
    """
    return np.sqrt(np.asarray(alphas, dtype=np.float64))


def require_full_chain(options: BakeOptions, what: str) -> None:
    """Refuse a mip count short of the full chain for a container whose reader needs every level.

    Parameters
    ----------
    options : BakeOptions
        The bake's options.
    what : str
        The container, for the message.

    Raises
    ------
    UsageError
        ``options.mips`` is given and below log₂(size) + 1.
    """
    if options.levels != options.full_chain:
        raise UsageError(f"{what} holds the full mip chain ({options.full_chain} levels for {options.size}): "
                         f"drop --mips {options.mips}")


def skybox_panorama(source: BakeSource, folder: EngineFolder, name: str) -> None:
    """Write the probe as a world-frame lat-long panorama of ``2 × skybox_size`` by ``skybox_size``.

    The panorama's centre is world −Z, its right-hand quarter +X, its top +Y (docs: conventions), which is how
    three.js, Babylon and glTF viewers map an equirectangular image.

    Parameters
    ----------
    source : BakeSource
        The bake's working form.
    folder : EngineFolder
        The engine's folder.
    name : str
        The file's name (.hdr or .exr).
    """
    rows = source.options.skybox_size
    sky = source.env if source.env.layout is LATLONG and source.env.grid[0] == rows else source.env.to(LATLONG, rows)
    folder.add_image(name, sky.data, "skybox", "radiance", layout="latlong", size=[2 * rows, rows], frame="world")
