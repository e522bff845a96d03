"""Make ``docs/viewer_carry.png``: the GLT palletizer carrying a 400 x 300 x 250 mm box from a
conveyor to a pallet, caught mid-move in the viewer, drawn by headless Chromium.

The task (move above the conveyor, 200 mm down, attach the box, up, over to the pallet, down,
detach, up) is planned by the ``motion`` job kind run in this process as a worker runs it; the
viewer (viser, on a free loopback port, without the environment map so nothing is fetched)
shows its result and is put at ``--share`` of the way through the move from the conveyor to
the pallet; Playwright drives Debian's Chromium (``tests/web/chromium_setup.py``'s flags) to
take the picture.

    .venv/bin/python tools/screenshot_carry.py                 # docs/viewer_carry.png
    .venv/bin/python tools/screenshot_carry.py --out /tmp/x.png --width 1600 --height 1000
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROBOT = "glt_palletizer"
START = [0.0, 0.3, -0.3, 0.0, 0.5, 0.0]
#: The tool pointing straight down.
DOWN = [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]
PICK = np.array([1200.0, 600.0, 700.0])
PLACE = np.array([1200.0, -600.0, 700.0])
UP = np.array([0.0, 0.0, 200.0])
BOX = [400.0, 300.0, 250.0]
#: The camera (m): from the front left, above, looking at the middle of the cell.
CAMERA = (2.3, -1.45, 1.45)
LOOK_AT = (1.0, 0.2, 0.5)
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--disable-quic",
                 "--no-first-run"]


def _pose(p: np.ndarray, R=DOWN) -> list:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = p
    return T.tolist()


def task_params() -> dict:
    """The pick and place task: the box hangs 195 mm below the tool point (its top 70 mm
    clear of the tool's collision capsule), 10 mm above the conveyor and the pallet where it
    is taken and put down."""
    grip = np.eye(4)
    grip[2, 3] = 195.0
    eye = np.eye(3).tolist()
    steps = [
        {"type": "move", "goal": {"pose": _pose(PICK + UP)}},
        {"type": "line", "target": PICK.tolist(), "orientation": "hold"},
        {"type": "attach", "object": {"type": "box", "id": "carton", "size": BOX},
         "link": "tool", "pose": grip.tolist()},
        {"type": "line", "target": (PICK + UP).tolist(), "orientation": "hold"},
        {"type": "move", "goal": {"pose": _pose(PLACE + UP)}},
        {"type": "line", "target": PLACE.tolist(), "orientation": "hold"},
        {"type": "detach", "object": "carton"},
        {"type": "line", "target": (PLACE + UP).tolist(), "orientation": "hold"},
        {"type": "move", "goal": {"q": START}},
    ]
    scene = {"objects": [
        {"type": "box", "id": "conveyor", "size": [600, 500, 370],
         "pose": _pose(np.array([1200.0, 600.0, 185.0]), eye)},
        {"type": "box", "id": "pallet", "size": [1000, 800, 370],
         "pose": _pose(np.array([1200.0, -600.0, 185.0]), eye)},
    ]}
    return {"robot": ROBOT, "start": START, "steps": steps, "scene": scene, "time_limit": 10.0}


def run_task() -> tuple[dict, dict]:
    """The task's stored params and result, planned as a worker plans a ``motion`` job."""
    from app.jobs.catalog import KINDS
    from app.jobs.kinds import JobPayload, execute
    from kinematics.library import builtin_model

    checked = KINDS["motion"].load_params(task_params())
    payload = JobPayload(params=checked.model_dump(mode="json"),
                         robot_model=builtin_model(ROBOT).to_dict())
    result = json.loads(execute("motion", payload.model_dump(mode="json"),
                                lambda fraction, message: None))
    if result["status"] != "ok":
        raise SystemExit(f"the task was not planned: {result['message']}")
    return checked.model_dump(mode="json"), result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="docs/viewer_carry.png", help="the PNG to write")
    parser.add_argument("--width", type=int, default=1280)
    parser.add_argument("--height", type=int, default=860)
    parser.add_argument("--share", type=float, default=0.5,
                        help="where in the move from the conveyor to the pallet (0..1)")
    args = parser.parse_args(argv)

    from playwright.sync_api import sync_playwright

    from app.config import Settings
    from app.main import create_app
    from kinematics.library import builtin_model
    from web.results import plan_from_result
    from web.viewer import Viewer

    chromium = shutil.which("chromium") or "/usr/bin/chromium"
    params, result = run_task()
    with tempfile.TemporaryDirectory() as data:
        app = create_app(Settings(no_viewer=True, data_dir=Path(data), workers=1))
        viewer = Viewer.start("127.0.0.1", 0, app.state, environment_map=False)
        try:
            viewer.show_plan(plan_from_result("motion", params, result, job="pick-and-place",
                                              models=builtin_model))
            spans = {s.index: s for s in viewer._plan.task.spans}
            move = spans[4]                    # from above the conveyor to above the pallet
            t = move.start + args.share * (move.end - move.start)
            viewer.set_time(t)
            viewer.gizmo.visible = False           # the IK gizmo would hide the box
            with sync_playwright() as p:
                browser = p.chromium.launch(executable_path=chromium, args=CHROMIUM_ARGS)
                page = browser.new_page(viewport={"width": args.width,
                                                  "height": args.height})
                page.set_default_timeout(30_000)
                page.goto(f"http://127.0.0.1:{viewer.port}")
                page.bring_to_front()
                page.get_by_text("Connected").wait_for()
                page.wait_for_function(
                    "() => window.__viserSceneTree !== undefined && "
                    "'/plan/motion/loads/carton/carton' in window.__viserSceneTree.getState()")
                page.wait_for_function(
                    "() => { const c = document.querySelector('canvas');"
                    " return c && getComputedStyle(c).opacity === '1'; }")
                time.sleep(1.0)                # the viewer frames the page's canvas first
                for client in viewer.server.get_clients().values():   # closer than framed
                    client.camera.position = CAMERA
                    client.camera.look_at = LOOK_AT
                # The panel shows the plan's text: the other folders folded, the notice
                # about software rendering closed.
                for title in ("Joints of glt_palletizer", "IK: drag the gizmo at the tool",
                              "Workspace"):
                    page.get_by_text(title, exact=True).click()
                page.evaluate(
                    """() => document.querySelectorAll('.mantine-Notification-root, '
                       + '.mantine-Notifications-notification').forEach(e => e.remove())""")
                time.sleep(2.0)                # let the frame render
                out = Path(args.out)
                out.parent.mkdir(parents=True, exist_ok=True)
                page.screenshot(path=str(out))
                browser.close()
            pose = viewer.loads["carton"]
            print(f"{args.out}: t = {t:.2f} s of {viewer._plan.duration:.2f} s, the box's "
                  f"centre at {np.round(pose[:3, 3], 1).tolist()} mm")
        finally:
            viewer.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
