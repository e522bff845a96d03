"""Paper 002's RBF inverse kinematics on the paper's own inputs and outputs (section 3.1).

The paper draws 10,000 sets of joint values ``[theta1 theta2 d3 theta4 theta5 theta6]`` of the
drilling arm (feed fixed at d7 = 4022 mm), turns each tool pose into roll-pitch-yaw angles and
a position ``[alpha beta lambda px py pz]``, and trains a three-layer RBF network on 8,800 of
them (pose in, the six joint values out); on the other 1,200 it reports a largest relative
joint error of 0.62 % and a largest positioning error of 2.94 mm.

``kinematics.learned_ik`` solves an easier problem in the drilling posture: it learns only
swing, pitch and telescope from the position and sets roll and the compensation joints by the
drilling rule. This module learns what the paper learns: six inputs (RPY in rad, position in
mm, each standardised), six outputs (the joints, each scaled to its range), with scipy's
``RBFInterpolator`` (quintic kernel with its quadratic tail, the kernel
``kinematics.learned_ik`` uses, so the two differ only in what they learn; local: each
prediction uses the ``NEIGHBORS`` nearest samples). Inputs that never vary (the orientation
in the drilling posture) are dropped before fitting.

Two samplings, as the paper's text allows both readings ("according to the drilling attitude
... within the allowable range of each joint variable"):

* ``"drilling"``: swing, pitch and telescope uniform in their limits, roll 0, the
  compensation joints on the drilling rule (every pose then has the same orientation);
* ``"free"``: all six joints uniform and independent in their limits.

"Relative joint error" is the error as a fraction of the joint's range (the paper does not
say what it divides by); the positioning error is the distance between the tool point of the
predicted joints and the true one (mm).

Roll-pitch-yaw: ``R = Rz(yaw) Ry(pitch) Rx(roll)`` (the Robotics Toolbox's ``tr2rpy``
default), angles in rad from ``scipy.spatial.transform.Rotation``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import RBFInterpolator
from scipy.spatial.transform import Rotation

from .drilling import DRILL_D7, check_drilling_structure, compensation_angles
from .fk import fk
from .model import RobotModel

__all__ = ["NEIGHBORS", "PaperRBFIK", "PaperRBFReport", "rpy_xyz", "sample_joint_sets",
           "train_paper_rbf_ik"]

#: Training samples each prediction draws on.
NEIGHBORS = 128
#: Kernel of the interpolator (RPY and position obey no quadratic identity, so its quadratic
#: tail is well posed).
KERNEL = "quintic"
#: The six joints the paper learns (indices into q; the feed d7 is fixed).
LEARNED_JOINTS = (0, 1, 2, 3, 4, 5)


def rpy_xyz(T: np.ndarray) -> np.ndarray:
    """Poses ``(N, 4, 4)`` -> ``(N, 6)``: roll, pitch, yaw (rad) with
    ``R = Rz(yaw) Ry(pitch) Rx(roll)``, then x, y, z (mm)."""
    T = np.asarray(T, dtype=float)
    yaw_pitch_roll = Rotation.from_matrix(T[:, :3, :3]).as_euler("ZYX")
    return np.concatenate([yaw_pitch_roll[:, ::-1], T[:, :3, 3]], axis=1)


def sample_joint_sets(model: RobotModel, samples: int, rng: np.random.Generator,
                      posture: str = "free", d7: float = DRILL_D7) -> np.ndarray:
    """``samples`` configurations ``(N, 7)`` within the limits, the feed at ``d7`` mm:
    ``posture="free"`` draws the six joints independently, ``"drilling"`` draws swing, pitch
    and telescope and puts roll at 0 and the compensation joints on the drilling rule
    (redrawing where the rule leaves their limits)."""
    check_drilling_structure(model)
    if posture not in ("free", "drilling"):
        raise ValueError("posture: must be 'free' or 'drilling'")
    lower, upper = np.asarray(model.lower), np.asarray(model.upper)
    q = np.empty((0, model.dof))
    while len(q) < samples:
        draw = rng.uniform(lower, upper, size=(samples - len(q), model.dof))
        draw[:, 6] = d7
        if posture == "drilling":
            draw[:, 3] = 0.0
            draw[:, 4], draw[:, 5] = compensation_angles(draw[:, 0], draw[:, 1])
        q = np.vstack([q, draw[model.within_limits(draw)]])
    return q


@dataclass(frozen=True, eq=False)
class PaperRBFIK:
    """The trained map: RPY + position ``(N, 6)`` -> the six joints ``(N, 6)``.
    ``lower``/``upper (6,)`` are the joints' limits (outputs are scaled to them)."""

    inputs: np.ndarray
    joints: np.ndarray
    lower: np.ndarray
    upper: np.ndarray

    def __post_init__(self) -> None:
        varying = self.inputs.std(axis=0) > 1e-9
        mean = self.inputs[:, varying].mean(axis=0)
        scale = self.inputs[:, varying].std(axis=0)
        X = (self.inputs[:, varying] - mean) / scale
        Y = (self.joints - self.lower) / (self.upper - self.lower)
        _, first = np.unique(X, axis=0, return_index=True)
        keep = np.sort(first)  # coinciding inputs would make the system singular
        interp = RBFInterpolator(X[keep], Y[keep], kernel=KERNEL,
                                 neighbors=min(NEIGHBORS, len(keep)))
        for name, value in (("_interp", interp), ("_varying", varying), ("_mean", mean),
                            ("_scale", scale)):
            object.__setattr__(self, name, value)

    def predict(self, inputs: np.ndarray) -> np.ndarray:
        """Joints ``(N, 6)`` for RPY + position ``(N, 6)`` (not clipped: the test errors are
        the network's own)."""
        X = (np.asarray(inputs, dtype=float)[:, self._varying] - self._mean) / self._scale
        return self.lower + self._interp(X) * (self.upper - self.lower)


@dataclass(frozen=True)
class PaperRBFReport:
    """Test-set errors: the largest relative error (fraction of the range) per joint
    ``per_joint (6,)`` and over all joints, and the tool point's positioning error (mm)."""

    posture: str
    train: int
    test: int
    per_joint: tuple[float, ...]
    max_relative_joint_error: float
    max_position_error: float
    mean_position_error: float


def train_paper_rbf_ik(model: RobotModel, samples: int = 10_000, train: int = 8_800,
                       seed: int = 0, posture: str = "free",
                       d7: float = DRILL_D7) -> tuple[PaperRBFIK, PaperRBFReport]:
    """Draw ``samples`` joint sets (seeded), learn RPY + position -> six joints on the first
    ``train`` and report the errors on the rest (paper: 10,000, 8,800 / 1,200)."""
    if not 20 <= train < samples:
        raise ValueError("train: must be at least 20 and fewer than samples")
    rng = np.random.default_rng(seed)
    q = sample_joint_sets(model, samples, rng, posture, d7)
    T = fk(model, q)
    X = rpy_xyz(T)
    idx = list(LEARNED_JOINTS)
    lower, upper = np.asarray(model.lower)[idx], np.asarray(model.upper)[idx]
    net = PaperRBFIK(X[:train], q[:train, idx], lower, upper)
    guess = q[train:].copy()
    guess[:, idx] = net.predict(X[train:])
    rel = np.abs(guess[:, idx] - q[train:, idx]) / (upper - lower)
    dp = np.linalg.norm(fk(model, guess)[:, :3, 3] - T[train:, :3, 3], axis=1)
    report = PaperRBFReport(posture, train, samples - train,
                            tuple(float(v) for v in rel.max(axis=0)), float(rel.max()),
                            float(dp.max()), float(dp.mean()))
    return net, report
