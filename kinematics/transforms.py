"""Rigid-body transforms on batches of 4x4 homogeneous matrices.

Conventions (used everywhere in kinoplan; the whole list: docs/conventions.md):

* Lengths in mm, angles in rad.
* ``T_a_b`` maps coordinates in frame ``b`` to frame ``a``: ``p_a = T_a_b @ p_b``.
* Batched arrays carry the batch axes first: ``(*, 4, 4)``, ``(*, 3)``.
* Roll-pitch-yaw triples mean ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)``.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "rot_x",
    "rot_y",
    "rot_z",
    "trans",
    "make_pose",
    "invert_pose",
    "rpy_to_matrix",
    "matrix_to_rpy",
    "rotation_angle",
    "rotation_log",
    "pose_errors",
    "rigidity_error",
    "project_to_rigid",
]


def _axis_rotation(angle: np.ndarray, i: int, j: int) -> np.ndarray:
    angle = np.asarray(angle, dtype=float)
    T = np.zeros(angle.shape + (4, 4))
    c, s = np.cos(angle), np.sin(angle)
    k = 3 - i - j
    T[..., k, k] = 1.0
    T[..., 3, 3] = 1.0
    T[..., i, i] = c
    T[..., j, j] = c
    T[..., i, j] = -s
    T[..., j, i] = s
    return T


def rot_x(angle) -> np.ndarray:
    """Rotation about x: angle ``(*,)`` rad -> ``(*, 4, 4)``."""
    return _axis_rotation(angle, 1, 2)


def rot_y(angle) -> np.ndarray:
    """Rotation about y: angle ``(*,)`` rad -> ``(*, 4, 4)``."""
    return _axis_rotation(angle, 2, 0)


def rot_z(angle) -> np.ndarray:
    """Rotation about z: angle ``(*,)`` rad -> ``(*, 4, 4)``."""
    return _axis_rotation(angle, 0, 1)


def trans(x=0.0, y=0.0, z=0.0) -> np.ndarray:
    """Pure translation ``(x, y, z)`` mm (scalars or broadcastable arrays) -> ``(*, 4, 4)``."""
    x, y, z = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (x, y, z)))
    T = np.zeros(x.shape + (4, 4))
    T[..., 0, 0] = T[..., 1, 1] = T[..., 2, 2] = T[..., 3, 3] = 1.0
    T[..., 0, 3], T[..., 1, 3], T[..., 2, 3] = x, y, z
    return T


def make_pose(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Pose from rotation ``(*, 3, 3)`` and position ``(*, 3)`` -> ``(*, 4, 4)``."""
    R = np.asarray(R, dtype=float)
    p = np.asarray(p, dtype=float)
    shape = np.broadcast_shapes(R.shape[:-2], p.shape[:-1])
    T = np.zeros(shape + (4, 4))
    T[..., :3, :3] = R
    T[..., :3, 3] = p
    T[..., 3, 3] = 1.0
    return T


def invert_pose(T: np.ndarray) -> np.ndarray:
    """Inverse of rigid poses ``(*, 4, 4)`` using ``R^T`` (no general matrix inverse)."""
    T = np.asarray(T, dtype=float)
    Rt = np.swapaxes(T[..., :3, :3], -1, -2)
    return make_pose(Rt, -np.einsum("...ij,...j->...i", Rt, T[..., :3, 3]))


def rpy_to_matrix(rpy) -> np.ndarray:
    """Roll-pitch-yaw ``(*, 3)`` rad -> rotation ``(*, 3, 3)``, ``R = Rz(y) Ry(p) Rx(r)``."""
    rpy = np.asarray(rpy, dtype=float)
    return (rot_z(rpy[..., 2]) @ rot_y(rpy[..., 1]) @ rot_x(rpy[..., 0]))[..., :3, :3]


def matrix_to_rpy(R: np.ndarray) -> np.ndarray:
    """Rotation ``(*, 3, 3)`` (or pose ``(*, 4, 4)``) -> roll-pitch-yaw ``(*, 3)`` rad.

    At pitch = ±90° (gimbal lock) roll is set to 0 and yaw carries the whole turn.
    """
    R = np.asarray(R, dtype=float)[..., :3, :3]
    pitch = np.arctan2(-R[..., 2, 0], np.hypot(R[..., 0, 0], R[..., 1, 0]))
    locked = np.hypot(R[..., 0, 0], R[..., 1, 0]) < 1e-12
    roll = np.where(locked, 0.0, np.arctan2(R[..., 2, 1], R[..., 2, 2]))
    yaw = np.where(
        locked,
        np.arctan2(-R[..., 0, 1], R[..., 1, 1]),
        np.arctan2(R[..., 1, 0], R[..., 0, 0]),
    )
    return np.stack([roll, pitch, yaw], axis=-1)


def rotation_angle(R: np.ndarray) -> np.ndarray:
    """Angle of rotations ``(*, 3, 3)`` in rad, accurate near 0 and near pi."""
    R = np.asarray(R, dtype=float)[..., :3, :3]
    # atan2 of |axis*sin| and cos keeps full precision for tiny angles, unlike arccos.
    w = np.stack(
        [R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]],
        axis=-1,
    )
    cos = (np.trace(R, axis1=-2, axis2=-1) - 1.0) / 2.0
    return np.arctan2(np.linalg.norm(w, axis=-1) / 2.0, cos)


def rotation_log(R: np.ndarray) -> np.ndarray:
    """Rotation vector (axis * angle) of rotations ``(*, 3, 3)`` -> ``(*, 3)`` rad."""
    R = np.asarray(R, dtype=float)[..., :3, :3]
    w = 0.5 * np.stack(
        [R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]],
        axis=-1,
    )
    angle = rotation_angle(R)
    s = np.sin(angle)
    small = s < 1e-9
    scale = np.where(small, 1.0 + angle**2 / 6.0, angle / np.where(small, 1.0, s))
    out = w * scale[..., None]
    # Near pi the antisymmetric part vanishes: take the axis from the symmetric part instead.
    near_pi = angle > np.pi - 1e-6
    if np.any(near_pi):
        B = (R[near_pi] + np.eye(3)) / 2.0
        col = np.argmax(np.diagonal(B, axis1=-2, axis2=-1), axis=-1)
        axis = B[np.arange(len(col)), :, col]
        axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
        sign = np.sign(np.sum(axis * w[near_pi], axis=-1))
        sign[sign == 0] = 1.0
        out[near_pi] = axis * (sign * angle[near_pi])[..., None]
    return out


def pose_errors(T_a: np.ndarray, T_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Position error (mm) and rotation error (rad) between poses ``(*, 4, 4)``."""
    T_a = np.asarray(T_a, dtype=float)
    T_b = np.asarray(T_b, dtype=float)
    dp = np.linalg.norm(T_a[..., :3, 3] - T_b[..., :3, 3], axis=-1)
    R_rel = np.swapaxes(T_a[..., :3, :3], -1, -2) @ T_b[..., :3, :3]
    return dp, rotation_angle(R_rel)


def rigidity_error(T: np.ndarray) -> np.ndarray:
    """How far ``(*, 4, 4)`` is from a rigid pose: max of |R^T R - I|, |det R - 1|, last row."""
    T = np.asarray(T, dtype=float)
    R = T[..., :3, :3]
    ortho = np.abs(np.swapaxes(R, -1, -2) @ R - np.eye(3)).max(axis=(-1, -2))
    det = np.abs(np.linalg.det(R) - 1.0)
    row = np.abs(T[..., 3, :] - np.array([0.0, 0.0, 0.0, 1.0])).max(axis=-1)
    return np.maximum(np.maximum(ortho, det), row)


def project_to_rigid(T: np.ndarray) -> np.ndarray:
    """Nearest rigid pose (rotation by SVD), for printed matrices rounded to a few digits."""
    T = np.asarray(T, dtype=float)
    U, _, Vt = np.linalg.svd(T[..., :3, :3])
    D = np.ones(T.shape[:-2] + (3,))
    D[..., 2] = np.sign(np.linalg.det(U @ Vt))
    R = (U * D[..., None, :]) @ Vt
    return make_pose(R, T[..., :3, 3])
