"""Hydraulic limits of a trajectory: cylinder speeds and the pump's flow.

A cylinder driving joint j moves at ``v = dL/dq_j * qd_j`` (mm/s, positive extending). It
may not extend faster than ``max_extension_speed`` nor retract faster than
``max_retraction_speed``. Oil flows into it at ``piston_area * v`` while extending and
``annulus_area * |v|`` while retracting, and every cylinder fed by the pump shares its flow:
``sum_i area_i(sign v_i) |v_i| <= Q``. Along a path q(s) both are first-order in the path
speed: ``v_i = g_i(s) sdot`` with ``g_i = dL_i/dq_j(q(s)) q_j'(s)``, and since the sign of
``g_i`` is known at each grid point, the flow is ``sdot * sum_i area_i(sign g_i) |g_i|``:
each bounds ``sdot^2`` per grid point (``HydraulicLimits.path_bounds``).

Speeds in mm/s, areas in mm^2, flows in mm^3/s inside (L/min at the edges: 1 L/min =
1e6 / 60 mm^3/s).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinematics.cylinders import (
    LPM_TO_MM3_PER_S,
    CylinderError,
    CylinderSet,
    Pump,
    cylinder_set,
)
from kinematics.errors import FieldError
from kinematics.model import RobotModel

__all__ = ["HydraulicLimits", "hydraulic_limits", "LPM_TO_MM3_PER_S"]


@dataclass(frozen=True, eq=False)
class HydraulicLimits:
    """The cylinders of a robot that limit its motion. Arrays ``(C,)`` over ``names``:
    ``joint`` driven; ``max_extension``/``max_retraction`` speeds (mm/s, inf when not
    given); ``piston``/``annulus`` areas (mm^2, 0 for cylinders outside the pump);
    ``pump_flow`` (mm^3/s, inf without a pump)."""

    cylinders: CylinderSet
    names: tuple[str, ...]
    joint: np.ndarray
    max_extension: np.ndarray
    max_retraction: np.ndarray
    piston: np.ndarray
    annulus: np.ndarray
    pump_flow: float

    @property
    def has_pump(self) -> bool:
        return bool(np.isfinite(self.pump_flow))

    def dlength_dq(self, q) -> np.ndarray:
        """``dL_i/dq_joint(i)`` (mm/rad) at ``q (S, dof)`` -> ``(S, C)``."""
        q = np.asarray(q, dtype=float)
        out = np.empty(q.shape[:-1] + (len(self.names),))
        col = {n: i for i, n in enumerate(self.names)}
        for mech in self.cylinders.mechanisms:
            dL = mech.dlengths_dtheta(q[..., mech.joint])
            for k, name in enumerate(mech.names):
                if name in col:
                    out[..., col[name]] = dL[..., k]
        return out

    def speeds(self, q, qd) -> np.ndarray:
        """Cylinder speeds (mm/s, positive extending) ``(S, C)`` at ``q, qd (S, dof)``."""
        qd = np.asarray(qd, dtype=float)
        return self.dlength_dq(q) * qd[..., self.joint]

    def flow(self, speeds: np.ndarray) -> np.ndarray:
        """Pump flow (mm^3/s) ``(S,)`` drawn by cylinder ``speeds (S, C)``."""
        v = np.asarray(speeds, dtype=float)
        return np.where(v > 0, self.piston * v, -self.annulus * v).sum(axis=-1)

    def speed_ratios(self, speeds: np.ndarray) -> np.ndarray:
        """``|v| / limit`` for the direction each cylinder moves in ``(S, C)``."""
        v = np.asarray(speeds, dtype=float)
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.where(v > 0, v / self.max_extension, -v / self.max_retraction)
        return np.nan_to_num(r, nan=0.0)

    def path_bounds(self, q, dq_ds) -> np.ndarray:
        """Largest ``sdot^2`` the cylinders and the pump allow at path points ``q (S, dof)``
        with tangents ``dq_ds (S, dof)``: ``(S,)``, inf where nothing binds."""
        g = self.speeds(q, dq_ds)  # mm per unit of s
        ag = np.abs(g)
        with np.errstate(divide="ignore"):
            lim = np.where(g > 0, self.max_extension, self.max_retraction)
            sd = np.where(ag > 0, lim / ag, np.inf).min(axis=-1, initial=np.inf)
            demand = np.where(g > 0, self.piston * g, -self.annulus * g).sum(axis=-1)
            sd = np.minimum(sd, np.where(demand > 0, self.pump_flow / demand, np.inf))
        return sd**2


def hydraulic_limits(model: RobotModel | None, pump_flow: float | None = None
                     ) -> HydraulicLimits | None:
    """The hydraulic limits of ``model``: cylinders with a speed limit or on the pump, and
    the pump (``pump_flow`` L/min overrides the model's and needs cylinders with bore and
    rod). None for a robot without cylinders or without any hydraulic limit. ``FieldError``
    naming ``pump_flow`` when it is not positive or has nothing to feed."""
    if pump_flow is not None and not (np.isfinite(pump_flow) and pump_flow > 0):
        raise FieldError(("limits", "pump_flow"), "limits.pump_flow: must be positive (L/min)")
    if model is None or "cylinders" not in model.extras:
        if pump_flow is not None:
            raise FieldError(("limits", "pump_flow"), "limits.pump_flow: the robot has no "
                             "cylinders for a pump to feed")
        return None
    cs = cylinder_set(model)
    pump = cs.pump
    if pump_flow is not None:
        if pump is not None:
            pump = Pump(pump_flow, pump.cylinders)
        else:
            fed = tuple(n for n, h in cs.hydraulics.items() if h.has_areas)
            if not fed:
                raise FieldError(("limits", "pump_flow"), "limits.pump_flow: no cylinder of "
                                 "this robot has a bore and rod, so its flow is unknown")
            try:
                pump = Pump(pump_flow, fed)
            except CylinderError as exc:
                raise FieldError(("limits", "pump_flow"), exc.message) from None
    fed = set(pump.cylinders) if pump is not None else set()
    rows = []
    for name in cs.names:
        h = cs.hydraulics.get(name)
        ext = h.max_extension_speed if h and h.max_extension_speed else np.inf
        ret = h.max_retraction_speed if h and h.max_retraction_speed else np.inf
        on_pump = name in fed
        if np.isfinite(ext) or np.isfinite(ret) or on_pump:
            rows.append((name, cs.joint_of(name), ext, ret,
                         h.piston_area if on_pump else 0.0,
                         h.annulus_area if on_pump else 0.0))
    if not rows:
        return None
    names, joint, ext, ret, piston, annulus = (tuple(c) for c in zip(*rows))
    return HydraulicLimits(
        cs, names, np.array(joint), np.array(ext, dtype=float), np.array(ret, dtype=float),
        np.array(piston, dtype=float), np.array(annulus, dtype=float),
        pump.flow_mm3_per_s if pump is not None else np.inf)
