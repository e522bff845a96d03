"""The imported robot: its chain model, its links (frames, geometry) and their world poses.

Every pose is a ``(4, 4)`` float64 array in mm; ``T_a_b`` maps frame ``b`` to frame ``a``.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property
from typing import Any, Literal

import numpy as np

from ..errors import FieldError
from ..fk import batch_of, fk_frames
from ..model import ModelError, RobotModel

__all__ = ["MeshData", "Geometry", "MimicStep", "Link", "ImportedRobot", "MESH_KEY_PATTERN",
           "axis_motion"]

#: Mesh keys are file-name safe: the service stores mesh ``k`` as a file named after ``k``.
MESH_KEY_PATTERN = r"^[A-Za-z0-9_-]{1,100}$"
#: Format tag of ``ImportedRobot.to_dict``.
FORMAT = "kinoplan.imported_robot"
FORMAT_VERSION = 1
# Largest batch of configurations handled at once by ``link_poses`` (memory of the temporaries
# is about 130 bytes per link per configuration).
_CHUNK = 4096


@dataclass(frozen=True, eq=False)
class MeshData:
    """A triangle mesh: ``vertices (V, 3)`` float64 in mm (the URDF ``<mesh scale>`` already
    applied) and ``faces (F, 3)`` int64 vertex indices, counter-clockwise seen from outside
    when the source file was."""

    vertices: np.ndarray
    faces: np.ndarray

    @property
    def triangles(self) -> int:
        return int(self.faces.shape[0])

    def same_as(self, other: MeshData) -> bool:
        """Exactly equal vertices and faces."""
        return (np.array_equal(self.vertices, other.vertices)
                and np.array_equal(self.faces, other.faces))


@dataclass(frozen=True, eq=False)
class Geometry:
    """One ``<collision>`` or ``<visual>`` shape of a link.

    ``origin`` is ``T_link_shape`` (mm). A box is centred on its origin with full side lengths
    ``size``; a cylinder has ``radius`` and ``length`` along its local z, centred; a sphere has
    ``radius``; a mesh names its data in ``ImportedRobot.meshes`` by ``mesh``. ``color`` (RGBA
    in 0..1) only for visual shapes whose URDF material gives one.
    """

    kind: Literal["box", "cylinder", "sphere", "mesh"]
    origin: np.ndarray
    size: tuple[float, float, float] = (0.0, 0.0, 0.0)
    radius: float = 0.0
    length: float = 0.0
    mesh: str | None = None
    color: tuple[float, float, float, float] | None = None

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"kind": self.kind, "origin": np.asarray(self.origin).tolist()}
        if self.kind == "box":
            out["size"] = list(self.size)
        elif self.kind == "cylinder":
            out["radius"] = self.radius
            out["length"] = self.length
        elif self.kind == "sphere":
            out["radius"] = self.radius
        else:
            out["mesh"] = self.mesh
        if self.color is not None:
            out["color"] = list(self.color)
        return out

    @classmethod
    def from_dict(cls, data: Any, path: str) -> Geometry:
        if not isinstance(data, dict):
            raise ModelError(path, "must be an object")
        kind = data.get("kind")
        if kind not in ("box", "cylinder", "sphere", "mesh"):
            raise ModelError(f"{path}.kind", f"unknown geometry kind {kind!r}")
        kwargs: dict[str, Any] = {"kind": kind, "origin": _pose(data.get("origin"),
                                                                f"{path}.origin")}
        if kind == "box":
            kwargs["size"] = tuple(_numbers(data.get("size"), 3, f"{path}.size"))
        elif kind in ("cylinder", "sphere"):
            kwargs["radius"] = _numbers([data.get("radius")], 1, f"{path}.radius")[0]
            if kind == "cylinder":
                kwargs["length"] = _numbers([data.get("length")], 1, f"{path}.length")[0]
        else:
            key = data.get("mesh")
            if not isinstance(key, str) or re.fullmatch(MESH_KEY_PATTERN, key) is None:
                raise ModelError(f"{path}.mesh", f"not a mesh key: {key!r}")
            kwargs["mesh"] = key
        if data.get("color") is not None:
            kwargs["color"] = tuple(_numbers(data["color"], 4, f"{path}.color"))
        return cls(**kwargs)


@dataclass(frozen=True, eq=False)
class MimicStep:
    """A joint off the chain that mimics a chain joint, on the way from a link's chain frame to
    the link: ``T = origin @ Motion(axis, gain * q[master] + bias)`` with ``q[master]`` the
    chain joint's value and the motion a rotation (rad) or a translation (mm) along the unit
    ``axis``. ``gain`` and ``bias`` are the URDF ``<mimic multiplier offset>`` in our units."""

    joint: str
    kind: Literal["revolute", "prismatic"]
    axis: tuple[float, float, float]
    origin: np.ndarray
    master: int
    gain: float
    bias: float

    def to_dict(self) -> dict[str, Any]:
        return {"joint": self.joint, "kind": self.kind, "axis": list(self.axis),
                "origin": np.asarray(self.origin).tolist(), "master": self.master,
                "gain": self.gain, "bias": self.bias}

    @classmethod
    def from_dict(cls, data: Any, path: str, dof: int) -> MimicStep:
        if not isinstance(data, dict):
            raise ModelError(path, "must be an object")
        kind = data.get("kind")
        if kind not in ("revolute", "prismatic"):
            raise ModelError(f"{path}.kind", f"must be 'revolute' or 'prismatic', got {kind!r}")
        master = data.get("master")
        if not isinstance(master, int) or isinstance(master, bool) or not 0 <= master < dof:
            raise ModelError(f"{path}.master", f"must be a chain joint index 0..{dof - 1}")
        joint = data.get("joint")
        if not isinstance(joint, str) or not joint:
            raise ModelError(f"{path}.joint", "must be a non-empty string")
        return cls(joint=joint, kind=kind, axis=tuple(_numbers(data.get("axis"), 3,
                                                               f"{path}.axis")),
                   origin=_pose(data.get("origin"), f"{path}.origin"), master=master,
                   gain=_numbers([data.get("gain")], 1, f"{path}.gain")[0],
                   bias=_numbers([data.get("bias")], 1, f"{path}.bias")[0])


@dataclass(frozen=True, eq=False)
class Link:
    """A URDF link riding on a chain frame.

    ``frame`` numbers the frames as ``kinematics.fk.fk_frames`` does: 0 is the model's base
    frame, ``i`` the frame after chain joint ``i`` (``i = dof``: after the last joint, which for
    an imported model, whose ``tool`` is the identity, is the tip link's pose). The link's
    world pose is ``fk_frames(model, q)[..., frame, :, :] @ offset`` — unless ``mimic`` lists
    joints off the chain that follow chain joints (gripper fingers), then it is
    ``fk_frames(...)[frame] @ step_1 @ ... @ step_k @ offset`` with each step's transform
    (``MimicStep``); ``offset`` is constant either way.
    """

    name: str
    frame: int
    offset: np.ndarray
    collision: tuple[Geometry, ...] = ()
    visual: tuple[Geometry, ...] = ()
    mimic: tuple[MimicStep, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "name": self.name, "frame": self.frame,
            "offset": np.asarray(self.offset).tolist(),
            "collision": [g.to_dict() for g in self.collision],
            "visual": [g.to_dict() for g in self.visual],
        }
        if self.mimic:
            out["mimic"] = [s.to_dict() for s in self.mimic]
        return out


@dataclass(frozen=True, eq=False)
class ImportedRobot:
    """A robot imported from URDF (``import_robot``).

    * ``model``: the chain from ``base_link`` to ``tip_link`` as a product-of-exponentials
      ``RobotModel`` (joints in chain order, URDF names; ``base`` = ``T_root_base``, so the
      world frame is the URDF root link; ``home`` = ``T_base_tip`` at q = 0; ``tool`` the
      identity): ``fk(model, q)`` is the tip link's pose.
    * ``links``: every URDF link, in document order.
    * ``adjacent_pairs``: links joined by a URDF joint, links rigidly joined (through fixed
      joints or joints held at fixed values), and the links of two rigid bodies joined by a
      moving joint.
    * ``disabled_pairs``: the SRDF's ``<disable_collisions>`` pairs.
    * ``meshes``: mesh data by key (``Geometry.mesh``).
    * ``root_link``, ``base_link``, ``tip_link``: the URDF root and the chain's ends;
      ``chain_links``: ``base_link`` then the child link of each chain joint (``dof + 1``).
    """

    model: RobotModel
    links: tuple[Link, ...]
    adjacent_pairs: frozenset[frozenset[str]]
    disabled_pairs: frozenset[frozenset[str]]
    meshes: Mapping[str, MeshData]
    root_link: str
    base_link: str
    tip_link: str
    chain_links: tuple[str, ...]

    # ---- poses ----------------------------------------------------------------------------
    @cached_property
    def link_names(self) -> tuple[str, ...]:
        return tuple(link.name for link in self.links)

    @cached_property
    def _tables(self) -> tuple[np.ndarray, np.ndarray, tuple[int, ...]]:
        frames = np.array([link.frame for link in self.links], dtype=np.intp)
        offsets = np.stack([np.asarray(link.offset, dtype=float) for link in self.links])
        moving = tuple(k for k, link in enumerate(self.links) if link.mimic)
        return frames, offsets, moving

    def link_poses(self, q) -> np.ndarray:
        """World poses of ``links`` in order (mm): ``q: (*, dof) -> (*, L, 4, 4)``, e.g.
        ``(dof,) -> (L, 4, 4)`` and ``(B, dof) -> (B, L, 4, 4)``. Joint values rad / mm."""
        q2, lead = batch_of(self.model, q)
        frames, offsets, moving = self._tables
        n_links = len(self.links)
        out = np.empty((q2.shape[0], n_links, 4, 4))
        for start in range(0, q2.shape[0], _CHUNK):
            qc = q2[start:start + _CHUNK]
            F = fk_frames(self.model, qc)  # (b, dof + 1, 4, 4)
            out[start:start + len(qc)] = F[:, frames] @ offsets
            for k in moving:
                link = self.links[k]
                T = F[:, link.frame]
                for step in link.mimic:
                    value = step.gain * qc[:, step.master] + step.bias
                    T = T @ step.origin @ axis_motion(step.kind, step.axis, value)
                out[start:start + len(qc), k] = T @ offsets[k]
        return out.reshape(lead + (n_links, 4, 4))

    def link_pose(self, name: str, q) -> np.ndarray:
        """World pose of one link by name: ``q: (*, dof) -> (*, 4, 4)``."""
        try:
            k = self.link_names.index(name)
        except ValueError:
            raise KeyError(name) from None
        return self.link_poses(q)[..., k, :, :]

    @property
    def triangles(self) -> int:
        """Triangles of all meshes (each mesh counted once)."""
        return sum(m.triangles for m in self.meshes.values())

    # ---- JSON -----------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """JSON-able description without mesh data (meshes are referred to by key; store
        them with ``mesh_to_bytes``). ``from_dict(to_dict(), meshes)`` rebuilds it exactly."""
        return {
            "format": FORMAT,
            "version": FORMAT_VERSION,
            "model": self.model.to_dict(),
            "root_link": self.root_link,
            "base_link": self.base_link,
            "tip_link": self.tip_link,
            "chain_links": list(self.chain_links),
            "links": [link.to_dict() for link in self.links],
            "adjacent_pairs": _pairs_to_list(self.adjacent_pairs),
            "disabled_pairs": _pairs_to_list(self.disabled_pairs),
            "meshes": sorted(self.meshes),
        }

    @classmethod
    def from_dict(cls, data: Any, meshes: Mapping[str, MeshData]) -> ImportedRobot:
        """Rebuild from ``to_dict()`` and the mesh data by key; ``FieldError`` (a
        ``ModelError``) naming the field at fault, or ``("meshes", key)`` for a missing mesh."""
        if not isinstance(data, dict):
            raise ModelError("robot", "must be a JSON object")
        if data.get("format") != FORMAT or data.get("version") != FORMAT_VERSION:
            raise ModelError("format", f"not a {FORMAT} version {FORMAT_VERSION} description")
        model = RobotModel.from_dict(data.get("model"))
        if model.convention != "poe":
            raise ModelError("model.convention", "an imported robot's model is 'poe'")
        links_data = data.get("links")
        if not isinstance(links_data, list) or not links_data:
            raise ModelError("links", "must be a non-empty list")
        links = []
        for k, item in enumerate(links_data):
            path = f"links[{k}]"
            if not isinstance(item, dict):
                raise ModelError(path, "must be an object")
            frame = item.get("frame")
            if not isinstance(frame, int) or isinstance(frame, bool) or not (
                    0 <= frame <= model.dof):
                raise ModelError(f"{path}.frame", f"must be an integer 0..{model.dof}")
            name = item.get("name")
            if not isinstance(name, str) or not name:
                raise ModelError(f"{path}.name", "must be a non-empty string")
            links.append(Link(
                name=name, frame=frame, offset=_pose(item.get("offset"), f"{path}.offset"),
                collision=tuple(Geometry.from_dict(g, f"{path}.collision[{i}]")
                                for i, g in enumerate(_list(item, "collision", path))),
                visual=tuple(Geometry.from_dict(g, f"{path}.visual[{i}]")
                             for i, g in enumerate(_list(item, "visual", path))),
                mimic=tuple(MimicStep.from_dict(s, f"{path}.mimic[{i}]", model.dof)
                            for i, s in enumerate(_list(item, "mimic", path))),
            ))
        names = {link.name for link in links}
        if len(names) != len(links):
            raise ModelError("links", "link names must be unique")
        keys = _list(data, "meshes", "")
        used = {g.mesh for link in links for g in (*link.collision, *link.visual)
                if g.kind == "mesh"}
        for key in sorted(used | set(keys)):
            if key not in meshes:
                raise FieldError(("meshes", key), f"mesh {key!r} is missing")
        chain_links = tuple(_list(data, "chain_links", ""))
        if len(chain_links) != model.dof + 1 or not set(chain_links) <= names:
            raise ModelError("chain_links", f"must name {model.dof + 1} links of the robot")
        for key in ("root_link", "base_link", "tip_link"):
            if data.get(key) not in names:
                raise ModelError(key, "must name a link of the robot")
        return cls(
            model=model, links=tuple(links),
            adjacent_pairs=_pairs_from_list(data.get("adjacent_pairs"), "adjacent_pairs",
                                            names),
            disabled_pairs=_pairs_from_list(data.get("disabled_pairs"), "disabled_pairs",
                                            names),
            meshes={key: meshes[key] for key in sorted(used | set(keys))},
            root_link=data["root_link"], base_link=data["base_link"],
            tip_link=data["tip_link"], chain_links=chain_links,
        )


def axis_motion(kind: str, axis, value: np.ndarray) -> np.ndarray:
    """A joint's motion for values ``(N,)`` -> ``(N, 4, 4)``: rotation by ``value`` rad about
    the unit ``axis`` through the origin (``kind == "revolute"``) or translation by ``value``
    mm along it."""
    value = np.asarray(value, dtype=float)
    a = np.asarray(axis, dtype=float)
    T = np.zeros(value.shape + (4, 4))
    T[..., 3, 3] = 1.0
    if kind == "prismatic":
        T[..., 0, 0] = T[..., 1, 1] = T[..., 2, 2] = 1.0
        T[..., :3, 3] = value[..., None] * a
        return T
    K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    s = np.sin(value)[..., None, None]
    c = np.cos(value)[..., None, None]
    T[..., :3, :3] = np.eye(3) + s * K + (1.0 - c) * (K @ K)
    return T


# ---- JSON helpers ------------------------------------------------------------------------
def _pairs_to_list(pairs: frozenset[frozenset[str]]) -> list[list[str]]:
    return sorted(sorted(p) for p in pairs)


def _pairs_from_list(value: Any, path: str, names: set[str]) -> frozenset[frozenset[str]]:
    if not isinstance(value, list):
        raise ModelError(path, "must be a list of [link, link] pairs")
    out = set()
    for k, pair in enumerate(value):
        if (not isinstance(pair, list) or len(pair) != 2 or not set(pair) <= names
                or pair[0] == pair[1]):
            raise ModelError(f"{path}[{k}]", "must be two different links of the robot")
        out.add(frozenset(pair))
    return frozenset(out)


def _list(data: dict, key: str, path: str) -> list:
    value = data.get(key, [])
    if not isinstance(value, list):
        raise ModelError(f"{path}.{key}" if path else key, "must be a list")
    return value


def _numbers(value: Any, n: int, path: str) -> list[float]:
    if not isinstance(value, list | tuple) or len(value) != n:
        raise ModelError(path, f"must be {n} numbers")
    out = []
    for v in value:
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            raise ModelError(path, f"must be {n} finite numbers")
        out.append(float(v))
    return out


def _pose(value: Any, path: str) -> np.ndarray:
    try:
        T = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ModelError(path, "must be a 4x4 list of numbers") from None
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise ModelError(path, "must be a 4x4 list of finite numbers")
    T.setflags(write=False)
    return T

