"""Field types shared by the request bodies and the job parameters (mm, rad, s).

Every number a client sends is finite and inside a physical range, and every list has a
maximum length that is checked *before* its items are: a list of 30 million numbers costs
one ``len`` and one error, not 30 million validations. Arrays of numbers (joint vectors,
batches of them, poses) are checked in one numpy pass and report one error naming the first
bad element.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Annotated, Any

import numpy as np
from pydantic import BaseModel, BeforeValidator, ConfigDict, Field
from pydantic_core import PydanticCustomError

from kinematics.model import MAX_DOF, MAX_LENGTH_MM

__all__ = [
    "StrictModel",
    "MAX_COORDINATE_MM",
    "MAX_JOINT_VALUE",
    "MAX_DURATION_S",
    "MAX_RATE",
    "MAX_NAME_LENGTH",
    "Coordinate",
    "Point3",
    "Direction3",
    "JointValue",
    "JointVector",
    "Duration",
    "Rate",
    "Name",
    "bounded_list",
    "joint_batch",
    "pose_type",
    "pose_batch",
    "joint_input",
    "pose_input",
]

#: Largest coordinate a request may carry (mm): 10 km, beyond any machine's site, small
#: enough that squares and sums of coordinates stay finite.
MAX_COORDINATE_MM = MAX_LENGTH_MM
#: Largest |joint value| accepted (rad or mm): the longest prismatic stroke a model may have.
MAX_JOINT_VALUE = MAX_LENGTH_MM
#: Longest duration (s) of a move or a segment: a day.
MAX_DURATION_S = 86_400.0
#: Shortest duration (s) of a move or a segment: a millisecond.
MIN_DURATION_S = 1e-3
#: Smallest rate limit: slower joints never finish a move inside MAX_DURATION_S.
MIN_RATE = 1e-6
#: Largest rate limit (rad/s, mm/s and their derivatives).
MAX_RATE = 1e9
#: Longest name or id string in a request.
MAX_NAME_LENGTH = 200


class StrictModel(BaseModel):
    """Base of every model a client sends (request bodies, job parameters, planner knobs)
    and of job results: unknown fields and NaN/inf are rejected, each error naming its
    field."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


Coordinate = Annotated[float, Field(ge=-MAX_COORDINATE_MM, le=MAX_COORDINATE_MM)]
JointValue = Annotated[float, Field(ge=-MAX_JOINT_VALUE, le=MAX_JOINT_VALUE,
                                    description="rad (revolute) or mm (prismatic)")]
Duration = Annotated[float, Field(ge=MIN_DURATION_S, le=MAX_DURATION_S, description="s")]
Rate = Annotated[float, Field(ge=MIN_RATE, le=MAX_RATE)]
Name = Annotated[str, Field(min_length=1, max_length=MAX_NAME_LENGTH)]


def _too_long(value: Any, max_length: int, what: str = "items",
              error: str = "too_long") -> None:
    if isinstance(value, list | tuple) and len(value) > max_length:
        raise PydanticCustomError(
            error, "at most {max_length} {what}, got {length}",
            {"max_length": max_length, "what": what, "length": len(value)})


def _length_first(max_length: int, what: str = "items",
                  error: str = "too_long") -> BeforeValidator:
    def check(value: Any) -> Any:
        _too_long(value, max_length, what, error)
        return value

    return BeforeValidator(check)


def bounded_list(item: Any, max_length: int, *, min_length: int = 0, what: str = "items",
                 per_call: bool = False) -> Any:
    """``list[item]`` whose length is checked before any item is validated. ``per_call``:
    the cap is a documented request-size cap, answered 413 (type ``too_large``) rather than
    422."""
    return Annotated[list[item], Field(min_length=min_length, max_length=max_length),
                     _length_first(max_length, what, "too_large" if per_call else "too_long")]


Point3 = Annotated[list[Coordinate], Field(min_length=3, max_length=3,
                                           description="[x, y, z] mm"), _length_first(3)]
Direction3 = Annotated[list[Coordinate], Field(min_length=3, max_length=3,
                                               description="[x, y, z], any length"),
                       _length_first(3)]


# ---- numeric arrays checked in one pass ------------------------------------------------
def _first_bad(value: Any, depth: int, path: str = "") -> tuple[str, str] | None:
    """Where and why a nested list is not a ``depth``-deep array of numbers (the slow path,
    taken once numpy's conversion has failed; sizes are already bounded)."""
    if depth == 0:
        if isinstance(value, str):
            try:
                float(value)  # numpy, like pydantic's lax mode, reads "1.5" as a number
            except ValueError:
                return path, "must be a number, got a string"
            return None
        if isinstance(value, bool) or not isinstance(value, int | float):
            return path, f"must be a number, got {type(value).__name__}"
        return None
    if not isinstance(value, list):
        return path, f"must be a list, got {type(value).__name__}"
    for k, item in enumerate(value):
        bad = _first_bad(item, depth - 1, f"{path}[{k}]")
        if bad is not None:
            return bad
    return None


def _array(value: Any, depth: int, bound: float, unit: str) -> np.ndarray:
    """``value`` as a float array of ``depth`` dimensions, every entry finite and within
    ``±bound``; one ``PydanticCustomError`` otherwise."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        arr = None
    if arr is None or arr.ndim != depth:
        where, why = _first_bad(value, depth) or ("", "must be numbers in rows of equal "
                                                   "length")
        raise PydanticCustomError("value_error", "{where}{why}",
                                  {"where": f"{where}: " if where else "", "why": why})
    bad = ~np.isfinite(arr) | (np.abs(arr) > bound)
    if bad.any():
        idx = "".join(f"[{int(i)}]" for i in np.argwhere(bad)[0])
        where = f"{idx}: " if idx else ""
        raise PydanticCustomError(
            "value_error", "{where}must be finite and within ±{bound} {unit}",
            {"where": where, "bound": f"{bound:g}", "unit": unit})
    return arr


def _array_check(depth: int, shape_check: Callable[[list], None], bound: float,
                 unit: str) -> Callable[[Any], Any]:
    def check(value: Any) -> Any:
        if not isinstance(value, list):
            return value  # pydantic says what type was expected
        shape_check(value)
        _array(value, depth, bound, unit)
        return value

    return check


def _array_validator(depth: int, shape_check: Callable[[list], None], bound: float,
                     unit: str) -> BeforeValidator:
    return BeforeValidator(_array_check(depth, shape_check, bound, unit))


def _depth(value: Any) -> int:
    """Nesting depth of a list along its first elements (``[[1, 2]]`` -> 2)."""
    depth = 0
    while isinstance(value, list):
        depth += 1
        value = value[0] if value else None
    return depth


def _one_or_many(one: Callable[[Any], Any], many: Callable[[Any], Any],
                 one_depth: int) -> BeforeValidator:
    """For a field that takes one array or a list of them: check the input as the one its
    nesting says it is, so a bad input gets that form's one error (not one per form)."""
    def check(value: Any) -> Any:
        return many(value) if _depth(value) > one_depth else one(value)

    return BeforeValidator(check)


def _rows_fit(max_rows: int, max_cols: int, what: str,
              per_call: bool = True) -> Callable[[list], None]:
    """At most ``max_rows`` rows of at most ``max_cols`` values (lengths only). ``per_call``:
    too many rows is a request-size cap (``too_large``, 413)."""
    def check(value: list) -> None:
        if len(value) > max_rows:
            raise PydanticCustomError(
                "too_large" if per_call else "too_long",
                "at most {max_rows} {what}{per}, got {n}",
                {"max_rows": max_rows, "what": what, "n": len(value),
                 "per": " per call" if per_call else ""})
        for k, row in enumerate(value):
            if isinstance(row, list) and len(row) > max_cols:
                raise PydanticCustomError(
                    "too_long", "[{k}]: at most {max_cols} values, got {n}",
                    {"k": k, "max_cols": max_cols, "n": len(row)})

    return check


JointVector = Annotated[
    list[JointValue],
    Field(min_length=1, max_length=MAX_DOF,
          description="One configuration: a value per joint, rad or mm"),
    BeforeValidator(lambda v: _joint_vector_check(v)),
]


def _joint_vector_check(value: Any) -> Any:
    # Length only: at most MAX_DOF items, each then checked by pydantic with its own loc.
    _too_long(value, MAX_DOF, "joint values")
    return value



def joint_batch(max_rows: int) -> Any:
    """A list of at most ``max_rows`` configurations (each at most ``MAX_DOF`` values)."""
    return Annotated[
        list[Annotated[list[JointValue], Field(min_length=1, max_length=MAX_DOF)]],
        Field(max_length=max_rows),
        _array_validator(2, _rows_fit(max_rows, MAX_DOF, "configurations"), MAX_JOINT_VALUE,
                         "(rad or mm)"),
    ]


def _square(n: int) -> Callable[[list], None]:
    def check(value: list) -> None:
        if len(value) != n or any(not isinstance(r, list) or len(r) != n for r in value):
            raise PydanticCustomError("value_error", "must be a {n}x{n} matrix (a list of {n} "
                                      "rows of {n} numbers)", {"n": n})

    return check


def pose_type(n: int = 4) -> Any:
    """An ``n x n`` matrix of bounded numbers (4: a pose, mm; 3: a rotation)."""
    return Annotated[
        list[Annotated[list[Coordinate], Field(min_length=n, max_length=n)]],
        Field(min_length=n, max_length=n),
        _array_validator(2, _square(n), MAX_COORDINATE_MM, "mm"),
    ]


def pose_batch(max_poses: int) -> Any:
    """A list of at most ``max_poses`` 4x4 poses."""
    return Annotated[
        list[pose_type(4)],
        Field(max_length=max_poses),
        _array_validator(3, _rows_fit(max_poses, 4, "poses"), MAX_COORDINATE_MM, "mm"),
    ]


def joint_input(max_rows: int) -> Any:
    """One configuration or a list of at most ``max_rows`` of them."""
    batch = _array_check(2, _rows_fit(max_rows, MAX_DOF, "configurations"), MAX_JOINT_VALUE,
                         "(rad or mm)")
    return Annotated[JointVector | joint_batch(max_rows),
                     _one_or_many(_joint_vector_check, batch, 1)]


def pose_input(max_poses: int) -> Any:
    """One 4x4 pose or a list of at most ``max_poses`` of them."""
    one = _array_check(2, _square(4), MAX_COORDINATE_MM, "mm")
    many = _array_check(3, _rows_fit(max_poses, 4, "poses"), MAX_COORDINATE_MM, "mm")
    return Annotated[pose_type(4) | pose_batch(max_poses), _one_or_many(one, many, 2)]
