"""GLT palletizer (paper 004): FK and IK against the printed tables."""

from __future__ import annotations

import numpy as np
import pytest

from kinematics.fk import fk
from kinematics.ik import solve_ik, spherical_wrist
from kinematics.library import builtin_model
from kinematics.transforms import pose_errors, rot_x, rot_y, rot_z

MODEL = builtin_model("glt_palletizer")


def paper_rotation(rpy_deg) -> np.ndarray:
    """Paper 004's (R, P, Y) = (a, b, c) triple means RotX(c) RotY(b) RotZ(a) (Tables 4-5)."""
    a, b, c = np.radians(rpy_deg)
    return (rot_x(c) @ rot_y(b) @ rot_z(a))[:3, :3]


def test_has_spherical_wrist_closed_form():
    assert spherical_wrist.supports(MODEL)


def test_fk_table2_positions(paper_tables):
    for row in paper_tables["glt_palletizer"]["fk_table2"]:
        p = fk(MODEL, np.radians(row["q_deg"]))[:3, 3]
        np.testing.assert_allclose(p, row["xyz"], atol=0.1)


def test_fk_matrices_eq14_16(paper_tables):
    for row in paper_tables["glt_palletizer"]["fk_matrices_eq14_16"]:
        T = fk(MODEL, np.radians(row["q_deg"]))
        np.testing.assert_allclose(T[:3, :3], np.array(row["T"])[:3, :3], atol=1e-3)
        np.testing.assert_allclose(T[:3, 3], np.array(row["T"])[:3, 3], atol=0.1)


def test_fk_table4_key_points(paper_tables):
    # Table 4 prints its joint values to 0.01 deg, which alone moves the tool by up to about
    # 0.15 mm at this reach; each coordinate still lands within 0.1 mm.
    for row in paper_tables["glt_palletizer"]["key_points_table4"]:
        T = fk(MODEL, np.radians(row["q_deg"]))
        np.testing.assert_allclose(T[:3, 3], row["xyz"], atol=0.1, err_msg=row["name"])
        R_paper = paper_rotation(row["paper_rpy"])
        angle = np.arccos(np.clip((np.trace(R_paper.T @ T[:3, :3]) - 1) / 2, -1, 1))
        assert angle < np.radians(0.05), row["name"]


def test_fk_table5_simulated_positions(paper_tables):
    for row in paper_tables["glt_palletizer"]["measured_vs_simulated_table5"]:
        T = fk(MODEL, np.radians(row["q_deg"]))
        np.testing.assert_allclose(T[:3, 3], row["simulated_xyz"], atol=0.1)
        # The measured positions differ from the model by the robot's own error (< 0.1 mm).
        np.testing.assert_allclose(T[:3, 3], row["measured_xyz"], atol=0.1)
        R_paper = paper_rotation(row["paper_rpy_sim"])
        angle = np.arccos(np.clip((np.trace(R_paper.T @ T[:3, :3]) - 1) / 2, -1, 1))
        assert angle < np.radians(0.05)


@pytest.mark.parametrize("group", [0, 1, 2])
def test_ik_of_printed_matrices_returns_fk_inputs(paper_tables, group):
    """Eqs. 14-16 (printed to 4 decimals) -> every branch; the Table 2 input is among them.

    Table 3 prints theta6 = 200 deg for group 1 where the FK input was 160: 200 is a misprint
    (a turn of the tool about its axis changes the orientation), so we look for 160.
    """
    row = paper_tables["glt_palletizer"]["fk_matrices_eq14_16"][group]
    (res,) = solve_ik(MODEL, np.array(row["T"]), method="analytic", all_solutions=True)
    assert res.success and res.method == "analytic:spherical_wrist"
    sols_deg = np.degrees(res.solutions)
    diff = np.abs(sols_deg - np.array(row["q_deg"])).max(axis=1)
    # The printed rotations are rounded to 1e-4, worth a few hundredths of a degree.
    assert diff.min() < 0.05
    assert all(MODEL.within_limits(res.solutions))


@pytest.mark.parametrize("group", [0, 1, 2])
def test_ik_of_exact_fk_recovers_inputs_exactly(paper_tables, group):
    q = np.radians(paper_tables["glt_palletizer"]["fk_table2"][group]["q_deg"])
    (res,) = solve_ik(MODEL, fk(MODEL, q), method="analytic", all_solutions=True)
    assert np.abs(res.solutions - q).max(axis=1).min() < 1e-9
    # Joint 4 (+-400 deg) and joint 6 (+-500 deg) allow extra turns: every copy is listed.
    assert len(res.solutions) >= 4


def test_ik_lists_all_wrist_and_arm_branches():
    q = np.radians([20, 40, -30, 10, 45, 30])
    (res,) = solve_ik(MODEL, fk(MODEL, q), method="analytic", all_solutions=True)
    # Distinct (joints 1-3, sign of joint 5) combinations: shoulder x elbow x wrist.
    keys = {(round(s[0], 6), round(s[1], 6), round(s[2], 6), s[4] > 0) for s in res.solutions}
    assert len(keys) >= 2
    T = fk(MODEL, res.solutions)
    dp, dr = pose_errors(T, fk(MODEL, q)[None])
    assert dp.max() < 1e-6 and dr.max() < 1e-9


def test_ik_out_of_reach_says_why():
    T = fk(MODEL, np.zeros(6))
    T[0, 3] += 5000.0
    (res,) = solve_ik(MODEL, T)
    assert not res.success and res.status == "unreachable"
    assert "reach" in res.message and res.q is None


def test_ik_prefers_solution_nearest_q0():
    q = np.radians([10, 30, 20, 50, 40, 60])
    T = fk(MODEL, q)
    (res,) = solve_ik(MODEL, T, q0=q + 0.01)
    np.testing.assert_allclose(res.q, q, atol=1e-9)
    q_turned = q.copy()
    q_turned[5] -= 2 * np.pi
    (res,) = solve_ik(MODEL, T, q0=q_turned)
    np.testing.assert_allclose(res.q, q_turned, atol=1e-9)
