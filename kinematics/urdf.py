"""Export a ``RobotModel`` as URDF (Unified Robot Description Format) XML.

Units: URDF lengths are metres, so every length of the model (mm) is divided by 1000: joint
origins, prismatic limits, prismatic offsets and prismatic speed limits (mm/s -> m/s). Angles
stay in rad. A URDF joint value equals our joint value ``q`` (rad, or mm / 1000 for a prismatic
joint): offsets are folded into the constant joint origins.

The kinematic tree (no geometry, no inertia: the model carries none)::

    base_link --[base: fixed, origin = model.base]--> link_0
    link_{i-1} --[joint i's name: revolute/prismatic]--> link_i      (i = 1..dof)
    link_dof --[tool: fixed]--> tool

so ``base_link`` is the world frame and the pose of link ``tool`` in it is ``T_world_tool``
of ``kinematics.fk.fk`` (metres instead of mm).
Each joint's ``origin`` is the constant part of its transform, its ``axis`` the motion axis:

* modified D-H: ``origin = RotX(alpha) TransX(a) RotZ(offset) TransZ(d)`` (revolute) or
  ``RotX(alpha) TransX(a) RotZ(theta) TransZ(offset)`` (prismatic), axis z. ``link_i`` is
  D-H frame i (``fk_frames`` entry i).
* standard D-H: the trailing ``TransX(a) RotX(alpha)`` of joint i comes after its motion, so it
  opens the origin of joint i+1 (or of the ``tool`` joint); ``link_i`` is frame i without
  that trailing part.
* product of exponentials: joint i's origin sits at its axis point (prismatic joints: the base
  origin) relative to the previous one, ``Trans(p_i - p_{i-1})`` times its offset motion, with
  the screw axis as ``axis``; the ``tool`` joint carries ``Trans(-p_dof) home tool``.
  ``link_i`` is ``fk_frames`` entry i (the last one before ``home`` and ``tool``).

The fixed joints are named ``base`` and ``tool`` unless a model joint already has that name,
then ``base_joint`` / ``tool_joint`` (then with a number). URDF requires ``effort`` and
``velocity`` on every moving joint's ``<limit>``; the model has no effort limits and may have
no speed limit, so both default to a large placeholder (``unlimited``, 1e6).

Example::

    >>> from kinematics.library import builtin_model
    >>> xml = to_urdf(builtin_model("glt_palletizer"))
    >>> xml.splitlines()[0]
    '<?xml version="1.0"?>'
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np

from .model import RobotModel
from .transforms import rot_x, rot_z, trans

__all__ = ["to_urdf", "urdf_chain", "rotation_to_rpy", "MM_PER_M", "UNLIMITED"]

MM_PER_M = 1000.0
#: Placeholder for a required URDF limit the model does not give (rad/s, m/s, N, N·m).
UNLIMITED = 1e6
# Round-off such as cos(pi/2) = 6e-17 is written as 0 (1e-14 m and rad are far below any
# tolerance) so the XML stays readable.
_SNAP = 1e-14


def rotation_to_rpy(R: np.ndarray) -> np.ndarray:
    """URDF roll-pitch-yaw of a rotation ``(3, 3)`` (or pose ``(4, 4)``) -> ``(3,)`` rad.

    ``R = RotZ(yaw) RotY(pitch) RotX(roll)``. Stays accurate to round-off near pitch = ±pi/2,
    where roll and yaw are ill-determined one by one: only the well-conditioned combination
    ``roll ∓ yaw`` is taken from the large matrix entries, so the rotation rebuilt from the
    angles matches ``R`` within a few ulp everywhere.

    >>> from kinematics.transforms import rot_y
    >>> rotation_to_rpy(rot_z(0.5) @ rot_y(0.2) @ rot_x(0.3)).round(12).tolist()
    [0.3, 0.2, 0.5]
    """
    R = np.asarray(R, dtype=float)[:3, :3]
    pitch = math.atan2(-R[2, 0], math.hypot(R[0, 0], R[1, 0]))
    yaw = math.atan2(R[1, 0], R[0, 0])
    if R[2, 0] <= 0.0:  # sin(pitch) >= 0: (1 + sin p) scales sin and cos of (roll - yaw)
        roll = yaw + math.atan2(R[0, 1] - R[1, 2], R[1, 1] + R[0, 2])
    else:  # (1 - sin p) scales sin and cos of (roll + yaw)
        roll = math.atan2(-(R[0, 1] + R[1, 2]), R[1, 1] - R[0, 2]) - yaw
    roll = math.remainder(roll, 2.0 * math.pi)
    return np.array([roll, pitch, yaw])


def _axis_rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation by ``angle`` (rad) about the unit ``axis (3,)`` through the origin -> (4, 4)."""
    K = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    T = np.eye(4)
    T[:3, :3] += math.sin(angle) * K + (1.0 - math.cos(angle)) * (K @ K)
    return T


def urdf_chain(model: RobotModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The constant transforms of the URDF chain, in mm.

    Returns ``(origins (dof, 4, 4), axes (dof, 3), T_last_tool (4, 4))``: joint i's origin in
    the frame of ``link_{i-1}``, its unit motion axis in its own frame, and the ``tool`` fixed
    joint's origin in ``link_dof``. The tool pose is
    ``base @ prod_i (origins[i] @ Motion(axes[i], q_i)) @ T_last_tool`` for every ``q``.
    """
    origins = []
    axes = []
    if model.convention == "poe":
        p_prev = np.zeros(3)
        for j in model.joints:
            axis = np.asarray(j.axis, dtype=float)
            p = np.asarray(j.point, dtype=float) if j.revolute else np.zeros(3)
            motion = _axis_rotation(axis, j.offset) if j.revolute else trans(*(j.offset * axis))
            origins.append(trans(*(p - p_prev)) @ motion)
            axes.append(axis)
            p_prev = p
        T_last_tool = trans(*(-p_prev)) @ model.home @ model.tool
    else:
        mdh = model.convention == "mdh"
        pending = np.eye(4)  # SDH: the previous joint's TransX(a) RotX(alpha)
        for j in model.joints:
            if j.revolute:
                moving = rot_z(j.offset) @ trans(z=j.d)
            else:
                moving = rot_z(j.theta) @ trans(z=j.offset)
            if mdh:
                origins.append(rot_x(j.alpha) @ trans(j.a) @ moving)
            else:
                origins.append(pending @ moving)
                pending = trans(j.a) @ rot_x(j.alpha)
            axes.append(np.array([0.0, 0.0, 1.0]))
        T_last_tool = model.tool if mdh else pending @ model.tool
    return np.stack(origins), np.stack(axes), np.asarray(T_last_tool, dtype=float)


def _fmt(values) -> str:
    """Space-separated floats written to full precision (``repr`` round-trips exactly)."""
    out = []
    for v in values:
        v = float(v)
        out.append(repr(0.0 if abs(v) < _SNAP else v))
    return " ".join(out)


def _origin(parent: ET.Element, T_mm: np.ndarray) -> None:
    ET.SubElement(
        parent, "origin",
        xyz=_fmt(np.asarray(T_mm)[:3, 3] / MM_PER_M), rpy=_fmt(rotation_to_rpy(T_mm)),
    )


def _unique(name: str, taken: set[str]) -> str:
    if name not in taken:
        return name
    candidate, k = f"{name}_joint", 2
    while candidate in taken:
        candidate, k = f"{name}_joint_{k}", k + 1
    return candidate


def _joint(robot: ET.Element, name: str, kind: str, parent: str, child: str) -> ET.Element:
    joint = ET.SubElement(robot, "joint", name=name, type=kind)
    ET.SubElement(joint, "parent", link=parent)
    ET.SubElement(joint, "child", link=child)
    return joint


def to_urdf(model: RobotModel, *, unlimited: float = UNLIMITED) -> str:
    """URDF XML text of ``model`` (metres, rad; see the module docstring for the frames).

    ``unlimited`` is written as the ``velocity`` of joints without a speed limit and as every
    joint's ``effort`` (both are required by URDF; the model has no efforts).
    """
    origins, axes, T_last_tool = urdf_chain(model)
    joint_names = {j.name for j in model.joints}
    robot = ET.Element("robot", name=model.id)
    robot.append(ET.Comment(
        f" kinoplan model '{model.id}' ({model.convention}); lengths in m, angles in rad "
    ))
    links = ["base_link", *(f"link_{i}" for i in range(model.dof + 1)), "tool"]
    for link in links:
        ET.SubElement(robot, "link", name=link)

    base = _joint(robot, _unique("base", joint_names), "fixed", "base_link", "link_0")
    _origin(base, model.base)
    for i, j in enumerate(model.joints):
        joint = _joint(robot, j.name, j.type, f"link_{i}", f"link_{i + 1}")
        _origin(joint, origins[i])
        ET.SubElement(joint, "axis", xyz=_fmt(axes[i]))
        scale = 1.0 if j.revolute else MM_PER_M
        velocity = unlimited if j.velocity is None else j.velocity / scale
        ET.SubElement(
            joint, "limit", lower=_fmt([j.lower / scale]), upper=_fmt([j.upper / scale]),
            effort=_fmt([unlimited]), velocity=_fmt([velocity]),
        )
    tool = _joint(robot, _unique("tool", joint_names), "fixed", f"link_{model.dof}", "tool")
    _origin(tool, T_last_tool)

    ET.indent(robot)
    # No encoding in the declaration: the text is a str, and lxml (used by most URDF
    # readers) rejects str input that declares one. XML's default encoding is UTF-8.
    return '<?xml version="1.0"?>\n' + ET.tostring(robot, encoding="unicode") + "\n"
