"""Data shipped inside the package (CC0 only; see README.md in this folder)."""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

DEFAULT_PROBE_NAME = "rooitou_park_512.hdr"


def default_probe_path() -> Path:
    """Path of the shipped CC0 probe (Poly Haven "Rooitou Park", 512×256 latlong, Radiance .hdr)."""
    return Path(str(files(__package__) / DEFAULT_PROBE_NAME))
