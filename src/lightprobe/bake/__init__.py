"""``lightprobe bake``: a probe baked into exactly the files each engine loads for image-based lighting.

:func:`bake` writes one folder per engine (``lightprobe.util.names.BAKE_ENGINES``) from one working form
(:class:`~lightprobe.bake.source.BakeSource`: the probe, its SH, its lights, its GGX chains, each computed once),
converting at the edge to the engine's frame, face order, roughness per mip, units and encoding; each folder has a
``manifest.json`` (:mod:`lightprobe.bake.manifest`) and a ``USAGE.md``.
"""

from .options import BakeOptions, parse_engines
from .run import bake

__all__ = ["BakeOptions", "bake", "parse_engines"]
