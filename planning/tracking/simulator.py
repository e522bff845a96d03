"""Tool-path tracking of a redundant arm by a PI resolved-rate law (paper 003, eqs. 1-13, 24).

At every control step ``k`` (period ``dt``) the tool position error ``e = x_d - x`` (mm, world
frame) feeds the PI law of eq. 1, ``delta = Kp e + ki * integral(e)`` (mm/s), and the joint
rates come from the weighted, damped inverse of the three position rows ``J (3, dof)`` of the
Jacobian (eq. 13)::

    qd = W^-1 J^T (J W^-1 J^T + lambda I)^-1 delta,     W = diag(w_i)   (eqs. 6-7)

with the joint-limit weights of eq. 8: ``w_i = 1 + |dH/dq_i|`` while ``|dH/dq_i|`` grows (the
joint moves towards a limit) and 1 otherwise, ``dH/dq_i`` being eq. 10
(``kinematics.ik.numeric.limit_gradient``). If any joint would exceed its speed limit
(0.1 rad/s for the 9-DOF arm) the whole ``qd`` vector is scaled down, which keeps the tool's
direction of motion; every such step is counted in ``TrackingResult.saturated_steps``. Then
``q <- clip(q + qd dt, lower, upper)``. Fitness (eq. 24) is the mean Euclidean tool error over
the ``n + 1`` samples ``t_k = k dt``, in mm.

Reading of the printed gains. The paper prints ``kp`` as a 2-vector and ``ki`` as a scalar
(line: kp = [0.2784e-4, 30.6587], ki = [0.3399]; curve: kp = [174.7392, 143.3465],
ki = [2.917e3]) but eq. 1 has one scalar kp, and it never says what the two entries multiply.
We read them as per-axis-group proportional gains: ``kp[0]`` on the horizontal error
components (x, y) and ``kp[1]`` on the vertical one (z); ``ki`` acts on all three. So
``Kp = diag(kp[0], kp[0], kp[1])`` and the tuned vector is ``(kp_xy, kp_z, ki)``. It keeps the
law a pure PI (eq. 2's Lyapunov argument holds per axis, for ``kp, ki > 0``), gives the
tuners the three numbers the paper prints, and does not smuggle a feed-forward or derivative
term into "PI" (which would make the tuned PI the project's default controller below). The
paper's own numbers cannot be reused: its gains depend on its unstated units, step and task.

Controllers. ``"pi"`` is the paper's law. ``"default"`` is the project's best controller:
the same PI plus velocity feed-forward of the desired path,
``delta = (x_d(t_{k+1}) - x_d(t_k)) / dt + Kp e + ki * integral(e)``. The secant feed-forward
is the desired velocity to O(dt) and cancels the lag that any PI has on a moving target, so
only the arm's second-order (curvature) error over one step is left for the PI to correct.

Tasks (the paper prints no sizes; these are ours, chosen so that the peak joint speed is
0.03 rad/s, as in its Fig. 7). Both start at rest at the tool position of the start
configuration and follow a minimum-jerk (quintic) timing, so they also end at rest:

* ``LineTask``: 200 mm along ``(0.48, 0.6, -0.64)`` (towards the base axis and down) in 20 s
  (peak tool speed 18.8 mm/s).
* ``EllipseTask``: one lap of a 150 x 100 mm ellipse in the vertical x-z plane through the
  start point, major axis vertical, in 30 s (peak tool speed 50 mm/s); the start point is the
  top end of the major axis.

The start configuration (default) is the mid-configuration with every second joint bent by
1/8 of its range: for the 9-DOF arm, the pitch joints 2, 4, 6, 8 at 30 deg, which puts the
tool at (0, -870, 540) mm, well inside the reach and clear of the straight (singular) pose.
The control period is 0.1 s.

What the tuners find. For a discrete PI on this (nearly integrator) plant the closed loop is
stable for ``kp dt < 2`` and ``ki dt^2 + 2 kp dt < 4``, and on smooth rest-to-rest paths the
mean error falls as ``1/ki``: the optimum of eq. 24 lies at small ``kp`` and ``ki`` near the
stability edge. The tuners' ``GainBounds`` (``planning.tracking.tuning``) therefore keep
``kp >= 0.5 /s`` (eq. 4 needs ``kp > 0``; at ``kp = 0`` the discrete loop is undamped), so
tuned gains stay asymptotically stable.

Everything is vectorised over a population of ``P`` gain candidates: the state is
``q (P, dof)``, so one call simulates a whole optimiser population.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from kinematics.ik.numeric import limit_gradient
from kinematics.jacobian import PositionJacobian
from kinematics.model import RobotModel

__all__ = [
    "LineTask",
    "EllipseTask",
    "Task",
    "Controller",
    "PIGains",
    "TrackingConfig",
    "TrackingResult",
    "PAPER_PI_GAINS",
    "DEFAULT_GAINS",
    "UNTUNED_PI_GAINS",
    "NO_PI_GAINS",
    "MAX_STEPS",
    "default_start",
    "desired_path",
    "simulate",
    "tracking_fitness",
]

Controller = Literal["pi", "default"]

#: Gains the paper prints for PI-HGSO (its units; shown for reference, not reusable here).
PAPER_PI_GAINS = {
    "line": {"kp": (0.2784e-4, 30.6587), "ki": 0.3399},
    "ellipse": {"kp": (174.7392, 143.3465), "ki": 2.9170e3},
}


@dataclass(frozen=True)
class PIGains:
    """PI gains: ``kp = (kp_xy, kp_z)`` in 1/s on the (x, y) and z error, ``ki`` in 1/s^2."""

    kp: tuple[float, float]
    ki: float

    def __post_init__(self) -> None:
        kp = tuple(float(v) for v in np.ravel(self.kp))
        if len(kp) != 2:
            raise ValueError(f"kp: must hold 2 gains (x-y, z), got {len(kp)}")
        for name, v in (("kp", kp[0]), ("kp", kp[1]), ("ki", self.ki)):
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"{name}: gains must be finite and >= 0, got {v}")
        object.__setattr__(self, "kp", kp)
        object.__setattr__(self, "ki", float(self.ki))

    def as_vector(self) -> np.ndarray:
        """``(3,)``: ``(kp_xy, kp_z, ki)``, the vector the tuners search."""
        return np.array([self.kp[0], self.kp[1], self.ki])

    @classmethod
    def from_vector(cls, x) -> PIGains:
        x = np.asarray(x, dtype=float).reshape(-1)
        if x.shape != (3,):
            raise ValueError(f"gains: expected (kp_xy, kp_z, ki), got shape {list(x.shape)}")
        return cls((x[0], x[1]), x[2])


#: Untuned PI ("PI" in Table 3), hand-picked by the textbook rule for a PI on an integrator
#: plant: a time constant of two control periods (kp = 5 /s at dt = 0.1 s) and critical
#: damping of the continuous loop (ki = kp^2 / 4).
UNTUNED_PI_GAINS = PIGains((5.0, 5.0), 6.25)

#: "No PI" (Table 3's first row), read as the resolved-rate law without the PI block: with
#: ``controller="default"`` and these zero gains the desired velocity alone is mapped through
#: eq. 13 (open loop, no correction of the deviation), so the error is the drift of the
#: integration. It involves no gains chosen by us, unlike ``UNTUNED_PI_GAINS``.
NO_PI_GAINS = PIGains((0.0, 0.0), 0.0)

#: Gains of the default (feed-forward) controller at dt = 0.1 s: discrete poles at
#: |z| = 0.71 (well damped); the integral removes the slow bias that the arm's curvature
#: leaves under feed-forward.
DEFAULT_GAINS = PIGains((5.0, 5.0), 50.0)


# ---- tasks ------------------------------------------------------------------------------
#: Largest task extents and durations accepted (mm, s); beyond them the arm cannot follow.
MAX_TASK_SIZE_MM = 1000.0
MAX_DURATION_S = 600.0


def _positive(name: str, value: float, upper: float) -> float:
    value = float(value)
    if not (math.isfinite(value) and 0 < value <= upper):
        raise ValueError(f"{name}: must be in (0, {upper:g}], got {value}")
    return value


def _unit(name: str, v) -> tuple[float, float, float]:
    a = np.asarray(v, dtype=float).reshape(-1)
    if a.shape != (3,) or not np.all(np.isfinite(a)) or np.linalg.norm(a) < 1e-9:
        raise ValueError(f"{name}: must be a finite non-zero 3-vector")
    return tuple((a / np.linalg.norm(a)).tolist())


def _min_jerk(tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Quintic rest-to-rest timing ``s(tau)`` and ``ds/dtau`` on ``tau in [0, 1]``."""
    s = tau**3 * (10 - 15 * tau + 6 * tau**2)
    ds = 30 * tau**2 * (1 - tau) ** 2
    return s, ds


@dataclass(frozen=True)
class LineTask:
    """Straight tool line of ``length`` mm along ``direction`` in ``duration`` s."""

    length: float = 200.0
    direction: tuple[float, float, float] = (0.48, 0.6, -0.64)
    duration: float = 20.0
    kind: str = field(default="line", init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "length", _positive("length", self.length, MAX_TASK_SIZE_MM))
        object.__setattr__(self, "direction", _unit("direction", self.direction))
        object.__setattr__(self, "duration",
                           _positive("duration", self.duration, MAX_DURATION_S))

    def path(self, p0: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Desired position and velocity ``(n, 3)`` (mm, mm/s) at times ``t (n,)``."""
        s, ds = _min_jerk(np.clip(t / self.duration, 0.0, 1.0))
        u = np.asarray(self.direction)
        return (p0 + self.length * s[:, None] * u,
                (self.length / self.duration) * ds[:, None] * u)


@dataclass(frozen=True)
class EllipseTask:
    """One lap of an ellipse with ``radii = (a, b)`` mm along ``major`` and ``normal x major``,
    in ``duration`` s, starting (and ending) at the tool's start position ``center + a major``.
    """

    radii: tuple[float, float] = (150.0, 100.0)
    duration: float = 30.0
    normal: tuple[float, float, float] = (0.0, 1.0, 0.0)
    major: tuple[float, float, float] = (0.0, 0.0, 1.0)
    kind: str = field(default="ellipse", init=False)

    def __post_init__(self) -> None:
        r = np.asarray(self.radii, dtype=float).reshape(-1)
        if r.shape != (2,):
            raise ValueError("radii: must be two numbers (a, b)")
        radii = (_positive("radii", r[0], MAX_TASK_SIZE_MM),
                 _positive("radii", r[1], MAX_TASK_SIZE_MM))
        object.__setattr__(self, "radii", radii)
        object.__setattr__(self, "duration",
                           _positive("duration", self.duration, MAX_DURATION_S))
        n = np.asarray(_unit("normal", self.normal))
        m = np.asarray(_unit("major", self.major))
        m = m - n * (m @ n)
        if np.linalg.norm(m) < 1e-6:
            raise ValueError("major: must not be parallel to the normal")
        object.__setattr__(self, "normal", tuple(n.tolist()))
        object.__setattr__(self, "major", tuple((m / np.linalg.norm(m)).tolist()))

    def path(self, p0: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Desired position and velocity ``(n, 3)`` (mm, mm/s) at times ``t (n,)``."""
        a, b = self.radii
        ex = np.asarray(self.major)
        ey = np.cross(np.asarray(self.normal), ex)
        s, ds = _min_jerk(np.clip(t / self.duration, 0.0, 1.0))
        phi, dphi = 2 * np.pi * s, 2 * np.pi * ds / self.duration
        c = p0 - a * ex
        x = c + a * np.cos(phi)[:, None] * ex + b * np.sin(phi)[:, None] * ey
        v = dphi[:, None] * (-a * np.sin(phi)[:, None] * ex + b * np.cos(phi)[:, None] * ey)
        return x, v


Task = LineTask | EllipseTask


# ---- configuration and kinematics -------------------------------------------------------
@dataclass(frozen=True)
class TrackingConfig:
    """Simulation settings. ``dt`` control period (s); ``damping`` lambda of eq. 13 (mm^2,
    small against ``J W^-1 J^T`` ~ 1e4..1e6 mm^2 on this arm); ``speed_limit`` (rad/s) per
    joint or ``None`` for the model's limits; ``q0 (dof,)`` the start configuration or ``None``
    for ``default_start``."""

    dt: float = 0.1
    damping: float = 10.0
    speed_limit: float | None = None
    q0: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.dt) and 1e-3 <= self.dt <= 1.0):
            raise ValueError(f"dt: must be in [0.001, 1] s, got {self.dt}")
        if not (math.isfinite(self.damping) and self.damping >= 0):
            raise ValueError(f"damping: must be finite and >= 0, got {self.damping}")
        if self.speed_limit is not None and not (
                math.isfinite(self.speed_limit) and self.speed_limit > 0):
            raise ValueError(f"speed_limit: must be positive, got {self.speed_limit}")


#: Most control steps one simulation may take (duration / dt).
MAX_STEPS = 20_000


def default_start(model: RobotModel) -> np.ndarray:
    """Start configuration ``(dof,)``: mid-configuration, every second joint bent by 1/8 of
    its range (30 deg on the 9-DOF arm's pitch joints)."""
    q = model.mid_configuration().copy()
    q[1::2] += (model.upper - model.lower)[1::2] / 8.0
    return q


def desired_path(model: RobotModel, task: Task, config: TrackingConfig
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Times ``t (n+1,)`` s, desired positions and velocities ``(n+1, 3)`` (mm, mm/s) and the
    start configuration ``q0 (dof,)``."""
    q0 = default_start(model) if config.q0 is None else np.asarray(config.q0, dtype=float)
    if q0.shape != (model.dof,):
        raise ValueError(f"q0: must hold {model.dof} joint values, got {list(q0.shape)}")
    bad = model.limit_violations(q0)
    if bad:
        raise ValueError(f"q0: outside the joint limits ({', '.join(bad)})")
    n = int(round(task.duration / config.dt))
    if n > MAX_STEPS:
        raise ValueError(f"dt: {n} steps exceed the cap of {MAX_STEPS}; raise dt")
    if n < 2:
        raise ValueError("dt: the task needs at least 2 control steps")
    t = np.arange(n + 1) * config.dt
    p0, _ = PositionJacobian(model)(q0[None])
    x_d, v_d = task.path(p0[0], t)
    return t, x_d, v_d, q0


# ---- simulation -------------------------------------------------------------------------
@dataclass(frozen=True)
class TrackingResult:
    """Simulation of ``P`` gain candidates over ``n`` steps (``n + 1`` samples).

    ``t (n+1,)`` s; ``x_desired (n+1, 3)`` mm; ``q (P, n+1, dof)`` rad; ``qd (P, n, dof)``
    rad/s (the rates applied over each step); ``error_xyz (P, n+1, 3)`` mm (desired minus
    actual); ``error (P, n+1)`` mm Euclidean; ``saturated_steps (P,)`` steps whose rates were
    scaled down to the speed limit. ``q``/``qd``/``error_xyz`` are ``None`` unless recorded.
    """

    t: np.ndarray
    x_desired: np.ndarray
    error: np.ndarray
    saturated_steps: np.ndarray
    q: np.ndarray | None = None
    qd: np.ndarray | None = None
    error_xyz: np.ndarray | None = None

    @property
    def mean_error(self) -> np.ndarray:
        """Eq. 24, ``(P,)`` mm."""
        return self.error.mean(axis=1)

    @property
    def max_error(self) -> np.ndarray:
        return self.error.max(axis=1)

    @property
    def std_error(self) -> np.ndarray:
        return self.error.std(axis=1)

    @property
    def joint_speed_max(self) -> np.ndarray | None:
        """Largest joint speed of each candidate ``(P,)`` rad/s (if recorded)."""
        return None if self.qd is None else np.abs(self.qd).max(axis=(1, 2))


def _gain_arrays(gains) -> tuple[np.ndarray, np.ndarray]:
    """``Kp (P, 3)`` per axis and ``ki (P, 1)`` from a PIGains, a list of them, or ``(P, 3)``."""
    if isinstance(gains, PIGains):
        X = gains.as_vector()[None]
    elif isinstance(gains, list | tuple) and gains and isinstance(gains[0], PIGains):
        X = np.array([g.as_vector() for g in gains])
    else:
        X = np.atleast_2d(np.asarray(gains, dtype=float))
    if X.ndim != 2 or X.shape[1] != 3:
        raise ValueError(f"gains: expected (P, 3) rows (kp_xy, kp_z, ki), got {list(X.shape)}")
    if not np.all(np.isfinite(X)):
        raise ValueError("gains: must be finite")
    return X[:, [0, 0, 1]], X[:, 2:3]


def simulate(
    model: RobotModel,
    task: Task,
    gains,
    *,
    controller: Controller = "pi",
    config: TrackingConfig = TrackingConfig(),
    record: bool = True,
    _jac: PositionJacobian | None = None,
) -> TrackingResult:
    """Track ``task`` with ``P`` gain candidates at once.

    ``gains``: a ``PIGains``, a list of them, or an array ``(P, 3)`` of ``(kp_xy, kp_z, ki)``.
    ``controller``: ``"pi"`` (eq. 1) or ``"default"`` (PI plus velocity feed-forward).
    ``record=False`` keeps only the errors (what the fitness needs).
    """
    if controller not in ("pi", "default"):
        raise ValueError(f"controller: must be 'pi' or 'default', got {controller!r}")
    Kp, ki = _gain_arrays(gains)
    P = Kp.shape[0]
    t, x_d, _, q0 = desired_path(model, task, config)
    n, dt, dof = len(t) - 1, config.dt, model.dof
    jac = _jac if _jac is not None else PositionJacobian(model)
    lower, upper = model.lower, model.upper
    vlim = model.velocity_limits if config.speed_limit is None else \
        np.full(dof, config.speed_limit)
    inv_vlim = np.where(np.isfinite(vlim), 1.0 / vlim, 0.0)
    ff = np.diff(x_d, axis=0) / dt if controller == "default" else np.zeros((n, 3))
    lam = config.damping * np.eye(3)

    q = np.repeat(q0[None], P, axis=0)
    integral = np.zeros((P, 3))
    g_prev = np.abs(limit_gradient(q, lower, upper))
    error = np.empty((P, n + 1))
    saturated = np.zeros(P, dtype=int)
    q_hist = np.empty((P, n + 1, dof)) if record else None
    qd_hist = np.empty((P, n, dof)) if record else None
    e_hist = np.empty((P, n + 1, 3)) if record else None
    for k in range(n + 1):
        p, J = jac(q)
        e = x_d[k] - p
        error[:, k] = np.sqrt(np.einsum("pi,pi->p", e, e))
        if record:
            q_hist[:, k] = q
            e_hist[:, k] = e
        if k == n:
            break
        integral += e * dt
        delta = ff[k] + Kp * e + ki * integral  # eq. 1 (+ feed-forward), mm/s
        # Eq. 8: penalise a joint only while it moves towards a limit.
        g = np.abs(limit_gradient(q, lower, upper))
        w_inv = np.where(g - g_prev >= 0, 1.0 / (1.0 + g), 1.0)
        g_prev = g
        JW = J * w_inv[:, None, :]
        y = np.linalg.solve(JW @ np.swapaxes(J, 1, 2) + lam, delta[:, :, None])
        qd = (np.swapaxes(JW, 1, 2) @ y)[..., 0]  # eq. 13, rad/s
        ratio = np.max(np.abs(qd) * inv_vlim, axis=1)
        over = ratio > 1.0
        saturated += over
        qd = qd / np.where(over, ratio, 1.0)[:, None]
        if record:
            qd_hist[:, k] = qd
        q = np.clip(q + qd * dt, lower, upper)
    return TrackingResult(t=t, x_desired=x_d, error=error, saturated_steps=saturated,
                          q=q_hist, qd=qd_hist, error_xyz=e_hist)


def tracking_fitness(
    model: RobotModel,
    task: Task,
    *,
    controller: Controller = "pi",
    config: TrackingConfig = TrackingConfig(),
) -> Callable[[np.ndarray], np.ndarray]:
    """Eq. 24 as a batched objective for the tuners: ``X (P, 3) -> mean error (P,)`` mm."""
    desired_path(model, task, config)  # validate once, up front
    jac = PositionJacobian(model)

    def f(X: np.ndarray) -> np.ndarray:
        return simulate(model, task, X, controller=controller, config=config, record=False,
                        _jac=jac).mean_error

    return f
