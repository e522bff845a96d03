"""Carried loads: objects attached to a robot link, moving with it and colliding like a link.

An ``Attachment`` is a scene object (the ``POST /scenes`` format: ``box``, ``sphere``,
``cylinder``, ``capsule``, ``mesh``; parsed by ``planning.geometry.objects.parse_object``),
the link it rides on (a link name of the robot, or ``"tool"`` for the last link: an
imported robot's tip link, a D-H / PoE robot's ``link{dof-1}`` whose frame is the tool
frame), its pose in that link's frame (``T_link_attachment``, 4x4 mm; the object's own
``pose``, if any, is composed after it) and ``touch_links``: the links it may touch (as
MoveIt's allowed contacts; the link it rides on is always allowed).

``attach(model, attachments)`` (``RobotCollisionModel.with_attached``) gives a new model in
which every attachment is one more body of the robot, named by the object's ``id``:

* its state is its link's frame composed with ``T_link_object``, so the sphere stage, the
  exact stage and the compiled checker of ``planning.motion`` place it like any link;
* its sphere tree covers the object (``planning.geometry.spheres.cover_link``: balls that
  contain it by construction; a sphere is its own ball);
* its exact shape is the object's FCL shape;
* self pairs: against every robot link but its own and its ``touch_links``, and against
  every other attachment (unless one lists the other among its ``touch_links``).

Link frames: an imported robot's link ``name`` is ``link_poses(q)`` of that link (any link of
the URDF, with or without geometry); a D-H / PoE robot's ``link{k}`` (``k = 0 .. dof-1``) is
``fk_frames`` entry ``k + 1``, the frame after joint ``k`` (its capsule runs from frame ``k``
to that frame's origin). A capsule model with attachments keeps its capsules but stores
every state as ``(3, 4)`` (``[run | 0 | 0 | start]``, capsule sphere centres
``[t, 0, 0, 1]``), so links and attachments share one layout. Lengths in mm.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace
from itertools import combinations
from typing import Any

import numpy as np

from kinematics.errors import FieldError
from kinematics.model import MAX_NAME_LENGTH

from ..geometry.distance import segment_frame
from ..geometry.fields import parse_pose
from ..geometry.objects import MeshResolver, SceneObject, parse_object
from ..geometry.spheres import (
    RADIUS_SLACK,
    SphereTree,
    box_solid,
    cover_link,
    cylinder_solid,
    sphere_solid,
)

__all__ = ["Attachment", "ATTACHABLE_TYPES", "MAX_ATTACHMENTS", "TOOL", "attach"]

#: Object types that can be attached (a point cloud is a scan of the site, not a load).
ATTACHABLE_TYPES = ("box", "sphere", "cylinder", "capsule", "mesh")
#: Most attachments on one model.
MAX_ATTACHMENTS = 32
#: The link name that means the last link (tip link, or the tool frame's link).
TOOL = "tool"


def _name(value: Any, loc: tuple, what: str) -> str:
    if not isinstance(value, str) or not value or len(value) > MAX_NAME_LENGTH \
            or not value.isprintable():
        raise FieldError(loc, f"{what} must be printable text of 1 to {MAX_NAME_LENGTH} "
                         f"characters")
    return value


@dataclass(frozen=True, eq=False)
class Attachment:
    """An object carried by a robot link (module docstring). Build it with ``from_dict``
    or ``make``; ``object`` is the parsed ``SceneObject``, ``pose`` is
    ``T_link_attachment (4, 4)`` (read-only), ``touch_links`` the names it may touch."""

    object: SceneObject
    link: str = TOOL
    pose: np.ndarray = field(default_factory=lambda: np.eye(4))
    touch_links: tuple[str, ...] = ()

    @property
    def id(self) -> str:
        """The attachment's name: its object's ``id``."""
        return self.object.id

    @property
    def T_link_object(self) -> np.ndarray:
        """The object's frame in the link's frame: ``pose @ object.pose``."""
        return np.asarray(self.pose, dtype=float) @ np.asarray(self.object.pose, dtype=float)

    # ---- parsing ------------------------------------------------------------------------
    @classmethod
    def from_dict(cls, data: Any, index: int = 0, resolve_mesh: MeshResolver | None = None,
                  prefix: tuple = ("attached",), default_id: str | None = None
                  ) -> Attachment:
        """``{"object": {...}, "link": "tool", "pose": 4x4, "touch_links": [...]}``
        (``link`` default ``"tool"``, ``pose`` default the identity); ``FieldError`` at
        ``prefix + (index, field, ...)``. An object without ``id`` is ``default_id``
        (None: ``attached{index}``)."""
        loc = prefix + (index,)
        if not isinstance(data, Mapping):
            raise FieldError(loc, "an attachment must be a JSON object with an 'object'")
        for key in data:
            if key not in ("object", "link", "pose", "touch_links"):
                raise FieldError(loc + (str(key),), "unknown field for an attachment; an "
                                 "attachment has link, object, pose, touch_links")
        if "object" not in data:
            raise FieldError(loc + ("object",), "an attachment needs 'object'")
        return cls.make(data["object"], data.get("link", TOOL), data.get("pose"),
                        data.get("touch_links", ()), resolve_mesh=resolve_mesh, index=index,
                        prefix=prefix, default_id=default_id)

    @classmethod
    def make(cls, object: Any, link: str = TOOL, pose: Any = None,
             touch_links: Iterable[str] = (), *, resolve_mesh: MeshResolver | None = None,
             index: int = 0, prefix: tuple = ("attached",),
             default_id: str | None = None) -> Attachment:
        """An attachment from an object dict (or a parsed ``SceneObject``), the link's name,
        ``T_link_attachment`` (nested lists or an array; None: the identity) and
        ``touch_links``; errors and ``default_id`` as ``from_dict``'s."""
        loc = prefix + (index,)
        obj = _parse_object(object, loc + ("object",), resolve_mesh,
                            default_id or f"attached{index}")
        link = _name(link, loc + ("link",), "link")
        T = parse_pose(np.asarray(pose).tolist() if isinstance(pose, np.ndarray) else pose,
                       loc + ("pose",))
        if isinstance(touch_links, str) or not isinstance(touch_links, Iterable):
            raise FieldError(loc + ("touch_links",), "touch_links must be a list of link "
                             "names")
        touch = tuple(_name(x, loc + ("touch_links", j), "a touch link")
                      for j, x in enumerate(touch_links))
        return cls(obj, link, T, touch)

    def to_dict(self) -> dict[str, Any]:
        """The attachment in the ``from_dict`` format (a stored mesh by name)."""
        return {"object": self.object.to_dict(), "link": self.link,
                "pose": np.asarray(self.pose).tolist(), "touch_links": list(self.touch_links)}

    # ---- geometry -----------------------------------------------------------------------
    def cover(self, n_groups: int, per_group: int) -> SphereTree:
        """A sphere tree in the object's frame whose balls contain the object (a sphere:
        one ball; the others: ``cover_link`` on the exact solids or the mesh's triangles,
        as FCL treats a mesh: its surface)."""
        o = self.object
        if o.type == "sphere":
            r = float(o.radius) * (1 + RADIUS_SLACK[0]) + RADIUS_SLACK[1]
            ball = np.array([0.0, 0.0, 0.0, r])
            return SphereTree(ball, ball[None], ball[None, None], ball[None])
        triangles, solids = np.empty((0, 3, 3)), []
        eye = np.eye(4)
        if o.type == "box":
            solids.append(box_solid(o.size, eye))
        elif o.type == "cylinder":
            solids.append(cylinder_solid(o.radius, o.height, eye))
        elif o.type == "capsule":
            a, b = np.asarray(o.a, dtype=float), np.asarray(o.b, dtype=float)
            for p in (a, b):
                Tp = np.eye(4)
                Tp[:3, 3] = p
                solids.append(sphere_solid(o.radius, Tp))
            L = float(np.linalg.norm(b - a))
            if L > 0:
                solids.append(cylinder_solid(o.radius, L, segment_frame(a, b)))
        else:
            V, F = _mesh(o)
            triangles = V[F]
        return cover_link(triangles, solids, n_groups, per_group)

    def exact_shapes(self) -> list:
        """The object's exact shapes (``planning.collision.exact``'s ``_Shape``) in its own
        frame."""
        from .exact import _bvh, _fcl, _Shape

        fcl = _fcl()
        o = self.object
        eye = np.eye(4)
        if o.type == "box":
            return [_Shape("box", eye, fcl.Box(*o.size), size=tuple(o.size))]
        if o.type == "sphere":
            return [_Shape("sphere", eye, fcl.Sphere(o.radius), radius=o.radius)]
        if o.type == "cylinder":
            return [_Shape("cylinder", eye, fcl.Cylinder(o.radius, o.height),
                           radius=o.radius, height=o.height)]
        if o.type == "capsule":
            a, b = np.asarray(o.a, dtype=float), np.asarray(o.b, dtype=float)
            L = float(np.linalg.norm(b - a))
            if L > 0:
                return [_Shape("capsule", segment_frame(a, b), fcl.Capsule(o.radius, L),
                               radius=o.radius, height=L)]
            Ta = np.eye(4)
            Ta[:3, 3] = a
            return [_Shape("sphere", Ta, fcl.Sphere(o.radius), radius=o.radius)]
        V, F = _mesh(o)
        return [_Shape("mesh", eye, _bvh(V, F), triangles=V[F])]

    def summary(self) -> dict[str, Any]:
        """JSON-ready: id, type, link, ``T_link_object``, touch links."""
        return {"id": self.id, "type": self.object.type, "link": self.link,
                "pose": np.round(self.T_link_object, 9).tolist(),
                "touch_links": list(self.touch_links)}


def _mesh(o: SceneObject) -> tuple[np.ndarray, np.ndarray]:
    V = np.asarray(o.vertices, dtype=float) * np.asarray(o.scale, dtype=float)
    return V, np.asarray(o.faces, dtype=np.int64)


def _parse_object(value: Any, loc: tuple, resolve_mesh: MeshResolver | None,
                  default_id: str) -> SceneObject:
    """A ``SceneObject`` from a dict (errors at ``loc + (field,)``; no ``id``:
    ``default_id``) or as given."""
    if isinstance(value, SceneObject):
        obj = value
    else:
        if not isinstance(value, Mapping):
            raise FieldError(loc, "object must be a JSON object with a 'type'")
        data = dict(value)
        if data.get("type") == "points":
            raise FieldError(loc + ("type",), _types_message("points"))
        data.setdefault("id", default_id)
        try:
            obj = parse_object(data, 0, resolve_mesh, prefix=("object",))
        except FieldError as exc:
            raise FieldError(loc + exc.loc[2:], exc.message) from None
    if obj.type not in ATTACHABLE_TYPES:
        raise FieldError(loc + ("type",), _types_message(obj.type))
    return obj


def _types_message(kind: str) -> str:
    return f"a {kind} cannot be attached; attachable types: {', '.join(ATTACHABLE_TYPES)}"


# ---- the model with its attachments ------------------------------------------------------------
def _frames(model: Any) -> tuple[dict[str, int], dict[str, str], set[str]]:
    """The robot's link names: ``frame`` (name -> index into ``link_poses`` of an imported
    robot, or into ``fk_frames`` of a D-H / PoE one), ``alias`` (``"tool"`` -> the last
    link) and every valid name (touch links included)."""
    if model.kind == "imported":
        robot = model.source
        frame = {link.name: k for k, link in enumerate(robot.links)}
        last = robot.tip_link
    else:
        dof = int(model.dof)
        frame = {f"link{k}": k + 1 for k in range(dof)}
        last = f"link{dof - 1}"
    return frame, {TOOL: last}, set(frame) | {TOOL}


def _pad_levels(root, root_r, group, group_r, leaf, leaf_r, G: int, m: int) -> tuple:
    """A tree's levels padded to ``G`` groups of ``m`` leaves by repeating the first group
    and each group's first leaf (repeats change no distance)."""
    L, g0, m0, w = leaf.shape
    if g0 < G:
        group = np.concatenate([group, np.repeat(group[:, :1], G - g0, axis=1)], axis=1)
        group_r = np.concatenate([group_r, np.repeat(group_r[:, :1], G - g0, axis=1)], axis=1)
        leaf = np.concatenate([leaf, np.repeat(leaf[:, :1], G - g0, axis=1)], axis=1)
        leaf_r = np.concatenate([leaf_r, np.repeat(leaf_r[:, :1], G - g0, axis=1)], axis=1)
    if m0 < m:
        leaf = np.concatenate([leaf, np.repeat(leaf[:, :, :1], m - m0, axis=2)], axis=2)
        leaf_r = np.concatenate([leaf_r, np.repeat(leaf_r[:, :, :1], m - m0, axis=2)], axis=2)
    return root, root_r, group, group_r, leaf, leaf_r


def _wide(local: np.ndarray) -> np.ndarray:
    """Capsule locals ``[1, t]`` as ``[t, 0, 0, 1]`` (the ``(3, 4)`` capsule state is
    ``[run | 0 | 0 | start]``)."""
    out = np.zeros(local.shape[:-1] + (4,))
    out[..., 0] = local[..., 1]
    out[..., 3] = local[..., 0]
    return out


def attach(model: Any, attachments: Iterable[Any],
           resolve_mesh: MeshResolver | None = None) -> Any:
    """``model`` (a ``RobotCollisionModel``) with ``attachments`` (``Attachment``s or
    ``from_dict`` dicts) added to those it already carries: a new model (module
    docstring); ``model`` is unchanged. ``FieldError`` at ``("attached", i, ...)`` (``i``:
    the position in ``attachments``) for an unknown link or touch link, an id already
    used, or a bad object."""
    base = model.base if model.base is not None else model
    if isinstance(attachments, Mapping) or not isinstance(attachments, Iterable):
        raise FieldError(("attached",), "attached must be a list of attachments")
    first = len(model.attached)
    new = [a if isinstance(a, Attachment) else
           Attachment.from_dict(a, i, resolve_mesh, default_id=f"attached{first + i}")
           for i, a in enumerate(attachments)]
    every = list(model.attached) + new
    if len(every) > MAX_ATTACHMENTS:
        raise FieldError(("attached",), f"at most {MAX_ATTACHMENTS} attachments")
    if not every:
        return base
    frame, alias, valid = _frames(base)
    ids = {a.id for a in model.attached}
    robot_names = set(frame) | set(base.names)
    for i, a in enumerate(new):
        loc = ("attached", i)
        if a.link not in valid:
            raise FieldError(loc + ("link",), f"unknown link {a.link!r}; links: "
                             f"{', '.join(sorted(valid))}")
        if a.id in robot_names or a.id in ids or a.id == TOOL:
            raise FieldError(loc + ("object", "id"), f"id {a.id!r} is already used by a "
                             f"link or another attachment")
        ids.add(a.id)
    all_ids = {a.id for a in every}
    for i, a in enumerate(new):
        for j, name in enumerate(a.touch_links):
            if name not in valid and name not in all_ids:
                raise FieldError(("attached", i, "touch_links", j),
                                 f"unknown link {name!r}; links: {', '.join(sorted(valid))}")

    opts = base.options
    groups = int(opts.get("n_groups", 4))
    per = int(opts.get("spheres_per_group", 8))
    covers = [a.cover(groups, per) for a in every]
    t = base.tree
    levels = (t.root, t.root_r, t.group, t.group_r, t.leaf, t.leaf_r)
    flat = t.flat
    if t.root.shape[-1] == 2:
        levels = (_wide(t.root), t.root_r, _wide(t.group), t.group_r, _wide(t.leaf), t.leaf_r)
        flat = _wide(t.flat)
    G = max(t.group.shape[1], *(len(c.groups) for c in covers))
    m = max(t.leaf.shape[2], *(c.leaves.shape[1] for c in covers))
    parts = [_pad_levels(*levels, G, m)]

    def homog(x):
        return np.concatenate([x[..., :3], np.ones(x.shape[:-1] + (1,))], axis=-1)

    for c in covers:
        parts.append(_pad_levels(homog(c.root[None]), c.root[None, 3], homog(c.groups[None]),
                                 c.groups[None, :, 3], homog(c.leaves[None]),
                                 c.leaves[None, ..., 3], G, m))
    stacked = [np.concatenate([p[i] for p in parts]) for i in range(6)]
    n = len(base.names)
    flat_link = np.concatenate([t.flat_link] + [np.full(len(c.unique), n + i)
                                                for i, c in enumerate(covers)])
    tree = type(t)(*stacked, np.vstack([flat] + [homog(c.unique) for c in covers]),
                 np.concatenate([t.flat_r] + [c.unique[:, 3] for c in covers]), flat_link)

    names = tuple(base.names) + tuple(a.id for a in every)
    pairs = [tuple(p) for p in np.asarray(base.pairs).tolist()]
    extra = []
    for i, a in enumerate(every):
        allowed = {alias.get(x, x) for x in (a.link, *a.touch_links)}
        for k, name in enumerate(base.names):
            if name not in allowed:
                extra.append((k, n + i))
    for i, j in combinations(range(len(every)), 2):
        if every[j].id not in every[i].touch_links and every[i].id not in every[j].touch_links:
            extra.append((n + i, n + j))
    P = len(pairs)
    all_pairs = np.array(pairs + extra, dtype=np.intp).reshape(-1, 2)
    sphere_pairs = np.concatenate([np.asarray(base.sphere_pairs, dtype=np.intp),
                                   np.arange(P, P + len(extra), dtype=np.intp)])
    link_frame = np.array([frame[alias.get(a.link, a.link)] for a in every], dtype=np.intp)
    T = np.array([a.T_link_object for a in every])
    return replace(base, names=names, pairs=all_pairs, tree=tree, sphere_pairs=sphere_pairs,
                   attached=tuple(every), attached_frame=link_frame, attached_pose=T,
                   base=base)


def attached_state(model: Any, frames: np.ndarray) -> np.ndarray:
    """The attachments' states ``(B, A, 3, 4)`` from the robot's link frames ``frames
    (B, F, 4, 4)`` (``link_poses`` of an imported robot, ``fk_frames`` of a D-H one)."""
    return np.matmul(frames[:, model.attached_frame], model.attached_pose)[..., :3, :]
