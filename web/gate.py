"""The viewer's public port: a small front that checks each connection, then relays it.

viser serves its page, its assets and its websocket on one port and checks nothing. The viewer
therefore runs viser on an internal loopback port and puts this front on the public one
(``Viewer.start(host, port, ...)``). For every TCP connection the front reads the HTTP request
head (at most ``HEAD_LIMIT`` bytes within ``HEAD_TIMEOUT_S``), decides, and then either answers
itself (401, 403, a redirect, 4xx for malformed requests) or relays the bytes both ways to
viser. Static files and the websocket upgrade go through the same decision:

* **Origin.** A request carrying an ``Origin`` header must come from an allowed origin (403
  otherwise, with or without a key). The allowed origins are the configured ones
  (``KINOPLAN_ALLOWED_ORIGINS``), else the viewer's own: ``http://<host>:<port>``, plus
  ``http://localhost:<port>``, ``http://127.0.0.1:<port>`` and ``http://[::1]:<port>`` on a
  loopback bind; bound to every interface (``0.0.0.0``, ``::``, as in the container), an
  origin naming the very host and port the request was sent to (its ``Host`` header) is
  allowed too: with a key, any such name; without one, only an IP address or ``localhost``
  (a page of another site whose DNS name was rebound to this machine would name itself).
  Browsers always send ``Origin`` on a websocket upgrade; a request without one is not from
  another site's page.
* **Key.** With an API key configured, ``/?key=<key>`` (any path) checks the key in constant
  time, sets an HttpOnly, SameSite=Strict cookie holding ``session_token(key)`` (an HMAC of a
  fixed label under the key, not the key) and redirects (303) to the same address without the
  key. Later requests (assets, the websocket) pass with that cookie. Anything else gets a
  plain-text 401 saying how to open the viewer. Without a key the viewer is open (it binds to
  127.0.0.1 by default).
* **One request per connection.** Only ``GET`` without a body is relayed. After a plain
  request's head nothing more is read from the client (viser answers one request per
  connection and closes it), so a pipelined second request is never seen by viser unchecked;
  only a websocket upgrade is relayed both ways.

The front adds a header carrying a per-process secret (``GATE_HEADER``) to what it relays, and
``lock_websockets_server`` makes viser's server refuse requests without it, so the internal
port is of no use to other pages in a browser or to other local processes.
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import gc
import hashlib
import hmac
import ipaddress
import logging
import re
import secrets
import threading
from collections.abc import Iterable
from dataclasses import dataclass
from urllib.parse import parse_qsl, urlencode, urlsplit

__all__ = [
    "Gate",
    "GatePolicy",
    "HeadError",
    "RequestHead",
    "parse_head",
    "normalize_origin",
    "parse_origins",
    "default_origins",
    "session_token",
    "lock_websockets_server",
    "GATE_HEADER",
    "HEAD_LIMIT",
    "HEAD_TIMEOUT_S",
    "MAX_CONNECTIONS",
]

log = logging.getLogger(__name__)

#: Largest request head read from a client (bytes) and the time it has to send it (s).
HEAD_LIMIT = 16 * 1024
HEAD_TIMEOUT_S = 10.0
#: Connections open at once; more are closed at once.
MAX_CONNECTIONS = 256
#: Time (s) to connect to the internal viser port.
UPSTREAM_TIMEOUT_S = 5.0
#: Ports tried after a busy one (as viser itself does) before giving up.
PORT_ATTEMPTS = 100
#: Header through which the front proves to viser that it relayed a request.
GATE_HEADER = "X-Kinoplan-Gate"
#: What the cookie's token is an HMAC of.
COOKIE_LABEL = b"kinoplan 3D viewer session v1"
KEY_PARAM = "key"

_TOKEN = re.compile(r"^[!#$%&'*+.^_`|~0-9A-Za-z-]+$")
_TARGET = re.compile(r"^/[\x21-\x7e]*$")
_WILDCARD_HOSTS = {"", "0.0.0.0", "::", "[::]"}
_LOOPBACK_NAMES = {"localhost"}
_REASONS = {303: "See Other", 400: "Bad Request", 401: "Unauthorized", 403: "Forbidden",
            405: "Method Not Allowed", 408: "Request Timeout",
            431: "Request Header Fields Too Large", 502: "Bad Gateway",
            503: "Service Unavailable"}

UNAUTHORIZED_TEXT = (
    "401 Unauthorized\n\n"
    "This 3D viewer needs the service's API key (KINOPLAN_API_KEY).\n"
    "Open this address with ?key=<API key> appended, e.g.\n\n"
    "    http://<viewer host>:<viewer port>/?key=<API key>\n\n"
    "The key is checked, kept in a cookie for this browser session (as a token derived\n"
    "from it, not the key itself) and removed from the address.\n"
)


class HeadError(ValueError):
    """A request head the front does not relay; ``status`` is the answer to give."""

    def __init__(self, status: int, message: str) -> None:
        super().__init__(message)
        self.status = status


@dataclass(frozen=True)
class RequestHead:
    """A parsed HTTP/1.x request head."""

    method: str
    target: str
    version: str
    headers: tuple[tuple[str, str], ...]

    def values(self, name: str) -> list[str]:
        name = name.lower()
        return [v for k, v in self.headers if k.lower() == name]

    def one(self, name: str) -> str | None:
        """The header's value; None if absent, 400 if given more than once."""
        found = self.values(name)
        if len(found) > 1:
            raise HeadError(400, f"more than one {name} header")
        return found[0] if found else None

    @property
    def is_upgrade(self) -> bool:
        return bool(self.values("upgrade"))

    def encode(self, extra: Iterable[tuple[str, str]] = (),
               drop: Iterable[str] = ()) -> bytes:
        """The head as bytes, without the headers named in ``drop``, plus ``extra``."""
        dropped = {d.lower() for d in drop}
        lines = [f"{self.method} {self.target} {self.version}"]
        lines += [f"{k}: {v}" for k, v in self.headers if k.lower() not in dropped]
        lines += [f"{k}: {v}" for k, v in extra]
        return ("\r\n".join(lines) + "\r\n\r\n").encode("latin-1")


def parse_head(data: bytes) -> RequestHead:
    """Parse a request head ending in a blank line. ``HeadError`` (400) if malformed."""
    if not data.endswith(b"\r\n\r\n"):
        raise HeadError(400, "the request head does not end with a blank line")
    text = data[:-4].decode("latin-1")
    lines = text.split("\r\n")
    if any("\r" in line or "\n" in line or "\x00" in line for line in lines):
        raise HeadError(400, "bare CR, LF or NUL in the request head")
    parts = lines[0].split(" ")
    if len(parts) != 3 or parts[2] not in ("HTTP/1.1", "HTTP/1.0"):
        raise HeadError(400, "malformed request line")
    method, target, version = parts
    if not _TOKEN.match(method):
        raise HeadError(400, "malformed method")
    if not _TARGET.match(target) or target.startswith("//"):
        raise HeadError(400, "the request target must be a path (origin form)")
    headers = []
    for line in lines[1:]:
        name, sep, value = line.partition(":")
        if not sep or not _TOKEN.match(name):
            raise HeadError(400, "malformed header line")
        headers.append((name, value.strip(" \t")))
    return RequestHead(method, target, version, tuple(headers))


# ---- origins -------------------------------------------------------------------------------
def _default_port(scheme: str) -> int:
    return 443 if scheme in ("https", "wss") else 80


def _host_port(netloc: str, scheme: str) -> tuple[str, int]:
    parsed = urlsplit(f"//{netloc}")
    try:
        port = parsed.port
    except ValueError as exc:
        raise ValueError(f"bad port in '{netloc}'") from exc
    host = (parsed.hostname or "").lower()
    if not host:
        raise ValueError(f"no host in '{netloc}'")
    return host, _default_port(scheme) if port is None else port


def _netloc(host: str, port: int, scheme: str) -> str:
    shown = f"[{host}]" if ":" in host else host
    return shown if port == _default_port(scheme) else f"{shown}:{port}"


def normalize_origin(origin: str) -> str:
    """``scheme://host[:port]`` as browsers send it: lower case, no default port, no path.
    ValueError for anything that is not an http(s) origin."""
    text = origin.strip()
    parts = urlsplit(text)
    scheme = parts.scheme.lower()
    if scheme not in ("http", "https"):
        raise ValueError(f"origin '{origin}' must start with http:// or https://")
    if parts.path not in ("", "/") or parts.query or parts.fragment or "@" in parts.netloc:
        raise ValueError(f"origin '{origin}' must be scheme://host[:port] with no path, "
                         "query or user")
    host, port = _host_port(parts.netloc, scheme)
    return f"{scheme}://{_netloc(host, port, scheme)}"


def parse_origins(origins: str | Iterable[str] | None) -> tuple[str, ...] | None:
    """Origins from a comma-separated string or a list, normalized; None when none is given
    (the defaults apply). ValueError for a malformed one."""
    if origins is None:
        return None
    items = origins.split(",") if isinstance(origins, str) else list(origins)
    found = tuple(normalize_origin(o) for o in items if o.strip())
    return found or None


def _is_address(host: str) -> bool:
    """An IP address literal or ``localhost``."""
    name = host.strip("[]").lower()
    if name in _LOOPBACK_NAMES:
        return True
    try:
        ipaddress.ip_address(name)
    except ValueError:
        return False
    return True


def _is_loopback(host: str) -> bool:
    name = host.strip("[]").lower()
    if name in _LOOPBACK_NAMES:
        return True
    try:
        return ipaddress.ip_address(name).is_loopback
    except ValueError:
        return False


def default_origins(host: str, port: int) -> tuple[frozenset[str], bool]:
    """The viewer's own origins for a bind address and port, and whether an origin naming the
    request's own ``Host`` is allowed too (binds to every interface)."""
    name = host.strip("[]").lower()
    wildcard = host in _WILDCARD_HOSTS
    origins = set()
    if not wildcard:
        origins.add(normalize_origin(f"http://{_netloc(name, port, 'http')}"))
    if wildcard or _is_loopback(name):
        origins |= {f"http://localhost:{port}", f"http://127.0.0.1:{port}",
                    f"http://[::1]:{port}"}
    return frozenset(normalize_origin(o) for o in origins), wildcard


def session_token(api_key: str) -> str:
    """What the viewer's cookie holds: an HMAC of a fixed label under the key."""
    return hmac.new(api_key.encode(), COOKIE_LABEL, hashlib.sha256).hexdigest()


# ---- the decision --------------------------------------------------------------------------
def _response(status: int, text: str = "", headers: Iterable[tuple[str, str]] = ()) -> bytes:
    body = (text or f"{status} {_REASONS.get(status, '')}\n").encode()
    lines = [f"HTTP/1.1 {status} {_REASONS.get(status, 'Error')}",
             "Content-Type: text/plain; charset=utf-8", f"Content-Length: {len(body)}",
             "Cache-Control: no-store", "X-Content-Type-Options: nosniff",
             "Referrer-Policy: no-referrer", "Connection: close"]
    lines += [f"{k}: {v}" for k, v in headers]
    return ("\r\n".join(lines) + "\r\n\r\n").encode("latin-1") + body


@dataclass(frozen=True)
class Relay:
    """Relay the connection: send ``head`` to viser; both ways if ``both_ways``."""

    head: bytes
    both_ways: bool


@dataclass(frozen=True)
class Answer:
    """Answer the client with ``data`` and close."""

    status: int
    data: bytes


class GatePolicy:
    """What the front decides for a request head (no I/O; thread-safe)."""

    def __init__(self, *, port: int, host: str, api_key: str | None = None,
                 allowed_origins: str | Iterable[str] | None = None,
                 upstream_secret: str = "") -> None:
        self.api_key = api_key or None
        configured = parse_origins(allowed_origins)
        if configured:
            self.origins = frozenset(configured)
            self.same_host = False
        else:
            self.origins, self.same_host = default_origins(host, port)
        self.cookie_name = f"kinoplan_viewer_{port}"
        self._token = session_token(self.api_key) if self.api_key else ""
        self.upstream_secret = upstream_secret

    def origin_allowed(self, origin: str, host_header: str | None) -> bool:
        try:
            normal = normalize_origin(origin)
        except ValueError:
            return False  # "null", file://, garbage
        if normal in self.origins:
            return True
        if self.same_host and host_header:
            # Bound to every interface: the page's own address is whatever the client used to
            # reach it (its Host header; behind a TLS proxy, the https origin of that host).
            # Without a key, only an address literal or localhost: a name could be another
            # site's, rebound by its DNS to this machine (with a key, its cookie is missing).
            scheme, _, netloc = normal.partition("://")
            try:
                theirs = _host_port(netloc, scheme)
                ours = _host_port(host_header.strip(), scheme)
            except ValueError:
                return False
            return theirs == ours and (self.api_key is not None or _is_address(ours[0]))
        return False

    def _has_cookie(self, head: RequestHead) -> bool:
        for header in head.values("cookie"):
            for part in header.split(";"):
                name, sep, value = part.strip().partition("=")
                if sep and name == self.cookie_name and hmac.compare_digest(
                        value.strip().strip('"').encode(), self._token.encode()):
                    return True
        return False

    def decide(self, head: RequestHead) -> Relay | Answer:
        if head.method != "GET":
            return Answer(405, _response(405, "The viewer serves GET requests only.\n",
                                         [("Allow", "GET")]))
        length = head.one("content-length")
        if head.values("transfer-encoding") or (length is not None and length.strip() != "0"):
            return Answer(400, _response(400, "A viewer request has no body.\n"))
        origin = head.one("origin")
        if origin is not None and not self.origin_allowed(origin, head.one("host")):
            return Answer(403, _response(
                403, f"Origin '{origin}' is not allowed to use this viewer "
                "(KINOPLAN_ALLOWED_ORIGINS).\n"))
        if self.api_key is not None:
            parts = urlsplit(head.target)
            query = parse_qsl(parts.query, keep_blank_values=True)
            keys = [v for k, v in query if k == KEY_PARAM]
            if keys:
                if len(keys) != 1 or not hmac.compare_digest(keys[0].encode(),
                                                             self.api_key.encode()):
                    return Answer(401, _response(401, UNAUTHORIZED_TEXT))
                rest = urlencode([(k, v) for k, v in query if k != KEY_PARAM])
                location = "/" + parts.path.lstrip("/\\") + (f"?{rest}" if rest else "")
                cookie = (f"{self.cookie_name}={self._token}; Path=/; HttpOnly; "
                          "SameSite=Strict")
                return Answer(303, _response(303, "The key is right: opening the viewer.\n",
                                             [("Location", location), ("Set-Cookie", cookie)]))
            if not self._has_cookie(head):
                return Answer(401, _response(401, UNAUTHORIZED_TEXT))
        forwarded = head.encode(extra=[(GATE_HEADER, self.upstream_secret)], drop=[GATE_HEADER])
        return Relay(forwarded, head.is_upgrade)


# ---- the server ----------------------------------------------------------------------------
class Gate:
    """The front on ``host:port`` (0: any free port) relaying to ``127.0.0.1:upstream_port``.
    Runs its own event loop on a daemon thread; ``start`` returns once it listens."""

    def __init__(self, host: str, port: int, upstream_port: int, *, api_key: str | None = None,
                 allowed_origins: str | Iterable[str] | None = None,
                 upstream_secret: str = "") -> None:
        self.host = host
        self.requested_port = port
        self.upstream_port = upstream_port
        self._api_key = api_key
        self._allowed = parse_origins(allowed_origins)  # ValueError now, not at a request
        self._secret = upstream_secret
        self.policy: GatePolicy | None = None
        self.port = 0
        self._loop: asyncio.AbstractEventLoop | None = None
        self._server: asyncio.AbstractServer | None = None
        self._thread: threading.Thread | None = None
        self._tasks: set[asyncio.Task] = set()

    # lifecycle --------------------------------------------------------------------------
    def start(self) -> Gate:
        ready = threading.Event()
        failure: list[BaseException] = []
        loop = asyncio.new_event_loop()
        self._loop = loop

        def run() -> None:
            asyncio.set_event_loop(loop)
            try:
                loop.run_until_complete(self._listen())
            except BaseException as exc:  # reported to start()
                failure.append(exc)
                ready.set()
                loop.close()
                return
            ready.set()
            loop.run_forever()
            loop.close()

        self._thread = threading.Thread(target=run, name="viewer-gate", daemon=True)
        self._thread.start()
        ready.wait()
        if failure:
            raise failure[0]
        return self

    async def _listen(self) -> None:
        port = self.requested_port
        for attempt in range(PORT_ATTEMPTS if port else 1):
            try:
                self._server = await asyncio.start_server(
                    self._handle, self.host or None, port + attempt if port else 0,
                    limit=HEAD_LIMIT, reuse_address=True)
                break
            except OSError as exc:
                if exc.errno != errno.EADDRINUSE or attempt == PORT_ATTEMPTS - 1 or not port:
                    raise
        assert self._server is not None
        self.port = self._server.sockets[0].getsockname()[1]
        if port and self.port != port:
            log.warning("viewer port %d is busy: the viewer listens on %d", port, self.port)
        self.policy = GatePolicy(port=self.port, host=self.host, api_key=self._api_key,
                                 allowed_origins=self._allowed, upstream_secret=self._secret)

    def stop(self) -> None:
        loop, thread = self._loop, self._thread
        if loop is None or thread is None or loop.is_closed():
            return

        async def shutdown() -> None:
            if self._server is not None:
                self._server.close()
            for task in list(self._tasks):
                task.cancel()
            if self._tasks:
                await asyncio.wait(list(self._tasks), timeout=2.0)

        with contextlib.suppress(Exception):
            asyncio.run_coroutine_threadsafe(shutdown(), loop).result(timeout=5.0)
        with contextlib.suppress(RuntimeError):
            loop.call_soon_threadsafe(loop.stop)
        thread.join(timeout=5.0)

    # connections ------------------------------------------------------------------------
    async def _handle(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        task = asyncio.current_task()
        if len(self._tasks) >= MAX_CONNECTIONS or task is None:
            writer.transport.abort()
            return
        self._tasks.add(task)
        upstream: asyncio.StreamWriter | None = None
        try:
            answer = await self._read_and_decide(reader)
            if isinstance(answer, Answer):
                writer.write(answer.data)
                await writer.drain()
                return
            try:
                up_reader, upstream = await asyncio.wait_for(
                    asyncio.open_connection("127.0.0.1", self.upstream_port),
                    UPSTREAM_TIMEOUT_S)
            except (OSError, TimeoutError):
                writer.write(_response(502, "The viewer is not running.\n"))
                await writer.drain()
                return
            upstream.write(answer.head)
            await upstream.drain()
            pumps = [asyncio.ensure_future(_pump(up_reader, writer))]
            if answer.both_ways:
                pumps.append(asyncio.ensure_future(_pump(reader, upstream)))
            try:
                await asyncio.wait(pumps, return_when=asyncio.FIRST_COMPLETED)
            finally:
                for p in pumps:
                    p.cancel()
        except (OSError, asyncio.IncompleteReadError):
            pass  # the client went away
        except asyncio.CancelledError:
            pass  # stopping; a cancelled connection task would be logged as an error
        finally:
            self._tasks.discard(task)
            for w in (upstream, writer):
                if w is not None:
                    with contextlib.suppress(Exception):
                        w.close()

    async def _read_and_decide(self, reader: asyncio.StreamReader) -> Relay | Answer:
        assert self.policy is not None
        try:
            data = await asyncio.wait_for(reader.readuntil(b"\r\n\r\n"), HEAD_TIMEOUT_S)
        except TimeoutError:
            return Answer(408, _response(408, "The request head took too long.\n"))
        except (asyncio.LimitOverrunError, ValueError):
            return Answer(431, _response(431, f"The request head is over {HEAD_LIMIT} "
                                              "bytes.\n"))
        try:
            return self.policy.decide(parse_head(data))
        except HeadError as exc:
            return Answer(exc.status, _response(exc.status, f"{exc}\n"))


async def _pump(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
    with contextlib.suppress(OSError, asyncio.IncompleteReadError):
        while data := await reader.read(65536):
            writer.write(data)
            await writer.drain()


# ---- the internal port ---------------------------------------------------------------------
def lock_websockets_server(port: int, secret: str, header: str = GATE_HEADER) -> bool:
    """Make the websockets server listening on ``port`` in this process (viser's) answer 403
    to any request whose ``header`` is not ``secret``. True if the server was found.

    viser builds its ``websockets.asyncio.server.Server`` inside its own thread and keeps no
    reference to it; the server reads its ``process_request`` hook for every connection, so
    the hook is wrapped once on the instance found among the live objects."""
    from websockets.asyncio.server import Server

    for obj in gc.get_objects():
        if not isinstance(obj, Server):
            continue
        try:
            ports = {s.getsockname()[1] for s in obj.sockets}
        except (OSError, RuntimeError, AttributeError, IndexError):
            continue
        if port not in ports:
            continue
        obj.process_request = _require_header(obj.process_request, header, secret)
        return True
    return False


def _require_header(original, header: str, secret: str):
    """A ``process_request`` hook: 403 unless ``header`` is ``secret``, else ``original``."""
    expected = secret.encode()

    def guarded(connection, request):
        given = request.headers.get_all(header)
        if not expected or len(given) != 1 or not hmac.compare_digest(given[0].encode(),
                                                                      expected):
            return connection.respond(403, "Open the viewer on its public port.\n")
        return None if original is None else original(connection, request)

    return guarded


def new_secret() -> str:
    """A fresh secret for ``GATE_HEADER``."""
    return secrets.token_hex(32)
