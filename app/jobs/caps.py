"""Limits every job submission meets before its kind looks at it, and the job time limit.

``check_params`` runs on the raw ``params`` of ``POST /jobs``: first their size (one
C-speed ``json.dumps``, so an oversized submission costs no validation at all), then one walk
for nesting depth and non-finite numbers. FastAPI's JSON parser accepts the literals ``NaN``,
``Infinity`` and ``-Infinity`` (and ``1e999`` parses to infinity); the kinds' typed fields
reject them, but free-form fields (``echo``'s ``value``, planner ``params``) would store them
as ``null`` and fail later, so they are caught here, with the field named.
"""

from __future__ import annotations

import json
import math
from typing import Any

__all__ = [
    "MAX_PARAMS_BYTES",
    "MAX_PARAMS_DEPTH",
    "DEFAULT_TIME_LIMIT_S",
    "MAX_TIME_LIMIT_S",
    "ParamsLimitError",
    "check_params",
    "time_limit_message",
]

#: Largest compact JSON text of a job's ``params`` (413 above).
MAX_PARAMS_BYTES = 1 << 20
#: Deepest nesting of objects and lists in ``params`` (``params`` itself is level 1).
MAX_PARAMS_DEPTH = 32
#: Seconds a job may run unless the service or the job says otherwise.
DEFAULT_TIME_LIMIT_S = 3600.0
#: Longest time limit a service may be configured with (a week).
MAX_TIME_LIMIT_S = 7 * 86_400.0


class ParamsLimitError(ValueError):
    """``params`` break a limit; ``loc`` names the field (``["params", "value", 0]``)."""

    def __init__(self, loc: list, message: str, status: int = 422) -> None:
        super().__init__(message)
        self.loc = loc
        self.message = message
        self.status = status


def check_params(params: Any, max_bytes: int = MAX_PARAMS_BYTES,
                 max_depth: int = MAX_PARAMS_DEPTH) -> None:
    """Raise ``ParamsLimitError`` for params over ``max_bytes`` of JSON (status 413),
    nested deeper than ``max_depth`` or holding a NaN or infinite number (422)."""
    try:
        size = len(json.dumps(params, separators=(",", ":"), ensure_ascii=False)
                   .encode("utf-8"))
    except RecursionError:
        size = 0  # nested too deep to encode: the walk below says where
    except (TypeError, ValueError) as exc:  # not JSON data (only from code, not requests)
        raise ParamsLimitError(["params"], f"must be JSON data: {exc}") from None
    if size > max_bytes:
        raise ParamsLimitError(
            ["params"], f"params take {size:,} bytes of JSON; at most {max_bytes:,}", 413)
    stack: list[tuple[Any, list, int]] = [(params, ["params"], 1)]
    while stack:
        value, loc, depth = stack.pop()
        if isinstance(value, dict | list):
            if depth > max_depth:
                raise ParamsLimitError(
                    loc, f"nested deeper than {max_depth} levels of objects and lists")
            items = value.items() if isinstance(value, dict) else enumerate(value)
            # Reversed onto the stack, so the first bad item in document order is reported.
            stack.extend((v, [*loc, k], depth + 1) for k, v in reversed(list(items)))
        elif isinstance(value, float) and not math.isfinite(value):
            raise ParamsLimitError(
                loc, f"must be a finite number, got {value} (NaN and Infinity are not JSON)")


def time_limit_message(seconds: float) -> str:
    """The error of a job stopped at its time limit."""
    return f"time limit of {seconds:g} s exceeded"
