"""One module per engine, each turning the bake's working form into the files that engine loads.

Every module has ``bake(source, folder) -> dict`` (writes its files into ``folder``, returns the manifest's extra
fields: ``lights``, ``accuracy`` …), ``FRAME`` (the frame its directions are stated in), ``ENCODINGS`` (the encodings
it offers, default first) and ``usage(folder) -> str`` (the engine code that loads the folder, as Markdown). Modules
are imported only when their engine is baked.
"""

from __future__ import annotations

import importlib

from ...util.names import BAKE_ENGINES

# The encodings each engine offers where it gives a choice, default first (an engine absent has none to choose).
ENCODINGS: dict[str, tuple[str, ...]] = {"threejs": ("rgba16f", "rgba32f"),
                                         "custom": ("rgba16f", "rgb9e5", "b10g11r11", "rgba32f"),
                                         "gltf": ("rgbd", "ktx2")}


def engine_module(name: str):
    """The module that bakes for ``name``.

    Parameters
    ----------
    name : str
        An engine of :data:`lightprobe.util.names.BAKE_ENGINES`.

    Returns
    -------
    module
        ``lightprobe.bake.engines.<name>``.
    """
    if name not in BAKE_ENGINES:
        raise KeyError(name)
    return importlib.import_module(f"{__name__}.{name}")
