"""The geometry layer (planning.geometry): the shape registry, the pair table, and every
compiled kernel against its Python twin on random cases."""

from __future__ import annotations

import ast
import math
from pathlib import Path

import numpy as np
import pytest

from kinematics.errors import FieldError
from planning.geometry import (
    KERNEL_CODES,
    ShapeKind,
    pair_functions,
    pairs,
    parse_object,
    register_shape,
    shape_kind,
    shape_names,
)
from planning.geometry.balls import BallSet
from planning.geometry.compiled import kernel_objects

RNG_SEED = 20261202
ROOT = Path(__file__).resolve().parents[2]
BUILTIN = ("box", "sphere", "cylinder", "capsule", "mesh", "points")


def random_pose(rng: np.random.Generator, spread: float = 400.0) -> np.ndarray:
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    if np.linalg.det(Q) < 0:
        Q[:, 0] = -Q[:, 0]
    T = np.eye(4)
    T[:3, :3] = Q
    T[:3, 3] = rng.uniform(-spread, spread, 3)
    return T


def random_spec(name: str, rng: np.random.Generator) -> dict:
    """A random object of a built-in shape, in the API format."""
    spec: dict = {"type": name, "pose": random_pose(rng).tolist()}
    if name == "box":
        spec["size"] = rng.uniform(5, 300, 3).tolist()
    elif name == "sphere":
        spec["radius"] = float(rng.uniform(5, 200))
    elif name == "cylinder":
        spec.update(radius=float(rng.uniform(5, 150)), height=float(rng.uniform(5, 400)))
    elif name == "capsule":
        spec.update(a=rng.uniform(-200, 200, 3).tolist(), b=rng.uniform(-200, 200, 3).tolist(),
                    radius=float(rng.uniform(5, 100)))
    elif name == "mesh":
        V = rng.uniform(-150, 150, (4, 3))
        spec.update(vertices=V.tolist(), faces=[[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    else:
        spec.update(points=rng.uniform(-100, 100, (40, 3)).tolist(),
                    radius=float(rng.uniform(10, 40)))
    return spec


def test_the_builtin_shapes_are_registered_in_order():
    assert shape_names()[:len(BUILTIN)] == BUILTIN
    for name in BUILTIN:
        kind = shape_kind(name)
        assert kind.name == name and kind.exact is not None and kind.path_cover is not None
        assert kind.code is not None


def test_every_point_pair_has_a_kernel_and_a_twin():
    """The compiled checker switches on codes: each code a shape uses has its row of the
    pair table, with a Python twin and a kernel that exists in planning.geometry.kernels."""
    kernels = pytest.importorskip("planning.geometry.kernels")
    rows = {row.shape: row for row in pairs() if row.query == "point"}
    for name in shape_names():
        kind = shape_kind(name)
        if kind.code is None:
            continue
        row = rows["balls" if kind.balls is not None else name]
        assert callable(row.twin)
        assert row.kernel is not None and callable(getattr(kernels, row.kernel))
    assert set(KERNEL_CODES) == {"balls"} | {n for n in shape_names()
                                             if shape_kind(n).balls is None
                                             and shape_kind(n).code is not None}


@pytest.mark.parametrize("name", BUILTIN)
def test_kernels_agree_with_their_python_twins(name):
    """Random objects of each shape and random points around them: the compiled distance
    (``object_distance``, through the codes and parameters the registry gives) equals the
    Python twin of the shape's row of the pair table."""
    kernels = pytest.importorskip("planning.geometry.kernels")
    rng = np.random.default_rng(RNG_SEED + BUILTIN.index(name))
    for _ in range(20):
        o = parse_object(random_spec(name, rng), 0)
        kind = shape_kind(name)
        P = o.pose[:3, 3] + rng.uniform(-500, 500, (200, 3))
        if kind.balls is not None:
            balls = kind.balls(o, 15.0)
            sets = [(0, BallSet(balls))]
            bounds = [sets[0][1].bounds()]
            twin = pair_functions("point", "balls").twin(P, balls)
        else:
            sets, bounds = [], [kind.bounds(o)]
            twin = pair_functions("point", name).twin(P, *kind.pack([o]))[:, 0]
        kind_arr, T_inv, par, _, B, cells, meta = kernel_objects([o], sets, bounds)
        compiled = np.array([kernels.object_distance(p, 1e9, 0, kind_arr, T_inv, par, B,
                                                     cells, meta) for p in P])
        np.testing.assert_allclose(compiled, twin, rtol=0, atol=1e-8)
        near = np.abs(twin) < 50.0  # the early-out agrees with the distance
        for p, d in zip(P[near], twin[near]):
            assert kernels.object_within(p, max(d, 0.0) + 1e-6, 0, kind_arr, T_inv, par, B,
                                         cells, meta)
        # ... and says no beyond it (compared squared for some shapes: never a near miss
        # answered as clear, never a far point answered as near).
        for reach in (0.0, 10.0, 80.0, 300.0):
            clear = twin > reach + 1e-6
            close = twin <= reach - 1e-6
            within = np.array([kernels.object_within(p, reach, 0, kind_arr, T_inv, par, B,
                                                     cells, meta) for p in P])
            assert not within[clear].any() and within[close].all()


@pytest.mark.slow
@pytest.mark.parametrize("name", BUILTIN)
def test_bounds_contain_the_object_and_the_json_round_trips(name):
    """Points inside an object (negative distance) lie within its bounds; ``to_dict`` reads
    back to an object at the same distances."""
    rng = np.random.default_rng(RNG_SEED + 100 + BUILTIN.index(name))
    kind = shape_kind(name)
    for _ in range(10):
        o = parse_object(random_spec(name, rng), 3)
        again = parse_object(o.to_dict(), 3)
        assert again.to_dict().keys() == o.to_dict().keys()
        if kind.balls is not None:
            balls = kind.balls(o, 15.0)
            lo, hi = BallSet(balls).bounds()
        else:
            lo, hi = kind.bounds(o)
        # Around the bounds, a quarter of their size beyond them on every side: a point
        # inside the object but outside the bounds would show.
        # (Fewer points for a ball cover, whose twin measures every ball: hundreds.)
        pad = 0.25 * (hi - lo)
        P = rng.uniform(lo - pad, hi + pad, (4000 if kind.balls is not None else 20000, 3))
        if kind.balls is not None:
            d = pair_functions("point", "balls").twin(P, balls)
            d2 = pair_functions("point", "balls").twin(P, kind.balls(again, 15.0))
        else:
            d = pair_functions("point", name).twin(P, *kind.pack([o]))[:, 0]
            d2 = pair_functions("point", name).twin(P, *kind.pack([again]))[:, 0]
        assert np.array_equal(d, d2)
        inside = P[d < 0]
        assert len(inside) > 0
        assert np.all((inside >= lo - 1e-9) & (inside <= hi + 1e-9))


def test_segment_rows_are_the_point_path_functions():
    from planning.geometry import segments

    assert pair_functions("segment", "sphere").twin is segments.segment_point_distance
    assert pair_functions("segment", "capsule").twin is segments.segment_segment_distance
    assert pair_functions("segment", "box").twin is segments.segment_box_distance


def test_errors_name_the_field():
    with pytest.raises(FieldError) as err:
        parse_object({"type": "capsule", "a": [0, 0, 0], "b": [1, 0, 0], "radius": -1}, 2)
    assert err.value.loc == ("objects", 2, "radius")
    with pytest.raises(FieldError) as err:
        parse_object({"type": "wedge"}, 0)
    assert err.value.loc == ("objects", 0, "type")
    assert "known types: " + ", ".join(BUILTIN) in str(err.value)


def test_registering_a_taken_name_or_an_unknown_code_fails():
    box = shape_kind("box")
    with pytest.raises(ValueError, match="already registered"):
        register_shape(box)
    with pytest.raises(ValueError, match="has no compiled kernel"):
        register_shape(ShapeKind(name="odd", required=(), optional=(), parse=box.parse,
                                 to_dict=box.to_dict, pack=box.pack, code=99,
                                 kernel_params=box.kernel_params))
    assert "odd" not in shape_names()


def test_geometry_imports_nothing_above_it():
    """planning.geometry sits on the lowest floor of planning: it imports kinematics, its
    own modules and planning's status/budget/registry, nothing else of planning."""
    allowed = ("planning.geometry", "planning.status", "planning.budget", "planning.registry")
    offenders = []
    for path in sorted((ROOT / "planning" / "geometry").rglob("*.py")):
        module = ".".join(path.relative_to(ROOT).with_suffix("").parts)
        package = module if path.name == "__init__.py" else module.rsplit(".", 1)[0]
        for node in ast.walk(ast.parse(path.read_text())):
            names = []
            if isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    parts = package.split(".")
                    parts = parts[:len(parts) - node.level + 1]
                    base = ".".join(parts + ([base] if base else []))
                names = [base]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            offenders += [f"{module} imports {n}" for n in names
                          if n.split(".")[0] == "planning" and not n.startswith(allowed)]
    assert not offenders, offenders


def test_drilling_envelopes_and_point_paths_share_the_segment_distance():
    """Envelopes (planning.drilling) measure capsules with the same segment distance the
    point paths use: a known case, two crossing capsules 100 mm apart."""
    from planning.geometry.segments import segment_segment_distance

    d, s, t = segment_segment_distance(np.array([-1.0, 0, 0]) * 500, np.array([1.0, 0, 0]) * 500,
                                       np.array([0, -500.0, 100]), np.array([0, 500.0, 100]))
    assert float(d) == pytest.approx(100.0) and float(s) == 0.5 and float(t) == 0.5
    assert math.isfinite(float(d))


@pytest.mark.slow
@pytest.mark.parametrize("name", BUILTIN)
def test_path_covers_contain_the_shape(name):
    """A stored scene's object becomes point-path obstacles (its ``path_cover``) that are
    never smaller: every point inside the object is inside the cover."""
    from planning.geometry.obstacles import obstacle_from_dict
    from planning.paths.scene import Scene

    rng = np.random.default_rng(RNG_SEED + 200 + BUILTIN.index(name))
    kind = shape_kind(name)
    for _ in range(5):
        o = parse_object(random_spec(name, rng), 0)
        cover = [obstacle_from_dict(d) for d in kind.path_cover(o)]
        scene = Scene.create([[-2000] * 3, [2000] * 3], cover)
        if name == "mesh":  # a mesh is its surface: points on its triangles
            tri = o.world_vertices()[o.faces]
            w = rng.dirichlet(np.ones(3), size=(len(tri), 200))
            inside = np.einsum("tkj,tji->tki", w, tri).reshape(-1, 3)
        elif name == "points":  # a cloud is its inflated points: points within the radius
            u = rng.normal(size=(3000, 3))
            u *= (o.radius * rng.random(3000) ** (1 / 3) / np.linalg.norm(u, axis=1))[:, None]
            inside = o.world_points()[rng.integers(len(o.points), size=3000)] + u
        else:
            lo, hi = kind.bounds(o)
            P = rng.uniform(lo, hi, (3000, 3))
            inside = P[pair_functions("point", name).twin(P, *kind.pack([o]))[:, 0] < 0]
        assert len(inside) > 10
        assert np.all(scene.point_clearance(inside).min(axis=1) <= 1e-9)


def test_a_path_obstacle_and_its_scene_object_are_the_same_shape():
    """``object_dict`` turns a point-path obstacle into the scene object of the same shape:
    their signed distances agree at random points."""
    from planning.geometry.obstacles import obstacle_from_dict

    rng = np.random.default_rng(RNG_SEED + 300)
    specs = [{"center": rng.uniform(-300, 300, 3).tolist(), "radius": 80.0},
             {"type": "box", "lower": [-100.0, -50, 0], "upper": [150.0, 60, 40]},
             {"type": "capsule", "a": [0.0, 0, 0], "b": [200.0, 100, -50], "radius": 30.0}]
    P = rng.uniform(-500, 500, (2000, 3))
    for spec in specs:
        ob = obstacle_from_dict(spec)
        o = parse_object(ob.object_dict("x"), 0)
        d = pair_functions("point", o.type).twin(P, *shape_kind(o.type).pack([o]))[:, 0]
        clearance = pair_functions("segment", ob.kind).twin
        if ob.kind == "sphere":
            ref = clearance(P, P, ob.center)[0] - ob.radius
        elif ob.kind == "capsule":
            ref = clearance(P, P, ob.a, ob.b)[0] - ob.radius
        else:
            ref = clearance(P, P, ob.lower, ob.upper)[0]
        np.testing.assert_allclose(d, ref, rtol=0, atol=1e-9)
        lo, hi = ob.bounding_box()
        c, r = ob.bounding_sphere()
        inside = P[d < 0]
        assert np.all((inside >= lo) & (inside <= hi))
        assert np.all(np.linalg.norm(inside - c, axis=1) <= r + 1e-9)
