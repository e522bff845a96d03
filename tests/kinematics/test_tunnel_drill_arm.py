"""Paper 002's tunnel drilling arm: the identified model reproduces the printed poses, the
drilling IK gives back Table 3, and the three-boom rig places copies of the arm."""

from __future__ import annotations

import importlib.util
import json
import math
from pathlib import Path

import numpy as np
import pytest

from kinematics.drilling import (
    DRILL_D7,
    compensation_angles,
    drill_axis,
    drill_ik,
)
from kinematics.fk import fk
from kinematics.ik import IKStatus
from kinematics.library import builtin_model
from kinematics.model import ModelError, RobotModel
from kinematics.rigs import Rig, builtin_rig
from kinematics.transforms import rot_x, rot_z, rotation_angle, trans

ARM = builtin_model("tunnel_drill_arm")
ROOT = Path(__file__).resolve().parents[2]
Q_KEYS = ["theta1_deg", "theta2_deg", "d3_mm", "theta4_deg", "theta5_deg", "theta6_deg"]
R_INITIAL = np.array([[0.0, 0, 1], [1, 0, 0], [0, 1, 0]])
X_AXIS = np.array([1.0, 0.0, 0.0])


def paper_q(row: dict, d7: float = DRILL_D7) -> np.ndarray:
    """Paper joint values (deg, mm) -> q (7,) rad / mm."""
    q = [math.radians(row[k]) if k.endswith("_deg") else float(row[k]) for k in Q_KEYS]
    return np.array(q + [row.get("d7_mm", d7)])


@pytest.fixture(scope="module")
def paper(paper_tables):
    return paper_tables["tunnel_drill_arm"]


# ---- the model ------------------------------------------------------------------------------
def test_structure_matches_table_1():
    assert ARM.convention == "mdh" and ARM.dof == 7
    assert [j.type[0].upper() for j in ARM.joints] == list("RRPRRRP")
    np.testing.assert_allclose([math.degrees(j.alpha) for j in ARM.joints],
                               [0, -90, -90, 0, 90, 90, 90], atol=1e-12)
    assert all(j.offset == 0.0 for j in ARM.joints)
    assert ARM.joints[3].a == ARM.joints[3].d == ARM.joints[4].a == 0.0
    data = ARM.to_dict()
    assert "002" in data["source"] and len(data["notes"]) >= 5
    assert any("misprint" in n for n in data["notes"])


def test_initial_orientation_follows_from_table_1_alone(paper):
    """The printed initial rotation, and the drill along the tunnel axis at Table 3's target
    configuration, from Table 1's twists and the printed joint values whatever the link
    constants: an independent check (the constants were fitted to the positions, not to
    the rotation)."""
    tool = _identification_tool()
    R_paper = np.array(paper["initial_pose"]["T"], dtype=float)[:3, :3]
    configs = [paper_q(paper["initial_pose"]["q"]), paper_q(paper["table3"][1]["q"])]
    rng = np.random.default_rng(8)
    for constants in rng.uniform(-500.0, 500.0, (10, len(tool.UNKNOWNS))):
        model = RobotModel.from_dict(tool.skeleton(dict(zip(tool.UNKNOWNS, constants))))
        for q in configs:
            assert rotation_angle(fk(model, q)[:3, :3].T @ R_paper) < 1e-9
    for q in configs:  # ... and so does the stored model
        assert rotation_angle(fk(ARM, q)[:3, :3].T @ R_paper) < 1e-9


def test_table_3_positions_are_fitted_not_predicted(paper):
    """The six unprinted constants the positions determine were fitted to exactly these
    numbers: two distinct configurations (the initial pose is Table 3's first row), six
    coordinates, rank 6. So FK reproducing them is no check of the model; what is left is
    the paper's own disagreement, y = 906.5 in the matrix and 907 in Table 3 for the same
    pose, which the fit splits."""
    tool = _identification_tool()
    meas = tool.measurements(paper)
    res = tool.fit(meas)
    distinct = {tuple(np.round(m["q"], 9)) for m in meas}
    assert res.rank == 3 * len(distinct) == 6  # as many constants as coordinates: no check
    T = fk(ARM, np.array([m["q"] for m in meas]))
    init, row1, row2 = (T[k, :3, 3] for k in range(3))
    np.testing.assert_allclose(init, row1)  # one configuration
    y_init, y_row1 = paper["initial_pose"]["T"][1][3], paper["table3"][0]["xyz"][1]
    assert abs(y_init - y_row1) == 0.5
    assert abs(init[1] - y_init) + abs(init[1] - y_row1) == pytest.approx(0.5, abs=2e-3)
    np.testing.assert_allclose(row2, paper["table3"][1]["xyz"], atol=2e-3)  # stored to 1 um


def test_limits_contain_table_3(paper):
    for row in [paper["initial_pose"]["q"], *[r["q"] for r in paper["table3"]]]:
        assert ARM.within_limits(paper_q(row))


def test_table_3_obeys_the_compensation_rule_as_printed(paper):
    for row in paper["table3"]:
        t5, t6 = compensation_angles(math.radians(row["q"]["theta1_deg"]),
                                     math.radians(row["q"]["theta2_deg"]))
        assert math.degrees(t5) == pytest.approx(row["q"]["theta5_deg"], abs=1e-9)
        assert math.degrees(t6) == pytest.approx(row["q"]["theta6_deg"], abs=1e-9)


def test_rule_keeps_the_whole_tool_orientation():
    """With theta4 = 0 the rule fixes the tool rotation at the initial pose's, for any swing,
    pitch, telescope and feed, so the drill stays along the tunnel axis."""
    rng = np.random.default_rng(3)
    q = rng.uniform(ARM.lower, ARM.upper, (50, 7))
    q[:, 3] = 0.0
    q[:, 4], q[:, 5] = compensation_angles(q[:, 0], q[:, 1])
    R = fk(ARM, q)[:, :3, :3]
    np.testing.assert_allclose(R, np.broadcast_to(R_INITIAL, R.shape), atol=1e-12)


def test_printed_link_matrix_differs_only_by_the_sign_of_d1():
    """The paper prints -c_alpha d in row 3 of its link matrix; with Table 1's twists that is
    Craig's matrix with d1 negated (c_alpha = 0 elsewhere, d4 = 0)."""

    def printed(alpha, a, theta, d):
        ca, sa, c, s = math.cos(alpha), math.sin(alpha), math.cos(theta), math.sin(theta)
        return np.array([[c, -s, 0, a], [ca * s, c * ca, -sa, -sa * d],
                         [sa * s, c * sa, ca, -ca * d], [0, 0, 0, 1]])

    flipped = ARM.to_dict()
    flipped["joints"][0]["d"] = -flipped["joints"][0]["d"]
    for q in np.random.default_rng(4).uniform(ARM.lower, ARM.upper, (10, 7)):
        T = np.eye(4)
        for j, v in zip(flipped["joints"], q):
            theta = v if j["type"] == "revolute" else j["theta"]
            d = j["d"] if j["type"] == "revolute" else v
            T = T @ printed(j["alpha"], j["a"], theta, d)
        np.testing.assert_allclose(T, fk(ARM, q), atol=1e-9)
        # ... and our FK is Craig's elementary product.
        T_craig = np.eye(4)
        for j, v in zip(ARM.joints, q):
            theta = v if j.revolute else j.theta
            d = j.d if j.revolute else v
            T_craig = T_craig @ rot_x(j.alpha) @ trans(j.a) @ rot_z(theta) @ trans(0, 0, d)
        np.testing.assert_allclose(T_craig, fk(ARM, q), atol=1e-9)


def _identification_tool():
    path = ROOT / "tools" / "identify_tunnel_arm.py"
    spec = importlib.util.spec_from_file_location("identify_tunnel_arm", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_json_is_what_the_identification_tool_produces(paper):
    tool = _identification_tool()
    fresh = tool.identify(paper, draws=0)
    stored = json.loads((ROOT / "kinematics" / "robots" / "tunnel_drill_arm.json").read_text())
    assert fresh["joints"] == stored["joints"]
    assert fresh["base"] == stored["base"] and fresh["tool"] == stored["tool"]
    # The calibration says which constants the three paper poses leave open.
    res = tool.fit(tool.measurements(paper))
    splits = {tool.UNKNOWNS[s] for s in ("d1", "d6", "a1", "a5", "d2", "d5")}
    assert set(res.unidentified) == splits
    assert res.rank == 6 and len(res.warnings) >= 3
    assert res.position_errors.max() < 0.3


# ---- drilling IK --------------------------------------------------------------------------
def test_drill_ik_on_table_3s_hole(paper):
    """Drilling IK on the target hole: status, feed and a drill perpendicular to the face.
    Its joints equal Table 3's (to 6e-6 deg) only because the model was fitted to that row
    (``test_table_3_positions_are_fitted_not_predicted``): not a paper check."""
    row = paper["table3"][1]
    (res,) = drill_ik(ARM, row["xyz"])
    assert res.status is IKStatus.OK and res.method == "drilling"
    assert res.q[6] == DRILL_D7 and res.q[3] == 0.0
    T = fk(ARM, res.q)
    assert np.linalg.norm(T[:3, 3] - row["xyz"]) < 1e-6
    axis = drill_axis(ARM, res.q)
    assert math.atan2(np.linalg.norm(np.cross(axis, X_AXIS)), axis @ X_AXIS) < 1e-9
    assert res.position_error < 1e-6 and res.rotation_error < 1e-9


def test_drill_ik_inverts_the_rule_over_the_workspace():
    rng = np.random.default_rng(5)
    q = rng.uniform(ARM.lower, ARM.upper, (200, 7))
    q[:, 3], q[:, 6] = 0.0, DRILL_D7
    q[:, 4], q[:, 5] = compensation_angles(q[:, 0], q[:, 1])
    inside = ARM.within_limits(q)
    holes = fk(ARM, q)[:, :3, 3]
    results = drill_ik(ARM, holes)
    assert len(results) == 200
    for k, res in enumerate(results):
        if inside[k]:
            assert res.success
            np.testing.assert_allclose(res.q, q[k], atol=1e-8)
    Q = np.array([r.q for r in results if r.success])
    T = fk(ARM, Q)
    assert np.linalg.norm(T[:, :3, 3] - holes[inside], axis=1).max() < 1e-6
    np.testing.assert_allclose(T[:, :3, 2], np.broadcast_to(X_AXIS, (len(Q), 3)), atol=1e-12)


def test_drill_ik_with_roll_keeps_the_drill_perpendicular(paper):
    holes = np.array([paper["table3"][1]["xyz"], [9500.0, 1500.0, 3000.0]])
    for roll in (0.3, -1.0):
        for res, hole in zip(drill_ik(ARM, holes, roll=roll), holes):
            assert res.success, res.message
            assert res.q[3] == pytest.approx(roll) and res.q[6] == DRILL_D7
            T = fk(ARM, res.q)
            assert np.linalg.norm(T[:3, 3] - hole) < 1e-6
            assert math.atan2(np.linalg.norm(np.cross(T[:3, 2], X_AXIS)),
                              T[:3, 2] @ X_AXIS) < 1e-9


def test_unreachable_holes_say_why():
    far, on_axis, low = drill_ik(ARM, [[9000, 8000, 9000], [4500, 250, 500], [9000, 0, -9000]])
    assert far.status is IKStatus.OUT_OF_LIMITS and far.q is None
    assert "telescope" in far.message and "10000.0" in far.message
    assert len(far.solutions) == 1  # the out-of-limits answer, for the caller to inspect
    assert on_axis.status is IKStatus.UNREACHABLE and "swing axis" in on_axis.message
    assert low.status is IKStatus.OUT_OF_LIMITS and "pitch" in low.message


def test_drill_ik_validates_input():
    with pytest.raises(ValueError, match="hole_xyz"):
        drill_ik(ARM, [[1.0, 2.0]])
    with pytest.raises(ValueError, match=r"hole_xyz\[1\]"):
        drill_ik(ARM, [[9000, 0, 0], [math.nan, 0, 0]])
    with pytest.raises(ValueError, match="d7"):
        drill_ik(ARM, [9000, 0, 0], d7=math.inf)
    with pytest.raises(ValueError, match="joints"):
        drill_ik(builtin_model("glt_palletizer"), [9000, 0, 0])


# ---- the three-boom rig ---------------------------------------------------------------------
RIG = builtin_rig("tunnel_jumbo")
OFFSETS = {"left": [0.0, 2000.0, 0.0], "middle": [0.0, 0.0, 0.0], "right": [0.0, -2000.0, 0.0]}


def test_rig_has_three_arms():
    assert list(RIG.arms) == ["left", "middle", "right"]
    assert {n: m.id for n, m in RIG.arms.items()} == {
        n: f"tunnel_jumbo-{n}" for n in OFFSETS}
    assert RIG.to_dict()["notes"] and RIG.to_dict()["source"]


def test_middle_arm_is_the_drilling_arm():
    middle = RIG.arms["middle"]
    assert middle.joints == ARM.joints
    np.testing.assert_array_equal(middle.base, ARM.base)
    np.testing.assert_array_equal(middle.tool, ARM.tool)
    q = np.random.default_rng(6).uniform(ARM.lower, ARM.upper, (20, 7))
    np.testing.assert_array_equal(fk(middle, q), fk(ARM, q))


@pytest.mark.parametrize("side", ["left", "right"])
def test_side_arms_are_the_middle_arm_shifted(side):
    q = np.random.default_rng(7).uniform(ARM.lower, ARM.upper, (20, 7))
    T_side, T_mid = fk(RIG.arms[side], q), fk(RIG.arms["middle"], q)
    np.testing.assert_allclose(T_side[:, :3, :3], T_mid[:, :3, :3], atol=1e-12)
    np.testing.assert_allclose(T_side[:, :3, 3] - T_mid[:, :3, 3],
                               np.broadcast_to(OFFSETS[side], (20, 3)), atol=1e-9)
    # Drilling IK on a side arm: the same joints for the shifted hole.
    hole = np.array([9000.0, -3877.0, 6595.0])
    (mid,) = drill_ik(RIG.arms["middle"], hole)
    (res,) = drill_ik(RIG.arms[side], hole + OFFSETS[side])
    np.testing.assert_allclose(res.q, mid.q, atol=1e-9)


def test_rig_description_errors_name_the_field():
    base = RIG.to_dict()
    bad = json.loads(json.dumps(base))
    bad["arms"][1]["model"] = "no_such_arm"
    with pytest.raises(ModelError) as err:
        Rig.from_dict(bad)
    assert err.value.field == "arms[1].model"
    bad = json.loads(json.dumps(base))
    bad["arms"][2]["name"] = "left"
    with pytest.raises(ModelError, match="twice"):
        Rig.from_dict(bad)
    bad = json.loads(json.dumps(base))
    bad["arms"][0]["base"] = [[2, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]
    with pytest.raises(ModelError) as err:
        Rig.from_dict(bad)
    assert err.value.field == "arms[0].base"
    with pytest.raises(KeyError):
        builtin_rig("no_such_rig")
    again = Rig.from_dict(base)
    assert again.to_dict() == base
