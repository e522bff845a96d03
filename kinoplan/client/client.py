"""``Client``: the service's REST API from Python, numpy arrays in and out.

A thin layer over HTTP (httpx): each method is one request, its body built from numpy
arrays or plain values, its answer decoded into arrays where the answer is an array. The
kinematics batch answers travel as ``.npy`` (``Accept: application/x-npy``): float64, no
text round trip. It never imports the service's code to talk to it (only ``Job.result``
may, to validate a result into its kind's model).

Units are the service's: mm, rad, s; poses 4x4 (batches ``(N, 4, 4)``); joint values in
the robot's joint order (``client.robot(id)["joints"]``).
"""

from __future__ import annotations

import io
import json
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import httpx
import numpy as np

from .errors import error_from_answer
from .jobs import Job

__all__ = ["Client", "DEFAULT_URL", "NPY"]

#: Where ``python -m kinoplan`` serves the API by default.
DEFAULT_URL = "http://127.0.0.1:8000"
#: The media type of the binary answers.
NPY = "application/x-npy"


def _plain(value: Any) -> Any:
    """What ``json.dumps`` cannot write itself: numpy arrays and scalars, paths."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"cannot send a {type(value).__name__} as JSON")


def _array(value: Any) -> np.ndarray:
    """A float64 array of a numeric answer field (None stays None: see callers)."""
    return np.asarray(value, dtype=np.float64)


def _with_arrays(data: dict[str, Any], keys: Sequence[str]) -> dict[str, Any]:
    """``data`` with the fields ``keys`` (when present and not null) as float64 arrays."""
    out = dict(data)
    for key in keys:
        if out.get(key) is not None:
            out[key] = _array(out[key])
    return out


def _upload(file: str | os.PathLike[str] | bytes, filename: str | None
            ) -> tuple[str, bytes]:
    """``(filename, bytes)`` of an upload given as a path or as bytes. For bytes without a
    name, the name the service needs to tell the format: a zip, a gzip'd tar, else URDF."""
    if isinstance(file, bytes | bytearray):
        data = bytes(file)
        if filename is None:
            filename = "robot.zip" if data[:2] == b"PK" else \
                "robot.tar.gz" if data[:2] == b"\x1f\x8b" else "robot.urdf"
        return filename, data
    path = Path(file)
    return filename or path.name, path.read_bytes()


class Client:
    """The kinoplan service at ``url``.

    ``api_key``: sent as ``Authorization: Bearer <key>`` (the service asks for it on
    requests that change state when it runs with ``KINOPLAN_API_KEY``); None reads the
    environment variable ``KINOPLAN_API_KEY``, and sends none when that is unset too.
    ``timeout``: seconds each request may take (connecting, and waiting for the answer).

    Use it as a context manager (``with Client() as c:``) or call ``close()``: it keeps
    one connection pool. Every failed request raises an ``ApiError`` (``status``,
    ``detail``, ``field``); a service that cannot be reached raises httpx's
    ``TransportError``. ``transport``: an httpx transport to use in place of the network
    (e.g. ``httpx.MockTransport`` in a test)."""

    def __init__(self, url: str = DEFAULT_URL, api_key: str | None = None,
                 timeout: float = 60.0, *, transport: httpx.BaseTransport | None = None
                 ) -> None:
        self.url = url.rstrip("/")
        key = api_key if api_key is not None else os.environ.get("KINOPLAN_API_KEY") or None
        headers = {"user-agent": "kinoplan-client"}
        if key:
            headers["authorization"] = f"Bearer {key}"
        self._http = httpx.Client(base_url=self.url, headers=headers, timeout=timeout,
                                  transport=transport)

    def __repr__(self) -> str:
        return f"Client({self.url!r})"

    def __enter__(self) -> Client:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Close the connection pool."""
        self._http.close()

    # ---- HTTP --------------------------------------------------------------------------
    def _request(self, method: str, path: str, *, json_body: Any = None,
                 accept: str | None = None, **kwargs: Any) -> httpx.Response:
        """One request; ``ApiError`` for an answer of 400 or more."""
        headers = dict(kwargs.pop("headers", None) or {})
        if accept is not None:
            headers["accept"] = accept
        if json_body is not None:
            headers["content-type"] = "application/json"
            kwargs["content"] = json.dumps(json_body, default=_plain).encode()
        response = self._http.request(method, path, headers=headers, **kwargs)
        if response.status_code >= 400:
            raise error_from_answer(response.status_code, response.content, response.headers,
                                    method=method, url=path)
        return response

    def _json(self, method: str, path: str, **kwargs: Any) -> Any:
        """The answer's JSON (None for an empty answer, e.g. 204)."""
        response = self._request(method, path, **kwargs)
        return response.json() if response.content else None

    def _npy(self, path: str, body: Mapping[str, Any]) -> np.ndarray:
        """POST ``body`` asking for the ``.npy`` answer; the array."""
        response = self._request("POST", path, json_body=body, accept=NPY)
        media = response.headers.get("content-type", "")
        if not media.startswith(NPY):
            raise ValueError(f"POST {path} answered {media!r}, not {NPY}: a service of an "
                             "older version?")
        return np.load(io.BytesIO(response.content), allow_pickle=False)

    def request(self, method: str, path: str, json: Any = None, **kwargs: Any) -> Any:
        """Any endpoint: ``method`` on ``path`` (e.g. ``"/robots/glt_palletizer/collision"``)
        with ``json`` as its body (numpy arrays allowed); the answer's JSON. For the routes
        this class has no method for."""
        return self._json(method, path, json_body=json, **kwargs)

    # ---- service -----------------------------------------------------------------------
    def health(self) -> dict[str, Any]:
        """``GET /health``: version, jobs backend, store and pool state."""
        return self._json("GET", "/health")

    # ---- robots ------------------------------------------------------------------------
    def robots(self) -> list[dict[str, Any]]:
        """Every robot, built-in and custom: id, name, dof, builtin, joints, IK methods."""
        return self._json("GET", "/robots")

    def robot(self, robot_id: str) -> dict[str, Any]:
        """A robot's model JSON (the schema ``add_robot`` takes)."""
        return self._json("GET", f"/robots/{robot_id}")

    def add_robot(self, model: Mapping[str, Any]) -> dict[str, Any]:
        """Store a custom robot from its model JSON (D-H or PoE, with ``"id"``); the stored
        model."""
        return self._json("POST", "/robots", json_body=dict(model))

    def delete_robot(self, robot_id: str) -> None:
        """Delete a custom robot (built-ins are read-only: ``ForbiddenError``)."""
        self._request("DELETE", f"/robots/{robot_id}")

    def import_robot(self, file: str | os.PathLike[str] | bytes, robot_id: str, *,
                     filename: str | None = None, name: str | None = None,
                     urdf: str | None = None, base_link: str | None = None,
                     tip_link: str | None = None,
                     srdf: str | os.PathLike[str] | bytes | None = None,
                     group: str | None = None,
                     fixed_joints: Mapping[str, float] | None = None) -> dict[str, Any]:
        """Import a robot from a URDF file, or a .zip / .tar.gz holding the URDF and its
        meshes (``POST /robots/import``); the stored model.

        ``file``: a path, or the file's bytes (``filename`` then tells the format; guessed
        from the bytes when not given). The other options are the route's: which URDF of an
        archive, the chain's base and tip links, an SRDF (path or bytes) and its group,
        values of the movable joints off the chain."""
        files = {"file": _upload(file, filename)}
        if srdf is not None:
            files["srdf"] = _upload(srdf, "robot.srdf" if isinstance(srdf, bytes) else None)
        form: dict[str, str] = {"id": robot_id}
        for key, value in (("name", name), ("urdf", urdf), ("base_link", base_link),
                           ("tip_link", tip_link), ("group", group)):
            if value is not None:
                form[key] = value
        if fixed_joints is not None:
            form["fixed_joints"] = json.dumps(dict(fixed_joints), default=_plain)
        return self._json("POST", "/robots/import", files=files, data=form)

    def robot_urdf(self, robot_id: str) -> str:
        """The robot as URDF XML (metres)."""
        return self._request("GET", f"/robots/{robot_id}/urdf").text

    # ---- kinematics --------------------------------------------------------------------
    def fk(self, robot_id: str, q: Any, *, frames: str = "tool") -> np.ndarray:
        """Tool poses of configurations ``q``: ``(dof,)`` gives ``(4, 4)``, ``(N, dof)``
        gives ``(N, 4, 4)``. ``frames="all"``: every frame, ``(dof + 1, 4, 4)`` or
        ``(N, dof + 1, 4, 4)`` (the base, then the frame after each joint; the last is the
        tool pose). Sent as JSON, answered as ``.npy``."""
        q = np.asarray(q, dtype=np.float64)
        out = self._npy(f"/robots/{robot_id}/fk", {"q": q, "frames": frames})
        return out[0] if q.ndim == 1 else out

    def jacobian(self, robot_id: str, q: Any) -> np.ndarray:
        """The geometric Jacobian ``(6, dof)`` at one configuration (rows vx, vy, vz in mm
        per joint unit, then wx, wy, wz; world frame)."""
        return self._npy(f"/robots/{robot_id}/jacobian",
                         {"q": np.asarray(q, dtype=np.float64)})

    def ik(self, robot_id: str, pose: Any, *, q0: Any = None, method: str = "auto"
           ) -> np.ndarray:
        """The best joint solution of each target pose: ``(4, 4)`` gives ``(dof,)``,
        ``(N, 4, 4)`` gives ``(N, dof)``; NaN where a pose has no solution (``ik_results``
        says why). ``q0``: the configuration solutions are preferred near; ``method``:
        ``auto``, ``analytic``, ``numeric`` or ``learned``."""
        pose = np.asarray(pose, dtype=np.float64)
        body: dict[str, Any] = {"pose": pose, "method": method}
        if q0 is not None:
            body["q0"] = np.asarray(q0, dtype=np.float64)
        out = self._npy(f"/robots/{robot_id}/ik", body)
        return out[0] if pose.ndim == 2 else out

    def ik_results(self, robot_id: str, pose: Any, *, q0: Any = None, method: str = "auto",
                   all_solutions: bool = False) -> list[dict[str, Any]]:
        """One result per target pose, as JSON with ``q`` (``(dof,)`` or None) and
        ``solutions`` (``(K, dof)``) as arrays: success, status, errors, message.
        ``all_solutions``: every branch the closed forms give, not only the best."""
        body: dict[str, Any] = {"pose": np.asarray(pose, dtype=np.float64), "method": method,
                                "all_solutions": all_solutions}
        if q0 is not None:
            body["q0"] = np.asarray(q0, dtype=np.float64)
        results = self._json("POST", f"/robots/{robot_id}/ik", json_body=body)["results"]
        return [_with_arrays(r, ("q", "solutions")) for r in results]

    def workspace(self, robot_id: str, samples: int = 10_000, *, seed: int = 0,
                  voxel: float | None = None, return_points: int = 20_000) -> np.ndarray:
        """Points the tool reaches, ``(M, 3)`` mm: ``samples`` random configurations (seeded),
        ``return_points`` of them. ``request("POST", f"/robots/{id}/workspace", {...})``
        answers the extents and volume too."""
        body: dict[str, Any] = {"samples": samples, "seed": seed,
                                "return_points": return_points, "projections": False}
        if voxel is not None:
            body["voxel"] = voxel
        return self._npy(f"/robots/{robot_id}/workspace", body)

    # ---- scenes ------------------------------------------------------------------------
    def store_scene(self, scene_id: str, objects: Sequence[Mapping[str, Any]] | None = None,
                    *, name: str | None = None, moveit: Mapping[str, Any] | None = None
                    ) -> dict[str, Any]:
        """Store a scene (``POST /scenes``): ``objects`` (mm, 4x4 ``pose`` arrays allowed)
        and/or a MoveIt PlanningScene (``moveit``, metres); the scene as stored."""
        body: dict[str, Any] = {"id": scene_id}
        if name is not None:
            body["name"] = name
        if objects is not None:
            body["objects"] = [dict(o) for o in objects]
        if moveit is not None:
            body["moveit"] = dict(moveit)
        return self._json("POST", "/scenes", json_body=body)

    def scene(self, scene_id: str, format: str = "objects") -> dict[str, Any]:
        """A stored scene; ``format="moveit"``: as a MoveIt PlanningScene (metres)."""
        return self._json("GET", f"/scenes/{scene_id}", params={"format": format})

    def scenes(self) -> list[dict[str, Any]]:
        """Every stored scene: id, name, object count."""
        return self._json("GET", "/scenes")

    def delete_scene(self, scene_id: str) -> None:
        """Delete a stored scene."""
        self._request("DELETE", f"/scenes/{scene_id}")

    # ---- motion and trajectories -------------------------------------------------------
    def motion(self, robot_id: str, start: Any, goal: Any, *,
               scene: str | Mapping[str, Any] | None = None, time_limit: float | None = None,
               **settings: Any) -> dict[str, Any]:
        """Plan a collision-free joint-space move (``POST /robots/{id}/motion``, at most 2 s
        of planning; longer ones: ``submit("motion", ...)``).

        ``goal``: joint values ``(dof,)``, a tool pose ``(4, 4)`` (the planner picks the IK
        branch), or the route's ``{"q": ...}`` / ``{"pose": ...}``. ``scene``: a stored
        scene's id, ``{"objects": [...]}`` or None. ``settings``: the route's other fields
        (``planner``, ``seed``, ``resolution``, ``simplify``, ``margin``, ...).

        The answer's JSON with arrays: ``path`` ``(K, dof)``, ``goal`` ``(dof,)`` and
        ``trajectory``'s ``t``, ``q``, ``qd``, ``qdd``. Every planner status (``ok``,
        ``goal_unreachable``, ...) is an answer, not an error."""
        if not isinstance(goal, Mapping):
            g = np.asarray(goal, dtype=np.float64)
            goal = {"pose": g} if g.ndim == 2 else {"q": g}
        body: dict[str, Any] = {"start": np.asarray(start, dtype=np.float64),
                                "goal": dict(goal), "scene": scene, **settings}
        if time_limit is not None:
            body["time_limit"] = time_limit
        out = self._json("POST", f"/robots/{robot_id}/motion", json_body=body)
        return _motion_arrays(out)

    def motion_replay(self, robot_id: str, answer: Mapping[str, Any],
                      scene: str | Mapping[str, Any] | None = None) -> str:
        """An answer of ``motion`` as one self-contained HTML page that plays it offline
        (``POST /robots/{id}/motion/replay.html``), with ``scene`` (as planned in) drawn."""
        body = {"answer": {"robot": answer.get("robot", robot_id),
                           "trajectory": answer.get("trajectory")}, "scene": scene}
        return self._request("POST", f"/robots/{robot_id}/motion/replay.html",
                             json_body=body).text

    def trajectory(self, waypoints: Any, durations: Any = None, *, method: str = "quintic",
                   dt: float = 0.01, robot: str | None = None, **fields: Any
                   ) -> dict[str, Any]:
        """A joint trajectory through ``waypoints`` ``(W, dof)`` (``POST /trajectories``),
        ``durations`` ``(W - 1,)`` s per segment, sampled every ``dt``; ``robot``: check its
        limits; ``fields``: the route's others (``time_scaling``, ``limits``, ``profile``,
        ...). The answer's JSON with ``t`` ``(S,)`` and ``q``, ``qd``, ``qdd``, ``qddd``
        ``(S, dof)`` as arrays, and its continuity and limit reports."""
        body: dict[str, Any] = {"method": method, "waypoints": np.asarray(waypoints, float),
                                "dt": dt, **fields}
        if durations is not None:
            body["durations"] = np.asarray(durations, dtype=np.float64).reshape(-1)
        if robot is not None:
            body["robot"] = robot
        out = self._json("POST", "/trajectories", json_body=body)
        return _with_arrays(out, ("t", "q", "qd", "qdd", "qddd", "durations"))

    # ---- jobs --------------------------------------------------------------------------
    def submit(self, kind: str, params: Mapping[str, Any] | None = None, *,
               time_limit_s: float | None = None) -> Job:
        """Queue a job of ``kind`` (``job_kinds()``) with ``params`` (numpy arrays allowed);
        its ``Job``. The params are checked before the job is queued: ``InvalidError``
        naming the field (``["body", "params", ...]``)."""
        body: dict[str, Any] = {"kind": kind, "params": dict(params or {})}
        if time_limit_s is not None:
            body["time_limit_s"] = time_limit_s
        record = self._json("POST", "/jobs", json_body=body)
        return Job(self, record["id"], record.get("kind", kind), record)

    def job(self, job_id: str) -> Job:
        """The job ``job_id`` (``NotFoundError`` when the service does not know it)."""
        job = Job(self, job_id)
        job.record()
        return job

    def jobs(self, *, status: str | None = None, kind: str | None = None,
             limit: int | None = None, offset: int = 0) -> list[dict[str, Any]]:
        """Job records oldest first (without results): one page of ``limit`` (the service's
        default 100, at most 1,000) from ``offset``, of a ``status`` and ``kind`` if given."""
        params: dict[str, Any] = {"offset": offset}
        for key, value in (("status", status), ("kind", kind), ("limit", limit)):
            if value is not None:
                params[key] = value
        return self._json("GET", "/jobs", params=params)

    def job_kinds(self) -> list[dict[str, Any]]:
        """The job kinds: description and the JSON schemas of their params and result."""
        return self._json("GET", "/jobs/kinds")


def _motion_arrays(out: dict[str, Any]) -> dict[str, Any]:
    """A motion answer with its path, goal and trajectory as arrays (an empty path as
    ``(0, dof)``)."""
    out = _with_arrays(out, ("goal",))
    dof = len(out.get("joints") or ()) or None
    path = np.asarray(out.get("path") or [], dtype=np.float64)
    out["path"] = path.reshape(0, dof) if path.size == 0 and dof else path
    if isinstance(out.get("trajectory"), dict):
        out["trajectory"] = _with_arrays(out["trajectory"], ("t", "q", "qd", "qdd"))
    return out
