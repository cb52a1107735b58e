"""Rotations and frame changes, as pure numpy functions.

Conventions: quaternions are (x, y, z, w), pybullet's order; roll-pitch-yaw angles are
fixed-axis X, then Y, then Z (R = Rz(yaw) @ Ry(pitch) @ Rx(roll)), the URDF and pybullet
convention.  The part frame is in millimetres; the workcell world frame is in metres, z up.
A part placement maps a part point p (mm) to the world point ``R @ (scale * p) + t`` (m).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


def rpy_to_matrix(rpy: ArrayLike) -> FloatArray:
    """Rotation matrix (3, 3) of fixed-axis roll, pitch, yaw angles (3,) in radians."""
    roll, pitch, yaw = np.asarray(rpy, dtype=float)
    cr, sr = np.cos(roll), np.sin(roll)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cy, sy = np.cos(yaw), np.sin(yaw)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def matrix_to_quaternion(matrix: ArrayLike) -> FloatArray:
    """Unit quaternion (4,) (x, y, z, w), w >= 0, of a rotation matrix (3, 3)."""
    m = np.asarray(matrix, dtype=float)
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0.0:
        s = 2.0 * np.sqrt(trace + 1.0)
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, 0.25 * s]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s]
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s]
    else:
        s = 2.0 * np.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s, (m[1, 0] - m[0, 1]) / s]
    quat = np.asarray(q, dtype=float)
    quat /= np.linalg.norm(quat)
    return -quat if quat[3] < 0.0 else quat


def quaternion_to_matrix(quaternion: ArrayLike) -> FloatArray:
    """Rotation matrix (3, 3) of a quaternion (4,) (x, y, z, w); normalises it first."""
    x, y, z, w = np.asarray(quaternion, dtype=float) / np.linalg.norm(quaternion)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def homogeneous(rotation: ArrayLike, translation: ArrayLike) -> FloatArray:
    """4x4 transform (4, 4) from a rotation (3, 3) and a translation (3,)."""
    t = np.eye(4)
    t[:3, :3] = np.asarray(rotation, dtype=float)
    t[:3, 3] = np.asarray(translation, dtype=float)
    return t


def axes_to_matrix(x_axis: ArrayLike, y_axis: ArrayLike, tol: float = 1e-6) -> FloatArray:
    """Rotation (3, 3) whose columns are x_axis, y_axis and their cross product.

    Raises ValueError unless both (3,) axes are unit length and orthogonal within `tol`.
    """
    x = np.asarray(x_axis, dtype=float)
    y = np.asarray(y_axis, dtype=float)
    if x.shape != (3,) or y.shape != (3,):
        raise ValueError("axes must be 3-vectors")
    if abs(np.linalg.norm(x) - 1.0) > tol or abs(np.linalg.norm(y) - 1.0) > tol:
        raise ValueError("axes must be unit vectors")
    if abs(float(x @ y)) > tol:
        raise ValueError("axes must be orthogonal")
    return np.column_stack([x, y, np.cross(x, y)])


def part_to_world_points(
    points_mm: ArrayLike, rotation: ArrayLike, translation_m: ArrayLike, scale: float = 0.001
) -> FloatArray:
    """World points (n, 3) in metres of part points (n, 3) in millimetres."""
    p = np.atleast_2d(np.asarray(points_mm, dtype=float))
    return scale * p @ np.asarray(rotation, dtype=float).T + np.asarray(translation_m, dtype=float)


def world_to_part_points(
    points_m: ArrayLike, rotation: ArrayLike, translation_m: ArrayLike, scale: float = 0.001
) -> FloatArray:
    """Part points (n, 3) in millimetres of world points (n, 3) in metres (the inverse map)."""
    w = np.atleast_2d(np.asarray(points_m, dtype=float)) - np.asarray(translation_m, dtype=float)
    return (w @ np.asarray(rotation, dtype=float)) / scale


def rotate_vectors(vectors: ArrayLike, rotation: ArrayLike) -> FloatArray:
    """Directions (n, 3) rotated by a rotation (3, 3): normals go from part to world this way."""
    v = np.atleast_2d(np.asarray(vectors, dtype=float))
    return v @ np.asarray(rotation, dtype=float).T


def unit_rows(vectors: ArrayLike) -> FloatArray:
    """Rows of (n, 3) scaled to unit length; raises ValueError for a (near) zero row."""
    v = np.atleast_2d(np.asarray(vectors, dtype=float))
    norms = np.linalg.norm(v, axis=1, keepdims=True)
    if np.any(norms < 1e-9):
        raise ValueError("zero-length direction")
    return v / norms
