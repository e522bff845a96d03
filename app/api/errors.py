"""HTTP errors in the shape FastAPI uses for its own validation errors.

Every 4xx the service raises carries ``{"detail": [{"loc": [...], "msg": str, "type": str}]}``
so clients can handle them like pydantic's, and the field at fault is named in ``loc``.
"""

from __future__ import annotations

from collections.abc import Sequence

from fastapi import HTTPException

__all__ = [
    "http_error","invalid", "too_large", "not_found", "forbidden", "conflict", "unavailable"]


def http_error(status: int, loc: Sequence[str | int], msg: str, kind: str,
               headers: dict[str, str] | None = None) -> HTTPException:
    """Any 4xx/5xx in the service's shape; ``loc`` is the full location."""
    return HTTPException(status, detail=[{"loc": list(loc), "msg": msg, "type": kind}],
                         headers=headers)


_error = http_error


def invalid(field: Sequence[str | int], msg: str) -> HTTPException:
    """422 for a body field that is well-formed JSON but wrong for this robot or request."""
    return _error(422, ["body", *field], msg, "value_error")


def too_large(field: Sequence[str | int], msg: str) -> HTTPException:
    """413 for a request over a documented size cap."""
    return _error(413, ["body", *field], msg, "too_large")


def not_found(what: str, ident: str) -> HTTPException:
    return _error(404, ["path", f"{what}_id"], f"unknown {what} '{ident}'", "not_found")


def forbidden(what: str, ident: str, msg: str) -> HTTPException:
    """403 for an existing resource the client may not change (e.g. a built-in robot)."""
    return _error(403, ["path", f"{what}_id"], msg, "forbidden")


def conflict(field: Sequence[str | int], msg: str) -> HTTPException:
    return _error(409, ["body", *field], msg, "conflict")


def unavailable(what: str, msg: str) -> HTTPException:
    """503 for a part of the service that is not running."""
    return _error(503, ["service", what], msg, "unavailable")
