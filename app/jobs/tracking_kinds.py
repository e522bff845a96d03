"""Job kind ``tracking``: PI resolved-rate tracking of a tool line or ellipse, optionally with
the gains tuned by a metaheuristic (paper 003), several runs with statistics.

Params (see ``TrackingParams``): ``robot``; ``task`` ``{"kind": "line", "length",
"direction", "duration"}`` or ``{"kind": "ellipse", "radii", "duration", "normal",
"major"}`` (mm, s; defaults as in ``planning.tracking``); ``controller`` ``{"kind":
"default" | "pi", "kp"?: [kp_xy, kp_z] or a number, "ki"?}``; ``tune`` one of
"hgso", "pso", "ga", "aco", "gwo" or null; ``bounds`` of the tuned gains; ``runs`` (at most
``MAX_RUNS``; runs differ only by their tuning seed, so more than one run needs ``tune``);
``seed``; ``dt``; ``q0``.

Result (mm, rad, rad/s): ``mean_error``, ``max_error``, ``std_error`` (over the path),
``kp``, ``ki``, ``q`` (per step), ``x_desired`` and ``x_actual`` (the desired and the reached
tool position per step), ``errors`` (per step, their distance), ``joint_speed_max``,
``saturated_steps``, ``t``, ``controller``, ``tune``, ``fitness_history`` (tuning) and, when
``runs > 1``, ``runs`` (per-run ``seed``, ``kp``, ``ki``, ``mean_error``, ``max_error``,
``std_error``) with ``summary`` (max/mean/std over runs) -- the top-level trajectory is the
best run's.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import Field, model_validator

from ..fields import Coordinate, JointValue
from .kinds import MAX_SEED, JobKind, Params, Progress, register

__all__ = ["TrackingParams", "run_tracking", "MAX_RUNS", "MAX_TUNING_WORK"]

#: Most runs one job may ask for (the paper's 30).
MAX_RUNS = 30
#: Most control steps of one simulated run (``planning.tracking.MAX_STEPS``).
MAX_STEPS = 20_000
#: Most control steps x (tuner iterations + 1) x runs of a tuned job: each unit is one step
#: simulated for a population of 50, about 0.25 ms, so the largest job takes ~25 minutes.
MAX_TUNING_WORK = 6_000_000
#: Tuner iterations when ``iterations`` is not given (paper 003, Table 2).
DEFAULT_TUNER_ITERATIONS = 50

#: A direction (scaled to unit length); bounded like every coordinate so its norm is finite.
Vector3 = Annotated[list[Coordinate], Field(min_length=3, max_length=3)]
Size = Annotated[float, Field(gt=0, le=1000, description="mm")]
Duration = Annotated[float, Field(gt=0, le=600, description="s")]


class LineTaskParams(Params):
    kind: Literal["line"]
    length: Size = 200.0
    direction: Vector3 = [0.48, 0.6, -0.64]
    duration: Duration = 20.0


class EllipseTaskParams(Params):
    kind: Literal["ellipse"]
    radii: Annotated[list[Size], Field(min_length=2, max_length=2)] = [150.0, 100.0]
    duration: Duration = 30.0
    normal: Vector3 = [0.0, 1.0, 0.0]
    major: Vector3 = [0.0, 0.0, 1.0]


Gain = Annotated[float, Field(ge=0, le=1e6)]


class ControllerParams(Params):
    kind: Literal["default", "pi"] = "default"
    kp: Annotated[list[Gain], Field(min_length=1, max_length=2)] | Gain | None = Field(
        None, description="(kp_xy, kp_z) in 1/s, or one number for both")
    ki: Gain | None = Field(None, description="1/s^2")


class BoundsParams(Params):
    kp: Annotated[list[Gain], Field(min_length=2, max_length=2)] = [0.5, 20.0]
    ki: Annotated[list[Gain], Field(min_length=2, max_length=2)] = [0.0, 400.0]

    @model_validator(mode="after")
    def _ordered(self) -> BoundsParams:
        for name in ("kp", "ki"):
            lo, hi = getattr(self, name)
            if not hi > lo:
                raise ValueError(f"{name}: the upper bound must exceed the lower")
        return self


class TrackingParams(Params):
    robot: str = Field("hyper_redundant_9dof", max_length=200, description="Robot id")
    task: LineTaskParams | EllipseTaskParams = Field(discriminator="kind")
    controller: ControllerParams = ControllerParams()
    tune: Literal["hgso", "pso", "ga", "aco", "gwo"] | None = None
    bounds: BoundsParams = BoundsParams()
    iterations: int | None = Field(None, ge=1, le=200, description="Tuner iterations "
                                   "(default: Table 2's 50)")
    runs: int = Field(1, ge=1, le=MAX_RUNS)
    seed: int = Field(0, ge=0, le=MAX_SEED)
    dt: float = Field(0.1, ge=0.01, le=1.0, description="Control period, s (at most "
                      f"{MAX_STEPS:,} steps per run)")
    q0: list[JointValue] | None = Field(None, min_length=1, max_length=32)

    @model_validator(mode="after")
    def _runs_need_tuning(self) -> TrackingParams:
        if self.runs > 1 and self.tune is None:
            raise ValueError("runs: more than one run needs 'tune' (untuned runs are equal)")
        return self

    @model_validator(mode="after")
    def _work(self) -> TrackingParams:
        steps = round(self.task.duration / self.dt)
        if steps > MAX_STEPS:
            raise ValueError(f"dt: the task takes {steps:,} control steps; at most "
                             f"{MAX_STEPS:,} (raise dt or shorten the task)")
        if self.tune is not None:
            iterations = self.iterations or DEFAULT_TUNER_ITERATIONS
            work = steps * (iterations + 1) * self.runs
            if work > MAX_TUNING_WORK:
                raise ValueError(
                    f"iterations: {steps:,} control steps x {iterations + 1} tuner "
                    f"iterations x {self.runs} runs = {work:,}; at most {MAX_TUNING_WORK:,} "
                    "(fewer runs or iterations, a larger dt or a shorter task)")
        return self


def _gains(controller: dict, default):
    from planning.tracking import PIGains

    kp, ki = controller.get("kp"), controller.get("ki")
    if kp is None and ki is None:
        return default
    if kp is None:
        kp = default.kp
    elif not isinstance(kp, list):
        kp = [kp, kp]
    elif len(kp) == 1:
        kp = kp * 2
    return PIGains(tuple(kp), default.ki if ki is None else ki)


def run_tracking(params: dict[str, Any], progress: Progress) -> dict[str, Any]:
    """Simulate (and optionally tune) a tracking task; see the module docstring."""
    import numpy as np

    from kinematics.model import RobotModel
    from planning.tracking import (
        DEFAULT_GAINS,
        UNTUNED_PI_GAINS,
        EllipseTask,
        GainBounds,
        LineTask,
        TrackingConfig,
        simulate,
        tune_gains,
    )

    model = RobotModel.from_dict(params["_model"])
    t = params["task"]
    if t["kind"] == "line":
        task = LineTask(t["length"], tuple(t["direction"]), t["duration"])
    else:
        task = EllipseTask(tuple(t["radii"]), t["duration"], tuple(t["normal"]),
                           tuple(t["major"]))
    ctrl = params["controller"]["kind"]
    config = TrackingConfig(dt=params["dt"],
                            q0=None if params["q0"] is None else tuple(params["q0"]))
    bounds = GainBounds(tuple(params["bounds"]["kp"]), tuple(params["bounds"]["ki"]))
    fixed = _gains(params["controller"], DEFAULT_GAINS if ctrl == "default" else UNTUNED_PI_GAINS)
    runs, tuner = params["runs"], params["tune"]

    per_run, histories = [], []
    for r in range(runs):
        seed = params["seed"] + r
        if tuner is None:
            gains = fixed
        else:
            def sub(f: float, r: int = r) -> None:
                progress(0.95 * (r + f) / runs, f"run {r + 1} of {runs}: tuning ({tuner})")

            tuned = tune_gains(model, task, tuner, seed, controller=ctrl, config=config,
                               bounds=bounds, iterations=params["iterations"], progress=sub)
            gains = tuned.gains
            histories.append(tuned.optim.history.tolist())
        per_run.append((seed, gains))
        progress(0.95 * (r + 1) / runs, f"run {r + 1} of {runs} done")

    sim = simulate(model, task, [g for _, g in per_run], controller=ctrl, config=config)
    best = int(np.argmin(sim.mean_error))
    seed_best, g_best = per_run[best]
    out: dict[str, Any] = {
        "robot": model.id,
        "task": t,
        "controller": ctrl,
        "tune": tuner,
        "mean_error": float(sim.mean_error[best]),
        "max_error": float(sim.max_error[best]),
        "std_error": float(sim.std_error[best]),
        "kp": list(g_best.kp),
        "ki": g_best.ki,
        "seed": seed_best,
        "t": sim.t.tolist(),
        "x_desired": sim.x_desired.tolist(),
        "x_actual": (sim.x_desired - sim.error_xyz[best]).tolist(),
        "q": sim.q[best].tolist(),
        "errors": sim.error[best].tolist(),
        "joint_speed_max": float(sim.joint_speed_max[best]),
        "saturated_steps": int(sim.saturated_steps[best]),
        "fitness_history": histories[best] if histories else [],
    }
    if runs > 1:
        out["runs"] = [
            {"seed": s, "kp": list(g.kp), "ki": g.ki, "mean_error": float(sim.mean_error[i]),
             "max_error": float(sim.max_error[i]), "std_error": float(sim.std_error[i])}
            for i, (s, g) in enumerate(per_run)
        ]
        out["summary"] = {
            "max": float(sim.max_error.max()),
            "mean": float(sim.mean_error.mean()),
            "std": float(sim.std_error.mean()),
            "mean_error_std_over_runs": float(sim.mean_error.std()),
        }
    progress(1.0, "done")
    return out


register(JobKind("tracking", TrackingParams, run_tracking,
                 "PI resolved-rate tool tracking; gains optionally tuned (paper 003)",
                 needs_robot=True))
