"""Joint trajectories out of stored job results, for ``GET /jobs/{id}/trajectory``.

A finished job's result is stored as JSON (``GET /jobs/{id}/result``); several kinds carry
timed joint samples in it. ``EXTRACTORS`` maps each such kind to a function that reads its
stored JSON (no kind module is asked: the result's shape is the kind's documented result
schema) and answers its trajectories as ``Track`` values, in the service's units (s, rad,
mm): one per job for ``motion`` (one problem), ``path`` (with a robot) and ``tracking``, one
per problem of a ``motion`` batch, one per arm of a ``multiarm`` plan. ``select`` picks what
a request asks for; ``to_json``, ``to_joint_trajectory`` and ``to_csv`` write it.

Kinds whose result stores velocities and accelerations (``motion``, ``path``) are exported
as stored; ``multiarm`` and ``tracking`` store positions only, and their velocities and
accelerations are estimated from those samples by second-order finite differences
(``numpy.gradient``), which the answer says (``derivatives``).

``joint_trajectory`` follows ROS ``trajectory_msgs/JointTrajectory`` (ROS 2 field names):
SI units, so prismatic joints, stored in mm, are converted to m (and mm/s, mm/s² to m/s,
m/s²); revolute joints stay in rad. ``time_from_start`` is a ``builtin_interfaces/Duration``
rounded to the nearest nanosecond.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import orjson

from kinematics.model import RobotModel
from kinematics.rigs import builtin_rig

__all__ = ["EXPORT_FORMATS", "EXTRACTORS", "ExportError", "Track", "Tracks", "csv_header",
           "extract", "select", "to_csv", "to_joint_trajectory", "to_json",
           "trajectory_kinds"]

#: The formats of ``GET /jobs/{id}/trajectory``.
EXPORT_FORMATS = ("json", "csv", "joint_trajectory")
#: The header frame of an exported ``JointTrajectory``: the robot's (or rig's) world frame,
#: the frame every pose of the service is given in (as in the MoveIt scene export).
FRAME_ID = "world"
#: Prismatic joints are stored in mm; ROS expects m.
MM_TO_M = 1e-3
NS_PER_S = 1_000_000_000

Derivatives = Literal["stored", "finite_differences"]


class ExportError(ValueError):
    """A job result without the trajectory asked for; ``loc`` names the request's field at
    fault (``("path", "job_id")``, ``("query", "arm")``, ...)."""

    def __init__(self, loc: Sequence[str | int], message: str) -> None:
        super().__init__(message)
        self.loc = list(loc)
        self.message = message


@dataclass(frozen=True, eq=False)
class Track:
    """One timed joint trajectory in the service's units: ``t (N,)`` s from the start,
    ``q``, ``qd``, ``qdd`` ``(N, dof)`` in rad, rad/s, rad/s² (revolute joints) or mm, mm/s,
    mm/s² (prismatic joints, ``prismatic (dof,)`` True)."""

    robot: str | None
    joint_names: tuple[str, ...]
    prismatic: np.ndarray
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    derivatives: Derivatives

    @property
    def joint_types(self) -> list[str]:
        return ["prismatic" if p else "revolute" for p in self.prismatic]


@dataclass(frozen=True)
class Tracks:
    """A job's trajectories. ``selector``: the query parameter that picks one (``"arm"``,
    ``"problem"``) or None when the job has one; ``items`` maps each arm or problem (None:
    the only one) to its ``Track``, or to why it has none."""

    selector: Literal["arm", "problem"] | None
    items: dict[Any, Track | str]


Lookup = Callable[[str], RobotModel]
Extractor = Callable[[Mapping[str, Any], Mapping[str, Any], Lookup], Tracks]


# ---- reading the stored results ----------------------------------------------------------
def _array(value: Any, rows: int | None, cols: int | None, what: str) -> np.ndarray:
    """``value`` as float64 of ``(rows,)`` or ``(rows, cols)``; ExportError if misshapen."""
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        arr = None
    shape_ok = arr is not None and (
        (cols is None and arr.ndim == 1) or (cols is not None and arr.ndim == 2
                                             and arr.shape[1] == cols))
    if not shape_ok or (rows is not None and len(arr) != rows):
        raise ExportError(["path", "job_id"], f"the stored result's {what} is not a "
                          "sampled trajectory of the expected shape; run the job again")
    return arr


def _model(lookup: Lookup, robot_id: str, dof: int) -> RobotModel:
    """The robot's model as the service knows it now, checked against the stored samples."""
    try:
        model = lookup(robot_id)
    except KeyError:
        raise ExportError(["path", "job_id"], f"the job's robot '{robot_id}' is no longer "
                          "stored: its joints' names and types (rad or mm) are unknown") from None
    if model.dof != dof:
        raise ExportError(["path", "job_id"], f"the job's robot '{robot_id}' has changed "
                          f"since ({model.dof} joints now, {dof} in the result)")
    return model


def finite_differences(t: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Velocities and accelerations of samples ``q (N, dof)`` at times ``t (N,)``: second-order
    central differences inside, second-order one-sided at the ends (first order with 2
    samples, zeros with 1). ExportError if ``t`` does not increase."""
    if len(t) < 2:
        return np.zeros_like(q), np.zeros_like(q)
    if np.any(np.diff(t) <= 0):
        raise ExportError(["path", "job_id"], "the stored sample times do not increase")
    edge = 2 if len(t) >= 3 else 1
    qd = np.gradient(q, t, axis=0, edge_order=edge)
    qdd = np.gradient(qd, t, axis=0, edge_order=edge)
    return qd, qdd


def _sampled(data: Mapping[str, Any], model: RobotModel | None, names: Sequence[str] | None,
             robot: str, lookup: Lookup, what: str) -> Track:
    """A ``Track`` of a stored ``{"t", "q", "qd", "qdd"}`` (qd and qdd optional: estimated
    when absent). ``model`` given (rig arms) or looked up by ``robot``."""
    t = _array(data.get("t"), None, None, f"{what}.t")
    first = data.get("q") or [[]]
    q = _array(data.get("q"), len(t), len(first[0]), f"{what}.q")
    if model is None:
        model = _model(lookup, robot, q.shape[1])
    elif model.dof != q.shape[1]:
        raise ExportError(["path", "job_id"], f"{what}.q has {q.shape[1]} joints, the "
                          f"model {model.dof}")
    if data.get("qd") is not None and data.get("qdd") is not None:
        qd = _array(data["qd"], len(t), model.dof, f"{what}.qd")
        qdd = _array(data["qdd"], len(t), model.dof, f"{what}.qdd")
        derivatives: Derivatives = "stored"
    else:
        qd, qdd = finite_differences(t, q)
        derivatives = "finite_differences"
    joint_names = tuple(names) if names is not None else tuple(j.name for j in model.joints)
    prismatic = np.array([not j.revolute for j in model.joints], dtype=bool)
    return Track(robot, joint_names, prismatic, t, q, qd, qdd, derivatives)


def _motion(params: Mapping[str, Any], result: Mapping[str, Any], lookup: Lookup) -> Tracks:
    """``motion``: the one problem's ``trajectory``, or each problem's of a batch."""
    robot, names = result.get("robot"), result.get("joints")

    def one(problem: Mapping[str, Any], what: str, where: str) -> Track | str:
        if problem.get("trajectory") is None:
            why = ("it was planned with trajectory: false" if problem.get("status") == "ok"
                   else f"its status is {problem.get('status')}")
            return f"{what} has no trajectory: {why}"
        return _sampled(problem["trajectory"], None, names, robot, lookup, where)

    if result.get("problems") is None:
        return Tracks(None, {None: one(result, "the motion", "trajectory")})
    return Tracks("problem", {k: one(p, f"problem {k}", f"problems.{k}.trajectory")
                              for k, p in enumerate(result["problems"])})


def _path(params: Mapping[str, Any], result: Mapping[str, Any], lookup: Lookup) -> Tracks:
    """``path``: the arm's ``trajectory`` (paths planned for a robot's tool)."""
    robot = result.get("robot") or params.get("robot")
    if not robot:
        return Tracks(None, {None: "this path was planned without a robot: it has a tool "
                             "path, no joint trajectory"})
    if result.get("trajectory") is None:
        return Tracks(None, {None: f"this path job has no joint trajectory (status "
                             f"{result.get('status')}: {result.get('message')})"})
    return Tracks(None, {None: _sampled(result["trajectory"], None, None, robot, lookup,
                                        "trajectory")})


def _tracking(params: Mapping[str, Any], result: Mapping[str, Any], lookup: Lookup) -> Tracks:
    """``tracking``: the best run's joints ``q`` at its steps ``t``."""
    data = {"t": result.get("t"), "q": result.get("q")}
    return Tracks(None, {None: _sampled(data, None, None, result.get("robot")
                                        or params.get("robot"), lookup, "result")})


def _rig_tracks(params: Mapping[str, Any], result: Mapping[str, Any], lookup: Lookup,
                arms: Mapping[str, Any], samples: Callable[[Mapping[str, Any]], dict],
                what: str) -> Tracks:
    """One track per arm (``what``: "arm" or "boom") of the job's built-in rig: ``samples``
    gives an arm's ``{"t", "q"}`` from its entry in ``arms``."""
    rig_id = result.get("rig") or params.get("rig", "tunnel_jumbo")
    try:
        rig = builtin_rig(rig_id)
    except KeyError:
        raise ExportError(["path", "job_id"], f"unknown rig '{rig_id}'") from None
    items: dict[Any, Track | str] = {}
    for arm, data in arms.items():
        model = rig.arms.get(arm)
        if model is None:
            raise ExportError(["path", "job_id"], f"rig '{rig_id}' has no {what} '{arm}'")
        items[arm] = _sampled(samples(data), model, None, model.id, lookup, f"{what}s.{arm}")
    return Tracks("arm", items)


def _multiarm(params: Mapping[str, Any], result: Mapping[str, Any], lookup: Lookup) -> Tracks:
    """``multiarm``: each arm's joints ``arms.<arm>.q`` at the plan's ``t``."""
    return _rig_tracks(params, result, lookup, result.get("arms") or {},
                       lambda data: {"t": result.get("t"), "q": data.get("q")}, "arm")


def _round(params: Mapping[str, Any], result: Mapping[str, Any], lookup: Lookup) -> Tracks:
    """``round``: each boom's own timed joints ``booms.<boom>.t``, ``.q``."""
    return _rig_tracks(params, result, lookup, result.get("booms") or {},
                       lambda data: {"t": data.get("t"), "q": data.get("q")}, "boom")


#: The kinds whose results carry timed joint samples, and how to read them.
EXTRACTORS: dict[str, Extractor] = {
    "motion": _motion,
    "multiarm": _multiarm,
    "path": _path,
    "round": _round,
    "tracking": _tracking,
}


def trajectory_kinds() -> str:
    """The kinds with a trajectory, in words (for error messages)."""
    return ("motion (a solved problem, each of a batch), path (planned for a robot), "
            "multiarm and round (one per arm or boom) and tracking")


def extract(kind: str, params: Mapping[str, Any], result: Mapping[str, Any],
            lookup: Lookup) -> Tracks:
    """The trajectories of a stored result of ``kind``; ExportError for a kind without."""
    extractor = EXTRACTORS.get(kind)
    if extractor is None:
        raise ExportError(["path", "job_id"], f"jobs of kind '{kind}' have no trajectory; "
                          f"trajectories exist for {trajectory_kinds()} jobs")
    return extractor(params, result, lookup)


def select(kind: str, tracks: Tracks, fmt: str, chosen: Mapping[str, Any]
           ) -> tuple[list[tuple[Any, Track]], bool]:
    """What a request asks for: ``([(label, Track)], False)`` for one trajectory, or, when a
    job has several and none is chosen (json and joint_trajectory only), ``(those that have
    one, True)``. ``chosen``: the query's ``arm`` and ``problem`` (None when not given)."""
    for name, value in chosen.items():
        if value is not None and name != tracks.selector:
            picks = (f"jobs of kind '{kind}' have one trajectory per {tracks.selector}"
                     if tracks.selector else f"this {kind} job has one trajectory")
            raise ExportError(["query", name], f"{name} selects one of several trajectories;"
                              f" {picks}")
    if tracks.selector is None:
        ((label, item),) = tracks.items.items()
        if isinstance(item, str):
            raise ExportError(["path", "job_id"], item)
        return [(label, item)], False
    loc = ["query", tracks.selector]
    value = chosen.get(tracks.selector)
    names = ", ".join(str(k) for k in tracks.items)
    if value is not None:
        if value not in tracks.items:
            raise ExportError(loc, f"unknown {tracks.selector} {value!r}; this job has "
                              f"{tracks.selector}s {names}")
        item = tracks.items[value]
        if isinstance(item, str):
            raise ExportError(loc, item)
        return [(value, item)], False
    if fmt == "csv":
        raise ExportError(loc, f"a csv holds one trajectory: choose the {tracks.selector} "
                          f"({names})")
    found = [(k, v) for k, v in tracks.items.items() if isinstance(v, Track)]
    if not found:
        reasons = "; ".join(v for v in tracks.items.values() if isinstance(v, str))
        raise ExportError(["path", "job_id"], f"no {tracks.selector} of this job has a "
                          f"trajectory: {reasons or 'none planned'}")
    return found, True


# ---- writing -----------------------------------------------------------------------------
def _units(track: Track, suffix: str) -> list[str]:
    return [("mm" if p else "rad") + suffix for p in track.prismatic]


def to_json(track: Track, label: dict[str, Any]) -> dict[str, Any]:
    """The service's own form, in its units (s, rad, mm), each stated: ``label`` (job, kind,
    arm or problem) first, then joints, units and ``points``."""
    points = [{"time_from_start": t, "positions": q, "velocities": qd, "accelerations": qdd}
              for t, q, qd, qdd in zip(track.t.tolist(), track.q.tolist(), track.qd.tolist(),
                                       track.qdd.tolist(), strict=True)]
    return {**label, "robot": track.robot, "joint_names": list(track.joint_names),
            "joint_types": track.joint_types,
            "units": {"time_from_start": "s", "positions": _units(track, ""),
                      "velocities": _units(track, "/s"),
                      "accelerations": _units(track, "/s^2")},
            "derivatives": track.derivatives,
            "duration": float(track.t[-1] - track.t[0]) if len(track.t) else 0.0,
            "points": points}


def durations(t: np.ndarray) -> tuple[list[int], list[int]]:
    """``builtin_interfaces/Duration`` of each time ``t (N,)`` s: ``(sec, nanosec)``, the
    nearest nanosecond."""
    ns = np.rint(np.asarray(t, dtype=np.float64) * NS_PER_S).astype(np.int64)
    return (ns // NS_PER_S).tolist(), (ns % NS_PER_S).tolist()


def to_joint_trajectory(track: Track) -> dict[str, Any]:
    """A ``trajectory_msgs/JointTrajectory`` as JSON (ROS 2 field names): rad and m, rad/s
    and m/s, rad/s² and m/s²; the header's stamp zero (start when received)."""
    scale = np.where(track.prismatic, MM_TO_M, 1.0)
    sec, nanosec = durations(track.t)
    points = [{"positions": q, "velocities": qd, "accelerations": qdd, "effort": [],
               "time_from_start": {"sec": s, "nanosec": n}}
              for q, qd, qdd, s, n in zip((track.q * scale).tolist(),
                                          (track.qd * scale).tolist(),
                                          (track.qdd * scale).tolist(), sec, nanosec,
                                          strict=True)]
    return {"header": {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": FRAME_ID},
            "joint_names": list(track.joint_names), "points": points}


def csv_header(joint_names: Sequence[str]) -> list[str]:
    """``time_s``, then each joint's ``<name>_pos``, then ``_vel``, then ``_acc``."""
    return (["time_s"] + [f"{n}_pos" for n in joint_names] + [f"{n}_vel" for n in joint_names]
            + [f"{n}_acc" for n in joint_names])


def to_csv(track: Track) -> str:
    """One row per sample under ``csv_header``, in the service's units (s; rad or mm per
    joint, per s, per s²); every float in its shortest form that reads back to the same
    float64 (as in the JSON answers: orjson writes the rows, whose brackets become line
    breaks)."""
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow(csv_header(track.joint_names))
    table = np.ascontiguousarray(np.column_stack([track.t, track.q, track.qd, track.qdd]),
                                 dtype=np.float64)
    if len(table):
        rows = orjson.dumps(table, option=orjson.OPT_SERIALIZE_NUMPY).decode()
        buf.write(rows[2:-2].replace("],[", "\n") + "\n")
    return buf.getvalue()
