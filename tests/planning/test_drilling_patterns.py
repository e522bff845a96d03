"""Tunnel-face drilling patterns, hole import and the allocation of holes to the jumbo's arms
(paper 002, section 5: 40 / 52 / 40 holes)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.spatial.distance import pdist

from kinematics.drilling import drill_ik
from kinematics.rigs import builtin_rig
from planning.drilling.allocation import allocate_holes, assign_holes, home_configuration
from planning.drilling.patterns import FACE_X, FacePattern, face_pattern, load_holes, parse_holes


@pytest.fixture(scope="module")
def rig():
    return builtin_rig("tunnel_jumbo")


@pytest.fixture(scope="module")
def face():
    return face_pattern()


# ---- generated faces -------------------------------------------------------------------------
def test_default_horseshoe_face(face):
    H = face.holes
    assert H.shape == (122, 3) and len(face.kinds) == 122
    assert np.all(H[:, 0] == FACE_X)  # the face plane, x = 9000 mm (Table 3)
    counts = face.counts()
    assert counts["cut"] == 17 and counts["contour"] > 30 and counts["helper"] > 20
    assert set(counts) <= {"contour", "lifter", "helper", "stoping", "cut"}
    # inside the 10 m x 8 m section: |y| <= 5 m, floor at -1.5 m, roof at 6.5 m
    spec = face.spec
    y, z = H[:, 1], H[:, 2] - spec.floor_z
    assert np.all(np.abs(y) < spec.width / 2) and np.all(z > 0)
    spring = spec.height - spec.width / 2
    roof = z > spring
    assert np.all(np.hypot(y[roof], z[roof] - spring) < spec.width / 2)
    # mirror symmetric about the centre line
    mirrored = H * [1, -1, 1]
    d = np.linalg.norm(H[:, None] - mirrored[None], axis=2).min(axis=1)
    assert d.max() < 1e-6
    # the cut's innermost square is 100 mm from its centre hole; other holes are further
    # apart, contour holes one spacing
    cut = np.array(face.kinds) == "cut"
    assert pdist(H[cut, 1:]).min() == pytest.approx(spec.spacing * 1.6 / 8)
    assert pdist(H[~cut, 1:]).min() > 0.5 * spec.spacing
    contour = H[np.array(face.kinds) == "contour"][:, 1:]
    gaps = np.linalg.norm(np.diff(contour, axis=0), axis=1)
    np.testing.assert_allclose(gaps, spec.spacing, rtol=0.15)


def test_circular_face_and_parameters():
    f = face_pattern(shape="circular", width=8000, height=8000, floor_z=-1000, face_x=8500)
    H = f.holes
    assert np.all(H[:, 0] == 8500) and len(H) > 60
    r = np.hypot(H[:, 1], H[:, 2] - (-1000 + 4000))
    assert r.max() < 4000
    assert len(face_pattern(spacing=700).holes) < len(face_pattern(spacing=500).holes)


@pytest.mark.parametrize(("kwargs", "field"), [
    ({"shape": "oval"}, "shape"),
    ({"width": 10_000, "height": 4_000}, "height"),  # no room for a semicircular roof
    ({"shape": "circular", "width": 8000, "height": 7000}, "height"),
    ({"spacing": 0.0}, "spacing"),
    ({"spacing": float("nan")}, "spacing"),
    ({"cut_height": 9000.0}, "cut_height"),
])
def test_bad_face_parameters_name_the_field(kwargs, field):
    with pytest.raises(ValueError, match=field):
        FacePattern(**kwargs)


# ---- import ----------------------------------------------------------------------------------
def test_import_csv_and_json(tmp_path):
    rows = [[9000, 100, 200], [9000, -300, 1200.5], [9000, 800, 50]]
    csv_text = "id,z,x,y\n" + "\n".join(f"h{k},{z},{x},{y}" for k, (x, y, z) in
                                        enumerate(rows))
    np.testing.assert_array_equal(parse_holes(csv_text), rows)
    plain = "\n".join(",".join(str(v) for v in r) for r in rows)
    np.testing.assert_array_equal(parse_holes(plain, "csv"), rows)
    for data in (rows, {"holes": rows}, [{"x": x, "y": y, "z": z} for x, y, z in rows]):
        np.testing.assert_array_equal(parse_holes(json.dumps(data)), rows)
    (tmp_path / "face.json").write_text(json.dumps(rows))
    (tmp_path / "face.csv").write_text(plain)
    np.testing.assert_array_equal(load_holes(tmp_path / "face.json"), rows)
    np.testing.assert_array_equal(load_holes(tmp_path / "face.csv"), rows)


@pytest.mark.parametrize(("text", "words"), [
    ("9000,0,0\n9000,10,10\n9000,0,0.4\n", "holes[2]: duplicate of holes[0]"),
    ("9000,0,0\n", "at least 2 holes"),
    ("9000,0,0\n9000,nan,0\n", "holes[1]: has a NaN"),
    ("9000,0,0\n9000,abc,0\n", "holes[1]: CSV row"),
    ('[[9000, 0, 0], [9000, 1, "x"]]', "holes[1]: coordinates must be numbers"),
    ('[{"x": 9000, "y": 0}]', "holes[0]: missing 'z'"),
    ("[[9000, 0, 0], [9000, 0", "not valid JSON"),
])
def test_import_errors_name_the_hole(text, words):
    with pytest.raises(ValueError) as err:
        parse_holes(text)
    assert words in str(err.value)


# ---- allocation ------------------------------------------------------------------------------
def test_allocation_balances_and_respects_reach(rig, face):
    alloc = allocate_holes(rig, face.holes)
    assert alloc.counts() == {"left": 41, "middle": 41, "right": 40}
    assert np.array_equal(np.sort(np.concatenate(list(alloc.indices.values()))),
                          np.arange(len(face.holes)))
    for a in alloc.arms:
        res = drill_ik(rig.arms[a], face.holes[alloc.indices[a]])
        assert all(r.success for r in res)  # within limits, drill perpendicular to the face
        np.testing.assert_allclose(np.array([r.q for r in res]), alloc.q[a])
    # vertical strips: left of the middle arm's holes on the left, and so on
    y = {a: face.holes[alloc.indices[a], 1] for a in alloc.arms}
    assert y["left"].min() > y["middle"].max() and y["middle"].min() > y["right"].max()


def test_allocation_with_the_papers_counts(rig):
    """Section 5: 40 holes for each side arm, 52 for the middle arm (132 in all)."""
    face = face_pattern(width=9_800, height=7_800, spacing=470)
    assert len(face.holes) == 132
    alloc = allocate_holes(rig, face.holes, counts={"left": 40, "middle": 52, "right": 40})
    assert alloc.counts() == {"left": 40, "middle": 52, "right": 40}
    with pytest.raises(ValueError, match="counts"):
        allocate_holes(rig, face.holes, counts={"left": 40, "middle": 50, "right": 40})
    with pytest.raises(ValueError, match="counts.top"):
        allocate_holes(rig, face.holes, counts={"left": 40, "middle": 52, "top": 40})


def test_reach_beats_balance(rig):
    """Holes only the left arm reaches go to it even past its share."""
    H = np.array([[9000, 7800, 6000], [9000, 8000, 6000], [9000, 0, 1000],
                  [9000, 500, 1000], [9000, -7000, 1000], [9000, -7500, 1000.0]])
    alloc = allocate_holes(rig, H)  # equal shares would be 2, 2, 2
    assert alloc.indices["left"].tolist() == [0, 1]
    assert alloc.indices["right"].tolist() == [4, 5]
    alloc = allocate_holes(rig, H, counts={"left": 0, "middle": 6, "right": 0})
    assert alloc.counts() == {"left": 2, "middle": 2, "right": 2}


def test_work_balance_does_not_raise_the_largest_load(rig, face):
    by_count = allocate_holes(rig, face.holes, balance="work", drill_time_s=0.0,
                              max_rounds=3)
    work = by_count.extras["max_work_history_s"]
    assert all(b <= a for a, b in zip(work, work[1:]))
    assert sum(by_count.counts().values()) == len(face.holes)


def test_holes_out_of_every_arms_reach_are_named(rig):
    H = [[9000, 0, 1000], [9000, 0, 20_000], [9000, 500, 1000]]
    with pytest.raises(ValueError, match=r"out of reach of every arm: holes\[1\] "):
        allocate_holes(rig, H)
    with pytest.raises(ValueError, match=r"holes\[2\]: duplicate of holes\[0\]"):
        allocate_holes(rig, [[9000, 0, 1000], [9000, 5, 1000], [9000, 0, 1000.2]])


def test_holes_given_per_arm(rig):
    alloc = assign_holes(rig, {"left": [[9000, 3000, 1000]], "right": [[9000, -3000, 2000]]})
    assert alloc.arms == ("left", "right") and alloc.counts() == {"left": 1, "right": 1}
    with pytest.raises(ValueError, match=r"holes.left\[0\].*out of reach of the left arm"):
        assign_holes(rig, {"left": [[9000, -7000, 1000]], "middle": [[9000, 0, 1000]]})
    with pytest.raises(ValueError, match=r"holes.middle\[0\]: duplicate of holes.left\[0\]"):
        assign_holes(rig, {"left": [[9000, 0, 1000]], "middle": [[9000, 0, 1000]]})
    with pytest.raises(ValueError, match="holes.top"):
        assign_holes(rig, {"top": [[9000, 0, 1000]]})
    with pytest.raises(ValueError, match="at least 2 holes"):
        assign_holes(rig, {"left": [[9000, 3000, 1000]]})


def test_home_configuration_is_the_papers_initial_pose(rig, paper_tables):
    """Table 3 row 1 (swing 0, pitch -90 deg, d3 5598 mm, roll 0, 90 / 90 deg) puts the tip at
    x = 10025 mm; at x = 9000 mm only the telescope is shorter."""
    model = rig.arms["middle"]
    row = paper_tables["tunnel_drill_arm"]["table3"][0]
    q = home_configuration(model, float(row["xyz"][0]))
    assert q[2] == pytest.approx(row["q"]["d3_mm"], abs=1.0)
    np.testing.assert_allclose(np.degrees(q[[0, 1, 3, 4, 5]]), [0, -90, 0, 90, 90])
    assert home_configuration(model, 9000.0)[2] == pytest.approx(row["q"]["d3_mm"] - 1025,
                                                                 abs=1.0)
    with pytest.raises(ValueError, match="face_x"):
        home_configuration(model, 50_000.0)
