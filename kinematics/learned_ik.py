"""Learned IK (paper 002 section 3.1): a radial-basis-function map from tool pose to joints.

The paper trains an RBF network on 10,000 Monte Carlo samples (8,800 to train, 1,200 to
test), pose in, joint values out, and reports a largest relative joint error of 0.62 % and a
largest positioning error of 2.94 mm. We fit scipy's ``RBFInterpolator`` (quintic kernel,
local: each prediction uses the nearest training samples) to the same split, and report the
same two figures. Departures, both for accuracy: the pose enters as position / length scale
and the first two columns of the rotation matrix (continuous, unlike roll-pitch-yaw, which
jumps at ±180°), and the joints are scaled to their ranges.

The quintic kernel needs a quadratic polynomial tail, and that tail is singular whenever the
features obey a quadratic identity, as rotation columns always do (|x| = |y| = 1, x·y = 0):
a map that learns the orientation too (any robot outside the drilling posture) therefore
uses the thin-plate spline, whose linear tail those identities leave well posed. Samples
whose features coincide (several joint solutions of one pose) would make the interpolation
system singular as well: only the first of them is kept.

A learned guess is good enough to start from, not to drill with: ``polish`` refines it with
the numeric IK, and both errors are reported. "Relative joint error" here is the error as a
fraction of the joint's range (the paper does not say what it divides by; dividing by the
joint value itself is meaningless near zero).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import RBFInterpolator

from .drilling import check_drilling_structure, compensation_angles
from .fk import fk
from .ik.numeric import NumericOptions, solve_batch
from .ik.result import IKResult
from .model import RobotModel
from .transforms import pose_errors

__all__ = ["LearnedIK", "train_learned_ik", "TrainingReport", "pose_features",
           "sample_configurations", "validate_learned_ik", "ValidationReport",
           "VALIDATION_SAMPLES"]

#: Training samples each prediction draws on.
NEIGHBORS = 128
#: Kernel of the map when the features allow a quadratic tail, and the one used otherwise.
KERNEL = "quintic"
FALLBACK_KERNEL = "thin_plate_spline"
#: Rows of the feature matrix the rank test looks at (identities hold on every row).
RANK_TEST_ROWS = 4000
#: Singular values below this fraction of the largest count as zero in the rank test.
RANK_TOL = 1e-9
#: Poses a validation draws by default.
VALIDATION_SAMPLES = 1000
#: Spawn key of the validation's random stream under the training seed: a stream of its
#: own, so no validation pose is a training or test sample of the same seed.
VALIDATION_STREAM = (1,)


def quadratic_tail_is_singular(X: np.ndarray) -> bool:
    """Whether the polynomials of degree 2 in the columns of ``X (N, d)`` are linearly
    dependent on its rows (e.g. rotation columns, whose squares sum to 1)."""
    X = X[:RANK_TEST_ROWS]
    X = (X - X.mean(axis=0)) / X.std(axis=0)
    d = X.shape[1]
    cols = [np.ones(len(X)), *X.T]
    cols += [X[:, i] * X[:, j] for i in range(d) for j in range(i, d)]
    if len(cols) > len(X):
        return True
    s = np.linalg.svd(np.column_stack(cols), compute_uv=False)
    return bool(s[-1] <= RANK_TOL * s[0])


def distinct_rows(X: np.ndarray) -> np.ndarray:
    """Indices (ascending) of the first occurrence of each distinct row of ``X``."""
    _, first = np.unique(X, axis=0, return_index=True)
    return np.sort(first)


def apply_drilling_rule(q: np.ndarray) -> np.ndarray:
    """``q (N, 7)`` with roll 0 and theta5, theta6 set by the drilling rule from theta1, 2."""
    q = np.array(q, dtype=float)
    q[:, 3] = 0.0
    q[:, 4], q[:, 5] = compensation_angles(q[:, 0], q[:, 1])
    return q


def pose_features(model: RobotModel, T: np.ndarray) -> np.ndarray:
    """Poses ``(N, 4, 4)`` -> features ``(N, 9)``: position / length scale, rotation columns
    x and y."""
    return np.concatenate(
        [T[:, :3, 3] / model.length_scale, T[:, :3, 0], T[:, :3, 1]], axis=1
    )


@dataclass(frozen=True, eq=False)
class LearnedIK:
    """A trained pose -> joints map for one robot. ``free (dof,)`` marks the joints learned;
    the others are held at ``fixed_values``."""

    robot_id: str
    features: np.ndarray
    targets: np.ndarray
    free: np.ndarray
    fixed_values: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    posture: str = "free"

    def __post_init__(self) -> None:
        # Features that never vary (e.g. the orientation in the drilling posture) carry no
        # information and would make the interpolant's polynomial part singular: drop them.
        varying = self.features.std(axis=0) > 1e-9
        X = self.features[:, varying]
        keep = distinct_rows(X)
        X, Y = X[keep], self.targets[keep]
        kernel = FALLBACK_KERNEL if quadratic_tail_is_singular(X) else KERNEL
        interp = RBFInterpolator(X, Y, kernel=kernel, neighbors=min(NEIGHBORS, len(X)))
        object.__setattr__(self, "_interp", interp)
        object.__setattr__(self, "_varying", varying)
        object.__setattr__(self, "kernel", kernel)

    def predict(self, model: RobotModel, T: np.ndarray) -> np.ndarray:
        """Joint guesses ``(N, dof)`` for poses ``(N, 4, 4)`` (clipped to the limits)."""
        f = pose_features(model, np.asarray(T, dtype=float))[:, self._varying]
        u = self._interp(f)
        q = np.tile(self.fixed_values, (len(u), 1))
        q[:, self.free] = self.lower[self.free] + u * (self.upper - self.lower)[self.free]
        if self.posture == "drilling":
            q = apply_drilling_rule(q)
        return np.clip(q, self.lower, self.upper)

    def polish(self, model: RobotModel, T: np.ndarray,
               options: NumericOptions | None = None) -> tuple[np.ndarray, list[IKResult]]:
        """The learned guesses and the numeric IK started from them: ``(N, dof)``, results."""
        guess = self.predict(model, T)
        opts = options or NumericOptions(restarts=8)
        return guess, solve_batch(model, T, guess, options=opts)

    def to_dict(self) -> dict:
        """Plain data (JSON-ready) from which ``from_dict`` rebuilds the same map."""
        return {
            "robot_id": self.robot_id, "features": self.features.tolist(),
            "targets": self.targets.tolist(), "free": self.free.tolist(),
            "fixed_values": self.fixed_values.tolist(), "lower": self.lower.tolist(),
            "upper": self.upper.tolist(), "posture": self.posture,
        }

    @classmethod
    def from_dict(cls, data: dict) -> LearnedIK:
        return cls(
            robot_id=data["robot_id"], features=np.asarray(data["features"], dtype=float),
            targets=np.asarray(data["targets"], dtype=float),
            free=np.asarray(data["free"], dtype=bool),
            fixed_values=np.asarray(data["fixed_values"], dtype=float),
            lower=np.asarray(data["lower"], dtype=float),
            upper=np.asarray(data["upper"], dtype=float),
            posture=data.get("posture", "free"),
        )


@dataclass(frozen=True)
class TrainingReport:
    """Test-set errors of the learned map alone and after numeric polishing.

    ``max_relative_joint_error`` (fraction of each joint's range, worst joint) and
    ``max_position_error`` (mm) are the paper's two figures; ``per_joint`` lists the
    largest relative error per joint. ``polished_*`` are the same after the numeric IK
    starts from the learned guess; ``polished_success`` the fraction it solved.
    """

    samples: int
    train: int
    test: int
    max_relative_joint_error: float
    mean_relative_joint_error: float
    per_joint: list[float]
    max_position_error: float
    mean_position_error: float
    max_rotation_error: float
    polished_max_position_error: float
    polished_max_rotation_error: float
    polished_success: float

    def to_dict(self) -> dict:
        return dict(self.__dict__)


def train_learned_ik(
    model: RobotModel,
    samples: int = 10_000,
    test_fraction: float = 0.12,
    seed: int = 0,
    *,
    fixed: dict[int, float] | None = None,
    posture: str = "free",
    progress: Callable[[float, str], None] | None = None,
) -> tuple[LearnedIK, TrainingReport]:
    """Sample ``samples`` configurations within the limits (seeded), learn pose -> joints on
    ``1 - test_fraction`` of them, report the errors on the rest (paper: 10,000 samples,
    8,800 / 1,200). ``fixed`` holds joints at given values (e.g. the drill feed d7).

    ``posture="drilling"`` (tunnel drilling arm) samples as the paper does, in the drilling
    attitude: swing, pitch and telescope free, roll 0 and the compensation joints following
    the drilling rule (theta5 = -theta2, theta6 = 90 deg - theta1), so the drill stays
    perpendicular to the face; the map then learns (theta1, theta2, d3) from the position.
    ``posture="free"`` samples every joint independently; where several joint solutions share
    a pose the map cannot choose and its guesses are only starting points."""
    if samples < 20:
        raise ValueError("samples: need at least 20")
    if not 0 < test_fraction < 1:
        raise ValueError("test_fraction: must be between 0 and 1")
    fixed = dict(fixed or {})
    for j, v in fixed.items():
        if not 0 <= j < model.dof:
            raise ValueError(f"fixed: joint index {j} out of range")
        if not model.lower[j] <= v <= model.upper[j]:
            raise ValueError(f"fixed: {model.joints[j].name} = {v} is outside its limits")
    report = progress or (lambda f, m: None)
    lower, upper = np.asarray(model.lower), np.asarray(model.upper)
    q = sample_configurations(model, np.random.default_rng(seed), samples, fixed=fixed,
                              posture=posture)
    free = np.ones(model.dof, dtype=bool)
    fixed_values = model.mid_configuration().copy()
    if posture == "drilling":
        free[3:6] = False  # roll and the two compensation joints follow the rule
        fixed_values[3] = 0.0
    for j, v in fixed.items():
        free[j] = False
        fixed_values[j] = v
    T = fk(model, q)
    n_test = max(1, int(round(samples * test_fraction)))
    train_idx, test_idx = np.arange(samples - n_test), np.arange(samples - n_test, samples)
    span = (upper - lower)[free]
    targets = (q[train_idx][:, free] - lower[free]) / span
    report(0.2, "fitting the RBF map")
    learned = LearnedIK(model.id, pose_features(model, T[train_idx]), targets, free,
                        fixed_values, lower, upper, posture)
    report(0.5, "testing")
    guess = learned.predict(model, T[test_idx])
    rel = np.abs(guess[:, free] - q[test_idx][:, free]) / span
    dp, dr = pose_errors(fk(model, guess), T[test_idx])
    report(0.7, "polishing with the numeric IK")
    _, polished = learned.polish(model, T[test_idx])
    ok = [r for r in polished if r.success]
    result = TrainingReport(
        samples=samples, train=len(train_idx), test=len(test_idx),
        max_relative_joint_error=float(rel.max()),
        mean_relative_joint_error=float(rel.mean()),
        per_joint=[float(v) for v in rel.max(axis=0)],
        max_position_error=float(dp.max()), mean_position_error=float(dp.mean()),
        max_rotation_error=float(dr.max()),
        polished_max_position_error=float(max((r.position_error for r in ok), default=np.nan)),
        polished_max_rotation_error=float(max((r.rotation_error for r in ok), default=np.nan)),
        polished_success=len(ok) / len(polished),
    )
    report(1.0, "done")
    return learned, result


def sample_configurations(model: RobotModel, rng: np.random.Generator, n: int, *,
                          fixed: dict[int, float] | None = None, posture: str = "free"
                          ) -> np.ndarray:
    """``n`` configurations ``(n, dof)`` drawn from ``rng`` as ``train_learned_ik`` draws its
    samples: uniform within the limits (``posture="drilling"``: in the drilling attitude,
    redrawn where the rule leaves the limits), the ``fixed`` joints at their values."""
    lower, upper = np.asarray(model.lower), np.asarray(model.upper)
    q = rng.uniform(lower, upper, size=(n, model.dof))
    if posture == "drilling":
        check_drilling_structure(model)
        q = apply_drilling_rule(q)
        inside = model.within_limits(q)
        while not inside.all():  # resample where the rule leaves the compensation limits
            redo = rng.uniform(lower, upper, size=(int((~inside).sum()), model.dof))
            q[~inside] = apply_drilling_rule(redo)
            inside = model.within_limits(q)
    elif posture != "free":
        raise ValueError("posture: must be 'free' or 'drilling'")
    for j, v in (fixed or {}).items():
        q[:, j] = v
    return q


@dataclass(frozen=True)
class ValidationReport:
    """Errors of the learned map alone (no numeric polish) on ``samples`` held-out poses:
    position (mm) and rotation (rad) mean, 95th percentile and largest."""

    samples: int
    mean_position_error: float
    p95_position_error: float
    max_position_error: float
    mean_rotation_error: float
    p95_rotation_error: float
    max_rotation_error: float

    def to_dict(self) -> dict:
        return dict(self.__dict__)


def validate_learned_ik(model: RobotModel, learned: LearnedIK,
                        samples: int = VALIDATION_SAMPLES, seed: int = 0, *,
                        fixed: dict[int, float] | None = None) -> ValidationReport:
    """How far the learned map's guesses put the tool from ``samples`` poses drawn as its
    training drew its own (its posture, the ``fixed`` joints) but from a stream of their
    own: seeded by ``seed``, apart from the training stream of that seed (``VALIDATION_STREAM``),
    so none was trained on."""
    if samples < 1:
        raise ValueError("samples: need at least 1")
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=VALIDATION_STREAM))
    q = sample_configurations(model, rng, samples, fixed=fixed, posture=learned.posture)
    T = fk(model, q)
    dp, dr = pose_errors(fk(model, learned.predict(model, T)), T)
    return ValidationReport(
        samples=samples,
        mean_position_error=float(dp.mean()),
        p95_position_error=float(np.percentile(dp, 95)),
        max_position_error=float(dp.max()),
        mean_rotation_error=float(dr.mean()),
        p95_rotation_error=float(np.percentile(dr, 95)),
        max_rotation_error=float(dr.max()),
    )
