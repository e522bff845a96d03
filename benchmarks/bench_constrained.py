"""Constrained motion: upright carrying, Cartesian lines, heavy machines; every answer re-checked.

**Arm problems** (the Panda and the UR5 of ``../shared/robots``, imported as in
``bench_motion.py``), generated here in MotionBenchMaker's scenes (``../shared/mbm-dev/panda``;
the UR5 sees the same scenes moved in front of it as ``mbm_problems.generate_ur5`` moves
them): family ``shelf`` in the ``bookshelf_tall`` scenes (a box taken from one shelf and put
on another), family ``table`` in the ``table_pick`` scenes (a box moved between two places
on the table). Problem ``k`` of a family draws everything from
``numpy.random.default_rng(SeedSequence([--gen-seed, family, robot, k]))`` (``GEN_SEED``,
used by nothing else): the scene (one of the 20), two places A and B (on two different
shelves; or two places on the table top at least 400 mm apart, clear of the objects standing
there), for each a horizontal side grasp of a ``BOX_MM`` box (60 x 60 x 100 mm, upright,
5 mm above the surface, the fingers across it; approach heading within +-15 deg of into the
shelf, +-30 deg of away from the shoulder on the table) solved by numeric IK
(``kinematics.ik.solve_ik``; A's from a drawn configuration, B's started at A's pre-grasp
configuration, so that both ends lie on one IK branch as a cell's program would have them)
and, 200 mm back along the approach, the pre-grasp pose (IK started at the grasp's
configuration). A draw is kept when every configuration is free on
the exact geometry (python-fcl below) with the box where it is at that moment; at most
``ATTEMPTS`` draws per problem. From each problem:

* ``upright``: ``plan_constrained`` from the pre-grasp at A to the pre-grasp at B carrying
  the box (``RobotCollisionModel.with_attached``: the box on the tool link, its hand and
  finger links allowed to touch it), the gripper's vertical axis (the tool-frame axis that is
  world-up at the grasps) within ``TILT`` = 0.1 rad of world up all the way (an ``axis``
  constraint: the orientation constraint that bounds the tilt and leaves the turn about the
  vertical free; ``--time-limit`` 10 s, seed ``--seed`` + k);
* ``approach``: ``plan_line`` 200 mm from the pre-grasp at A to the grasp, orientation held,
  the box standing in the scene between the fingers; ``retreat``: back 200 mm from the grasp
  carrying the box.

**Heavy machines** (built-in models, ``planning.motion.sites`` scenes, capsule collision
models ``RobotCollisionModel.from_model``): ``tunnel`` -- the tunnel drill arm at the
collaring poses (300 mm before the face, ``drill_ik``) of five holes of ``FacePattern()``
(drawn, free), each fed 3 m along its axis by ``plan_line`` (the tunnel without its rock
face, which the holes go into); ``pile`` -- the pile driver lowering its mast (the tool's x
axis) 1 m along the pile's axis, inclined 5-15 deg from vertical: the end drawn (the tip
100-400 mm down in the trench), the start 1 m back up the axis by IK started at the end
(``plan_line``, orientation held; ``--heavy-problems`` of them); ``glt`` -- the GLT
palletizer carrying a 400 x 300 x 250 mm box hanging 10 mm under its flange from 50-200 mm
above the conveyor to 50-200 mm above a pallet's load (start: IK at a drawn yaw; goal: IK
started at the start turned by the waist towards the pallet, so the wrist does not turn a
whole revolution), the tool's z axis within 0.1 rad of straight down (``plan_constrained``,
the box attached, the wrist's last capsule allowed to touch it).

**Independent checks** (not the planner's checker, not its answer's figures): each answered
path is stepped densely (straight joint-space interpolation between consecutive states, no
joint step over ``--step`` = 0.005 rad, x 100 mm on prismatic joints: half the planners'
resolution) and at every state

* the constraint is measured again from forward kinematics: the tilt of the gripper's
  vertical axis (arccos of its world z component) for ``upright`` / ``glt``; for lines the
  distance of the tool point from the ideal segment (mm) and the angle of the tool's
  rotation from the held one (rad); the imported robots' FK is the URDF tree's
  (``ImportedRobot.link_pose``), the built-in machines' ``kinematics.fk.fk_frames``.
  *Worst violation* is the largest excess over the tolerance (0.1 rad; lines
  ``LINE_TOL_MM`` = 1 mm and ``LINE_TOL_RAD`` = 0.01 rad); a line must also end within
  0.1 mm of its target;
* the exact geometry is checked with python-fcl, objects built here: the imported robots'
  collision meshes (``bench_collision.Reference``, the verifier of ``bench_motion.py``) at
  the SRDF's self-collision rules, the built-in machines' capsules (``fcl.Capsule`` between
  the frame origins, the radii and self pairs the collision model declares), the carried box
  as an ``fcl.Box`` on the tool frame (against the scene and every link but the ones it may
  touch), the scene's boxes, cylinders and meshes as ``fcl`` shapes from the scene files.

**OMPL** (python ``ompl`` 2.x), on the same Panda ``upright`` problems in the same run:
RRT-Connect on a ``ProjectedStateSpace`` (ambient: the joint box) with the same constraint
written as an ``ompl.base.Constraint`` (``f(q)`` = the vertical axis's two horizontal
components, Jacobian from ``kinematics.jacobian``; OMPL's projection tolerance
``--ompl-tolerance`` = 0.02, i.e. OMPL holds the axis within about 0.02 rad), validity =
the joint limits (a projection can leave them) and the python-fcl check above with the
box; ``--ompl-time`` (10 s) of search, then ``PathSimplifier.simplify`` for half the limit
within what the search left (at least 0.2 s, as ours), then the path interpolated along its
geodesics (the states a controller would get); checked like ours. Time = search +
simplification.

Printed per family: problems, solved (and fraction), median and p95 planning time (over the
solved), worst violation over every state checked, states checked, paths free on the exact
geometry; then failures with their messages. The machine has 2 cores shared by everyone:
times are noisy.

Run: ``.venv/bin/python benchmarks/bench_constrained.py [--problems 10] [--limit N | --quick]
[--robots panda ur5] [--skip-heavy] [--skip-ompl] [--time-limit 10] [--ompl-time 10]
[--json out.json]`` (``--quick``: 2 problems per family, 2 holes, 5 s limits). Needs
python-fcl, pyyaml, trimesh and ompl. A report: the exit status is 0 in any case.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import fcl
import numpy as np
import yaml
from scipy.spatial.transform import Rotation

sys.path.insert(0, str(Path(__file__).resolve().parent))
import mbm_problems as mbm  # noqa: E402
from bench_collision import Reference, mbm_scene  # noqa: E402

from kinematics.fk import fk, fk_frames  # noqa: E402
from kinematics.ik import solve_ik  # noqa: E402
from kinematics.ik.numeric import NumericOptions  # noqa: E402
from kinematics.jacobian import jacobian_and_pose  # noqa: E402
from kinematics.library import builtin_model  # noqa: E402
from planning.collision import CollisionScene, RobotCollisionModel  # noqa: E402
from planning.motion import MotionChecker  # noqa: E402
from planning.motion.cartesian import plan_line  # noqa: E402
from planning.motion.constraints import plan_constrained  # noqa: E402

#: Seed of the problem generator (used nowhere else).
GEN_SEED = 60221
#: Families: name -> MotionBenchMaker scene folder.
FAMILIES = {"shelf": "bookshelf_tall", "table": "table_pick"}
#: The carried box (mm): along the approach, across the fingers, vertical.
BOX_MM = (60.0, 60.0, 100.0)
GLT_BOX_MM = (400.0, 300.0, 250.0)
TILT = 0.1
LINE_TOL_MM = 1.0
LINE_TOL_RAD = 0.01
END_TOL_MM = 0.1
APPROACH_MM = 200.0
ATTEMPTS = 300
TOUCH = {"panda": ["panda_hand", "panda_leftfinger", "panda_rightfinger", "panda_link7",
                   "panda_link8"],
         "ur5": ["ee_link", "tool0", "fts_robotside", "fts_toolside", "robotiq_85_base_link",
                 "robotiq_85_left_knuckle_link", "robotiq_85_right_knuckle_link",
                 "robotiq_85_left_finger_link", "robotiq_85_right_finger_link",
                 "robotiq_85_left_inner_knuckle_link", "robotiq_85_right_inner_knuckle_link",
                 "robotiq_85_left_finger_tip_link", "robotiq_85_right_finger_tip_link",
                 "wrist_3_link"]}
UP = np.array([0.0, 0.0, 1.0])


# ---- python-fcl geometry ----------------------------------------------------------------------
def fcl_tf(T: np.ndarray) -> fcl.Transform:
    return fcl.Transform(np.asarray(T[:3, :3], float), np.asarray(T[:3, 3], float))


def fcl_object(o) -> fcl.CollisionObject:
    """An FCL object of a ``planning.geometry`` scene object (box, sphere, cylinder, mesh)."""
    if o.type == "box":
        geom = fcl.Box(*o.size)
    elif o.type == "sphere":
        geom = fcl.Sphere(o.radius)
    elif o.type == "cylinder":
        geom = fcl.Cylinder(o.radius, o.height)
    elif o.type == "mesh":
        V = np.asarray(o.vertices, float) * np.asarray(o.scale, float)
        F = np.asarray(o.faces, np.int64)
        geom = fcl.BVHModel()
        geom.beginModel(len(V), len(F))
        geom.addSubModel(V, F)
        geom.endModel()
    else:
        raise ValueError(f"no FCL shape for a {o.type}")
    return fcl.CollisionObject(geom, fcl_tf(np.asarray(o.pose, float)))


def box_object(size, T: np.ndarray) -> fcl.CollisionObject:
    return fcl.CollisionObject(fcl.Box(*size), fcl_tf(T))


def _hit(a, b) -> bool:
    return fcl.collide(a, b, fcl.CollisionRequest(), fcl.CollisionResult())


def _depth(a, b) -> str:
    """How deep ``a`` and ``b`` overlap (FCL's signed distance), as text."""
    d = fcl.distance(a, b, fcl.DistanceRequest(enable_signed_distance=True),
                     fcl.DistanceResult())
    return f" by {-d:.3g} mm" if d < 0 else ""


class ImportedCheck:
    """The imported robot's meshes (``bench_collision.Reference``) + an optional carried box."""

    def __init__(self, robot, touch: list[str]) -> None:
        self.robot = robot
        self.ref = Reference(robot)
        self.tip = robot.link_names.index(robot.tip_link)
        self.touch = {robot.link_names.index(n) for n in touch if n in robot.link_names}
        self.touch.add(self.tip)
        self.extra: list = []

    def set_world(self, objects: list) -> None:
        self.ref.set_scene(objects)

    def poses(self, Q: np.ndarray) -> np.ndarray:
        return self.robot.link_poses(Q)

    def tool(self, P: np.ndarray) -> np.ndarray:
        return P[self.tip]

    def collides(self, P: np.ndarray, load: tuple | None) -> str:
        """'' when free, else the touching pair; ``load = (size, T_tool_box)``."""
        if self.ref.collides(P):
            names = self.robot.link_names
            for k, _, obj in self.ref.objects:
                for j, other in enumerate(self.ref.world):
                    if _hit(obj, other):
                        return f"{names[k]} - scene object {j}{_depth(obj, other)}"
            return "robot self-collision"
        if load is not None:
            box = box_object(load[0], P[self.tip] @ load[1])
            for j, other in enumerate(self.ref.world):
                if _hit(box, other):
                    return f"box - scene object {j}{_depth(box, other)}"
            for k, _, obj in self.ref.objects:
                if k not in self.touch and _hit(box, obj):
                    return f"box - {self.robot.link_names[k]}"
        return ""


class CapsuleCheck:
    """A built-in machine's capsules (radii and self pairs as the collision model declares
    them) + an optional carried box, posed by ``fk_frames``."""

    def __init__(self, model, cm, touch: list[int]) -> None:
        self.model = model
        self.links = [int(k) for k in cm.capsule_link]
        self.radii = [float(r) for r in cm.capsule_radius]
        self.pairs = [tuple(int(v) for v in p) for p in np.asarray(cm.pairs).reshape(-1, 2)]
        self.touch = set(touch) | {model.dof - 1}
        self.world: list = []

    def set_world(self, objects: list) -> None:
        self.world = objects

    def poses(self, Q: np.ndarray) -> np.ndarray:
        return fk_frames(self.model, Q)

    def tool(self, P: np.ndarray) -> np.ndarray:
        return P[-1]

    def _capsules(self, P: np.ndarray) -> list:
        out = []
        for k, r in zip(self.links, self.radii):
            a, b = P[k][:3, 3], P[k + 1][:3, 3]
            d = b - a
            L = float(np.linalg.norm(d))
            z = d / L if L > 1e-9 else np.array([0.0, 0.0, 1.0])
            x = np.cross(z, [1.0, 0, 0]) if abs(z[0]) < 0.9 else np.cross(z, [0, 1.0, 0])
            x /= np.linalg.norm(x)
            T = np.eye(4)
            T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
            T[:3, 3] = (a + b) / 2
            out.append(fcl.CollisionObject(fcl.Capsule(r, max(L, 1e-6)), fcl_tf(T)))
        return out

    def collides(self, P: np.ndarray, load: tuple | None) -> str:
        caps = self._capsules(P)
        for c, k in zip(caps, self.links):
            for j, other in enumerate(self.world):
                if _hit(c, other):
                    return f"link{k} - scene object {j}{_depth(c, other)}"
        for i, j in self.pairs:
            if _hit(caps[i], caps[j]):
                return f"link{self.links[i]} - link{self.links[j]}"
        if load is not None:
            box = box_object(load[0], P[-1] @ load[1])
            for j, other in enumerate(self.world):
                if _hit(box, other):
                    return f"box - scene object {j}{_depth(box, other)}"
            for c, k in zip(caps, self.links):
                if k not in self.touch and _hit(box, c):
                    return f"box - link{k}"
        return ""


# ---- dense re-check ---------------------------------------------------------------------------
def dense(path: np.ndarray, step: np.ndarray) -> np.ndarray:
    """The path's states and, between consecutive ones, straight joint-space states no
    joint farther than ``step (dof,)`` from the next."""
    out = [path[:1]]
    for a, b in zip(path[:-1], path[1:]):
        n = max(1, math.ceil(float(np.max(np.abs(b - a) / step)) - 1e-12))
        t = np.arange(1, n + 1)[:, None] / n
        out.append(a + t * (b - a))
    return np.concatenate(out)


def tilt_of(T: np.ndarray, axis: np.ndarray, direction: np.ndarray) -> float:
    v = T[:3, :3] @ axis
    return float(np.arccos(np.clip(v @ direction / np.linalg.norm(v), -1.0, 1.0)))


@dataclass
class Check:
    """What the dense re-check found."""

    states: int = 0
    worst: float = 0.0          # largest excess over the tolerance (0: within everywhere)
    worst_error: float = 0.0    # largest measured deviation (rad, or mm for lines)
    worst_angle: float = 0.0    # lines: largest rotation from the held one (rad)
    free: bool = True
    why: str = ""


def recheck(checker, path, step: np.ndarray, load: tuple | None, measure, lower, upper
            ) -> Check:
    """Every dense state: within the joint limits, free on the exact geometry, and measured
    by ``measure(T_tool) -> (excess, error, angle)``."""
    path = np.asarray(path, float)
    out = Check()
    if path.ndim != 2 or len(path) < 1 or not np.all(np.isfinite(path)):
        return Check(free=False, why="no usable path")
    Q = dense(path, step)
    out.states = len(Q)
    over = np.maximum(lower - Q, Q - upper)
    if np.any(over > 1e-9):
        k, j = np.unravel_index(int(np.argmax(over)), over.shape)
        out.free = False
        out.why = (f"state {k}/{len(Q)} outside the joint limits: joint {j} by "
                   f"{over[k, j]:.3g}")
    for i in range(0, len(Q), 256):
        poses = checker.poses(Q[i:i + 256])
        for k, P in enumerate(poses):
            excess, err, ang = measure(checker.tool(P))
            out.worst = max(out.worst, excess)
            out.worst_error = max(out.worst_error, err)
            out.worst_angle = max(out.worst_angle, ang)
            if out.free:
                why = checker.collides(P, load)
                if why:
                    out.free, out.why = False, f"state {i + k}/{len(Q)}: {why}"
    return out


def tilt_measure(axis: np.ndarray, direction: np.ndarray):
    def m(T):
        t = tilt_of(T, axis, direction)
        return max(t - TILT, 0.0), t, 0.0
    return m


def line_measure(T0: np.ndarray, T1: np.ndarray):
    """Distance of the tool point from the segment T0-T1 (mm) and its rotation from T0's."""
    p0, p1 = T0[:3, 3], T1[:3, 3]
    u = p1 - p0
    L2 = float(u @ u)
    R0 = T0[:3, :3]

    def m(T):
        p = T[:3, 3]
        s = min(1.0, max(0.0, float((p - p0) @ u) / L2))
        d = float(np.linalg.norm(p - (p0 + s * u)))
        ang = float(np.linalg.norm(Rotation.from_matrix(R0.T @ T[:3, :3]).as_rotvec()))
        return max(d - LINE_TOL_MM, ang - LINE_TOL_RAD, 0.0), d, ang
    return m


# ---- rows --------------------------------------------------------------------------------------
@dataclass
class Row:
    robot: str
    family: str
    index: int
    planner: str = "ours"
    status: str = "-"
    message: str = ""
    time_s: float | None = None
    states: int = 0
    worst: float | None = None
    worst_error: float | None = None
    worst_angle: float | None = None
    end_mm: float | None = None
    free: bool | None = None
    why: str = ""
    extra: dict = field(default_factory=dict)

    @property
    def solved(self) -> bool:
        return self.status == "ok"


def fill(row: Row, c: Check, checker=None, path=None) -> None:
    """The re-check's findings into ``row``; for a path not free, what the planner's own
    checker says of it at its resolution (0.01) and at the re-check's states."""
    row.states, row.worst, row.worst_error = c.states, c.worst, c.worst_error
    row.worst_angle, row.free, row.why = c.worst_angle, c.free, c.why
    if path is not None and len(path) > 1:
        steps = np.max(np.abs(np.diff(np.asarray(path, float), axis=0)), axis=1)
        row.extra["max_joint_step"] = float(steps.max())
        row.extra["at_state"] = int(steps.argmax())
    if not c.free and checker is not None and path is not None:
        row.why += (f" (the planner's own checker: path_free at 0.01 = "
                    f"{checker.path_free(path, 0.01)}, at 0.005 = "
                    f"{checker.path_free(path, 0.005)})")


# ---- arm problems ------------------------------------------------------------------------------
@dataclass
class ArmProblem:
    family: str
    index: int
    scene_data: dict
    world: list                  # fcl objects of the scene
    box_A: np.ndarray            # (4, 4) the box's pose at A (mm)
    T_grasp: np.ndarray          # tool pose at the grasp at A
    T_pre: np.ndarray            # tool pose 200 mm back
    q_pre_A: np.ndarray
    q_grasp_A: np.ndarray
    q_pre_B: np.ndarray
    axis: np.ndarray             # tool-frame vertical axis
    T_tool_box: np.ndarray


class Arm:
    """One imported robot: its check, tool/grasp geometry and IK."""

    def __init__(self, name: str, panda) -> None:
        self.name = name
        self.robot = panda if name == "panda" else mbm.import_named(name)
        self.model = self.robot.model
        self.check = ImportedCheck(self.robot, TOUCH[name])
        q = (self.model.lower + self.model.upper) / 2
        tip = self.robot.link_pose(self.robot.tip_link, q)
        if name == "panda":
            gt = self.robot.link_pose("panda_grasptarget", q)
            self.T_tip_grasp = np.linalg.inv(tip) @ gt
        else:
            self.T_tip_grasp = np.eye(4)
            self.T_tip_grasp[0, 3] = mbm.GRASP_DEPTH
        if name == "ur5":
            T_base = np.array(self.model.base, float)
            self.T_scene = T_base @ np.array([[1, 0, 0, 0], [0, 1, 0, 0],
                                              [0, 0, 1, (mbm.UR5_SHOULDER - mbm.PANDA_SHOULDER)
                                               * 1000.0], [0, 0, 0, 1.0]])
            self.shoulder = (T_base @ np.array([0, 0, mbm.UR5_SHOULDER * 1000.0, 1]))[:3]
        else:
            self.T_scene = np.eye(4)
            self.shoulder = np.array([0.0, 0.0, 333.0])

    def grasp_frame(self, centre: np.ndarray, approach: np.ndarray) -> np.ndarray:
        """``T_world_grasp``: approach ``a`` (horizontal), the fingers closing across it
        (horizontal), in the robot's grasp-frame convention."""
        a = approach / np.linalg.norm(approach)
        c = np.cross(UP, a)
        G = np.eye(4)
        if self.name == "panda":                       # hand: z approach, y closing
            G[:3, :3] = np.column_stack([np.cross(c, a), c, a])
        else:                                          # ee_link: x approach, y closing
            G[:3, :3] = np.column_stack([a, c, np.cross(a, c)])
        G[:3, 3] = centre
        return G @ np.linalg.inv(self.T_tip_grasp)

    def ik(self, T: np.ndarray, rng, q0=None, within: float | None = 1.5
           ) -> np.ndarray | None:
        """A solution of ``T`` within the limits, by numeric IK from ``q0`` (default drawn);
        with ``q0`` and ``within``, no joint farther than that from ``q0``."""
        m = self.model
        opts = NumericOptions(seed=int(rng.integers(2**31)), restarts=8)
        start = rng.uniform(m.lower, m.upper) if q0 is None else q0
        r = solve_ik(m, T, method="numeric", q0=start, options=opts)[0]
        if not r.success:
            return None
        q = np.asarray(r.q, float)
        if np.any(q < m.lower) or np.any(q > m.upper):
            return None
        Tq = self.robot.link_pose(self.robot.tip_link, q)
        if np.linalg.norm(Tq[:3, 3] - T[:3, 3]) > 1e-3 or np.linalg.norm(
                Rotation.from_matrix(Tq[:3, :3].T @ T[:3, :3]).as_rotvec()) > 1e-6:
            return None
        if q0 is not None and within is not None and np.max(np.abs(q - q0)) > within:
            return None
        return q

    def free(self, q, load=None) -> bool:
        return self.check.collides(self.robot.link_poses(q), load) == ""


def _moveit_data(arm: Arm, path: Path) -> dict:
    data = yaml.safe_load(path.read_text())
    if arm.name == "ur5":
        T = arm.T_scene.copy()
        T[:3, 3] /= 1000.0
        data = mbm.moved_scene(data, T, "ur5")
    return data


def _world(data: dict) -> list:
    with tempfile.NamedTemporaryFile("w", suffix=".yaml", delete=False) as f:
        yaml.safe_dump(data, f)
    try:
        return mbm_scene(Path(f.name))[0]
    finally:
        os.unlink(f.name)


def _places(arm: Arm, family: str, objects: list, rng, world: list):
    """A place on a surface: (box centre (3,), approach direction (3,)) or None."""
    if family == "shelf":
        shelves = [o for o in objects if o["id"].startswith("shelf_") and o["id"] != "shelf_top"]
        o = shelves[int(rng.integers(len(shelves)))]
        T = np.asarray(o["pose"], float)
        sx, sy, sz = o["size"]
        s = 1.0 if T[:3, 0] @ (arm.shoulder - T[:3, 3]) > 0 else -1.0
        local = np.array([s * (sx / 2 - rng.uniform(80.0, 220.0)),
                          rng.uniform(-0.38, 0.38) * sy, sz / 2 + 5.0 + BOX_MM[2] / 2])
        centre = T[:3, :3] @ local + T[:3, 3]
        inward = -s * T[:3, 0]
        jitter = math.radians(rng.uniform(-15.0, 15.0))
        key = o["id"]
    else:
        o = next(o for o in objects if o["id"] == "table_top")
        T = np.asarray(o["pose"], float)
        sx, sy, sz = o["size"]
        towards = math.atan2(T[1, 3] - arm.shoulder[1], T[0, 3] - arm.shoulder[0])
        d, phi = rng.uniform(350.0, 750.0), towards + rng.uniform(-1.2, 1.2)
        inward = np.array([math.cos(phi), math.sin(phi), 0.0])
        centre = arm.shoulder + d * inward
        local = T[:3, :3].T @ (centre - T[:3, 3])
        if abs(local[0]) > sx / 2 - 100 or abs(local[1]) > sy / 2 - 100:
            return None
        centre = T[:3, :3] @ np.array([local[0], local[1], sz / 2 + 5.0 + BOX_MM[2] / 2]) \
            + T[:3, 3]
        jitter = math.radians(rng.uniform(-30.0, 30.0))
        key = centre
    c, s_ = math.cos(jitter), math.sin(jitter)
    a = np.array([c * inward[0] - s_ * inward[1], s_ * inward[0] + c * inward[1], 0.0])
    B = np.eye(4)
    B[:3, :3] = np.column_stack([a, np.cross(UP, a), UP])
    B[:3, 3] = centre
    big = box_object([BOX_MM[0] + 40.0, BOX_MM[1] + 40.0, BOX_MM[2]], B)   # 20 mm clear
    if any(_hit(big, w) for w in world):
        return None
    return centre, a, key


def make_problem(arm: Arm, family: str, robot_no: int, k: int, seed: int) -> ArmProblem | None:
    from planning.collision.moveit import scene_from_moveit

    rng = np.random.default_rng(np.random.SeedSequence(
        [seed, list(FAMILIES).index(family), robot_no, k]))
    scene_no = int(rng.integers(1, 21))
    path = mbm.PANDA_FOLDER / FAMILIES[family] / f"scene{scene_no:04d}.yaml"
    data = _moveit_data(arm, path)
    world = _world(data)
    objects = scene_from_moveit(data)
    arm.check.set_world(world)

    def side(avoid=None):
        """A place, its grasp and pre-grasp configurations, free with the box as it is."""
        for _ in range(ATTEMPTS):
            P = _places(arm, family, objects, rng, world)
            if P is None or (avoid is not None and (
                    (family == "shelf" and P[2] == avoid[0][2])
                    or (family == "table" and np.linalg.norm(P[0] - avoid[0][0]) < 400.0))):
                continue
            T = arm.grasp_frame(P[0], P[1])
            box = np.eye(4)
            box[:3, :3] = np.column_stack([P[1], np.cross(UP, P[1]), UP])
            box[:3, 3] = P[0]
            load = (BOX_MM, np.linalg.inv(T) @ box)
            pre = T.copy()
            pre[:3, 3] -= APPROACH_MM * P[1]
            # B's grasp by IK from A's pre-grasp configuration (the arm stays on its branch)
            q = arm.ik(T, rng) if avoid is None else arm.ik(T, rng, avoid[1], None)
            if q is None or not arm.free(q, load):
                continue
            if avoid is None:
                arm.check.set_world(world + [box_object(BOX_MM, box)])
                ok = arm.free(q)                          # fingers round the standing box
                arm.check.set_world(world)
                if not ok:
                    continue
            q_pre = arm.ik(pre, rng, q)
            if q_pre is None or not arm.free(q_pre, load):
                continue
            return P, T, pre, box, load, q, q_pre
        return None

    A = side()
    if A is None:
        return None
    B = side((A[0], A[6]))
    if B is None:
        return None
    P, T_A, preA, box_A, load, qA, q_preA = A
    axis = T_A[:3, :3].T @ UP
    return ArmProblem(family, k, data, world, box_A, T_A, preA, q_preA, qA, B[6], axis,
                      load[1])


def load_dict(T_tool_box: np.ndarray, size, touch: list[str]) -> dict:
    return {"object": {"type": "box", "id": "load", "size": list(size)}, "link": "tool",
            "pose": T_tool_box.tolist(), "touch_links": touch}


def run_arm(arm: Arm, robot_no: int, args, cm) -> list[Row]:
    rows: list[Row] = []
    m = arm.model
    step = np.full(m.dof, args.step)
    touch = [n for n in TOUCH[arm.name] if n in arm.robot.link_names]
    for family in FAMILIES:
        made = 0
        for k in range(1, 3 * args.problems + 1):
            if made == args.problems:
                break
            t = time.perf_counter()
            p = make_problem(arm, family, robot_no, k, args.gen_seed)
            gen_s = time.perf_counter() - t
            if p is None:
                print(f"  {arm.name} {family}/{k}: no problem found in {ATTEMPTS} draws; "
                      "the next number takes its place")
                continue
            made += 1
            load = (BOX_MM, p.T_tool_box)
            scene = CollisionScene.from_moveit(p.scene_data)
            cma = cm.with_attached([load_dict(p.T_tool_box, BOX_MM, touch)])
            carrying = MotionChecker(cma, scene)
            empty_with_box = MotionChecker(cm, CollisionScene(
                scene.objects + CollisionScene.from_dicts([{
                    "type": "box", "id": "load", "size": list(BOX_MM),
                    "pose": p.box_A.tolist()}]).objects, scene.mesh_resolution))
            # upright move
            spec = [{"type": "axis", "direction": [0.0, 0.0, 1.0], "tolerance": TILT,
                     "axis": p.axis.tolist()}]
            row = Row(arm.name, f"{family} upright", k)
            res = plan_constrained(carrying, p.q_pre_A, p.q_pre_B, spec,
                                   time_limit=args.time_limit, seed=args.seed + k)
            row.status, row.message, row.time_s = str(res.status), res.message, \
                res.planning_time_s
            row.extra = {"generated_s": gen_s, "waypoints": len(res.path),
                         "planner_worst_violation": res.worst_violation}
            arm.check.set_world(p.world)
            if res.success:
                fill(row, recheck(arm.check, res.path, step, load,
                                  tilt_measure(p.axis, UP), m.lower, m.upper),
                     carrying, res.path)
            rows.append(row)
            report(row)
            if arm.name == "panda" and not args.skip_ompl:
                o = Row(arm.name, f"{family} upright", k, planner="ompl")
                res_o = ompl_upright(arm, p, load, args)
                o.status, o.time_s = res_o["status"], res_o["time_s"]
                o.extra = {"plan_s": res_o["plan_s"], "simplify_s": res_o["simplify_s"]}
                if res_o["path"] is not None:
                    fill(o, recheck(arm.check, res_o["path"], step, load,
                                    tilt_measure(p.axis, UP), m.lower, m.upper))
                rows.append(o)
                report(o)
            # approach (box standing at A) and retreat (carrying it)
            for kind, checker, q0, _T0, T1, ld in (
                    ("approach", empty_with_box, p.q_pre_A, p.T_pre, p.T_grasp, None),
                    ("retreat", carrying, p.q_grasp_A, p.T_grasp, p.T_pre, load)):
                row = Row(arm.name, f"{family} {kind}", k)
                res = plan_line(checker, q0, T1, orientation="hold")
                row.status, row.message, row.time_s = str(res.status), res.message, \
                    res.planning_time_s
                T_start = arm.robot.link_pose(arm.robot.tip_link, q0)
                world = p.world + ([box_object(BOX_MM, p.box_A)] if ld is None else [])
                arm.check.set_world(world)
                if res.success:
                    fill(row, recheck(arm.check, res.path, step, ld,
                                      line_measure(T_start, T1), m.lower, m.upper),
                         checker, res.path)
                    row.extra["planner_deviation_mm"] = float(res.deviation)
                    end = arm.robot.link_pose(arm.robot.tip_link, res.path[-1])
                    row.end_mm = float(np.linalg.norm(end[:3, 3] - T1[:3, 3]))
                rows.append(row)
                report(row)
    return rows


# ---- OMPL ---------------------------------------------------------------------------------------
def ompl_upright(arm: Arm, p: ArmProblem, load, args) -> dict:
    """OMPL RRT-Connect on a ProjectedStateSpace with the upright constraint, FCL validity."""
    from ompl import base as ob
    from ompl import geometric as og

    m = arm.model
    dof = m.dof
    axis = p.axis
    class Upright(ob.Constraint):
        """f(q) = the horizontal components of the tool's vertical axis (0: upright)."""

        def __init__(self) -> None:
            super().__init__(dof, 2, args.ompl_tolerance)

        def function(self, x, out):
            T = fk(m, np.asarray(x, float))
            v = T[:3, :3] @ axis
            out[0], out[1] = v[0], v[1]

        def jacobian(self, x, out):
            J, T = jacobian_and_pose(m, np.asarray(x, float))
            v = T[:3, :3] @ axis
            dv = np.cross(J[3:].T, v)          # (dof, 3): w_i x v
            out[0, :] = dv[:, 0]
            out[1, :] = dv[:, 1]

    space = ob.RealVectorStateSpace(dof)
    bounds = ob.RealVectorBounds(dof)
    for i in range(dof):
        bounds.setLow(i, float(m.lower[i]))
        bounds.setHigh(i, float(m.upper[i]))
    space.setBounds(bounds)
    constraint = Upright()
    css = ob.ProjectedStateSpace(space, constraint)
    csi = ob.ConstrainedSpaceInformation(css)
    ss = og.SimpleSetup(csi)

    def valid(s) -> bool:
        q = np.array([s[i] for i in range(dof)])
        if np.any(q < m.lower) or np.any(q > m.upper):     # projection may leave the box
            return False
        return arm.check.collides(arm.robot.link_poses(q), load) == ""

    arm.check.set_world(p.world)
    ss.setStateValidityChecker(valid)
    s0, s1 = css.allocState(), css.allocState()
    s0.copy([float(v) for v in p.q_pre_A])
    s1.copy([float(v) for v in p.q_pre_B])
    ss.setStartAndGoalStates(s0, s1)
    ss.setPlanner(og.RRTConnect(csi))
    t = time.perf_counter()
    ss.solve(args.ompl_time)
    plan_s = time.perf_counter() - t
    out = {"status": "ok" if ss.haveExactSolutionPath() else "timeout", "plan_s": plan_s,
           "simplify_s": 0.0, "time_s": plan_s, "path": None}
    if out["status"] == "ok":
        path = ss.getSolutionPath()
        t = time.perf_counter()
        # as ours: half the limit within what the search left, at least 0.2 s
        budget = max(0.2, min(0.5 * args.ompl_time, args.ompl_time - plan_s))
        og.PathSimplifier(csi).simplify(path, budget, False)
        out["simplify_s"] = time.perf_counter() - t
        out["time_s"] = plan_s + out["simplify_s"]
        path.interpolate()
        out["path"] = np.array([[path.getState(i)[j] for j in range(dof)]
                                for i in range(path.getStateCount())])
    return out


# ---- heavy machines ---------------------------------------------------------------------------
def heavy_rows(args) -> list[Row]:
    from kinematics.drilling import drill_ik
    from planning.motion.sites import pallet_station, pile_driver_site, tunnel_site
    from planning.sequencing.patterns import FacePattern, face_pattern

    rows: list[Row] = []
    rng = np.random.default_rng(np.random.SeedSequence([args.gen_seed, 100]))

    def setup(name):
        model = builtin_model(name)
        cm = RobotCollisionModel.from_model(model)
        step = np.where([j.revolute for j in model.joints], args.step, args.step * 100.0)
        return model, cm, step

    def world_of(scene):
        return [fcl_object(o) for o in scene.objects]

    # tunnel arm: 3 m feed along five holes
    model, cm, step = setup("tunnel_drill_arm")
    scene = tunnel_site(face=False)
    checker = MotionChecker(cm, scene)
    ref = CapsuleCheck(model, cm, [])
    ref.set_world(world_of(scene))
    face = face_pattern(FacePattern())
    H = face.holes.copy()
    H[:, 0] -= 300.0
    res = drill_ik(model, H)
    usable = [i for i, r in enumerate(res) if r.q is not None and checker.free(r.q)
              and ref.collides(fk_frames(model, r.q), None) == ""]
    chosen = rng.choice(usable, size=min(args.holes, len(usable)), replace=False)
    for n, i in enumerate(chosen, start=1):
        q0 = np.asarray(res[i].q, float)
        T0 = fk(model, q0)
        T1 = T0.copy()
        T1[:3, 3] += 3000.0 * T0[:3, 2]
        rows.append(heavy_line(Row("tunnel_drill_arm", "tunnel feed 3 m", n,
                                   extra={"hole": int(i), "kind": face.kinds[i]}),
                               checker, ref, model, q0, T0, T1, step))

    # pile driver: lower the mast 1 m along an inclined pile axis
    model, cm, step = setup("pile_driver")
    scene = pile_driver_site(model)
    checker = MotionChecker(cm, scene)
    ref = CapsuleCheck(model, cm, [])
    ref.set_world(world_of(scene))
    obj = {o.id: o for o in scene.objects}
    bottom, ground = obj["trench_bottom"], obj["ground_near"]
    gz = float(ground.pose[2, 3] + ground.size[2] / 2)
    a_x = float(bottom.pose[0, 3] - bottom.size[0] / 2)
    b_x = float(bottom.pose[0, 3] + bottom.size[0] / 2)
    made = 0
    for _ in range(50):
        if made == args.heavy_problems:
            break
        # the end: the mast (tool x) 5-15 deg off vertical, its tip 100-400 mm down into
        # the trench; the start: the same pose 1 m back up the mast's axis, by IK from it
        Q = rng.uniform(model.lower, model.upper, size=(20000, model.dof))
        T = fk(model, Q)
        x = T[:, :3, 0]
        incline = np.degrees(np.arccos(np.clip(-x[:, 2], -1.0, 1.0)))
        h = T[:, 2, 3] - gz
        ok = (incline > 5.0) & (incline < 15.0) & (h > -400.0) & (h < -100.0) \
            & (T[:, 0, 3] > a_x + 120.0) & (T[:, 0, 3] < b_x - 120.0)
        for i in np.flatnonzero(ok)[:20]:
            q1 = Q[i]
            if not checker.free(q1) or ref.collides(fk_frames(model, q1), None):
                continue
            T0 = T[i].copy()
            T0[:3, 3] -= 1000.0 * T[i][:3, 0]
            opts = NumericOptions(seed=int(rng.integers(2**31)), restarts=4)
            r = solve_ik(model, T0, method="numeric", q0=q1, options=opts)[0]
            if not r.success:
                continue
            q0 = np.asarray(r.q, float)
            if np.any(q0 < model.lower) or np.any(q0 > model.upper) \
                    or np.max(np.abs(q0 - q1)) > 1.5 or not checker.free(q0) \
                    or ref.collides(fk_frames(model, q0), None) \
                    or np.linalg.norm(fk(model, q0)[:3, 3] - T0[:3, 3]) > 1e-2:
                continue
            T0 = fk(model, q0)
            made += 1
            rows.append(heavy_line(Row("pile_driver", "pile lower 1 m", made,
                                       extra={"incline_deg": float(incline[i])}),
                                   checker, ref, model, q0, T0, T[i], step))
            break

    # GLT palletizer: a box carried level from the conveyor to a pallet
    model, cm, step = setup("glt_palletizer")
    scene = pallet_station(model)
    T_tool_box = np.eye(4)
    T_tool_box[2, 3] = GLT_BOX_MM[2] / 2 + 10.0
    touch = [f"link{model.dof - 2}"]
    cma = cm.with_attached([load_dict(T_tool_box, GLT_BOX_MM, touch)])
    checker = MotionChecker(cma, scene)
    ref = CapsuleCheck(model, cm, [model.dof - 2])
    ref.set_world(world_of(scene))
    load = (GLT_BOX_MM, T_tool_box)
    obj = {o.id: o for o in scene.objects}
    loads = [o for o in scene.objects if o.id.startswith("load_")]

    def above(o, rng, q_ref=None):
        """A configuration holding the box level 50-200 mm above ``o``; with ``q_ref``,
        IK from it turned by the waist towards the place (no wrist turn in between)."""
        for _ in range(200):
            T = np.asarray(o.pose, float)
            half = np.asarray(o.size) / 2 - 250.0
            local = np.array([rng.uniform(-half[0], half[0]), rng.uniform(-half[1], half[1]),
                              o.size[2] / 2 + rng.uniform(50.0, 200.0) + GLT_BOX_MM[2] + 10.0])
            p = T[:3, :3] @ local + T[:3, 3]
            q0 = None
            if q_ref is None:
                yaw = rng.uniform(-math.pi, math.pi)
            else:
                T_ref = fk(model, q_ref)
                turn = math.atan2(p[1], p[0]) - math.atan2(T_ref[1, 3], T_ref[0, 3])
                yaw = math.atan2(T_ref[1, 0], T_ref[0, 0]) + turn
                q0 = q_ref.copy()
                q0[0] = q_ref[0] + (turn + math.pi) % (2 * math.pi) - math.pi
            Tt = np.eye(4)
            Tt[:3, :3] = Rotation.from_euler("z", yaw).as_matrix() @ np.diag([1.0, -1.0, -1.0])
            Tt[:3, 3] = p
            opts = NumericOptions(seed=int(rng.integers(2**31)), restarts=16)
            r = solve_ik(model, Tt, method="numeric", q0=q0, options=opts)[0]
            if not r.success:
                continue
            q = np.asarray(r.q, float)
            if q_ref is not None and np.max(np.abs(q - q0)[1:]) > 1.0:
                continue
            if np.any(q < model.lower) or np.any(q > model.upper) or not checker.free(q) \
                    or ref.collides(fk_frames(model, q), load) \
                    or tilt_of(fk(model, q), np.array([0, 0, 1.0]), -UP) > 1e-6:
                continue
            return q
        return None

    for n in range(1, args.heavy_problems + 1):
        qs = above(obj["conveyor"], rng)
        qg = None if qs is None else above(loads[(n - 1) % len(loads)], rng, qs)
        row = Row("glt_palletizer", "glt box level", n)
        if qs is None or qg is None:
            row.status, row.message = "no_problem", "no free start or goal found"
            rows.append(row)
            report(row)
            continue
        spec = [{"type": "axis", "direction": [0.0, 0.0, -1.0], "tolerance": TILT,
                 "axis": [0.0, 0.0, 1.0]}]
        res = plan_constrained(checker, qs, qg, spec, time_limit=args.time_limit,
                               seed=args.seed + 500 + n)
        row.status, row.message, row.time_s = str(res.status), res.message, \
            res.planning_time_s
        if res.success:
            fill(row, recheck(ref, res.path, step, load,
                              tilt_measure(np.array([0, 0, 1.0]), -UP), model.lower,
                              model.upper), checker, res.path)
        rows.append(row)
        report(row)
    return rows


def heavy_line(row: Row, checker, ref, model, q0, T0, T1, step) -> Row:
    res = plan_line(checker, q0, T1, orientation="hold")
    row.status, row.message, row.time_s = str(res.status), res.message, res.planning_time_s
    row.extra["fraction"] = float(res.fraction)
    if res.success:
        fill(row, recheck(ref, res.path, step, None, line_measure(T0, T1), model.lower,
                          model.upper), checker, res.path)
        row.extra["planner_deviation_mm"] = float(res.deviation)
        row.end_mm = float(np.linalg.norm(fk(model, res.path[-1])[:3, 3] - T1[:3, 3]))
    report(row)
    return row


# ---- report ------------------------------------------------------------------------------------
def report(r: Row) -> None:
    text = f"  {r.robot:<16} {r.family:<18} {r.index:>3} {r.planner:<5} {r.status:<12}"
    if r.time_s is not None:
        text += f" {r.time_s * 1e3:9.1f} ms"
    if r.solved:
        unit = "mm" if "upright" not in r.family and "glt" not in r.family else "rad"
        text += (f" | {r.states} states, worst {r.worst_error:.4g} {unit}"
                 + (f" / {r.worst_angle:.2g} rad" if unit == "mm" else "")
                 + f", excess {r.worst:.3g}, {'free' if r.free else 'NOT FREE: ' + r.why}")
        if r.end_mm is not None:
            text += f", end {r.end_mm:.3g} mm"
    elif r.message:
        text += f" ({r.message[:140]})"
    print(text, flush=True)


def pct(values, q):
    v = [x for x in values if x is not None]
    return float(np.percentile(v, q)) if v else None


def fmt(v, scale=1.0, digits=1):
    return "-" if v is None else f"{v * scale:.{digits}f}"


def table(rows: list[Row]) -> None:
    print("\n| robot | family | planner | problems | solved | median ms | p95 ms | worst "
          "deviation (independent) | tolerance | worst excess | states checked | free on "
          "exact geometry |")
    print("|" + "---|" * 12)
    keys = list(dict.fromkeys((r.robot, r.family, r.planner) for r in rows))
    for robot, family, planner in keys:
        g = [r for r in rows if (r.robot, r.family, r.planner) == (robot, family, planner)]
        s = [r for r in g if r.solved]
        lines = "upright" not in family and "glt" not in family
        tol = f"{LINE_TOL_MM:g} mm, {LINE_TOL_RAD:g} rad" if lines else f"{TILT:g} rad"
        worst = "-" if not s else (
            f"{max(r.worst_error for r in s):.3g} mm, {max(r.worst_angle for r in s):.2g} rad"
            if lines else f"{max(r.worst_error for r in s):.4f} rad")
        ends = [r.end_mm for r in s if r.end_mm is not None]
        if ends:
            worst += f" (end {max(ends):.2g} mm)"
        print(f"| {robot} | {family} | {planner} | {len(g)} | {len(s)}/{len(g)} "
              f"({len(s) / len(g):.0%}) | {fmt(pct([r.time_s for r in s], 50), 1e3)} | "
              f"{fmt(pct([r.time_s for r in s], 95), 1e3)} | {worst} | {tol} | "
              f"{fmt(max((r.worst for r in s), default=None), 1, 3)} | "
              f"{sum(r.states for r in s)} | {sum(bool(r.free) for r in s)}/{len(s)} |")
    fails = [r for r in rows if not r.solved or not r.free or (r.worst or 0) > 0
             or (r.end_mm or 0) > END_TOL_MM]
    print(f"\nFailures or findings ({len(fails)}):")
    for r in fails:
        what = f"{r.status}: {r.message}" if not r.solved else (
            f"NOT FREE: {r.why}" if not r.free else
            f"worst excess {r.worst:.3g}, end {r.end_mm} mm")
        print(f"  {r.robot} {r.family} {r.index} {r.planner}: {what}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--robots", nargs="*", default=["panda", "ur5"])
    parser.add_argument("--problems", type=int, default=10, help="problems per family")
    parser.add_argument("--limit", type=int, default=None, help="as --problems (short runs)")
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--holes", type=int, default=5)
    parser.add_argument("--heavy-problems", type=int, default=5)
    parser.add_argument("--time-limit", type=float, default=10.0)
    parser.add_argument("--ompl-time", type=float, default=10.0)
    parser.add_argument("--ompl-tolerance", type=float, default=0.02)
    parser.add_argument("--ompl-seed", type=int, default=4243)
    parser.add_argument("--seed", type=int, default=1414)
    parser.add_argument("--gen-seed", type=int, default=GEN_SEED)
    parser.add_argument("--step", type=float, default=0.005)
    parser.add_argument("--skip-ompl", action="store_true")
    parser.add_argument("--skip-heavy", action="store_true")
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    if args.limit is not None:
        args.problems = args.limit
    if args.quick:
        args.problems = min(args.problems, 2)
        args.holes, args.heavy_problems = 2, 2
        args.time_limit, args.ompl_time = 5.0, 5.0
    if not args.skip_ompl:
        from ompl import util as ou

        ou.setLogLevel(ou.LOG_NONE)
        ou.RNG.setSeed(args.ompl_seed)
    rows: list[Row] = []
    panda = mbm.import_named("panda")
    for name in args.robots:
        t = time.perf_counter()
        arm = Arm(name, panda)
        cm = RobotCollisionModel.from_imported(arm.robot)
        print(f"== {name}: imported and collision model built in "
              f"{time.perf_counter() - t:.1f} s")
        rows += run_arm(arm, ["panda", "ur5"].index(name), args, cm)
    if not args.skip_heavy:
        print("== heavy machines")
        rows += heavy_rows(args)
    table(rows)
    if args.json:
        args.json.write_text(json.dumps([asdict(r) for r in rows], indent=1, default=str))
    sys.stdout.flush()
    os._exit(0)    # OMPL's bindings report leaked objects at interpreter exit


if __name__ == "__main__":
    main()
