"""Transform helpers: identities on random inputs."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from kinematics.transforms import (
    invert_pose,
    make_pose,
    matrix_to_rpy,
    pose_errors,
    project_to_rigid,
    rigidity_error,
    rotation_angle,
    rotation_log,
    rpy_to_matrix,
)

angles = st.floats(-np.pi, np.pi)


@settings(max_examples=100, deadline=None, derandomize=True, database=None)
@given(angles, st.floats(-1.5, 1.5), angles)
def test_rpy_round_trip(roll, pitch, yaw):
    R = rpy_to_matrix([roll, pitch, yaw])
    np.testing.assert_allclose(rpy_to_matrix(matrix_to_rpy(R)), R, atol=1e-9)


@settings(max_examples=100, deadline=None, derandomize=True, database=None)
@given(st.lists(st.floats(-1, 1), min_size=3, max_size=3), st.floats(0, np.pi))
def test_log_and_angle_agree(axis, angle):
    axis = np.array(axis)
    if np.linalg.norm(axis) < 1e-3:
        axis = np.array([0.0, 0.0, 1.0])
    axis /= np.linalg.norm(axis)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    R = np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K
    assert rotation_angle(R) == np.float64(rotation_angle(R))
    np.testing.assert_allclose(rotation_angle(R), angle, atol=1e-9)
    w = rotation_log(R)
    if angle < np.pi - 1e-6:
        np.testing.assert_allclose(w, axis * angle, atol=1e-8)
    else:  # at pi both signs of the axis are the same rotation
        np.testing.assert_allclose(np.abs(w), np.abs(axis * angle), atol=1e-6)


def test_batched_inverse_and_errors():
    rng = np.random.default_rng(0)
    R = rpy_to_matrix(rng.uniform(-3, 3, (10, 3)))
    T = make_pose(R, rng.uniform(-1000, 1000, (10, 3)))
    np.testing.assert_allclose(T @ invert_pose(T), np.broadcast_to(np.eye(4), T.shape),
                               atol=1e-9)
    dp, dr = pose_errors(T, T)
    assert dp.max() == 0 and dr.max() < 1e-7
    assert rigidity_error(T).max() < 1e-12


def test_project_to_rigid_fixes_rounded_matrices():
    R = rpy_to_matrix([0.3, -0.2, 1.1])
    T = make_pose(np.round(R, 4), [1, 2, 3])
    assert rigidity_error(T) > 1e-6
    P = project_to_rigid(T)
    assert rigidity_error(P) < 1e-12
    np.testing.assert_allclose(P[:3, :3], R, atol=1e-4)
