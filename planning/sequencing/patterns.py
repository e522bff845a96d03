"""Drilling patterns of a tunnel face: generated (horseshoe or circular section) or imported.

Frames and units: holes are points on the face in the rig frame (that of
``kinematics.rigs.builtin_rig("tunnel_jumbo")``), mm: ``x`` = the face distance (the tunnel
axis points at the face; paper 002's Table 3 hole is at x = 9000 mm), ``y`` across (positive
to the left looking at the face), ``z`` up. A pattern is ``(N, 3)``, one row per hole.

The generator lays out what a drill-and-blast face plan has (e.g. Olofsson, *Modern Rock
Blasting*; Persson, Holmberg and Lee, *Rock Blasting and Explosives Engineering*, ch. 12):

* **contour** holes along the outline (walls and roof), ``spacing`` apart and
  ``contour_inset`` inside the outline (look-out room for the next round);
* **lifter** holes along the floor, ``lifter_spacing`` apart;
* **helper** rings: the outline shrunk by ``burden`` again and again, holes
  ``helper_spacing`` apart, while the ring stays clear of the cut;
* **cut** holes at the cut centre (``cut_height`` above the floor, on the centre line): a
  parallel four-section cut, one centre hole and four squares of four holes whose half
  diagonals double from ``cut_radius / 8`` to ``cut_radius``, each square turned 45 degrees
  from the one inside it;
* **stoping** holes on a grid ``helper_spacing`` apart filling what the rings leave between
  the innermost ring and the cut.

Every default is documented on ``FacePattern``; the defaults give 122 holes on a
10 m x 8 m horseshoe, the size of the paper's face (40 + 52 + 40 holes).

The pattern sits with the sequencers that order its holes, below everything that plans
motions over the face (``planning.drilling``, the work sites of ``planning.motion.sites``);
``planning.drilling.patterns`` is the name the drilling planners and the service use.
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .base import DUPLICATE_TOL, check_holes

__all__ = [
    "FACE_X",
    "HOLE_KINDS",
    "FacePattern",
    "HolePattern",
    "face_pattern",
    "load_holes",
    "parse_holes",
]

#: Default face distance along the tunnel axis, mm (paper 002, Table 3: x = 9000 mm).
FACE_X = 9000.0
HOLE_KINDS = ("contour", "lifter", "helper", "stoping", "cut")


@dataclass(frozen=True)
class FacePattern:
    """Parameters of a generated face (mm). ``shape``: ``"horseshoe"`` (vertical walls, a
    semicircular roof of radius ``width / 2``, flat floor; needs ``height > width / 2``) or
    ``"circular"`` (diameter ``width``; ``height`` must equal ``width``).

    ``face_x``: face distance; ``center_y``: the tunnel's centre line; ``floor_z``: floor height
    in the rig frame (the booms' mounts are about 1.5 m above the floor on a typical jumbo).
    ``spacing``: contour hole spacing; the other spacings default to multiples of it
    (``lifter_spacing = 1.4 s``, ``burden = 1.5 s``, ``helper_spacing = 1.7 s``,
    ``contour_inset = s / 4``). ``cut_height`` defaults to 0.3 of the height (where the
    floor-level lifters can still throw the cut's muck), ``cut_radius`` to 1.6 ``s``.
    """

    shape: str = "horseshoe"
    width: float = 10_000.0
    height: float = 8_000.0
    spacing: float = 500.0
    face_x: float = FACE_X
    center_y: float = 0.0
    floor_z: float = -1_500.0
    lifter_spacing: float | None = None
    burden: float | None = None
    helper_spacing: float | None = None
    contour_inset: float | None = None
    cut_height: float | None = None
    cut_radius: float | None = None

    def __post_init__(self) -> None:
        if self.shape not in ("horseshoe", "circular"):
            raise ValueError(f"shape: must be 'horseshoe' or 'circular', got {self.shape!r}")
        for name in ("width", "height", "spacing", "face_x", "center_y", "floor_z",
                     "lifter_spacing", "burden", "helper_spacing", "contour_inset",
                     "cut_height", "cut_radius"):
            v = getattr(self, name)
            if v is None:
                continue
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"{name}: must be a finite number (mm), got {v!r}")
        for name in ("width", "height", "spacing", "lifter_spacing", "burden",
                     "helper_spacing", "cut_radius"):
            v = getattr(self, name)
            if v is not None and not v > 0:
                raise ValueError(f"{name}: must be positive (mm), got {v}")
        if self.spacing < 10 * DUPLICATE_TOL:
            raise ValueError(f"spacing: must be at least {10 * DUPLICATE_TOL:g} mm")
        if self.width > 50_000 or self.height > 50_000:
            raise ValueError("width: a face is at most 50 m across")
        if self.width / self.spacing > 2_000:
            raise ValueError("spacing: too small for the face (more than 2000 holes per row)")
        if self.shape == "horseshoe" and not self.height > self.width / 2:
            raise ValueError("height: a horseshoe needs height > width / 2 (semicircular roof)")
        if self.shape == "circular" and abs(self.height - self.width) > 1e-9:
            raise ValueError("height: a circular section has height = width (the diameter)")
        if self.contour_inset is not None and not 0 <= self.contour_inset < self.spacing:
            raise ValueError("contour_inset: must be in [0, spacing)")
        if self.cut_height is not None and not 0 < self.cut_height < self.height:
            raise ValueError("cut_height: must be inside the face (0 < cut_height < height)")

    # derived values
    def value(self, name: str) -> float:
        """A spacing with its default applied (mm)."""
        s = self.spacing
        defaults = {"lifter_spacing": 1.4 * s, "burden": 1.5 * s, "helper_spacing": 1.7 * s,
                    "contour_inset": 0.25 * s, "cut_height": 0.3 * self.height,
                    "cut_radius": 1.6 * s}
        v = getattr(self, name)
        return float(defaults[name] if v is None else v)


@dataclass(frozen=True)
class HolePattern:
    """Holes of a face: ``holes (N, 3)`` mm in the rig frame, ``kinds (N,)`` one of
    ``HOLE_KINDS`` per hole, and the parameters that made it."""

    holes: np.ndarray
    kinds: tuple[str, ...]
    spec: FacePattern | None = None
    extras: dict[str, Any] = field(default_factory=dict)

    def counts(self) -> dict[str, int]:
        return {k: self.kinds.count(k) for k in HOLE_KINDS if k in self.kinds}


# ---- outline geometry (face plane coordinates u = y - center_y, v = z - floor_z) ----------
def _outline(spec: FacePattern, inset: float) -> tuple[list[np.ndarray], float]:
    """The outline shrunk by ``inset`` as a list of polyline pieces ``(K, 2)`` (u, v), sampled
    finely, and its length. Horseshoe: left wall up, roof arc, right wall down (no floor);
    circle: the whole loop from the bottom, so even sampling is mirror symmetric."""
    w, h = spec.width, spec.height
    if spec.shape == "circular":
        R = w / 2 - inset
        if R <= 0:
            return [], 0.0
        a = -math.pi / 2 + np.linspace(0, 2 * math.pi, 721)
        return [np.c_[R * np.cos(a), h / 2 + R * np.sin(a)]], 2 * math.pi * R
    R0 = w / 2
    spring = h - R0  # height of the roof's springline
    R = R0 - inset
    top_floor = inset
    if R <= 0 or spring <= top_floor:
        return [], 0.0
    arc = np.linspace(0, math.pi, 361)
    pieces = [
        np.c_[np.full(2, -R), [top_floor, spring]],  # left wall, up
        np.c_[-R * np.cos(arc), spring + R * np.sin(arc)],  # roof, left to right
        np.c_[np.full(2, R), [spring, top_floor]],  # right wall, down
    ]
    length = 2 * (spring - top_floor) + math.pi * R
    return pieces, length


def _resample(pieces: list[np.ndarray], step: float, closed: bool,
              include_ends: bool = True) -> np.ndarray:
    """Points every ~``step`` along a polyline (pieces joined), with both ends for open lines;
    the spacing is adjusted so the points are evenly spread. ``(K, 2)``."""
    P = np.vstack(pieces)
    seg = np.linalg.norm(np.diff(P, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    total = s[-1]
    if total <= 0:
        return np.zeros((0, 2))
    if closed:
        k = max(3, round(total / step))
        t = np.arange(k) * total / k
    else:
        k = max(1, round(total / step))
        t = np.linspace(0.0, total, k + 1)
        if not include_ends:
            t = t[1:-1]
    return np.c_[np.interp(t, s, P[:, 0]), np.interp(t, s, P[:, 1])]


def _inside(spec: FacePattern, uv: np.ndarray, margin: float) -> np.ndarray:
    """True where a point is at least ``margin`` inside the section. ``(K, 2) -> (K,)``."""
    u, v = uv[:, 0], uv[:, 1]
    if spec.shape == "circular":
        return np.hypot(u, v - spec.height / 2) <= spec.width / 2 - margin
    R0 = spec.width / 2
    spring = spec.height - R0
    in_walls = (np.abs(u) <= R0 - margin) & (v >= margin) & (v <= spring)
    in_roof = (v > spring) & (np.hypot(u, v - spring) <= R0 - margin)
    return in_walls | in_roof


def _cut(radius: float) -> np.ndarray:
    """Parallel four-section cut: a centre hole and four squares of four holes, half
    diagonals radius/8, /4, /2, 1, each turned 45 degrees from the last. ``(17, 2)``."""
    pts = [np.zeros((1, 2))]
    for k in range(4):
        r = radius / 2 ** (3 - k)
        a = math.pi / 4 * (k % 2) + np.arange(4) * math.pi / 2
        pts.append(np.c_[r * np.cos(a), r * np.sin(a)])
    return np.vstack(pts)


def face_pattern(spec: FacePattern | None = None, **kwargs: Any) -> HolePattern:
    """Generate a face's holes. Give a ``FacePattern`` or its fields as keywords, e.g.
    ``face_pattern(shape="horseshoe", width=10_000, height=8_000, spacing=600)``.

    Returns a ``HolePattern`` with holes ``(N, 3)`` in mm on the plane ``x = face_x`` (rig
    frame), ordered contour, lifter, helper rings (outer first), stoping, cut.
    ValueError naming the field at fault.
    """
    if spec is None:
        spec = FacePattern(**kwargs)
    elif kwargs:
        raise ValueError("spec: give a FacePattern or keywords, not both")
    s = spec.spacing
    inset = spec.value("contour_inset")
    burden = spec.value("burden")
    helper = spec.value("helper_spacing")
    cut_r = spec.value("cut_radius")
    cut_c = np.array([0.0, spec.value("cut_height")])
    uv: list[np.ndarray] = []
    kinds: list[str] = []

    def add(points: np.ndarray, kind: str) -> None:
        if len(points):
            uv.append(points)
            kinds.extend([kind] * len(points))

    pieces, _ = _outline(spec, inset)
    if spec.shape == "circular":
        contour = _resample(pieces, s, closed=True)
        # The lowest third of the circle is the invert: drilled as lifters, wider apart.
        low = contour[:, 1] < spec.height * 0.15
        add(contour[~low], "contour")
        add(_resample([contour[low]], spec.value("lifter_spacing"), closed=False)
            if low.sum() > 1 else contour[low], "lifter")
    else:
        add(_resample(pieces, s, closed=False), "contour")
        R = spec.width / 2 - inset
        floor = np.c_[np.linspace(-R, R, 2), np.full(2, inset)]
        add(_resample([floor], spec.value("lifter_spacing"), closed=False,
                      include_ends=False), "lifter")
    # helper rings: closed offsets of the outline, while clear of the cut
    ring_inset = inset + burden
    innermost = None
    while True:
        ring_pieces, length = _outline(spec, ring_inset)
        if length <= 0:
            break
        if spec.shape == "horseshoe":
            # a closed loop from the floor's midpoint, so even sampling is mirror symmetric
            R = spec.width / 2 - ring_inset
            ring_pieces = [np.c_[[0.0, -R], [ring_inset, ring_inset]], *ring_pieces,
                           np.c_[[R, 0.0], [ring_inset, ring_inset]]]
        ring = _resample(ring_pieces, helper, closed=True)
        if spec.shape == "horseshoe":
            # the floor row of a ring is left to the lifters (muck lies there): only walls
            # and roof are drilled, from half a burden up
            ring = ring[ring[:, 1] >= ring_inset + 0.5 * burden]
        clear = np.hypot(*(ring - cut_c).T) > cut_r + burden
        if not clear.all() or len(ring) < 3:
            break
        add(ring, "helper")
        innermost = ring_inset
        ring_inset += burden
    # stoping grid between the innermost ring and the cut
    inner = innermost if innermost is not None else inset
    half_w = spec.width / 2
    k_max = int(half_w // helper)
    gu = helper * np.arange(-k_max, k_max + 1)  # centred: the grid is mirror symmetric
    gv = np.arange(0.0, spec.height + 1e-9, helper)
    G = np.stack(np.meshgrid(gu, gv), axis=-1).reshape(-1, 2)
    G = G[_inside(spec, G, inner + burden)]
    G = G[np.hypot(*(G - cut_c).T) > cut_r + 0.75 * burden]
    if spec.shape == "horseshoe":
        G = G[G[:, 1] >= inset + burden]
    add(G, "stoping")
    add(cut_c + _cut(cut_r), "cut")
    UV = np.vstack(uv)
    holes = np.c_[np.full(len(UV), spec.face_x), UV[:, 0] + spec.center_y,
                  UV[:, 1] + spec.floor_z]
    holes = check_holes(holes, "holes")  # a generated pattern never has duplicates
    return HolePattern(holes, tuple(kinds), spec)


# ---- import --------------------------------------------------------------------------------
def parse_holes(text: str, fmt: str = "auto", name: str = "holes") -> np.ndarray:
    """Holes from CSV or JSON text (mm), validated by ``check_holes`` (shape, NaN, at least 2
    holes, no duplicates). ``(N, 3)``.

    CSV: one hole per line, ``x,y,z`` (an optional header line naming x, y, z in any order;
    extra columns ignored). JSON: ``[[x, y, z], ...]``, ``[{"x":..,"y":..,"z":..}, ...]`` or
    ``{"holes": ...}`` with either. ``fmt``: ``"csv"``, ``"json"`` or ``"auto"`` (JSON if the
    text starts with ``[`` or ``{``). ValueError naming the field (and line) at fault.
    """
    if fmt not in ("auto", "csv", "json"):
        raise ValueError(f"format: must be 'auto', 'csv' or 'json', got {fmt!r}")
    stripped = text.lstrip()
    if fmt == "json" or (fmt == "auto" and stripped[:1] in ("[", "{")):
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            raise ValueError(f"{name}: not valid JSON ({exc.msg}, line {exc.lineno})") from None
        return _holes_from_json(data, name)
    return _holes_from_csv(text, name)


def _holes_from_json(data: Any, name: str) -> np.ndarray:
    if isinstance(data, dict):
        if "holes" not in data:
            raise ValueError(f"{name}: a JSON object needs a 'holes' list")
        data = data["holes"]
    if not isinstance(data, list):
        raise ValueError(f"{name}: must be a list of holes")
    rows = []
    for k, h in enumerate(data):
        if isinstance(h, dict):
            missing = [c for c in "xyz" if c not in h]
            if missing:
                raise ValueError(f"{name}[{k}]: missing '{missing[0]}'")
            h = [h["x"], h["y"], h["z"]]
        if not isinstance(h, list) or len(h) != 3:
            raise ValueError(f"{name}[{k}]: must be [x, y, z] or {{x, y, z}}")
        try:
            rows.append([_number(v) for v in h])
        except (TypeError, ValueError):
            raise ValueError(f"{name}[{k}]: coordinates must be numbers (mm)") from None
    return check_holes(np.array(rows, dtype=float).reshape(-1, 3), name)


def _number(v: Any) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float, str)):
        raise TypeError
    return float(v)


def _holes_from_csv(text: str, name: str) -> np.ndarray:
    lines = [row for row in csv.reader(io.StringIO(text)) if row and any(c.strip() for c in row)]
    if not lines:
        raise ValueError(f"{name}: no holes in the CSV")
    cols = (0, 1, 2)
    header = [c.strip().lower() for c in lines[0]]
    if {"x", "y", "z"} <= set(header):
        cols = tuple(header.index(c) for c in "xyz")
        lines = lines[1:]
    rows = []
    for k, row in enumerate(lines):
        try:
            rows.append([float(row[c]) for c in cols])
        except (IndexError, ValueError):
            raise ValueError(f"{name}[{k}]: CSV row {row!r} is not x,y,z numbers (mm)") from None
    return check_holes(np.array(rows, dtype=float).reshape(-1, 3), name)


def load_holes(path: str | Path, fmt: str = "auto") -> np.ndarray:
    """Holes from a CSV or JSON file (by suffix unless ``fmt`` says). See ``parse_holes``."""
    p = Path(path)
    if fmt == "auto" and p.suffix.lower() in (".csv", ".json"):
        fmt = p.suffix.lower()[1:]
    return parse_holes(p.read_text(), fmt)
