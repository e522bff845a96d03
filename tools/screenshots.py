"""The steps the viewer's screenshot scripts share (``screenshot_round.py``,
``screenshot_pallet.py``, ``screenshot_piles.py``): plan a job in this process as a worker
plans it, show its plan in the viewer (viser, on a free loopback port, without the
environment map so nothing is fetched), and have Playwright drive Debian's Chromium
(``tests/web/chromium_setup.py``'s flags) to take the picture from a given camera.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import tempfile
import time
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--disable-quic",
                 "--no-first-run"]
#: The panel's folders folded before the picture, so the panel shows the plan's text (any
#: ``Joints of <robot>`` folder is folded too).
FOLDED = ("IK: drag the gizmo at the tool", "Workspace", "Work cycle")


def run_job(kind: str, params: dict, robot: str | None = None) -> tuple[dict, dict]:
    """The job's stored params and its result, ``kind`` run here as a worker runs it
    (``robot``: the built-in robot whose model the worker is handed, if the kind takes one)."""
    from app.jobs.catalog import KINDS
    from app.jobs.kinds import JobPayload, execute
    from kinematics.library import builtin_model

    checked = KINDS[kind].load_params(params)
    payload = JobPayload(params=checked.model_dump(mode="json"),
                         robot_model=builtin_model(robot).to_dict() if robot else None)
    result = json.loads(execute(kind, payload.model_dump(mode="json"),
                                lambda fraction, message: None))
    return checked.model_dump(mode="json"), result


def screenshot(kind: str, params: dict, result: dict, out: str | Path, *, job: str,
               camera: tuple[float, float, float], look_at: tuple[float, float, float],
               wait_node: str, time_s: float | None = None, width: int = 1280,
               height: int = 860, hide_robot: bool = False,
               folded: Iterable[str] = FOLDED,
               ready: Callable[[Any], None] | None = None) -> None:
    """Draw the finished job (``kind``, its stored ``params`` and ``result``) in a fresh
    viewer and write what Chromium shows to ``out`` (PNG).

    ``time_s``: the plan's moment shown (None: its start); ``camera`` and ``look_at``: the
    camera's position and target, m in the viewer's world; ``wait_node``: a scene node of
    the plan waited for before the picture; ``hide_robot``: hide the robot model (a plan
    that draws its arms itself); ``ready``: called with the viewer once the plan is shown
    and put at ``time_s``, before the picture.
    """
    from playwright.sync_api import sync_playwright

    from app.config import Settings
    from app.main import create_app
    from kinematics.library import builtin_model
    from web.results import plan_from_result
    from web.viewer import Viewer

    chromium = shutil.which("chromium") or "/usr/bin/chromium"
    with tempfile.TemporaryDirectory() as data:
        app = create_app(Settings(no_viewer=True, data_dir=Path(data), workers=1))
        viewer = Viewer.start("127.0.0.1", 0, app.state, environment_map=False)
        try:
            viewer.show_plan(plan_from_result(kind, params, result, job=job,
                                              models=builtin_model,
                                              rigs=app.state.registry.rigs))
            if time_s is not None:
                viewer.set_time(time_s)
            viewer.gizmo.visible = False       # the IK gizmo would hide the plan
            if hide_robot:
                for arm in viewer._arms.values():
                    for handle in arm.nodes.handles.values():
                        handle.visible = False
            if ready is not None:
                ready(viewer)
            with sync_playwright() as p:
                browser = p.chromium.launch(executable_path=chromium, args=CHROMIUM_ARGS)
                page = browser.new_page(viewport={"width": width, "height": height})
                page.set_default_timeout(60_000)
                page.goto(f"http://127.0.0.1:{viewer.port}")
                page.bring_to_front()
                page.get_by_text("Connected").wait_for()
                page.wait_for_function(
                    "node => window.__viserSceneTree !== undefined && "
                    "node in window.__viserSceneTree.getState()", arg=wait_node)
                page.wait_for_function(
                    "() => { const c = document.querySelector('canvas');"
                    " return c && getComputedStyle(c).opacity === '1'; }")
                time.sleep(1.0)                # the viewer frames the page's canvas first
                for client in viewer.server.get_clients().values():
                    client.camera.position = camera
                    client.camera.look_at = look_at
                # The panel shows the plan's text: the other folders folded, the notice
                # about software rendering closed.
                titles = [*folded, re.compile(r"^Joints of ")]
                for title in titles:
                    found = page.get_by_text(title, exact=True) if isinstance(title, str) \
                        else page.get_by_text(title)
                    if found.count():
                        found.first.click()
                page.evaluate(
                    """() => document.querySelectorAll('.mantine-Notification-root, '
                       + '.mantine-Notifications-notification').forEach(e => e.remove())""")
                time.sleep(2.0)                # let the frame render
                out = Path(out)
                out.parent.mkdir(parents=True, exist_ok=True)
                page.screenshot(path=str(out))
                browser.close()
        finally:
            viewer.stop()


def parser(doc: str, out: str) -> argparse.ArgumentParser:
    """The options every screenshot script takes: ``--out`` (default ``out``), ``--width``
    and ``--height`` of the page; a script adds its own."""
    p = argparse.ArgumentParser(description=doc.splitlines()[0])
    p.add_argument("--out", default=out, help="the PNG to write")
    p.add_argument("--width", type=int, default=1280)
    p.add_argument("--height", type=int, default=860)
    return p
