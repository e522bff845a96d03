"""The recipe "Adding a collision shape" (docs/extending.md), followed to the letter for a
toy shape defined here: a ``slab`` (a plate: ``extent`` [x, y] full sides, ``thickness``
along local z, centred on its origin). It registers through the registry's public API,
parses, bounds, collides against robots through the public collision check (the exact
stage through FCL, the sphere stage through its Python twin, the joint-space checker on the
Python path as it has no compiled kernel), and is unregistered afterwards."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from kinematics.errors import FieldError
from kinematics.model import RobotModel
from planning.collision import CollisionScene, RobotCollisionModel, check, collides
from planning.geometry import (
    ShapeKind,
    parse_object,
    register_pair,
    register_shape,
    shape_names,
    unregister_shape,
)
from planning.geometry.distance import to_local
from planning.geometry.fields import number

fcl = pytest.importorskip("fcl")


# ---- step 1: the shape's module (here, this test module) ------------------------------------
def parse(data: dict, loc: tuple, resolve_mesh: Any = None) -> dict[str, Any]:
    """Fields in the order their errors should be reported."""
    value = data["extent"]
    if not isinstance(value, list | tuple) or len(value) != 2:
        raise FieldError(loc + ("extent",), "extent must be a list of 2 numbers")
    extent = tuple(number(v, loc + ("extent", k), "extent") for k, v in enumerate(value))
    return {"extent": extent,
            "thickness": number(data["thickness"], loc + ("thickness",), "thickness")}


def to_dict(o) -> dict[str, Any]:
    return {"extent": list(o.extent), "thickness": o.thickness}


def half_sides(o) -> np.ndarray:
    return 0.5 * np.array([o.extent[0], o.extent[1], o.thickness])


def bounds(o) -> tuple[np.ndarray, np.ndarray]:
    T = o.pose
    half = np.abs(T[:3, :3]) @ half_sides(o)
    return T[:3, 3] - half, T[:3, 3] + half


def pack(objs: list) -> tuple[np.ndarray, np.ndarray]:
    return (np.array([o.pose for o in objs]).reshape(-1, 4, 4),
            np.array([half_sides(o) for o in objs]).reshape(-1, 3))


def slab_distance(P: np.ndarray, T: np.ndarray, half: np.ndarray) -> np.ndarray:
    """Signed distance ``(K, n)`` of points ``P (K, 3)`` to slabs posed ``T (n, 4, 4)`` with
    half sides ``half (n, 3)``: the distance to the nearest face outside, minus the depth
    inside."""
    q = np.abs(to_local(P, T)) - half[None]
    return np.linalg.norm(np.maximum(q, 0.0), axis=-1) + np.minimum(q.max(-1), 0.0)


def exact(o) -> tuple:
    T = np.asarray(o.pose, dtype=float)
    geom = fcl.Box(*(2 * half_sides(o)))
    return ("fcl", fcl.CollisionObject(geom, fcl.Transform(T[:3, :3], T[:3, 3])))


def path_cover(o) -> list[dict[str, Any]]:
    lo, hi = bounds(o)
    return [{"type": "box", "lower": lo.tolist(), "upper": hi.tolist()}]


# ---- step 2: registration (and unregistration when done) ----------------------------------------
@pytest.fixture
def slab():
    kind = register_shape(ShapeKind(
        name="slab", required=("extent", "thickness"), optional=(), parse=parse,
        to_dict=to_dict, bounds=bounds, pack=pack, exact=exact, path_cover=path_cover))
    register_pair("point", "slab", slab_distance)
    try:
        yield kind
    finally:
        unregister_shape("slab")
    assert "slab" not in shape_names()


def ry90(x: float) -> list:
    """A pose whose local z is world x, at ``(x, 0, 0)``."""
    T = np.array([[0.0, 0, 1, x], [0, 1, 0, 0], [-1, 0, 0, 0], [0, 0, 0, 1]])
    return T.tolist()


WALL = {"type": "slab", "id": "wall", "extent": [400, 300], "thickness": 20,
        "pose": ry90(700.0)}


def reach_arm() -> RobotCollisionModel:
    """A capsule of radius 20 from the origin to ``(500 + q, 0, 0)``."""
    T = np.eye(4)
    T[0, 3] = 500.0
    model = RobotModel.from_dict({
        "id": "reach", "name": "reach", "convention": "poe",
        "joints": [{"name": "feed", "type": "prismatic", "axis": [1, 0, 0], "lower": 0,
                    "upper": 300}],
        "home": T.tolist()})
    return RobotCollisionModel.from_model(model, link_radius=20.0)


# ---- step 3: the checks the recipe asks for ----------------------------------------------
def test_it_parses_and_names_its_fields(slab):
    o = parse_object(WALL, 0)
    assert o.type == "slab" and o.thickness == 20.0 and o.extent == (400.0, 300.0)
    with pytest.raises(FieldError) as err:
        parse_object({**WALL, "thickness": -1}, 4)
    assert err.value.loc == ("objects", 4, "thickness")
    with pytest.raises(FieldError) as err:
        parse_object({"type": "slab", "extent": [1, 1]}, 0)
    assert err.value.loc == ("objects", 0, "thickness")
    with pytest.raises(FieldError) as err:
        parse_object({**WALL, "extent": [1, 1, 1]}, 0)
    assert err.value.loc == ("objects", 0, "extent")
    assert parse_object(o.to_dict(), 0).to_dict() == o.to_dict()


def test_bounds_contain_it(slab):
    o = parse_object(WALL, 0)
    lo, hi = o.kind.bounds(o)
    assert lo == pytest.approx([690, -150, -200]) and hi == pytest.approx([710, 150, 200])


def test_it_collides_through_the_public_check(slab):
    """The capsule's tip reaches x = 520 + q; the wall's face is at x = 690: gap 170 - q,
    measured exactly (FCL), and the same answers as the equal box."""
    cm = reach_arm()
    scene = CollisionScene.from_dicts([WALL])
    q = np.array([[0.0], [100.0], [169.0], [171.0], [250.0]])
    rep = check(cm, q, scene, exact_distance=True)
    assert rep.collides.tolist() == [False, False, False, True, True]
    assert rep.distance[:3] == pytest.approx([170.0, 70.0, 1.0], abs=1e-4)
    assert [pair[1] for pair in rep.pairs[4]] == ["wall"]
    box = CollisionScene.from_dicts([{"type": "box", "id": "wall", "size": [400, 300, 20],
                                      "pose": ry90(700.0)}])
    assert collides(cm, q, scene, exact=True).tolist() == \
        collides(cm, q, box, exact=True).tolist()
    assert check(cm, q, box, exact_distance=True).distance[:3] == \
        pytest.approx(rep.distance[:3], abs=1e-6)


def test_the_joint_space_checker_falls_back_to_python(slab):
    """No compiled kernel for the slab: the motion checker answers on the Python path, the
    same as the collision check."""
    from planning.motion.checker import MotionChecker

    cm = reach_arm()
    scene = CollisionScene.from_dicts([WALL])
    q = np.array([[0.0], [169.0], [171.0]])
    assert MotionChecker(cm, scene).free(q).tolist() == [True, True, False]
    assert (~collides(cm, q, scene, exact=True)).tolist() == [True, True, False]


def test_it_is_unknown_once_unregistered(slab):
    unregister_shape("slab")
    try:
        with pytest.raises(FieldError, match="'slab' is not a known type"):
            parse_object(WALL, 0)
    finally:
        register_shape(slab)
        register_pair("point", "slab", slab_distance)
