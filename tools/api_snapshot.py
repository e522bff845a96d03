"""Before/after snapshot of the REST API's answers, to show that a refactor left them unchanged.

``record`` builds a fresh application in process (a temporary data directory, two local job
workers, the viewer on a free loopback port, explicit settings: no ``KINOPLAN_*`` variable of
the caller's environment is read), sends it a fixed list of requests with fixed seeds, and
writes each request (method, path, body) with its status, a few headers and its answer,
normalised, to a JSON file. ``compare`` prints every difference between two such files
(request, place in the answer, both values) and exits 1 if there is any; a list of named items
(robots, job kinds) that only changed order is one difference, then each item is compared
with its namesake.

No request's answer may depend on the machine's speed: a case that did (the motion endpoint's
shortening, cut by its 2 s deadline on a loaded machine) was changed, not masked.

The requests cover every operation of the OpenAPI document (at least one valid and one invalid
request each; valid bodies come from the examples of the README and docs/API.md) and every job
kind of ``GET /jobs/kinds`` (submitted with a small valid payload, waited for, its record,
result and, where the kind has one, plot fetched). ``record`` prints the operations and kinds
it did not cover, if any (a new endpoint or kind needs a case here), and keeps them in the
file's ``meta``.

Normalisation of an answer:

- JSON: job ids the run created are replaced by their case's label (``{job:echo}``), in
  values and inside messages; the values listed in ``MASKED`` below are replaced by
  ``"<masked>"`` (a ``null`` stays ``null``, so "no finish time yet" still differs from one);
  floats are rounded to 9 significant digits and ``-0.0`` is written ``0.0``.
- ``application/x-npy``: the array, its shape and dtype, normalised as JSON numbers.
- PNG: width, height and the SHA-256 of the bytes. ZIP: each member's name, size and SHA-256
  (not the members' timestamps). Other text (URDF XML): the text itself.
- Headers: only those in ``RECORDED_HEADERS`` (job ids replaced as above).

``MASKED`` was found by recording the same checkout twice and diffing: each entry is a
volatile value (wall times, timestamps, process ids, store sizes) and says why. Keep it
explicit: a masked field is one whose changes go unseen.

Usage (from the checkout to record; PYTHONPATH puts another checkout's packages first)::

    .venv/bin/python tools/api_snapshot.py record before.json
    .venv/bin/python tools/api_snapshot.py record after.json --only health,fk
    .venv/bin/python tools/api_snapshot.py compare before.json after.json
    # another checkout (the venv's editable install points here: PYTHONPATH goes first)
    REPO=$PWD; cd /tmp/base && PYTHONPATH=$PWD $REPO/.venv/bin/python \
        $REPO/tools/api_snapshot.py record base.json

45 to 90 s on 2 cores, depending on their load (the first run of a checkout compiles its
numba kernels into its ``__pycache__`` and takes minutes).
"""

from __future__ import annotations

import argparse
import fnmatch
import hashlib
import io
import json
import math
import os
import re
import struct
import sys
import tempfile
import time
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

FORMAT = "kinoplan-api-snapshot/1"

#: Values masked in every JSON answer, by the dotted path of the value (list indices written
#: as numbers; ``*`` matches any run of characters, dots included). Each is volatile between
#: two runs of the same build.
MASKED: dict[str, str] = {
    # job records
    "created": "job record: submission time",
    "started": "job record: start time",
    "finished": "job record: end time",
    "*.created": "job records in a list: submission time",
    "*.started": "job records in a list: start time",
    "*.finished": "job records in a list: end time",
    # wall times measured by the planners and jobs
    "*runtime_s": "wall time of a planner or job step",
    "*planning_time_s": "wall time of a motion plan (search and shortening)",
    "*simplify_time_s": "wall time of a path's shortening",
    "*mean_time_s": "path_compare: mean wall time per run",
    # the sleep diagnostic reports its worker's process and the time it slept
    "slept": "sleep job: the time it actually slept",
    "pid": "sleep job: its worker's process id",
    # /health: sizes of the SQLite file as it grows and is checkpointed
    "store.bytes": "/health: the SQLite file, its WAL and index on disk",
    "store.free_bytes": "/health: free pages inside the SQLite file",
}

#: Response headers kept in a record; the others (date, content-length of masked answers...)
#: are either volatile or follow from the body.
RECORDED_HEADERS = ("content-type", "x-total-count", "link", "retry-after", "location", "allow")

#: A job id that no run creates (answers 404 wherever a job id is asked for).
UNKNOWN_JOB = "0000000000000000"

#: Job statuses after which a job no longer changes.
ENDED = ("succeeded", "failed", "cancelled")

# ---------------------------------------------------------------------------------------------
# Fixed request data (units mm, rad, s)

POSE = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]


def _pose(x: float, y: float, z: float) -> list[list[float]]:
    return [[1, 0, 0, x], [0, 1, 0, y], [0, 0, 1, z], [0, 0, 0, 1]]


#: docs/API.md's robot model example (an MDH arm of a revolute and a prismatic joint).
MY_ARM = {
    "id": "my_arm", "name": "My arm", "convention": "mdh",
    "joints": [
        {"name": "j1", "type": "revolute", "a": 0, "alpha": 0, "d": 0, "offset": 0,
         "lower": -3.1, "upper": 3.1, "velocity": 1.0},
        {"name": "j2", "type": "prismatic", "a": 150, "alpha": -1.5708, "theta": 0,
         "offset": 0, "lower": 0, "upper": 800},
    ],
    "base": POSE, "tool": POSE,
}

#: A three-joint arm written as a bare URDF (metres), boxes and a cylinder as collision shapes.
URDF = """<?xml version="1.0"?>
<robot name="snap_arm">
  <link name="base_link">
    <collision><geometry><box size="0.3 0.3 0.2"/></geometry></collision>
  </link>
  <link name="upper">
    <collision><origin xyz="0.25 0 0"/><geometry><box size="0.5 0.1 0.1"/></geometry></collision>
  </link>
  <link name="fore">
    <collision><origin xyz="0.2 0 0" rpy="0 1.5708 0"/>
      <geometry><cylinder radius="0.04" length="0.4"/></geometry></collision>
  </link>
  <link name="tool"/>
  <joint name="waist" type="revolute">
    <parent link="base_link"/><child link="upper"/><origin xyz="0 0 0.2"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="10" velocity="1"/>
  </joint>
  <joint name="shoulder" type="revolute">
    <parent link="upper"/><child link="fore"/><origin xyz="0.5 0 0"/>
    <axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="10" velocity="1"/>
  </joint>
  <joint name="slide" type="prismatic">
    <parent link="fore"/><child link="tool"/><origin xyz="0.4 0 0"/>
    <axis xyz="1 0 0"/><limit lower="0" upper="0.2" effort="10" velocity="0.1"/>
  </joint>
</robot>
"""


def _box_stl(sx: float, sy: float, sz: float) -> bytes:
    """An ASCII STL of a box of side lengths ``(sx, sy, sz)`` centred on the origin
    (12 triangles, outward normals)."""
    hx, hy, hz = sx / 2, sy / 2, sz / 2
    v = [(x, y, z) for x in (-hx, hx) for y in (-hy, hy) for z in (-hz, hz)]
    quads = [(0, 1, 3, 2, (-1, 0, 0)), (4, 6, 7, 5, (1, 0, 0)), (0, 4, 5, 1, (0, -1, 0)),
             (2, 3, 7, 6, (0, 1, 0)), (0, 2, 6, 4, (0, 0, -1)), (1, 5, 7, 3, (0, 0, 1))]
    lines = ["solid box"]
    for a, b, c, d, n in quads:
        for tri in ((a, b, c), (a, c, d)):
            lines.append(f"facet normal {n[0]} {n[1]} {n[2]}\n outer loop")
            lines += [f"  vertex {v[i][0]} {v[i][1]} {v[i][2]}" for i in tri]
            lines.append(" endloop\nendfacet")
    lines.append("endsolid box")
    return ("\n".join(lines) + "\n").encode()


CRATE_STL = _box_stl(400, 300, 200)

#: A scene of each object type (mesh: the uploaded crate).
CELL = {
    "id": "cell", "name": "Palletizing cell",
    "objects": [
        {"type": "box", "id": "table", "size": [1200, 800, 40], "pose": _pose(1500, 0, 400)},
        {"type": "sphere", "id": "ball", "radius": 150, "pose": _pose(-1500, 0, 500)},
        {"type": "cylinder", "id": "post", "radius": 60, "height": 1500,
         "pose": _pose(-600, 900, 750)},
        {"type": "capsule", "id": "pipe", "a": [0, -1500, 200], "b": [800, -1500, 200],
         "radius": 50},
        {"type": "mesh", "id": "crate", "mesh": "crate", "pose": _pose(0, 1500, 100)},
    ],
}

#: The README's motion example: the palletizer swings its waist past a ball.
BALL_SCENE = {"objects": [{"type": "sphere", "id": "ball", "radius": 150,
                           "pose": _pose(1367, 0, 1288)}]}
MOTION = {"start": [-1.0, 0.3, -0.3, 0.0, 0.5, 0.0],
          "goal": {"q": [1.0, 0.3, -0.3, 0.0, 0.5, 0.0]}, "scene": BALL_SCENE,
          "time_limit": 2, "seed": 0}

#: The README's FK configuration (the palletizer paper's Table 2, first row) and its pose.
GLT_Q = [0.2618, 0.5236, 0.7854, 1.0472, 1.5708, 2.7925]
GLT_POSE = [[-0.467, -0.5522, -0.6907, 783.71], [0.3022, 0.6344, -0.7115, -336.47],
            [0.831, -0.541, -0.1294, 323.58], [0, 0, 0, 1]]
PD_POSE = [[0.8047, -0.458, -0.3777, 1732.3], [0.3534, -0.1417, 0.9247, 535.9],
           [-0.477, -0.8776, 0.0479, 327.5], [0, 0, 0, 1]]
PD_Q = [0.3, 0.5, -0.5, -0.5, 0.1, 0.0]

#: Drill holes on the face of paper 002's tunnel (x along the tunnel).
FACE = [[9000, 0, 0], [9000, 1200, 300], [9000, -800, 900], [9000, 400, 2000],
        [9000, -1500, 2500], [9000, 2000, 1500]]
SIDES = {"left": [[9000, 2600, 300], [9000, 3400, 1500]],
         "middle": [[9000, 0, 2400], [9000, 1000, 4300], [9000, -1100, 800]],
         "right": [[9000, -2600, 500], [9000, -3500, 2000]]}

PATH_SCENE = {"bounds": [[0, 0, 0], [100, 100, 100]],
              "obstacles": [{"center": [30, 30, 30], "radius": 12},
                            {"center": [55, 50, 55], "radius": 12},
                            {"type": "box", "lower": [70, 70, 60], "upper": [85, 85, 80]}]}

#: Tool positions of a palletizer whose joints[2].a is 3 mm longer than the built-in's, at
#: fixed configurations (rounded to 1 µm): the calibration should find the 3 mm.
CALIBRATION = [
    {"q": [0.851, -0.505, -2.924, -6.751, 1.312, 7.204], "position": [-670.141, 857.666, 862.541]},
    {"q": [0.663, 1.549, -0.678, 6.075, 1.323, -8.679], "position": [1224.472, -920.355, -207.149]},
    {"q": [2.221, -1.56, 0.153, -4.529, 1.521, 0.724], "position": [299.197, 622.253, 1343.205]},
    {"q": [-1.244, 0.178, -2.98, -5.246, 0.715, 2.569], "position": [-135.436, -647.633, 1455.494]},
    {"q": [0.717, 0.004, 1.349, 6.714, 0.777, 2.626], "position": [288.671, -306.453, 317.673]},
    {"q": [1.171, 0.027, -2.503, 3.093, 0.106, -3.312], "position": [-280.468, 661.883, 1731.105]},
    {"q": [-0.088, 2.264, 1.067, -1.986, 0.3, -3.109], "position": [-252.174, 16.046, -33.862]},
    {"q": [0.586, -0.201, -1.357, 5.449, -1.143, 2.15], "position": [-247.6, 50.233, 2149.421]},
]

#: One small valid payload per job kind (seeded), submitted in this order.
JOB_PAYLOADS: dict[str, dict] = {
    "sleep": {"seconds": 0.2, "steps": 2},
    "echo": {"value": {"a": [1, 2.5, "x"], "b": None}},
    "workspace": {"robot": "pile_driver", "samples": 20000, "seed": 3, "return_points": 5,
                  "projections": False},
    "sequence": {"holes": FACE, "start": [9000, 0, -500], "cost": "time", "arm": "middle",
                 "seed": 1},
    "multiarm": {"holes": SIDES, "seed": 0},
    "calibrate": {"robot": "glt_palletizer", "measurements": CALIBRATION,
                  "parameters": ["joints[2].a"]},
    "ik_train": {"robot": "tunnel_drill_arm", "samples": 500, "validation_samples": 100,
                 "seed": 0},
    # RRT-Connect with a generous time limit: the path is shortened until it stops improving,
    # well before the limit (at 2 s, a worker starting on a loaded machine has cut it short).
    "motion": {"robot": "glt_palletizer", **MOTION, "planner": "rrt_connect", "time_limit": 10},
    "path": {"scene": PATH_SCENE, "start": [1, 1, 1], "goal": [100, 100, 100], "seed": 0},
    "path_compare": {"scene": PATH_SCENE, "start": [1, 1, 1], "goal": [100, 100, 100],
                     "algorithms": ["auto", "ga"], "runs": 2, "seed": 0,
                     "params": {"ga": {"iterations": 20, "population": 20}}},
    "pallet": {"box": {"size": [400, 300, 250]}, "count": 2, "time_limit": 10, "seed": 0,
               "pick": [[1, 0, 0, 0], [0, 1, 0, -1100], [0, 0, 1, 825], [0, 0, 0, 1]]},
    "piles": {"plan": [{"id": "A", "x": 1600, "y": 0, "z": 0},
                       {"id": "far", "x": 9000, "y": 0, "z": 0}],
              "setups": {"positions": [[0, 0, 0]]}},
    "round": {"holes": [{"id": "M1", "collar": [9000, 0, 2500], "toe": [10000, 0, 2500]}],
              "booms": ["middle"], "collaring_s": 1, "retract_s": 5,
              "penetration_rate_m_min": 6, "output_dt": 5.0},
    "tracking": {"robot": "hyper_redundant_9dof",
                 "task": {"kind": "line", "length": 100.0, "duration": 5.0},
                 "controller": {"kind": "pi"}, "tune": None, "seed": 0},
}


# ---------------------------------------------------------------------------------------------
# The requests


@dataclass
class Case:
    """One request. ``path`` and ``body`` may name a job a previous case submitted as
    ``{job:LABEL}``. ``save``: the label under which the answer's ``id`` is kept (a job
    submission). ``until``: poll this GET until the answer's ``status`` is one of these (it
    records the answer that stops the polling)."""

    name: str
    method: str
    path: str
    json: Any = None
    content: bytes | None = None
    files: dict | None = None
    data: dict | None = None
    headers: dict = field(default_factory=dict)
    save: str | None = None
    until: tuple[str, ...] | None = None


def cases() -> list[Case]:
    """Every request of a record, in the order sent (later ones read what earlier ones stored)."""
    c: list[Case] = []

    def add(name, method, path, **kw):
        c.append(Case(name, method, path, **kw))

    npy = {"accept": "application/x-npy"}
    # service and reference data
    add("health", "GET", "/health")
    add("health.bad_method", "POST", "/health", json={})
    add("openapi", "GET", "/openapi.json")
    add("robots.list", "GET", "/robots")
    add("robots.list.bad_method", "PUT", "/robots", json={})
    add("robots.get", "GET", "/robots/glt_palletizer")
    add("robots.get.pile_driver", "GET", "/robots/pile_driver")
    add("robots.get.unknown", "GET", "/robots/nope")
    add("robots.urdf", "GET", "/robots/glt_palletizer/urdf")
    add("robots.urdf.unknown", "GET", "/robots/nope/urdf")
    add("robots.archive", "GET", "/robots/glt_palletizer/archive")
    add("robots.archive.unknown", "GET", "/robots/nope/archive")
    add("rigs.list", "GET", "/rigs")
    add("rigs.list.bad_method", "POST", "/rigs", json={})
    add("rigs.get", "GET", "/rigs/tunnel_jumbo")
    add("rigs.get.unknown", "GET", "/rigs/nope")
    # custom robots
    add("robots.create", "POST", "/robots", json=MY_ARM)
    add("robots.create.duplicate", "POST", "/robots", json=MY_ARM)
    add("robots.create.invalid", "POST", "/robots",
        json={**MY_ARM, "id": "bad arm", "convention": "xyz"})
    add("robots.create.bad_limits", "POST", "/robots",
        json={**MY_ARM, "id": "bad_limits",
              "joints": [{**MY_ARM["joints"][0], "lower": 2.0, "upper": -2.0}]})
    add("robots.get.custom", "GET", "/robots/my_arm")
    add("fk.custom", "POST", "/robots/my_arm/fk", json={"q": [0.5, 300]})
    add("robots.import", "POST", "/robots/import",
        files={"file": ("snap_arm.urdf", URDF.encode(), "text/xml")}, data={"id": "snap_arm"})
    add("robots.import.duplicate", "POST", "/robots/import",
        files={"file": ("snap_arm.urdf", URDF.encode(), "text/xml")}, data={"id": "snap_arm"})
    add("robots.import.not_urdf", "POST", "/robots/import",
        files={"file": ("x.urdf", b"<robot name='x'><link/></robot>", "text/xml")},
        data={"id": "x"})
    add("robots.import.json_body", "POST", "/robots/import", json={"id": "y"})
    add("robots.get.imported", "GET", "/robots/snap_arm")
    add("robots.urdf.imported", "GET", "/robots/snap_arm/urdf")
    add("robots.archive.imported", "GET", "/robots/snap_arm/archive")
    add("fk.imported", "POST", "/robots/snap_arm/fk", json={"q": [[0.3, -0.4, 50], [0, 0, 0]]})
    add("ik.imported", "POST", "/robots/snap_arm/ik",   # the pose of fk.imported's first q
        json={"pose": [[0.879923176281, -0.295520206661, -0.372025551942, 873.633673889],
                       [0.272192135295, 0.955336489126, -0.115080988997, 270.246564214],
                       [0.389418342309, 0.0, 0.921060994003, 375.238254039], [0, 0, 0, 1]],
              "q0": [0.2, -0.3, 20]})
    # kinematics
    add("fk", "POST", "/robots/glt_palletizer/fk", json={"q": GLT_Q})
    add("fk.all_frames", "POST", "/robots/glt_palletizer/fk",
        json={"q": [GLT_Q, [0, 0.2, -0.3, 0, 0.5, 0]], "frames": "all"})
    add("fk.npy", "POST", "/robots/glt_palletizer/fk", headers=npy,
        json={"q": [[0, 0.2, -0.3, 0, 0.5, 0], [0.1, 0.2, -0.3, 0, 0.5, 0]]})
    add("fk.wrong_length", "POST", "/robots/glt_palletizer/fk", json={"q": [0, 1]})
    add("fk.nan", "POST", "/robots/glt_palletizer/fk",
        content=b'{"q": [0, NaN, 0, 0, 0, 0]}', headers={"content-type": "application/json"})
    add("fk.unknown_robot", "POST", "/robots/nope/fk", json={"q": [0]})
    add("fk.not_json", "POST", "/robots/glt_palletizer/fk", content=b"q=1",
        headers={"content-type": "application/x-www-form-urlencoded"})
    add("jacobian", "POST", "/robots/glt_palletizer/jacobian", json={"q": GLT_Q})
    add("jacobian.npy", "POST", "/robots/pile_driver/jacobian", json={"q": PD_Q}, headers=npy)
    add("jacobian.bad_field", "POST", "/robots/glt_palletizer/jacobian",
        json={"q": GLT_Q, "extra": 1})
    add("ik", "POST", "/robots/glt_palletizer/ik", json={"pose": GLT_POSE, "all_solutions": True})
    add("ik.numeric", "POST", "/robots/hyper_redundant_9dof/ik",
        json={"pose": [[1, 0, 0, 900], [0, 1, 0, 100], [0, 0, 1, 300], [0, 0, 0, 1]],
              "method": "numeric"})
    add("ik.batch_npy", "POST", "/robots/glt_palletizer/ik", headers=npy,
        json={"pose": [GLT_POSE, _pose(99999, 0, 0)]})
    add("ik.not_rigid", "POST", "/robots/glt_palletizer/ik",
        json={"pose": [[2, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]})
    add("ik.learned_untrained", "POST", "/robots/tunnel_drill_arm/ik",
        json={"pose": _pose(9000, 0, 1000), "method": "learned"})
    add("workspace", "POST", "/robots/pile_driver/workspace",
        json={"samples": 30000, "return_points": 0, "projections": False})
    add("workspace.projections", "POST", "/robots/glt_palletizer/workspace",
        json={"samples": 3000, "seed": 7, "voxel": 100, "return_points": 4})
    add("workspace.npy", "POST", "/robots/glt_palletizer/workspace", headers=npy,
        json={"samples": 500, "seed": 2, "return_points": 3})
    add("workspace.zero_samples", "POST", "/robots/pile_driver/workspace", json={"samples": 0})
    add("drill_ik", "POST", "/robots/tunnel_drill_arm/drill-ik",
        json={"holes": FACE[:3], "d7": 4022, "roll": 0})
    add("drill_ik.npy", "POST", "/robots/tunnel_jumbo-middle/drill-ik", headers=npy,
        json={"holes": FACE[:2]})
    add("drill_ik.not_a_drill", "POST", "/robots/glt_palletizer/drill-ik",
        json={"holes": FACE[:1]})
    # cylinders
    add("cylinders", "POST", "/robots/pile_driver/cylinders",
        json={"q": PD_Q, "qd": [0, 0.1, -0.1, 0.05, 0.2, 0]})
    add("cylinders.no_cylinders", "POST", "/robots/glt_palletizer/cylinders", json={"q": GLT_Q})
    add("cylinders.inverse", "POST", "/robots/pile_driver/cylinders/inverse",
        json={"lengths": {"boom": 490.0, "stick": 480.0}, "q": PD_Q})
    add("cylinders.inverse.out_of_stroke", "POST", "/robots/pile_driver/cylinders/inverse",
        json={"lengths": {"boom": 5000.0}})
    add("pose_to_cylinders", "POST", "/robots/pile_driver/pose-to-cylinders",
        json={"pose": PD_POSE})
    add("pose_to_cylinders.unreachable", "POST", "/robots/pile_driver/pose-to-cylinders",
        json={"pose": _pose(50000, 0, 0)})
    add("pose_to_cylinders.bad_pose", "POST", "/robots/pile_driver/pose-to-cylinders",
        json={"pose": [[1, 0, 0]]})
    # trajectories
    add("trajectories.quintic", "POST", "/trajectories",
        json={"method": "quintic", "waypoints": [[0, 0], [1, -0.5], [0.5, 0.5]],
              "durations": [1.0, 1.5], "dt": 0.1})
    add("trajectories.time_scaling", "POST", "/trajectories",
        json={"robot": "pile_driver", "time_scaling": "optimal", "limits": {"acceleration": 5.0},
              "waypoints": [[0, 0.1, -0.9, -0.5, 0, 0], [0, 0.9, -0.1, -0.5, 0, 0]], "dt": 0.1})
    add("trajectories.bspline_limits", "POST", "/trajectories",
        json={"method": "bspline5", "waypoints": [[0, 0, 0], [1, 1, 0], [2, 0, 1], [3, 1, 1]],
              "durations": [1, 1, 1], "dt": 0.25, "limits": {"velocity": 1.0, "jerk": [5, 5, 5]}})
    add("trajectories.bad_durations", "POST", "/trajectories",
        json={"method": "quintic", "waypoints": [[0], [1]], "durations": [1, 2], "dt": 0.1})
    add("trajectories.plot", "POST", "/trajectories/plot",
        json={"method": "quintic", "waypoints": [[0, 0], [1, -0.5]], "durations": [1.0],
              "dt": 0.05, "title": "snapshot"})
    add("trajectories.plot.bad_dt", "POST", "/trajectories/plot",
        json={"method": "quintic", "waypoints": [[0], [1]], "durations": [1.0], "dt": 0})
    add("trajectories.cartesian", "POST", "/trajectories/cartesian",
        json={"robot": "glt_palletizer", "path": {"kind": "line", "end": [900, 200, 800]},
              "q0": [0, 0.3, -0.3, 0, 0.5, 0], "points": 10, "duration": 4, "dt": 0.2})
    add("trajectories.cartesian.unreachable", "POST", "/trajectories/cartesian",
        json={"robot": "glt_palletizer", "path": {"kind": "line", "end": [90000, 0, 0]},
              "points": 10, "duration": 4, "dt": 0.2})
    # meshes and scenes
    add("meshes.upload", "POST", "/meshes",
        files={"file": ("crate.stl", CRATE_STL, "model/stl")}, data={"id": "crate"})
    add("meshes.upload.not_a_mesh", "POST", "/meshes",
        files={"file": ("junk.stl", b"not a mesh " * 50, "model/stl")}, data={"id": "junk"})
    add("meshes.list", "GET", "/meshes")
    add("meshes.list.bad_method", "PUT", "/meshes", json={})
    add("meshes.get", "GET", "/meshes/crate")
    add("meshes.get.unknown", "GET", "/meshes/nope")
    add("scenes.create", "POST", "/scenes", json=CELL)
    add("scenes.create.duplicate", "POST", "/scenes", json=CELL)
    add("scenes.create.bad_object", "POST", "/scenes",
        json={"id": "bad", "objects": [{"type": "sphere", "radius": -1}]})
    add("scenes.list", "GET", "/scenes")
    add("scenes.list.bad_method", "PUT", "/scenes", json={})
    add("scenes.get", "GET", "/scenes/cell")
    add("scenes.get.moveit", "GET", "/scenes/cell?format=moveit")
    add("scenes.get.bad_format", "GET", "/scenes/cell?format=yaml")
    add("scenes.get.unknown", "GET", "/scenes/nope")
    add("meshes.delete.in_use", "DELETE", "/meshes/crate")
    # collision and motion
    add("collision.model", "GET", "/robots/glt_palletizer/collision")
    add("collision.model.imported", "GET", "/robots/snap_arm/collision")
    add("collision.model.unknown", "GET", "/robots/nope/collision")
    add("collision.inline", "POST", "/robots/glt_palletizer/collision",
        json={"q": [[-1.0, 0.3, -0.3, 0.0, 0.5, 0.0], [0.0, 0.3, -0.3, 0.0, 0.5, 0.0]],
              "scene": BALL_SCENE})
    add("collision.stored_scene", "POST", "/robots/glt_palletizer/collision",
        json={"q": [0.0, 0.6, 0.3, 0.0, 0.5, 0.0], "scene": "cell", "exact_distance": True})
    add("collision.imported", "POST", "/robots/snap_arm/collision",
        json={"q": [[0, 0, 0], [0, 1.9, 0.1]], "exact_distance": True})
    add("collision.unknown_scene", "POST", "/robots/glt_palletizer/collision",
        json={"q": GLT_Q, "scene": "nope"})
    # The endpoint's time limit is at most 2 s, and the path's shortening and the blending of
    # its trajectory stop at it: on a loaded machine (or while a worker compiles kernels) the
    # README's example answers a longer path. The search alone finishes within it; the whole
    # example runs as the ``motion`` job below, with 10 s.
    add("motion", "POST", "/robots/glt_palletizer/motion",
        json={**MOTION, "simplify": False, "trajectory": False})
    add("motion.start_in_collision", "POST", "/robots/glt_palletizer/motion",
        json={**MOTION, "start": [0.0, 0.3, -0.3, 0.0, 0.5, 0.0]})
    add("motion.time_limit_too_long", "POST", "/robots/glt_palletizer/motion",
        json={**MOTION, "time_limit": 5})
    # jobs: one of each kind, then their records, results and plots
    add("jobs.kinds", "GET", "/jobs/kinds")
    add("jobs.kinds.bad_method", "POST", "/jobs/kinds", json={})
    for kind, params in JOB_PAYLOADS.items():
        add(f"jobs.submit.{kind}", "POST", "/jobs", json={"kind": kind, "params": params},
            save=kind)
    add("jobs.submit.failing", "POST", "/jobs",
        json={"kind": "sleep", "params": {"seconds": 0.1, "steps": 1, "outcome": "raise"}},
        save="failing")
    add("jobs.submit.unknown_kind", "POST", "/jobs", json={"kind": "nope", "params": {}})
    add("jobs.submit.bad_params", "POST", "/jobs",
        json={"kind": "workspace", "params": {"robot": "pile_driver", "samples": 0}})
    add("jobs.submit.unknown_robot", "POST", "/jobs",
        json={"kind": "workspace", "params": {"robot": "nope"}})
    add("jobs.submit.time_limit_over", "POST", "/jobs",
        json={"kind": "echo", "params": {"value": 1}, "time_limit_s": 10**9})
    for label in [*JOB_PAYLOADS, "failing"]:
        add(f"jobs.get.{label}", "GET", f"/jobs/{{job:{label}}}", until=ENDED)
        add(f"jobs.result.{label}", "GET", f"/jobs/{{job:{label}}}/result")
    add("jobs.get.unknown", "GET", f"/jobs/{UNKNOWN_JOB}")
    add("jobs.result.unknown", "GET", f"/jobs/{UNKNOWN_JOB}/result")
    add("jobs.plot.tracking", "GET", "/jobs/{job:tracking}/plot")
    add("jobs.plot.no_plot", "GET", "/jobs/{job:workspace}/plot")
    add("jobs.plot.unknown", "GET", f"/jobs/{UNKNOWN_JOB}/plot")
    # trajectory exports (JSON only: a csv writes every float in full, unrounded)
    add("jobs.trajectory.motion", "GET", "/jobs/{job:motion}/trajectory")
    add("jobs.trajectory.motion.ros", "GET",
        "/jobs/{job:motion}/trajectory?format=joint_trajectory")
    add("jobs.trajectory.multiarm.arm", "GET",
        "/jobs/{job:multiarm}/trajectory?arm=left&format=joint_trajectory")
    add("jobs.trajectory.multiarm.csv_of_all", "GET",
        "/jobs/{job:multiarm}/trajectory?format=csv")
    add("jobs.trajectory.multiarm.bad_arm", "GET", "/jobs/{job:multiarm}/trajectory?arm=top")
    add("jobs.trajectory.bad_format", "GET", "/jobs/{job:motion}/trajectory?format=xml")
    add("jobs.trajectory.no_trajectory", "GET", "/jobs/{job:workspace}/trajectory")
    add("jobs.trajectory.unknown", "GET", f"/jobs/{UNKNOWN_JOB}/trajectory")
    add("jobs.list", "GET", "/jobs")
    add("jobs.list.page", "GET", "/jobs?limit=3&offset=2")
    add("jobs.list.filtered", "GET", "/jobs?kind=sleep&status=failed")
    add("jobs.list.bad_status", "GET", "/jobs?status=lost")
    add("ik.learned", "POST", "/robots/tunnel_drill_arm/ik", json={"method": "learned", "pose": [
        [0.0008, 0.0, 1.0, 9000.5031], [1.0, 0.0, -0.0008, -4.112], [0.0, 1.0, 0.0, 17.1006],
        [0, 0, 0, 1]]})   # drill tip near FACE[0], drilling along +x
    # cancelling a running job, then deleting it
    add("jobs.submit.long", "POST", "/jobs",
        json={"kind": "sleep", "params": {"seconds": 60, "steps": 1}}, save="long")
    add("jobs.get.long.running", "GET", "/jobs/{job:long}", until=("running", *ENDED))
    add("jobs.cancel.running", "DELETE", "/jobs/{job:long}")
    add("jobs.get.long.cancelled", "GET", "/jobs/{job:long}", until=ENDED)
    add("jobs.result.cancelled", "GET", "/jobs/{job:long}/result")
    add("jobs.delete.ended", "DELETE", "/jobs/{job:long}")
    add("jobs.get.deleted", "GET", "/jobs/{job:long}")
    add("jobs.delete.unknown", "DELETE", f"/jobs/{UNKNOWN_JOB}")
    # the viewer (not running: the service is built without it)
    add("viewer.show.robot", "POST", "/viewer/show", json={"robot": "pile_driver", "q": PD_Q})
    add("viewer.show.job", "POST", "/viewer/show", json={"job": "{job:tracking}"})
    add("viewer.show.both", "POST", "/viewer/show",
        json={"robot": "pile_driver", "job": "{job:tracking}"})
    # deletions last
    add("scenes.delete", "DELETE", "/scenes/cell")
    add("scenes.delete.unknown", "DELETE", "/scenes/cell")
    add("meshes.delete", "DELETE", "/meshes/crate")
    add("meshes.delete.unknown", "DELETE", "/meshes/crate")
    add("robots.delete", "DELETE", "/robots/my_arm")
    add("robots.delete.imported", "DELETE", "/robots/snap_arm")
    add("robots.delete.builtin", "DELETE", "/robots/glt_palletizer")
    add("robots.delete.unknown", "DELETE", "/robots/my_arm")
    add("robots.list.after", "GET", "/robots")
    return c


# ---------------------------------------------------------------------------------------------
# Normalisation


def round_float(x: float) -> float | str:
    """``x`` to 9 significant digits; ``-0.0`` as ``0.0``; NaN and infinities as strings (JSON
    has no literal for them)."""
    if not math.isfinite(x):
        return repr(x)
    return float(f"{x:.9g}") + 0.0


def _masked(path: str) -> bool:
    return any(fnmatch.fnmatchcase(path, pattern) for pattern in MASKED)


def normalise(value: Any, ids: dict[str, str], path: str = "") -> Any:
    """``value`` (parsed JSON) with job ids replaced by their labels, the ``MASKED`` values
    masked and floats rounded (``round_float``). ``ids``: job id -> its placeholder."""
    if path and value is not None and _masked(path):
        return "<masked>"
    if isinstance(value, dict):
        return {_unid(k, ids): normalise(v, ids, f"{path}.{k}" if path else str(k))
                for k, v in value.items()}
    if isinstance(value, list):
        return [normalise(v, ids, f"{path}.{i}" if path else str(i))
                for i, v in enumerate(value)]
    if isinstance(value, float):
        return round_float(value)
    if isinstance(value, str):
        return _unid(value, ids)
    return value


def _unid(text: str, ids: dict[str, str]) -> str:
    for job_id, label in ids.items():
        if job_id in text:
            text = text.replace(job_id, label)
    return text


def _png_size(data: bytes) -> tuple[int, int] | None:
    if data[:8] != b"\x89PNG\r\n\x1a\n" or len(data) < 24:
        return None
    return struct.unpack(">II", data[16:24])


def answer_of(response, ids: dict[str, str]) -> Any:
    """The normalised body of ``response``, by its content type (see the module docstring)."""
    ctype = response.headers.get("content-type", "").split(";")[0].strip()
    data = response.content
    if not data:
        return None
    if ctype == "application/json" or ctype.endswith("+json"):
        return normalise(response.json(), ids)
    if ctype == "application/x-npy":
        import numpy as np

        array = np.load(io.BytesIO(data), allow_pickle=False)
        return {"npy": {"dtype": str(array.dtype), "shape": list(array.shape),
                        "values": normalise(array.tolist(), ids)}}
    if ctype == "image/png":
        size = _png_size(data)
        return {"png": {"width": size and size[0], "height": size and size[1],
                        "sha256": hashlib.sha256(data).hexdigest()}}
    if ctype in ("application/zip", "application/x-zip-compressed"):
        with zipfile.ZipFile(io.BytesIO(data)) as z:
            return {"zip": [{"name": i.filename, "size": i.file_size,
                             "sha256": hashlib.sha256(z.read(i)).hexdigest()}
                            for i in z.infolist()]}
    if ctype.startswith("text/") or ctype.endswith("xml"):
        return {"text": _unid(response.text, ids)}
    return {"bytes": len(data), "sha256": hashlib.sha256(data).hexdigest()}


def _substitute(value: Any, saved: dict[str, str]) -> Any:
    """``value`` with each ``{job:LABEL}`` replaced by the id saved under LABEL."""
    if isinstance(value, str):
        for label, job_id in saved.items():
            value = value.replace(f"{{job:{label}}}", job_id)
        return value
    if isinstance(value, dict):
        return {k: _substitute(v, saved) for k, v in value.items()}
    if isinstance(value, list):
        return [_substitute(v, saved) for v in value]
    return value


def _body_of(case: Case) -> Any:
    """What a record keeps of the request's body (files by name, size and SHA-256)."""
    if case.files is not None or case.data is not None:
        files = {k: {"filename": f[0], "bytes": len(f[1]),
                     "sha256": hashlib.sha256(f[1]).hexdigest()}
                 for k, f in (case.files or {}).items()}
        return {"multipart": {"data": case.data or {}, "files": files}}
    if case.content is not None:
        return {"raw": case.content.decode("utf-8", "replace")}
    return case.json


# ---------------------------------------------------------------------------------------------
# record


def _environment() -> None:
    """The service's settings come from ``Settings`` below alone: drop the caller's
    ``KINOPLAN_*`` variables (the job workers inherit the environment too)."""
    for name in [n for n in os.environ if n.startswith("KINOPLAN_")]:
        del os.environ[name]
    os.environ["KINOPLAN_PRESTART_COMPUTE"] = "0"


def _sources() -> dict[str, str]:
    import app
    import kinematics
    import planning

    return {m.__name__: str(Path(m.__file__).resolve().parent.parent)
            for m in (app, kinematics, planning)}


def _send(client, case: Case, saved: dict[str, str], timeout_s: float):
    path = _substitute(case.path, saved)
    kw: dict[str, Any] = {"headers": case.headers}
    if case.files is not None or case.data is not None:
        kw.update(files=case.files, data=case.data)
    elif case.content is not None:
        kw["content"] = case.content
    elif case.json is not None:
        kw["json"] = _substitute(case.json, saved)
    deadline = time.monotonic() + timeout_s
    while True:
        response = client.request(case.method, path, **kw)
        if case.until is None or response.status_code != 200:
            return response
        if response.json().get("status") in case.until or time.monotonic() > deadline:
            return response
        time.sleep(0.05)


def _coverage(document: dict, kinds: list[str],
              sent: list[tuple[Case, int]]) -> dict[str, list[str]]:
    """Operations of the OpenAPI document without a valid (< 400) and an invalid (>= 400)
    answer among the cases sent, and job kinds never submitted."""
    outcomes: dict[str, set[bool]] = {}
    for case, status in sent:
        template = case.path.split("?")[0]
        for path, operations in document["paths"].items():
            pattern = "^" + re.sub(r"\{[^}]+\}", r"[^/]+", path) + "$"
            if not re.match(pattern, template) or (template in document["paths"]
                                                    and template != path):
                continue   # another path (``/jobs/kinds``, not ``/jobs/{job_id}``)
            if case.method.lower() in operations:
                outcomes.setdefault(f"{case.method} {path}", set()).add(status < 400)
            elif status == 405:  # a method the path does not take: invalid for each it does
                for method in operations:
                    outcomes.setdefault(f"{method.upper()} {path}", set()).add(False)
    missing = {"valid": [], "invalid": []}
    for path, operations in document["paths"].items():
        for method in operations:
            seen = outcomes.get(f"{method.upper()} {path}", set())
            if True not in seen:
                missing["valid"].append(f"{method.upper()} {path}")
            if False not in seen:
                missing["invalid"].append(f"{method.upper()} {path}")
    submitted = {c.json["kind"] for c, s in sent if c.path == "/jobs" and c.method == "POST"
                 and s == 202}
    missing["kinds"] = sorted(set(kinds) - submitted)
    return missing


def record(out: Path, only: list[str] | None, verbose: bool, timeout_s: float) -> int:
    """Send the cases (those whose name starts with one of ``only``, if given) to a fresh app;
    write the records to ``out``. The command line clears the ``KINOPLAN_*`` environment
    first (``_environment``); called from Python, the settings below are explicit anyway."""
    from fastapi.testclient import TestClient

    from app.config import Settings
    from app.main import create_app

    todo = [c for c in cases() if not only or any(c.name.startswith(o) for o in only)]
    start = time.monotonic()
    records: list[dict] = []
    sent: list[tuple[Case, int]] = []
    saved: dict[str, str] = {}   # label -> job id
    with tempfile.TemporaryDirectory(prefix="kinoplan-snapshot-") as data_dir:
        settings = Settings(no_viewer=True, data_dir=Path(data_dir), workers=2,
                            jobs_backend="local", compute_workers=2, api_key=None,
                            allowed_hosts="*", prestart_compute=False,
                            prebuild_collision=False)
        api = create_app(settings)
        if any(c.path.startswith("/viewer/") for c in todo):
            # The viewer on a free loopback port, so that POST /viewer/show answers (as the
            # viewer tests start it; ``python -m kinoplan`` starts it the same way).
            from web.viewer import Viewer

            api.state.viewer = Viewer.start("127.0.0.1", 0, api.state, environment_map=False)
        try:
            with TestClient(api) as client:
                for case in todo:
                    t0 = time.monotonic()
                    response = _send(client, case, saved, timeout_s)
                    if case.save and response.status_code < 300:
                        saved[case.save] = response.json()["id"]
                    ids = {job_id: f"{{job:{label}}}" for label, job_id in saved.items()}
                    headers = {h: _unid(response.headers[h], ids) for h in RECORDED_HEADERS
                               if h in response.headers}
                    records.append({
                        "name": case.name, "method": case.method, "path": case.path,
                        "body": _body_of(case), "status": response.status_code,
                        "headers": headers, "answer": answer_of(response, ids)})
                    sent.append((case, response.status_code))
                    if verbose:
                        print(f"{time.monotonic() - t0:6.2f} s  {response.status_code}  "
                              f"{case.name}", file=sys.stderr)
                document = client.get("/openapi.json").json()
                kinds = [k["kind"] for k in client.get("/jobs/kinds").json()]
        finally:
            if api.state.viewer is not None:
                api.state.viewer.stop()
    missing = _coverage(document, kinds, sent)
    elapsed = time.monotonic() - start
    snapshot = {"format": FORMAT,
                "meta": {"sources": _sources(), "seconds": round(elapsed, 1),
                         "only": only, "masked": MASKED, "not_covered": missing},
                "records": records}
    out.write_text(json.dumps(snapshot, indent=1, sort_keys=False) + "\n")
    sources = snapshot["meta"]["sources"]
    print(f"{len(records)} requests recorded in {elapsed:.0f} s to {out} "
          f"(app from {sources['app']})")
    if len(set(sources.values())) > 1:
        print(f"warning: the packages come from different checkouts: {sources} (PYTHONPATH?)")
    if not only:
        for what, names in missing.items():
            if names:
                print(f"not covered ({what}): {', '.join(names)}")
    return 0


# ---------------------------------------------------------------------------------------------
# compare


def differences(a: Any, b: Any, path: str = "") -> list[tuple[str, Any, Any]]:
    """Every place where ``a`` and ``b`` (normalised JSON) differ: ``(path, a, b)``, the path
    dotted (``answer.results.0.q.3``); a key on one side only is ``<absent>`` on the other.
    Numbers compare by value (1 and 1.0 are equal); other types must match."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for key in list(a) + [k for k in b if k not in a]:
            sub = f"{path}.{key}" if path else str(key)
            if key not in b:
                out.append((sub, a[key], "<absent>"))
            elif key not in a:
                out.append((sub, "<absent>", b[key]))
            else:
                out += differences(a[key], b[key], sub)
        return out
    if isinstance(a, list) and isinstance(b, list):
        key = _identity(a, b)
        if key is not None:
            # The same items (robots, job kinds...) in another order: one difference for the
            # order, then each item against its namesake, not against its neighbour.
            ka, kb = [x[key] for x in a], [y[key] for y in b]
            out = [] if ka == kb else [(f"{path}.<order of {key}>", ka, kb)]
            by_key = {y[key]: y for y in b}
            for x in a:
                out += differences(x, by_key[x[key]], f"{path}.{x[key]}")
            return out
        out = []
        if len(a) != len(b):
            out.append((f"{path}.<length>", len(a), len(b)))
        for i, (x, y) in enumerate(zip(a, b)):
            out += differences(x, y, f"{path}.{i}")
        return out
    number = (int, float)
    if (isinstance(a, number) and isinstance(b, number) and not isinstance(a, bool)
            and not isinstance(b, bool)):
        return [] if a == b else [(path, a, b)]
    if type(a) is not type(b) or a != b:
        return [(path, a, b)]
    return []


#: Keys that name the items of a list of objects (tried in this order).
IDENTITY_KEYS = ("id", "kind", "name", "$ref")


def _identity(a: list, b: list) -> str | None:
    """The key that names every item of both lists, when they hold the same items, each
    named once, in another order; None otherwise (the lists then compare index by index)."""
    items = a + b
    if not a or not all(isinstance(x, dict) for x in items):
        return None
    for key in IDENTITY_KEYS:
        if not all(isinstance(x.get(key), str) for x in items):
            continue
        ka, kb = [x[key] for x in a], [y[key] for y in b]
        if len(set(ka)) == len(ka) and sorted(ka) == sorted(kb) and ka != kb:
            return key
    return None


def _text_differences(a: str, b: str) -> list[tuple[str, Any, Any]]:
    """Line by line, for text answers (a URDF)."""
    la, lb = a.splitlines(), b.splitlines()
    out = [(f"line {i + 1}", x, y) for i, (x, y) in enumerate(zip(la, lb)) if x != y]
    if len(la) != len(lb):
        out.append(("<lines>", len(la), len(lb)))
    return out


def _short(value: Any, width: int = 160) -> str:
    text = json.dumps(value) if not isinstance(value, str) else value
    return text if len(text) <= width else text[: width - 3] + "..."


def compare(path_a: Path, path_b: Path, limit: int) -> int:
    """Print every difference of the records of two snapshots (by request name); 1 if any."""
    a, b = (json.loads(p.read_text()) for p in (path_a, path_b))
    for snap, p in ((a, path_a), (b, path_b)):
        if snap.get("format") != FORMAT:
            print(f"{p}: not a snapshot of format {FORMAT}")
            return 2
    ra = {r["name"]: r for r in a["records"]}
    rb = {r["name"]: r for r in b["records"]}
    total = 0
    for name in list(ra) + [n for n in rb if n not in ra]:
        if name not in rb or name not in ra:
            side = "b" if name not in rb else "a"
            print(f"== {name}: only in {'a' if side == 'b' else 'b'} (absent from {side})")
            total += 1
            continue
        x, y = ra[name], rb[name]
        found: list[tuple[str, Any, Any]] = []
        for key in ("method", "path", "body", "status", "headers"):
            found += differences(x[key], y[key], key)
        ax, ay = x["answer"], y["answer"]
        if isinstance(ax, dict) and isinstance(ay, dict) and set(ax) == set(ay) == {"text"}:
            found += [(f"answer.text {where}", u, v)
                      for where, u, v in _text_differences(ax["text"], ay["text"])]
        else:
            found += differences(ax, ay, "answer")
        if not found:
            continue
        total += len(found)
        print(f"== {name}: {x['method']} {x['path']}  ({len(found)} differences)")
        for where, u, v in found[: limit or None]:
            width = 10_000 if "<order of" in where else 160   # orders in full
            print(f"   {where}: a={_short(u, width)}  b={_short(v, width)}")
        if limit and len(found) > limit:
            print(f"   ... and {len(found) - limit} more")
    full = [not snap["meta"].get("only") for snap in (a, b)]
    covered = [snap["meta"].get("not_covered") for snap in (a, b)]
    if all(full) and covered[0] != covered[1]:   # a partial record covers little, by design
        print(f"== coverage (not covered): a={covered[0]}  b={covered[1]}")
        total += 1
    print(f"{total} difference(s) between {path_a} ({len(ra)} requests) and {path_b} "
          f"({len(rb)} requests)")
    return 1 if total else 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True)
    rec = sub.add_parser("record", help="send the fixed requests to a fresh app, write OUT")
    rec.add_argument("out", type=Path, nargs="?")
    rec.add_argument("--only", help="comma-separated prefixes of case names (e.g. health,fk.)")
    rec.add_argument("--timeout", type=float, default=180.0,
                     help="seconds to wait for a job to end (%(default)s)")
    rec.add_argument("-v", "--verbose", action="store_true",
                     help="print each request's status and time on stderr")
    rec.add_argument("--list", action="store_true", help="list the case names and exit")
    cmp_ = sub.add_parser("compare", help="print the differences of two records; 1 if any")
    cmp_.add_argument("a", type=Path)
    cmp_.add_argument("b", type=Path)
    cmp_.add_argument("--limit", type=int, default=0,
                      help="differences printed per request (0: all, the default)")
    args = p.parse_args(argv)
    if args.command == "record":
        if args.list:
            print("\n".join(c.name for c in cases()))
            return 0
        if args.out is None:
            p.error("record needs OUT")
        _environment()
        only = [o.strip() for o in args.only.split(",") if o.strip()] if args.only else None
        return record(args.out, only, args.verbose, args.timeout)
    return compare(args.a, args.b, args.limit)


if __name__ == "__main__":
    sys.exit(main())
