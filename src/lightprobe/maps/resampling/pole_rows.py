"""Row weights near a lat-long pole that keep every row's ∫ dω: the resampler's B-spline, made rational there.

The resampler reads a lat-long map through a cubic B-spline in each direction. Away from the poles a row's weight
function integrates, against dω, to the row's own solid angle (the spline is symmetric and dω is near linear in θ
across its support). At a pole it does not: the spline's taps past the pole are the first rows again, half a turn
round, and with dω ∝ θ dθ there the first row's weight integrates to 1.25× its solid angle (∫|t| B(t − ½) dt =
0.624 against ½) — a sun wholly in that row gained 22–25 % of its energy. The excess is the spline's wider second
moment (1/3 against a box's 1/12) meeting the pole: any partition of unity that is the B-spline further out keeps
the same total excess over the rows near the pole, so it cannot be removed, only spread.

Here it is spread. Within ROWS + 2 rows of a pole each row j gets a factor a_j and the four tap weights become
the rational B-spline a_j B_j / Σ_m a_m B_m — still a partition of unity, so a uniform map stays exactly uniform —
with the a_j solved so that each of the first ROWS rows carries the same small relative excess ε and the rows after
them none: ε ≈ 0.25 / ROWS². ROWS grows with the map (:data:`TIERS`): 24 rows (ε = 0.043 %) from 96 rows up, 16
(0.098 %) from 64 and 12 (0.17 %) from 48 — the rows of both poles must not meet. Shorter maps keep the plain
B-spline (their first row +25 %): a resampler never box-reduces a source to fewer than 48 rows, and flux-corrects
a source that has fewer (:func:`lightprobe.maps.resampling.flux._flux_corrects`). ``tests/test_resample.py`` measures ε
with the sin θ measure of real grids.

The factors are solved by :func:`solve` on the limit measure dω ∝ (y + ½) dy (y: the row coordinate, row j's centre
at j, the pole at −½), by Gauss–Newton on log a_j, and written out in :data:`FACTORS` (the solves take 60 ms, which
every command that imports the resampler would pay; ``tests/test_resample.py`` solves again and compares). The
kernel in :mod:`lightprobe.maps.resampling.fused` reads them.
"""

from __future__ import annotations

import numpy as np

TIERS = ((96, 24), (64, 16), (48, 12))  # (least map height, ROWS): each pole's rows stay within a quarter of the map
ROWS = TIERS[0][1]  # the most rows sharing the excess (maps of 96 rows or more): ε ≈ 0.125 / Σ_{j<ROWS} (j + ½)
REACH = ROWS + 2  # the most rows whose factor is not 1 (two more than ROWS, which take none of the excess)
MIN_HEIGHT = TIERS[-1][0]  # shorter maps keep the plain B-spline (their poles' rows would overlap): first row +25 %


def bspline(t: np.ndarray) -> np.ndarray:
    """The uniform cubic B-spline centred at 0 (support ±2)."""
    t = np.abs(t)
    return np.where(t < 1, 2 / 3 - t * t + t ** 3 / 2, np.where(t < 2, (2 - t) ** 3 / 6, 0.0))


def _quadrature(last: float) -> tuple[np.ndarray, np.ndarray]:
    """Gauss–Legendre nodes and weights (8 per unit segment) over y ∈ [−½, last], splitting at the integers
    (the knots of every folded spline), times the limit measure y + ½."""
    x, w = np.polynomial.legendre.leggauss(8)
    edges = np.concatenate([[-0.5], np.arange(0.0, last + 1.0)])
    lo, hi = edges[:-1, None], edges[1:, None]
    nodes = (lo + hi) / 2 + (hi - lo) / 2 * x
    weights = (hi - lo) / 2 * w * (nodes + 0.5)
    return nodes.ravel(), weights.ravel()


def _relative_excess(log_a: np.ndarray, basis: np.ndarray, dw: np.ndarray, own: np.ndarray) -> np.ndarray:
    a = np.ones(basis.shape[0])
    a[:log_a.size] = np.exp(log_a)
    weighted = a[:, None] * basis
    return (weighted / weighted.sum(axis=0) * dw).sum(axis=1) / own - 1.0


def solve(rows: int = ROWS) -> tuple[np.ndarray, float]:
    """(factors a_j for j < rows + 2, ε): the rational weights under which each of the first ``rows`` rows'
    weight integrates to (1 + ε) × its solid angle and the next six rows' to exactly theirs, on the limit measure."""
    check = rows + 6  # rows whose integral is prescribed
    y, dw = _quadrature(check + 4.0)
    rows_all = np.arange(check + 4)
    basis = bspline(y[None, :] - rows_all[:, None]) + bspline(y[None, :] + 1 + rows_all[:, None])  # folded
    own = rows_all + 0.5
    share = (rows_all[:check] < rows).astype(float)
    p = np.zeros(rows + 3)  # log a_0 … log a_{rows+1}, ε

    def residual(p):
        return _relative_excess(p[:-1], basis, dw, own)[:check] - p[-1] * share

    for _ in range(50):
        r = residual(p)
        jac = np.empty((check, p.size))
        for i in range(p.size):
            q = p.copy()
            q[i] += 1e-7
            jac[:, i] = (residual(q) - r) / 1e-7
        step = np.linalg.lstsq(jac, -r, rcond=None)[0]
        p += step
        if np.abs(step).max() < 1e-13:
            break
    return np.exp(p[:-1]), float(p[-1])


# solve(ROWS) for each tier: a_0 … a_{ROWS+1}, padded with 1 to REACH; and the excess each of the first ROWS rows
# carries (as a fraction of its own energy)
FACTORS = np.array([
    [0.277466917158, 0.431335141983, 0.517060255119, 0.584712699497, 0.640418352691, 0.688008407443,
     0.729497391189, 0.766124652664, 0.798707149919, 0.827814634532, 0.853861995986, 0.877162202419,
     0.897958504171, 0.916444989452, 0.932780228901, 0.947096630889, 0.959507032036, 0.970109446994,
     0.978990557851, 0.986228319693, 0.991893925833, 0.996053389656, 0.998767754256, 1.000106199335,
     0.999992065199, 1.000000693134],
    [0.323125118707, 0.501867833255, 0.600626748510, 0.677550350826, 0.739684066151, 0.791419966792,
     0.835054630962, 0.871997965872, 0.903182299037, 0.929265096393, 0.950735522542, 0.967975267190,
     0.981295282194, 0.990959169691, 0.997196160161, 1.000239087619, 0.999982310307, 1.000001531846,
     1, 1, 1, 1, 1, 1, 1, 1],
    [0.360073931926, 0.558562168410, 0.666947614496, 0.749788608265, 0.814818652024, 0.866853144288,
     0.908413047679, 0.941065474242, 0.965876284092, 0.983633456288, 0.994959220455, 1.000425266095,
     0.999968834040, 1.000002676793, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1]])
EXCESS = np.array([4.34029063e-4, 9.76566970e-4, 1.73612201e-3])
TIER_HEIGHTS = np.array([height for height, _ in TIERS], np.int64)
TIER_REACH = np.array([rows + 2 for _, rows in TIERS], np.int64)


def tier(height: int) -> int:
    """The row of :data:`TIERS` (and :data:`FACTORS`) a lat-long of ``height`` rows takes, or −1 (no rational
    weights)."""
    return next((t for t, (least, _) in enumerate(TIERS) if height >= least), -1)


def reach(height: int) -> int:
    """How many rows at each pole of a lat-long of ``height`` rows have rational weights (0: none)."""
    t = tier(height)
    return int(TIER_REACH[t]) if t >= 0 else 0
