"""Cylinders of the pile-driver arm (paper 000, section 3.4): joint angle <-> cylinder length.

Identities, not only numbers: angle -> length -> angle round trips, dL/dtheta against finite
differences, the four-bar length against an independent construction from point coordinates,
stroke ends = joint limits, and the paper's arm-scene endpoints (section 4.5) through IK.
"""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
from scipy.optimize import least_squares, minimize

from kinematics.cylinders import (
    CylinderError,
    CylinderSet,
    FourBarCylinder,
    SwingCylinderPair,
    TriangleCylinder,
)
from kinematics.fk import fk
from kinematics.ik import IKStatus, solve_ik
from kinematics.library import builtin_model
from kinematics.model import RobotModel

MODEL = builtin_model("pile_driver")
CYL = CylinderSet.from_model(MODEL)
MECHS = {m.name: m for m in CYL.mechanisms}
L1, L2, L3, L4, L5 = 200.0, 800.0, 600.0, 300.0, 100.0
#: Farthest the tool gets from the base axis for any q: L1 + L2 + L3 + |(L4, L5)|.
REACH_BOUND = L1 + L2 + L3 + math.hypot(L4, L5)

# Section 4.5: the paper's arm-scene endpoints (mm).
SCENE_START = np.array([500.0, -1000.0, 0.0])
SCENE_GOAL = np.array([1800.0, 1800.0, 800.0])
#: Our reachable stand-in for SCENE_START: the same bearing (-63.43 deg), pushed out from
#: 1118 mm to 1565 mm from the base axis, 38 mm inside the workspace boundary at z = 0.
NEAR_START = np.array([700.0, -1400.0, 0.0])


def _pile_data() -> dict:
    return copy.deepcopy(MODEL.to_dict())


def _with_cylinders(cylinders) -> RobotModel:
    data = _pile_data()
    data["cylinders"] = cylinders
    return RobotModel.from_dict(data)


# ---------------------------------------------------------------------------------------
# The built-in geometry


def test_pile_driver_has_five_cylinders_on_the_paper_joints():
    assert CYL.names == ("boom", "stick", "four_bar", "swing_left", "swing_right")
    joints = [MODEL.joints[CYL.joint_of(n)].name for n in CYL.names]
    assert joints == ["boom", "stick", "four_bar", "tilt", "tilt"]
    # The slewing joint and the rotator are motor driven: no cylinder.
    assert {CYL.joint_of(n) for n in CYL.names} == {1, 2, 3, 4}
    assert isinstance(MECHS["boom"], TriangleCylinder)
    assert isinstance(MECHS["four_bar"], FourBarCylinder)
    assert isinstance(MECHS["swing"], SwingCylinderPair)


def test_check_is_clean_and_stroke_ends_are_the_joint_limits():
    assert CYL.check() == []
    for name in CYL.names:
        i = CYL.joint_of(name)
        q = np.zeros((2, MODEL.dof))
        q[:, i] = [MODEL.lower[i], MODEL.upper[i]]
        ends = np.sort(CYL.lengths(q)[name])
        lo, hi = CYL.limits(name)
        np.testing.assert_allclose(ends, [lo, hi], rtol=0, atol=1e-9)
        # Plausible hydraulic cylinders: 300-500 mm retracted, stroke below that.
        assert 300.0 <= lo <= 500.0 and 0 < hi - lo < lo


def test_model_json_round_trip_keeps_the_cylinders():
    again = RobotModel.from_dict(MODEL.to_dict())
    assert again.extras["cylinders"] == MODEL.extras["cylinders"]
    assert CylinderSet.from_model(again).names == CYL.names


# ---------------------------------------------------------------------------------------
# Each mechanism over its joint range

GRID = 20_001


@pytest.mark.parametrize("mech", CYL.mechanisms, ids=lambda m: m.name)
def test_round_trip_angle_length_angle(mech):
    theta = np.linspace(mech.lower, mech.upper, GRID)
    L = mech.lengths(theta)
    for k in range(L.shape[-1]):
        back = mech.angle_of(L[:, k], k)
        assert np.abs(back - theta).max() < 1e-9


@pytest.mark.parametrize("mech", CYL.mechanisms, ids=lambda m: m.name)
def test_length_is_strictly_monotonic(mech):
    L = mech.lengths(np.linspace(mech.lower, mech.upper, GRID))
    steps = np.diff(L, axis=0)
    for k in range(L.shape[-1]):
        assert np.all(steps[:, k] > 0) or np.all(steps[:, k] < 0)


@pytest.mark.parametrize("mech", CYL.mechanisms, ids=lambda m: m.name)
def test_derivative_matches_central_differences(mech):
    theta = np.linspace(mech.lower, mech.upper, 401)
    h = 1e-6
    fd = (mech.lengths(theta + h) - mech.lengths(theta - h)) / (2 * h)
    np.testing.assert_allclose(mech.dlengths_dtheta(theta), fd, rtol=1e-7, atol=1e-6)


@pytest.mark.parametrize("mech", CYL.mechanisms, ids=lambda m: m.name)
def test_speed_both_ways(mech):
    rng = np.random.default_rng(7)
    theta = rng.uniform(mech.lower, mech.upper, 500)
    theta_dot = rng.uniform(-0.5, 0.5, 500)
    dL = mech.dlengths_dtheta(theta)  # (N, k): k = 1, or 2 for the swing pair
    v = np.reshape(mech.speed(theta, theta_dot), dL.shape)
    np.testing.assert_allclose(v, dL * theta_dot[:, None], rtol=1e-12)
    for k in range(dL.shape[1]):
        if isinstance(mech, SwingCylinderPair):
            back = mech.joint_speed(theta, v[:, k], side=k)
        else:
            back = mech.joint_speed(theta, v[:, k])
        np.testing.assert_allclose(back, theta_dot, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("shape", [(), (1,), (3, 1, 2)])
def test_batch_shapes(shape):
    boom = MECHS["boom"]
    theta = np.full(shape, 0.3)
    assert boom.length(theta).shape == shape
    assert boom.angle(boom.length(theta)).shape == shape
    assert MECHS["four_bar"].length(theta - 0.5).shape == shape
    assert MECHS["swing"].length(theta * 0).shape == (*shape, 2)
    q = np.zeros((*shape, MODEL.dof)) + MODEL.mid_configuration()
    lengths = CYL.lengths(q)
    assert all(v.shape == shape for v in lengths.values())
    np.testing.assert_allclose(CYL.joints_from_lengths(lengths, q), q, atol=1e-12)


def test_triangle_is_eq_18():
    boom = MECHS["boom"]
    theta = np.radians([0.0, 20.0, 60.0])
    cad = boom.phi0 + theta  # angle CAD = angle CAT + theta2 + angle BAD
    expected = np.sqrt(boom.r1**2 + boom.r2**2 - 2 * boom.r1 * boom.r2 * np.cos(cad))
    np.testing.assert_allclose(boom.length(theta), expected, rtol=1e-15)


def test_four_bar_against_point_coordinates():
    """Eqs. 20-23 against a construction from coordinates: N at the origin, H on +x, K on the
    crank, M where the rocker and coupler circles meet, G on its ray from N."""
    fb = MECHS["four_bar"]
    theta = np.linspace(fb.lower, fb.upper, 61)
    a, b, m, k, g = fb.l_kh, fb.l_hn, fb.l_mn, fb.l_km, fb.l_ng
    alpha = fb.psi0 + fb.sign * theta
    K = np.stack([b - a * np.cos(alpha), a * np.sin(alpha)], axis=1)
    d = np.linalg.norm(K, axis=1)
    ek = K / d[:, None]
    along = (m * m - k * k + d * d) / (2 * d)
    h = np.sqrt(m * m - along**2)
    M = along[:, None] * ek + h[:, None] * np.stack([-ek[:, 1], ek[:, 0]], axis=1)
    G = g * np.array([math.cos(-fb.angle_gnh), math.sin(-fb.angle_gnh)])
    np.testing.assert_allclose(np.linalg.norm(M - K, axis=1), k, rtol=1e-12)
    np.testing.assert_allclose(fb.length(theta), np.linalg.norm(M - G, axis=1), rtol=1e-12)


def test_swing_pair_is_symmetric_and_antagonistic():
    swing = MECHS["swing"]
    theta = np.linspace(swing.lower, swing.upper, 101)
    L = swing.length(theta)
    np.testing.assert_allclose(L[:, 0], L[::-1, 1], rtol=1e-14)  # left(t) = right(-t)
    dL = swing.dlength_dtheta(theta)
    assert np.all(dL[:, 0] < 0) and np.all(dL[:, 1] > 0)
    assert L[50, 0] == pytest.approx(math.hypot(120.0, 350.0))  # both 370 mm at theta5 = 0


# ---------------------------------------------------------------------------------------
# The whole set


def test_set_round_trip_and_speeds_over_random_configurations():
    rng = np.random.default_rng(0)
    q = rng.uniform(MODEL.lower, MODEL.upper, (2000, MODEL.dof))
    lengths = CYL.lengths(q)
    assert all(np.all(v) for v in CYL.within_stroke(lengths).values())
    back = CYL.joints_from_lengths(lengths, q_other=q * [1, 0, 0, 0, 0, 1])
    assert np.abs(back - q).max() < 1e-9
    # Only the left swing cylinder given: the pair is one joint.
    only_left = {n: v for n, v in lengths.items() if n != "swing_right"}
    assert np.abs(CYL.joints_from_lengths(only_left, q)[:, 4] - q[:, 4]).max() < 1e-9
    qd = rng.uniform(-0.3, 0.3, q.shape)
    v = CYL.speeds(q, qd)
    assert v["swing_left"] * v["swing_right"] == pytest.approx(
        -np.abs(v["swing_left"] * v["swing_right"]))
    qd_back = CYL.joint_speeds(q, v, qd_other=qd * [1, 0, 0, 0, 0, 1])
    np.testing.assert_allclose(qd_back, qd, rtol=1e-10, atol=1e-13)
    # Speed = dL/dt: compare with the lengths a small time step apart.
    dt = 1e-6
    ahead = CYL.lengths(q + qd * dt)
    for name in CYL.names:
        np.testing.assert_allclose((ahead[name] - lengths[name]) / dt, v[name], atol=1e-3)


def test_joints_from_lengths_names_the_field_at_fault():
    lo, hi = CYL.limits("boom")
    with pytest.raises(CylinderError) as err:
        CYL.joints_from_lengths({"boom": hi + 1.0})
    assert err.value.field == "lengths.boom" and "outside the stroke" in str(err.value)
    with pytest.raises(CylinderError) as err:
        CYL.joints_from_lengths({"bucket": 400.0})
    assert err.value.field == "lengths.bucket" and "boom, stick" in str(err.value)
    with pytest.raises(CylinderError) as err:
        CYL.joints_from_lengths({"swing_left": 330.0, "swing_right": 330.0})
    assert err.value.field == "lengths.swing_right" and "pair" in str(err.value)
    with pytest.raises(CylinderError) as err:
        CYL.lengths(np.zeros(5))
    assert err.value.field == "q"
    # Within LENGTH_TOL of a stroke end counts as the end.
    q = CYL.joints_from_lengths({"boom": lo - 1e-9})
    assert q[1] == pytest.approx(MODEL.lower[1], abs=1e-9)


# ---------------------------------------------------------------------------------------
# Inconsistent data is reported in words


def _boom(**changes) -> TriangleCylinder:
    fields = {f: getattr(MECHS["boom"], f) for f in (
        "name", "joint", "r1", "r2", "phi0", "sign", "min_length", "max_length", "lower",
        "upper")}
    fields.update(changes)
    return TriangleCylinder(**fields)


def test_check_reports_each_kind_of_mismatch():
    lo, hi = CYL.limits("boom")
    (msg,) = _boom(min_length=lo + 10).check()
    assert msg.startswith("boom:") and "bottoms out 10.000 mm before the joint" in msg
    (msg,) = _boom(max_length=hi - 10).check()
    assert "runs out of travel 10.000 mm before the joint" in msg
    (msg,) = _boom(min_length=lo - 5).check()
    assert "travel wasted" in msg
    assert _boom(min_length=lo - 0.5).check() == []  # a margin under MAX_STROKE_MARGIN
    # Pin angle swept through 180 deg: a dead point, not monotonic.
    (msg,) = _boom(phi0=math.radians(150)).check()
    assert "dead point" in msg
    # A stroke longer than the retracted length is not a hydraulic cylinder.
    wide = dict(r1=200.0, phi0=math.radians(10), upper=math.radians(160))
    L = _boom(**wide).length(np.array([0.0, wide["upper"]]))  # 255 -> 648 mm
    msgs = _boom(**wide, min_length=float(L[0]), max_length=float(L[1])).check()
    assert any("not below the retracted length" in m for m in msgs)


def test_check_reports_a_four_bar_that_cannot_close():
    spec = copy.deepcopy(MODEL.extras["cylinders"])
    spec[2]["l_km"] = 10.0  # coupler far too short to reach from M to K
    cyl = CylinderSet.from_model(_with_cylinders(spec))
    (msg,) = cyl.check()
    assert msg.startswith("four_bar:") and "cannot close" in msg


def test_set_check_names_the_inconsistent_cylinder_of_a_model():
    spec = copy.deepcopy(MODEL.extras["cylinders"])
    spec[3]["right"]["max_length"] -= 3.0
    msgs = CylinderSet.from_model(_with_cylinders(spec)).check()
    assert len(msgs) == 1 and msgs[0].startswith("swing_right:")


@pytest.mark.parametrize(
    "edit, field",
    [
        (lambda s: s[0].pop("r1"), "cylinders[0].r1"),
        (lambda s: s[0].update(r2=-5.0), "cylinders[0].r2"),
        (lambda s: s[1].update(joint="elbow"), "cylinders[1].joint"),
        (lambda s: s[1].update(joint="boom"), "cylinders[1].joint"),
        (lambda s: s[2].update(kind="piston"), "cylinders[2].kind"),
        (lambda s: s[2].update(psi0="wide"), "cylinders[2].psi0"),
        (lambda s: s[3]["right"].update(sign=-1), "cylinders[3].right.sign"),
        (lambda s: s[3]["left"].update(min_length=900.0), "cylinders[3].left.min_length"),
        (lambda s: s[0].update(colour="red"), "cylinders[0].colour"),
    ],
)
def test_from_model_names_the_field_at_fault(edit, field):
    spec = copy.deepcopy(MODEL.extras["cylinders"])
    edit(spec)
    with pytest.raises(CylinderError) as err:
        CylinderSet.from_model(_with_cylinders(spec))
    assert err.value.field == field


def test_a_model_without_cylinders_says_so():
    with pytest.raises(CylinderError, match="has no cylinders"):
        CylinderSet.from_model(builtin_model("glt_palletizer"))


# ---------------------------------------------------------------------------------------
# Section 4.5: the arm scene's endpoints through IK to cylinder lengths


def _planar(q234: np.ndarray, bearing: float) -> np.ndarray:
    """Tool (radius from the base axis, height) for boom/stick/four-bar angles ``(N, 3)``."""
    q = np.zeros((len(q234), MODEL.dof))
    q[:, 0] = bearing
    q[:, 1:4] = q234
    p = fk(MODEL, q)[:, :3, 3]
    return np.stack([np.hypot(p[:, 0], p[:, 1]), p[:, 2]], axis=1)


def _pose_at(q: np.ndarray) -> np.ndarray:
    return fk(MODEL, q)


def test_scene_goal_is_beyond_reach_and_ik_says_unreachable():
    radial = math.hypot(*SCENE_GOAL[:2])
    assert radial == pytest.approx(2545.6, abs=0.1)
    # r = L1 + L2 c2 + L3 c23 + L4 c234 - L5 s234 <= L1 + L2 + L3 + hypot(L4, L5), any q.
    assert radial > REACH_BOUND == pytest.approx(1916.23, abs=0.01)
    for q_orient in ([0.3, -0.2, -0.4, 0.1, 0.0], [0.9, -0.5, -0.3, -0.4, 1.0]):
        T = _pose_at(np.array([0.0, *q_orient]))
        T[:3, 3] = SCENE_GOAL
        (res,) = solve_ik(MODEL, T)
        assert res.status is IKStatus.UNREACHABLE and not res.success
        assert res.message.startswith("unreachable:") and "mm from the boom pivot" in res.message


def test_scene_start_is_outside_the_workspace_by_400_mm():
    """[500, -1000, 0] lies 1118 mm from the base axis at z = 0; within Table 1's limits the
    arm only reaches beyond 1527.6 mm there (stick and four-bar both at -60 deg).

    The tool position depends on q1..q4 only, the arm always reaches forward (r > 0), so the
    distance to the target is at least the distance in the (r, z) half-plane. A 1-degree
    grid over the boom/stick/four-bar box bounds that from below: moving a joint by half a
    step (0.5 deg) moves the tool by at most its lever arm times 0.0087 rad (25.7 mm in all).
    """
    bearing = math.atan2(SCENE_START[1], SCENE_START[0])
    target = np.array([math.hypot(*SCENE_START[:2]), SCENE_START[2]])
    axes = [np.linspace(MODEL.lower[i], MODEL.upper[i], 61) for i in (1, 2, 3)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    dist = np.linalg.norm(_planar(grid, bearing) - target, axis=1)
    half_step = math.radians(0.5)
    levers = [L2 + L3 + math.hypot(L4, L5), L3 + math.hypot(L4, L5), math.hypot(L4, L5)]
    lower_bound = dist.min() - half_step * sum(levers)
    assert lower_bound > 380.0
    # The nearest reachable point, refined from the best grid point.
    best = minimize(
        lambda t: np.sum((_planar(t[None], bearing)[0] - target) ** 2),
        grid[np.argmin(dist)], method="L-BFGS-B",
        bounds=list(zip(MODEL.lower[1:4], MODEL.upper[1:4])),
    )
    assert math.sqrt(best.fun) == pytest.approx(409.55, abs=0.05)
    np.testing.assert_allclose(np.degrees(best.x[1:]), [-60.0, -60.0], atol=1e-6)
    # So IK, for any orientation, finds it only outside the limits.
    T = _pose_at(np.array([bearing, 0.5, -0.3, -0.4, 0.1, 0.2]))
    T[:3, 3] = SCENE_START
    (res,) = solve_ik(MODEL, T)
    assert res.status is IKStatus.OUT_OF_LIMITS and "outside the joint limits" in res.message


def _config_reaching(point: np.ndarray, tilt: float = 0.1, roll: float = 0.2) -> np.ndarray:
    """A configuration within limits whose tool is at ``point`` (mm), found by bounded least
    squares over boom, stick and four-bar (the tool orientation follows from them)."""
    bearing = math.atan2(point[1], point[0])

    def residual(t):
        q = np.array([bearing, *t, tilt, roll])
        return fk(MODEL, q)[:3, 3] - point

    sol = least_squares(
        residual, MODEL.mid_configuration()[1:4], bounds=(MODEL.lower[1:4], MODEL.upper[1:4]),
        xtol=1e-15, ftol=1e-15, gtol=1e-15,
    )
    return np.array([bearing, *sol.x, tilt, roll])


def test_near_start_pose_to_cylinders():
    q = _config_reaching(NEAR_START)
    assert MODEL.within_limits(q)
    T = _pose_at(q)
    np.testing.assert_allclose(T[:3, 3], NEAR_START, atol=1e-6)
    (res,) = solve_ik(MODEL, T, q0=q)
    assert res.success and res.position_error < 1e-6
    np.testing.assert_allclose(res.q, q, atol=1e-7)
    lengths = CYL.lengths(res.q)
    assert all(CYL.within_stroke(lengths).values())
    # The point is near the workspace edge: stick and four-bar (-57, -58 deg) work near their
    # -60 deg ends, so their cylinders are within 10% of fully retracted.
    for name in ("stick", "four_bar"):
        lo, hi = CYL.limits(name)
        assert 0 < lengths[name] - lo < 0.1 * (hi - lo)
    np.testing.assert_allclose(CYL.joints_from_lengths(lengths, res.q), res.q, atol=1e-9)


TRIANGLE = dict(name="c", joint=1, r1=300.0, r2=400.0, phi0=1.0, sign=1, min_length=400.0,
                max_length=600.0, lower=-0.5, upper=0.5)
FOUR_BAR = dict(name="b", joint=3, l_hn=300.0, l_kh=200.0, l_mn=250.0, l_km=220.0,
                l_ng=500.0, psi0=1.2, sign=1, angle_gnh=0.3, min_length=400.0,
                max_length=700.0, lower=-0.5, upper=0.5)


@pytest.mark.parametrize(
    ("cls", "base", "change", "field"),
    [
        (TriangleCylinder, TRIANGLE, {"r1": 0.0}, "r1"),
        (TriangleCylinder, TRIANGLE, {"phi0": math.nan}, "phi0"),
        (TriangleCylinder, TRIANGLE, {"sign": 2}, "sign"),
        (TriangleCylinder, TRIANGLE, {"min_length": 700.0}, "min_length"),
        (TriangleCylinder, TRIANGLE, {"lower": 1.0}, "lower"),
        (TriangleCylinder, TRIANGLE, {"name": ""}, "name"),
        (FourBarCylinder, FOUR_BAR, {"l_ng": -1.0}, "l_ng"),
        (FourBarCylinder, FOUR_BAR, {"angle_gnh": math.inf}, "angle_gnh"),
        (FourBarCylinder, FOUR_BAR, {"max_length": 300.0}, "min_length"),
    ],
)
def test_bad_cylinder_geometry_names_the_field(cls, base, change, field):
    cls(**base)  # the base geometry is valid
    with pytest.raises(CylinderError) as err:
        cls(**{**base, **change})
    assert err.value.field == field


# ---------------------------------------------------------------------------------------
# Hydraulics: speed limits, bore and rod, the pump


def test_pile_driver_hydraulics_are_as_documented():
    h = CYL.hydraulics
    assert set(h) == set(CYL.names)
    assert (h["boom"].bore, h["boom"].rod) == (63.0, 36.0)
    assert (h["boom"].max_extension_speed, h["boom"].max_retraction_speed) == (150.0, 220.0)
    assert h["boom"].piston_area == pytest.approx(math.pi * 63.0**2 / 4)
    assert h["boom"].annulus_area == pytest.approx(math.pi * (63.0**2 - 36.0**2) / 4)
    assert CYL.pump.flow == 40.0 and CYL.pump.cylinders == CYL.names
    assert CYL.pump.flow_mm3_per_s == pytest.approx(40.0 * 1e6 / 60)
    # Each speed limit is its valve section's flow over the area, within rounding (5 %).
    for name, rated in (("boom", 28), ("stick", 22), ("four_bar", 14), ("swing_left", 12)):
        c = h[name]
        for area, speed in ((c.piston_area, c.max_extension_speed),
                            (c.annulus_area, c.max_retraction_speed)):
            assert area * speed * 60 / 1e6 == pytest.approx(rated, rel=0.05), name


def _with_hydraulics(edit=None, **model_keys) -> RobotModel:
    """The pile driver with its cylinders edited and model keys set (None: removed)."""
    data = _pile_data()
    if edit is not None:
        edit(data["cylinders"])
    data.update(model_keys)
    return RobotModel.from_dict({k: v for k, v in data.items() if v is not None})


@pytest.mark.parametrize(
    ("edit", "model_keys", "field"),
    [
        (lambda s: s[0].update(rod=63.0), {}, "cylinders[0].rod"),
        (lambda s: s[0].update(rod=80.0), {}, "cylinders[0].rod"),
        (lambda s: s[1].pop("rod"), {}, "cylinders[1].rod"),
        (lambda s: s[1].pop("bore"), {}, "cylinders[1].bore"),
        (lambda s: s[0].update(max_extension_speed=0.0), {}, "cylinders[0].max_extension_speed"),
        (lambda s: s[2].update(max_retraction_speed=-5.0), {},
         "cylinders[2].max_retraction_speed"),
        (lambda s: s[3]["left"].update(bore="wide"), {}, "cylinders[3].left.bore"),
        (None, {"pump_flow": 0.0}, "pump_flow"),
        (None, {"pump_flow": math.inf}, "pump_flow"),
        (None, {"pump_cylinders": ["boom", "dipper"]}, "pump_cylinders.1"),
        (None, {"pump_flow": None, "pump_cylinders": ["boom"]}, "pump_flow"),
        (lambda s: [c.pop(k, None) for c in s[:1] for k in ("bore", "rod")],
         {"pump_cylinders": ["boom"]}, "pump_cylinders.0"),
    ],
)
def test_bad_hydraulics_name_the_field(edit, model_keys, field):
    model = _with_hydraulics(edit, **model_keys)
    with pytest.raises(CylinderError) as err:
        CylinderSet.from_model(model)
    assert err.value.field == field


def test_hydraulics_are_optional_and_json_without_them_stays_valid():
    def strip(spec):
        for mech in spec:
            for c in (mech["left"], mech["right"]) if mech["kind"] == "swing_pair" else (mech,):
                for k in ("bore", "rod", "max_extension_speed", "max_retraction_speed"):
                    c.pop(k)
    data = _pile_data()
    strip(data["cylinders"])
    data.pop("pump_flow")
    cs = CylinderSet.from_model(RobotModel.from_dict(data))
    assert cs.hydraulics == {} and cs.pump is None
    # Only speed limits, no areas: fine without a pump.
    data["cylinders"][0]["max_extension_speed"] = 100.0
    cs = CylinderSet.from_model(RobotModel.from_dict(data))
    assert cs.hydraulics["boom"].max_extension_speed == 100.0
    assert not cs.hydraulics["boom"].has_areas
