"""Write the DFG table the package ships (src/lightprobe/data/dfg_multiscatter_128.npy).

    python tools/make_dfg_table.py

It is :func:`lightprobe.glossy.dfg.computed_multiscatter_lut` at its defaults, float64; tests/test_dfg.py checks
the shipped file against the same sums at random texels.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from lightprobe.glossy.dfg import computed_multiscatter_lut

OUT = Path(__file__).resolve().parents[1] / "src" / "lightprobe" / "data" / "dfg_multiscatter_128.npy"

if __name__ == "__main__":
    np.save(OUT, computed_multiscatter_lut())
    print(f"wrote {OUT}")
