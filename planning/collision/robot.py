"""A robot's collision model: conservative sphere trees on its links, the self-collision
pairs, and the exact geometry the spheres stand for.

Two kinds of robot:

* **imported** (``RobotCollisionModel.from_imported``: a URDF robot, duck-typed as
  ``kinematics.urdf_import.ImportedRobot``): each link's collision geometry (meshes, boxes,
  cylinders, spheres) is covered by a three-level sphere tree in the link frame
  (``planning.geometry.spheres.cover_link``: ``n_groups`` groups of at most
  ``spheres_per_group`` leaves); the exact geometry is the URDF's. Self-collision pairs: every
  pair of links with geometry except the adjacent ones and the SRDF's disabled ones.
* **capsules** (``RobotCollisionModel.from_model``: built-in and custom D-H / PoE robots,
  which carry no geometry): link ``k`` is a capsule of radius ``link_radius[k]`` between the
  origins of ``fk_frames`` entries ``k`` and ``k + 1`` (as ``planning.paths.arm``), covered
  by balls along its axis; the exact geometry is the capsule. Links of zero length are left
  out. Self-collision pairs: every pair except those the chain holds in contact whatever the
  joints do: two capsules whose facing ends are joined by links shorter in total than the sum
  of their radii (this covers neighbours, and neighbours across zero-length links).

A model turns configurations into a *state* ``M (B, L, 3, w)`` from which every sphere's
world centre is ``M @ local``: for imported robots ``M = [R | p]`` of each link's pose and
``local = [x, y, z, 1]``; for capsules ``M = [A | B - A]`` of each link's end points and
``local = [1, t]``. Lengths in mm.

``with_attached`` adds carried objects (``planning.collision.attached``): one more body
each after the links, whose state is its link's frame composed with its pose there; a
capsule model carrying any then writes its capsules' states ``[B - A | 0 | 0 | A]`` with
``local = [t, 0, 0, 1]`` (``width`` 4), one layout for links and objects.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from itertools import combinations
from typing import Any

import numpy as np

from kinematics.errors import FieldError

from ..geometry.distance import frames_along
from ..geometry.spheres import (
    SphereTree,
    box_solid,
    cover_link,
    cylinder_solid,
    sphere_solid,
)
from .tables import TABLE_MAX_NODES, TABLE_TOLERANCE, build_pair_table, sweep_ratio

__all__ = ["RobotCollisionModel", "DEFAULT_LINK_RADIUS", "DEFAULT_GROUPS",
           "DEFAULT_SPHERES_PER_GROUP", "MAX_CAPSULE_SPHERES"]

#: Default capsule radius (mm) of a D-H / PoE robot's links (as ``planning.paths.arm``).
DEFAULT_LINK_RADIUS = 60.0
#: Default sphere tree of an imported robot's link: groups, and leaves per group.
DEFAULT_GROUPS = 4
DEFAULT_SPHERES_PER_GROUP = 8
#: Most balls along one capsule; spacing between balls along a capsule, as a fraction of its
#: radius (0.5: the balls are 3 % wider than the capsule).
MAX_CAPSULE_SPHERES = 64
CAPSULE_SPACING = 0.5


@dataclass(frozen=True, eq=False)
class _Tree:
    """Sphere trees of all links, padded to one shape: ``local`` coordinates (width ``w``)
    and radii per level, and the distinct leaves flattened (sorted by link)."""

    root: np.ndarray          # (L, w)
    root_r: np.ndarray        # (L,)
    group: np.ndarray         # (L, G, w)
    group_r: np.ndarray       # (L, G)
    leaf: np.ndarray          # (L, G, m, w)
    leaf_r: np.ndarray        # (L, G, m)
    flat: np.ndarray          # (S, w)
    flat_r: np.ndarray        # (S,)
    flat_link: np.ndarray     # (S,)


def _pad_trees(trees: list[SphereTree]) -> _Tree:
    """Stack link trees (frame coordinates ``[x, y, z, r]``) as ``local = [x, y, z, 1]``."""
    G = max(len(t.groups) for t in trees)
    m = max(t.leaves.shape[1] for t in trees)
    L = len(trees)
    group = np.empty((L, G, 4))
    leaf = np.empty((L, G, m, 4))
    for k, t in enumerate(trees):
        g = np.vstack([t.groups, np.repeat(t.groups[:1], G - len(t.groups), axis=0)])
        lv = np.concatenate([t.leaves, np.repeat(t.leaves[:1], G - len(t.groups), axis=0)])
        lv = np.concatenate([lv, np.repeat(lv[:, :1], m - lv.shape[1], axis=1)], axis=1)
        group[k], leaf[k] = g, lv
    root = np.array([t.root for t in trees])
    flat = np.vstack([t.unique for t in trees])
    link = np.repeat(np.arange(L), [len(t.unique) for t in trees])

    def homog(a):
        return np.concatenate([a[..., :3], np.ones(a.shape[:-1] + (1,))], axis=-1)

    return _Tree(homog(root), root[:, 3].copy(), homog(group), group[..., 3].copy(),
                 homog(leaf), leaf[..., 3].copy(), homog(flat), flat[:, 3].copy(), link)


@dataclass(frozen=True, eq=False)
class RobotCollisionModel:
    """A robot's collision model (see the module docstring); build it with ``from_imported``
    or ``from_model``.

    ``names``: the links that have geometry, in the robot's order (``L``); ``pairs (P, 2)``:
    indices into ``names`` of the self-collision pairs; ``kind``: ``"imported"`` or
    ``"capsules"``; ``dof``: joints of ``q``."""

    kind: str
    names: tuple[str, ...]
    pairs: np.ndarray
    dof: int
    tree: _Tree
    source: Any
    link_index: np.ndarray          # imported: index of each link in robot.links
    capsule_radius: np.ndarray      # capsules: (L,) radii; imported: empty
    capsule_link: np.ndarray        # capsules: (L,) chain link k of each capsule
    capsule_length: np.ndarray      # capsules: (L,) largest length over the joint limits
    options: dict
    tables: tuple = ()              # PairTable per self pair checked by table
    sphere_pairs: np.ndarray | None = None  # indices into pairs checked by spheres
    attached: tuple = ()            # Attachment per carried object (names' last entries)
    attached_frame: np.ndarray | None = None  # (A,) link frame each attachment rides on
    attached_pose: np.ndarray | None = None   # (A, 4, 4) T_link_object of each
    base: Any = None                # the model without attachments (None: this one)

    def __post_init__(self):
        if self.sphere_pairs is None:
            object.__setattr__(self, "sphere_pairs", np.arange(len(self.pairs)))

    # ---- construction ----------------------------------------------------------------------
    @classmethod
    def from_imported(cls, robot: Any, n_groups: int = DEFAULT_GROUPS,
                      spheres_per_group: int = DEFAULT_SPHERES_PER_GROUP,
                      pair_tables: bool = True, table_tolerance: float = TABLE_TOLERANCE,
                      table_nodes: int = TABLE_MAX_NODES) -> RobotCollisionModel:
        """The collision model of an imported robot (duck-typed
        ``kinematics.urdf_import.ImportedRobot``: ``links`` with ``name``, ``frame`` and
        ``collision`` geometry, ``meshes``, ``adjacent_pairs``, ``disabled_pairs``,
        ``link_poses(q)`` and ``model``). Each link with geometry gets a sphere tree of
        ``n_groups`` groups of at most ``spheres_per_group`` leaves. With ``pair_tables``,
        self pairs whose frames are one or two chain joints apart are checked by a distance
        table (``planning.collision.tables``: slack ``table_tolerance`` mm, at most
        ``table_nodes`` nodes) instead of spheres."""
        for name, value in (("n_groups", n_groups), ("spheres_per_group", spheres_per_group)):
            if not isinstance(value, int) or isinstance(value, bool) or not 1 <= value <= 64:
                raise FieldError((name,), f"{name} must be a whole number from 1 to 64")
        index, trees = [], []
        for k, link in enumerate(robot.links):
            if not link.collision:
                continue
            triangles, solids = _link_geometry(link, robot.meshes)
            index.append(k)
            trees.append(cover_link(triangles, solids, n_groups, spheres_per_group))
        if not trees:
            raise FieldError(("links",), "the robot has no collision geometry")
        names = tuple(robot.links[k].name for k in index)
        skip = set(robot.adjacent_pairs) | set(robot.disabled_pairs)
        pairs = [(a, b) for a, b in combinations(range(len(names)), 2)
                 if frozenset((names[a], names[b])) not in skip]
        tree = _pad_trees(trees)
        tables, by_sphere = [], []
        shapes: dict[int, list] = {}
        triangles: dict[int, np.ndarray] = {}
        screen = _TableScreen(robot, tree, index)
        for p, (a, b) in enumerate(pairs):
            table = None
            if pair_tables:
                inner, outer = sorted((a, b), key=lambda x: robot.links[index[x]].frame)
                k = robot.links[index[outer]].frame - robot.links[index[inner]].frame
                for x in (inner, outer):
                    if k >= 1 and x not in shapes:
                        shapes[x] = _exact_shapes(robot, index[x])
                        triangles[x] = _link_triangles(robot.links[index[x]], robot.meshes)
                for sweep in _SWEEPS.get(k, ()):
                    if sweep != (False, False) and not screen.sweepable(
                            inner, outer, sweep, k, triangles):
                        continue
                    ball = (tree.root[outer, :3], float(tree.root_r[outer]))
                    table = build_pair_table(robot, index[inner], index[outer], ball,
                                             shapes[inner], shapes[outer], table_tolerance,
                                             table_nodes, a, b, p, sweep=sweep,
                                             triangles_a=triangles[inner],
                                             triangles_b=triangles[outer])
                    if table is not None and (sweep == (False, False)
                                              or screen.better(table, a, b)):
                        break
                    table = None
            if table is None:
                by_sphere.append(p)
            else:
                tables.append(table)
        return cls(kind="imported", names=names, pairs=_pair_array(pairs),
                   dof=int(robot.model.dof), tree=tree, source=robot,
                   link_index=np.array(index), capsule_radius=np.empty(0),
                   capsule_link=np.empty(0, dtype=int), capsule_length=np.empty(0),
                   options={"n_groups": n_groups, "spheres_per_group": spheres_per_group,
                            "pair_tables": pair_tables, "table_tolerance": table_tolerance,
                            "table_nodes": table_nodes},
                   tables=tuple(tables), sphere_pairs=np.array(by_sphere, dtype=np.intp))

    @classmethod
    def from_model(cls, model: Any, link_radius: float | Iterable[float] = DEFAULT_LINK_RADIUS,
                   disabled_pairs: Iterable[Iterable[str]] = ()) -> RobotCollisionModel:
        """The collision model of a D-H / PoE ``RobotModel``: a capsule per link between
        consecutive ``fk_frames`` origins, ``link_radius`` mm (one number or one per link,
        ``dof``); links ``link0`` .. ``link{dof-1}`` (link ``k`` runs from frame ``k`` to
        frame ``k + 1``). ``disabled_pairs``: further link name pairs never checked."""
        radii = _radii(model.dof, link_radius)
        lengths = _max_link_lengths(model)
        keep = [k for k in range(model.dof) if lengths[k] > 1e-9]
        if not keep:
            raise FieldError(("model",), "every link of the robot has zero length")
        names = tuple(f"link{k}" for k in keep)
        skip = {frozenset(p) for p in (tuple(x) for x in disabled_pairs)}
        pairs = []
        for a, b in combinations(range(len(keep)), 2):
            j, k = keep[a], keep[b]
            between = float(lengths[j + 1:k].sum())
            if between < radii[j] + radii[k] or frozenset((names[a], names[b])) in skip:
                continue
            pairs.append((a, b))
        trees = []
        for k in keep:
            r, L = radii[k], lengths[k]
            n = int(min(MAX_CAPSULE_SPHERES,
                        max(2, math.ceil(L / max(CAPSULE_SPACING * r, L / 1e3)) + 1)))
            trees.append(_capsule_tree(L, r, n))
        return cls(kind="capsules", names=names, pairs=_pair_array(pairs), dof=int(model.dof),
                   tree=_stack_capsules(trees), source=model,
                   link_index=np.empty(0, dtype=int), capsule_radius=radii[keep],
                   capsule_link=np.array(keep), capsule_length=lengths[keep],
                   options={"link_radius": radii.tolist()})

    # ---- attachments -------------------------------------------------------------------------
    def with_attached(self, attachments: Iterable[Any],
                      resolve_mesh: Any = None) -> RobotCollisionModel:
        """A new model carrying ``attachments`` (``planning.collision.attached``:
        ``Attachment``s or their dicts) beside the ones this model carries; this model is
        unchanged. Each is one more body, named by its object's id, in the sphere stage,
        the exact stage, the self pairs and against the scene. ``resolve_mesh``: a stored
        mesh's name -> (vertices, faces), for mesh objects given by name."""
        from .attached import attach

        return attach(self, attachments, resolve_mesh)

    def without_attached(self) -> RobotCollisionModel:
        """The model without any attachment (the one ``with_attached`` started from)."""
        return self.base if self.base is not None else self

    @property
    def n_links(self) -> int:
        """How many of ``names`` are the robot's own links (the attachments follow)."""
        return len(self.names) - len(self.attached)

    @property
    def width(self) -> int:
        """``w`` of the states ``M (B, L, 3, w)``: 4 (link frames) or 2 (capsules without
        attachments)."""
        return int(self.tree.root.shape[-1])

    def state_frames(self, q2: np.ndarray) -> np.ndarray:
        """The states as ``(B, L, 4, 4)`` (last row ``[0, 0, 0, 1]``; ``width`` 4 only):
        rigid link poses, a capsule's ``[run | 0 | 0 | start]``."""
        M = self.state(q2)
        if M.shape[-1] != 4:
            raise ValueError("state frames need states of width 4")
        out = np.zeros(M.shape[:2] + (4, 4))
        out[..., :3, :] = M
        out[..., 3, 3] = 1.0
        return out

    # ---- configurations -----------------------------------------------------------------------
    def batch(self, q) -> tuple[np.ndarray, bool]:
        """``q`` as ``(B, dof)`` float rows and whether one ``(dof,)`` was given;
        ``FieldError`` at ``("q",)`` for a wrong shape or a non-finite value."""
        q = np.asarray(q, dtype=float)
        single = q.ndim == 1
        q2 = q[None] if single else q
        if q2.ndim != 2 or q2.shape[1] != self.dof:
            raise FieldError(("q",), f"q must have shape ({self.dof},) or (N, {self.dof}), got "
                             f"{list(q.shape)}")
        if not np.all(np.isfinite(q2)):
            raise FieldError(("q",), "q must be finite")
        return q2, single

    def link_poses(self, q2: np.ndarray) -> np.ndarray:
        """World poses ``(B, L, 4, 4)`` of the links in ``names`` for ``q2 (B, dof)``; for
        capsules, a frame at the capsule's start whose z axis runs along it."""
        F = self._frames(q2)
        if self.kind == "imported":
            out = F[:, self.link_index]
        else:
            out = frames_along(*self._ends(F))
        if self.attached:
            out = np.concatenate([out, np.matmul(F[:, self.attached_frame],
                                                 self.attached_pose)], axis=1)
        return out

    def state(self, q2: np.ndarray) -> np.ndarray:
        """``M (B, L, 3, w)`` of ``q2 (B, dof)``: world sphere centres are ``M @ local``
        (an attachment's: its link's frame composed with its pose in that frame)."""
        F = self._frames(q2)
        if self.kind == "imported":
            M = F[:, self.link_index, :3, :]
        elif not self.attached:
            return np.stack(self._ends(F), axis=-1)
        else:
            A, E = self._ends(F)
            M = np.zeros(A.shape[:2] + (3, 4))
            M[..., 0], M[..., 3] = E, A
        if self.attached:
            M = np.concatenate([M, np.matmul(F[:, self.attached_frame],
                                             self.attached_pose)[..., :3, :]], axis=1)
        return M

    def _frames(self, q2: np.ndarray) -> np.ndarray:
        """The robot's frames ``(B, F, 4, 4)``: an imported robot's ``link_poses``, a D-H
        / PoE robot's ``fk_frames``."""
        if self.kind == "imported":
            return self.source.link_poses(q2)
        from kinematics.fk import fk_frames

        return fk_frames(self.source, q2)

    def _ends(self, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        P = F[..., :3, 3]
        k = self.capsule_link
        return P[:, k], P[:, k + 1] - P[:, k]

    def spheres(self, q) -> np.ndarray:
        """The leaf spheres in the world frame: ``q (dof,) -> (S, 4)`` or ``(B, dof) ->
        (B, S, 4)`` as ``[x, y, z, radius]`` mm; ``sphere_links`` names their links."""
        q2, single = self.batch(q)
        M = self.state(q2)
        t = self.tree
        C = np.einsum("bsij,sj->bsi", M[:, t.flat_link], t.flat)
        out = np.concatenate([C, np.broadcast_to(t.flat_r, C.shape[:2])[..., None]], axis=-1)
        return out[0] if single else out

    @property
    def sphere_links(self) -> tuple[str, ...]:
        """The link of each leaf sphere of ``spheres``."""
        return tuple(self.names[k] for k in self.tree.flat_link)

    # ---- description --------------------------------------------------------------------------
    def describe(self) -> dict[str, Any]:
        """JSON-ready summary: the kind, the links (their shapes, sphere count and leaf
        spheres in the link frame — for capsules, ``t`` along the capsule instead of x, y, z),
        the self-collision pairs and the attached objects (id, type, link, pose in the
        link's frame, touch links, sphere count, leaf spheres in the object's frame)."""
        t = self.tree
        tcol = 0 if self.width == 4 else 1
        links = []
        for k, name in enumerate(self.names[:self.n_links]):
            sel = t.flat_link == k
            if self.kind == "imported":
                link = self.source.links[self.link_index[k]]
                shapes = [_shape_summary(g, self.source.meshes) for g in link.collision]
                spheres = np.column_stack([t.flat[sel, :3], t.flat_r[sel]]).round(3).tolist()
            else:
                c = int(self.capsule_link[k])
                shapes = [{"type": "capsule", "radius": float(self.capsule_radius[k]),
                           "max_length": float(self.capsule_length[k]),
                           "from_frame": c, "to_frame": c + 1}]
                spheres = np.column_stack([t.flat[sel, tcol], t.flat_r[sel]]).round(6).tolist()
            links.append({"name": name, "shapes": shapes, "spheres": int(sel.sum()),
                          "sphere_centres": spheres,
                          "bounding_radius": round(float(t.root_r[k]), 3)})
        return {"kind": self.kind, "links": links,
                "self_collision_pairs": [[self.names[a], self.names[b]] for a, b in self.pairs],
                "pair_tables": [{"links": [self.names[x.a], self.names[x.b]],
                                 "joints": [int(j) for j in x.joints],
                                 "nodes": int(len(x.values)),
                                 "swept": self._swept(x),
                                 "slack": round(x.slack, 3)} for x in self.tables],
                "attached": self._describe_attached(),
                "spheres": int(len(t.flat_r)), "options": self.options}

    def mesh_triangles(self, most: int) -> Any:
        """``planning.geometry.triangles.MeshTriangles`` of the links whose geometry is all
        mesh of at most ``most`` triangles (their frames; other links and attachments have
        none), for the compiled exact stage; built once per model and limit. None for a
        model of capsules."""
        if self.kind != "imported":
            return None
        cache = self.__dict__.setdefault("_mesh_triangles", {})
        if most not in cache:
            from ..geometry.triangles import MeshTriangles

            links = []
            for k in range(len(self.names)):
                t = None
                if k < len(self.link_index):
                    t, solids = _link_geometry(self.source.links[self.link_index[k]],
                                               self.source.meshes)
                    if solids or len(t) > most:
                        t = None
                links.append(t)
            cache[most] = MeshTriangles(links)
        return cache[most]

    def _swept(self, table: Any) -> list[str]:
        """Names of the links a pair table holds turned about a joint (its inner link is
        ``"a"`` of its ``sweep``, the one nearer the base)."""
        if not table.sweep:
            return []
        frame = [self.source.links[self.link_index[x]].frame for x in (table.a, table.b)]
        inner, outer = (table.a, table.b) if frame[0] <= frame[1] else (table.b, table.a)
        return [self.names[x] for x, on in ((inner, "a" in table.sweep),
                                            (outer, "b" in table.sweep)) if on]

    def _describe_attached(self) -> list[dict[str, Any]]:
        t = self.tree
        out = []
        for i, a in enumerate(self.attached):
            sel = t.flat_link == self.n_links + i
            out.append({**a.summary(), "spheres": int(sel.sum()),
                        "sphere_centres": np.column_stack([t.flat[sel, :3], t.flat_r[sel]]
                                                          ).round(3).tolist(),
                        "bounding_radius": round(float(t.root_r[self.n_links + i]), 3)})
        return out

    # ---- persistence ----------------------------------------------------------------------------
    def to_bytes(self) -> bytes:
        """The model as bytes (an ``.npz``: its arrays, and its small fields as JSON; no
        pickle), to store next to the robot and load with ``from_bytes``. A model with
        attachments is stored as the model without them and the attachments' dicts
        (``Attachment.to_dict``: a stored mesh by name), attached again on loading."""
        if self.attached:
            return self.without_attached()._to_bytes([a.to_dict() for a in self.attached])
        return self._to_bytes([])

    def _to_bytes(self, attached: list) -> bytes:
        import io
        import json

        arrays: dict[str, np.ndarray] = {f"tree_{f}": getattr(self.tree, f)
                                         for f in _Tree.__dataclass_fields__}
        for f in _ARRAY_FIELDS:
            arrays[f] = np.asarray(getattr(self, f))
        tables = []
        for i, x in enumerate(self.tables):
            for f in ("joints", "lo", "step", "rho", "values"):
                arrays[f"table{i}_{f}"] = np.asarray(getattr(x, f))
            tables.append({"a": int(x.a), "b": int(x.b), "pair": int(x.pair),
                           "shape": [int(v) for v in x.shape], "sweep": x.sweep})
        meta = {"format": MODEL_FORMAT, "kind": self.kind, "names": list(self.names),
                "dof": int(self.dof), "options": self.options, "tables": tables,
                "fingerprint": _fingerprint(self.kind, self.source)}
        if attached:
            meta["attached"] = attached
        arrays["meta"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
        buffer = io.BytesIO()
        np.savez_compressed(buffer, **arrays)
        return buffer.getvalue()

    @classmethod
    def from_bytes(cls, data: bytes, robot: Any, resolve_mesh: Any = None
                   ) -> RobotCollisionModel:
        """A model written by ``to_bytes``, for ``robot`` (the ``ImportedRobot`` or
        ``RobotModel`` it was built from). ``ValueError`` when the bytes are not such a
        model or were built from another robot or geometry (then build it anew), or when
        its attachments cannot be attached again (a stored mesh ``resolve_mesh`` does not
        know)."""
        import io
        import json

        from .tables import PairTable

        try:
            with np.load(io.BytesIO(data), allow_pickle=False) as z:
                arrays = {k: z[k] for k in z.files}
            meta = json.loads(arrays.pop("meta").tobytes().decode())
            if meta.get("format") != MODEL_FORMAT:
                raise _FormatError(f"collision model format {meta.get('format')!r}, "
                                   f"expected {MODEL_FORMAT}")
            tree = _Tree(**{f: arrays[f"tree_{f}"] for f in _Tree.__dataclass_fields__})
            tables = tuple(
                PairTable(t["a"], t["b"], t["pair"], arrays[f"table{i}_joints"],
                          arrays[f"table{i}_lo"], arrays[f"table{i}_step"], tuple(t["shape"]),
                          arrays[f"table{i}_rho"], arrays[f"table{i}_values"],
                          t.get("sweep", ""))
                for i, t in enumerate(meta["tables"]))
            fields = {f: arrays[f] for f in _ARRAY_FIELDS}
        except _FormatError:
            raise
        except Exception as exc:  # noqa: BLE001 - zip, key, pickle or JSON errors
            raise ValueError(f"not a stored collision model: {exc}") from exc
        try:
            same = meta["fingerprint"] == _fingerprint(meta["kind"], robot)
        except (AttributeError, KeyError, TypeError) as exc:
            raise ValueError(f"the stored collision model is not one of this robot: {exc}"
                             ) from exc
        if not same:
            raise ValueError("the stored collision model was built from another robot or "
                             "other geometry")
        model = cls(kind=meta["kind"], names=tuple(meta["names"]), dof=int(meta["dof"]),
                    tree=tree, source=robot, options=meta["options"], tables=tables, **fields)
        if meta.get("attached"):
            try:
                model = model.with_attached(meta["attached"], resolve_mesh)
            except FieldError as exc:
                raise ValueError(f"the stored attachments cannot be attached again: "
                                 f"{exc.message} (at {list(exc.loc)})") from exc
        return model

    # The exact geometry holds FCL objects (built on first use), which do not pickle.
    def __getstate__(self):
        state = dict(self.__dict__)
        state.pop("_exact", None)
        state.pop("_mesh_triangles", None)
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)


# ---- helpers ------------------------------------------------------------------------------
#: Version of ``to_bytes``' layout; ``from_bytes`` refuses others.
MODEL_FORMAT = 2


class _FormatError(ValueError):
    """A stored model of another ``MODEL_FORMAT``."""


_ARRAY_FIELDS = ("pairs", "link_index", "capsule_radius", "capsule_link", "capsule_length",
                 "sphere_pairs")


def _fingerprint(kind: str, source: Any) -> str:
    """A digest of what a model is built from: an imported robot's links, their poses and
    collision geometry (mesh vertices and faces included), or a D-H / PoE model's joints
    and limits (through its frames at both limits and mid-range, rounded to 1e-6 mm)."""
    import hashlib

    h = hashlib.sha256(kind.encode())
    if kind == "imported":
        for link in source.links:
            h.update(f"{link.name}|{link.frame}|".encode())
            for g in link.collision:
                h.update(f"{g.kind}|{getattr(g, 'mesh', '')}|".encode())
                h.update(np.ascontiguousarray(g.origin, dtype=float).tobytes())
                for name in ("size", "radius", "length"):
                    value = getattr(g, name, None)
                    if value is not None:
                        h.update(np.asarray(value, dtype=float).tobytes())
                if g.kind == "mesh":
                    mesh = source.meshes[g.mesh]
                    h.update(np.ascontiguousarray(mesh.vertices, dtype=float).tobytes())
                    h.update(np.ascontiguousarray(mesh.faces, dtype=np.int64).tobytes())
        model = source.model
    else:
        model = source
    from kinematics.fk import fk_frames

    h.update(f"{model.dof}|{model.convention}".encode())
    Q = np.stack([np.asarray(model.lower, dtype=float), np.asarray(model.upper, dtype=float),
                  model.mid_configuration()])
    h.update(np.round(fk_frames(model, Q), 6).tobytes())
    if kind == "imported":
        h.update(np.round(np.asarray(source.link_poses(Q), dtype=float), 6).tobytes())
    return h.hexdigest()


#: The pair tables tried for links ``k`` chain joints apart, in order (``sweep_a, sweep_b``:
#: which link is turned about its swept joint, ``planning.collision.tables``): one or two
#: joints apart, the plain table; three, link b turned about its own joint (a wrist flange,
#: a tool), else link a about the next; four, both.
_SWEEPS = {1: ((False, False),), 2: ((False, False),), 3: ((False, True), (True, False)),
           4: ((True, True),)}
#: A link is swept only if its swept solid has at most this volume over its hull's (nearly a
#: solid of revolution about that joint); a swept table is kept only if it flags fewer of
#: ``TABLE_SCREEN_SAMPLES`` random configurations (seed ``TABLE_SCREEN_SEED``) than the
#: spheres do.
SWEEP_VOLUME_RATIO = 1.7
TABLE_SCREEN_SAMPLES = 512
TABLE_SCREEN_SEED = 20261202


class _TableScreen:
    """Whether a swept table is worth its place: random configurations within the limits,
    and the sphere stage's bound of a pair there, to compare a table with."""

    def __init__(self, robot: Any, tree: _Tree, index: list[int]) -> None:
        self.robot, self.tree, self.index = robot, tree, index
        model = robot.model
        rng = np.random.default_rng(TABLE_SCREEN_SEED)
        self.Q = rng.uniform(model.lower, model.upper, (TABLE_SCREEN_SAMPLES, model.dof))
        self._poses: np.ndarray | None = None
        self._ratio: dict[tuple[int, int], float] = {}

    def sweepable(self, inner: int, outer: int, sweep: tuple, k: int,
                  triangles: dict) -> bool:
        frame = self.robot.links[self.index[inner]].frame
        for on, x, joint in ((sweep[0], inner, frame), (sweep[1], outer, frame + k - 1)):
            if not on:
                continue
            key = (x, joint)
            if key not in self._ratio:
                self._ratio[key] = sweep_ratio(self.robot, self.index[x], joint, triangles[x])
            if self._ratio[key] > SWEEP_VOLUME_RATIO:
                return False
        return True

    def better(self, table: Any, a: int, b: int) -> bool:
        """Whether ``table`` flags fewer of the configurations than the spheres of
        collision-model links ``a`` and ``b``."""
        if self._poses is None:
            self._poses = self.robot.link_poses(self.Q)[:, self.index]
        t, P = self.tree, self._poses
        A = np.einsum("bij,sj->bsi", P[:, a, :3], t.flat[t.flat_link == a])
        C = np.einsum("bij,sj->bsi", P[:, b, :3], t.flat[t.flat_link == b])
        d = (np.linalg.norm(A[:, :, None] - C[:, None], axis=-1)
             - t.flat_r[t.flat_link == a][:, None] - t.flat_r[t.flat_link == b][None])
        spheres = int((d.reshape(len(self.Q), -1).min(axis=1) <= 0).sum())
        return int((table.lower_bound(self.Q) <= 0).sum()) < spheres


def _pair_array(pairs: list[tuple[int, int]]) -> np.ndarray:
    return np.array(pairs, dtype=np.intp).reshape(-1, 2)


def _link_geometry(link: Any, meshes: Any) -> tuple[np.ndarray, list]:
    """A link's collision geometry in its frame: mesh triangles ``(T, 3, 3)`` and the
    primitives as convex solids."""
    triangles, solids = [], []
    for g in link.collision:
        T = np.asarray(g.origin, dtype=float)
        if g.kind == "mesh":
            data = meshes[g.mesh]
            V = np.asarray(data.vertices, dtype=float) @ T[:3, :3].T + T[:3, 3]
            triangles.append(V[np.asarray(data.faces)])
        elif g.kind == "box":
            solids.append(box_solid(g.size, T))
        elif g.kind == "cylinder":
            solids.append(cylinder_solid(g.radius, g.length, T))
        elif g.kind == "sphere":
            solids.append(sphere_solid(g.radius, T))
        else:
            raise FieldError(("links", link.name, "collision"), f"unknown geometry kind "
                             f"{g.kind!r}")
    tri = np.concatenate(triangles) if triangles else np.empty((0, 3, 3))
    return tri, solids


def _link_triangles(link: Any, meshes: Any) -> np.ndarray:
    """A link's collision geometry in its frame as triangles ``(T, 3, 3)``: its meshes'
    and the hull faces of its primitives' circumscribing polytopes."""
    from scipy.spatial import ConvexHull

    tri, solids = _link_geometry(link, meshes)
    parts = [tri] + [s.vertices[ConvexHull(s.vertices).simplices] for s in solids]
    return np.concatenate(parts)


def _exact_shapes(robot: Any, k: int) -> list:
    from .exact import link_shape

    cache: dict = {}
    return [link_shape(g, robot.meshes, cache) for g in robot.links[k].collision]


def _shape_summary(g: Any, meshes: Any) -> dict[str, Any]:
    out: dict[str, Any] = {"type": g.kind, "origin": np.asarray(g.origin).round(9).tolist()}
    if g.kind == "box":
        out["size"] = list(g.size)
    elif g.kind in ("cylinder", "sphere"):
        out["radius"] = g.radius
        if g.kind == "cylinder":
            out["length"] = g.length
    else:
        out["mesh"] = g.mesh
        out["triangles"] = int(len(meshes[g.mesh].faces))
    return out


def _radii(dof: int, link_radius) -> np.ndarray:
    r = np.asarray(link_radius, dtype=float) if not isinstance(link_radius, int | float) \
        else np.full(dof, float(link_radius))
    if r.ndim == 0:
        r = np.full(dof, float(r))
    if r.shape != (dof,):
        raise FieldError(("link_radius",), f"link_radius must be one number or {dof} numbers")
    if not np.all(np.isfinite(r)) or np.any(r <= 0):
        raise FieldError(("link_radius",), "link_radius must be finite and positive")
    return r


def _max_link_lengths(model: Any, grid: int = 721) -> np.ndarray:
    """The largest length ``(dof,)`` of each link over the joint limits.

    Link ``k`` joins the origins of ``fk_frames`` entries ``k`` and ``k + 1``; its length
    depends on joint ``k`` alone (the frames before move both ends rigidly), so it is
    sampled over that joint's range on ``grid`` points. A prismatic joint's length is convex
    in the joint (the largest at an end of the range, which the grid holds); a revolute
    joint's changes at most ``L`` per radian, so the grid's largest value ``m`` bounds it by
    ``m / (1 - step / 2)``."""
    from kinematics.fk import fk_frames

    dof = model.dof
    mid = model.mid_configuration()
    Q = np.repeat(mid[None], dof * grid, axis=0)
    steps = np.zeros(dof)
    for k in range(dof):
        lo, hi = float(model.lower[k]), float(model.upper[k])
        Q[k * grid:(k + 1) * grid, k] = np.linspace(lo, hi, grid)
        steps[k] = (hi - lo) / (grid - 1)
    P = fk_frames(model, Q)[..., :3, 3].reshape(dof, grid, dof + 1, 3)
    ks = np.arange(dof)
    L = np.linalg.norm(P[ks, :, ks + 1] - P[ks, :, ks], axis=-1).max(axis=1)
    revolute = np.asarray(model.revolute, dtype=bool)
    pad = np.where(revolute, 1.0 / np.maximum(1.0 - steps / 2, 0.5), 1.0)
    return np.where(L > 1e-9, L * pad * (1 + 1e-9), 0.0)


def _capsule_tree(L: float, r: float, n: int, n_groups: int = 4) -> tuple:
    """Balls at ``t = 0 .. 1`` along a capsule of largest length ``L`` and radius ``r``:
    ``n`` leaves of radius ``sqrt(r^2 + (L / (2 (n - 1)))^2)`` (each covers the capsule up
    to half-way to its neighbours), grouped in runs, each group's ball containing its
    leaves' at any length up to ``L``."""
    rho = math.sqrt(r * r + (L / (2 * (n - 1))) ** 2) * (1 + 1e-9)
    t = np.linspace(0.0, 1.0, n)
    G = min(n_groups, n)
    runs = np.array_split(np.arange(n), G)
    groups = []
    for run in runs:
        a, b = t[run[0]], t[run[-1]]
        groups.append((0.5 * (a + b), 0.5 * (b - a) * L + rho))
    return t, rho, runs, groups, 0.5 * L + rho


def _stack_capsules(trees: list[tuple]) -> _Tree:
    L = len(trees)
    G = max(len(tr[3]) for tr in trees)
    m = max(max(len(run) for run in tr[2]) for tr in trees)
    root = np.zeros((L, 2))
    root[:, 0] = 1.0
    root[:, 1] = 0.5
    root_r = np.array([tr[4] for tr in trees])
    group = np.zeros((L, G, 2))
    group[..., 0] = 1.0
    group_r = np.zeros((L, G))
    leaf = np.zeros((L, G, m, 2))
    leaf[..., 0] = 1.0
    leaf_r = np.zeros((L, G, m))
    flat, flat_r, flat_link = [], [], []
    for k, (t, rho, runs, groups, _) in enumerate(trees):
        for g in range(G):
            gi = min(g, len(runs) - 1)
            run = runs[gi]
            group[k, g, 1], group_r[k, g] = groups[gi]
            idx = np.r_[run, np.repeat(run[:1], m - len(run))]
            leaf[k, g, :, 1] = t[idx]
            leaf_r[k, g] = rho
        flat.append(np.column_stack([np.ones(len(t)), t]))
        flat_r.append(np.full(len(t), rho))
        flat_link.append(np.full(len(t), k))
    return _Tree(root, root_r, group, group_r, leaf, leaf_r, np.vstack(flat),
                 np.concatenate(flat_r), np.concatenate(flat_link))
