"""URDF and SRDF elements read into plain descriptions, every error naming its element.

Locations (``FieldError.loc``) follow one scheme: the request field (``"file"`` for the
uploaded URDF, ``"srdf"`` for an SRDF given on its own, ``("file", "<member>.srdf")`` for one
found in the archive), then named elements as ``"tag[name]"`` (``"joint[elbow_joint]"``),
repeated unnamed children as the tag and a 0-based index (``"collision", 0``), then the child
element and the attribute: ``("file", "joint[elbow_joint]", "axis", "xyz")``,
``("file", "link[base_link]", "visual", 0, "geometry", "mesh", "filename")``. An element
without a name is located by its tag and index among its kind (``("file", "link", 3,
"name")``).

Lengths are converted to mm here; joint limits stay in URDF units (rad, m, m/s) until the
chain is built.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

import numpy as np

from ..errors import FieldError, Loc
from ..model import MAX_ANGLE_RAD, MAX_LENGTH_MM
from ..transforms import rpy_to_matrix

__all__ = ["UrdfGeometry", "UrdfLink", "UrdfJoint", "UrdfRobot", "Srdf", "parse_urdf",
           "parse_srdf", "unit_vector", "MOVING_TYPES", "JOINT_TYPES"]

MM_PER_M = 1000.0
JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")
#: Joint types driven by one coordinate (the ones that can be on the chain or mimic).
MOVING_TYPES = ("revolute", "continuous", "prismatic")


@dataclass
class UrdfGeometry:
    kind: str  # box, cylinder, sphere, mesh
    origin: np.ndarray  # T_link_shape, mm
    loc: Loc  # the shape element
    size: tuple[float, float, float] = (0.0, 0.0, 0.0)  # mm
    radius: float = 0.0
    length: float = 0.0
    filename: str | None = None
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    color: tuple[float, float, float, float] | None = None


@dataclass
class UrdfLink:
    name: str
    loc: Loc
    collision: list[UrdfGeometry] = field(default_factory=list)
    visual: list[UrdfGeometry] = field(default_factory=list)


@dataclass
class UrdfJoint:
    name: str
    type: str
    parent: str
    child: str
    origin: np.ndarray  # T_parent_joint, mm
    loc: Loc
    axis: np.ndarray | None = None  # unit, in the joint frame; None for fixed and floating
    limit: tuple[float, float] | None = None  # lower, upper (rad or m)
    velocity: float | None = None  # rad/s or m/s, as written
    mimic: tuple[str, float, float] | None = None  # master, multiplier, offset (URDF units)

    @property
    def prismatic(self) -> bool:
        return self.type == "prismatic"


@dataclass
class UrdfRobot:
    name: str
    links: dict[str, UrdfLink]
    joints: dict[str, UrdfJoint]


@dataclass
class Srdf:
    loc: Loc
    groups: dict[str, list[tuple[str, str, Loc]]]  # group -> its chains (base, tip, loc)
    disabled: list[tuple[str, str, Loc]]


# ---- numbers -----------------------------------------------------------------------------
def _floats(text: str | None, counts: tuple[int, ...], loc: Loc, what: str) -> list[float]:
    if text is None:
        raise FieldError(loc, f"{what} is missing")
    parts = text.split()
    if len(parts) not in counts:
        n = " or ".join(str(c) for c in counts)
        raise FieldError(loc, f"{what} must be {n} numbers, got {text.strip()!r}")
    try:
        values = [float(p) for p in parts]
    except ValueError:
        raise FieldError(loc, f"{what} must be numbers, got {text.strip()!r}") from None
    if not all(math.isfinite(v) for v in values):
        raise FieldError(loc, f"{what} must be finite, got {text.strip()!r}")
    return values


def _float(element: ET.Element, attribute: str, loc: Loc, what: str,
           default: float | None = None) -> float:
    text = element.get(attribute)
    if text is None and default is not None:
        return default
    return _floats(text, (1,), loc + (attribute,), what)[0]


def unit_vector(v) -> np.ndarray:
    """``v / |v|``, repeated until the norm is exactly 1.0 where round-off allows, so that
    normalising the result again (as ``RobotModel.from_dict`` does) changes nothing."""
    v = np.asarray(v, dtype=float)
    for _ in range(4):
        norm = float(np.linalg.norm(v))
        if norm == 1.0:
            break
        v = v / norm
    return v


def _origin(parent: ET.Element, loc: Loc, what: str) -> np.ndarray:
    """``T_parent_child`` (mm) of ``parent``'s ``<origin>`` (identity when there is none)."""
    T = np.eye(4)
    element = parent.find("origin")
    if element is None:
        return T
    loc = loc + ("origin",)
    xyz = np.array(_floats(element.get("xyz", "0 0 0"), (3,), loc + ("xyz",),
                           f"{what}: origin xyz"))
    rpy = np.array(_floats(element.get("rpy", "0 0 0"), (3,), loc + ("rpy",),
                           f"{what}: origin rpy"))
    if np.abs(xyz).max() * MM_PER_M > MAX_LENGTH_MM:
        raise FieldError(loc + ("xyz",), f"{what}: origin xyz must be within "
                                         f"±{MAX_LENGTH_MM / MM_PER_M:g} m")
    if np.abs(rpy).max() > MAX_ANGLE_RAD:
        raise FieldError(loc + ("rpy",), f"{what}: origin rpy must be within "
                                         f"±{MAX_ANGLE_RAD:.4g} rad")
    T[:3, :3] = rpy_to_matrix(rpy)
    T[:3, 3] = xyz * MM_PER_M
    return T


# ---- links -------------------------------------------------------------------------------
def _color(material: ET.Element | None, materials: dict[str, tuple], loc: Loc,
           what: str) -> tuple[float, float, float, float] | None:
    if material is None:
        return None
    color = material.find("color")
    if color is None:
        return materials.get(material.get("name", ""))
    values = _floats(color.get("rgba"), (4,), loc + ("material", "color", "rgba"),
                     f"{what}: material rgba")
    return tuple(min(max(v, 0.0), 1.0) for v in values)  # type: ignore[return-value]


def _geometry(element: ET.Element, loc: Loc, what: str, materials: dict[str, tuple],
              visual: bool) -> UrdfGeometry:
    origin = _origin(element, loc, what)
    holder = element.find("geometry")
    if holder is None:
        raise FieldError(loc + ("geometry",), f"{what}: missing <geometry>")
    shapes = list(holder)
    if len(shapes) != 1:
        raise FieldError(loc + ("geometry",), f"{what}: <geometry> must hold exactly one "
                                              f"shape (box, cylinder, sphere or mesh), found "
                                              f"{len(shapes)}")
    shape = shapes[0]
    sloc = loc + ("geometry", shape.tag)
    color = _color(element.find("material"), materials, loc, what) if visual else None
    geom = UrdfGeometry(kind=shape.tag, origin=origin, loc=sloc, color=color)

    def length(attribute: str) -> float:
        value = _float(shape, attribute, sloc, f"{what}: {shape.tag} {attribute}") * MM_PER_M
        if value < 0 or value > MAX_LENGTH_MM:
            raise FieldError(sloc + (attribute,), f"{what}: {shape.tag} {attribute} must be "
                                                  f"between 0 and {MAX_LENGTH_MM / 1000:g} m")
        return value

    if shape.tag == "box":
        size = _floats(shape.get("size"), (3,), sloc + ("size",), f"{what}: box size")
        if min(size) < 0 or max(size) * MM_PER_M > MAX_LENGTH_MM:
            raise FieldError(sloc + ("size",), f"{what}: box sizes must be between 0 and "
                                               f"{MAX_LENGTH_MM / 1000:g} m")
        geom.size = tuple(v * MM_PER_M for v in size)  # type: ignore[assignment]
    elif shape.tag == "cylinder":
        geom.radius = length("radius")
        geom.length = length("length")
    elif shape.tag == "sphere":
        geom.radius = length("radius")
    elif shape.tag == "mesh":
        filename = shape.get("filename")
        if not filename:
            raise FieldError(sloc + ("filename",), f"{what}: <mesh> needs a filename")
        geom.filename = filename
        geom.loc = sloc + ("filename",)
        if shape.get("scale") is not None:
            scale = _floats(shape.get("scale"), (1, 3), sloc + ("scale",), f"{what}: mesh scale")
            if len(scale) == 1:
                scale = scale * 3
            if any(s == 0 or abs(s) > 1e6 for s in scale):
                raise FieldError(sloc + ("scale",), f"{what}: mesh scale must be non-zero and "
                                                    "within ±1e6")
            geom.scale = tuple(scale)  # type: ignore[assignment]
    else:
        raise FieldError(sloc, f"{what}: unsupported geometry <{shape.tag}> (box, cylinder, "
                               "sphere or mesh)")
    return geom


def _link(element: ET.Element, index: int, materials: dict[str, tuple]) -> UrdfLink:
    name = element.get("name")
    if not name:
        raise FieldError(("file", "link", index, "name"), f"<link> number {index + 1} has no "
                                                          "name")
    loc: Loc = ("file", f"link[{name}]")
    link = UrdfLink(name=name, loc=loc)
    for kind, into in (("collision", link.collision), ("visual", link.visual)):
        for k, element_k in enumerate(element.findall(kind)):
            into.append(_geometry(element_k, loc + (kind, k), f"link '{name}' {kind} {k}",
                                  materials, kind == "visual"))
    return link


# ---- joints ------------------------------------------------------------------------------
def _joint(element: ET.Element, index: int) -> UrdfJoint:
    name = element.get("name")
    if not name:
        raise FieldError(("file", "joint", index, "name"), f"<joint> number {index + 1} has "
                                                           "no name")
    loc: Loc = ("file", f"joint[{name}]")
    what = f"joint '{name}'"
    kind = element.get("type")
    if kind not in JOINT_TYPES:
        raise FieldError(loc + ("type",), f"{what}: unknown type {kind!r} (revolute, "
                                          "continuous, prismatic, fixed, floating or planar)")
    ends = []
    for end in ("parent", "child"):
        sub = element.find(end)
        link = sub.get("link") if sub is not None else None
        if not link:
            raise FieldError(loc + (end,), f"{what}: needs <{end} link=\"...\"/>")
        ends.append(link)
    joint = UrdfJoint(name=name, type=kind, parent=ends[0], child=ends[1],
                      origin=_origin(element, loc, what), loc=loc)
    if kind in (*MOVING_TYPES, "planar"):
        axis_element = element.find("axis")
        text = "1 0 0" if axis_element is None else axis_element.get("xyz", "1 0 0")
        axis = np.array(_floats(text, (3,), loc + ("axis", "xyz"), f"{what}: axis"))
        norm = float(np.linalg.norm(axis))
        if not norm > 1e-12:
            raise FieldError(loc + ("axis", "xyz"), f"{what}: axis must not be zero")
        joint.axis = unit_vector(axis)
    if kind in MOVING_TYPES:
        limit = element.find("limit")
        if limit is not None:
            lloc = loc + ("limit",)
            lower = _float(limit, "lower", lloc, f"{what}: limit lower", 0.0)
            upper = _float(limit, "upper", lloc, f"{what}: limit upper", 0.0)
            joint.limit = (lower, upper)
            if limit.get("velocity") is not None:
                joint.velocity = _float(limit, "velocity", lloc, f"{what}: limit velocity")
        mimic = element.find("mimic")
        if mimic is not None:
            mloc = loc + ("mimic",)
            master = mimic.get("joint")
            if not master:
                raise FieldError(mloc + ("joint",), f"{what}: <mimic> needs a joint")
            joint.mimic = (master,
                           _float(mimic, "multiplier", mloc, f"{what}: mimic multiplier", 1.0),
                           _float(mimic, "offset", mloc, f"{what}: mimic offset", 0.0))
    return joint


def parse_urdf(root: ET.Element, max_links: int) -> UrdfRobot:
    """The links and joints of a URDF ``<robot>`` element, in document order."""
    if root.tag != "robot":
        raise FieldError(("file",), f"the URDF's root element is <{root.tag}>, not <robot>")
    # Named colours: top-level materials, then ones defined inside a visual (which later
    # visuals may name without a colour, as ROS tools allow); the first definition wins.
    materials: dict[str, tuple] = {}
    for k, material in enumerate(root.findall("material")):
        if not material.get("name"):
            raise FieldError(("file", "material", k, "name"), "a top-level <material> needs "
                                                              "a name")
    top_level = root.findall("material")
    for material in [*top_level, *root.iter("material")]:
        name = material.get("name")
        color = material.find("color")
        if not name or name in materials or color is None:
            continue
        try:
            values = _floats(color.get("rgba"), (4,), ("file", f"material[{name}]", "color",
                                                       "rgba"), f"material '{name}': rgba")
        except FieldError:
            if any(material is m for m in top_level):
                raise
            continue  # an inline one: its own visual reports it, at its place
        materials[name] = tuple(min(max(v, 0.0), 1.0) for v in values)
    link_elements = root.findall("link")
    if not link_elements:
        raise FieldError(("file",), "the URDF has no <link>")
    if len(link_elements) > max_links:
        raise FieldError(("file",), f"the URDF has {len(link_elements):,} links; at most "
                                    f"{max_links:,} allowed")
    links: dict[str, UrdfLink] = {}
    for k, element in enumerate(link_elements):
        link = _link(element, k, materials)
        if link.name in links:
            raise FieldError(link.loc + ("name",), f"two links are named '{link.name}'")
        links[link.name] = link
    joints: dict[str, UrdfJoint] = {}
    for k, element in enumerate(root.findall("joint")):
        joint = _joint(element, k)
        if joint.name in joints:
            raise FieldError(joint.loc + ("name",), f"two joints are named '{joint.name}'")
        joints[joint.name] = joint
    return UrdfRobot(name=root.get("name") or "", links=links, joints=joints)


# ---- SRDF --------------------------------------------------------------------------------
def parse_srdf(root: ET.Element, loc: Loc) -> Srdf:
    """Groups with their ``<chain>`` elements and the ``<disable_collisions>`` pairs."""
    if root.tag != "robot":
        raise FieldError(loc, f"the SRDF's root element is <{root.tag}>, not <robot>")
    groups: dict[str, list[tuple[str, str, Loc]]] = {}
    for k, group in enumerate(root.findall("group")):
        name = group.get("name")
        if not name:
            raise FieldError(loc + ("group", k, "name"), "a <group> needs a name")
        gloc = loc + (f"group[{name}]",)
        chains = groups.setdefault(name, [])
        for i, chain in enumerate(group.findall("chain")):
            base, tip = chain.get("base_link"), chain.get("tip_link")
            if not base or not tip:
                raise FieldError(gloc + ("chain", i), f"group '{name}': <chain> needs "
                                                      "base_link and tip_link")
            chains.append((base, tip, gloc + ("chain", i)))
    disabled = []
    for k, pair in enumerate(root.findall("disable_collisions")):
        a, b = pair.get("link1"), pair.get("link2")
        if not a or not b:
            raise FieldError(loc + ("disable_collisions", k), "<disable_collisions> needs "
                                                              "link1 and link2")
        disabled.append((a, b, loc + ("disable_collisions", k)))
    return Srdf(loc=loc, groups=groups, disabled=disabled)
