"""Hydraulic cylinders: joint angle <-> cylinder length (paper 000, section 3.4).

The pile-driver paper moves its arm with cylinders, not motors: after IK gives the joint
angles, each angle is turned into the length of the cylinder that drives the joint. Three
mechanisms cover its arm, each a frozen dataclass with its pin geometry as data (mm, rad):

* ``TriangleCylinder`` (boom, eq. 18; stick, eq. 19): the cylinder joins two pins at fixed
  distances ``r1``, ``r2`` from the joint axis; the angle between the two pin rays is
  ``phi = phi0 + sign * theta`` and ``L = sqrt(r1^2 + r2^2 - 2 r1 r2 cos(phi))``.
* ``FourBarCylinder`` (eqs. 20-23): the cylinder G-M drives the rocker N-M of a four-bar
  linkage H-N-M-K whose crank H-K turns with the joint at H (Fig. 4c).
* ``SwingCylinderPair`` (eqs. 24-25): two cylinders (left P-Q, right T-S) about the swing
  joint J; one lengthens as the other shortens.

Every map is vectorised: angles ``theta (*,)`` in rad -> lengths ``(*,)`` in mm (``(*, 2)``
for the swing pair), and back. ``stroke = length - min_length``, the current extension
(``min_length`` is the retracted, ``max_length`` the extended length); the full travel,
``max_length - min_length``, is called travel, never stroke. Cylinder speed (mm/s) is
``dL/dtheta * theta_dot``.

``CylinderSet.from_model(model)`` reads the list under the model's ``"cylinders"`` key (kept in
``model.extras``); see ``kinematics/robots/pile_driver.json`` for the format. Each joint is
driven by at most one mechanism; joints without one (e.g. the pile driver's slewing joint,
driven by a motor) are passed through. Each cylinder may also carry its hydraulics
(``CylinderHydraulics``: ``max_extension_speed``, ``max_retraction_speed`` in mm/s, ``bore``
and ``rod`` diameters in mm), and the robot a pump (``pump_flow`` in L/min shared by the
cylinders named in ``pump_cylinders``, default all with bore and rod): the limits that time
scaling of a hydraulic arm respects (``planning.trajectories.hydraulic``). ``check()``
says, in words, where stroke limits and joint limits disagree; ``check_mechanisms()``
raises, naming the field, for a mechanism that cannot take some joint value of its range (a
four-bar that cannot close: what the service refuses in a model); ``diagnose_limits`` says,
for a configuration outside the joint limits (e.g. the nearest IK solution of a pose), what
it asks of each joint and cylinder at fault.

Pin points (``CylinderSet.pins``, each mechanism's ``pins``) are given in the *joint plane*
of the joint a mechanism drives: a 2-D frame (mm) fixed to the carrying link (the link
before the joint), with its origin on the joint axis, x along the carrying link's reference
ray and y = axis x x. The driven link's reference ray is at angle ``theta`` (the joint value)
from x. The data fix each pin's distance from the joint and the angles between pin rays, not
where the rays point on the links, so the reference rays are a convention: a triangle's rod
pin lies on the driven link's ray and its barrel pin at ``-sign * phi0`` from the carrying
link's; a four-bar's stick (N to H) lies along the carrying link's ray, mirrored by ``sign``
so that K turns with the driven link. Points on the carrying link (barrel pins, H, N, G) keep
their coordinates as the joint turns; points on the driven link (a triangle's rod pin, K)
keep theirs turned back by ``theta``. The distance between a cylinder's two pins is its
``length`` (to rounding), NaN where the mechanism cannot take the joint value.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import StrEnum
from functools import lru_cache
from typing import Any, Protocol

import numpy as np

from .errors import FieldError, KinematicsError, loc_from_path
from .model import MAX_LENGTH_MM, RobotModel

__all__ = [
    "CHECK_SAMPLES",
    "LENGTH_TOL",
    "HYDRAULIC_KEYS",
    "MAX_CYLINDER_SPEED",
    "MAX_PUMP_FLOW",
    "MAX_STROKE_MARGIN",
    "PAIR_LENGTH_TOL",
    "CylinderError",
    "CylinderLimit",
    "CylinderHydraulics",
    "CylinderPins",
    "CylinderSet",
    "FourBarCylinder",
    "JointLimit",
    "LimitCause",
    "Mechanism",
    "MechanismFault",
    "Pump",
    "SwingCylinderPair",
    "TriangleCylinder",
    "cylinder_set",
    "diagnose_limits",
]

#: Lengths this close (mm) outside a stroke still count as inside (round-off of the data).
LENGTH_TOL = 1e-6
#: Largest unused stroke (mm) at either end before ``check`` reports it: a longer stroke than
#: the joint range needs means the joint stop, not the cylinder, ends the motion.
MAX_STROKE_MARGIN = 1.0
#: Joint angles sampled per mechanism by ``check`` (monotonicity, closure of the linkage).
CHECK_SAMPLES = 2001
#: The two cylinders of a swing pair are coupled: given both, they must agree to this (mm).
PAIR_LENGTH_TOL = 0.5

_TWO_PI = 2.0 * math.pi

#: Optional hydraulic fields of one cylinder: speeds in mm/s, diameters in mm.
HYDRAULIC_KEYS = ("max_extension_speed", "max_retraction_speed", "bore", "rod")
#: Largest cylinder speed a model may give (mm/s): 100 m/s, beyond any hydraulic cylinder.
MAX_CYLINDER_SPEED = 1e5
#: Largest pump flow a model may give (L/min).
MAX_PUMP_FLOW = 1e5
#: Litres per minute in mm^3/s.
LPM_TO_MM3_PER_S = 1e6 / 60.0


class CylinderError(FieldError, KinematicsError):
    """Invalid cylinder data or input; ``field`` names the field at fault
    (``cylinders[0].r1``), ``loc`` the same as parts. Given as parts (``("lengths", name)``),
    a field keeps a cylinder name whole, dots and all."""

    def __init__(self, field_path: str | tuple[str | int, ...], message: str):
        parts = isinstance(field_path, tuple)
        super().__init__(field_path if parts else loc_from_path(field_path), message)
        self.field = ".".join(map(str, field_path)) if parts else field_path

    def __str__(self) -> str:
        return f"{self.field}: {self.message}"


# ---- geometry shared by the mechanisms -------------------------------------------------


def _side(r1: float, r2: float, phi: np.ndarray) -> np.ndarray:
    """Law of cosines: the side opposite ``phi`` in a triangle with sides ``r1``, ``r2``."""
    return np.sqrt(np.maximum(r1 * r1 + r2 * r2 - 2.0 * r1 * r2 * np.cos(phi), 0.0))


def _apex_angle(r1: float, r2: float, L: np.ndarray) -> np.ndarray:
    """Inverse of ``_side``: the angle in [0, pi] between sides ``r1``, ``r2`` for the
    opposite side ``L``; NaN where no triangle has these sides."""
    c = (r1 * r1 + r2 * r2 - L * L) / (2.0 * r1 * r2)
    c = np.where(np.abs(c) <= 1.0 + 1e-12, np.clip(c, -1.0, 1.0), np.nan)
    return np.arccos(c)


def _nearest_turn(theta: np.ndarray, lower: float, upper: float) -> np.ndarray:
    """Shift ``theta`` by whole turns toward the joint range (a turn of the pin angle is a
    turn of the joint)."""
    mid = 0.5 * (lower + upper)
    return theta + _TWO_PI * np.round((mid - theta) / _TWO_PI)


def _deg(x: float) -> str:
    return f"{math.degrees(x):.2f} deg"


def _ray(angle, radius: float = 1.0) -> np.ndarray:
    """Points at ``radius`` along rays at ``angle (*,)`` rad in a plane: ``(*, 2)``."""
    angle = np.asarray(angle, dtype=float)
    return radius * np.stack([np.cos(angle), np.sin(angle)], axis=-1)


@dataclass(frozen=True, eq=False)
class CylinderPins:
    """One cylinder's pins at joint values ``theta (*,)``, in the joint plane of the joint it
    drives (module docstring), mm: ``barrel`` on the carrying side, ``rod`` on the driven side,
    each ``(*, 2)``. ``linkage``: for a four-bar, its points ``H, N, K, M, G`` ``(*, 2)`` each
    (``barrel`` is G, ``rod`` is M); empty for the other mechanisms."""

    name: str
    joint: int
    barrel: np.ndarray
    rod: np.ndarray
    linkage: Mapping[str, np.ndarray] = field(default_factory=dict)

    @property
    def length(self) -> np.ndarray:
        """Distance between the pins (mm): the cylinder's length, ``(*,)``."""
        return np.linalg.norm(self.rod - self.barrel, axis=-1)


@dataclass(frozen=True)
class MechanismFault:
    """Where a mechanism cannot take the joint values of its range (a linkage that cannot
    close, pins through a dead point): ``reason`` in words, the first and last failing
    joint values sampled (``lower``, ``upper``, rad), the field most likely at fault
    (``field``, None when no one field can be blamed) and what would cure it (``hint``)."""

    reason: str
    lower: float
    upper: float
    field: str | None = None
    hint: str = ""


def _fault(reason: str, theta: np.ndarray, bad: np.ndarray, field: str | None = None,
           hint: str = "") -> MechanismFault:
    """A ``MechanismFault`` spanning the samples of ``theta (S,)`` where ``bad (S,)``."""
    failing = theta[bad] if bad.any() else theta
    return MechanismFault(reason, float(failing[0]), float(failing[-1]), field, hint)


def _check_cylinder(
    name: str, theta: np.ndarray, L: np.ndarray, dL: np.ndarray, min_length: float,
    max_length: float, tol: float, max_margin: float,
) -> list[str]:
    """Problems of one cylinder sampled over its joint range: ``theta, L, dL (S,)``."""
    problems = []
    if not np.all(np.isfinite(L)) or not np.all(np.isfinite(dL)):
        return problems  # the mechanism has already said why
    rising = dL > 0
    if not (np.all(dL > 0) or np.all(dL < 0)) or not (
        np.all(np.diff(L) > 0) or np.all(np.diff(L) < 0)
    ):
        k = int(np.argmax(rising != rising[0])) if np.any(rising != rising[0]) else 0
        problems.append(
            f"{name}: the length is not monotonic over the joint range: dL/dtheta changes sign "
            f"or vanishes near theta = {_deg(theta[k])}, so one length would give two angles"
        )
        return problems
    lo_i, hi_i = (0, -1) if rising[0] else (-1, 0)
    lo, hi = float(L[lo_i]), float(L[hi_i])
    if lo < min_length - tol:
        problems.append(
            f"{name}: at the joint limit {_deg(theta[lo_i])} the cylinder would be {lo:.3f} mm, "
            f"shorter than its retracted length {min_length:.3f} mm: it bottoms out "
            f"{min_length - lo:.3f} mm before the joint reaches its limit"
        )
    elif lo > min_length + max_margin:
        problems.append(
            f"{name}: at the joint limit {_deg(theta[lo_i])} the cylinder is {lo:.3f} mm, "
            f"{lo - min_length:.3f} mm longer than its retracted length {min_length:.3f} mm: "
            "the joint stop, not the cylinder, ends the motion (travel wasted)"
        )
    if hi > max_length + tol:
        problems.append(
            f"{name}: at the joint limit {_deg(theta[hi_i])} the cylinder would be {hi:.3f} mm, "
            f"longer than its extended length {max_length:.3f} mm: it runs out of travel "
            f"{hi - max_length:.3f} mm before the joint reaches its limit"
        )
    elif hi < max_length - max_margin:
        problems.append(
            f"{name}: at the joint limit {_deg(theta[hi_i])} the cylinder is {hi:.3f} mm, "
            f"{max_length - hi:.3f} mm shorter than its extended length {max_length:.3f} mm: "
            "the joint stop, not the cylinder, ends the motion (travel wasted)"
        )
    if max_length - min_length >= min_length:
        problems.append(
            f"{name}: travel {max_length - min_length:.3f} mm is not below the retracted length "
            f"{min_length:.3f} mm: a hydraulic cylinder's barrel must hold its rod"
        )
    return problems


def _validate(name: str, **values: float) -> None:
    for key, v in values.items():
        if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
            raise CylinderError(key, f"must be a finite number, got {v!r}")
        if abs(v) > MAX_LENGTH_MM:  # lengths in mm; angles are far smaller
            raise CylinderError(key, f"must be within ±{MAX_LENGTH_MM:g}, got {v:g}")
    for key in ("r1", "r2", "l_hn", "l_kh", "l_mn", "l_km", "l_ng"):
        if key in values and values[key] <= 0:
            raise CylinderError(key, f"must be positive (mm), got {values[key]}")
    if "sign" in values and values["sign"] not in (1, -1):
        raise CylinderError("sign", f"must be +1 or -1, got {values['sign']}")
    if not 0 < values["min_length"] < values["max_length"]:
        raise CylinderError(
            "min_length",
            f"need 0 < min_length < max_length, got {values['min_length']} and "
            f"{values['max_length']} mm",
        )
    if not values["lower"] < values["upper"]:
        raise CylinderError("lower", "the joint range must have lower < upper")
    if not isinstance(name, str) or not name:
        raise CylinderError("name", "must be a non-empty string")
    if len(name) > 200 or not name.isprintable():
        raise CylinderError("name", "at most 200 printable characters (no control characters)")


def _validate_fields(cylinder: Any) -> None:
    """``_validate`` a cylinder dataclass: every field but ``name`` and ``joint``."""
    _validate(cylinder.name, **{f.name: getattr(cylinder, f.name)
                                for f in dataclasses.fields(cylinder)
                                if f.name not in ("name", "joint")})


class Mechanism(Protocol):
    """What ``CylinderSet`` needs of a mechanism driving one joint with k cylinders."""

    name: str
    joint: int
    lower: float
    upper: float

    @property
    def names(self) -> tuple[str, ...]: ...

    @property
    def limits(self) -> tuple[tuple[float, float], ...]: ...

    def lengths(self, theta) -> np.ndarray: ...

    def dlengths_dtheta(self, theta) -> np.ndarray: ...

    def angle_of(self, length, index: int = 0) -> np.ndarray: ...

    def pins(self, theta) -> tuple[CylinderPins, ...]: ...

    def check(self, samples: int = ..., tol: float = ..., max_margin: float = ...) -> list[str]:
        ...


class _OneCylinder:
    """Shared by mechanisms with one cylinder (``length``, ``angle``, ``dlength_dtheta``)."""

    name: str
    min_length: float
    max_length: float
    lower: float
    upper: float

    def length(self, theta) -> np.ndarray:  # pragma: no cover - overridden
        raise NotImplementedError

    def angle(self, length) -> np.ndarray:  # pragma: no cover - overridden
        raise NotImplementedError

    def dlength_dtheta(self, theta) -> np.ndarray:  # pragma: no cover - overridden
        raise NotImplementedError

    def _fault(self, theta: np.ndarray) -> MechanismFault | None:  # pragma: no cover
        raise NotImplementedError

    @property
    def names(self) -> tuple[str, ...]:
        return (self.name,)

    @property
    def limits(self) -> tuple[tuple[float, float], ...]:
        return ((self.min_length, self.max_length),)

    def stroke(self, theta) -> np.ndarray:
        """Extension beyond the retracted length (mm): ``theta (*,) -> (*,)``."""
        return self.length(theta) - self.min_length

    def speed(self, theta, theta_dot) -> np.ndarray:
        """Cylinder speed (mm/s, positive = extending) for joint speed ``theta_dot`` (rad/s)."""
        return self.dlength_dtheta(theta) * np.asarray(theta_dot, dtype=float)

    def joint_speed(self, theta, length_speed) -> np.ndarray:
        """Joint speed (rad/s) at ``theta`` for cylinder speed ``length_speed`` (mm/s)."""
        return np.asarray(length_speed, dtype=float) / self.dlength_dtheta(theta)

    def lengths(self, theta) -> np.ndarray:
        return self.length(theta)[..., None]

    def dlengths_dtheta(self, theta) -> np.ndarray:
        return self.dlength_dtheta(theta)[..., None]

    def angle_of(self, length, index: int = 0) -> np.ndarray:
        return self.angle(length)

    def check(
        self, samples: int = CHECK_SAMPLES, tol: float = LENGTH_TOL,
        max_margin: float = MAX_STROKE_MARGIN,
    ) -> list[str]:
        """Problems (in words) between the joint range and the stroke; empty if they agree."""
        theta = np.linspace(self.lower, self.upper, samples)
        fault = self._fault(theta)
        if fault is not None:
            return [f"{self.name}: {fault.reason}"]
        return _check_cylinder(
            self.name, theta, self.length(theta), self.dlength_dtheta(theta),
            self.min_length, self.max_length, tol, max_margin,
        )

    def fault(self, samples: int = CHECK_SAMPLES) -> MechanismFault | None:
        """Where in its joint range, if anywhere, the mechanism cannot take the joint value:
        what ``check`` looks at first, on the same samples (None: nowhere)."""
        return self._fault(np.linspace(self.lower, self.upper, samples))


@dataclass(frozen=True)
class TriangleCylinder(_OneCylinder):
    """A cylinder between two pins at distances ``r1``, ``r2`` (mm) from the joint axis (eqs.
    18, 19). The angle between the pin rays is ``phi = phi0 + sign * theta`` (rad) and must
    stay in (0, pi) over the joint range ``[lower, upper]`` (rad) for the map to be one-to-one.

    Boom (eq. 18): r1 = L_AC, r2 = L_AD, phi0 = angle CAT + angle BAD, sign = +1.
    Stick (eq. 19): r1 = L_BE, r2 = L_BF, phi0 = 180 deg - angle FBH - angle ABE, sign = +1.

    >>> c = TriangleCylinder("c", 0, r1=300.0, r2=400.0, phi0=math.pi / 2, sign=1,
    ...                      min_length=400.0, max_length=600.0, lower=-0.5, upper=0.5)
    >>> round(float(c.length(0.0)), 9)  # a 3-4-5 triangle
    500.0
    """

    name: str
    joint: int
    r1: float
    r2: float
    phi0: float
    sign: int
    min_length: float
    max_length: float
    lower: float
    upper: float

    def __post_init__(self) -> None:
        _validate_fields(self)

    def phi(self, theta) -> np.ndarray:
        """Angle between the pin rays (rad): ``theta (*,) -> (*,)``."""
        return self.phi0 + self.sign * np.asarray(theta, dtype=float)

    def length(self, theta) -> np.ndarray:
        """Cylinder length (mm) between the pins: ``theta (*,) rad -> (*,) mm``."""
        return _side(self.r1, self.r2, self.phi(theta))

    def dlength_dtheta(self, theta) -> np.ndarray:
        """``dL/dtheta = sign r1 r2 sin(phi) / L`` (mm/rad): ``(*,) -> (*,)``."""
        phi = self.phi(theta)
        return self.sign * self.r1 * self.r2 * np.sin(phi) / _side(self.r1, self.r2, phi)

    def angle(self, length) -> np.ndarray:
        """Joint angle (rad) for a cylinder length (mm): ``(*,) -> (*,)``; the branch with
        phi in [0, pi], taken to the turn nearest the joint range. NaN where no triangle has
        the pin distances and this length."""
        phi = _apex_angle(self.r1, self.r2, np.asarray(length, dtype=float))
        theta = (phi - self.phi0) * self.sign
        return _nearest_turn(theta, self.lower, self.upper)

    def pins(self, theta) -> tuple[CylinderPins, ...]:
        """The pins at ``theta (*,)`` in the joint plane: the barrel pin ``r1`` out at
        ``-sign * phi0`` (fixed to the carrying link), the rod pin ``r2`` out on the driven
        link's ray (at ``theta``), so the angle between them is ``phi0 + sign * theta``."""
        theta = np.asarray(theta, dtype=float)
        barrel = np.broadcast_to(_ray(-self.sign * self.phi0, self.r1), theta.shape + (2,))
        return (CylinderPins(self.name, self.joint, barrel, _ray(theta, self.r2)),)

    def _fault(self, theta: np.ndarray) -> MechanismFault | None:
        phi = self.phi(theta)
        phi_mod = np.mod(phi, _TWO_PI)
        bad = ~((phi_mod > 0) & (phi_mod < math.pi))
        if not bad.any() and np.ptp(phi) < math.pi:
            return None
        reason = (
            f"the pin angle phi = phi0 + sign*theta runs from {_deg(phi[0])} to "
            f"{_deg(phi[-1])} over the joint range [{_deg(self.lower)}, {_deg(self.upper)}] and "
            "leaves (0, 180) deg: the pins pass a dead point (cylinder in line with the joint) "
            "and the length is not monotonic"
        )
        # phi0 turns every pin angle alike, so it is at fault unless the range is too wide
        # for any phi0 (then the joint limits are, and they are not the cylinder's fields).
        if np.ptp(phi) < math.pi:
            return _fault(reason, theta, bad, "phi0")
        return _fault(reason, theta, bad)


#: The bars of a four-bar whose lengths decide whether it closes: L_KH and L_HN set L_KN,
#: which the rocker L_MN and the coupler L_KM must bridge (``FourBarCylinder._angles``).
_CLOSING_FIELDS = ("l_kh", "l_hn", "l_mn", "l_km")
#: Lengths of one bar tried when blaming one for a linkage that cannot close, as fractions
#: of the other three together: 1/10,000 to 1, 0.23 % apart.
_CLOSING_FACTORS = np.geomspace(1e-4, 1.0, 4001)


@dataclass(frozen=True)
class FourBarCylinder(_OneCylinder):
    """A cylinder G-M driving the rocker N-M of the four-bar linkage H-N-M-K (eqs. 20-23).

    Points (Fig. 4c): H is the joint axis (stick tip) and N the rocker pivot, both on the
    stick; K is a pin of the driven link at ``l_kh`` from H; the rocker N-M (``l_mn``) and the
    coupler M-K (``l_km``) meet at M, where the cylinder's rod is pinned; G is the cylinder's
    base pin on the stick at ``l_ng`` from N. Angles at the joint and at N:

    * ``angle KHN = psi0 + sign * theta`` (rad), in (0, pi) over the joint range;
    * eq. 21: ``L_KN^2 = L_KH^2 + L_HN^2 - 2 L_KH L_HN cos(KHN)``;
    * eqs. 22, 23: ``angle KNH`` and ``angle KNM`` by the law of cosines;
    * ``angle MNG = 2 pi - angle_gnh - angle KNH - angle KNM`` with ``angle_gnh`` = angle GNB +
      angle BNH, the fixed angle at N from the G ray to the H ray;
    * eq. 20: ``L_MG^2 = L_MN^2 + L_NG^2 - 2 L_MN L_NG cos(MNG)``.

    The inverse is closed form: the length fixes angle MNG, hence M; K is where the circles
    about H (radius l_kh) and M (radius l_km) meet, on the side the forward map assembles.
    """

    name: str
    joint: int
    l_hn: float
    l_kh: float
    l_mn: float
    l_km: float
    l_ng: float
    psi0: float
    sign: int
    angle_gnh: float
    min_length: float
    max_length: float
    lower: float
    upper: float

    def __post_init__(self) -> None:
        _validate_fields(self)

    def _angles(self, theta, **lengths) -> dict[str, np.ndarray]:
        """Every intermediate angle (rad) and length (mm) of the linkage, each ``(*,)``.
        ``lengths`` (any of ``_CLOSING_FIELDS``) stand in for the model's, broadcast with
        ``theta``: the same linkage with other bars (``_closing_field``)."""
        a, b, m, k = (lengths.get(key, getattr(self, key)) for key in _CLOSING_FIELDS)
        khn = self.psi0 + self.sign * np.asarray(theta, dtype=float)
        kn = _side(a, b, khn)  # eq. 21
        # eq. 22 as atan2 of K seen from N (H on N's +x axis): exact where arccos loses digits.
        knh = np.arctan2(a * np.sin(khn), b - a * np.cos(khn))
        u = (m * m + kn * kn - k * k) / (2.0 * m * kn)
        knm = np.arccos(np.where(np.abs(u) <= 1.0, u, np.nan))  # eq. 23; NaN: cannot close
        mng = _TWO_PI - self.angle_gnh - knh - knm
        return {"khn": khn, "kn": kn, "knh": knh, "knm": knm, "u": u, "mng": mng}

    def length(self, theta) -> np.ndarray:
        """Cylinder length L_MG (mm): ``theta (*,) rad -> (*,) mm`` (NaN where the linkage
        cannot close)."""
        return _side(self.l_mn, self.l_ng, self._angles(theta)["mng"])

    def points(self, theta) -> dict[str, np.ndarray]:
        """Points H, N, K, M, G of the linkage at ``theta (*,)`` in the joint plane (module
        docstring), ``(*, 2)`` mm each, from the angles ``length`` uses: H at the origin, N at
        ``-l_hn`` on x; M is NaN where the linkage cannot close."""
        a, b, m = self.l_kh, self.l_hn, self.l_mn
        s = self._angles(theta)
        khn = s["khn"]
        # Laid out with N at the origin and H on +x, K on the +y side; then moved so that H
        # is the origin and mirrored by ``sign``.
        own = {
            "H": np.broadcast_to(np.array([b, 0.0]), khn.shape + (2,)),
            "N": np.zeros(khn.shape + (2,)),
            "K": np.stack([b - a * np.cos(khn), a * np.sin(khn)], axis=-1),
            "M": _ray(s["knh"] + s["knm"], m),
            "G": np.broadcast_to(_ray(-self.angle_gnh, self.l_ng), khn.shape + (2,)),
        }
        flip = np.array([1.0, -float(self.sign)])
        return {key: (p - [b, 0.0]) * flip for key, p in own.items()}

    def pins(self, theta) -> tuple[CylinderPins, ...]:
        """The cylinder's pins G (barrel, on the stick) and M (rod, on the rocker) at
        ``theta (*,)`` in the joint plane, with every point of the linkage (``points``)."""
        P = self.points(theta)
        return (CylinderPins(self.name, self.joint, P["G"], P["M"], P),)

    def dlength_dtheta(self, theta) -> np.ndarray:
        """Analytic ``dL_MG/dtheta`` (mm/rad): ``(*,) -> (*,)``."""
        a, b, m, g = self.l_kh, self.l_hn, self.l_mn, self.l_ng
        s = self._angles(theta)
        khn, kn, u, mng = s["khn"], s["kn"], s["u"], s["mng"]
        dkn = a * b * np.sin(khn) / kn
        dknh = (a * b * np.cos(khn) - a * a) / (kn * kn)
        du = (kn * kn - m * m + self.l_km**2) / (2.0 * m * kn * kn)
        dknm = -du / np.sqrt(1.0 - u * u) * dkn
        dmng = -(dknh + dknm) * self.sign
        return m * g * np.sin(mng) / _side(m, g, mng) * dmng

    def angle(self, length) -> np.ndarray:
        """Joint angle (rad) for a cylinder length (mm): ``(*,) -> (*,)``, NaN where the
        linkage cannot take this length."""
        a, b, m, k = self.l_kh, self.l_hn, self.l_mn, self.l_km
        mng = _apex_angle(m, self.l_ng, np.asarray(length, dtype=float))
        hnm = _TWO_PI - self.angle_gnh - mng  # = angle KNH + angle KNM
        # N at the origin, H at (b, 0): M on the rocker circle, K on both circles.
        Mx, My = m * np.cos(hnm), m * np.sin(hnm)
        dx, dy = Mx - b, My
        dist = np.hypot(dx, dy)
        along = (a * a - k * k + dist * dist) / (2.0 * dist)
        h2 = a * a - along * along
        h = np.sqrt(np.where(h2 >= -1e-9 * a * a, np.maximum(h2, 0.0), np.nan))
        ex, ey = dx / dist, dy / dist
        best = np.full(np.shape(dist), np.nan)
        best_gap = np.full(np.shape(dist), np.inf)
        for side in (1.0, -1.0):
            Kx = b + along * ex - side * h * ey
            Ky = along * ey + side * h * ex
            # The forward map has K above N-H (angle KHN in (0, pi)) and M turned further
            # the same way from K (angle KNM in (0, pi)).
            ok = (Ky > 0) & (Kx * My - Ky * Mx > 0)
            theta = (np.arctan2(Ky, b - Kx) - self.psi0) * self.sign
            theta = _nearest_turn(theta, self.lower, self.upper)
            gap = np.maximum(self.lower - theta, 0) + np.maximum(theta - self.upper, 0)
            take = ok & (gap < best_gap)
            best = np.where(take, theta, best)
            best_gap = np.where(take, gap, best_gap)
        return best

    def _fault(self, theta: np.ndarray) -> MechanismFault | None:
        s = self._angles(theta)
        khn = np.mod(s["khn"], _TWO_PI)
        bad = ~((khn > 0) & (khn < math.pi))
        if bad.any():
            reason = (
                f"angle KHN = psi0 + sign*theta leaves (0, 180) deg over the joint range "
                f"[{_deg(self.lower)}, {_deg(self.upper)}]"
            )
            # psi0 shifts angle KHN alike over the range: a range under 180 deg fits some psi0.
            return _fault(reason, theta, bad, "psi0" if np.ptp(s["khn"]) < math.pi else None)
        bad = ~(np.abs(s["u"]) < 1.0)
        if bad.any():
            i = int(np.argmax(bad))
            lo, hi = abs(self.l_mn - self.l_km), self.l_mn + self.l_km
            reason = (
                f"the linkage cannot close (or toggles) at theta = {_deg(theta[i])}: L_KN = "
                f"{s['kn'][i]:.3f} mm is outside ({lo:.3f}, {hi:.3f}) mm = (|L_MN - L_KM|, "
                "L_MN + L_KM)"
            )
            return _fault(reason, theta, bad, *self._closing_field())
        mng = s["mng"]
        bad = ~((mng > 0) & (mng < math.pi))
        if bad.any():
            reason = (
                f"angle MNG runs from {_deg(mng[0])} to {_deg(mng[-1])} and leaves (0, 180) deg "
                "over the joint range: the cylinder passes a dead point"
            )
            # angle_gnh shifts angle MNG alike over the range.
            return _fault(reason, theta, bad, "angle_gnh" if np.ptp(mng) < math.pi else None)
        return None

    def _closing_field(self) -> tuple[str | None, str]:
        """The bar to blame when the linkage cannot close somewhere in its joint range, and
        what would cure it. Of the four bars that set L_KN and the span M must bridge, the
        suspects are those that alone could close it over the whole range, the others as
        they are; named is the one most out of proportion with the other three (as a slip
        of a digit or of units leaves it), then the one needing the smaller change. None
        when no bar alone can."""
        # L_KN grows with angle KHN on (0, pi) (checked before): the limits decide closure.
        ends = np.array([self.lower, self.upper])
        best: tuple[tuple[float, float], str | None, str] = ((-1.0, 0.0), None, "")
        for key in _CLOSING_FIELDS:
            value = getattr(self, key)
            others = [getattr(self, k) for k in _CLOSING_FIELDS if k != key]
            # No bar of a closed four-bar is longer than the other three together.
            trial = sum(others) * _CLOSING_FACTORS
            u = self._angles(ends, **{key: trial[:, None]})["u"]
            closing = trial[np.all(np.abs(u) < 1.0, axis=1)]
            if not len(closing):
                continue
            change = np.abs(np.log(closing / value))
            score = (abs(math.log(value / float(np.median(others)))), -float(change.min()))
            if score > best[0]:
                best = (score, key, f"the nearest {key} that closes it over the whole range, "
                        f"the other bars as they are, is about "
                        f"{closing[np.argmin(change)]:.4g} mm")
        return best[1], best[2]


@dataclass(frozen=True)
class SwingCylinderPair:
    """Two cylinders about the swing joint J (eqs. 24, 25), each a ``TriangleCylinder`` on J:
    ``left`` (P-Q: r1 = L_PJ, r2 = L_QJ, angle PJQ = phi0 - theta, so sign = -1) and ``right``
    (T-S: r1 = L_TJ, r2 = L_SJ, angle SJT = phi0 + theta, sign = +1). Opposite signs: one
    lengthens as the other shortens. Lengths are ``(*, 2)``: [left, right]."""

    name: str
    joint: int
    left: TriangleCylinder
    right: TriangleCylinder

    def __post_init__(self) -> None:
        for side, c in (("left", self.left), ("right", self.right)):
            if c.joint != self.joint or (c.lower, c.upper) != (self.left.lower, self.left.upper):
                raise CylinderError(side, "both cylinders of a pair drive the pair's joint")
        if self.left.sign == self.right.sign:
            raise CylinderError(
                "right.sign", "the two swing cylinders must have opposite signs (one lengthens "
                "as the other shortens)"
            )
        if self.left.name == self.right.name:
            raise CylinderError("right.name", "the two swing cylinders need different names")

    @property
    def lower(self) -> float:
        return self.left.lower

    @property
    def upper(self) -> float:
        return self.left.upper

    @property
    def sides(self) -> tuple[TriangleCylinder, TriangleCylinder]:
        return (self.left, self.right)

    @property
    def names(self) -> tuple[str, ...]:
        return (self.left.name, self.right.name)

    @property
    def limits(self) -> tuple[tuple[float, float], ...]:
        return tuple((c.min_length, c.max_length) for c in self.sides)

    def length(self, theta) -> np.ndarray:
        """Lengths [left, right] (mm): ``theta (*,) rad -> (*, 2)``."""
        return np.stack([c.length(theta) for c in self.sides], axis=-1)

    def dlength_dtheta(self, theta) -> np.ndarray:
        """``dL/dtheta`` [left, right] (mm/rad): ``(*,) -> (*, 2)``."""
        return np.stack([c.dlength_dtheta(theta) for c in self.sides], axis=-1)

    def angle(self, length, side: int = 0) -> np.ndarray:
        """Joint angle (rad) from one cylinder's length (mm), ``side`` 0 = left, 1 = right."""
        return self.sides[side].angle(length)

    def stroke(self, theta) -> np.ndarray:
        """``(*,) -> (*, 2)`` extensions beyond the retracted lengths (mm)."""
        return self.length(theta) - np.array([c.min_length for c in self.sides])

    def speed(self, theta, theta_dot) -> np.ndarray:
        """Cylinder speeds [left, right] (mm/s) for joint speed ``theta_dot (*,)`` (rad/s)."""
        return self.dlength_dtheta(theta) * np.asarray(theta_dot, dtype=float)[..., None]

    def joint_speed(self, theta, length_speed, side: int = 0) -> np.ndarray:
        """Joint speed (rad/s) from one cylinder's speed (mm/s)."""
        return self.sides[side].joint_speed(theta, length_speed)

    def pins(self, theta) -> tuple[CylinderPins, ...]:
        """The pins of both cylinders [left, right] at ``theta (*,)`` in the joint plane."""
        return self.left.pins(theta) + self.right.pins(theta)

    lengths = length
    dlengths_dtheta = dlength_dtheta
    angle_of = angle

    def check(
        self, samples: int = CHECK_SAMPLES, tol: float = LENGTH_TOL,
        max_margin: float = MAX_STROKE_MARGIN,
    ) -> list[str]:
        """Problems of both cylinders (see ``TriangleCylinder.check``)."""
        return [p for c in self.sides for p in c.check(samples, tol, max_margin)]


# ---- hydraulics: cylinder speeds, areas and the pump ------------------------------------


def _positive(value: Any, key: str, bound: float) -> float:
    if not isinstance(value, (int, float)) or isinstance(value, bool) or \
            not math.isfinite(value):
        raise CylinderError(key, f"must be a finite number, got {value!r}")
    if not 0 < value <= bound:
        raise CylinderError(key, f"must be positive and at most {bound:g}, got {value:g}")
    return float(value)


@dataclass(frozen=True)
class CylinderHydraulics:
    """The hydraulic side of one cylinder, every field optional: the largest extension and
    retraction speeds (mm/s) and the bore (piston) and rod diameters (mm). Oil flow is
    ``piston_area * speed`` while extending and ``annulus_area * speed`` while retracting.

    >>> h = CylinderHydraulics("boom", 150.0, 200.0, bore=100.0, rod=60.0)
    >>> round(h.piston_area), round(h.annulus_area)  # mm^2
    (7854, 5027)
    """

    name: str
    max_extension_speed: float | None = None
    max_retraction_speed: float | None = None
    bore: float | None = None
    rod: float | None = None

    def __post_init__(self) -> None:
        for key in ("max_extension_speed", "max_retraction_speed"):
            if getattr(self, key) is not None:
                _positive(getattr(self, key), key, MAX_CYLINDER_SPEED)
        for key in ("bore", "rod"):
            if getattr(self, key) is not None:
                _positive(getattr(self, key), key, MAX_LENGTH_MM)
        if (self.bore is None) != (self.rod is None):
            missing = "rod" if self.rod is None else "bore"
            raise CylinderError(missing, "bore and rod are given together (the oil flow needs "
                                "both the piston and the annulus area)")
        if self.bore is not None and self.rod >= self.bore:
            raise CylinderError("rod", f"the rod diameter {self.rod:g} mm must be smaller than "
                                f"the bore {self.bore:g} mm")

    @property
    def has_areas(self) -> bool:
        return self.bore is not None

    @property
    def piston_area(self) -> float:
        """Area the oil pushes on while extending (mm^2); NaN without a bore."""
        return math.nan if self.bore is None else math.pi * self.bore**2 / 4.0

    @property
    def annulus_area(self) -> float:
        """Area the oil pushes on while retracting: piston less rod (mm^2); NaN without."""
        if self.bore is None:
            return math.nan
        return math.pi * (self.bore**2 - self.rod**2) / 4.0


@dataclass(frozen=True)
class Pump:
    """One pump of ``flow`` L/min feeding the named ``cylinders`` (all moving at once share it)."""

    flow: float
    cylinders: tuple[str, ...]

    def __post_init__(self) -> None:
        _positive(self.flow, "pump_flow", MAX_PUMP_FLOW)

    @property
    def flow_mm3_per_s(self) -> float:
        """The flow in mm^3/s (1 L/min = 1e6 / 60 mm^3/s)."""
        return self.flow * LPM_TO_MM3_PER_S


# ---- a robot's set of cylinders --------------------------------------------------------


@dataclass(frozen=True, eq=False)
class CylinderSet:
    """Every cylinder of one robot, by name, in model order; ``mechanisms`` each drive one
    joint (index into ``joint_names``). Joint values ``q (*, dof)``: rad (and mm for
    prismatic joints, which no cylinder drives); lengths in mm; speeds in mm/s and rad/s."""

    robot: str
    joint_names: tuple[str, ...]
    mechanisms: tuple[Mechanism, ...]
    #: Hydraulic data by cylinder name (only the cylinders that have some).
    hydraulics: Mapping[str, CylinderHydraulics] = field(default_factory=dict)
    pump: Pump | None = None
    _index: dict[str, tuple[int, int]] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        index: dict[str, tuple[int, int]] = {}
        joints: set[int] = set()
        for m, mech in enumerate(self.mechanisms):
            if mech.joint in joints:
                raise CylinderError(
                    f"cylinders[{m}].joint",
                    f"joint '{self.joint_names[mech.joint]}' is already driven by another "
                    "mechanism",
                )
            joints.add(mech.joint)
            for k, name in enumerate(mech.names):
                if name in index:
                    raise CylinderError(f"cylinders[{m}].name", f"duplicate cylinder '{name}'")
                index[name] = (m, k)
        object.__setattr__(self, "_index", index)
        for name in self.hydraulics:
            if name not in index:
                raise CylinderError("cylinders", f"hydraulic data for unknown cylinder '{name}'")
        if self.pump is not None:
            for k, name in enumerate(self.pump.cylinders):
                h = self.hydraulics.get(name)
                if name not in index:
                    raise CylinderError(("pump_cylinders", k), f"robot '{self.robot}' has no "
                                        f"cylinder '{name}'; it has {', '.join(index)}")
                if h is None or not h.has_areas:
                    raise CylinderError(("pump_cylinders", k), f"cylinder '{name}' has no bore "
                                        "and rod: the pump cannot know its flow")
            if len(set(self.pump.cylinders)) != len(self.pump.cylinders):
                raise CylinderError("pump_cylinders", "each cylinder at most once")
            if not self.pump.cylinders:
                raise CylinderError("pump_flow", "the pump needs cylinders with bore and rod "
                                    "to feed")

    @property
    def dof(self) -> int:
        return len(self.joint_names)

    @property
    def names(self) -> tuple[str, ...]:
        """Cylinder names in model order."""
        return tuple(self._index)

    def joint_of(self, name: str) -> int:
        """Index of the joint that cylinder ``name`` drives."""
        return self.mechanisms[self._locate(name)[0]].joint

    def limits(self, name: str) -> tuple[float, float]:
        """``(min_length, max_length)`` of cylinder ``name`` (mm)."""
        m, k = self._locate(name)
        return self.mechanisms[m].limits[k]

    def _locate(self, name: str, field_path: str | tuple[str, str] | None = None
                ) -> tuple[int, int]:
        try:
            return self._index[name]
        except KeyError:
            raise CylinderError(
                field_path or "name",
                f"robot '{self.robot}' has no cylinder '{name}'; it has "
                f"{', '.join(self.names)}",
            ) from None

    def _rows(self, q, field_path: str) -> np.ndarray:
        q = np.asarray(q, dtype=float)
        if q.ndim == 0 or q.shape[-1] != self.dof:
            raise CylinderError(
                field_path, f"must have shape (*, {self.dof}) for robot '{self.robot}', got "
                f"{list(q.shape)}"
            )
        if not np.all(np.isfinite(q)):
            raise CylinderError(field_path, "has a NaN or infinite entry")
        return q

    # ---- forward ------------------------------------------------------------------------
    def lengths(self, q) -> dict[str, np.ndarray]:
        """Cylinder lengths (mm) by name: ``q (*, dof) -> {name: (*,)}``."""
        q = self._rows(q, "q")
        out: dict[str, np.ndarray] = {}
        for mech in self.mechanisms:
            L = mech.lengths(q[..., mech.joint])
            for k, name in enumerate(mech.names):
                out[name] = L[..., k]
        return out

    def speeds(self, q, qd) -> dict[str, np.ndarray]:
        """Cylinder speeds (mm/s, positive = extending): ``q, qd (*, dof) -> {name: (*,)}``."""
        q = self._rows(q, "q")
        qd = self._rows(qd, "qd")
        out: dict[str, np.ndarray] = {}
        for mech in self.mechanisms:
            dL = mech.dlengths_dtheta(q[..., mech.joint]) * qd[..., mech.joint, None]
            for k, name in enumerate(mech.names):
                out[name] = dL[..., k]
        return out

    def pins(self, q) -> dict[str, CylinderPins]:
        """Every cylinder's pins by name, in model order: ``q (*, dof) -> {name:
        CylinderPins}`` with points ``(*, 2)`` mm in the joint plane of the joint each drives
        (module docstring). The distance between a cylinder's pins is ``lengths(q)[name]``."""
        q = self._rows(q, "q")
        return {p.name: p for mech in self.mechanisms for p in mech.pins(q[..., mech.joint])}

    def within_stroke(self, lengths: Mapping[str, Any], tol: float = LENGTH_TOL) -> dict:
        """Whether each given length (mm) lies in its cylinder's stroke: ``{name: (*,) bool}``."""
        out = {}
        for name, L in lengths.items():
            lo, hi = self.limits(name)
            L = np.asarray(L, dtype=float)
            out[name] = (L >= lo - tol) & (L <= hi + tol)
        return out

    # ---- inverse ------------------------------------------------------------------------
    def joints_from_lengths(
        self, lengths: Mapping[str, Any], q_other=None, *, tol: float = LENGTH_TOL,
        pair_tol: float = PAIR_LENGTH_TOL,
    ) -> np.ndarray:
        """Joint values from cylinder lengths: ``{name: (*,) mm}`` -> ``q (*, dof)``.

        Joints whose cylinders are not given keep their value from ``q_other`` (``(dof,)`` or
        ``(*, dof)``; default 0). A length outside its stroke (by more than ``tol``) raises
        ``CylinderError`` naming ``lengths.<name>``; so do unknown names and the two
        cylinders of a pair disagreeing by more than ``pair_tol`` mm.
        """
        given: dict[str, np.ndarray] = {}
        for name, value in lengths.items():
            path = ("lengths", name)
            self._locate(name, path)
            L = np.asarray(value, dtype=float)
            if not np.all(np.isfinite(L)):
                raise CylinderError(path, "has a NaN or infinite entry")
            lo, hi = self.limits(name)
            out = (L < lo - tol) | (L > hi + tol)
            if out.any():
                bad = float(L[out].flat[0])
                raise CylinderError(
                    path, f"{bad:.6g} mm is outside the stroke of cylinder '{name}': "
                    f"[{lo:.3f}, {hi:.3f}] mm"
                )
            given[name] = np.clip(L, lo, hi)
        shape = np.broadcast_shapes(*(v.shape for v in given.values())) if given else ()
        if q_other is None:
            q = np.zeros((*shape, self.dof))
        else:
            q_other = self._rows(q_other, "q")
            q = np.array(np.broadcast_to(q_other, np.broadcast_shapes(
                q_other.shape, (*shape, self.dof))), dtype=float)
        for mech in self.mechanisms:
            present = [k for k, n in enumerate(mech.names) if n in given]
            if not present:
                continue
            thetas = [mech.angle_of(given[mech.names[k]], k) for k in present]
            for k, theta in zip(present, thetas):
                if not np.all(np.isfinite(theta)):
                    raise CylinderError(
                        ("lengths", mech.names[k]), "no joint angle gives this length (the "
                        "cylinder data is inconsistent; see check())"
                    )
            if len(present) > 1:
                # The pair is rigidly coupled: the second length must be the one the first implies.
                implied = mech.lengths(thetas[0])[..., present[1]]
                gap = np.abs(implied - given[mech.names[present[1]]])
                if np.any(gap > pair_tol):
                    raise CylinderError(
                        ("lengths", mech.names[present[1]]),
                        f"disagrees with '{mech.names[present[0]]}' by {float(gap.max()):.3f} "
                        f"mm (more than {pair_tol} mm): the two cylinders of a pair move "
                        "together; give one, or lengths that match",
                    )
            q[..., mech.joint] = sum(thetas) / len(thetas)
        return q

    def joint_speeds(self, q, speeds: Mapping[str, Any], qd_other=None) -> np.ndarray:
        """Joint speeds from cylinder speeds: ``q (*, dof)``, ``{name: (*,) mm/s}`` ->
        ``qd (*, dof)`` (rad/s); joints without a given cylinder keep ``qd_other`` (default 0).
        For a pair, the first cylinder given decides."""
        q = self._rows(q, "q")
        qd = np.zeros_like(q) if qd_other is None else np.array(
            np.broadcast_to(self._rows(qd_other, "qd"), q.shape), dtype=float)
        done: set[int] = set()
        for name, v in speeds.items():
            m, k = self._locate(name, ("speeds", name))
            mech = self.mechanisms[m]
            if m in done:
                continue
            done.add(m)
            dL = mech.dlengths_dtheta(q[..., mech.joint])[..., k]
            qd[..., mech.joint] = np.asarray(v, dtype=float) / dL
        return qd

    def check(
        self, samples: int = CHECK_SAMPLES, tol: float = LENGTH_TOL,
        max_margin: float = MAX_STROKE_MARGIN,
    ) -> list[str]:
        """Every disagreement between stroke limits and joint limits, in words (empty: none)."""
        return [p for mech in self.mechanisms for p in mech.check(samples, tol, max_margin)]

    def check_mechanisms(self, samples: int = CHECK_SAMPLES) -> None:
        """Raise ``CylinderError`` for the first cylinder whose mechanism cannot take some
        joint value of its joint's range (a four-bar that cannot close, pins through a dead
        point), naming the field most likely at fault (``cylinders[2].l_mn``; the cylinder
        when no one field is) and where in the range it fails.

        ``check`` finds the same first, on the same ``samples`` joint values from limit to
        limit, both limits included. Closure needs no more: L_KN grows with angle KHN on
        (0, pi), so a four-bar closes everywhere once it closes at both limits; a triangle's
        pin angle is linear in the joint value; only a four-bar's angle MNG is sampled
        (steps under pi / (samples - 1) rad, as angle KHN keeps the range under pi).
        Unlike ``check``'s stroke mismatches, which a robot may live with, these leave the
        joint without a cylinder length there (NaN in every map through it: lengths, speeds,
        the pump's flow) or with a joint that stops following its cylinder."""
        for m, mech in enumerate(self.mechanisms):
            parts = zip((".left", ".right"), mech.sides) \
                if isinstance(mech, SwingCylinderPair) else (("", mech),)
            for sub, cyl in parts:
                fault = cyl.fault(samples)
                if fault is None:
                    continue
                joint = f"joint '{self.joint_names[cyl.joint]}' (q[{cyl.joint}])"
                where = f"{joint} = {fault.lower:.6g} rad" if fault.lower == fault.upper \
                    else f"{joint} from {fault.lower:.6g} to {fault.upper:.6g} rad"
                message = (f"cylinder {m} ('{cyl.name}'): the mechanism cannot take {where} "
                           f"of the joint's range [{cyl.lower:.6g}, {cyl.upper:.6g}] rad: "
                           f"{fault.reason}")
                path = f"cylinders[{m}]{sub}"
                if fault.field is not None:
                    path += f".{fault.field}"
                    message += f"; {fault.field} = {getattr(cyl, fault.field):g} is the field " \
                        "most likely at fault"
                    if fault.hint:
                        message += f" ({fault.hint})"
                raise CylinderError(path, message)

    # ---- construction -------------------------------------------------------------------
    @classmethod
    def from_model(cls, model: RobotModel) -> CylinderSet:
        """Read ``model.extras["cylinders"]``; ``CylinderError`` names the field at fault."""
        data = model.extras.get("cylinders")
        if data is None:
            for key in ("pump_flow", "pump_cylinders"):
                if key in model.extras:
                    raise CylinderError(key, "a pump needs the robot's cylinders to feed")
            raise CylinderError("cylinders", f"robot '{model.id}' has no cylinders")
        if not isinstance(data, list) or not data:
            raise CylinderError("cylinders", "must be a non-empty list of mechanisms")
        mechanisms = tuple(_mechanism(model, d, f"cylinders[{i}]") for i, d in enumerate(data))
        hydraulics = {h.name: h for i, d in enumerate(data)
                      for h in _hydraulics(d, f"cylinders[{i}]")}
        return cls(model.id, tuple(j.name for j in model.joints), mechanisms, hydraulics,
                   _pump(model.extras, hydraulics))


_KINDS = {"triangle", "four_bar", "swing_pair"}
_TRIANGLE_KEYS = {"r1", "r2", "phi0", "sign", "min_length", "max_length"}
_FOUR_BAR_KEYS = {
    "l_hn", "l_kh", "l_mn", "l_km", "l_ng", "psi0", "sign", "angle_gnh", "min_length",
    "max_length",
}


def _hydraulics(data: dict, path: str) -> list[CylinderHydraulics]:
    """The hydraulic fields of a mechanism's cylinders (one, or a pair's two)."""
    sides = [(data, path)] if data.get("kind") != "swing_pair" else \
        [(data[side], f"{path}.{side}") for side in ("left", "right")]
    out = []
    for d, sub in sides:
        values = {k: d[k] for k in HYDRAULIC_KEYS if k in d}
        if values:
            out.append(_build(CylinderHydraulics, sub, name=d["name"], **values))
    return out


def _pump(extras: Mapping[str, Any], hydraulics: Mapping[str, CylinderHydraulics]
          ) -> Pump | None:
    """The robot's pump from ``pump_flow`` (L/min) and ``pump_cylinders`` (default: every
    cylinder with bore and rod); None without ``pump_flow``."""
    flow = extras.get("pump_flow")
    names = extras.get("pump_cylinders")
    if flow is None:
        if names is not None:
            raise CylinderError("pump_flow", "is required with pump_cylinders")
        return None
    if names is None:
        names = [n for n, h in hydraulics.items() if h.has_areas]
    elif not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        raise CylinderError("pump_cylinders", "must be a list of cylinder names")
    return Pump(flow, tuple(names))


def _joint_index(model: RobotModel, value: Any, path: str) -> int:
    names = [j.name for j in model.joints]
    if isinstance(value, str):
        if value not in names:
            raise CylinderError(path, f"unknown joint '{value}'; joints: {', '.join(names)}")
        index = names.index(value)
    elif isinstance(value, int) and not isinstance(value, bool):
        if not 0 <= value < model.dof:
            raise CylinderError(path, f"joint index {value} outside 0..{model.dof - 1}")
        index = value
    else:
        raise CylinderError(path, "must be a joint name or index")
    if not model.joints[index].revolute:
        raise CylinderError(path, f"joint '{names[index]}' is not revolute")
    return index


def _fields(data: Any, keys: set[str], path: str, extra: set[str]) -> dict[str, Any]:
    if not isinstance(data, dict):
        raise CylinderError(path, "must be a JSON object")
    unknown = set(data) - keys - extra
    if unknown:
        raise CylinderError(f"{path}.{sorted(unknown)[0]}", "unknown cylinder field")
    missing = keys - set(data)
    if missing:
        raise CylinderError(f"{path}.{sorted(missing)[0]}", "is required")
    return {k: data[k] for k in keys}


def _build(cls, path: str, **kwargs):
    try:
        return cls(**kwargs)
    except CylinderError as exc:
        raise CylinderError(f"{path}.{exc.field}", exc.message) from None


def _name(data: dict, path: str) -> str:
    name = data.get("name")
    if not isinstance(name, str) or not name:
        raise CylinderError(f"{path}.name", "must be a non-empty string")
    return name


def _mechanism(model: RobotModel, data: Any, path: str) -> Mechanism:
    if not isinstance(data, dict):
        raise CylinderError(path, "must be a JSON object")
    kind = data.get("kind")
    if kind not in _KINDS:
        raise CylinderError(f"{path}.kind", f"must be one of {sorted(_KINDS)}, got {kind!r}")
    name = _name(data, path)
    joint = _joint_index(model, data.get("joint"), f"{path}.joint")
    lim = {"lower": model.joints[joint].lower, "upper": model.joints[joint].upper}
    head = {"name", "kind", "joint", "note", *HYDRAULIC_KEYS}
    if kind == "triangle":
        values = _fields(data, _TRIANGLE_KEYS, path, head)
        return _build(TriangleCylinder, path, name=name, joint=joint, **values, **lim)
    if kind == "four_bar":
        values = _fields(data, _FOUR_BAR_KEYS, path, head)
        return _build(FourBarCylinder, path, name=name, joint=joint, **values, **lim)
    _fields(data, {"left", "right"}, path, {"name", "kind", "joint", "note"})
    sides = {}
    for side in ("left", "right"):
        sub = f"{path}.{side}"
        values = _fields(data[side], _TRIANGLE_KEYS, sub, {"name", "note", *HYDRAULIC_KEYS})
        sides[side] = _build(
            TriangleCylinder, sub, name=_name(data[side], sub), joint=joint, **values, **lim
        )
    return _build(SwingCylinderPair, path, name=name, joint=joint, **sides)


@lru_cache(maxsize=64)
def cylinder_set(model: RobotModel) -> CylinderSet:
    """``CylinderSet.from_model(model)``, built once per model (models are immutable)."""
    return CylinderSet.from_model(model)


# ---- why a configuration outside the joint limits cannot be driven --------------------


class LimitCause(StrEnum):
    """What a cylinder makes of a joint value outside its joint's limits."""

    #: The mechanism cannot take the joint value (a linkage that cannot close): no length.
    CANNOT_CLOSE = "cannot_close"
    #: The cylinder would be shorter than its retracted length.
    BELOW_STROKE = "below_stroke"
    #: The cylinder would be longer than its extended length.
    BEYOND_STROKE = "beyond_stroke"
    #: The length is within the stroke and gives back the joint value: only the joint stop
    #: is in the way.
    JOINT_STOP = "joint_stop"
    #: The length is within the stroke but gives another joint value: the joint value lies
    #: past the mechanism's dead point, where no length of the cylinder reaches.
    DEAD_POINT = "dead_point"


@dataclass(frozen=True)
class CylinderLimit:
    """One cylinder driving a joint that is outside its limits: why it cannot serve
    (``cause``), the length it would need (mm; NaN for ``CANNOT_CLOSE``) and its stroke."""

    name: str
    cause: LimitCause
    length: float
    min_length: float
    max_length: float


@dataclass(frozen=True)
class JointLimit:
    """One joint outside its limits: its index and name, the value asked (rad), its limits
    (rad) and the cylinders driving it (none for a motor-driven joint), in model order."""

    joint: int
    name: str
    value: float
    lower: float
    upper: float
    cylinders: tuple[CylinderLimit, ...]


#: Joint values this far (rad) outside a limit still count as inside.
LIMIT_TOL = 1e-9
#: A length inside the stroke gives back the joint value to this (rad), or the value lies
#: past a dead point.
ANGLE_TOL = 1e-6


def diagnose_limits(model: RobotModel, q, cylinders: CylinderSet | None = None
                    ) -> tuple[JointLimit, ...]:
    """Every joint of ``q (dof,)`` outside its limits, with what it asks of the cylinders
    driving it (``cylinders``, default ``cylinder_set(model)``); empty when ``q`` is within
    the limits. Pure: it reports, it never raises for a value the mechanism cannot take."""
    cyl = cylinder_set(model) if cylinders is None else cylinders
    q = cyl._rows(q, "q")
    if q.shape != (model.dof,):
        raise CylinderError("q", f"must have {model.dof} joint values, got {list(q.shape)}")
    lengths = cyl.lengths(q)
    out = []
    for i, j in enumerate(model.joints):
        if j.lower - LIMIT_TOL <= q[i] <= j.upper + LIMIT_TOL:
            continue
        found = []
        for mech in (m for m in cyl.mechanisms if m.joint == i):
            for k, name in enumerate(mech.names):
                L = float(lengths[name])
                lo, hi = mech.limits[k]
                if not math.isfinite(L):
                    cause = LimitCause.CANNOT_CLOSE
                elif L < lo:
                    cause = LimitCause.BELOW_STROKE
                elif L > hi:
                    cause = LimitCause.BEYOND_STROKE
                elif abs(float(mech.angle_of(L, k)) - q[i]) < ANGLE_TOL:
                    cause = LimitCause.JOINT_STOP
                else:  # another joint value (or none, NaN) has this length
                    cause = LimitCause.DEAD_POINT
                found.append(CylinderLimit(name, cause, L, lo, hi))
        out.append(JointLimit(i, j.name, float(q[i]), j.lower, j.upper, tuple(found)))
    return tuple(out)
