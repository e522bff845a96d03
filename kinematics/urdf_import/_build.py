"""``import_robot``: an upload in, an ``ImportedRobot`` out."""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from typing import Any

import numpy as np

from ..errors import FieldError, Loc
from ..fk import fk_frames
from ..model import (
    ID_PATTERN,
    MAX_ANGLE_RAD,
    MAX_DOF,
    MAX_JOINT_SPEED,
    MAX_LENGTH_MM,
    MAX_NAME_LENGTH,
    ModelError,
    RobotModel,
)
from ..transforms import invert_pose
from ._archive import SRDF_SUFFIXES, URDF_SUFFIXES, Upload, open_upload
from ._limits import DEFAULT_LIMITS, ImportLimits
from ._meshes import load_mesh, resolve_mesh
from ._parse import (
    MM_PER_M,
    MOVING_TYPES,
    Srdf,
    UrdfGeometry,
    UrdfJoint,
    UrdfRobot,
    parse_srdf,
    parse_urdf,
    unit_vector,
)
from ._robot import Geometry, ImportedRobot, Link, MeshData, MimicStep, axis_motion
from ._tree import Tree, chain_ends, known_link, listing, movable
from ._xml import parse_xml

__all__ = ["import_robot", "CONTINUOUS_LIMIT"]

#: Limits given to a continuous joint on the chain: ±2π rad (two turns of travel).
CONTINUOUS_LIMIT = 2.0 * math.pi
#: URDF velocity limits at or above this (rad/s or m/s) mean "no limit" (our URDF export
#: writes 1e6 for a joint without one).
_NO_SPEED_LIMIT = 1e6


# ---- the upload's files ------------------------------------------------------------------
def _choose_urdf(upload: Upload, urdf: str | None) -> str:
    candidates = upload.with_suffix(URDF_SUFFIXES)
    if upload.kind == "urdf":
        name = candidates[0]
        if urdf is not None and urdf.replace("\\", "/").rsplit("/", 1)[-1] != name:
            raise FieldError(("urdf",), f"names a file in an archive; the upload is the URDF "
                                        f"'{name}' itself")
        return name
    if not candidates:
        xacro = [n for n in upload.names if n.lower().endswith(".xacro")]
        hint = (" (found xacro files: expand them to URDF with xacro first)" if xacro else "")
        raise FieldError(("file",), f"the archive holds no .urdf file{hint}")
    if urdf is not None:
        if not isinstance(urdf, str):
            raise FieldError(("urdf",), "must be a path inside the archive")
        wanted = urdf.replace("\\", "/").strip("/")
        exact = [n for n in candidates if n == wanted]
        by_name = [n for n in candidates if n.rsplit("/", 1)[-1] == wanted]
        for hits in (exact, by_name):
            if len(hits) == 1:
                return hits[0]
        raise FieldError(("urdf",), f"no single URDF '{urdf}' in the archive; candidates: "
                                    f"{listing(candidates)}")
    if len(candidates) > 1:
        raise FieldError(("urdf",), f"the archive holds {len(candidates)} URDF files; name "
                                    f"one with urdf; candidates: {listing(candidates)}")
    return candidates[0]


def _read_srdf(srdf: bytes | None, upload: Upload, urdf_name: str,
               limits: ImportLimits) -> Srdf | None:
    """The SRDF given; else the archive's .srdf named like the URDF (``robot.srdf`` for
    ``robot.urdf``, in any folder); else its only .srdf when it holds only one URDF; else
    none."""
    if srdf is not None:
        if not isinstance(srdf, bytes | bytearray | memoryview):
            raise FieldError(("srdf",), "must be the bytes of an SRDF file")
        loc: Loc = ("srdf",)
        data, what = bytes(srdf), "the SRDF"
    else:
        found = upload.with_suffix(SRDF_SUFFIXES)
        stem = urdf_name.rsplit("/", 1)[-1].rsplit(".", 1)[0]
        named = [n for n in found if n.rsplit("/", 1)[-1].rsplit(".", 1)[0] == stem]
        if len(named) == 1:
            found = named
        elif len(upload.with_suffix(URDF_SUFFIXES)) > 1:
            return None  # one SRDF among several URDFs: whose is it?
        if len(found) != 1:
            return None
        loc, data, what = ("file", found[0]), upload.read(found[0]), f"the SRDF '{found[0]}'"
    root = parse_xml(data, loc, what=what, max_bytes=limits.max_xml_bytes,
                     max_depth=limits.max_xml_depth, max_elements=limits.max_xml_elements)
    return parse_srdf(root, loc)


# ---- joint values off the chain ----------------------------------------------------------
def _held_values(robot: UrdfRobot, chain: set[str],
                 fixed_joints: Mapping[str, Any] | None) -> dict[str, float]:
    """Values (URDF units) of the movable joints off the chain set by ``fixed_joints``
    (rad, or mm for prismatic joints)."""
    if fixed_joints is None:
        return {}
    if not isinstance(fixed_joints, Mapping):
        raise FieldError(("fixed_joints",), "must be an object: joint name -> value")
    off_chain = [n for n, j in robot.joints.items() if movable(j) and n not in chain]
    values = {}
    for name, value in fixed_joints.items():
        loc = ("fixed_joints", name)
        joint = robot.joints.get(name)
        if joint is None:
            raise FieldError(loc, f"unknown joint {name!r}; movable joints off the chain: "
                                  f"{listing(off_chain)}")
        if name in chain:
            raise FieldError(loc, f"joint '{name}' is on the chain: its value is part of q")
        if joint.type not in MOVING_TYPES:
            held = "is fixed" if joint.type == "fixed" else "is held at identity off the chain"
            raise FieldError(loc, f"joint '{name}' is a {joint.type} joint and {held}")
        if joint.mimic is not None:
            raise FieldError(loc, f"joint '{name}' mimics '{joint.mimic[0]}' and follows it")
        if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(
                value):
            raise FieldError(loc, f"must be a finite number, got {value!r}")
        urdf_value = value / MM_PER_M if joint.prismatic else float(value)
        if joint.type != "continuous" and joint.limit is not None:
            lower, upper = joint.limit
            if not lower - 1e-12 <= urdf_value <= upper + 1e-12:
                scale = MM_PER_M if joint.prismatic else 1.0
                unit = "mm" if joint.prismatic else "rad"
                raise FieldError(loc, f"{value:g} {unit} is outside the limits of joint "
                                      f"'{name}' [{lower * scale:g}, {upper * scale:g}]")
        values[name] = urdf_value
    return values


def _check_mimics(robot: UrdfRobot) -> None:
    for joint in robot.joints.values():
        if joint.type not in MOVING_TYPES or joint.mimic is None:
            continue
        master = joint.mimic[0]
        loc = joint.loc + ("mimic", "joint")
        other = robot.joints.get(master)
        if other is None or master == joint.name:
            raise FieldError(loc, f"joint '{joint.name}' mimics {master!r}, which is not "
                                  "another joint of the URDF")
        if other.type in MOVING_TYPES and other.mimic is not None:
            raise FieldError(loc, f"joint '{joint.name}' mimics '{master}', which mimics "
                                  f"'{other.mimic[0]}': chains of mimic joints are not "
                                  "supported; mimic the driving joint directly")


def _motion(joint: UrdfJoint, value: float) -> np.ndarray:
    """The joint's motion at ``value`` (URDF units): rotation, translation (to mm) or none."""
    if joint.type in ("revolute", "continuous"):
        return axis_motion("revolute", joint.axis, np.array(value))
    if joint.type == "prismatic":
        return axis_motion("prismatic", joint.axis, np.array(value * MM_PER_M))
    return np.eye(4)  # fixed; floating and planar are held at identity off the chain


# ---- the chain model ---------------------------------------------------------------------
def _chain_entry(joint: UrdfJoint, T_base_joint: np.ndarray) -> dict[str, Any]:
    what = f"joint '{joint.name}'"
    if joint.type == "continuous":
        lower, upper = -CONTINUOUS_LIMIT, CONTINUOUS_LIMIT
    else:
        if joint.limit is None:
            raise FieldError(joint.loc + ("limit",), f"{what} ({joint.type}, on the chain) "
                                                     "needs <limit lower=... upper=...>")
        scale = MM_PER_M if joint.prismatic else 1.0
        lower, upper = joint.limit[0] * scale, joint.limit[1] * scale
        if not lower < upper:
            raise FieldError(joint.loc + ("limit", "upper"),
                             f"{what}: upper limit ({joint.limit[1]:g}) must be above the "
                             f"lower one ({joint.limit[0]:g})")
        bound = MAX_LENGTH_MM if joint.prismatic else MAX_ANGLE_RAD
        if max(abs(lower), abs(upper)) > bound or (
                not joint.prismatic and upper - lower > 8 * math.pi):
            raise FieldError(joint.loc + ("limit",),
                             f"{what}: limits [{joint.limit[0]:g}, {joint.limit[1]:g}] are "
                             "beyond what a model accepts (revolute: within ±8π rad and four "
                             "turns wide; prismatic: within ±10 km)")
    entry: dict[str, Any] = {
        "name": joint.name,
        "type": "prismatic" if joint.prismatic else "revolute",
        "axis": unit_vector(T_base_joint[:3, :3] @ joint.axis).tolist(),
        "lower": lower,
        "upper": upper,
    }
    if not joint.prismatic:
        entry["point"] = T_base_joint[:3, 3].tolist()
    if joint.velocity is not None and 0.0 < joint.velocity < _NO_SPEED_LIMIT:
        velocity = joint.velocity * (MM_PER_M if joint.prismatic else 1.0)
        if velocity <= MAX_JOINT_SPEED:
            entry["velocity"] = velocity
    return entry


_MODEL_FIELDS = {"lower": ("limit", "lower"), "upper": ("limit", "upper"),
                 "velocity": ("limit", "velocity"), "axis": ("axis", "xyz"),
                 "point": ("origin",), "name": ("name",)}


def _build_model(spec: dict[str, Any], chain: list[UrdfJoint]) -> RobotModel:
    try:
        return RobotModel.from_dict(spec)
    except ModelError as exc:
        loc = exc.loc
        if len(loc) >= 2 and loc[0] == "joints" and isinstance(loc[1], int):
            joint = chain[loc[1]]
            sub = _MODEL_FIELDS.get(str(loc[2]) if len(loc) > 2 else "", ())
            raise FieldError(joint.loc + sub, f"joint '{joint.name}': {exc.message}") from None
        if loc and loc[0] in ("id", "name"):
            raise FieldError(("robot_id",) if loc[0] == "id" else ("name",),
                             exc.message) from None
        raise FieldError(("file",), f"the chain's {exc.field}: {exc.message}") from None


# ---- meshes ------------------------------------------------------------------------------
class _Meshes:
    """Loads each (file, scale) once under the caps and names it with a file-safe key."""

    def __init__(self, upload: Upload, urdf_dir: str, limits: ImportLimits):
        self.upload = upload
        self.urdf_dir = urdf_dir
        self.limits = limits
        self.keys: dict[tuple[str, tuple[float, ...]], str] = {}
        self.meshes: dict[str, MeshData] = {}
        self.triangles = 0

    def key(self, geom: UrdfGeometry, link: str) -> str:
        member = resolve_mesh(geom.filename or "", self.urdf_dir, self.upload, geom.loc, link)
        ident = (member, tuple(geom.scale))
        if ident in self.keys:
            return self.keys[ident]
        if len(self.keys) >= self.limits.max_mesh_files:
            raise FieldError(geom.loc, f"link '{link}': more than "
                                       f"{self.limits.max_mesh_files} distinct mesh files")
        mesh = load_mesh(self.upload.read(member), member, np.array(geom.scale), geom.loc,
                         link, self.limits)
        self.triangles += mesh.triangles
        if self.triangles > self.limits.max_mesh_triangles_total:
            raise FieldError(geom.loc, f"link '{link}': the meshes have more than "
                                       f"{self.limits.max_mesh_triangles_total:,} triangles "
                                       f"in all (at '{member}')")
        # Keys read like the file's path from the URDF's folder, without a leading
        # "meshes/" (it says nothing, and the URDF export writes meshes/<key>.stl).
        stem = member.rsplit(".", 1)[0]
        if self.urdf_dir and stem.startswith(self.urdf_dir + "/"):
            stem = stem[len(self.urdf_dir) + 1:]
        if stem.lower().startswith("meshes/"):
            stem = stem[len("meshes/"):]
        slug = re.sub(r"[^A-Za-z0-9_-]+", "_", stem).strip("_")[-80:] or "mesh"
        if geom.scale != (1.0, 1.0, 1.0):
            slug += "_scaled"
        key, k = slug, 2
        while key in self.meshes:
            key, k = f"{slug}_{k}", k + 1
        self.keys[ident] = key
        self.meshes[key] = mesh
        return key


def _geometry(geom: UrdfGeometry, meshes: _Meshes, link: str) -> Geometry:
    origin = geom.origin.copy()
    origin.setflags(write=False)
    if geom.kind == "mesh":
        return Geometry(kind="mesh", origin=origin, mesh=meshes.key(geom, link),
                        color=geom.color)
    return Geometry(kind=geom.kind, origin=origin, size=geom.size, radius=geom.radius,  # type: ignore[arg-type]
                    length=geom.length, color=geom.color)


# ---- adjacency ---------------------------------------------------------------------------
def _adjacent_pairs(robot: UrdfRobot, moving: set[str]) -> frozenset[frozenset[str]]:
    """Links in one rigid body (joined by joints that do not move), and the links of two
    bodies joined by a moving joint."""
    body = {name: name for name in robot.links}

    def find(name: str) -> str:
        while body[name] != name:
            body[name] = body[body[name]]
            name = body[name]
        return name

    for joint in robot.joints.values():
        if joint.name not in moving:
            body[find(joint.child)] = find(joint.parent)
    members: dict[str, list[str]] = {}
    for name in robot.links:
        members.setdefault(find(name), []).append(name)
    pairs: set[frozenset[str]] = set()
    for group in members.values():
        pairs.update(frozenset((a, b)) for i, a in enumerate(group) for b in group[i + 1:])
    for name in moving:
        joint = robot.joints[name]
        for a in members[find(joint.parent)]:
            pairs.update(frozenset((a, b)) for b in members[find(joint.child)] if a != b)
    return frozenset(pairs)


# ---- the import --------------------------------------------------------------------------
def import_robot(
    data: bytes,
    filename: str,
    *,
    robot_id: str,
    name: str | None = None,
    urdf: str | None = None,
    base_link: str | None = None,
    tip_link: str | None = None,
    srdf: bytes | None = None,
    group: str | None = None,
    fixed_joints: Mapping[str, float] | None = None,
    limits: ImportLimits | None = None,
) -> ImportedRobot:
    """Import a robot from a URDF (``data``: a ``.urdf`` file, or a ``.zip`` / ``.tar.gz`` /
    ``.tgz`` / ``.tar`` archive with the URDF and its meshes; ``filename``'s suffix says
    which). Every error users can cause is a ``FieldError`` naming the field or URDF element
    (see the package docstring for the rules and ``ImportLimits`` for the caps)."""
    limits = DEFAULT_LIMITS if limits is None else limits
    if not isinstance(robot_id, str) or re.fullmatch(ID_PATTERN, robot_id) is None:
        raise FieldError(("robot_id",), "use 1 to 64 ASCII letters, digits, '_' or '-'")
    if name is not None and (not isinstance(name, str) or not name or len(name) >
                             MAX_NAME_LENGTH or not name.isprintable()):
        raise FieldError(("name",), f"must be printable text of 1 to {MAX_NAME_LENGTH} "
                                    "characters")
    if not isinstance(filename, str):
        raise FieldError(("file",), "the upload needs a file name")
    upload = open_upload(data, filename, limits)
    urdf_name = _choose_urdf(upload, urdf)
    root_element = parse_xml(upload.read(urdf_name), ("file",), what=f"the URDF '{urdf_name}'",
                             max_bytes=limits.max_xml_bytes, max_depth=limits.max_xml_depth,
                             max_elements=limits.max_xml_elements)
    robot = parse_urdf(root_element, limits.max_links)
    srdf_doc = _read_srdf(srdf, upload, urdf_name, limits)
    tree = Tree(robot)
    _check_mimics(robot)
    base, tip = chain_ends(tree, robot, srdf_doc, base_link, tip_link, group)

    # The chain: movable joints from base to tip.
    chain: list[UrdfJoint] = []
    for joint in tree.path(base, tip):
        if joint.type in ("floating", "planar"):
            raise FieldError(joint.loc + ("type",),
                             f"joint '{joint.name}' is {joint.type}: a {joint.type} joint "
                             f"cannot be on the chain from '{base}' to '{tip}' (revolute, "
                             "continuous, prismatic and fixed joints can)")
        if joint.type in MOVING_TYPES:
            if joint.mimic is not None:
                raise FieldError(joint.loc + ("mimic",),
                                 f"joint '{joint.name}' mimics '{joint.mimic[0]}': a mimic "
                                 f"joint on the chain from '{base}' to '{tip}' is not "
                                 "supported (each chain joint has its own coordinate)")
            chain.append(joint)
    if not chain:
        raise FieldError(("tip_link",), f"no movable joint between '{base}' and '{tip}'")
    if len(chain) > MAX_DOF:
        raise FieldError(("tip_link",), f"{len(chain)} movable joints between '{base}' and "
                                        f"'{tip}'; at most {MAX_DOF}")
    index = {joint.name: i for i, joint in enumerate(chain)}
    held = _held_values(robot, set(index), fixed_joints)

    def value(joint: UrdfJoint) -> float:
        """The joint's value (URDF units) at q = 0."""
        if joint.name in index or joint.type not in MOVING_TYPES:
            return 0.0
        if joint.mimic is not None:
            master, multiplier, offset = joint.mimic
            other = robot.joints[master]
            base_value = 0.0 if master in index or other.type not in MOVING_TYPES else held.get(
                master, 0.0)
            return multiplier * base_value + offset
        return held.get(joint.name, 0.0)

    # World poses at q = 0 (the world frame is the URDF root).
    T_world = {tree.root: np.eye(4)}
    for link in tree.order[1:]:
        joint = tree.parent[link]
        T_world[link] = T_world[joint.parent] @ joint.origin @ _motion(joint, value(joint))
    T_world_base = T_world[base]
    T_base_world = invert_pose(T_world_base)
    spec = {
        "id": robot_id,
        "name": name if name is not None else _robot_name(robot.name, robot_id),
        "convention": "poe",
        "joints": [_chain_entry(j, T_base_world @ T_world[j.parent] @ j.origin) for j in chain],
        "base": T_world_base.tolist(),
        "tool": np.eye(4).tolist(),
        "home": (T_base_world @ T_world[tip]).tolist(),
    }
    model = _build_model(spec, chain)

    # Each link's chain frame, the mimic steps on its way and the constant rest.
    F0 = fk_frames(model, np.zeros(model.dof))
    chain_children = {j.child: i + 1 for i, j in enumerate(chain)}
    state: dict[str, tuple[int, list[MimicStep], np.ndarray]] = {
        tree.root: (0, [], invert_pose(F0[0]))}
    for link in tree.order[1:]:
        joint = tree.parent[link]
        frame, steps, tail = state[joint.parent]
        if link == base:
            if steps:
                raise FieldError(joint.loc + ("mimic",),
                                 f"joint '{joint.name}' moves base_link '{base}' with chain "
                                 f"joint '{steps[-1].joint}': the chain's base must be fixed")
            state[link] = (0, [], np.eye(4))
        elif link in chain_children:
            i = chain_children[link]
            state[link] = (i, [], invert_pose(F0[i]) @ T_world[link])
        elif joint.type in MOVING_TYPES and joint.mimic is not None and joint.mimic[0] in index:
            master, multiplier, offset = joint.mimic
            child_scale = MM_PER_M if joint.prismatic else 1.0
            master_scale = 1.0 / MM_PER_M if chain[index[master]].prismatic else 1.0
            step = MimicStep(
                joint=joint.name, kind="prismatic" if joint.prismatic else "revolute",
                axis=tuple(float(v) for v in joint.axis), origin=_frozen(tail @ joint.origin),
                master=index[master], gain=child_scale * multiplier * master_scale,
                bias=child_scale * offset)
            state[link] = (frame, [*steps, step], np.eye(4))
        else:
            state[link] = (frame, steps, tail @ joint.origin @ _motion(joint, value(joint)))

    urdf_dir = urdf_name.rpartition("/")[0]
    meshes = _Meshes(upload, urdf_dir, limits)
    links = []
    for link_name, link in robot.links.items():
        frame, steps, tail = state[link_name]
        links.append(Link(
            name=link_name, frame=frame, offset=_frozen(tail),
            collision=tuple(_geometry(g, meshes, link_name) for g in link.collision),
            visual=tuple(_geometry(g, meshes, link_name) for g in link.visual),
            mimic=tuple(steps)))

    moving = set(index) | {n for n, j in robot.joints.items()
                           if j.type in MOVING_TYPES and j.mimic is not None
                           and j.mimic[0] in index}
    disabled = set()
    if srdf_doc is not None:
        for a, b, loc in srdf_doc.disabled:
            for attribute, link_name in (("link1", a), ("link2", b)):
                known_link(robot, link_name, loc + (attribute,), "link")
            if a != b:
                disabled.add(frozenset((a, b)))
    return ImportedRobot(
        model=model, links=tuple(links), adjacent_pairs=_adjacent_pairs(robot, moving),
        disabled_pairs=frozenset(disabled), meshes=meshes.meshes, root_link=tree.root,
        base_link=base, tip_link=tip, chain_links=(base, *(j.child for j in chain)),
    )


def _robot_name(urdf_name: str, robot_id: str) -> str:
    ok = 0 < len(urdf_name) <= MAX_NAME_LENGTH and urdf_name.isprintable()
    return urdf_name if ok else robot_id


def _frozen(T: np.ndarray) -> np.ndarray:
    T = np.array(T, dtype=float)
    T.setflags(write=False)
    return T
