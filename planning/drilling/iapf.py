"""Improved artificial potential field (IAPF) in joint space, paper 002 section 3.3.

The search runs in the arm's normalised transfer space (``space.ArmSpace``: swing, pitch,
telescope, each scaled to its range). Our reading of eqs. 8-13:

* **Attraction per joint with a threshold** (eqs. 8-9): for joint i with
  ``Delta_i = u_goal,i - u_i``, ``F_att(i) = delta * Delta_i`` while ``|Delta_i| <= d*``
  (quadratic well) and ``delta * d* * Delta_i / |Delta_i|`` beyond (conic: bounded pull), so
  every joint is pulled towards its own goal value, not only the drill tip.
* **Repulsion that vanishes at the goal** (eqs. 10-13, the form of Ge and Cui): for each
  link l whose envelope is within the influence distance ``d_A`` of an obstacle (clearance
  ``d_l``, metres), ``U_rep = lambda / 2 (1 / d_l - 1 / d_A)^2 rho`` with ``rho`` the
  joint-space distance to the goal. Its negative gradient has the paper's two parts:
  ``F_rep1 = lambda (1 / d_l - 1 / d_A) rho / d_l^2`` along ``n_OR`` (away from the
  obstacle: the joint-space gradient of ``d_l``, by finite differences, normalised) and
  ``F_rep2 = lambda / 2 (1 / d_l - 1 / d_A)^2`` along ``n_RG`` (towards the goal). The
  first vanishes as ``rho -> 0``, so the goal stays reachable next to an obstacle (the
  paper's fix for GNRON), and the second pulls the same way as attraction (its fix for local
  minima). Eq. 10 prints the first power of ``(1 / d - 1 / d_A)``; eq. 13, whose gradient it
  is, needs the square, which we use. The sums run over the links, as eqs. 10 and 12 sum
  over the joints.

The arm moves ``step`` (normalised) along the total force each iteration (``far_step``
while every link is beyond the influence distance: 0.02 moves no point of the arm more than
about 0.45 m, less than the 0.8 m it is away), never closer to an obstacle than ``safety`` mm
(a step that would is halved, then refused). If the distance to the goal stops falling for
``stall_window`` steps (a residual local minimum), a slide along the nearest obstacle is taken
(the goal direction projected onto the obstacle's tangent plane in joint space, a seeded
random tangent when the goal is straight behind it), at most ``max_escapes`` times; after
that the planner reports failure rather than return a path that does not reach the goal.

``ClassicAPF`` is the conventional field the paper improves on (Khatib 1986), in the same
joint space: a quadratic attraction ``F_att = delta (u_goal - u)`` on the whole joint vector
and the repulsion ``U_rep = lambda / 2 (1 / d_l - 1 / d_A)^2``, whose force
``lambda (1 / d_l - 1 / d_A) / d_l^2`` along ``n_OR`` does not vanish at the goal. It is a
baseline for ``benchmarks/bench_papers.py``'s collision-probability experiment, not a
registered move planner. ``follow_field`` descends either field without the planner's
safeguards (no step refused for coming too close, no escapes), which is what a potential
field method is on its own: the field alone has to keep the arm clear.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from kinematics.errors import FieldError

from ..status import PlanStatus
from .space import ArmSpace, Obstacles

__all__ = ["IAPF", "ClassicAPF", "FieldRun", "MovePath", "follow_field"]


@dataclass(frozen=True)
class MovePath:
    """The joint-space path of one arm move, as ``IAPF`` and ``RRTConnect`` plan it:
    ``q (K, 3)`` planned joints (rad, rad, mm) from start to goal, ``status`` (``ok``;
    ``collision``: the start or goal configuration collides; ``invalid_input``: it leaves
    the joint limits (RRT-Connect checks); ``no_path``: stuck in a local minimum;
    ``budget_spent``: out of steps or iterations), a message, the smallest clearance along
    the path points (mm) and the number of planner iterations."""

    q: np.ndarray
    status: PlanStatus
    message: str
    min_clearance: float
    iterations: int
    planner: str
    extra: dict = field(default_factory=dict)

    @property
    def success(self) -> bool:
        return self.status is PlanStatus.OK


@dataclass(frozen=True)
class IAPF:
    """IAPF parameters. Distances in the potentials are in metres; ``influence`` and
    ``safety`` are given in mm. None of these is printed in the paper (ours)."""

    attraction_gain: float = field(default=1.0, metadata={"gt": 0.0, "le": 1e3})
    goal_threshold: float = field(default=0.3, metadata={
        "gt": 0.0, "le": 2.0, "description": "normalised joint distance"})
    repulsion_gain: float = field(default=0.01, metadata={"ge": 0.0, "le": 1e3})
    influence: float = field(default=800.0, metadata={"gt": 0.0, "le": 1e5, "description": "mm"})
    step: float = field(default=0.005, metadata={
        "ge": 1e-5, "le": 1.0, "description": "normalised"})
    far_step: float = field(default=0.02, metadata={
        "ge": 1e-5, "le": 1.0, "description": "normalised"})
    safety: float = field(default=100.0, metadata={"ge": 0.0, "le": 2000.0, "description": "mm"})
    max_steps: int = field(default=4000, metadata={"ge": 1, "le": 100_000})
    stall_window: int = field(default=40, metadata={"ge": 1, "le": 10_000})
    escape_steps: int = field(default=20, metadata={"ge": 0, "le": 10_000})
    max_escapes: int = field(default=10, metadata={"ge": 0, "le": 1000})
    gradient_step: float = field(default=1e-4, metadata={
        "ge": 1e-9, "le": 0.1, "description": "normalised"})

    def __post_init__(self) -> None:
        for name in ("attraction_gain", "goal_threshold", "influence", "step", "far_step",
                     "gradient_step"):
            if not getattr(self, name) > 0:
                raise FieldError(("planner_params", name),
                                 f"planner_params.{name}: must be positive")
        for name in ("repulsion_gain", "safety"):
            if getattr(self, name) < 0:
                raise FieldError(("planner_params", name), f"planner_params.{name}: must be >= 0")
        if self.max_steps < 1:
            raise FieldError(("planner_params", "max_steps"),
                             "planner_params.max_steps: must be >= 1")

    def forces(self, space: ArmSpace, obstacles: Obstacles, u: np.ndarray,
               u_goal: np.ndarray, clear_links: np.ndarray) -> np.ndarray:
        """Total force (normalised joint space) at ``u (3,)`` given the per-link clearance
        ``clear_links (L,)`` mm there. Eqs. 9, 12 and 13."""
        delta = u_goal - u
        ad = np.abs(delta)
        big = ad > self.goal_threshold
        F = np.where(big, self.attraction_gain * self.goal_threshold * np.sign(delta),
                     self.attraction_gain * delta)
        rho = float(np.linalg.norm(delta))
        near = np.flatnonzero(clear_links < self.influence)
        if len(near) == 0 or self.repulsion_gain == 0 or rho == 0:
            return F
        h = self.gradient_step
        probes = np.clip(u[None, :] + h * np.eye(3), 0.0, 1.0)
        c_probe = space.link_clearance(space.from_u(probes), obstacles)  # (3, L)
        grad = (c_probe[:, near] - clear_links[near][None, :]) / h  # (3, n_near) mm/unit
        d = np.maximum(clear_links[near], 1.0) / 1000.0  # m
        dA = self.influence / 1000.0
        inv = 1.0 / d - 1.0 / dA
        lam = self.repulsion_gain
        grad = np.where(np.isfinite(grad), grad, 0.0)
        norms = np.linalg.norm(grad, axis=0)
        n_or = np.where(norms > 0, grad / np.where(norms > 0, norms, 1.0), 0.0)
        F_rep1 = (lam * inv * rho / d**2)[None, :] * n_or
        F_rep2 = (0.5 * lam * inv**2)[None, :] * (delta / rho)[:, None]
        return F + F_rep1.sum(axis=1) + F_rep2.sum(axis=1)

    def plan(self, space: ArmSpace, obstacles: Obstacles, q_start, q_goal,
             rng: np.random.Generator) -> MovePath:
        """Path of the planned joints from ``q_start (3,)`` to ``q_goal (3,)``."""
        u = space.to_u(np.asarray(q_start, dtype=float)[None])[0]
        ug = space.to_u(np.asarray(q_goal, dtype=float)[None])[0]

        def clear(uu: np.ndarray) -> tuple[np.ndarray, bool]:
            c, valid = space.evaluate(space.from_u(uu[None]), obstacles)
            return c[0], bool(valid[0])

        (c_start, _), (c_goal, _) = clear(u), clear(ug)
        if c_goal.min() < 0:
            return self._fail(space, [u], c_goal.min(), 0, "goal configuration collides",
                              PlanStatus.COLLISION)
        if c_start.min() < 0:
            return self._fail(space, [u], c_start.min(), 0, "start configuration collides",
                              PlanStatus.COLLISION)
        margin = min(self.safety, float(c_start.min()), float(c_goal.min()))
        path = [u.copy()]
        c_links = c_start
        min_c = float(c_links.min())
        best_rho, quiet, escapes = np.inf, 0, 0
        for k in range(self.max_steps):
            rho = float(np.linalg.norm(ug - u))
            far = bool(c_links.min() > self.influence)
            if rho <= (self.far_step if far else self.step):
                path.append(ug.copy())
                min_c = min(min_c, float(c_goal.min()))
                return MovePath(space.from_u(np.array(path)), PlanStatus.OK, "reached the goal",
                                  min_c, k + 1, "iapf", {"escapes": escapes})
            F = self.forces(space, obstacles, u, ug, c_links)
            norm = float(np.linalg.norm(F))
            moved = False
            if norm > 1e-12:
                s = self.far_step if far else self.step
                for _ in range(4):
                    u_new = np.clip(u + s * F / norm, 0.0, 1.0)
                    c_new, valid = clear(u_new)
                    if valid and c_new.min() >= margin:
                        moved = True
                        break
                    s *= 0.5
            if moved:
                u, c_links = u_new, c_new
                path.append(u.copy())
                min_c = min(min_c, float(c_links.min()))
            rho_new = float(np.linalg.norm(ug - u))
            if rho_new < best_rho - 0.1 * self.step:
                best_rho, quiet = rho_new, 0
            else:
                quiet += 1
            if quiet >= self.stall_window or not moved:
                escapes += 1
                if escapes > self.max_escapes:
                    return self._fail(space, path, min_c, k + 1,
                                      f"stuck in a local minimum {rho_new:.3f} from the goal "
                                      f"after {self.max_escapes} escapes", PlanStatus.NO_PATH)
                u, c_links = self._escape(space, obstacles, u, ug, c_links, path, margin, rng)
                min_c = min(min_c, float(c_links.min()))
                quiet, best_rho = 0, float(np.linalg.norm(ug - u))
        return self._fail(space, path, min_c, self.max_steps,
                          f"goal not reached in {self.max_steps} steps", PlanStatus.BUDGET_SPENT)

    def _escape(self, space, obstacles, u, ug, c_links, path, margin, rng):
        """Slide along the nearest obstacle (a residual local minimum): ``escape_steps`` steps
        along the direction to the goal projected onto the obstacle's tangent plane in joint
        space (re-projected at every step, so the arm keeps to one side), pushed out when
        closer than twice the margin. A random tangent is used when the goal lies straight
        behind the obstacle."""
        h = self.gradient_step
        t_dir = None
        for _ in range(self.escape_steps):
            probes = np.clip(u[None, :] + h * np.eye(3), 0.0, 1.0)
            c_probe = space.link_clearance(space.from_u(probes), obstacles)
            l = int(np.argmin(c_links))
            g = (c_probe[:, l] - c_links[l]) / h
            gn = float(np.linalg.norm(g))
            n = g / gn if gn > 0 else np.zeros(3)
            if t_dir is None:
                w = ug - u
                t_dir = w - (w @ n) * n
                if np.linalg.norm(t_dir) < 1e-6 * max(np.linalg.norm(w), 1e-12):
                    r = rng.normal(size=3)
                    t_dir = r - (r @ n) * n
            t_dir = t_dir - (t_dir @ n) * n
            if np.linalg.norm(t_dir) < 1e-12:
                break
            d = t_dir / np.linalg.norm(t_dir)
            if c_links.min() < 2 * margin + 1.0:
                d = d + 0.5 * n
                d /= np.linalg.norm(d)
            moved = False
            s = self.step
            for _ in range(4):
                u_new = np.clip(u + s * d, 0.0, 1.0)
                c, valid = space.evaluate(space.from_u(u_new[None]), obstacles)
                if valid[0] and c[0].min() >= margin:
                    u, c_links = u_new, c[0]
                    path.append(u.copy())
                    moved = True
                    break
                s *= 0.5
            if not moved:
                t_dir = None  # blocked along this side: pick again next time
                break
        return u, c_links

    @staticmethod
    def _fail(space, path, min_c, iterations, message, status: PlanStatus) -> MovePath:
        return MovePath(space.from_u(np.array(path)), status, message, float(min_c),
                          iterations, "iapf")


@dataclass(frozen=True)
class ClassicAPF:
    """The conventional artificial potential field (Khatib): quadratic attraction, repulsion
    ``lambda (1 / d - 1 / d_A) / d^2`` per link within ``influence`` (distances in metres in
    the potentials, ``influence`` in mm). The gains and steps default to ``IAPF``'s, so the
    two fields differ only in their shape."""

    attraction_gain: float = 1.0
    repulsion_gain: float = 0.01
    influence: float = 800.0
    step: float = 0.005
    far_step: float = 0.02
    max_steps: int = 4000
    stall_window: int = 40
    gradient_step: float = 1e-4

    def forces(self, space: ArmSpace, obstacles: Obstacles, u: np.ndarray,
               u_goal: np.ndarray, clear_links: np.ndarray) -> np.ndarray:
        """Total force at ``u (3,)`` given the per-link clearance ``clear_links (L,)`` mm."""
        F = self.attraction_gain * (u_goal - u)
        near = np.flatnonzero(clear_links < self.influence)
        if len(near) == 0 or self.repulsion_gain == 0:
            return F
        h = self.gradient_step
        probes = np.clip(u[None, :] + h * np.eye(3), 0.0, 1.0)
        c_probe = space.link_clearance(space.from_u(probes), obstacles)
        grad = (c_probe[:, near] - clear_links[near][None, :]) / h
        grad = np.where(np.isfinite(grad), grad, 0.0)
        norms = np.linalg.norm(grad, axis=0)
        n_or = np.where(norms > 0, grad / np.where(norms > 0, norms, 1.0), 0.0)
        d = np.maximum(clear_links[near], 1.0) / 1000.0
        inv = 1.0 / d - 1.0 / (self.influence / 1000.0)
        return F + ((self.repulsion_gain * inv / d**2)[None, :] * n_or).sum(axis=1)


@dataclass(frozen=True)
class FieldRun:
    """A descent of a potential field: the normalised path ``u (K, 3)``, whether it got
    within one step of the goal, and the steps taken."""

    u: np.ndarray
    reached: bool
    steps: int


def follow_field(field, space: ArmSpace, obstacles: Obstacles, q_start, q_goal) -> FieldRun:
    """Descend ``field`` (an ``IAPF`` or ``ClassicAPF``) from ``q_start (3,)`` towards
    ``q_goal (3,)``: a step of ``step`` (``far_step`` while every link is beyond the
    influence distance) along the force, whatever the clearance there, until within one step
    of the goal, ``max_steps``, or no progress towards the goal over ``stall_window`` steps
    (a local minimum)."""
    u = space.to_u(np.asarray(q_start, dtype=float)[None])[0]
    ug = space.to_u(np.asarray(q_goal, dtype=float)[None])[0]
    path = [u.copy()]
    best, quiet = np.inf, 0
    for k in range(field.max_steps):
        c = space.link_clearance(space.from_u(u[None]), obstacles)[0]
        s = field.far_step if c.min() > field.influence else field.step
        rho = float(np.linalg.norm(ug - u))
        if rho <= s:
            path.append(ug.copy())
            return FieldRun(np.array(path), True, k + 1)
        F = field.forces(space, obstacles, u, ug, c)
        norm = float(np.linalg.norm(F))
        if norm < 1e-12:
            break
        u = np.clip(u + s * F / norm, 0.0, 1.0)
        path.append(u.copy())
        if rho < best - 0.1 * field.step:
            best, quiet = rho, 0
        else:
            quiet += 1
            if quiet >= field.stall_window:
                break
    return FieldRun(np.array(path), False, len(path) - 1)
