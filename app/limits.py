"""What every request passes before a route sees it: the Host allow-list, the content type of
bodies, and a body size cap per route (413 above), all checked before the body is read.

* **Host** (DNS rebinding): a browser on a page of ``evil.example`` resolving to 127.0.0.1
  sends ``Host: evil.example``; only the names in the allow-list are served (400 otherwise).
* **Content type** (cross-site forms): a browser posts forms cross-site without asking
  (``text/plain``, ``application/x-www-form-urlencoded``, ``multipart/form-data``), but never
  ``application/json``. Bodies of ``POST``/``PUT``/``PATCH`` must be JSON (415 otherwise),
  except on routes declared to take files.
* **Body size**: each route has a cap that fits its largest legal request (``ROUTE_BODY_CAPS``,
  ``DEFAULT_BODY_CAP`` for the rest), never above the service-wide ``max_body_bytes``; a
  declared ``Content-Length`` over it is refused unread, a streamed (chunked) body as soon as
  it passes it. Nothing past the cap is buffered.
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Iterable, Sequence

from starlette.types import ASGIApp, Message, Receive, Scope, Send

__all__ = [
    "RequestGuard",
    "ROUTE_BODY_CAPS",
    "DEFAULT_BODY_CAP",
    "FILE_ROUTES",
    "TEXT_ROUTES",
    "LOOPBACK_HOSTS",
    "host_allow_list",
]

MiB = 1024 * 1024

#: Body caps (bytes) of the routes whose largest legal request is more than a small JSON
#: object, by path template. FK: 100,000 configurations of a 6-axis arm at full float
#: precision; IK: 10,000 poses; a trajectory of 1,000 waypoints with rates; a job's params.
ROUTE_BODY_CAPS: dict[str, int] = {
    "/robots/{robot_id}/fk": 24 * MiB,
    "/robots/{robot_id}/ik": 6 * MiB,
    "/trajectories": 4 * MiB,
    "/trajectories/plot": 4 * MiB,
    "/jobs": 4 * MiB,
    "/robots": 256 * 1024,
    "/robots/{robot_id}/drill-ik": 256 * 1024,
    # An archive of a URDF with its meshes, and its SRDF (see kinematics.urdf_import).
    "/robots/import": 72 * MiB,
    # A scene with a scanned point cloud or MoveIt meshes inline.
    "/scenes": 24 * MiB,
    "/meshes": 40 * MiB,
    "/robots/{robot_id}/collision": 4 * MiB,
    "/robots/{robot_id}/motion": 4 * MiB,
    # A drill plan file (IREDES, CSV, JSON) of up to 5,000 holes; its JSON for writing.
    "/drill-plans/read": 8 * MiB,
    "/drill-plans/write": 4 * MiB,
}
#: Body cap of every other route: single configurations, single poses, small objects.
DEFAULT_BODY_CAP = 256 * 1024
#: Routes that take ``multipart/form-data`` (files) besides JSON.
FILE_ROUTES: frozenset[str] = frozenset({"/robots/import", "/meshes"})
#: Routes that take a file as the body itself, by the content types they accept besides
#: JSON (none a browser sends cross-site without asking first).
TEXT_ROUTES: dict[str, frozenset[str]] = {
    "/drill-plans/read": frozenset({"application/xml", "text/xml", "text/csv"}),
}

#: Names of this machine that a browser can only use for a service on this machine.
LOOPBACK_HOSTS = ("localhost", "127.0.0.1", "::1")

_WRITE_METHODS = {"POST", "PUT", "PATCH"}


def host_allow_list(setting: str | None, bind_host: str) -> list[str] | None:
    """Allowed ``Host`` names (without port); None allows every name.

    ``setting`` is ``KINOPLAN_ALLOWED_HOSTS`` (comma-separated; ``*`` allows any). Unset, a
    service bound to a loopback address serves its loopback names only; one bound to another
    address serves any name (it cannot know the names it is reached by: set the variable)."""
    if setting is not None and setting.strip():
        names = [n.strip().lower() for n in setting.split(",") if n.strip()]
        return None if "*" in names else [n.strip("[]") for n in names]
    if bind_host in LOOPBACK_HOSTS or bind_host.startswith("127.") or bind_host == "[::1]":
        return list(LOOPBACK_HOSTS)
    return None


def _template_regex(template: str) -> re.Pattern:
    """``/robots/{robot_id}/fk`` -> a regex matching ``/robots/<anything but '/'>/fk``."""
    parts = re.split(r"\{[^}]*\}", template)
    return re.compile("^" + "[^/]+".join(re.escape(p) for p in parts) + "$")


def body_caps(templates: Iterable[str], max_bytes: int) -> dict[str, int]:
    """The body cap of each path template, as ``RequestGuard`` applies it."""
    return {t: min(ROUTE_BODY_CAPS.get(t, DEFAULT_BODY_CAP), max_bytes) for t in templates}


def _error_body(loc: list, msg: str, kind: str) -> bytes:
    return json.dumps({"detail": [{"loc": loc, "msg": msg, "type": kind}]}).encode()


def _host_name(host: str) -> str:
    """``Host`` header value without its port, lower case (``[::1]:8000`` -> ``::1``)."""
    host = host.strip().lower()
    if host.startswith("["):
        return host[1:host.find("]")] if "]" in host else host
    return host.rsplit(":", 1)[0] if host.count(":") == 1 else host


class RequestGuard:
    """ASGI middleware: Host allow-list (400), JSON bodies (415), body caps per route (413).

    ``templates`` gives the application's path templates (``/robots/{robot_id}/fk``); it is
    called once, at the first request, to find each request's cap."""

    def __init__(self, app: ASGIApp, *, max_bytes: int,
                 templates: Callable[[], Iterable[str]] = tuple,
                 allowed_hosts: Sequence[str] | None = None) -> None:
        self.app = app
        self.max_bytes = max_bytes
        self._templates = templates
        self._routes: list[tuple[re.Pattern, str]] | None = None
        self.allowed_hosts = None if allowed_hosts is None else set(allowed_hosts)

    def cap_for(self, path: str) -> tuple[int, str | None]:
        """The body cap of ``path`` and its route template (None if no route matches)."""
        if self._routes is None:
            # Static paths first: '/robots/import' is not '/robots/{robot_id}'.
            templates = sorted(set(self._templates()), key=lambda t: t.count("{"))
            self._routes = [(_template_regex(t), t) for t in templates]
        for regex, template in self._routes:
            if regex.match(path):
                return min(ROUTE_BODY_CAPS.get(template, DEFAULT_BODY_CAP),
                           self.max_bytes), template
        return min(DEFAULT_BODY_CAP, self.max_bytes), None

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        headers = dict(scope.get("headers") or [])
        if self.allowed_hosts is not None:
            host = _host_name(headers.get(b"host", b"").decode("latin-1"))
            if host not in self.allowed_hosts:
                await _answer(send, 400, ["header", "host"],
                              f"host '{host}' is not served here; allowed: "
                              f"{', '.join(sorted(self.allowed_hosts))} (KINOPLAN_ALLOWED_HOSTS)",
                              "host_not_allowed")
                return
        cap, template = self.cap_for(scope.get("path", ""))
        declared = headers.get(b"content-length", b"")
        chunked = b"chunked" in headers.get(b"transfer-encoding", b"").lower()
        has_body = chunked or (declared.isdigit() and int(declared) > 0)
        if scope.get("method") in _WRITE_METHODS and has_body:
            ctype = headers.get(b"content-type", b"").decode("latin-1").split(";")[0]
            ctype = ctype.strip().lower()
            json_ok = ctype == "application/json" or (
                ctype.startswith("application/") and ctype.endswith("+json"))
            files_ok = template in FILE_ROUTES and ctype == "multipart/form-data"
            text_ok = ctype in TEXT_ROUTES.get(template or "", ())
            if not (json_ok or files_ok or text_ok):
                wanted = "' or '".join(["application/json",
                                        *sorted(TEXT_ROUTES.get(template or "", ()))])
                await _answer(send, 415, ["header", "content-type"],
                              f"send the body as '{wanted}', got '{ctype or 'none'}'",
                              "unsupported_media_type")
                return
        if declared.isdigit() and int(declared) > cap:
            await self._too_large(send, cap)
            return
        seen = 0
        started = False

        async def limited_receive() -> Message:
            nonlocal seen
            message = await receive()
            if message["type"] == "http.request":
                seen += len(message.get("body", b""))
                if seen > cap:
                    raise _TooLarge()
            return message

        async def tracking_send(message: Message) -> None:
            nonlocal started
            if message["type"] == "http.response.start":
                started = True
            await send(message)

        try:
            await self.app(scope, limited_receive, tracking_send)
        except _TooLarge:
            if not started:
                await self._too_large(send, cap)

    @staticmethod
    async def _too_large(send: Send, cap: int) -> None:
        await _answer(send, 413, ["body"], f"request body over {cap} bytes, this route's cap",
                      "too_large")


async def _answer(send: Send, status: int, loc: list, msg: str, kind: str) -> None:
    body = _error_body(loc, msg, kind)
    await send({"type": "http.response.start", "status": status,
                "headers": [(b"content-type", b"application/json"),
                            (b"content-length", str(len(body)).encode())]})
    await send({"type": "http.response.body", "body": body})


class _TooLarge(BaseException):
    """Raised from ``receive`` past the cap. A ``BaseException``, so that no handler on the
    way (FastAPI answers 400 to any ``Exception`` while reading a body) turns it into
    something else before this middleware answers 413."""
