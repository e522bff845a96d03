"""``plan_motion``: a collision-free joint-space move of any arm, from a configuration to a
configuration or to a tool pose, simplified and timed.

Steps: validate the input (``FieldError`` naming the field); check the start (limits,
collision); the goal configurations (the given one, or every IK branch of the goal pose within
the limits, numeric IK with several seeds for robots without a closed form; the free ones are
the goals); search (``planner``: ``rrt_connect``, ``rrt_star`` or ``auto``); simplify
(shortcuts); time the path (time-optimal along a polyline whose corners are blended, the
blends checked for collision and tightened until free, sharp corners at worst); measure the
least clearance. Every outcome other than bad input is a ``MotionStatus`` with a message
naming why (the colliding pair, the joint out of limits).

``rrt_connect`` (and ``auto``) runs the compiled RRT-Connect
(``search.rrt_connect_compiled``, restarting with growing budgets): first on the sphere
model alone (a state the spheres flag counts as a collision, so its paths are free without
the exact stage) for up to ``SPHERE_SHARE`` of the time limit and at most ``SPHERE_MAX_S``
s, a start or goal the spheres flag being first left by a short path checked on the exact
shapes (``search.escape``); if that finds nothing (a passage narrower than the spheres'
slack), again settling every flagged state exactly for the rest of the time. Without
compiled kernels RRT-Connect runs in Python (``search.rrt_connect``). The path is then
shortened with the checker that found it (compiled, every segment of the answer checked at
the resolution as it is shortened; a path shortened in Python is checked once more before
it is answered). The compiled search does not check its path at the resolution when it is
to be shortened: most of it is shortcut away, and what the answer keeps of it is checked at
the resolution by the shortening (bent about a state the finer check finds in collision;
with the exact stage when the spheres alone refuse it); if that fails, the search runs
again checking each path it finds at the resolution.
``auto`` with a time limit past ``AUTO_REFINE_AFTER`` s also hands the shortened path to
RRT* as the bound to beat until ``AUTO_REFINE_SHARE`` of the time, then shortens the
best path again. ``rrt_star`` searches with RRT* for the whole time limit.

Time: the search ends by ``time_limit``; simplification has half of it, within what the
search left (at least ``SIMPLIFY_MIN_S``); the final check, the blend checks of the trajectory
and the clearance have ``FINISH_S`` more. Each phase sets the checker's deadline, which every
segment check looks at (``MotionChecker.deadline``): past it a check answers "not free", so a
phase cut short keeps what it has proved (the path as found, sharp corners) and a plan ends
within ``time_limit + SIMPLIFY_MIN_S + FINISH_S`` plus one exact check, whatever the
``resolution`` (at least ``MIN_RESOLUTION``).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from kinematics.errors import FieldError
from kinematics.status import Status

from .checker import DEFAULT_RESOLUTION, MIN_RESOLUTION, MotionChecker
from .search import (
    escape,
    path_length,
    rrt_connect,
    rrt_connect_compiled,
    rrt_star,
    shortcut,
    shortcut_compiled,
    sphere_free,
)

__all__ = ["MotionStatus", "MotionResult", "plan_motion", "plan_checked", "PLANNERS",
           "MAX_RESOLUTION",
           "MIN_RESOLUTION", "MAX_TIME_LIMIT"]

PLANNERS = ("auto", "rrt_connect", "rrt_star")
#: Coarsest joint step allowed between checked states (rad).
MAX_RESOLUTION = 0.5
#: Longest time limit of one problem (s).
MAX_TIME_LIMIT = 3600.0
#: Least time simplification gets, even when the search used the whole time limit (s) ...
SIMPLIFY_MIN_S = 0.2
#: ... and the time of the final check, the trajectory's blend checks and the clearance (s).
FINISH_S = 0.5
#: Most states of a trajectory checked for collision (its blends): past it the states are
#: spread evenly, and a blend whose check cannot finish in ``FINISH_S`` is kept sharp.
TRAJECTORY_STATES_MAX = 200_000
#: ``auto`` refines with RRT* when the time limit exceeds this (s) ...
AUTO_REFINE_AFTER = 10.0
#: ... for at most this share of the time limit.
AUTO_REFINE_SHARE = 0.5
#: Seeds of numeric IK for a goal pose of a robot without a closed form.
IK_SEEDS = 8
#: Without compiled kernels, the search starts on the sphere model alone (a flagged state
#: counts as a collision, except within ``EXACT_ZONE`` of the start and goals) for this share
#: of the time limit, at most ``SPHERE_PHASE_MAX`` s, then confirms flagged states exactly:
#: cheap in open space, exact where the way is narrow.
SPHERE_PHASE_SHARE = 0.1
SPHERE_PHASE_MAX = 0.2
EXACT_ZONE = 0.3
#: Share of the time limit the compiled search on the sphere model alone may take before
#: the one that settles flagged states exactly takes over, and at most ``SPHERE_MAX_S`` s: a
#: problem the spheres solve at all they solve in milliseconds, and one whose passage is
#: narrower than their slack should not wait for the exact search.
SPHERE_SHARE = 0.6
SPHERE_MAX_S = 0.3
#: After that, the share of the search time the exact stage takes (the rest stays on the
#: spheres alone, growing the same trees).
EXACT_SHARE = 0.4
#: Shortcut attempts of the exact pass after the sphere pass.
SHORTCUT_ATTEMPTS_EXACT = 40
#: Corner blends tried for the trajectory: largest deviation from a corner (weighted rad).
BLEND_DEVIATIONS = (0.05, 0.01, 0.002)


class MotionStatus(Status):
    """How a motion plan ended (a member of the status family, ``kinematics.status``)."""

    OK = "ok"
    START_IN_COLLISION = "start_in_collision"
    GOAL_IN_COLLISION = "goal_in_collision"
    GOAL_UNREACHABLE = "goal_unreachable"
    OUT_OF_LIMITS = "out_of_limits"
    NO_PATH = "no_path"
    TIMEOUT = "timeout"


@dataclass
class MotionResult:
    """A motion plan (module docstring). ``path (K, dof)``: waypoints whose straight
    segments are free at ``resolution``; ``length``: the sum of the segments' Euclidean
    lengths (rad, mm for prismatic joints); times in s; ``min_clearance`` mm."""

    status: MotionStatus
    message: str
    path: np.ndarray
    length: float = math.nan
    planning_time_s: float = 0.0
    simplify_time_s: float = 0.0
    min_clearance: float | None = None
    trajectory: Any = None
    goal: np.ndarray | None = None
    pairs: list = field(default_factory=list)
    planner: str = ""
    resolution: float = DEFAULT_RESOLUTION
    stats: dict = field(default_factory=dict)

    @property
    def success(self) -> bool:
        return self.status is MotionStatus.OK

    def to_dict(self, joint_names: list[str] | None = None, samples: int = 200
                ) -> dict[str, Any]:
        """JSON-ready; the trajectory sampled at ``samples`` equal steps (and its knots'
        duration)."""
        def num(x):
            return None if x is None or not math.isfinite(float(x)) else float(x)

        out: dict[str, Any] = {
            "status": self.status.value, "message": self.message,
            "path": self.path.tolist(), "length": num(self.length),
            "planning_time_s": float(self.planning_time_s),
            "simplify_time_s": float(self.simplify_time_s),
            "min_clearance": num(self.min_clearance),
            "goal": None if self.goal is None else self.goal.tolist(),
            "pairs": [list(p) for p in self.pairs], "planner": self.planner,
            "resolution": self.resolution, "stats": self.stats, "trajectory": None,
        }
        if joint_names is not None:
            out["joints"] = list(joint_names)
        if self.trajectory is not None:
            out["trajectory"] = trajectory_samples(self.trajectory, samples)
        return out


def trajectory_samples(T: Any, samples: int) -> dict:
    """A trajectory as the answers carry it: ``samples`` evenly spaced times (at least 2)
    with positions, velocities and accelerations, and its duration."""
    t = np.linspace(0.0, T.duration, max(2, int(samples)))
    return {"t": t.tolist(), "q": T.evaluate(t).tolist(), "qd": T.evaluate(t, 1).tolist(),
            "qdd": T.evaluate(t, 2).tolist(), "duration": float(T.duration)}


# ---- input ------------------------------------------------------------------------------------
def joint_vector(value, dof: int, loc: tuple) -> np.ndarray:
    """``value`` as ``dof`` finite joint values, else a ``FieldError`` at ``loc``."""
    try:
        v = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise FieldError(loc, f"{loc[-1]} must be a list of {dof} numbers") from None
    if v.shape != (dof,):
        raise FieldError(loc, f"{loc[-1]} must have {dof} joint values, got shape "
                         f"{list(v.shape)}")
    if not np.all(np.isfinite(v)):
        raise FieldError(loc, f"{loc[-1]} must be finite")
    return v


def _number(value, loc: tuple, lo: float, hi: float, open_low: bool = True) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) \
            or not math.isfinite(value) or (value <= lo if open_low else value < lo) \
            or value > hi:
        low = f"> {lo}" if open_low else f">= {lo}"
        raise FieldError(loc, f"{loc[-1]} must be a number {low} and <= {hi}")
    return float(value)


def _limit_message(checker: MotionChecker, q: np.ndarray, what: str) -> str | None:
    names = [j.name for j in checker.robot_model.joints]
    for i in range(checker.dof):
        if q[i] < checker.lower[i] - 1e-9 or q[i] > checker.upper[i] + 1e-9:
            return (f"{what} is out of limits: joint '{names[i]}' = {q[i]:.6g}, limits "
                    f"[{checker.lower[i]:.6g}, {checker.upper[i]:.6g}]")
    return None


def _pairs_text(pairs: list) -> str:
    return ", ".join(f"{a} - {b}" for a, b in pairs[:4]) + (" ..." if len(pairs) > 4 else "")


def _goal_branches(checker: MotionChecker, model: Any, pose: np.ndarray, seed: int
                   ) -> tuple[np.ndarray, str]:
    """Every IK branch of ``pose`` within the limits ``(K, dof)`` (possibly none), and a
    message saying why there is none."""
    from kinematics.ik import IKStatus, NumericOptions, analytic_solver, solve_ik

    found, message = [], ""
    try:
        if analytic_solver(model) is not None:
            runs = [solve_ik(model, pose, all_solutions=True)[0]]
        else:
            runs = [solve_ik(model, pose, method="numeric", all_solutions=True,
                             options=NumericOptions(seed=seed + k))[0]
                    for k in range(IK_SEEDS)]
    except ValueError as exc:
        raise FieldError(("goal", "pose"), f"goal.pose: {exc}") from None
    for r in runs:
        if r.status is IKStatus.OK or len(r.solutions):
            found.append(np.atleast_2d(r.solutions))
        if not message:
            message = r.message
    if not found:
        return np.empty((0, checker.dof)), message or "no IK solution"
    Q = np.concatenate(found)
    from kinematics.fk import fk

    # Keep solutions that reach the pose (within 0.01 mm, 1e-5 rad) and the limits.
    T = fk(model, Q)
    pos = np.linalg.norm(T[:, :3, 3] - pose[:3, 3], axis=1)
    R = np.einsum("bji,jk->bik", T[:, :3, :3], pose[:3, :3])
    ang = np.arccos(np.clip((np.trace(R, axis1=1, axis2=2) - 1) / 2, -1, 1))
    ok = (pos <= 1e-2) & (ang <= 1e-5) & checker.within_limits(Q)
    Q = Q[ok]
    if len(Q) == 0:
        return Q.reshape(0, checker.dof), message or "no IK solution within the joint limits"
    # Distinct branches only.
    keep = [0]
    for i in range(1, len(Q)):
        if np.min(np.abs(Q[keep] - Q[i]).max(axis=1)) > 1e-6:
            keep.append(i)
    return Q[keep], ""


# ---- the plan -----------------------------------------------------------------------------------
def plan_motion(checker: MotionChecker, start, goal=None, *, goal_pose=None, model=None,
                planner: str = "auto", time_limit: float = 5.0, seed: int = 0,
                resolution: float = DEFAULT_RESOLUTION, simplify: bool = True,
                trajectory: bool = True, limits=None, hydraulics=None,
                progress=None) -> MotionResult:
    """Plan a collision-free move of ``checker``'s robot from ``start`` to ``goal`` (a
    configuration) or ``goal_pose`` (a tool pose ``(4, 4)`` mm; ``model`` gives the IK), in
    at most ``time_limit`` s of search (module docstring). ``limits``
    (``planning.trajectories.Limits``) and ``hydraulics`` time the trajectory (default: the
    model's joint speeds and the arm accelerations of ``planning.paths.arm``). ``progress``
    receives the fraction of the time limit used and may raise to stop."""
    t0 = time.perf_counter()
    dof = checker.dof
    q_start = joint_vector(start, dof, ("start",))
    if (goal is None) == (goal_pose is None):
        raise FieldError(("goal",), "goal: give a configuration (q) or a pose")
    if planner not in PLANNERS:
        raise FieldError(("planner",), f"planner must be one of {', '.join(PLANNERS)}")
    time_limit = _number(time_limit, ("time_limit",), 0.0, MAX_TIME_LIMIT)
    resolution = _number(resolution, ("resolution",), MIN_RESOLUTION, MAX_RESOLUTION,
                         open_low=False)
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer):
        raise FieldError(("seed",), "seed must be an integer")
    q_goal = pose = None
    if goal is not None:
        q_goal = joint_vector(goal, dof, ("goal", "q"))
    else:
        pose = np.asarray(goal_pose, dtype=float)
        if pose.shape != (4, 4) or not np.all(np.isfinite(pose)):
            raise FieldError(("goal", "pose"), "goal.pose must be a finite 4x4 matrix")
    return plan_checked(checker, q_start, q_goal, pose, model=model, planner=planner,
                        time_limit=time_limit, seed=int(seed), resolution=resolution,
                        simplify=simplify, trajectory=trajectory, limits=limits,
                        hydraulics=hydraulics, progress=progress, t0=t0)


def plan_checked(checker: MotionChecker, q_start: np.ndarray, q_goal: np.ndarray | None,
                 pose: np.ndarray | None, *, model=None, planner: str, time_limit: float,
                 seed: int, resolution: float, simplify: bool = True, trajectory: bool = True,
                 limits=None, hydraulics=None, progress=None,
                 t0: float | None = None) -> MotionResult:
    """``plan_motion`` of arguments already checked (a ``MotionRequest``'s: the service
    validates a request once, where it reads it): ``q_start (dof,)`` and either ``q_goal
    (dof,)`` or ``pose (4, 4)`` floats, ``planner`` one of ``PLANNERS``, ``time_limit`` and
    ``resolution`` within their bounds. ``t0``: when the request's clock started (now)."""
    t0 = time.perf_counter() if t0 is None else t0
    dof = checker.dof
    rng = np.random.default_rng(seed)
    if pose is not None and model is None:
        model = checker.robot_model
    deadline = t0 + time_limit
    base = {"planner": planner, "resolution": resolution}

    def result(status, message, **kw) -> MotionResult:
        kw.setdefault("path", np.empty((0, dof)))
        return MotionResult(status, message, planning_time_s=time.perf_counter() - t0,
                            **base, **kw)

    msg = _limit_message(checker, q_start, "the start")
    if msg:
        return result(MotionStatus.OUT_OF_LIMITS, msg)
    if not checker.free(q_start):
        pairs = checker.pairs(q_start)
        return result(MotionStatus.START_IN_COLLISION,
                      f"the start is in collision: {_pairs_text(pairs)}", pairs=pairs)
    if pose is None:
        msg = _limit_message(checker, q_goal, "the goal")
        if msg:
            return result(MotionStatus.OUT_OF_LIMITS, msg)
        goals = q_goal[None]
    else:
        goals, why = _goal_branches(checker, model, pose, int(seed))
        if len(goals) == 0:
            return result(MotionStatus.GOAL_UNREACHABLE, f"the goal pose is unreachable: {why}")
    free = np.atleast_1d(checker.free(goals))
    if not free.any():
        pairs = checker.pairs(goals[0])
        what = "the goal is" if pose is None else f"every IK branch of the goal pose " \
            f"({len(goals)}) is"
        return result(MotionStatus.GOAL_IN_COLLISION,
                      f"{what} in collision: {_pairs_text(pairs)}", pairs=pairs,
                      goal=goals[0])
    goals = goals[free]

    exact = checker.exact

    def stop() -> bool:
        now = time.perf_counter()
        if progress is not None:
            progress(min(1.0, (now - t0) / time_limit))
        return now >= deadline

    checker.deadline = deadline
    try:
        return _search(checker, q_start, goals, planner, rng, stop, resolution, simplify,
                       time_limit, t0, exact, result, trajectory, limits, hydraulics)
    finally:
        checker.exact = exact
        checker.exact_zone = None
        checker.deadline = None


def _sphere_phase(checker: MotionChecker, q_start: np.ndarray, goals: np.ndarray, stop,
                  time_limit: float, exact: bool):
    """For the Python searches: the checker on the spheres alone (the exact stage only
    within ``EXACT_ZONE`` of the start and goals) for the first ``SPHERE_PHASE_SHARE`` of the
    time limit (at most ``SPHERE_PHASE_MAX`` s), then exact again; answers the ``stop`` that
    switches it back."""
    if not exact:
        return stop
    switch_at = time.perf_counter() + min(SPHERE_PHASE_SHARE * time_limit, SPHERE_PHASE_MAX)
    checker.exact = False
    checker.exact_zone = (np.vstack([q_start[None], goals]), EXACT_ZONE)

    def phased() -> bool:
        if not checker.exact and time.perf_counter() >= switch_at:
            checker.exact, checker.exact_zone = True, None
        return stop()

    return phased


def _search(checker, q_start, goals, planner, rng, stop, resolution, simplify, time_limit, t0,
            exact, result, trajectory, limits, hydraulics) -> MotionResult:
    checks0, exact0 = checker.checks, checker.exact_checks
    stats: dict[str, Any] = {}
    used = planner
    path, mode = None, None
    if planner == "rrt_star":
        path, st = rrt_star(checker, q_start, goals, rng,
                            _sphere_phase(checker, q_start, goals, stop, time_limit, exact),
                            resolution)
    elif checker._k is not None:
        used = "rrt_connect"
        # With simplification the search's path is not checked at ``resolution`` when the
        # trees meet: most of it is shortcut away, and the simplification certifies what
        # it keeps (``shortcut_compiled(checked=...)``).
        path, st, mode = _compiled_search(checker, q_start, goals, rng, stop, resolution,
                                          time_limit, exact, validate=not simplify)
    else:
        used = "rrt_connect"
        path, st = rrt_connect(checker, q_start, goals, rng,
                               _sphere_phase(checker, q_start, goals, stop, time_limit, exact),
                               resolution)
    checker.exact, checker.exact_zone = exact, None
    stats.update(st)
    if path is None:
        return result(MotionStatus.TIMEOUT,
                      f"no path found within the time limit of {time_limit:g} s "
                      f"({st.get('nodes', 0)} tree nodes)",
                      stats={**stats, "checks": checker.checks - checks0})
    lazy = stats.pop("lazy_segments", None), stats.pop("lazy_step", None)
    stats["raw_waypoints"] = len(path)
    stats["raw_length"] = path_length(path)
    raw = path
    t_simplify = time.perf_counter()
    # Simplification: half the time limit, within what the search left, at least
    # SIMPLIFY_MIN_S.
    s_deadline = t_simplify + max(SIMPLIFY_MIN_S,
                                  min(0.5 * time_limit, t0 + time_limit - t_simplify))
    checker.deadline = s_deadline
    certified = False       # every segment checked at ``resolution`` by the simplification
    checked = None          # the step each segment was checked at, if coarser for some
    if lazy[0] is not None:
        checked = np.full(len(path) - 1, float(resolution))
        checked[lazy[0][0]:lazy[0][1]] = lazy[1]
    if simplify and (len(path) > 2 or checked is not None):

        def s_stop() -> bool:
            return time.perf_counter() >= s_deadline

        if mode is not None:
            # Compiled, with the checker the path was found with.
            shorter = shortcut_compiled(checker, path, rng, resolution, exact=mode == "exact",
                                        checked=checked)
            if shorter is None and mode == "spheres" and exact:
                # The spheres' slack (a gripper about its object, a wrist by its forearm)
                # may be all that blocks the finer check: settle it exactly.
                shorter = shortcut_compiled(checker, path, rng, resolution, exact=True,
                                            checked=checked)
            if shorter is None:
                # The search's lazily checked path could not be made free at
                # ``resolution`` (bent about its states at fault): search again, checking
                # each path at ``resolution`` when the trees meet, for the time left.
                stats["lazy_path_rejected"] = True
                checker.deadline = t0 + time_limit
                path, st2, mode = _compiled_search(checker, q_start, goals, rng, stop,
                                                   resolution, time_limit, exact)
                checker.exact, checker.exact_zone = exact, None
                if path is None:
                    return result(MotionStatus.TIMEOUT,
                                  f"no path found within the time limit of {time_limit:g} s "
                                  f"({st2.get('nodes', 0)} tree nodes)",
                                  stats={**stats, "checks": checker.checks - checks0})
                raw = path
                stats["raw_waypoints"] = len(path)
                stats["raw_length"] = path_length(path)
                s_deadline = max(s_deadline, time.perf_counter() + SIMPLIFY_MIN_S)
                checker.deadline = s_deadline
                shorter = shortcut_compiled(checker, path, rng, resolution,
                                            exact=mode == "exact")
            path = shorter
            certified = True
        else:
            checker.exact = False
            path = shortcut(checker, path, rng, s_stop, resolution)
            if exact:
                checker.exact, checker.exact_zone = True, None
                path = shortcut(checker, path, rng, s_stop, resolution,
                                attempts=SHORTCUT_ATTEMPTS_EXACT)
        if planner == "auto" and time_limit > AUTO_REFINE_AFTER:
            r_deadline = t0 + AUTO_REFINE_SHARE * time_limit
            better, st2 = rrt_star(checker, q_start, goals, rng,
                                   lambda: time.perf_counter() >= r_deadline, resolution,
                                   initial=path)
            stats["refine"] = st2
            if better is not None and path_length(better, checker.weights) < \
                    path_length(path, checker.weights):
                checker.deadline = s_deadline + 1.0
                path = shortcut(checker, better, rng,
                                lambda: time.perf_counter() >= s_deadline + 1.0, resolution)
                used = "rrt_connect+rrt_star"
                certified = False
    checker.exact, checker.exact_zone = exact, None
    checker.deadline = max(time.perf_counter(), s_deadline) + FINISH_S
    if len(path) != stats["raw_waypoints"] and not certified \
            and not checker.path_free(path, resolution):
        # The path as found (every edge checked at ``resolution``) is answered instead: the
        # time limit ended the check, or (never expected: every shortcut checks what it
        # keeps) the check failed. The compiled simplification checks every segment of its
        # answer at ``resolution`` itself (``shortcut_compiled``): checking it again here
        # would repeat the same states with the same kernels.
        stats["simplified_path_rejected"] = "time limit" if checker.late() else True
        path = raw
    simplify_time = time.perf_counter() - t_simplify
    stats["checks"] = checker.checks - checks0
    stats["exact_checks"] = checker.exact_checks - exact0
    planning_time = time.perf_counter() - t0
    goal_reached = path[-1].copy()
    out = MotionResult(MotionStatus.OK, "ok", path, length=path_length(path),
                       planning_time_s=planning_time, simplify_time_s=simplify_time,
                       goal=goal_reached, planner=used, resolution=resolution, stats=stats)
    if trajectory:
        out.trajectory, note = _trajectory(checker, path, resolution, limits, hydraulics)
        if note:
            out.stats["trajectory"] = note
    checker.deadline = None
    out.min_clearance = checker.clearance(path, resolution)
    return out


def _compiled_search(checker: MotionChecker, q_start: np.ndarray, goals: np.ndarray,
                     rng: np.random.Generator, stop, resolution: float, time_limit: float,
                     exact: bool, validate: bool = True
                     ) -> tuple[np.ndarray | None, dict, str | None]:
    """The compiled RRT-Connect, first on the sphere model alone (a flagged state counts as
    a collision), which is fast where the way is wide, for up to ``SPHERE_SHARE`` of the
    time limit and at most ``SPHERE_MAX_S`` s: a start or goal the spheres flag (a gripper
    about an object) is first left by a short exactly checked path (``escape``) to one they
    clear, and the trees grow from those paths' ends. Then, with ``exact``, the same trees
    grow on in chunks of iterations that either settle flagged states exactly (through a
    passage narrower than the spheres' slack) or stay on the spheres alone (fast across open
    space), the time shared evenly between the two. Without ``validate`` the path found is
    answered with its own edges checked at the lazy step only (``rrt_connect_compiled``;
    statistics ``lazy_segments`` and ``lazy_step``). Answers the path, statistics and the
    mode that found it (``"spheres"``, or ``"exact"`` once the exact stage has joined)."""
    stats: dict[str, Any] = {}
    ends = _sphere_ends(checker, q_start, goals, rng, stop, resolution, exact)
    if ends is None and not exact:
        return None, stats, None
    switch = time.perf_counter() + (min(SPHERE_SHARE * time_limit, SPHERE_MAX_S)
                                    if exact else time_limit)
    spent = {False: 0.0, True: 0.0}      # s of each mode since the switch
    last: list[Any] = [None, 0.0]         # the mode of the chunk running, since when

    def use_exact() -> bool:
        if ends is None:
            return True          # the ends stay flagged: only the exact stage can leave them
        now = time.perf_counter()
        if now < switch:
            return False
        if last[0] is not None:
            spent[last[0]] += now - last[1]
        # The time shared by ``EXACT_SHARE``: an exact chunk can take far longer than a
        # sphere chunk.
        last[:] = [spent[True] <= EXACT_SHARE * (spent[True] + spent[False]), now]
        return last[0]

    head, tails = ends if ends is not None else (None, ())
    path, st = rrt_connect_compiled(checker, q_start, goals, rng, stop, resolution,
                                    exact=use_exact, head=head, tails=tails,
                                    validate=validate)
    stats.update(st)
    stats["escaped"] = head is not None and len(head) > 1 or any(len(t) > 1 for t in tails)
    return path, stats, None if path is None else \
        ("exact" if st.get("exact_chunks", 0) else "spheres")


def _sphere_ends(checker: MotionChecker, q_start: np.ndarray, goals: np.ndarray,
                 rng: np.random.Generator, stop, resolution: float, exact: bool,
                 most_goals: int = 4) -> tuple[np.ndarray, list[np.ndarray]] | None:
    """Where a search on the spheres alone can start and end: ``(head, tails)``, ``head`` a
    path from the start to a configuration the spheres clear (the start alone when they
    clear it) and ``tails`` paths from such configurations to goals (``escape``, on the
    exact shapes, for up to ``most_goals`` goals the spheres flag); None when there is none
    (without ``exact``, flagged ends are not left)."""
    sf = sphere_free(checker, np.vstack([q_start[None], goals]))
    if sf[0]:
        head = q_start[None]
    elif exact:
        head = escape(checker, q_start, rng, stop, resolution)
        if head is None:
            return None
    else:
        return None
    tails = [g[None] for g in goals[sf[1:]]]
    if exact:
        for g in goals[~sf[1:]][:most_goals]:
            out = escape(checker, g, rng, stop, resolution)
            if out is not None:
                tails.append(out[::-1])
    return (head, tails) if tails else None


def _trajectory(checker: MotionChecker, path: np.ndarray, resolution: float, limits,
                hydraulics) -> tuple[Any, str]:
    """The time-optimal trajectory along ``path`` with blended corners whose samples are
    free (tightening the blends until they are), and a note of what was done."""
    from planning.trajectories.joint_path import smooth_polyline
    from planning.trajectories.topp import time_optimal
    from planning.trajectories.trajectory import ARM_ACCELERATION, Limits

    rm = checker.robot_model
    if limits is None:
        acc = np.where(rm.revolute, ARM_ACCELERATION[0], ARM_ACCELERATION[1])
        limits = Limits(velocity=np.asarray(rm.velocity_limits), acceleration=acc)
    if hydraulics is None:
        from planning.trajectories.hydraulic import hydraulic_limits

        hydraulics = hydraulic_limits(rm)
    corners = len(path) > 2
    for dev in (BLEND_DEVIATIONS if corners else (0.0,)) + ((0.0,) if corners else ()):
        if dev > 0.0 and checker.late():
            continue   # no time left to check a blend: sharp corners, without timing each
        jp = smooth_polyline(path, dev)
        res = time_optimal(jp, limits, hydraulics)
        if not res.success:
            return None, f"not timed: {res.message}"
        traj = res.trajectory
        if dev == 0.0 or _trajectory_free(checker, traj, resolution):
            return traj, "" if dev > 0 or not corners else "corners kept sharp (stops)"
    return None, "no collision-free blend"


def _trajectory_free(checker: MotionChecker, traj: Any, resolution: float) -> bool:
    """Whether the trajectory is free at states no farther apart than ``resolution``."""
    n = 64
    while True:
        t = np.linspace(0.0, traj.duration, n)
        Q = traj.evaluate(t)
        step = np.max(np.abs(np.diff(Q, axis=0)) * checker.weights) if n > 1 else 0.0
        if step <= resolution or n > TRAJECTORY_STATES_MAX:
            break
        n = min(int(n * step / resolution * 1.2) + 1, TRAJECTORY_STATES_MAX + 1)
    return not checker.late() and bool(np.all(checker.free(Q)))
