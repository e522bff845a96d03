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

Imported robots (``kinematics.urdf_import.ImportedRobot``) are written back with
``imported_to_urdf``: every link with its geometry, the chain joints, mimic joints that follow
chain joints, and fixed joints for the rest (see its docstring); ``imported_mesh_files`` gives
the mesh files it references and ``imported_to_archive`` a zip of both.

Example::

    >>> from kinematics.library import builtin_model
    >>> xml = to_urdf(builtin_model("glt_palletizer"))
    >>> xml.splitlines()[0]
    '<?xml version="1.0"?>'
"""

from __future__ import annotations

import io
import math
import xml.etree.ElementTree as ET
import zipfile
from typing import Any

import numpy as np

from .fk import fk_frames
from .model import RobotModel
from .transforms import invert_pose, rot_x, rot_z, trans

__all__ = ["to_urdf", "urdf_chain", "rotation_to_rpy", "MM_PER_M", "UNLIMITED",
           "imported_to_urdf", "imported_to_srdf", "imported_mesh_files",
           "imported_to_archive", "stl_bytes"]

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


# ---- imported robots ---------------------------------------------------------------------
def _unique_name(name: str, taken: set[str]) -> str:
    candidate, k = name, 2
    while candidate in taken:
        candidate, k = f"{name}_{k}", k + 1
    taken.add(candidate)
    return candidate


def _geometry_xml(parent: ET.Element, kind: str, geom: Any, mesh_dir: str,
                  material: str) -> None:
    element = ET.SubElement(parent, kind)
    _origin(element, geom.origin)
    holder = ET.SubElement(element, "geometry")
    if geom.kind == "box":
        ET.SubElement(holder, "box", size=_fmt(np.asarray(geom.size) / MM_PER_M))
    elif geom.kind == "cylinder":
        ET.SubElement(holder, "cylinder", radius=_fmt([geom.radius / MM_PER_M]),
                      length=_fmt([geom.length / MM_PER_M]))
    elif geom.kind == "sphere":
        ET.SubElement(holder, "sphere", radius=_fmt([geom.radius / MM_PER_M]))
    else:
        ET.SubElement(holder, "mesh", filename=f"{mesh_dir}/{geom.mesh}.stl")
    if kind == "visual" and geom.color is not None:
        colour = ET.SubElement(element, "material", name=material)
        ET.SubElement(colour, "color", rgba=_fmt(geom.color))


def imported_to_urdf(robot: Any, *, mesh_dir: str = "meshes",
                     unlimited: float = UNLIMITED) -> str:
    """URDF XML text of an imported robot (``kinematics.urdf_import.ImportedRobot``).

    Every link is written with its collision and visual geometry (meshes as
    ``<mesh_dir>/<key>.stl``, the files ``imported_mesh_files`` makes: binary STL in metres,
    so no ``scale``; colours as inline materials). The joints:

    * ``root_link`` is the root; ``base_link`` hangs from it on a fixed joint (the model's
      ``base``) when they differ;
    * chain joint i (its own name, revolute or prismatic, the model's limits and speeds)
      joins ``chain_links[i - 1]`` to ``chain_links[i]``;
    * every other link hangs on a fixed joint from the chain link of its frame (joints held
      at fixed values on import are written as fixed), named ``<link>_joint`` (or with a
      number when taken);
    * a link that follows chain joints through mimic joints gets those joints (their own
      names, continuous or prismatic, with ``<mimic>``), with ``<link>__mimic_<k>`` links
      between them when needed.

    Importing the text again (with the meshes, ``base_link`` and ``tip_link``) gives the
    same link poses and tool pose for every ``q`` up to round-off (~1e-12 mm).
    ``ValueError`` if a chain link's origin is off its joint's axis (import never makes such
    a robot).
    """
    model = robot.model
    links = {link.name: link for link in robot.links}
    chain = list(robot.chain_links)
    F0 = fk_frames(model, np.zeros(model.dof))
    T0 = {name: F0[chain.index(name)] @ links[name].offset for name in chain}
    names = set(links) | {j.name for j in model.joints} | {
        s.joint for link in robot.links for s in link.mimic}
    joints: list[tuple[str, str, str, str, np.ndarray, dict[str, Any]]] = []
    # (name, type, parent, child, origin, extra)

    if robot.base_link != robot.root_link:
        origin = invert_pose(links[robot.root_link].offset) @ links[robot.base_link].offset
        joints.append((_unique_name(f"{robot.base_link}_joint", names), "fixed",
                       robot.root_link, robot.base_link, origin, {}))
    for i, joint in enumerate(model.joints, start=1):
        parent, child = chain[i - 1], chain[i]
        origin = invert_pose(T0[parent]) @ T0[child]
        axis_world = model.base[:3, :3] @ np.asarray(joint.axis)
        axis = T0[child][:3, :3].T @ axis_world
        if joint.revolute:
            point = model.base[:3, :3] @ np.asarray(joint.point) + model.base[:3, 3]
            gap = np.cross(T0[child][:3, 3] - point, axis_world)
            if np.linalg.norm(gap) > 1e-6 * max(1.0, float(np.linalg.norm(point))):
                raise ValueError(f"chain link '{child}' is off the axis of joint "
                                 f"'{joint.name}'")
        joints.append((joint.name, joint.type, parent, child, origin, {"axis": axis,
                                                                       "joint": joint}))
    # A link whose offset is the identity after its mimic steps is the frame those steps
    # reach; other links with the same steps hang from it.
    owners = {(link.frame, tuple(s.joint for s in link.mimic)): link.name
              for link in robot.links
              if link.mimic and np.array_equal(link.offset, np.eye(4))}
    attached: set[str] = set()
    for link in robot.links:
        if link.name in chain or link.name == robot.root_link:
            continue
        parent = chain[link.frame]
        before = invert_pose(links[parent].offset)  # T_parent_frame
        for k, step in enumerate(link.mimic):
            prefix = (link.frame, tuple(s.joint for s in link.mimic[:k + 1]))
            owner = owners.get(prefix)
            if owner is None:
                owner = owners[prefix] = _unique_name(f"{link.name}__mimic_{k}", names)
            if owner not in attached:
                joints.append((step.joint, step.kind, parent, owner, before @ step.origin,
                               {"step": step}))
                attached.add(owner)
            parent, before = owner, np.eye(4)
        if parent != link.name:
            joints.append((_unique_name(f"{link.name}_joint", names), "fixed", parent,
                           link.name, before @ link.offset, {}))

    root = ET.Element("robot", name=model.id)
    root.append(ET.Comment(f" kinoplan imported robot '{model.id}': chain {robot.base_link} "
                           f"-> {robot.tip_link}; lengths in m, angles in rad "))
    extra_links = sorted({j[3] for j in joints} - set(links))
    for name in [*links, *extra_links]:
        element = ET.SubElement(root, "link", name=name)
        link = links.get(name)
        if link is None:
            continue
        for kind, shapes in (("visual", link.visual), ("collision", link.collision)):
            for k, geom in enumerate(shapes):
                _geometry_xml(element, kind, geom, mesh_dir, f"{name}_{kind}_{k}")
    master_names = [j.name for j in model.joints]
    for name, kind, parent, child, origin, extra in joints:
        if "step" in extra:
            step = extra["step"]
            master = model.joints[step.master]
            child_scale = MM_PER_M if step.kind == "prismatic" else 1.0
            master_scale = 1.0 if master.revolute else 1.0 / MM_PER_M
            element = _joint(root, name, "continuous" if step.kind == "revolute" else
                             "prismatic", parent, child)
            _origin(element, origin)
            ET.SubElement(element, "axis", xyz=_fmt(step.axis))
            if step.kind == "prismatic":
                ET.SubElement(element, "limit", lower=_fmt([-unlimited]),
                              upper=_fmt([unlimited]), effort=_fmt([unlimited]),
                              velocity=_fmt([unlimited]))
            ET.SubElement(element, "mimic", joint=master_names[step.master],
                          multiplier=_fmt([step.gain / (master_scale * child_scale)]),
                          offset=_fmt([step.bias / child_scale]))
            continue
        element = _joint(root, name, kind, parent, child)
        _origin(element, origin)
        if "joint" in extra:
            j = extra["joint"]
            ET.SubElement(element, "axis", xyz=_fmt(extra["axis"]))
            scale = 1.0 if j.revolute else MM_PER_M
            velocity = unlimited if j.velocity is None else j.velocity / scale
            ET.SubElement(element, "limit", lower=_fmt([j.lower / scale]),
                          upper=_fmt([j.upper / scale]), effort=_fmt([unlimited]),
                          velocity=_fmt([velocity]))
    ET.indent(root)
    return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def stl_bytes(vertices_mm: np.ndarray, faces: np.ndarray) -> bytes:
    """Binary STL of a triangle mesh, in metres (float32, as the format stores): vertices
    ``(V, 3)`` mm, faces ``(F, 3)`` indices; facet normals from the vertex order."""
    triangles = np.asarray(vertices_mm, dtype=float)[np.asarray(faces)] / MM_PER_M
    normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = np.divide(normals, length, out=np.zeros_like(normals), where=length > 0)
    record = np.dtype([("normal", "<f4", 3), ("vertices", "<f4", (3, 3)), ("attr", "<u2")])
    body = np.zeros(len(triangles), dtype=record)
    body["normal"] = normals
    body["vertices"] = triangles
    header = b"kinoplan binary STL, metres".ljust(80, b" ")
    return header + np.uint32(len(triangles)).tobytes() + body.tobytes()


def imported_mesh_files(robot: Any, *, mesh_dir: str = "meshes") -> dict[str, bytes]:
    """The mesh files ``imported_to_urdf`` references: ``"<mesh_dir>/<key>.stl"`` -> binary
    STL in metres (float32: about 0.1 µm of round-off at 1 m)."""
    return {f"{mesh_dir}/{key}.stl": stl_bytes(mesh.vertices, mesh.faces)
            for key, mesh in sorted(robot.meshes.items())}


def imported_to_srdf(robot: Any) -> str:
    """An SRDF keeping what URDF cannot say: the planning chain (group ``<id>``: base and
    tip link) and the disabled collision pairs."""
    root = ET.Element("robot", name=robot.model.id)
    group = ET.SubElement(root, "group", name=robot.model.id)
    ET.SubElement(group, "chain", base_link=robot.base_link, tip_link=robot.tip_link)
    for pair in sorted(sorted(p) for p in robot.disabled_pairs):
        first, second = (pair[0], pair[0]) if len(pair) == 1 else pair
        ET.SubElement(root, "disable_collisions", link1=first, link2=second, reason="Kept")
    ET.indent(root)
    return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def imported_to_archive(robot: Any) -> bytes:
    """A zip with ``<id>.urdf`` (``imported_to_urdf``), ``<id>.srdf`` (``imported_to_srdf``)
    and ``meshes/<key>.stl``: an upload that ``import_robot`` reads back to the same robot."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr(f"{robot.model.id}.urdf", imported_to_urdf(robot))
        zf.writestr(f"{robot.model.id}.srdf", imported_to_srdf(robot))
        for name, data in imported_mesh_files(robot).items():
            zf.writestr(name, data)
    return buffer.getvalue()
