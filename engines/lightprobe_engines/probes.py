"""Synthetic probes for the engines' direction checks: lat-long radiance whose content tells every axis apart.

:func:`axis_map` puts one smooth coloured marker near each of the six world axes, each of its own brightness and
placed off its axis toward both other axes (toward the next axis's negative side for a negative axis), on a dim
sky graded along all three. Looking along any axis an engine sees one marker, off centre in both directions of the
view. A mirror in any axis swaps the markers of that axis (the wrong brightness, and the marker on the other side)
and moves every other view's marker across its centre; a quarter turn about
an axis swaps the brightnesses of the views around it and turns the marker of the two views along it about their
centre. So a mirrored or rotated bake changes every view it moves: no view is left symmetric (a real interior's
ceiling and floor are nearly so under a mirror).
"""

from __future__ import annotations

import numpy as np

AXES = np.array([(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)], dtype=np.float64)
# (peak radiance, linear RGB) of the marker near each axis, in AXES order: distinct brightness, distinct colour;
# every peak under RGBP's 64 (PlayCanvas) and R11G11B10's range (Filament)
MARKERS = ((6.0, (1.0, 0.3, 0.3)), (10.0, (0.3, 1.0, 0.3)), (14.0, (0.3, 0.3, 1.0)),
           (18.0, (1.0, 1.0, 0.3)), (22.0, (0.3, 1.0, 1.0)), (26.0, (1.0, 0.3, 1.0)))
# the marker's offset from its axis toward the next axis and the one after (radians, about 8° and 5°): inside the
# narrowest view tested (PlayCanvas's 32° field), and moved by 10–16° by a mirror of either, past its 4° width
OFFSETS = (0.14, 0.09)
WIDTH_DEG = 4.0
X_MIRROR = np.diag([-1.0, 1.0, 1.0])
# a quarter turn about +y (world): +x → −z, −z → −x
Y_QUARTER = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])


def axis_markers(transform: np.ndarray | None = None) -> list[tuple[np.ndarray, float, np.ndarray]]:
    """The markers' (unit direction, peak, RGB) in the world frame, each direction multiplied by ``transform``.

    Parameters
    ----------
    transform : (3, 3) array, optional
        An orthogonal matrix applied to every marker direction (a mirror or a rotation of the whole probe);
        default the identity.

    Returns
    -------
    list of tuple
        Six (direction, peak radiance, linear RGB colour), in :data:`AXES` order.
    """
    t = np.eye(3) if transform is None else np.asarray(transform, np.float64)
    out = []
    for k, (axis, (peak, colour)) in enumerate(zip(AXES, MARKERS)):
        i = int(np.argmax(np.abs(axis)))
        u, v = np.eye(3)[(i + 1) % 3], np.eye(3)[(i + 2) % 3]
        # the first offset's sign is the axis's: the marker of −x mirrored in x lands away from that of +x
        d = axis + axis[i] * OFFSETS[0] * u + OFFSETS[1] * v
        out.append((t @ (d / np.linalg.norm(d)), peak, np.asarray(colour)))
    return out


def axis_map(rows: int, transform: np.ndarray | None = None) -> np.ndarray:
    """The axis probe as a world-frame lat-long radiance map, ``rows`` high and ``2 × rows`` wide.

    Parameters
    ----------
    rows : int
        Height of the panorama (pixels).
    transform : (3, 3) array, optional
        A mirror or rotation applied to the whole probe: the map's radiance at direction d is the plain probe's at
        transformᵀ d (the sky's gradient turns with the markers). Default the identity.

    Returns
    -------
    numpy.ndarray
        (rows, 2·rows, 3) float32 linear RGB radiance, lightprobe's lat-long layout (centre −Z, top +Y).
    """
    from lightprobe.maps.layouts import LATLONG

    t = np.eye(3) if transform is None else np.asarray(transform, np.float64)
    d = LATLONG.directions(LATLONG.grid_shape(rows)).astype(np.float64)
    plain = d @ t  # transformᵀ d for each row vector d
    sky = 0.25 + 0.04 * (plain[..., 0:1] + 1) + 0.08 * (plain[..., 1:2] + 1) + 0.02 * (plain[..., 2:3] + 1)
    out = np.broadcast_to(sky, d.shape[:-1] + (3,)).copy()
    for direction, peak, colour in axis_markers(t):
        angle = np.degrees(np.arccos(np.clip(d @ direction, -1, 1)))
        out += peak * np.exp(-(angle / WIDTH_DEG) ** 2)[..., None] * colour
    return out.astype(np.float32)
