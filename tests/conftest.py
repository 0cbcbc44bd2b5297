"""Shared fixtures. Test data lives in ../shared/data beside the project root; a missing file fails loudly."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

os.environ.setdefault("LIGHTPROBE_PROGRESS", "0")

ROOT = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("LIGHTPROBE_SHARED_DATA", ROOT.parent / "shared" / "data"))


def shared(relative: str) -> Path:
    """Path of a file in ../shared/data; fails (never skips) with a clear message if it is not there."""
    path = SHARED / relative
    if not path.is_file():
        pytest.fail(f"test data {relative} not found under {SHARED}: the suite needs ../shared/data beside the "
                    "project root (or LIGHTPROBE_SHARED_DATA pointing at it)", pytrace=False)
    return path


def random_directions(n: int, seed: int = 0) -> np.ndarray:
    d = np.random.default_rng(seed).normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


SPECIAL_DIRECTIONS = np.array(
    [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1],  # axes: poles, seams, disc rims
     [1, 1, 1], [-1, 1, -1], [1, -1, 1], [0.7, 0, 0.7], [-1e-9, 0.3, 1], [1e-9, 0.3, 1],  # cube corners, seam
     [0, 1, 1e-12], [1e-7, -1, 0], [0.5, 0.5, 0.5001]],
    dtype=np.float64,
)
SPECIAL_DIRECTIONS /= np.linalg.norm(SPECIAL_DIRECTIONS, axis=1, keepdims=True)
