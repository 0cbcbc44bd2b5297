"""Data shipped inside the package (CC0 only; see README.md in this folder)."""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

DEFAULT_PROBE_NAME = "rooitou_park_512.hdr"
DFG_TABLE_NAME = "dfg_multiscatter_128.npy"


def default_probe_path() -> Path:
    """Path of the shipped CC0 probe (Poly Haven "Rooitou Park", 512×256 latlong, Radiance .hdr)."""
    return Path(str(files(__package__) / DEFAULT_PROBE_NAME))


def dfg_table_path() -> Path:
    """Path of the shipped multiple-scattering DFG table: :func:`lightprobe.glossy.dfg.multiscatter_lut` at its
    defaults (128², DFG1, DFG2, sheen; float64 .npy), made by ``tools/make_dfg_table.py``."""
    return Path(str(files(__package__) / DFG_TABLE_NAME))
