"""What several engines' bakes share: the roughness of a level, the full-chain rule, the panorama skybox, the
manifest's accuracy and lights."""

from __future__ import annotations

import numpy as np

from ...exports.lights import engine_lights
from ...glossy.prefilter import PrefilteredCube
from ...maps.frames import Frame
from ...maps.layouts import LATLONG
from ...util.errors import UsageError
from ..accuracy import chain_accuracy
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


def manifest_extra(source: BakeSource, chain: PrefilteredCube | None = None, lights_frame: Frame | None = None,
                   over_pi: bool = False, whole_probe: bool = False, sh: bool = True, **fields) -> dict:
    """The manifest's fields an engine adds: ``accuracy`` and, when the bake finds lights, ``lights``.

    Parameters
    ----------
    source : BakeSource
        The bake's working form.
    chain : PrefilteredCube, optional
        The specular levels the engine writes (radiance, in their frame): measured level by level against brute
        force over the map they were prefiltered from (``accuracy.specular``).
    lights_frame : Frame, optional
        The frame the engine states its directional lights in; None: the engine writes no lights.
    over_pi : bool, default False
        Lights' intensity E⊥/π (engines whose Lambert term leaves out the 1/π) instead of E⊥.
    whole_probe : bool, default False
        The engine's diffuse term and chain are the whole probe's even with lights; default: the ambient
        remainder's when the bake finds lights (:meth:`BakeSource.diffuse`).
    sh : bool, default True
        Report the SH's accuracy (``accuracy.sh``: its irradiance against brute force), for engines whose diffuse
        term is the SH.
    **fields
        Further manifest fields, placed after ``accuracy``.

    Returns
    -------
    dict
        ``accuracy`` (``sh``, ``specular`` as asked), the ``fields``, and with lights ``lights``
        (:func:`lightprobe.exports.lights.engine_lights` in ``lights_frame``).
    """
    accuracy = {}
    if sh:
        accuracy["sh"] = source.sh_accuracy(whole_probe)
    if chain is not None:
        accuracy["specular"] = chain_accuracy(source.env if whole_probe else source.diffuse()[0], chain)
    extra = {"accuracy": accuracy, **fields}
    if source.options.lights and lights_frame is not None:
        extra["lights"] = engine_lights(source.lights(), lights_frame, over_pi=over_pi)
    return extra
