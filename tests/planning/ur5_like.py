"""A UR5-like arm for the motion tests: its standard D-H table, the model, a forward
kinematics written here (independent of the library's), and small geometry helpers."""

from __future__ import annotations

import math

import numpy as np

from kinematics.model import RobotModel

PI = math.pi
#: UR5 standard D-H (a, alpha, d), mm.
UR5_DH = [(0.0, PI / 2, 89.159), (-425.0, 0.0, 0.0), (-392.25, 0.0, 0.0),
          (0.0, PI / 2, 109.15), (0.0, -PI / 2, 94.65), (0.0, 0.0, 82.3)]
#: The model as POST /robots takes it (joints within +-2 pi).
UR5_MODEL = {"id": "ur5_like", "name": "UR5-like", "convention": "sdh",
             "joints": [{"name": f"j{i + 1}", "type": "revolute", "a": a, "alpha": al, "d": d,
                         "lower": -2 * PI, "upper": 2 * PI}
                        for i, (a, al, d) in enumerate(UR5_DH)]}


def ur5_model() -> RobotModel:
    return RobotModel.from_dict(UR5_MODEL)


def ur5_fk(q) -> np.ndarray:
    """Tool poses ``(n, 4, 4)`` of ``q (n, 6)``: RotZ(q) TransZ(d) TransX(a) RotX(alpha)."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    T = np.broadcast_to(np.eye(4), (len(q), 4, 4))
    for (a, alpha, d), th in zip(UR5_DH, q.T):
        ct, st = np.cos(th), np.sin(th)
        ca, sa = math.cos(alpha), math.sin(alpha)
        A = np.zeros((len(q), 4, 4))
        A[:, 0] = np.stack([ct, -st * ca, st * sa, a * ct], axis=1)
        A[:, 1] = np.stack([st, ct * ca, -ct * sa, a * st], axis=1)
        A[:, 2, 1:] = [sa, ca, d]
        A[:, 3, 3] = 1.0
        T = T @ A
    return T


def off_line(P: np.ndarray, p0: np.ndarray, p1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance of points ``P`` from the line through ``p0``, ``p1`` and their parameter."""
    d = p1 - p0
    t = (P - p0) @ d / (d @ d)
    return np.linalg.norm(P - p0 - t[:, None] * d, axis=1), t


def box(oid: str, size, at) -> dict:
    """A box scene object of ``size`` (mm) centred at ``at``."""
    T = np.eye(4)
    T[:3, 3] = at
    return {"type": "box", "id": oid, "size": list(size), "pose": T.tolist()}
