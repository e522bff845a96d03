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
best run's. ``TrackingResult`` types every field.

Plot (``GET /jobs/{id}/plot``): ``plot_tracking``, paper 003's Figure 7.

Several runs divide (``tracking_graph``): each run's tuning is a step (it depends on its seed
alone), and a last step simulates every run's gains and answers, as one process would.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Annotated, Literal

from pydantic import Field, model_validator

from planning.registry import algorithm_names

from ..fields import Coordinate, JointValue
from .graph import Ref, Step, run_inline
from .kinds import MAX_SEED, XYZ, JobKind, Params, Progress, Result, absent_when_none, register

if TYPE_CHECKING:
    from kinematics.model import RobotModel
    from planning.tracking import EllipseTask, GainBounds, LineTask, PIGains

__all__ = ["TrackingParams", "TrackingResult", "run_tracking", "tracking_graph", "plot_tracking",
           "MAX_RUNS", "MAX_TUNING_WORK"]

#: Most runs one job may ask for (the paper's 30).
MAX_RUNS = 30
#: Most control steps of one simulated run (``planning.tracking.simulator.MAX_STEPS``).
MAX_STEPS = 20_000
#: Most control steps x (tuner iterations + 1) x runs of a tuned job: each unit is one step
#: simulated for a population of 50, about 0.25 ms, so the largest job takes ~25 minutes.
MAX_TUNING_WORK = 6_000_000
#: Tuner iterations when ``iterations`` is not given (paper 003, Table 2).
DEFAULT_TUNER_ITERATIONS = 50
#: The gain tuners: the ``tuner`` family of ``planning.registry`` (``aco`` is ACO_R).
Tuner = Literal[algorithm_names("tuner")]  # type: ignore[valid-type]

#: A direction (scaled to unit length); bounded like every coordinate so its norm is finite.
Vector3 = Annotated[list[Coordinate], Field(min_length=3, max_length=3)]
Size = Annotated[float, Field(gt=0, le=1000, description="mm")]
Duration = Annotated[float, Field(gt=0, le=600, description="s")]


class LineTaskParams(Params):
    kind: Literal["line"]
    length: Size = 200.0
    direction: Vector3 = [0.48, 0.6, -0.64]
    duration: Duration = 20.0

    def to_task(self) -> LineTask:
        from planning.tracking import LineTask

        return LineTask(self.length, tuple(self.direction), self.duration)


class EllipseTaskParams(Params):
    kind: Literal["ellipse"]
    radii: Annotated[list[Size], Field(min_length=2, max_length=2)] = [150.0, 100.0]
    duration: Duration = 30.0
    normal: Vector3 = [0.0, 1.0, 0.0]
    major: Vector3 = [0.0, 0.0, 1.0]

    def to_task(self) -> EllipseTask:
        from planning.tracking import EllipseTask

        return EllipseTask(tuple(self.radii), self.duration, tuple(self.normal),
                           tuple(self.major))


Gain = Annotated[float, Field(ge=0, le=1e6)]


class ControllerParams(Params):
    kind: Literal["default", "pi"] = "default"
    kp: Annotated[list[Gain], Field(min_length=1, max_length=2)] | Gain | None = Field(
        None, description="(kp_xy, kp_z) in 1/s, or one number for both")
    ki: Gain | None = Field(None, description="1/s^2")

    def gains(self) -> PIGains:
        """The gains given, the rest from the controller's defaults."""
        from planning.tracking import DEFAULT_GAINS, UNTUNED_PI_GAINS, PIGains

        default = DEFAULT_GAINS if self.kind == "default" else UNTUNED_PI_GAINS
        if self.kp is None and self.ki is None:
            return default
        if self.kp is None:
            kp = tuple(default.kp)
        elif isinstance(self.kp, list):
            kp = tuple(self.kp * 2) if len(self.kp) == 1 else tuple(self.kp)
        else:
            kp = (self.kp, self.kp)
        return PIGains(kp, default.ki if self.ki is None else self.ki)


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

    def to_bounds(self) -> GainBounds:
        from planning.tracking import GainBounds

        return GainBounds(tuple(self.kp), tuple(self.ki))


class TrackingParams(Params):
    robot: str = Field("hyper_redundant_9dof", max_length=200, description="Robot id")
    task: LineTaskParams | EllipseTaskParams = Field(discriminator="kind")
    controller: ControllerParams = ControllerParams()
    tune: Tuner | None = None
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


Task = Annotated[LineTaskParams | EllipseTaskParams, Field(discriminator="kind")]
Gains = Annotated[list[float], Field(min_length=2, max_length=2,
                                     description="(kp_xy, kp_z), 1/s")]


class TrackingRun(Result):
    """One of several runs (they differ by the tuning seed)."""

    seed: int
    kp: Gains
    ki: float = Field(description="1/s^2")
    mean_error: float = Field(description="mm")
    max_error: float = Field(description="mm")
    std_error: float = Field(description="mm")


class TrackingSummary(Result):
    """Over the runs: the largest max error, the mean of the mean errors and of the standard
    deviations, and the spread of the mean errors (mm)."""

    max: float
    mean: float
    std: float
    mean_error_std_over_runs: float


class TrackingResult(Result):
    """The best run's trajectory (mm, rad, s), with its errors and gains."""

    robot: str
    task: Task
    controller: Literal["default", "pi"]
    tune: Tuner | None
    mean_error: float = Field(description="mm, over the path")
    max_error: float = Field(description="mm")
    std_error: float = Field(description="mm")
    kp: Gains
    ki: float = Field(description="1/s^2")
    seed: int = Field(description="The tuning seed of this run")
    t: list[float] = Field(description="s, per step")
    x_desired: list[XYZ] = Field(description="Desired tool position per step, mm")
    x_actual: list[XYZ] = Field(description="Reached tool position per step, mm")
    q: list[list[float]] = Field(description="Joints per step, rad")
    errors: list[float] = Field(description="Distance desired - reached per step, mm")
    joint_speed_max: float = Field(description="rad/s")
    saturated_steps: int
    fitness_history: list[float] = Field(description="The tuner's best fitness per iteration "
                                         "(empty without tuning)")
    runs: list[TrackingRun] | None = absent_when_none("Per run, when runs > 1")
    summary: TrackingSummary | None = absent_when_none("Over the runs, when runs > 1")


def tracking_graph(params: TrackingParams) -> list[Step]:
    """The steps of a tracking job: one run in one step; several runs (each tuned with its
    own seed, ``seed + r``) a step each, and a step that simulates them all and answers."""
    if params.runs == 1:
        return [Step(tracking_whole)]
    # a run's tuning simulates its population (iterations + 1) times; the last step
    # simulates the runs once, about one tuner iteration's work
    iterations = params.iterations or DEFAULT_TUNER_ITERATIONS
    steps = [Step(tracking_run_step, (r,), weight=iterations + 1,
                  label=f"run {r + 1} of {params.runs}") for r in range(params.runs)]
    steps.append(Step(tracking_result_step, ([Ref(r) for r in range(params.runs)],),
                      weight=1.0, label="simulating the runs"))
    return steps


def tracking_run_step(params: TrackingParams, run: int, progress: Progress) -> tuple:
    """Run ``run``'s gains: ``(seed, PIGains, fitness history)``, tuned with seed
    ``params.seed + run`` (the fixed gains without ``tune``)."""
    seed = params.seed + run
    if params.tune is None:
        progress(1.0, "fixed gains")
        return seed, params.controller.gains(), []
    from planning.tracking import TrackingConfig, tune_gains

    config = TrackingConfig(dt=params.dt, q0=None if params.q0 is None else tuple(params.q0))
    tuned = tune_gains(params.robot_model(), params.task.to_task(), params.tune, seed,
                       controller=params.controller.kind, config=config,
                       bounds=params.bounds.to_bounds(), iterations=params.iterations,
                       progress=lambda f: progress(f, f"tuning ({params.tune})"))
    return seed, tuned.gains, tuned.optim.history.tolist()


def tracking_whole(params: TrackingParams, progress: Progress) -> TrackingResult:
    """A tracking job of one run in one step."""
    run = tracking_run_step(params, 0, lambda f, m: progress(0.95 * f, m))
    return tracking_result_step(params, [run], lambda f, m: progress(0.95 + 0.05 * f, m))


def tracking_result_step(params: TrackingParams, per_run: list, progress: Progress
                         ) -> TrackingResult:
    """Simulate every run's gains (``tracking_run_step``'s, in run order) and answer with
    the best run's trajectory, and the runs' statistics when there are several."""
    import numpy as np

    from planning.tracking import TrackingConfig, simulate

    model = params.robot_model()
    ctrl = params.controller.kind
    config = TrackingConfig(dt=params.dt, q0=None if params.q0 is None else tuple(params.q0))
    histories = [h for _, _, h in per_run]
    sim = simulate(model, params.task.to_task(), [g for _, g, _ in per_run], controller=ctrl,
                   config=config)
    best = int(np.argmin(sim.mean_error))
    seed_best, g_best, _ = per_run[best]
    several = len(per_run) > 1
    out = TrackingResult(
        robot=model.id,
        task=params.task,
        controller=ctrl,
        tune=params.tune,
        mean_error=float(sim.mean_error[best]),
        max_error=float(sim.max_error[best]),
        std_error=float(sim.std_error[best]),
        kp=list(g_best.kp),
        ki=g_best.ki,
        seed=seed_best,
        t=sim.t.tolist(),
        x_desired=sim.x_desired.tolist(),
        x_actual=(sim.x_desired - sim.error_xyz[best]).tolist(),
        q=sim.q[best].tolist(),
        errors=sim.error[best].tolist(),
        joint_speed_max=float(sim.joint_speed_max[best]),
        saturated_steps=int(sim.saturated_steps[best]),
        fitness_history=histories[best] if params.tune is not None else [],
        runs=[
            TrackingRun(seed=s, kp=list(g.kp), ki=g.ki, mean_error=float(sim.mean_error[i]),
                        max_error=float(sim.max_error[i]), std_error=float(sim.std_error[i]))
            for i, (s, g, _) in enumerate(per_run)
        ] if several else None,
        summary=TrackingSummary(
            max=float(sim.max_error.max()),
            mean=float(sim.mean_error.mean()),
            std=float(sim.std_error.mean()),
            mean_error_std_over_runs=float(sim.mean_error.std()),
        ) if several else None,
    )
    progress(1.0, "done")
    return out


def run_tracking(params: TrackingParams, progress: Progress) -> TrackingResult:
    """Simulate (and optionally tune) a tracking task; see the module docstring. Several
    runs are tuned independently (``tracking_graph``): the same answer however they are
    spread over workers."""
    return run_inline(tracking_graph(params), params, progress)


def plot_tracking(params: TrackingParams, result: TrackingResult,
                  robot: RobotModel | None) -> bytes:
    """Paper 003's Figure 7 of a tracking run: joint angles, joint speeds (limits dashed),
    error per axis and tool error against time. ``robot``: the robot's model as the service
    knows it now (its joint names and speed limits), None if it was deleted since."""
    from ..plots import tracking_png

    dof = len(result.q[0])
    names, limits = [f"j{i + 1}" for i in range(dof)], None
    if robot is not None and robot.dof == dof:
        names, limits = [j.name for j in robot.joints], robot.velocity_limits
    tune = f", tuned by {result.tune.upper()}" if result.tune else ""
    controller = {"pi": "PI", "default": "default (PI + feed-forward)"}[result.controller]
    title = f"{result.robot}: {result.task.kind} task, {controller} controller{tune}"
    return tracking_png(result.t, result.q, result.x_desired, result.x_actual, names, title,
                        limits)


register(JobKind("tracking", TrackingParams, TrackingResult, run_tracking,
                 "PI resolved-rate tool tracking; gains optionally tuned (paper 003)",
                 needs_robot=True, plot=plot_tracking, graph=tracking_graph))
