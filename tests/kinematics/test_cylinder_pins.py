"""Pin points of the cylinders in the plane of the joint each drives: the distance between a
cylinder's pins is its length, carrying-link points stay put as the joint turns, driven-link
points turn with it, and a four-bar's bars keep their lengths."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

import kinematics
from kinematics.cylinders import (
    CylinderPins,
    CylinderSet,
    FourBarCylinder,
    SwingCylinderPair,
    TriangleCylinder,
)
from kinematics.library import builtin_model
from kinematics.model import RobotModel

MODEL = builtin_model("pile_driver")
CYL = CylinderSet.from_model(MODEL)
MECHS = {m.name: m for m in CYL.mechanisms}
TRIANGLES = [MECHS["boom"], MECHS["stick"], MECHS["swing"].left, MECHS["swing"].right]
#: A four-bar whose stick side is mirrored (sign -1), next to the built-in one (sign +1).
MIRRORED = FourBarCylinder(name="b", joint=3, l_hn=300.0, l_kh=200.0, l_mn=250.0,
                           l_km=220.0, l_ng=500.0, psi0=1.2, sign=-1, angle_gnh=0.3,
                           min_length=400.0, max_length=700.0, lower=-0.5, upper=0.5)
FOUR_BARS = [MECHS["four_bar"], MIRRORED]


def _turn(p: np.ndarray, angle) -> np.ndarray:
    """Points ``(*, 2)`` turned by ``angle (*,)`` about the origin of the plane."""
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([c * p[..., 0] - s * p[..., 1], s * p[..., 0] + c * p[..., 1]], axis=-1)


def _q(n: int, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).uniform(MODEL.lower, MODEL.upper, (n, MODEL.dof))


@pytest.mark.parametrize("shape", [(), (50,), (2, 3)])
def test_the_distance_between_the_pins_is_the_cylinder_length(shape):
    q = _q(int(np.prod(shape)) or 1).reshape(shape + (MODEL.dof,))
    pins = CYL.pins(q)
    lengths = CYL.lengths(q)
    assert tuple(pins) == CYL.names
    for name, p in pins.items():
        assert isinstance(p, CylinderPins) and p.name == name
        assert p.joint == CYL.joint_of(name)
        assert p.barrel.shape == p.rod.shape == shape + (2,)
        np.testing.assert_allclose(p.length, lengths[name], rtol=1e-13, atol=0)
        np.testing.assert_allclose(np.linalg.norm(p.rod - p.barrel, axis=-1), lengths[name],
                                   rtol=1e-13, atol=0)


@pytest.mark.parametrize("mech", TRIANGLES, ids=lambda m: m.name)
def test_triangle_pins_sit_on_their_links(mech):
    theta = np.linspace(mech.lower, mech.upper, 7)
    (p,) = mech.pins(theta)
    assert p.linkage == {}
    # Barrel pin: r1 from the joint, fixed to the carrying link.
    np.testing.assert_allclose(np.linalg.norm(p.barrel, axis=-1), mech.r1, rtol=1e-14)
    np.testing.assert_allclose(p.barrel, np.broadcast_to(p.barrel[0], p.barrel.shape),
                               atol=0)
    # Rod pin: r2 from the joint on the driven link's reference ray (at theta).
    np.testing.assert_allclose(_turn(p.rod, -theta), [[mech.r2, 0.0]] * len(theta),
                               atol=1e-12)
    # The angle between the pin rays is phi = phi0 + sign * theta (eqs. 18, 19, 24, 25).
    cos = np.einsum("ij,ij->i", p.barrel, p.rod) / (mech.r1 * mech.r2)
    np.testing.assert_allclose(cos, np.cos(mech.phi(theta)), atol=1e-14)


@pytest.mark.parametrize("mech", FOUR_BARS, ids=["pile_driver", "mirrored"])
def test_four_bar_points_keep_the_bars_and_ride_on_their_links(mech):
    theta = np.linspace(mech.lower, mech.upper, 9)
    (p,) = mech.pins(theta)
    P = p.linkage
    assert set(P) == {"H", "N", "K", "M", "G"}
    np.testing.assert_array_equal(p.barrel, P["G"])
    np.testing.assert_array_equal(p.rod, P["M"])

    def dist(a, b):
        return np.linalg.norm(P[a] - P[b], axis=-1)

    for (a, b), want in {("H", "N"): mech.l_hn, ("H", "K"): mech.l_kh,
                         ("N", "M"): mech.l_mn, ("M", "K"): mech.l_km,
                         ("N", "G"): mech.l_ng}.items():
        np.testing.assert_allclose(dist(a, b), want, rtol=1e-13, err_msg=a + b)
    np.testing.assert_allclose(dist("M", "G"), mech.length(theta), rtol=1e-13)
    # H on the joint axis; N back along the carrying link's ray; G fixed to the stick.
    np.testing.assert_allclose(P["H"], 0.0, atol=0)
    np.testing.assert_allclose(P["N"], [[-mech.l_hn, 0.0]] * len(theta), atol=1e-12)
    np.testing.assert_allclose(P["G"], np.broadcast_to(P["G"][0], P["G"].shape), atol=0)
    # K is fixed to the driven link: turned back by theta it stays put.
    K_driven = _turn(P["K"], -theta)
    np.testing.assert_allclose(K_driven, np.broadcast_to(K_driven[0], K_driven.shape),
                               atol=1e-9)
    # Angle KHN is psi0 + sign * theta, on the side of N-H that ``sign`` picks.
    NH, KH = P["N"] - P["H"], P["K"] - P["H"]
    khn = np.arccos(np.einsum("ij,ij->i", NH, KH) / (mech.l_hn * mech.l_kh))
    np.testing.assert_allclose(khn, mech.psi0 + mech.sign * theta, atol=1e-12)


def test_a_four_bar_that_cannot_close_has_no_rod_pin():
    spec = copy.deepcopy(MODEL.extras["cylinders"])
    spec[2]["l_km"] = 10.0  # coupler far too short to reach from M to K
    data = MODEL.to_dict()
    data["cylinders"] = spec
    cyl = CylinderSet.from_model(RobotModel.from_dict(data))
    q = np.zeros(MODEL.dof)
    pins = cyl.pins(q)["four_bar"]
    assert math.isnan(cyl.lengths(q)["four_bar"])
    assert np.all(np.isnan(pins.rod)) and np.all(np.isnan(pins.linkage["M"]))
    assert np.all(np.isfinite(pins.barrel)) and np.all(np.isfinite(pins.linkage["K"]))
    assert np.isnan(pins.length)


def test_pins_reject_a_wrong_shape_and_are_public():
    with pytest.raises(kinematics.CylinderError) as err:
        CYL.pins(np.zeros(3))
    assert err.value.field == "q"
    assert kinematics.CylinderPins is CylinderPins
    assert isinstance(MECHS["swing"], SwingCylinderPair)
    assert [p.name for p in MECHS["swing"].pins(0.1)] == ["swing_left", "swing_right"]
    assert isinstance(MECHS["boom"], TriangleCylinder)
