"""Validity checks of a robot's configurations in a scene, for the joint-space planners.

``MotionChecker`` joins a robot's collision model (``planning.collision.RobotCollisionModel``)
and a scene (``CollisionScene``) into flat arrays for the compiled kernels
(``planning.motion._kernels``), which go from joint values to an answer in one call: one
configuration, a batch, or every state of a straight segment at a given joint step, the
segment's states taken in bisection order (the middle first) and stopping at the first the
sphere stage flags. A flagged state goes to the exact stage (FCL on the real shapes, only the
flagged pairs) and the segment check resumes after it if it is free. A "free" answer is
therefore certain, and a "collides" answer is the exact one.

Joint steps: a segment is checked at states no farther apart than ``resolution`` rad on every
revolute joint and ``resolution * PRISMATIC_STEP`` mm on every prismatic one (1 mm at the
default 0.01). In the planners' metric a prismatic joint's ``PRISMATIC_SCALE`` mm count as
one radian (1 m: as far as a point 1 m from a revolute axis moves). With the compiled kernels
a stretch of that grid is proved free at once when its middle state is clear by the distance
any point of the robot can sweep within the stretch (``planning.motion._rrt.sweeps``: per
joint, its move times the largest distance from its axis of the geometry beyond it; up to
``SWEEP_MARGIN_MAX`` mm, by the spheres or the exact stage): such a stretch is free
everywhere, so a telescope's metres cost a few dozen checked states instead of one per mm,
and a thin obstacle between two grid states is refused where a proved stretch would cross
it. A stretch not proved is cut at its middle state, down to single grid steps: no two
checked states of it are farther apart than ``resolution``, as before.

Deadlines: while ``deadline`` (a ``time.perf_counter`` time) is set, a segment check looks at
the clock every ``DEADLINE_CHUNK`` states and answers "not free" once it has passed, so a
search never runs far past its time limit however fine the ``resolution``; "not free" keeps
every planner conservative (nothing unchecked is ever kept). The planner sets it and clears
it; the verification helpers (``path_free`` outside a plan, ``clearance``) run without one.

Without numba (``KINOPLAN_JIT=0``), for a robot whose links the chain layout cannot carry
(a link moved by a mimic joint; a prismatic joint's capsule on a D-H / PoE robot carrying
attached objects, ``planning.collision.attached``), or in a scene with a shape that has no
compiled kernel (a registered shape without a code, ``planning.geometry.registry``), the
checks run on ``planning.collision.collides`` instead: the same answers, slower.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from kinematics.errors import FieldError
from planning.geometry.registry import KERNEL_CODES

__all__ = ["MotionChecker", "PRISMATIC_SCALE", "PRISMATIC_STEP", "DEFAULT_RESOLUTION",
           "MIN_RESOLUTION", "bisection_order", "segment_states"]

#: Millimetres of a prismatic joint that count as one radian in the planners' metric.
PRISMATIC_SCALE = 1000.0
#: Largest step of a prismatic joint between checked states, in mm per radian of
#: ``resolution`` (1 mm at the default 0.01).
PRISMATIC_STEP = 100.0
#: Default largest joint step between checked states of a segment (rad).
DEFAULT_RESOLUTION = 0.01
#: Finest ``resolution`` accepted (rad; 0.01 mm on prismatic joints): 6e4 states per
#: radian-long segment, already a thousandth of a degree.
MIN_RESOLUTION = 1e-4
#: States of a segment checked between two looks at the deadline.
DEADLINE_CHUNK = 4096
#: Segment lengths (states) whose bisection order is kept for reuse, and how many at most.
_ORDER_CACHE_N = 1 << 16
_ORDER_CACHE_SIZE = 4096
#: Most flagged pairs collected for the exact stage of one configuration.
_HIT_CAP = 256
#: The scene's boxes and cylinders, and the largest link mesh (triangles) whose collisions
#: with them the exact stage settles in compiled code (``planning.geometry.triangles``; its
#: chunks keep a 40,000-triangle gripper mesh beside a box to a few of them).
_SOLIDS = (KERNEL_CODES["box"], KERNEL_CODES["cylinder"])
TRIANGLES_MAX = 200_000
#: Caps (mm) of the sphere bounds ``clearance`` tries in turn before its ``reach``.
CLEARANCE_CAPS = (32.0, 128.0, 512.0)
#: Scenes with more objects than this are screened by their distance grid.
GRID_OBJECTS = 24


def segment_states(P: np.ndarray, steps, most: int | None = None) -> np.ndarray:
    """The states ``(S, dof)`` of the polyline ``P (K, dof)`` with segment ``i`` cut into
    ``steps[i]`` steps: ``P[0]``, then each segment's ``P[i] + (P[i+1] - P[i]) k / steps[i]``
    for ``k = 1 .. steps[i]``. With ``most``, at most that many of them, evenly spread over
    that list (its first and last kept), computed without building the whole list: a fine
    resolution over a long path asks for millions of states of which a hundred are used."""
    P = np.asarray(P, dtype=float)
    steps = np.asarray(steps, dtype=np.int64).reshape(-1)
    ends = np.cumsum(steps)
    total = 1 + (int(ends[-1]) if len(ends) else 0)
    if most is None or total <= most:
        j = np.arange(total)
    else:
        j = np.unique(np.linspace(0, total - 1, most).round().astype(np.int64))
    out = np.empty((len(j), P.shape[1]))
    first = j == 0
    out[first] = P[0]
    jj = j[~first]
    seg = np.searchsorted(ends, jj, side="left")
    n = steps[seg]
    k = jj - (ends[seg] - n)
    out[~first] = P[seg] + (P[seg + 1] - P[seg]) * (k / n)[:, None]
    return out


def bisection_order(n: int) -> np.ndarray:
    """The interior states ``1 .. n - 1`` of a segment cut into ``n`` steps, in the order
    of a breadth-first bisection (middle, then quarters, ...). One numpy pass a level: the
    midpoints of disjoint intervals are new states, so nothing is seen twice (a loop in
    Python took 0.3 s for a segment at the finest resolution)."""
    a = np.zeros(1, dtype=np.int64)
    b = np.full(1, max(int(n), 0), dtype=np.int64)
    levels = []
    while True:
        keep = b - a >= 2
        a, b = a[keep], b[keep]
        if not len(a):
            break
        m = (a + b) // 2
        levels.append(m)
        a = np.stack([a, m], axis=1).ravel()
        b = np.stack([m, b], axis=1).ravel()
    return np.concatenate(levels) if levels else np.empty(0, dtype=np.int64)


class MotionChecker:
    """Batched validity checks of one robot's configurations in one scene (module
    docstring). ``lower``/``upper``: joint limits (default: the robot model's); ``margin``
    (mm): closer than that counts as a collision; ``exact``: confirm the spheres' hits on
    the real shapes (False: a flagged state counts as colliding, faster and more cautious).
    ``checks``/``exact_checks`` count the states checked. Segments: ``resolution`` sets
    the grid (``steps``); stretches of it are proved free by the distance they sweep, the
    rest checked state by state (module docstring)."""

    def __init__(self, collision_model: Any, scene: Any = None, *, lower=None, upper=None,
                 self_collision: bool = True, margin: float = 0.0, exact: bool = True) -> None:
        from planning.collision import CollisionScene, RobotCollisionModel

        if not isinstance(collision_model, RobotCollisionModel):
            raise TypeError("collision_model must be a RobotCollisionModel")
        if scene is not None and not isinstance(scene, CollisionScene):
            raise TypeError("scene must be a CollisionScene or None")
        if isinstance(margin, bool) or not isinstance(margin, int | float) \
                or not math.isfinite(margin) or margin < 0:
            raise FieldError(("margin",), "margin must be a finite number >= 0 (mm)")
        self.cm = collision_model
        self.scene = scene if scene is not None and len(scene) else None
        self.robot_model = (collision_model.source.model if collision_model.kind == "imported"
                            else collision_model.source)
        rm = self.robot_model
        self.dof = int(collision_model.dof)
        self.lower = np.array(rm.lower if lower is None else lower, dtype=float)
        self.upper = np.array(rm.upper if upper is None else upper, dtype=float)
        if self.lower.shape != (self.dof,) or self.upper.shape != (self.dof,):
            raise FieldError(("limits",), f"joint limits must have {self.dof} values")
        self.prismatic = np.array([not j.revolute for j in rm.joints], dtype=bool)
        #: Metric weight of each joint (1 per rad; 1 / PRISMATIC_SCALE per mm).
        self.weights = np.where(self.prismatic, 1.0 / PRISMATIC_SCALE, 1.0)
        #: Step weight of each joint (1 per rad; 1 / PRISMATIC_STEP per mm).
        self.step_weights = np.where(self.prismatic, 1.0 / PRISMATIC_STEP, 1.0)
        self.self_collision = bool(self_collision)
        self.margin = float(margin)
        self.exact = bool(exact)
        #: With ``exact`` off: ``(points (k, dof), radius)``, configurations within
        #: ``radius`` (weighted) of which still get the exact stage.
        self.exact_zone: tuple[np.ndarray, float] | None = None
        self.checks = 0
        self.exact_checks = 0
        #: ``time.perf_counter`` time after which segment checks answer "not free" (None:
        #: never); set by the planner for each phase of a plan.
        self.deadline: float | None = None
        self._orders: dict[int, np.ndarray] = {}
        self._k = _kernels()
        self._robot = self._scene = None
        if self._k is not None:
            self._robot = _robot_arrays(collision_model, self_collision)
            if self._robot is None:
                self._k = None
            else:
                self._scene = _scene_arrays(self.scene)
                if self._scene is None:
                    self._k = None
        self._q = np.empty(self.dof)
        self._fcl: _FastExact | None = None

    # ---- inputs --------------------------------------------------------------------------
    def batch(self, Q) -> tuple[np.ndarray, bool]:
        Q = np.asarray(Q, dtype=float)
        single = Q.ndim == 1
        Q2 = _kernel_array(Q[None] if single else Q)
        if Q2.ndim != 2 or Q2.shape[1] != self.dof:
            raise FieldError(("q",), f"configurations must have {self.dof} joint values")
        if not np.all(np.isfinite(Q2)):
            raise FieldError(("q",), "joint values must be finite")
        return Q2, single

    def within_limits(self, Q, tol: float = 1e-9) -> np.ndarray:
        """``(B,)`` whether each configuration is within the joint limits."""
        Q2, single = self.batch(Q)
        ok = np.all((Q2 >= self.lower - tol) & (Q2 <= self.upper + tol), axis=1)
        return bool(ok[0]) if single else ok

    # ---- checks --------------------------------------------------------------------------
    def free(self, Q):
        """Whether each configuration is collision-free: ``(dof,) -> bool``,
        ``(B, dof) -> (B,)`` (limits are not checked here: see ``within_limits``)."""
        Q2, single = self.batch(Q)
        out = np.empty(len(Q2), dtype=np.int64)
        self.checks += len(Q2)
        if self._k is None:
            from planning.collision import collides

            ok = ~np.asarray(collides(self.cm, Q2, self.scene, self.self_collision,
                                      exact=self.exact, margin=self.margin))
            return bool(ok[0]) if single else ok
        self._k.check_states(*self._robot[:7], Q2, self.margin, *self._robot[7:13],
                             *self._scene, self._robot[13], *self._robot[14:], out)
        ok = out == 0
        for b in np.flatnonzero(~ok):
            ok[b] = self._exact_free(Q2[b])
        return bool(ok[0]) if single else ok

    def _exact_free(self, q: np.ndarray, extra: float = 0.0) -> bool:
        """The exact stage of one flagged configuration (with ``exact`` off, only within
        ``exact_zone``), at the margin plus ``extra`` mm (a segment's sweep about a state:
        ``segment_free``)."""
        if not self.exact:
            zone = self.exact_zone
            if zone is None:
                return False
            d = (zone[0] - q) * self.weights
            if float(np.einsum("ij,ij->i", d, d).min()) > zone[1] ** 2:
                return False
        self.exact_checks += 1
        margin = self.margin + float(extra)
        k = self._k
        hits = np.empty((_HIT_CAP, 3), dtype=np.int64)
        M = np.empty((len(self.cm.names), 3, self._robot[6]))
        n = k.state_hits(*self._robot[:7], _kernel_array(q), margin,
                         *self._robot[7:13], *self._scene, self._robot[13],
                         *self._robot[14:], hits, M)
        if n >= _HIT_CAP:
            from planning.collision import collides

            return not bool(collides(self.cm, q, self.scene, self.self_collision, exact=True,
                                     margin=margin))
        # A mesh link against a box or cylinder of the scene is settled in compiled code, the
        # other pairs by FCL. At margin 0 the tests are FCL's yes/no. A sweep's proof
        # (``extra`` > 0) may refuse what is clear (the stretch is then checked more
        # finely), never accept what is not: the object grown by the margin on every side
        # contains every point within the margin of it, so triangles that miss the grown
        # object are farther than the margin.
        proof = extra > 0.0
        rest = []
        tri = self._mesh_triangles() if margin == 0.0 or proof else None
        if tri is not None:
            from planning.geometry.triangles import triangles_meet_object
        kind, T_inv, par = self._scene[1], self._scene[2], self._scene[3]
        for a, c, is_self in hits[:n]:
            a, c = int(a), int(c)
            if tri is not None and not is_self and tri.whole[a] and kind[c] in _SOLIDS:
                grown = par[c].copy()
                if margin > 0.0:
                    grown[:3 if kind[c] == _SOLIDS[0] else 2] += margin
                if triangles_meet_object(tri.tri, tri.lo, tri.hi, tri.cbox, tri.cstart,
                                         tri.cfirst[a], tri.cfirst[a + 1], M[a], T_inv[c],
                                         kind[c], grown):
                    return False
            else:
                rest.append((a, c, is_self))
        if not rest:
            return True
        if proof and tri is not None:
            # FCL's distance between meshes costs more than checking the stretch finely.
            return False
        from planning.collision import exact_stage

        stage = exact_stage(self.cm, self.scene)
        if self._fcl is None:
            self._fcl = _FastExact(stage)
        fast = self._fcl
        posed: dict[int, list] = {}
        for a, c, is_self in rest:
            if fast.ok and (is_self or stage.is_fcl(c)):
                if fast.collides(M, a, c, bool(is_self), posed, margin):
                    return False
            elif stage.pair_collides(M, a, c, bool(is_self), margin):
                return False
        return True

    def _mesh_triangles(self) -> Any:
        """The collision model's ``mesh_triangles`` (links all mesh of at most
        ``TRIANGLES_MAX`` triangles; larger meshes stay with FCL's bounding volume trees),
        None for a robot of capsules."""
        return self.cm.mesh_triangles(TRIANGLES_MAX)

    def steps(self, a: np.ndarray, b: np.ndarray, resolution: float) -> int:
        """Steps of the segment ``a``-``b`` so that no joint moves more than its step: the
        grid ``segment_free`` works on (its stretches proved by their sweep, module
        docstring)."""
        d = float(np.max(np.abs(b - a) * self.step_weights)) if self.dof else 0.0
        return max(1, int(math.ceil(d / resolution - 1e-12)))

    def _order(self, n: int) -> np.ndarray:
        order = self._orders.get(n)
        if order is None:
            order = bisection_order(n)
            # Only short orders are kept: fine resolutions give many long ones.
            if n <= _ORDER_CACHE_N and len(self._orders) < _ORDER_CACHE_SIZE:
                self._orders[n] = order
        return order

    def late(self) -> bool:
        """Whether the deadline has passed."""
        return self.deadline is not None and time.perf_counter() >= self.deadline

    def segment_free(self, a, b, resolution: float = DEFAULT_RESOLUTION,
                     ends: bool = False) -> bool:
        """Whether the straight segment ``a``-``b`` is free at joint steps of at most
        ``resolution`` (its interior; the end points too with ``ends``): with the compiled
        kernels, stretches of the grid proved free by the distance they sweep (module
        docstring) and the rest state by state."""
        a = _kernel_array(a)
        b = _kernel_array(b)
        if ends and not bool(np.all(self.free(np.stack([a, b])))):
            return False
        if self._k is not None:
            return self._segment_swept(a, b, resolution)
        n = self.steps(a, b, resolution)
        order = self._order(n)
        if len(order) == 0:
            return True
        for c in range(0, len(order), DEADLINE_CHUNK):
            if self.late():
                return False
            s = order[c:c + DEADLINE_CHUNK] / n
            if not bool(np.all(self.free(a + (b - a) * s[:, None]))):
                return False
        return True

    def _segment_swept(self, a: np.ndarray, b: np.ndarray, resolution: float) -> bool:
        """``segment_free``'s interior on the compiled kernels: the grid of ``steps``, its
        stretches proved free by the distance they sweep where the margin allows
        (``planning.motion._rrt._segment_free``), the exact stage in Python."""
        import planning.motion._rrt as rr

        work = self.__dict__.get("_work")
        if work is None:
            work = rr.make_work(self._robot, self._scene,
                                np.ascontiguousarray(self.step_weights))
            self._work = work
        count, mode = work[-2], work[-1]
        saved = mode.copy()
        local = (getattr(rr._local, "checker", None), getattr(rr._local, "deadline", None))
        mode[0] = 1                 # flagged states to ``_exact_free`` (which knows ``exact``)
        mode[2] = 0 if self.deadline is None else 1
        mode[3] = 0
        rr._local.checker = self
        rr._local.deadline = self.deadline
        c0 = int(count[0])
        try:
            return bool(rr._segment_free(self._robot, self._scene, a, b, self.weights,
                                         float(resolution), self.margin, self._q, work))
        finally:
            self.checks += int(count[0]) - c0
            mode[:] = saved
            rr._local.checker, rr._local.deadline = local

    def path_free(self, path, resolution: float = DEFAULT_RESOLUTION) -> bool:
        """Whether every waypoint of ``path (K, dof)`` and every straight segment between
        consecutive ones is free."""
        P, _ = self.batch(path)
        if not bool(np.all(self.free(P))):
            return False
        return all(self.segment_free(P[i], P[i + 1], resolution) for i in range(len(P) - 1))

    def pairs(self, q) -> list[tuple[str, str]]:
        """The colliding pairs of one configuration (link, object id) or (link, link), by the
        exact check (empty when it is free)."""
        from planning.collision import check

        q2, _ = self.batch(q)
        report = check(self.cm, q2[0], self.scene, self.self_collision, exact=True,
                       margin=self.margin)
        return [tuple(p) for p in report.pairs] if report.collides else []

    def clearance(self, path, resolution: float = DEFAULT_RESOLUTION, most: int = 100,
                  reach: float = 1000.0) -> float | None:
        """Least clearance (mm) of the robot from the scene and from itself over states of
        ``path`` no farther apart than ``resolution`` (at most ``most`` of them, evenly
        spread): exact (FCL) at the states and pairs the sphere model's lower bounds cannot
        rule out, so the answer is the exact least distance over those states, capped at
        ``reach``. None with nothing to collide with."""
        P, _ = self.batch(path)
        if self.scene is None and not (self.self_collision and len(self.cm.pairs)):
            return None
        Q = segment_states(P, [self.steps(P[i], P[i + 1], resolution)
                               for i in range(len(P) - 1)], most)
        if self._k is None:
            from planning.collision import check

            rep = check(self.cm, Q, self.scene, self.self_collision, exact=True,
                        exact_distance=True, margin=self.margin)
            return float(min(np.min(rep.distance), reach))
        # Nearest first: with a small cap the sphere bounds prune most pairs and states at
        # once; a larger cap is tried only when nothing lies within the smaller one.
        for cap in CLEARANCE_CAPS:
            if cap >= reach:
                break
            best = self._least_distance(Q, cap)
            if best < cap:
                return best
        return self._least_distance(Q, reach)

    def _least_distance(self, Q: np.ndarray, reach: float) -> float:
        """The exact least distance over the states ``Q`` if it is below ``reach``, else
        ``reach``: sphere lower bounds capped at ``reach`` for every state and pair, then the
        exact distance of (state, pair)s in the order of their bounds, until the bounds reach
        the least exact distance found."""
        r, sc = self._robot, self._scene
        L, n_o = len(self.cm.names), len(sc[1])
        S = len(Q)
        out_scene = np.empty((S, L, n_o))
        out_self = np.empty((S, len(r[13])))
        out_tab = np.empty((S, len(r[14])))
        M_all = np.empty((S, L, 3, r[6]))
        self._k.states_bounds(*r[:7], np.ascontiguousarray(Q, dtype=float), reach,
                              *r[7:13], *sc, *r[13:], out_scene, out_self, out_tab, M_all)
        # Best first over every (state, pair) whose bound is below the cap: the exact
        # distance of the lowest bound first, none once the bounds reach the least exact
        # distance found (the same answer as state by state, fewer FCL calls, no Python
        # loop over the states).
        s_o, l_o, o_o = np.nonzero(out_scene < reach)
        s_p, k_p = np.nonzero(out_self < reach)
        s_t, k_t = np.nonzero(out_tab < reach)
        bound = np.concatenate([out_scene[s_o, l_o, o_o], out_self[s_p, k_p],
                                out_tab[s_t, k_t]])
        state = np.concatenate([s_o, s_p, s_t])
        a = np.concatenate([l_o, r[13][k_p, 0], r[14][k_t, 6]]).astype(np.intp)
        c = np.concatenate([o_o, r[13][k_p, 1], r[14][k_t, 7]]).astype(np.intp)
        is_self = np.r_[np.zeros(len(s_o), bool), np.ones(len(s_p) + len(s_t), bool)]
        best = reach
        for i in np.argsort(bound, kind="stable"):
            if bound[i] >= best:
                break
            best = min(best, self._exact_distance(M_all[state[i]], int(a[i]), int(c[i]),
                                                  bool(is_self[i]), best))
        return float(best)

    def _exact_distance(self, M: np.ndarray, a: int, c: int, is_self: bool,
                        reach: float) -> float:
        from planning.collision import exact_stage

        stage = exact_stage(self.cm, self.scene)
        if self._fcl is None:
            self._fcl = _FastExact(stage)
        fast = self._fcl
        if fast.ok and (is_self or stage.is_fcl(c)):
            return fast.distance(M, a, c, is_self)
        return stage.pair_distance(M, a, c, is_self, reach=reach)


class _FastExact:
    """The exact stage with the FCL objects of every rigid body (an imported robot's links,
    attached objects) built once and posed in place, and a capsule link's capsule built
    from its state in scalar arithmetic (numpy's small-array calls cost more than FCL)."""

    def __init__(self, stage: Any) -> None:
        import fcl

        self.fcl = fcl
        self.stage = stage
        self.ok = True
        robot = stage.robot
        self.first = robot.first_rigid
        self.radius = [float(r) for r in robot.model.capsule_radius[:self.first]]
        self.links: list[list[tuple[Any, np.ndarray]]] = []
        for shapes in robot.shapes:
            self.links.append([(fcl.CollisionObject(sh.geom), np.asarray(sh.T, float))
                               for sh in shapes])

    def _pose(self, M: np.ndarray, k: int, posed: dict) -> list:
        objs = posed.get(k)
        if objs is None:
            if k < self.first:
                objs = [self._capsule(M[k], self.radius[k])]
            else:
                T = np.eye(4)
                T[:3] = M[k]
                objs = []
                for obj, G in self.links[k - self.first]:
                    W = T @ G
                    obj.setTransform(self.fcl.Transform(W[:3, :3], W[:3, 3]))
                    objs.append(obj)
            posed[k] = objs
        return objs

    def _capsule(self, Mk: np.ndarray, r: float) -> Any:
        """The FCL capsule of a capsule link's state ``[start | run]`` or
        ``[run | 0 | 0 | start]``: radius ``r`` along the run, centred on its middle."""
        fcl = self.fcl
        (ax, ay, az), (ex, ey, ez) = ((Mk[:, 3], Mk[:, 0]) if Mk.shape[1] == 4
                                      else (Mk[:, 0], Mk[:, 1]))
        L = math.sqrt(ex * ex + ey * ey + ez * ez)
        if L == 0:
            return fcl.CollisionObject(fcl.Sphere(r), fcl.Transform(np.eye(3),
                                                                     np.array([ax, ay, az])))
        zx, zy, zz = ex / L, ey / L, ez / L
        if abs(zx) < 0.9:     # x = (1, 0, 0) x z
            xx, xy, xz = 0.0, -zz, zy
        else:                 # x = (0, 1, 0) x z
            xx, xy, xz = zz, 0.0, -zx
        n = math.sqrt(xx * xx + xy * xy + xz * xz)
        xx, xy, xz = xx / n, xy / n, xz / n
        yx, yy, yz = zy * xz - zz * xy, zz * xx - zx * xz, zx * xy - zy * xx
        R = np.array([[xx, yx, zx], [xy, yy, zy], [xz, yz, zz]])
        p = np.array([ax + 0.5 * ex, ay + 0.5 * ey, az + 0.5 * ez])
        return fcl.CollisionObject(fcl.Capsule(r, L), fcl.Transform(R, p))

    def collides(self, M: np.ndarray, a: int, c: int, is_self: bool, posed: dict,
                 margin: float) -> bool:
        A = self._pose(M, a, posed)
        B = self._pose(M, c, posed) if is_self else [self.stage.item(c)]
        return any(self.stage.collide(o1, o2, margin) for o1 in A for o2 in B)

    def distance(self, M: np.ndarray, a: int, c: int, is_self: bool) -> float:
        posed: dict = {}
        A = self._pose(M, a, posed)
        B = self._pose(M, c, posed) if is_self else [self.stage.item(c)]
        return min(self.stage.distance(o1, o2) for o1 in A for o2 in B)


# ---- arrays for the kernels ---------------------------------------------------------------------
def _kernel_array(x: Any) -> np.ndarray:
    """``x`` as a contiguous, writable float64 array: numba compiles a kernel anew for a
    read-only array (a model's frozen limits, a broadcast), tens of seconds the warm-up
    did not pay, so a read-only one is copied."""
    x = np.ascontiguousarray(x, dtype=float)
    return x if x.flags.writeable else x.copy()


def _kernels():
    from kinematics import fast

    if fast.kernels() is None:
        return None
    try:
        import planning.motion._kernels as k
    except ImportError:  # pragma: no cover - numba missing
        return None
    return k


def _partials(chain: Any, q: np.ndarray) -> np.ndarray:
    """``P_j (n + 1, 4, 4)`` of the kernels' layout at one configuration."""
    n = len(q)
    out = np.empty((n + 1, 4, 4))
    T = np.eye(4)
    out[0] = T
    for i in range(n):
        Ci = np.eye(4)
        Ci[:3] = chain.C[i]
        T = T @ Ci
        x = q[i] + chain.offset[i]
        M = np.eye(4)
        if chain.prismatic[i]:
            M[2, 3] = x
        else:
            c, s = math.cos(x), math.sin(x)
            M[:2, :2] = [[c, -s], [s, c]]
        T = T @ M
        out[i + 1] = T
    return out


def _calibrate(chain: Any, targets, dof: int, lower: np.ndarray, upper: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray] | None:
    """``body (E,)``, ``X (E, 3, 4)`` such that frame ``e`` is ``P_body[e] @ X[e]`` at
    every configuration, found at a few seeded configurations; None if some frame is not
    carried by one body of the chain."""
    rng = np.random.default_rng(20261129)
    lo = np.where(np.isfinite(lower), lower, -math.pi)
    hi = np.where(np.isfinite(upper), upper, math.pi)
    Q = lo + (hi - lo) * rng.random((4, dof))
    F = targets(Q)                       # (4, E, 4, 4)
    P = np.array([_partials(chain, q) for q in Q])   # (4, n + 1, 4, 4)
    E = F.shape[1]
    body = np.empty(E, dtype=np.int64)
    X = np.empty((E, 3, 4))
    scale = max(1.0, float(np.abs(F[..., :3, 3]).max()))
    for e in range(E):
        for j in range(dof + 1):
            Xe = np.linalg.inv(P[0, j]) @ F[0, e]
            if np.abs(P[:, j] @ Xe - F[:, e]).max() <= 1e-9 * scale:
                body[e], X[e] = j, Xe[:3]
                break
        else:
            return None
    return body, X


def _robot_arrays(cm: Any, self_collision: bool) -> tuple | None:
    """The robot's arrays in the kernels' argument order, or None when its links cannot be
    carried by the chain layout. A state of width 4 is a frame ``P_body @ X`` (``X``
    constant, not necessarily rigid): a link's or an attachment's pose, or a capsule's
    ``[run | 0 | 0 | start]`` when both its ends ride on one body (a revolute joint's link;
    a prismatic joint's link with attachments on the robot: the Python checks)."""
    from kinematics.fast import chain_of
    from kinematics.fk import fk_frames

    rm = cm.source.model if cm.kind == "imported" else cm.source
    chain = chain_of(rm)
    lower, upper = np.asarray(rm.lower, float), np.asarray(rm.upper, float)
    if cm.width == 4:   # link frames (imported robots; any robot with attachments)
        cal = _calibrate(chain, cm.state_frames, cm.dof, lower, upper)
        ends = np.zeros(len(cm.names), dtype=np.int64)
        w = 4
    else:
        cal = _calibrate(chain, lambda Q: fk_frames(rm, Q), cm.dof, lower, upper)
        ends = np.ascontiguousarray(cm.capsule_link, dtype=np.int64)
        w = 2
    if cal is None:
        return None
    body, X = cal
    t = cm.tree
    c = np.ascontiguousarray
    if self_collision and len(cm.pairs):
        pairs = c(cm.pairs[cm.sphere_pairs], dtype=np.int64).reshape(-1, 2)
        tab_i, tab_f, values = _tables(cm)
    else:
        pairs = np.empty((0, 2), dtype=np.int64)
        tab_i, tab_f, values = np.empty((0, 8), np.int64), np.empty((0, 6)), np.empty(0)
    return (c(chain.C), c(chain.prismatic), c(chain.offset), c(body), c(X), ends, w,
            c(t.root), c(t.root_r), c(t.group), c(t.group_r), c(t.leaf), c(t.leaf_r),
            pairs, tab_i, tab_f, values)


def _tables(cm: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    tab_i = np.zeros((len(cm.tables), 8), dtype=np.int64)
    tab_f = np.zeros((len(cm.tables), 6))
    values = []
    first = 0
    for t, x in enumerate(cm.tables):
        k = len(x.joints)
        if k not in (1, 2):
            raise ValueError("pair tables over one or two joints only")
        tab_i[t, :2] = -1
        tab_i[t, :k] = x.joints
        tab_i[t, 2:2 + k] = x.shape
        tab_i[t, 4], tab_i[t, 5], tab_i[t, 6], tab_i[t, 7] = first, k, x.a, x.b
        tab_f[t, :k] = x.lo
        tab_f[t, 2:2 + k] = x.step
        tab_f[t, 4:4 + k] = x.rho
        values.append(np.asarray(x.values, dtype=float).ravel())
        first += values[-1].size
    return tab_i, tab_f, (np.concatenate(values) if values else np.empty(0))


def _scene_arrays(scene: Any) -> tuple:
    """``(has_scene, kind, T_inv, par, aabb, grid, grid_meta, scene_box, balls, cells,
    set_meta)`` of a ``CollisionScene`` (or empty ones); None when one of its shapes has no
    compiled kernel."""
    if scene is None:
        return (False, np.zeros(0, np.int64), np.zeros((0, 3, 4)), np.zeros((0, 4)),
                np.zeros((0, 6)), np.full(1, np.inf), np.array([0, 0, 0, 1, 1, 1, 1.0]),
                np.array([-np.inf] * 3 + [np.inf] * 3), np.zeros((0, 4)),
                np.zeros(1, np.int64), np.zeros((0, 9)))
    from planning.geometry.compiled import kernel_objects

    cs = scene.compiled()
    packed = kernel_objects(cs.objects, cs.sets, cs.bounds)
    if packed is None:  # a shape without a compiled kernel: the Python checks
        return None
    kind, T_inv, par, aabb, balls, cells, set_meta = packed
    if cs.n > GRID_OBJECTS:
        lo, h, shape, values = cs.grid
        grid_meta = np.r_[lo, h, shape].astype(float)
    else:   # few objects: tested one by one, no grid to build
        values, grid_meta = np.full(1, np.inf), np.array([0, 0, 0, 0, 1, 1, 1.0])
    return (True, kind, T_inv, par, aabb, np.ascontiguousarray(values, dtype=float),
            grid_meta, np.r_[cs.lo, cs.hi].astype(float), balls, cells, set_meta)

