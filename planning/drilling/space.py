"""The joint space a drilling arm moves in between holes, and its clearance to other arms.

Between two holes the drill stays perpendicular to the face (paper 002, sections 4.3 and 5):
roll held at 0 and the compensation joints on the paper's rule (``theta5 = -theta2``,
``theta6 = 90 deg - theta1``, ``kinematics.drilling.compensation_angles``). So a transfer is
planned in the three joints that place the drill: swing ``theta1``, pitch ``theta2`` and
telescope ``d3`` (the paper plans 1, 2, 3, 5, 6 with 5 and 6 following 1 and 2). The rule is
linear, so any smooth trajectory of (theta1, theta2) gives smooth compensation joints and
the drill's (y, z) on the face depends on these three joints alone. The feed ``d7`` only
moves the tip along the tunnel axis: it is the paper's "compensation of the distance to the
face" (section 4.3), set so the tip stays ``standoff`` mm in front of the face plane.

Planning coordinates are normalised, ``u = (q - lower) / (upper - lower)`` per planned joint,
so one unit is a joint's whole range (2.09 rad of swing or pitch, 6 m of telescope) and the
potential fields and RRT steps treat the three joints alike.

Collision checks use capsule envelopes (``envelopes.py``) against fixed obstacle capsules
(the other arms, parked). During planning the feed capsule is drawn up to the face plane,
which contains the retracted feed, so a plan that is clear is clear at any standoff.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinematics.drilling import DRILL_D7, check_drilling_structure, compensation_angles
from kinematics.fk import fk, fk_frames
from kinematics.model import RobotModel

from .envelopes import ArmEnvelope, capsule_distances, capsules

__all__ = ["PLANNED_JOINTS", "ArmSpace", "Obstacles"]

#: Joints planned between holes: swing, pitch, telescope (indices into q).
PLANNED_JOINTS = (0, 1, 2)


@dataclass(frozen=True)
class Obstacles:
    """Fixed capsules ``segments (M, 2, 3)`` mm with ``radii (M,)`` mm and, per capsule, the
    name of the arm it belongs to ``owners (M,)``."""

    segments: np.ndarray
    radii: np.ndarray
    owners: tuple[str, ...]

    @classmethod
    def none(cls) -> Obstacles:
        return cls(np.zeros((0, 2, 3)), np.zeros(0), ())

    @classmethod
    def of_arms(cls, arms: dict[str, tuple[RobotModel, np.ndarray]],
                envelope: ArmEnvelope) -> Obstacles:
        """Capsules of parked arms: ``{name: (model, q (7,))}``."""
        segs, radii, owners = [], [], []
        for name, (model, q) in arms.items():
            segs.append(capsules(model, q, envelope)[0])
            radii.append(envelope.radii)
            owners.extend([name] * envelope.size)
        if not segs:
            return cls.none()
        return cls(np.concatenate(segs), np.concatenate(radii), tuple(owners))


@dataclass(frozen=True, eq=False)
class ArmSpace:
    """One drilling arm's transfer space: ``model`` (mount applied), the face plane
    ``x = face_x`` of the rig frame (mm), its envelope and the feed value at the holes."""

    model: RobotModel
    envelope: ArmEnvelope
    face_x: float
    d7_hole: float = DRILL_D7

    def __post_init__(self) -> None:
        check_drilling_structure(self.model)

    @property
    def lower(self) -> np.ndarray:
        return self.model.lower[list(PLANNED_JOINTS)]

    @property
    def upper(self) -> np.ndarray:
        return self.model.upper[list(PLANNED_JOINTS)]

    def to_u(self, qp) -> np.ndarray:
        """Planned joints ``(S, 3)`` (rad, rad, mm) -> normalised ``(S, 3)``."""
        return (np.asarray(qp, dtype=float) - self.lower) / (self.upper - self.lower)

    def from_u(self, u) -> np.ndarray:
        """Normalised ``(S, 3)`` -> planned joints ``(S, 3)``."""
        return self.lower + np.asarray(u, dtype=float) * (self.upper - self.lower)

    def _rule_q(self, qp) -> np.ndarray:
        """``(S, 7)`` with roll 0, compensation on the rule and feed 0."""
        qp = np.atleast_2d(np.asarray(qp, dtype=float))
        q = np.zeros((len(qp), 7))
        q[:, :3] = qp
        q[:, 4], q[:, 5] = compensation_angles(qp[:, 0], qp[:, 1])
        return q

    def full_q(self, qp, d7=None) -> np.ndarray:
        """Full configurations ``(S, 7)`` from planned joints ``qp (S, 3)``: roll 0,
        compensation on the rule, feed ``d7 (S,)`` (default: tip on the face plane)."""
        q = self._rule_q(qp)
        q[:, 6] = self.d7_face(qp) if d7 is None else d7
        return q

    def d7_face(self, qp, standoff=0.0) -> np.ndarray:
        """Feed value putting the tip ``standoff`` mm in front of the face plane: ``(S,)``.
        Under the rule the drill axis is the tunnel axis, so the feed moves the tip along x
        only."""
        T = fk(self.model, self._rule_q(qp))
        return (self.face_x - np.asarray(standoff) - T[:, 0, 3]) / T[:, 0, 2]

    def tip_yz(self, qp) -> np.ndarray:
        """Drill tip on the face, ``(S, 2)`` (y, z) mm: independent of the feed."""
        return fk(self.model, self._rule_q(qp))[:, 1:3, 3]

    def frames_on_face(self, qp) -> tuple[np.ndarray, np.ndarray]:
        """Link frame origins with the tip on the face plane, ``(S, 8, 3)`` mm, and the
        feed values that put it there ``(S,)``, from one forward-kinematics pass (frames
        0..6 do not depend on the feed; the tip moves along the drill axis)."""
        F = fk_frames(self.model, self._rule_q(qp))
        P = F[:, :, :3, 3].copy()
        axis = F[:, -1, :3, 2]
        d7 = (self.face_x - P[:, -1, 0]) / axis[:, 0]
        P[:, -1] += d7[:, None] * axis
        return P, d7

    def valid(self, qp) -> np.ndarray:
        """Planned joints and the face-compensating feed within limits: ``(S,) bool``."""
        return self.model.within_limits(self.full_q(qp))

    def evaluate(self, qp, obstacles: Obstacles) -> tuple[np.ndarray, np.ndarray]:
        """Per-link clearance ``(S, L)`` mm (as ``link_clearance``) and validity ``(S,)``
        from one kinematics pass."""
        qp = np.atleast_2d(np.asarray(qp, dtype=float))
        P, d7 = self.frames_on_face(qp)
        q = self._rule_q(qp)
        q[:, 6] = d7
        ok = self.model.within_limits(q)
        if len(obstacles.radii) == 0:
            return np.full((len(qp), self.envelope.size), np.inf), ok
        fr = self.envelope.frames
        C = np.stack([P[:, fr[:, 0]], P[:, fr[:, 1]]], axis=2)
        d = capsule_distances(C, self.envelope.radii, obstacles.segments, obstacles.radii)
        return d.min(axis=2), ok

    def link_clearance(self, qp, obstacles: Obstacles) -> np.ndarray:
        """Per link, the signed distance (mm) from its capsule to the nearest obstacle
        capsule, the feed reaching the face plane: ``qp (S, 3) -> (S, L)`` (``inf``
        without obstacles)."""
        return self.evaluate(qp, obstacles)[0]

    def clearance(self, qp, obstacles: Obstacles) -> np.ndarray:
        """Smallest signed distance (mm) to any obstacle, ``(S,)``; ``-inf`` where a joint
        (the feed included) would leave its limits, so a planner treats it as blocked."""
        c, ok = self.evaluate(qp, obstacles)
        return np.where(ok, c.min(axis=1), -np.inf)
