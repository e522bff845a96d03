"""Every process ``python -m kinoplan`` starts dies with it, also when it is SIGKILLed
(``app.lifetime``).

The service runs in a session of its own (``Service``) while an imported robot's collision
model is being built in a compute worker and a job step runs in the local backend; then only
its main process is killed, as the out-of-memory killer would. Within 5 s none of the
processes it had started (forkserver, compute workers, job steps, multiprocessing's resource
tracker) may be left. The robot is made here: the GLT palletizer as URDF with trimesh
capsules as the collision meshes of its arm links.
"""

from __future__ import annotations

import contextlib
import io
import time
import zipfile
from collections.abc import Iterable

import httpx
import psutil
import pytest

from kinematics.library import builtin_model
from kinematics.urdf import to_urdf

from .cluster import cpu_seconds, descendants, describe, kill_tree, process_group
from .conftest import Service, wait_for

trimesh = pytest.importorskip("trimesh")

#: Arm links that get a capsule mesh: (length, radius) in m.
CAPSULES = {"base_link": (0.3, 0.16), "link_1": (0.4, 0.12), "link_2": (0.9, 0.08),
            "link_3": (0.8, 0.07), "link_4": (0.3, 0.06), "link_5": (0.2, 0.05),
            "link_6": (0.2, 0.045)}
#: Seconds the processes of a killed service may take to end.
GRACE_S = 5.0


def _meshed_arm() -> bytes:
    """A zip of the URDF and its STL meshes, as ``POST /robots/import`` takes it."""
    text = to_urdf(builtin_model("glt_palletizer"))
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        for link, (length, radius) in CAPSULES.items():
            path = f"arm/meshes/{link}.stl"
            mesh = trimesh.creation.capsule(height=length, radius=radius, count=[24, 24])
            z.writestr(path, mesh.export(file_type="stl"))
            geometry = f'<geometry><mesh filename="package://{path}"/></geometry>'
            text = text.replace(f'<link name="{link}" />',
                                f'<link name="{link}"><collision>{geometry}</collision></link>')
        z.writestr("arm/urdf/arm.urdf", text)
    return buf.getvalue()


def _running(procs: Iterable[psutil.Process]) -> list[psutil.Process]:
    """Those of ``procs`` still running (a zombie has ended: it only waits to be reaped)."""
    out = []
    for p in procs:
        with contextlib.suppress(psutil.Error):
            if p.is_running() and p.status() != psutil.STATUS_ZOMBIE:
                out.append(p)
    return out


def _forkserver_children(service: int, n: int, timeout: float = 60.0) -> list[psutil.Process]:
    """The processes the service's forkserver has forked, once there are at least ``n``."""
    deadline = time.monotonic() + timeout
    while True:
        servers = [p for p in _running(descendants(service))
                   if "multiprocessing.forkserver" in " ".join(p.cmdline())
                   and p.ppid() == service]
        children = _running(servers[0].children()) if servers else []
        if len(children) >= n:
            return children
        assert time.monotonic() < deadline, f"forkserver children: {children}"
        time.sleep(0.1)


@pytest.mark.cluster
def test_a_killed_service_leaves_no_process_behind(tmp_path):
    svc = Service(tmp_path, "--workers", "1")
    try:
        client = httpx.Client(base_url=svc.url, timeout=120)
        r = client.post("/robots/import", data={"id": "meshed_arm"},
                        files={"file": ("arm.zip", _meshed_arm(), "application/zip")})
        assert r.status_code == 201, r.text
        # Imported: its collision model is being built now, in a compute worker. A step that
        # sleeps without reporting stands for one that computes for long.
        job = client.post("/jobs", json={"kind": "sleep",
                                         "params": {"seconds": 120, "steps": 1}}).json()
        wait_for(client, job["id"], statuses=("running",))
        children = _forkserver_children(svc.proc.pid, 2)  # a compute worker, the job step
        busy = cpu_seconds([p.pid for p in children], window=1.0)
        assert max(busy.values()) > 0.1, f"no collision model being built: {busy}"
        started = _running(descendants(svc.proc.pid))
        commands = " ".join(" ".join(p.cmdline()) for p in started)
        assert "multiprocessing.resource_tracker" in commands

        svc.proc.kill()  # the main process only
        svc.proc.wait(timeout=10)
        deadline = time.monotonic() + GRACE_S
        left = _running({*started, *process_group(svc.proc.pid)})
        while left and time.monotonic() < deadline:
            time.sleep(0.1)
            left = _running(left)
        assert not left, (f"{len(left)} of the {len(started)} processes the service had "
                          f"started still run {GRACE_S:g} s after it was killed: "
                          f"{[describe(p) for p in left]}")
    finally:
        kill_tree(svc.proc)
