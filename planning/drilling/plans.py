"""Drill plans in and out: IREDES ``DRPPlan`` files, CSV and JSON.

A ``DrillPlan`` is a face's holes (collar and toe, mm, in the plan's site frame) with the
plan's coordinate system (the IREDES ``Coordsystem``: a name and a 4x4 ``TMatrix``,
translation in mm). Readers:

* ``read_iredes(text)``: the IREDES DrillRig profile's drill plan (``DRPPlan``), elements
  matched by local name (any namespace prefix), unknown elements ignored, the file's
  ``IR:ChkSum`` (CRC32, decimal, of the file as written with ``0`` in place of the value)
  verified, coordinates read in metres and held in mm, ``DrillBitDia`` in mm;
* ``read_csv(text)``: a header row, then one hole a row (columns in ``CSV_COLUMNS``, mm);
* ``read_json(obj)``: the form ``DrillPlan.to_json()`` writes.

Writers: ``write_iredes(plan)`` (optionally with each hole's boom, order and times in its
``HoleOptions``), ``to_csv(plan)``, ``DrillPlan.to_json()``. Reading what a writer wrote
gives the same plan.

Every reader raises ``PlanFormatError`` (a ``FieldError``, so a ``ValueError``) naming
where the input is wrong: an element path with the hole by its ``HoleId``
(``("DrillPlan", "Hole[17]", "EndPoint", "PointY")``), a CSV row (line of the file, the
header being row 1) and column (``("row", 5, "toe_z")``), or a JSON field
(``("holes", 3, "collar")``). Hostile XML is refused as the URDF reader refuses it (no
DOCTYPE or entities; size, depth and element caps), with the same guarded parser.
"""

from __future__ import annotations

import csv
import io
import math
import re
import xml.etree.ElementTree as ET
import zlib
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from datetime import datetime
from typing import Any
from xml.etree.ElementTree import Element
from xml.sax.saxutils import escape

import numpy as np

from kinematics.errors import FieldError, Loc

__all__ = [
    "Hole",
    "DrillPlan",
    "PlanFormatError",
    "PlanTooLargeError",
    "read_iredes",
    "read_iredes_with_assignments",
    "write_iredes",
    "read_csv",
    "to_csv",
    "read_json",
    "iredes_checksum",
    "CSV_COLUMNS",
    "ASSIGNMENT_FIELDS",
    "ASSIGNMENT_NAMESPACE",
    "MAX_HOLES",
    "MAX_PLAN_BYTES",
    "MAX_COORDINATE_MM",
    "MAX_DIAMETER_MM",
]

#: Most holes a plan may hold (a tunnel round has 50-200, a large bench pattern a few
#: thousand); more is a ``PlanTooLargeError``.
MAX_HOLES = 5_000
#: Largest IREDES, CSV or JSON text read (an 83-hole round is 45 kB as IREDES).
MAX_PLAN_BYTES = 8 * 1024 * 1024
#: Deepest element nesting of an IREDES file (the drill plan nests 6 deep).
MAX_XML_DEPTH = 32
#: Most elements of an IREDES file (about 20 a hole).
MAX_XML_ELEMENTS = 400_000
#: Largest coordinate magnitude, mm (10^9 km: any site or map grid is far inside).
MAX_COORDINATE_MM = 1e12
#: Largest drill bit diameter, mm.
MAX_DIAMETER_MM = 5_000.0
#: Largest deviation of the plan frame's rotation from a rotation (|R^T R - I|, element-wise),
#: so that a matrix written with 3 decimals (``1.000``, ``0.052``) still reads.
_ROTATION_TOL = 5e-3

#: CSV columns: id and the collar and toe coordinates (mm) are required; name, type and
#: diameter_mm optional (empty cells: name "", type "", no diameter).
CSV_COLUMNS = ("id", "name", "collar_x", "collar_y", "collar_z", "toe_x", "toe_y", "toe_z",
               "type", "diameter_mm")
_CSV_REQUIRED = ("id", "collar_x", "collar_y", "collar_z", "toe_x", "toe_y", "toe_z")

#: What a hole's assignment may say, and the element each is written as inside the hole's
#: ``HoleOptions`` (``<kp:Assignment>`` in the namespace ``ASSIGNMENT_NAMESPACE``).
ASSIGNMENT_FIELDS = {"boom": "Boom", "order": "Order", "start_s": "StartS", "end_s": "EndS"}
ASSIGNMENT_NAMESPACE = "urn:kinoplan:drill-plan:assignment:1"
_ASSIGNMENT_PREFIX = "kp"

_IR_NAMESPACE = "http://www.iredes.org/xml"
_DRILLRIG_NAMESPACE = "http://www.iredes.org/xml/DrillRig"
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
_CHKSUM = re.compile(rb"<((?:[A-Za-z_][\w.\-]*:)?ChkSum)(\s[^>]*)?>([^<]*)</\1\s*>")
_CONTROL = re.compile(r"[\x00-\x1f\x7f\ufffe\uffff]")


class PlanFormatError(FieldError):
    """A drill plan input that cannot be read: ``loc`` says where (an element path, a CSV
    row and column, or a JSON field), ``message`` what is wrong. ``hole_id``, ``row`` and
    ``column`` repeat the hole, CSV row and CSV column when there is one."""

    def __init__(self, loc: str | Iterable[str | int], message: str, *,
                 hole_id: str | None = None, row: int | None = None,
                 column: str | None = None):
        super().__init__(loc, message)
        self.hole_id = hole_id
        self.row = row
        self.column = column


class PlanTooLargeError(PlanFormatError):
    """A plan over ``MAX_HOLES`` holes or ``MAX_PLAN_BYTES`` bytes (the service answers 413)."""


# ---- the plan ----------------------------------------------------------------------------
def _vector(value: Any, what: str) -> np.ndarray:
    """``value`` as a read-only float64 (3,) array held to 1e-6 mm; ValueError saying why
    not. (Plain floats first: a plan's thousands of points are built one by one.)"""
    try:
        values = [float(v) for v in value]
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be 3 numbers (x, y, z in mm)") from None
    if len(values) != 3:
        raise ValueError(f"{what} must be 3 numbers (x, y, z in mm), got {len(values)}")
    for v in values:
        if not (math.isfinite(v) and abs(v) <= MAX_COORDINATE_MM):
            raise ValueError(f"{what} must be finite and within ±{MAX_COORDINATE_MM:.0e} mm")
    arr = np.array([round(v, 6) + 0.0 for v in values])  # + 0.0: no -0.0
    arr.setflags(write=False)
    return arr


def _check_frame(value: Any, what: str = "frame") -> np.ndarray:
    """``value`` as a read-only (4, 4) float64 rigid transform; ValueError saying why not."""
    T = np.array(value, dtype=np.float64)
    if T.shape != (4, 4):
        raise ValueError(f"{what} must be a 4x4 matrix, got shape {T.shape}")
    if not np.all(np.isfinite(T)):
        raise ValueError(f"{what} must hold finite numbers")
    if np.any(np.abs(T[3] - (0.0, 0.0, 0.0, 1.0)) > 1e-9):
        raise ValueError(f"{what}: the last row must be 0 0 0 1, got {T[3].tolist()}")
    R = T[:3, :3]
    if (np.max(np.abs(R.T @ R - np.eye(3))) > _ROTATION_TOL or np.linalg.det(R) <= 0):
        raise ValueError(f"{what}: the upper-left 3x3 block must be a rotation (orthonormal, "
                         f"determinant +1, to within {_ROTATION_TOL})")
    if np.any(np.abs(T[:3, 3]) > MAX_COORDINATE_MM):
        raise ValueError(f"{what}: the translation must be within ±{MAX_COORDINATE_MM:.0e} mm")
    T[:3, 3] = np.round(T[:3, 3], 6) + 0.0  # held to 1e-6 mm, as hole coordinates are
    T.setflags(write=False)
    return T


def _check_text(value: Any, what: str, *, empty: bool = True) -> str:
    if not isinstance(value, str):
        raise ValueError(f"{what} must be a string")
    if _CONTROL.search(value):
        raise ValueError(f"{what} must not hold control characters")
    if value != value.strip():
        raise ValueError(f"{what} must not start or end with white space")
    if not empty and not value:
        raise ValueError(f"{what} must not be empty")
    if len(value) > 200:
        raise ValueError(f"{what} is longer than 200 characters")
    return value


@dataclass(frozen=True)
class Hole:
    """One planned hole: ``collar`` (start) and ``toe`` (end), mm, in the plan's site frame;
    ``type`` as the file names it (``Contour``, ``Cut``, ...; "" if none) and the bit
    diameter (mm, None if not given). The arrays are float64 and read-only; coordinates and
    diameter are held to 1e-6 mm, so that what a writer writes reads back identical.
    ``ValueError`` for a zero depth (collar = toe), non-finite or huge coordinates, a
    diameter outside (0, ``MAX_DIAMETER_MM``], an empty id, or text with control
    characters or white space at either end."""

    id: str
    name: str
    collar: np.ndarray
    toe: np.ndarray
    type: str = ""
    diameter_mm: float | None = None

    def __post_init__(self) -> None:
        _check_text(self.id, "id", empty=False)
        _check_text(self.name, "name")
        _check_text(self.type, "type")
        collar = _vector(self.collar, "collar")
        toe = _vector(self.toe, "toe")
        object.__setattr__(self, "collar", collar)
        object.__setattr__(self, "toe", toe)
        if not math.dist(collar.tolist(), toe.tolist()) > 0.0:
            raise ValueError(f"hole '{self.id}' has zero depth: its collar and toe coincide")
        if self.diameter_mm is not None:
            d = self.diameter_mm
            if isinstance(d, bool) or not isinstance(d, int | float | np.floating):
                raise ValueError("diameter_mm must be a number or None")
            if not (math.isfinite(d) and 0.0 < d <= MAX_DIAMETER_MM):
                raise ValueError(f"diameter_mm must be in (0, {MAX_DIAMETER_MM:g}] mm, got {d}")
            object.__setattr__(self, "diameter_mm", round(float(d), 6))

    @property
    def depth_mm(self) -> float:
        """Length of the hole, collar to toe (mm)."""
        return float(np.linalg.norm(self.toe - self.collar))

    @property
    def axis(self) -> np.ndarray:
        """Unit vector from the collar to the toe (the drilling direction)."""
        return (self.toe - self.collar) / self.depth_mm

    def to_json(self) -> dict[str, Any]:
        return {"id": self.id, "name": self.name, "collar": self.collar.tolist(),
                "toe": self.toe.tolist(), "type": self.type, "diameter_mm": self.diameter_mm}

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Hole):
            return NotImplemented
        return (self.id == other.id and self.name == other.name and self.type == other.type
                and self.diameter_mm == other.diameter_mm
                and np.array_equal(self.collar, other.collar)
                and np.array_equal(self.toe, other.toe))

    def __hash__(self) -> int:
        return hash((self.id, self.collar.tobytes(), self.toe.tobytes()))


@dataclass(frozen=True)
class DrillPlan:
    """A drill plan: its id and name, its coordinate system (``frame``: the IREDES
    ``Coordsystem`` ``TMatrix``, translation in mm; ``frame_name``) and its holes, in file
    order, with distinct ids. Coordinates are mm in the plan's site frame."""

    plan_id: str
    name: str
    frame: np.ndarray
    frame_name: str
    holes: tuple[Hole, ...]

    def __post_init__(self) -> None:
        _check_text(self.plan_id, "plan_id", empty=False)
        _check_text(self.name, "name")
        _check_text(self.frame_name, "frame_name")
        object.__setattr__(self, "frame", _check_frame(self.frame))
        holes = tuple(self.holes)
        if not all(isinstance(h, Hole) for h in holes):
            raise ValueError("holes must be Hole objects")
        seen: set[str] = set()
        for h in holes:
            if h.id in seen:
                raise ValueError(f"hole id '{h.id}' is used twice")
            seen.add(h.id)
        object.__setattr__(self, "holes", holes)

    def __len__(self) -> int:
        return len(self.holes)

    def collars(self) -> np.ndarray:
        """(N, 3) collars, mm."""
        return np.array([h.collar for h in self.holes], dtype=np.float64).reshape(-1, 3)

    def toes(self) -> np.ndarray:
        """(N, 3) toes, mm."""
        return np.array([h.toe for h in self.holes], dtype=np.float64).reshape(-1, 3)

    def axes(self) -> np.ndarray:
        """(N, 3) unit drilling directions, collar to toe."""
        d = self.toes() - self.collars()
        return d / np.linalg.norm(d, axis=1, keepdims=True)

    def depths(self) -> np.ndarray:
        """(N,) hole lengths, mm."""
        return np.linalg.norm(self.toes() - self.collars(), axis=1)

    def ids(self) -> list[str]:
        return [h.id for h in self.holes]

    def to_json(self) -> dict[str, Any]:
        """``{"plan_id", "name", "frame_name", "frame": 4x4, "holes": [{"id", "name",
        "collar", "toe", "type", "diameter_mm"}]}``, mm; ``read_json`` reads it back."""
        return {"plan_id": self.plan_id, "name": self.name, "frame_name": self.frame_name,
                "frame": self.frame.tolist(), "holes": [h.to_json() for h in self.holes]}

    def in_frame(self, T: Any, frame_name: str | None = None) -> DrillPlan:
        """The same holes in the coordinates of another frame, ``T`` being that frame's pose
        (4x4, mm) in this plan's coordinates: each point ``p`` becomes ``T^-1 p``. ``frame``
        becomes ``frame @ T``, so that it maps the new coordinates where it mapped the old
        ones. E.g. with ``T`` the rig's pose in the site frame, the holes in the rig's frame.
        ``frame_name``: the new frame's name (default: unchanged)."""
        T = _check_frame(T, "T")
        R, t = T[:3, :3], T[:3, 3]
        # Exact rigid inverse: p' = R^T (p - t), batch axis first.
        collars = (self.collars() - t) @ R
        toes = (self.toes() - t) @ R
        holes = tuple(Hole(h.id, h.name, c, e, h.type, h.diameter_mm)
                      for h, c, e in zip(self.holes, collars, toes))
        return DrillPlan(self.plan_id, self.name, self.frame @ T,
                         self.frame_name if frame_name is None else frame_name, holes)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, DrillPlan):
            return NotImplemented
        return (self.plan_id == other.plan_id and self.name == other.name
                and self.frame_name == other.frame_name
                and np.array_equal(self.frame, other.frame) and self.holes == other.holes)

    def __hash__(self) -> int:
        return hash((self.plan_id, self.frame.tobytes(), self.holes))


# ---- IREDES: reading ---------------------------------------------------------------------
def _local(tag: str) -> str:
    """An element's local name: ``{http://www.iredes.org/xml}PointX`` -> ``PointX``."""
    return tag.rpartition("}")[2]


def _children(element: Element, name: str) -> list[Element]:
    return [c for c in element if _local(c.tag) == name]


def _child(element: Element, names: str | tuple[str, ...], loc: Loc,
           required: bool = True) -> Element | None:
    """The one child of ``element`` with local name ``name`` (or one of ``names``)."""
    names = (names,) if isinstance(names, str) else names
    found = [c for c in element if _local(c.tag) in names]
    if len(found) > 1:
        raise PlanFormatError((*loc, names[0]), f"<{names[0]}> appears {len(found)} times in "
                              f"<{loc[-1] if loc else 'DRPPlan'}>; one is allowed")
    if not found:
        if required:
            raise PlanFormatError((*loc, names[0]), f"<{names[0]}> is missing in "
                                  f"<{loc[-1] if loc else 'DRPPlan'}>")
        return None
    return found[0]


def _text(element: Element) -> str:
    return (element.text or "").strip()


def _number(text: str, loc: Loc, what: str, **where: Any) -> float:
    if not _NUMBER.fullmatch(text):
        raise PlanFormatError(loc, f"{what} must be a number, got {text!r}", **where)
    value = float(text)
    if not math.isfinite(value):
        raise PlanFormatError(loc, f"{what} must be finite, got {text!r}", **where)
    return value


def _mm(metres: float) -> float:
    """Metres read from a file as mm, rounded to 1e-6 mm so that ``-3.536`` is -3536.0."""
    return round(metres * 1000.0, 6)


def _point(element: Element, loc: Loc, northing_in_x: bool, hole_id: str) -> np.ndarray:
    xyz = []
    for axis in ("PointX", "PointY", "PointZ"):
        e = _child(element, axis, loc)
        xyz.append(_mm(_number(_text(e), (*loc, axis), f"{loc[-1]}/{axis} of hole "
                               f"'{hole_id}'", hole_id=hole_id)))
    if northing_in_x:
        xyz[0], xyz[1] = xyz[1], xyz[0]
    return np.array(xyz)


def _tmatrix(element: Element, loc: Loc, northing_in_x: bool) -> np.ndarray:
    cols = _children(element, "Col")
    if len(cols) != 4:
        raise PlanFormatError(loc, f"<TMatrix> must hold 4 <Col> columns, it holds {len(cols)}")
    T = np.zeros((4, 4))
    for j, col in enumerate(cols):
        for i, name in enumerate("xyzw"):
            e = _child(col, name, (*loc, f"Col[{j + 1}]"))
            T[i, j] = _number(_text(e), (*loc, f"Col[{j + 1}]", name),
                              f"TMatrix column {j + 1} '{name}'")
    T[:3, 3] = [_mm(v) for v in T[:3, 3]]
    if northing_in_x:
        P = np.eye(4)[[1, 0, 2, 3]]
        T = P @ T @ P
    try:
        return _check_frame(T, "TMatrix")
    except ValueError as exc:
        raise PlanFormatError(loc, str(exc)) from None


def _to_bytes(text: str | bytes) -> bytes:
    """The file's bytes: as given, or ``text`` encoded as its XML declaration says (UTF-8
    by default). Pass bytes to verify the checksum of a file whose text was changed on the
    way (line endings normalised by a text-mode read, for one)."""
    if isinstance(text, bytes | bytearray | memoryview):
        return bytes(text)
    if not isinstance(text, str):
        raise PlanFormatError((), f"an IREDES plan is text or bytes, got {type(text).__name__}")
    match = re.match(r"\s*<\?xml[^>]*encoding=[\"']([A-Za-z0-9._-]+)[\"']", text)
    encoding = match.group(1) if match else "utf-8"
    try:
        return text.encode(encoding)
    except (LookupError, UnicodeEncodeError):
        return text.encode("utf-8")


def iredes_checksum(data: str | bytes) -> int:
    """The IREDES checksum of a file: CRC32 of its bytes as written with ``0`` in place of
    the value of its (last) ``ChkSum`` element. ``PlanFormatError`` if it has none."""
    raw = _to_bytes(data)
    matches = list(_CHKSUM.finditer(raw))
    if not matches:
        raise PlanFormatError(("GenTrailer", "ChkSum"), "the file has no <IR:ChkSum> element")
    m = matches[-1]
    return zlib.crc32(raw[:m.start(3)] + b"0" + raw[m.end(3):])


def _verify_checksum(raw: bytes, trailer: Element | None) -> None:
    loc = ("GenTrailer", "ChkSum")
    element = None if trailer is None else _child(trailer, "ChkSum", ("GenTrailer",),
                                                  required=False)
    if element is None:
        raise PlanFormatError(loc, "the file has no <IR:GenTrailer>/<IR:ChkSum>: it cannot be "
                              "verified (with verify_checksum false it is read unverified)")
    written = _text(element)
    if not re.fullmatch(r"\d{1,10}", written):
        raise PlanFormatError(loc, f"IR:ChkSum must be a CRC32 as a decimal number, got "
                              f"{written!r}")
    computed = iredes_checksum(raw)
    if int(written) != computed:
        raise PlanFormatError(loc, f"IR:ChkSum {written} does not match the file's CRC32 "
                              f"{computed} (computed with 0 in place of the checksum): the "
                              "file was changed or damaged after it was written (with "
                              "verify_checksum false it is read anyway)")


def _assignment(options: Element | None, loc: Loc, hole_id: str) -> dict[str, Any] | None:
    if options is None:
        return None
    found = _children(options, "Assignment")
    if not found:
        return None
    out: dict[str, Any] = {}
    for key, tag in ASSIGNMENT_FIELDS.items():
        e = _child(found[0], tag, (*loc, "HoleOptions", "Assignment"), required=False)
        if e is None:
            continue
        text = _text(e)
        where = (*loc, "HoleOptions", "Assignment", tag)
        if key == "boom":
            out[key] = text
        elif key == "order":
            if not re.fullmatch(r"[+-]?\d{1,9}", text):
                raise PlanFormatError(where, f"Order of hole '{hole_id}' must be an integer, "
                                      f"got {text!r}", hole_id=hole_id)
            out[key] = int(text)
        else:
            out[key] = _number(text, where, f"{tag} of hole '{hole_id}'", hole_id=hole_id)
    return out


def _parse(raw: bytes) -> Element:
    """The element tree of ``raw`` with its text. The URDF reader's guarded parser goes
    first (it refuses a DOCTYPE and with it every entity declaration, and caps the size,
    the nesting depth and the element count); the tree with its text is then built by the
    standard library's expat parser, which meets nothing but plain elements, character
    references and the five predefined entities. Its tags are ``{namespace}name``."""
    # Imported here: the URDF import package costs ~0.1 s, paid by the first plan read.
    from kinematics.urdf_import._xml import parse_xml

    try:
        parse_xml(raw, (), what="the IREDES plan", max_bytes=MAX_PLAN_BYTES,
                  max_depth=MAX_XML_DEPTH, max_elements=MAX_XML_ELEMENTS)
    except FieldError as exc:
        cls = PlanTooLargeError if len(raw) > MAX_PLAN_BYTES else PlanFormatError
        raise cls(exc.loc, exc.message) from None
    parser = ET.XMLParser()
    try:
        parser.feed(raw)
        return parser.close()
    except ET.ParseError as exc:  # an unbound namespace prefix, say
        raise PlanFormatError((), f"the IREDES plan is not well-formed XML: {exc}") from None


def read_iredes_with_assignments(text: str | bytes, *, verify_checksum: bool = True,
                                 northing_in_x: bool = False
                                 ) -> tuple[DrillPlan, dict[str, dict[str, Any]]]:
    """``read_iredes``, and the per-hole assignments ``write_iredes`` wrote into the holes'
    ``HoleOptions`` (``{hole_id: {"boom", "order", "start_s", "end_s"}}``, only the holes
    that have one)."""
    raw = _to_bytes(text)
    root = _parse(raw)
    if _local(root.tag) != "DRPPlan":
        raise PlanFormatError((_local(root.tag),), f"the root element is <{_local(root.tag)}>; an "
                              "IREDES drill plan is a <DRPPlan>")
    if verify_checksum:
        _verify_checksum(raw, _child(root, "GenTrailer", (), required=False))

    plan_id = _text(_child(root, "PlanId", ()))
    if not plan_id:
        raise PlanFormatError(("PlanId",), "<IR:PlanId> is empty")
    name_el = _child(root, "PlanName", (), required=False)
    name = "" if name_el is None else _text(name_el)

    frame, frame_name = np.eye(4), ""
    pos = _child(root, "DrillPosPlan", (), required=False)
    if pos is not None:
        data = _child(pos, "PositionData", ("DrillPosPlan",), required=False)
        if data is not None:
            loc: Loc = ("DrillPosPlan", "PositionData")
            csys = _child(data, ("Coordsystem", "CoordSystem"), loc, required=False)
            if csys is not None:
                loc = (*loc, "Coordsystem")
                name_el = _child(csys, "CoordSysName", loc, required=False)
                frame_name = "" if name_el is None else _text(name_el)
                matrix = _child(csys, "TMatrix", loc, required=False)
                if matrix is not None:
                    frame = _tmatrix(matrix, (*loc, "TMatrix"), northing_in_x)

    drill = _child(root, "DrillPlan", ())
    elements = _children(drill, "Hole")
    if len(elements) > MAX_HOLES:
        raise PlanTooLargeError(("DrillPlan",), f"the plan has {len(elements):,} holes; at "
                                f"most {MAX_HOLES:,} are read")
    count_el = _child(drill, "NumberOfHoles", ("DrillPlan",), required=False)
    if count_el is not None:
        count = _text(count_el)
        if not re.fullmatch(r"\d{1,9}", count) or int(count) != len(elements):
            raise PlanFormatError(("DrillPlan", "NumberOfHoles"), f"NumberOfHoles says "
                                  f"{count!r} but the plan holds {len(elements)} <Hole> "
                                  "elements")

    holes: list[Hole] = []
    assignments: dict[str, dict[str, Any]] = {}
    seen: dict[str, int] = {}
    for k, element in enumerate(elements):
        id_el = _child(element, "HoleId", ("DrillPlan", f"Hole#{k + 1}"))
        hole_id = _text(id_el)
        if not hole_id:
            raise PlanFormatError(("DrillPlan", f"Hole#{k + 1}", "HoleId"),
                                  f"the HoleId of hole number {k + 1} is empty")
        loc = ("DrillPlan", f"Hole[{hole_id}]")
        if hole_id in seen:
            raise PlanFormatError((*loc, "HoleId"), f"HoleId '{hole_id}' is used by holes "
                                  f"number {seen[hole_id] + 1} and {k + 1}", hole_id=hole_id)
        seen[hole_id] = k
        name_el = _child(element, "HoleName", loc, required=False)
        collar = _point(_child(element, "StartPoint", loc), (*loc, "StartPoint"),
                        northing_in_x, hole_id)
        toe = _point(_child(element, "EndPoint", loc), (*loc, "EndPoint"), northing_in_x,
                     hole_id)
        type_el = _child(element, "TypeOfHole", loc, required=False)
        dia_el = _child(element, "DrillBitDia", loc, required=False)
        diameter = None
        if dia_el is not None and _text(dia_el):
            diameter = _number(_text(dia_el), (*loc, "DrillBitDia"),
                               f"DrillBitDia of hole '{hole_id}'", hole_id=hole_id)
        holes.append(_make_hole(hole_id, "" if name_el is None else _text(name_el), collar,
                                toe, "" if type_el is None else _text(type_el), diameter, loc,
                                _IREDES_FIELDS))
        found = _assignment(_child(element, "HoleOptions", loc, required=False), loc, hole_id)
        if found is not None:
            assignments[hole_id] = found
    return _make_plan(plan_id, name, frame, frame_name, holes, ()), assignments


def read_iredes(text: str | bytes, *, verify_checksum: bool = True,
                northing_in_x: bool = False) -> DrillPlan:
    """An IREDES drill plan (``DRPPlan``) as a ``DrillPlan`` (mm).

    ``text``: the file's bytes (best: the checksum covers them exactly) or its text.
    ``verify_checksum``: compare ``IR:GenTrailer/IR:ChkSum`` with the CRC32 of the file (a
    ``PlanFormatError`` at ``("GenTrailer", "ChkSum")`` when it differs or is missing).
    ``northing_in_x``: the file puts northing in ``PointX`` and easting in ``PointY``
    (some vendors do): x and y are swapped on reading, in the points and in the
    ``TMatrix``. Elements are matched by local name whatever their namespace prefix;
    unknown elements are ignored (the element list: docs/drilling.md, "Drill plans")."""
    return read_iredes_with_assignments(text, verify_checksum=verify_checksum,
                                        northing_in_x=northing_in_x)[0]


#: Where a hole's fields sit in an IREDES hole element.
_IREDES_FIELDS = {"diameter_mm": "DrillBitDia", "collar": "StartPoint", "toe": "EndPoint",
                  "name": "HoleName", "type": "TypeOfHole", "id": "HoleId"}


def _make_hole(hole_id: str, name: str, collar: Any, toe: Any, type_: str,
               diameter: float | None, loc: Loc, fields: Mapping[str, str] | None = None,
               **where: Any) -> Hole:
    """A ``Hole``; its construction's ValueError as a ``PlanFormatError`` naming the hole,
    at ``loc`` plus the field at fault (renamed by ``fields``; none for a zero depth)."""
    try:
        return Hole(hole_id, name, collar, toe, type_, diameter)
    except ValueError as exc:
        msg = str(exc)
        field = next((f for f in ("diameter_mm", "collar", "toe", "name", "type", "id")
                      if msg.startswith(f)), None)
        if field is not None:
            loc = (*loc, (fields or {}).get(field, field))
            msg = f"hole '{hole_id}': {msg}"
        raise PlanFormatError(loc, msg, hole_id=str(hole_id), **where) from None


def _make_plan(plan_id: str, name: str, frame: Any, frame_name: str, holes: list[Hole],
               loc: Loc) -> DrillPlan:
    try:
        return DrillPlan(plan_id, name, frame, frame_name, tuple(holes))
    except ValueError as exc:
        msg = str(exc)
        field = next((f for f in ("plan_id", "name", "frame_name", "frame") if
                      msg.startswith(f)), None)
        raise PlanFormatError((*loc, field) if field else loc, msg) from None


# ---- IREDES: writing ---------------------------------------------------------------------
def _fixed(value: float, places: int = 3) -> str:
    """The shortest text with at least ``places`` decimals that reads back as ``value``
    (``1.000``, ``0.99863``)."""
    value = float(value)
    if value == 0.0:
        return f"{0.0:.{places}f}"
    for d in range(places, 18):
        s = f"{value:.{d}f}"
        if float(s) == value:
            return s
    return repr(value)


def _metres(mm: float) -> str:
    """mm as metres with at least 3 decimals, exact enough that ``_mm`` reads ``mm`` back
    (to 1e-6 mm)."""
    target = round(float(mm), 6)
    for d in range(3, 13):
        s = f"{target / 1000.0:.{d}f}"
        if _mm(float(s)) == target:
            return "0.000" if float(s) == 0.0 else s
    return repr(target / 1000.0)


def _number_text(value: float) -> str:
    """A number as written for DrillBitDia and times: ``45`` for whole numbers, else the
    shortest exact form."""
    return str(int(value)) if float(value).is_integer() and abs(value) < 1e15 else repr(value)


def _check_assignments(plan: DrillPlan, assignments: Mapping[str, Any] | None
                       ) -> dict[str, dict[str, Any]]:
    if assignments is None:
        return {}
    if not isinstance(assignments, Mapping):
        raise PlanFormatError(("assignments",), "assignments must be an object hole id -> "
                              "{boom, order, start_s, end_s}")
    ids = set(plan.ids())
    out: dict[str, dict[str, Any]] = {}
    for hole_id, a in assignments.items():
        loc: Loc = ("assignments", str(hole_id))
        if hole_id not in ids:
            raise PlanFormatError(loc, f"no hole has the id '{hole_id}'", hole_id=str(hole_id))
        if not isinstance(a, Mapping):
            raise PlanFormatError(loc, "an assignment is an object {boom, order, start_s, "
                                  "end_s}", hole_id=hole_id)
        unknown = sorted(set(a) - set(ASSIGNMENT_FIELDS))
        if unknown:
            raise PlanFormatError((*loc, unknown[0]), f"unknown field '{unknown[0]}'; an "
                                  f"assignment has {', '.join(ASSIGNMENT_FIELDS)}",
                                  hole_id=hole_id)
        entry: dict[str, Any] = {}
        for key, value in a.items():
            if value is None:
                continue
            where = (*loc, key)
            if key == "boom":
                try:
                    entry[key] = _check_text(value, "boom")
                except ValueError as exc:
                    raise PlanFormatError(where, str(exc), hole_id=hole_id) from None
            elif key == "order":
                if isinstance(value, bool) or not isinstance(value, int) or abs(value) > 10**9:
                    raise PlanFormatError(where, "order must be an integer", hole_id=hole_id)
                entry[key] = int(value)
            else:
                if (isinstance(value, bool) or not isinstance(value, int | float)
                        or not math.isfinite(value) or abs(value) > 1e9):
                    raise PlanFormatError(where, f"{key} must be a finite number of seconds",
                                          hole_id=hole_id)
                entry[key] = float(value)
        out[hole_id] = entry
    return out


def write_iredes(plan: DrillPlan, *, assignments: Mapping[str, Any] | None = None,
                 northing_in_x: bool = False, created: datetime | str | None = None) -> str:
    """The plan as an IREDES drill plan (``DRPPlan``, IR version V 1.0), metres, CRLF line
    ends, with its ``IR:ChkSum``: encode it as UTF-8 and write the bytes as they are.

    ``assignments``: ``{hole_id: {"boom": str, "order": int, "start_s": s, "end_s": s}}``
    (any of the four) written into each hole's ``HoleOptions`` as ``<kp:Assignment>`` in
    the namespace ``ASSIGNMENT_NAMESPACE`` (rigs ignore options they do not know;
    ``read_iredes_with_assignments`` reads them back). ``northing_in_x``: write y in
    ``PointX`` and x in ``PointY``. ``created``: the file's create and close date (default:
    now, to the second)."""
    checked = _check_assignments(plan, assignments)
    if created is None:
        created = datetime.now().replace(microsecond=0)
    stamp = created.isoformat() if isinstance(created, datetime) else str(created)
    frame = np.array(plan.frame)
    if northing_in_x:
        P = np.eye(4)[[1, 0, 2, 3]]
        frame = P @ frame @ P
    lines = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        f'<DRPPlan xmlns:IR="{_IR_NAMESPACE}" xmlns="{_DRILLRIG_NAMESPACE}" '
        'IRVersion="V 1.0" IRDownwCompat="V 1.0">',
        "  <IR:GenHead>",
        f"    <IR:FileCreateDate>{escape(stamp)}</IR:FileCreateDate>",
        '    <IR:IRversion DownwCompat="V 1.0">V 1.0</IR:IRversion>',
        "  </IR:GenHead>",
        f"  <IR:PlanId>{escape(plan.plan_id)}</IR:PlanId>",
        f"  <IR:PlanName>{escape(plan.name)}</IR:PlanName>",
        '  <DrillPosPlan IRVersion="V 1.0" IRDownwCompat="V 1.0">',
        "    <PositionData>",
        "      <Coordsystem>",
        f"        <IR:CoordSysName>{escape(plan.frame_name)}</IR:CoordSysName>",
        "        <IR:TMatrix>",
    ]
    for j in range(4):
        lines.append("          <IR:Col>")
        for i, name in enumerate("xyzw"):
            value = _metres(frame[i, j]) if (j == 3 and i < 3) else _fixed(frame[i, j])
            lines.append(f"            <IR:{name}>{value}</IR:{name}>")
        lines.append("          </IR:Col>")
    lines += [
        "        </IR:TMatrix>",
        "        <IR:CsysType>L</IR:CsysType>",
        "      </Coordsystem>",
        "      <PlanIdRef />",
        "      <Bearing>0.000</Bearing>",
        "    </PositionData>",
        "  </DrillPosPlan>",
        "  <DrillPlan>",
        f"    <NumberOfHoles>{len(plan.holes)}</NumberOfHoles>",
    ]
    for h in plan.holes:
        lines += ["    <Hole>",
                  f"      <HoleId>{escape(h.id)}</HoleId>",
                  f"      <HoleName>{escape(h.name)}</HoleName>"]
        for tag, point in (("StartPoint", h.collar), ("EndPoint", h.toe)):
            x, y, z = point
            if northing_in_x:
                x, y = y, x
            lines += [f"      <{tag}>",
                      f"        <IR:PointX>{_metres(x)}</IR:PointX>",
                      f"        <IR:PointY>{_metres(y)}</IR:PointY>",
                      f"        <IR:PointZ>{_metres(z)}</IR:PointZ>",
                      f"      </{tag}>"]
        lines.append(f"      <TypeOfHole>{escape(h.type)}</TypeOfHole>")
        if h.diameter_mm is not None:
            lines.append(f"      <DrillBitDia>{_number_text(h.diameter_mm)}</DrillBitDia>")
        lines.append("      <MwdOn>0</MwdOn>")
        entry = checked.get(h.id)
        if entry:
            p = _ASSIGNMENT_PREFIX
            lines += [f'      <HoleOptions xmlns:{p}="{ASSIGNMENT_NAMESPACE}">',
                      f"        <{p}:Assignment>"]
            for key, tag in ASSIGNMENT_FIELDS.items():
                if key in entry:
                    value = entry[key]
                    text = escape(value) if key == "boom" else (
                        str(value) if key == "order" else repr(float(value)))
                    lines.append(f"          <{p}:{tag}>{text}</{p}:{tag}>")
            lines += [f"        </{p}:Assignment>", "      </HoleOptions>"]
        else:
            lines.append("      <HoleOptions />")
        lines.append("    </Hole>")
    lines += [
        "    <EquipmentData>",
        "      <IR:OptionData />",
        "    </EquipmentData>",
        "  </DrillPlan>",
        "  <IR:GenTrailer>",
        f"    <IR:FileCloseDate>{escape(stamp)}</IR:FileCloseDate>",
        "    <IR:ChkSum>0</IR:ChkSum>",
        "  </IR:GenTrailer>",
        "</DRPPlan>",
        "",
    ]
    text = "\r\n".join(lines)
    checksum = zlib.crc32(text.encode("utf-8"))
    return text.replace("<IR:ChkSum>0</IR:ChkSum>", f"<IR:ChkSum>{checksum}</IR:ChkSum>")


# ---- CSV ---------------------------------------------------------------------------------
def read_csv(text: str | bytes, *, plan_id: str = "csv", name: str = "",
             frame_name: str = "") -> DrillPlan:
    """A drill plan from CSV: a header row naming the columns (``CSV_COLUMNS``, any order;
    ``id``, ``collar_x/y/z`` and ``toe_x/y/z`` required), then one hole a row, mm. The
    delimiter is ``,`` (or ``;`` when the header has semicolons and no comma); blank lines
    are skipped. The plan's frame is the identity. A ``PlanFormatError`` names the row (the
    line of the file, the header being row 1) and the column at fault:
    ``("row", 5, "toe_z")``."""
    if isinstance(text, bytes | bytearray):
        if len(text) > MAX_PLAN_BYTES:
            raise PlanTooLargeError((), f"the CSV is {len(text):,} bytes; at most "
                                    f"{MAX_PLAN_BYTES:,} allowed")
        try:
            text = bytes(text).decode("utf-8-sig")
        except UnicodeDecodeError as exc:
            raise PlanFormatError((), f"the CSV is not UTF-8 text: {exc}") from None
    if len(text) > MAX_PLAN_BYTES:
        raise PlanTooLargeError((), f"the CSV is {len(text):,} characters; at most "
                                f"{MAX_PLAN_BYTES:,} allowed")
    text = text.lstrip("\ufeff")
    first = text.split("\n", 1)[0]
    delimiter = ";" if ";" in first and "," not in first else ","
    try:
        rows = list(csv.reader(io.StringIO(text, newline=""), delimiter=delimiter,
                               strict=True))
    except csv.Error as exc:
        raise PlanFormatError(("row",), f"the CSV cannot be read: {exc}") from None
    numbered = [(k + 1, r) for k, r in enumerate(rows) if any(c.strip() for c in r)]
    if not numbered:
        raise PlanFormatError(("row", 1), "the CSV is empty: a header row and one hole a row "
                              "are needed", row=1)
    header_row, header = numbered[0]
    columns = [c.strip().lower() for c in header]
    for c in columns:
        if c not in CSV_COLUMNS:
            raise PlanFormatError(("row", header_row, c), f"row {header_row}: unknown column "
                                  f"'{c}'; the columns are {', '.join(CSV_COLUMNS)}",
                                  row=header_row, column=c)
        if columns.count(c) > 1:
            raise PlanFormatError(("row", header_row, c), f"row {header_row}: column '{c}' "
                                  "appears twice", row=header_row, column=c)
    missing = [c for c in _CSV_REQUIRED if c not in columns]
    if missing:
        raise PlanFormatError(("row", header_row, missing[0]), f"row {header_row}: the header "
                              f"has no column '{missing[0]}' (required: "
                              f"{', '.join(_CSV_REQUIRED)})",
                              row=header_row, column=missing[0])
    data = numbered[1:]
    if len(data) > MAX_HOLES:
        raise PlanTooLargeError(("row",), f"the CSV has {len(data):,} holes; at most "
                                f"{MAX_HOLES:,} are read")
    holes: list[Hole] = []
    seen: dict[str, int] = {}
    for row, cells in data:
        if len(cells) != len(columns):
            column = columns[min(len(cells), len(columns) - 1)]
            raise PlanFormatError(("row", row, column), f"row {row} has {len(cells)} cells; "
                                  f"the header has {len(columns)}", row=row, column=column)
        value = {c: cell.strip() for c, cell in zip(columns, cells)}
        hole_id = value["id"]
        where = {"row": row}
        if not hole_id:
            raise PlanFormatError(("row", row, "id"), f"row {row}: the hole id is empty",
                                  column="id", **where)
        if hole_id in seen:
            raise PlanFormatError(("row", row, "id"), f"row {row}: hole id '{hole_id}' is "
                                  f"already used in row {seen[hole_id]}", column="id",
                                  hole_id=hole_id, **where)
        seen[hole_id] = row
        numbers = {}
        for c in ("collar_x", "collar_y", "collar_z", "toe_x", "toe_y", "toe_z"):
            numbers[c] = _number(value[c], ("row", row, c), f"row {row}, column '{c}'",
                                 column=c, hole_id=hole_id, **where)
        diameter = None
        if value.get("diameter_mm"):
            diameter = _number(value["diameter_mm"], ("row", row, "diameter_mm"),
                               f"row {row}, column 'diameter_mm'", column="diameter_mm",
                               hole_id=hole_id, **where)
        collar = [numbers["collar_x"], numbers["collar_y"], numbers["collar_z"]]
        toe = [numbers["toe_x"], numbers["toe_y"], numbers["toe_z"]]
        try:
            holes.append(Hole(hole_id, value.get("name", ""), collar, toe,
                              value.get("type", ""), diameter))
        except ValueError as exc:
            msg = str(exc)
            column = next((f for f in ("diameter_mm", "name", "type", "id")
                           if msg.startswith(f)), None)
            if column is None:
                column = "toe_x" if "zero depth" in msg else "collar_x"
                for c in ("collar", "toe"):
                    if msg.startswith(c):
                        column = f"{c}_x"
            raise PlanFormatError(("row", row, column), f"row {row}: {msg}", row=row,
                                  column=column, hole_id=hole_id) from None
    return _make_plan(plan_id, name, np.eye(4), frame_name, holes, ())


def to_csv(plan: DrillPlan) -> str:
    """The plan as CSV (``CSV_COLUMNS``, mm, a header row); ``read_csv`` reads it back
    (the plan's id, name and frame are not in it)."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(CSV_COLUMNS)
    for h in plan.holes:
        writer.writerow([h.id, h.name, *(repr(float(v)) for v in h.collar),
                         *(repr(float(v)) for v in h.toe), h.type,
                         "" if h.diameter_mm is None else repr(h.diameter_mm)])
    return out.getvalue()


# ---- JSON --------------------------------------------------------------------------------
_JSON_KEYS = {"plan_id", "name", "frame_name", "frame", "holes", "hole_count"}
_HOLE_KEYS = {"id", "name", "collar", "toe", "type", "diameter_mm"}


def _json_number(value: Any, loc: Loc, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise PlanFormatError(loc, f"{what} must be a number")
    if not math.isfinite(value):
        raise PlanFormatError(loc, f"{what} must be finite")
    return float(value)


def _json_vector(value: Any, loc: Loc, what: str) -> list[float]:
    if not isinstance(value, list) or len(value) != 3:
        raise PlanFormatError(loc, f"{what} must be [x, y, z] (mm)")
    return [_json_number(v, (*loc, i), what) for i, v in enumerate(value)]


def read_json(obj: Mapping[str, Any]) -> DrillPlan:
    """A drill plan from its JSON form (``DrillPlan.to_json()``; ``name``, ``frame_name``
    and ``frame`` optional, default "", "" and the identity; each hole's ``name``, ``type``
    and ``diameter_mm`` optional). ``hole_count``, when given, must equal the number of
    holes. A ``PlanFormatError`` names the field: ``("holes", 3, "toe", 2)``."""
    if not isinstance(obj, Mapping):
        raise PlanFormatError((), "a drill plan is a JSON object")
    unknown = sorted(set(obj) - _JSON_KEYS)
    if unknown:
        raise PlanFormatError((unknown[0],), f"unknown field '{unknown[0]}'; a plan has "
                              f"{', '.join(sorted(_JSON_KEYS))}")
    for key in ("plan_id", "holes"):
        if key not in obj:
            raise PlanFormatError((key,), f"'{key}' is required")
    texts = {}
    for key, default in (("plan_id", None), ("name", ""), ("frame_name", "")):
        value = obj.get(key, default)
        try:
            texts[key] = _check_text(value, key, empty=key != "plan_id")
        except ValueError as exc:
            raise PlanFormatError((key,), str(exc)) from None
    frame = obj.get("frame", None)
    if frame is None:
        frame = np.eye(4)
    elif (not isinstance(frame, list) or len(frame) != 4
          or not all(isinstance(r, list) and len(r) == 4 for r in frame)):
        raise PlanFormatError(("frame",), "frame must be a 4x4 matrix (rows, mm)")
    else:
        frame = [[_json_number(v, ("frame", i, j), "frame") for j, v in enumerate(r)]
                 for i, r in enumerate(frame)]
    holes_in = obj["holes"]
    if not isinstance(holes_in, list):
        raise PlanFormatError(("holes",), "holes must be a list")
    if len(holes_in) > MAX_HOLES:
        raise PlanTooLargeError(("holes",), f"the plan has {len(holes_in):,} holes; at most "
                                f"{MAX_HOLES:,} are read")
    count = obj.get("hole_count")
    if count is not None and (isinstance(count, bool) or count != len(holes_in)):
        raise PlanFormatError(("hole_count",), f"hole_count says {count!r} but holes holds "
                              f"{len(holes_in)}")
    holes: list[Hole] = []
    seen: dict[str, int] = {}
    for k, h in enumerate(holes_in):
        loc: Loc = ("holes", k)
        if not isinstance(h, Mapping):
            raise PlanFormatError(loc, "a hole is an object {id, name, collar, toe, type, "
                                  "diameter_mm}")
        bad = sorted(set(h) - _HOLE_KEYS)
        if bad:
            raise PlanFormatError((*loc, bad[0]), f"unknown field '{bad[0]}'; a hole has "
                                  f"{', '.join(sorted(_HOLE_KEYS))}")
        for key in ("id", "collar", "toe"):
            if key not in h:
                raise PlanFormatError((*loc, key), f"'{key}' is required")
        hole_id = h["id"]
        name, type_ = h.get("name", ""), h.get("type", "")
        for key, value in (("id", hole_id), ("name", name), ("type", type_)):
            try:
                _check_text(value, key, empty=key != "id")
            except ValueError as exc:
                raise PlanFormatError((*loc, key), str(exc)) from None
        if hole_id in seen:
            raise PlanFormatError((*loc, "id"), f"hole id '{hole_id}' is already used by "
                                  f"holes[{seen[hole_id]}]", hole_id=hole_id)
        seen[hole_id] = k
        collar = _json_vector(h["collar"], (*loc, "collar"), "collar")
        toe = _json_vector(h["toe"], (*loc, "toe"), "toe")
        diameter = h.get("diameter_mm")
        if diameter is not None:
            diameter = _json_number(diameter, (*loc, "diameter_mm"), "diameter_mm")
        holes.append(_make_hole(hole_id, name, collar, toe, type_, diameter, loc))
    return _make_plan(texts["plan_id"], texts["name"], frame, texts["frame_name"], holes, ())
