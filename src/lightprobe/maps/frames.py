"""Coordinate frames and rotations.

**World frame** (docs/spec.md §1): right-handed, +Y up, the *front* of a panorama is −Z, image right is +X. Every
layout in :mod:`lightprobe.maps.layouts` maps pixels to directions in this frame, so converting between layouts never
mirrors or rotates the scene.

A :class:`Frame` is a named orthogonal 3×3 matrix ``to_frame`` with ``d_frame = to_frame @ d_world``. It may be a
mirror (determinant −1): ``rh2001`` is the world frame with z negated, the frame in which Ramamoorthi & Hanrahan's
Figure 2 is printed.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..util.errors import UsageError


@dataclass(frozen=True)
class Frame:
    """A named frame: ``d_frame = to_frame @ d_world`` for unit direction vectors.

    Parameters
    ----------
    name : str
        The frame's name, as :func:`frame` looks it up (``world``, ``rh2001``, ``threejs``, …).
    to_frame : numpy.ndarray
        Orthogonal 3×3 matrix taking world-frame directions into this frame (stored as float64); it may be a mirror
        (determinant −1).
    description : str, default ""
        One line saying what the frame is.

    Raises
    ------
    UsageError
        When ``to_frame`` is not an orthogonal 3×3 matrix (to 1e-9).
    """

    name: str
    to_frame: np.ndarray = field(repr=False)
    description: str = ""

    def __post_init__(self) -> None:
        m = np.asarray(self.to_frame, dtype=np.float64)
        if m.shape != (3, 3) or not np.allclose(m @ m.T, np.eye(3), atol=1e-9):
            raise UsageError(f"frame {self.name!r}: to_frame must be an orthogonal 3×3 matrix")
        object.__setattr__(self, "to_frame", m)

    @property
    def is_mirror(self) -> bool:
        """True when the frame has the opposite handedness of the world frame."""
        return bool(np.linalg.det(self.to_frame) < 0)

    def from_world(self, d: np.ndarray) -> np.ndarray:
        """World-frame directions (..., 3) → this frame.

        Parameters
        ----------
        d : numpy.ndarray
            Directions in the world frame (+Y up, front −Z, right +X), shape (..., 3); unit vectors stay unit.

        Returns
        -------
        numpy.ndarray
            ``to_frame @ d`` for each direction, shape (..., 3), float64.
        """
        return np.asarray(d) @ self.to_frame.T

    def to_world(self, d: np.ndarray) -> np.ndarray:
        """Directions (..., 3) in this frame → world frame.

        The inverse of :meth:`from_world` (``to_frame`` is orthogonal: its inverse is its transpose).

        Parameters
        ----------
        d : numpy.ndarray
            Directions in this frame, shape (..., 3).

        Returns
        -------
        numpy.ndarray
            ``to_frame.T @ d`` for each direction: world-frame directions (+Y up, front −Z), shape (..., 3),
            float64.
        """
        return np.asarray(d) @ self.to_frame


WORLD = Frame("world", np.eye(3), "right-handed, +Y up, front of the panorama −Z, image right +X")
RH2001 = Frame(
    "rh2001",
    np.diag([1.0, 1.0, -1.0]),
    "Ramamoorthi & Hanrahan's prefilter frame: angular-probe centre +z, image right +x, up +y; (x, y, -z) of world",
)

# Engine frames. three.js, Filament and glTF are right-handed with +Y up and the default camera looking along −Z:
# the world frame itself. Unity and Babylon.js (by default) are left-handed with +Y up and the camera looking along
# +Z: the world frame with z negated, so the front of a panorama stays in front of the default camera.
# three.js maps an equirectangular image with u = atan(dir.z, dir.x)/2π + ½, v = asin(dir.y)/π + ½ (equirectUv in
# ShaderChunk/common.glsl.js): its image centre is +X and u = ¾ is +Z, where ours are −Z and +X. The same pixel, so
# the same light, is at (x₃, y₃, z₃) = (−z, y, x): a user who shows the probe as scene.background and lights with
# our LightProbe gets light from where the background shows it.
THREEJS = Frame("threejs", np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]]),
                "three.js as it shows an equirectangular background: (−z, y, x) of world (image centre at +X)")
# The world axes are three.js's own axes too (right-handed, +Y up, camera along −Z): for geometry, not panoramas.
THREEJS_AXES = Frame("threejs-axes", np.eye(3), "three.js world axes without its panorama mapping (= world)")
FILAMENT = Frame("filament", np.eye(3), "Filament world: right-handed, +Y up, camera looks along −Z (= world)")
GLTF = Frame("gltf", np.eye(3), "glTF: right-handed, +Y up, default camera looks along −Z (= world)")
UNITY = Frame("unity", np.diag([1.0, 1.0, -1.0]), "Unity: left-handed, +Y up, +Z forward; (x, y, −z) of world")
# Babylon (default left-handed scene) shows an equirectangular panorama with its centre at +Z and +X to the right of
# it: (x, y, −z) of world, the same mirror as its axes (checked against its HDRTools → cube → SH path in Node).
BABYLON = Frame("babylon", np.diag([1.0, 1.0, -1.0]),
                "Babylon.js default: left-handed, +Y up, +Z forward; (x, y, −z) of world")

FRAMES: dict[str, Frame] = {f.name: f for f in (WORLD, RH2001, THREEJS, THREEJS_AXES, FILAMENT, GLTF, UNITY, BABYLON)}


def frame(name: str | Frame) -> Frame:
    """Look a frame up by name (``world``, ``rh2001``, …); a :class:`Frame` passes through.

    Parameters
    ----------
    name : str or Frame
        A name of :data:`FRAMES` (``world``, ``rh2001``, ``threejs``, ``threejs-axes``, ``filament``, ``gltf``,
        ``unity``, ``babylon``), or a :class:`Frame`.

    Returns
    -------
    Frame
        The frame of that name, or ``name`` itself when it is a :class:`Frame`.

    Raises
    ------
    UsageError
        When no frame has that name.
    """
    if isinstance(name, Frame):
        return name
    try:
        return FRAMES[name]
    except KeyError:
        raise UsageError(f"unknown frame {name!r}; known frames: {', '.join(FRAMES)}") from None


def rotation_x(deg: float) -> np.ndarray:
    """Right-handed rotation by ``deg`` degrees about +X (counter-clockwise looking from +X toward the origin).

    Parameters
    ----------
    deg : float
        The angle in degrees; positive turns +Y toward +Z.

    Returns
    -------
    numpy.ndarray
        [[1, 0, 0], [0, c, −s], [0, s, c]] (c, s the angle's cosine and sine), float64, for column vectors.
    """
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def rotation_y(deg: float) -> np.ndarray:
    """Right-handed rotation by ``deg`` degrees about +Y (up).

    Parameters
    ----------
    deg : float
        The angle in degrees; positive turns +Z toward +X, so the front (−Z) toward −X (counter-clockwise seen from
        above).

    Returns
    -------
    numpy.ndarray
        [[c, 0, s], [0, 1, 0], [−s, 0, c]] (c, s the angle's cosine and sine), float64, for column vectors.
    """
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def rotation_z(deg: float) -> np.ndarray:
    """Right-handed rotation by ``deg`` degrees about +Z (which points backwards, out of the panorama's front).

    Parameters
    ----------
    deg : float
        The angle in degrees; positive turns +X toward +Y.

    Returns
    -------
    numpy.ndarray
        [[c, −s, 0], [s, c, 0], [0, 0, 1]] (c, s the angle's cosine and sine), float64, for column vectors.
    """
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def rotation_from_ypr(yaw: float, pitch: float, roll: float) -> np.ndarray:
    """Rotation matrix R = R_y(yaw) · R_x(pitch) · R_z(roll), angles in degrees, world frame.

    Applied to an environment, R moves the light that was in direction d to direction R·d: a positive yaw turns the
    panorama counter-clockwise seen from above (the front, −Z, moves toward −X), a positive pitch lifts the front
    toward +Y, a positive roll turns the view counter-clockwise about the backward axis +Z.

    Parameters
    ----------
    yaw : float
        Rotation about +Y (up), degrees.
    pitch : float
        Rotation about +X (right), degrees.
    roll : float
        Rotation about +Z (backward), degrees.

    Returns
    -------
    numpy.ndarray
        The 3×3 rotation matrix R (float64) in the world frame, applied to column vectors: ``R @ d``.
    """
    return rotation_y(yaw) @ rotation_x(pitch) @ rotation_z(roll)


def as_rotation(rotation: np.ndarray | tuple[float, float, float]) -> np.ndarray:
    """A 3×3 proper rotation from a matrix or a (yaw, pitch, roll) triple in degrees; refuses mirrors.

    Parameters
    ----------
    rotation : numpy.ndarray or tuple of float
        A 3×3 proper rotation matrix in the world frame (orthogonal to 1e-6, determinant +1), or (yaw, pitch, roll)
        in degrees as :func:`rotation_from_ypr` takes them.

    Returns
    -------
    numpy.ndarray
        The 3×3 rotation matrix (float64): the given matrix, or the one the three angles make.

    Raises
    ------
    UsageError
        When a value is not finite, or the matrix is not a proper orthogonal 3×3 matrix (a mirror included), or the
        input has another shape.
    """
    r = np.asarray(rotation, dtype=np.float64)
    if not np.isfinite(r).all():
        raise UsageError("a rotation must be finite numbers")
    if r.shape == (3,):
        return rotation_from_ypr(*r)
    if r.shape != (3, 3) or not np.allclose(r @ r.T, np.eye(3), atol=1e-6) or np.linalg.det(r) < 0:
        raise UsageError("a rotation must be a proper orthogonal 3×3 matrix or (yaw, pitch, roll) in degrees")
    return r
