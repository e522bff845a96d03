"""What the service answers when a request fails, as exceptions.

Every 4xx of the service carries ``{"detail": [{"loc": [...], "msg": str, "type": str}]}``
(the shape FastAPI uses for its validation errors); ``loc`` names the field at fault, e.g.
``["body", "q", 0]``. ``ApiError`` keeps the status, that detail, the first ``loc`` as
``field`` and its ``msg`` as ``message``, so a program can tell which input to fix without
parsing text. One subclass per status a caller may want to handle on its own.
"""

from __future__ import annotations

import json
from typing import Any

__all__ = [
    "ApiError",
    "UnauthorizedError",
    "ForbiddenError",
    "NotFoundError",
    "ConflictError",
    "TooLargeError",
    "InvalidError",
    "QueueFullError",
    "UnavailableError",
    "error_from_answer",
]


class ApiError(Exception):
    """An answer of the service with a status of 400 or more.

    ``status``: the HTTP status; ``detail``: the answer's ``detail`` as sent (a list of
    ``{"loc", "msg", "type"}`` for the service's own errors, else what the answer held);
    ``field``: the ``loc`` of the first error (e.g. ``["body", "q", 0]``), None when the
    answer names none; ``message``: its ``msg``; ``kind``: its ``type``; ``retry_after``:
    seconds the service asked to wait (``Retry-After``), None when it did not."""

    def __init__(self, status: int, detail: Any, *, method: str = "", url: str = "",
                 retry_after: float | None = None) -> None:
        self.status = status
        self.detail = detail
        first = detail[0] if isinstance(detail, list) and detail and \
            isinstance(detail[0], dict) else None
        self.field: list[str | int] | None = list(first["loc"]) if first and \
            isinstance(first.get("loc"), list | tuple) else None
        self.message: str = str(first.get("msg", "")) if first else \
            (detail if isinstance(detail, str) else json.dumps(detail, default=str))
        self.kind: str | None = first.get("type") if first else None
        self.method = method
        self.url = url
        self.retry_after = retry_after
        where = f" at {self.field}" if self.field is not None else ""
        request = f" ({method} {url})" if method else ""
        super().__init__(f"{status}{where}: {self.message}{request}")


class UnauthorizedError(ApiError):
    """401: the request changes state and the service wants its API key."""


class ForbiddenError(ApiError):
    """403: the resource may not be changed (e.g. deleting a built-in robot)."""


class NotFoundError(ApiError):
    """404: an unknown robot, scene, mesh or job."""


class ConflictError(ApiError):
    """409: an id is taken, or a job's result is not there (yet)."""


class TooLargeError(ApiError):
    """413: over a documented size cap (e.g. more than 100,000 configurations in one FK)."""


class InvalidError(ApiError):
    """422: a well-formed request with a wrong value; ``field`` names it."""


class QueueFullError(ApiError):
    """429: the job queue is full; submit again later."""


class UnavailableError(ApiError):
    """503: a part of the service is not running (the job cluster, the data store)."""


_BY_STATUS: dict[int, type[ApiError]] = {
    401: UnauthorizedError, 403: ForbiddenError, 404: NotFoundError, 409: ConflictError,
    413: TooLargeError, 422: InvalidError, 429: QueueFullError, 503: UnavailableError,
}


def error_from_answer(status: int, body: bytes, headers: Any = None, *, method: str = "",
                      url: str = "") -> ApiError:
    """The exception for an answer of ``status`` with ``body``: its ``detail`` when the body
    is the service's JSON, else the body's text."""
    try:
        data = json.loads(body)
        detail = data["detail"] if isinstance(data, dict) and "detail" in data else data
    except (ValueError, UnicodeDecodeError):
        detail = body.decode("utf-8", "replace").strip() or f"HTTP {status}"
    retry_after = None
    raw = (headers or {}).get("retry-after")
    if raw is not None:
        try:
            retry_after = float(raw)
        except ValueError:
            retry_after = None
    cls = _BY_STATUS.get(status, ApiError)
    return cls(status, detail, method=method, url=url, retry_after=retry_after)
