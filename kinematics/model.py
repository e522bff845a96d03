"""Serial-chain robot models: modified D-H, standard D-H or product of exponentials.

A model is a frozen value, built once from its JSON description (``RobotModel.from_dict``)
and validated there; everything downstream trusts it.

Per joint (``Joint``):

* ``convention="mdh"`` (Craig): ``a``, ``alpha`` are a_{i-1}, alpha_{i-1} and
  ``T_{i-1,i} = RotX(alpha) TransX(a) RotZ(theta) TransZ(d)``.
* ``convention="sdh"``: ``T_{i-1,i} = RotZ(theta) TransZ(d) TransX(a) RotX(alpha)``.
* Revolute: ``theta = q + offset`` with ``d`` constant; prismatic: ``d = q + offset`` with
  ``theta`` constant (the Robotics Toolbox's meaning of offset).
* ``convention="poe"``: space-frame screws. ``axis`` (unit) and, for a revolute joint, a
  ``point`` on the axis, both in the base frame at q = 0; the model's ``home`` is the tool
  flange pose at q = 0. ``offset`` is added to q as for D-H joints.

The tool pose is ``T_world_tool = base @ prod_i T_{i-1,i}(q_i) @ tool`` (``home`` inserted
before ``tool`` for product-of-exponentials models): ``base`` is ``T_world_base`` and ``tool``
is ``T_flange_tool`` (frames, units and layouts: docs/conventions.md).
"""

from __future__ import annotations

import copy
import math
import re
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, Literal

import numpy as np

from .errors import FieldError, KinematicsError, loc_from_path
from .transforms import rigidity_error

__all__ = ["Joint", "RobotModel", "ModelError", "MAX_DOF", "MAX_LENGTH_MM", "MAX_ANGLE_RAD",
           "MAX_JOINT_SPEED", "MAX_NAME_LENGTH", "ID_PATTERN"]

MAX_DOF = 32
#: Largest length (mm) in a model: link lengths and offsets, prismatic limits, base and tool
#: translations, screw points. 10 km is beyond any machine and keeps sums of squares finite.
MAX_LENGTH_MM = 1e7
#: Largest |angle| (rad) in a model: twists, joint angles, revolute limits and offsets.
MAX_ANGLE_RAD = 8 * math.pi
#: Largest joint speed limit (rad/s or mm/s).
MAX_JOINT_SPEED = 1e6
#: Longest robot or joint name; names are printable text (they end up in URDF and the viewer).
MAX_NAME_LENGTH = 200
#: Robot ids: ASCII letters, digits, '_' and '-', 1 to 64 characters.
ID_PATTERN = r"^[A-Za-z0-9_-]{1,64}$"
Convention = Literal["mdh", "sdh", "poe"]
JointType = Literal["revolute", "prismatic"]

_JOINT_KEYS = {
    "name", "type", "a", "alpha", "d", "theta", "offset", "lower", "upper", "velocity",
    "axis", "point",
}
_MODEL_KEYS = {"id", "name", "convention", "joints", "base", "tool", "home"}


class ModelError(FieldError, KinematicsError):
    """A robot model description is invalid; ``field`` names the JSON field at fault
    (``joints[2].lower``), ``loc`` the same as parts (``("joints", 2, "lower")``)."""

    def __init__(self, field_path: str, message: str):
        super().__init__(loc_from_path(field_path), message)
        self.field = field_path

    def __str__(self) -> str:
        return f"{self.field}: {self.message}"


@dataclass(frozen=True)
class Joint:
    """One joint of a serial chain. Lengths in mm, angles in rad."""

    name: str
    type: JointType
    lower: float
    upper: float
    a: float = 0.0
    alpha: float = 0.0
    d: float = 0.0
    theta: float = 0.0
    offset: float = 0.0
    velocity: float | None = None
    axis: tuple[float, float, float] | None = None
    point: tuple[float, float, float] | None = None

    @property
    def revolute(self) -> bool:
        return self.type == "revolute"

    def to_dict(self, convention: str) -> dict[str, Any]:
        out: dict[str, Any] = {"name": self.name, "type": self.type}
        if convention == "poe":
            out["axis"] = list(self.axis or (0.0, 0.0, 1.0))
            if self.revolute:
                out["point"] = list(self.point or (0.0, 0.0, 0.0))
        else:
            out["a"] = self.a
            out["alpha"] = self.alpha
            if self.revolute:
                out["d"] = self.d
            else:
                out["theta"] = self.theta
        out["offset"] = self.offset
        out["lower"] = self.lower
        out["upper"] = self.upper
        if self.velocity is not None:
            out["velocity"] = self.velocity
        return out


@dataclass(frozen=True, eq=False)
class RobotModel:
    """A serial robot. ``base``, ``tool`` and ``home`` are ``(4, 4)`` poses (read-only)."""

    id: str
    name: str
    convention: Convention
    joints: tuple[Joint, ...]
    base: np.ndarray
    tool: np.ndarray
    home: np.ndarray | None = None
    extras: dict[str, Any] = field(default_factory=dict)

    # ---- derived values (computed once on first use; the dataclass is immutable) ---------
    @property
    def dof(self) -> int:
        return len(self.joints)

    @cached_property
    def lower(self) -> np.ndarray:
        """Lower joint limits ``(dof,)``: rad for revolute, mm for prismatic joints."""
        return _frozen([j.lower for j in self.joints])

    @cached_property
    def upper(self) -> np.ndarray:
        """Upper joint limits ``(dof,)``."""
        return _frozen([j.upper for j in self.joints])

    @cached_property
    def revolute(self) -> np.ndarray:
        """Boolean mask ``(dof,)`` of revolute joints."""
        return _frozen([j.revolute for j in self.joints])

    @cached_property
    def velocity_limits(self) -> np.ndarray:
        """Joint speed limits ``(dof,)`` (rad/s or mm/s); ``inf`` where none is given."""
        return _frozen([math.inf if j.velocity is None else j.velocity for j in self.joints])

    @cached_property
    def length_scale(self) -> float:
        """A characteristic length (mm) of the arm: the sum of its constant link lengths.

        Used to make position and orientation errors comparable (``e_pos / length_scale``)
        and to bound the reach. Never below 1 mm.
        """
        total = 0.0
        for j in self.joints:
            if self.convention == "poe":
                continue
            total += abs(j.a) + (abs(j.d) if j.revolute else max(abs(j.lower), abs(j.upper)))
        if self.convention == "poe":
            pts = [np.zeros(3)] + [np.asarray(j.point) for j in self.joints if j.point]
            pts.append(np.asarray(self.home)[:3, 3])
            total = float(sum(np.linalg.norm(b - a) for a, b in zip(pts[:-1], pts[1:])))
            total += sum(max(abs(j.lower), abs(j.upper)) for j in self.joints if not j.revolute)
        total += float(np.linalg.norm(self.tool[:3, 3]))
        return max(total, 1.0)

    def mid_configuration(self) -> np.ndarray:
        """Centre of the joint limits ``(dof,)``."""
        return 0.5 * (self.lower + self.upper)

    def within_limits(self, q: np.ndarray, tol: float = 1e-9) -> np.ndarray:
        """``q: (*, dof) -> (*,)`` bool: every joint inside its limits (within ``tol``)."""
        q = np.asarray(q, dtype=float)
        return np.all((q >= self.lower - tol) & (q <= self.upper + tol), axis=-1)

    def limit_violations(self, q: np.ndarray, tol: float = 1e-9) -> list[str]:
        """Names of the joints of one configuration ``(dof,)`` outside their limits."""
        q = np.asarray(q, dtype=float)
        return [
            j.name
            for j, v in zip(self.joints, q)
            if not (j.lower - tol <= v <= j.upper + tol)
        ]

    # ---- JSON ---------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "id": self.id,
            "name": self.name,
            "convention": self.convention,
            "joints": [j.to_dict(self.convention) for j in self.joints],
            "base": self.base.tolist(),
            "tool": self.tool.tolist(),
        }
        if self.home is not None:
            out["home"] = self.home.tolist()
        # A copy: the caller may edit the answer (built-in models are shared and cached).
        out.update(copy.deepcopy(self.extras))
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> RobotModel:
        """Build and validate a model; raises ``ModelError`` naming the field at fault."""
        if not isinstance(data, dict):
            raise ModelError("model", "must be a JSON object")
        model_id = data.get("id")
        if not isinstance(model_id, str) or not model_id:
            raise ModelError("id", "must be a non-empty string")
        if re.fullmatch(ID_PATTERN, model_id) is None:
            raise ModelError("id", "use 1 to 64 ASCII letters, digits, '_' or '-'")
        name = _name(data.get("name", model_id), "name")
        convention = data.get("convention", "mdh")
        if convention not in ("mdh", "sdh", "poe"):
            raise ModelError("convention", f"must be 'mdh', 'sdh' or 'poe', got {convention!r}")
        joints_data = data.get("joints")
        if not isinstance(joints_data, list) or not joints_data:
            raise ModelError("joints", "must be a non-empty list")
        if len(joints_data) > MAX_DOF:
            raise ModelError("joints", f"at most {MAX_DOF} joints, got {len(joints_data)}")
        joints = tuple(
            _joint_from_dict(j, f"joints[{i}]", convention, i) for i, j in enumerate(joints_data)
        )
        names = [j.name for j in joints]
        if len(set(names)) != len(names):
            raise ModelError("joints", "joint names must be unique")
        base = pose_field(data.get("base"), "base")
        tool = pose_field(data.get("tool"), "tool")
        home = None
        if convention == "poe":
            if data.get("home") is None:
                raise ModelError("home", "a product-of-exponentials model needs 'home'")
            home = pose_field(data["home"], "home")
        extras = {k: v for k, v in data.items() if k not in _MODEL_KEYS}
        return cls(
            id=model_id, name=name, convention=convention, joints=joints,
            base=base, tool=tool, home=home, extras=extras,
        )


def _frozen(values: list) -> np.ndarray:
    arr = np.array(values)
    arr.setflags(write=False)
    return arr


def _name(value: Any, path: str) -> str:
    """A non-empty printable name (no control characters) of at most MAX_NAME_LENGTH."""
    if not isinstance(value, str) or not value:
        raise ModelError(path, "must be a non-empty string")
    if len(value) > MAX_NAME_LENGTH:
        raise ModelError(path, f"at most {MAX_NAME_LENGTH} characters, got {len(value)}")
    if not value.isprintable():
        raise ModelError(path, "must be printable text (no control characters)")
    return value


def _number(value: Any, path: str, default: float | None = None, *,
            bound: float = MAX_LENGTH_MM, unit: str = "mm") -> float:
    """A finite number within ``±bound`` (``default`` when missing, if there is one)."""
    if value is None:
        if default is None:
            raise ModelError(path, "is required")
        return default
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ModelError(path, f"must be a number, got {value!r}")
    if not math.isfinite(value):
        raise ModelError(path, "must be finite")
    if abs(value) > bound:
        raise ModelError(path, f"must be within ±{bound:g} {unit}, got {value:g}")
    return float(value)


def _angle(value: Any, path: str, default: float | None = None) -> float:
    return _number(value, path, default, bound=MAX_ANGLE_RAD, unit="rad")


def _vector3(value: Any, path: str, bound: float = MAX_LENGTH_MM) -> tuple[float, float, float]:
    if not isinstance(value, (list, tuple)) or len(value) != 3:
        raise ModelError(path, "must be a list of 3 numbers")
    vals = tuple(_number(v, f"{path}[{k}]", bound=bound) for k, v in enumerate(value))
    return vals  # type: ignore[return-value]


def pose_field(value: Any, path: str) -> np.ndarray:
    """A 4x4 rigid pose from JSON (identity if None), read-only; ModelError naming ``path``."""
    if value is None:
        T = np.eye(4)
    else:
        try:
            T = np.array(value, dtype=float)
        except (TypeError, ValueError) as exc:
            raise ModelError(path, "must be a 4x4 list of numbers") from exc
        if T.shape != (4, 4):
            raise ModelError(path, f"must be 4x4, got shape {list(T.shape)}")
        if not np.all(np.isfinite(T)):
            raise ModelError(path, "must be finite")
        if np.abs(T[:3, 3]).max() > MAX_LENGTH_MM:
            raise ModelError(path, f"translation must be within ±{MAX_LENGTH_MM:g} mm")
        if np.abs(T[:3, :3]).max() > 1.0 + 1e-6 or np.abs(T[3] - [0, 0, 0, 1]).max() > 1e-9:
            raise ModelError(path, "is not a rigid transform (rotation entries beyond ±1, or "
                             "last row not [0, 0, 0, 1])")
        if rigidity_error(T) > 1e-6:
            raise ModelError(path, "is not a rigid transform (rotation not orthonormal)")
    T.setflags(write=False)
    return T


def _joint_from_dict(data: Any, path: str, convention: str, index: int) -> Joint:
    if not isinstance(data, dict):
        raise ModelError(path, "must be a JSON object")
    unknown = set(data) - _JOINT_KEYS
    if unknown:
        raise ModelError(f"{path}.{sorted(unknown)[0]}", "unknown joint field")
    name = _name(data.get("name", f"j{index + 1}"), f"{path}.name")
    jtype = data.get("type", "revolute")
    if jtype not in ("revolute", "prismatic"):
        raise ModelError(f"{path}.type", f"must be 'revolute' or 'prismatic', got {jtype!r}")
    joint_value = _angle if jtype == "revolute" else _number
    lower = joint_value(data.get("lower"), f"{path}.lower")
    upper = joint_value(data.get("upper"), f"{path}.upper")
    if not lower < upper:
        raise ModelError(f"{path}.lower", f"must be below upper ({lower} >= {upper})")
    if jtype == "revolute" and upper - lower > 8 * math.pi:
        raise ModelError(f"{path}.upper", "a revolute range wider than four turns is not physical")
    velocity = data.get("velocity")
    if velocity is not None:
        velocity = _number(velocity, f"{path}.velocity", bound=MAX_JOINT_SPEED,
                           unit="rad/s or mm/s")
        if velocity <= 0:
            raise ModelError(f"{path}.velocity", "must be positive")
    kwargs: dict[str, Any] = dict(
        name=name, type=jtype, lower=lower, upper=upper, velocity=velocity,
        offset=joint_value(data.get("offset"), f"{path}.offset", 0.0),
    )
    if convention == "poe":
        axis = np.array(_vector3(data.get("axis"), f"{path}.axis"))
        norm = float(np.linalg.norm(axis))
        if abs(norm - 1.0) > 1e-6:
            raise ModelError(f"{path}.axis", f"must be a unit vector (norm {norm:.6g})")
        kwargs["axis"] = tuple(float(v) for v in axis / norm)
        if jtype == "revolute":
            kwargs["point"] = _vector3(data.get("point"), f"{path}.point")
    else:
        kwargs["a"] = _number(data.get("a"), f"{path}.a", 0.0)
        kwargs["alpha"] = _angle(data.get("alpha"), f"{path}.alpha", 0.0)
        kwargs["d"] = _number(data.get("d"), f"{path}.d", 0.0)
        kwargs["theta"] = _angle(data.get("theta"), f"{path}.theta", 0.0)
    return Joint(**kwargs)
