"""Make ``docs/viewer_round.png``: the tunnel jumbo's three booms drilling a small round at
once, caught mid-round in the viewer, drawn by headless Chromium.

Nine holes of the sample face (``examples/drill_face.csv``: the upper half of the contour
and two in the middle) are planned by the ``round`` job kind run in this
process as a worker runs it; the viewer (viser, on a free loopback port, without the
environment map so nothing is fetched) shows its result at the moment when the most booms are
drilling (the earliest such moment past ``--share`` of the round), seen from behind the booms
(a little to the side and above) towards the face. Holes are grey until drilled, in their
boom's colour while drilled, dark once done. Playwright drives Debian's Chromium
(``tests/web/chromium_setup.py``'s flags) to take the picture.

    .venv/bin/python tools/screenshot_round.py                 # docs/viewer_round.png
    .venv/bin/python tools/screenshot_round.py --out /tmp/x.png --share 0.3
"""

from __future__ import annotations

import argparse
import csv
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
#: The holes of the sample face drawn: its upper half (the viewer's ground grid lies at the
#: rig frame's z = 0, and hides the holes below it), both flanks of the contour and the
#: middle.
HOLES = ("H03", "H04", "H05", "H06", "H07", "H08", "H09", "H19", "H21")
#: The camera (m): behind the booms, to their right and above, looking at the middle of the
#: face, so each hole shows its length from collar to toe.
CAMERA = (5.5, -5.0, 4.0)
LOOK_AT = (10.5, 0.0, 1.0)
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--disable-quic",
                 "--no-first-run"]


def round_params() -> dict:
    """The ``round`` params: the chosen holes of the sample face, in the rig frame."""
    with open(ROOT / "examples" / "drill_face.csv", newline="") as f:
        rows = {r["id"]: r for r in csv.DictReader(f)}
    holes = [{"id": h, "collar": [float(rows[h][f"collar_{a}"]) for a in "xyz"],
              "toe": [float(rows[h][f"toe_{a}"]) for a in "xyz"], "type": rows[h]["type"]}
             for h in HOLES]
    return {"rig": "tunnel_jumbo", "holes": holes, "output_dt": 0.5}


def run_round() -> tuple[dict, dict]:
    """The round's stored params and result, planned as a worker plans a ``round`` job."""
    from app.jobs.catalog import KINDS
    from app.jobs.kinds import JobPayload, execute

    checked = KINDS["round"].load_params(round_params())
    payload = JobPayload(params=checked.model_dump(mode="json"))
    result = json.loads(execute("round", payload.model_dump(mode="json"),
                                lambda fraction, message: None))
    return checked.model_dump(mode="json"), result


def busiest_moment(result: dict, share: float) -> float:
    """The earliest time at or after ``share`` of the cycle with the most booms drilling
    (in the middle of that span)."""
    spans = [(h["start_s"], h["end_s"]) for h in result["holes"]]
    edges = np.unique([t for s in spans for t in s])
    mids = 0.5 * (edges[:-1] + edges[1:])
    busy = np.array([sum(s <= t < e for s, e in spans) for t in mids])
    late = mids >= share * result["cycle_time_s"]
    pick = np.flatnonzero(late & (busy == busy[late].max()))[0] if late.any() \
        else int(np.argmax(busy))
    return float(mids[pick])


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="docs/viewer_round.png", help="the PNG to write")
    parser.add_argument("--width", type=int, default=1280)
    parser.add_argument("--height", type=int, default=860)
    parser.add_argument("--share", type=float, default=0.0,
                        help="look for the busiest moment from this share of the round on")
    args = parser.parse_args(argv)

    from playwright.sync_api import sync_playwright

    from app.config import Settings
    from app.main import create_app
    from kinematics.library import builtin_model
    from web.results import plan_from_result
    from web.viewer import Viewer

    chromium = shutil.which("chromium") or "/usr/bin/chromium"
    started = time.monotonic()
    params, result = run_round()
    planned = time.monotonic() - started
    t = busiest_moment(result, args.share)
    with tempfile.TemporaryDirectory() as data:
        app = create_app(Settings(no_viewer=True, data_dir=Path(data), workers=1))
        viewer = Viewer.start("127.0.0.1", 0, app.state, environment_map=False)
        try:
            viewer.show_plan(plan_from_result("round", params, result, job="round",
                                              models=builtin_model, rigs=app.state.registry.rigs))
            viewer.set_time(t)
            viewer.gizmo.visible = False
            with sync_playwright() as p:
                browser = p.chromium.launch(executable_path=chromium, args=CHROMIUM_ARGS)
                page = browser.new_page(viewport={"width": args.width,
                                                  "height": args.height})
                page.set_default_timeout(60_000)
                page.goto(f"http://127.0.0.1:{viewer.port}")
                page.bring_to_front()
                page.get_by_text("Connected").wait_for()
                page.wait_for_function(
                    "() => window.__viserSceneTree !== undefined && "
                    "'/plan/round/holes' in window.__viserSceneTree.getState()")
                page.wait_for_function(
                    "() => { const c = document.querySelector('canvas');"
                    " return c && getComputedStyle(c).opacity === '1'; }")
                time.sleep(1.0)                # the viewer frames the page's canvas first
                for client in viewer.server.get_clients().values():
                    client.camera.position = CAMERA
                    client.camera.look_at = LOOK_AT
                # The panel shows the plan's text: the other folders folded.
                for title in ("Joints of tunnel_jumbo-left", "IK: drag the gizmo at the tool",
                              "Workspace"):
                    found = page.get_by_text(title, exact=True)
                    if found.count():
                        found.first.click()
                page.evaluate(
                    """() => document.querySelectorAll('.mantine-Notification-root, '
                       + '.mantine-Notifications-notification').forEach(e => e.remove())""")
                time.sleep(2.0)                # let the frame render
                out = Path(args.out)
                out.parent.mkdir(parents=True, exist_ok=True)
                page.screenshot(path=str(out))
                browser.close()
            drilling = [h["id"] + " (" + h["boom"] + ")" for h in result["holes"]
                        if h["start_s"] <= t < h["end_s"]]
            print(f"{args.out}: {len(result['holes'])} holes planned in {planned:.1f} s; "
                  f"t = {t:.1f} s of {result['cycle_time_s']:.1f} s, drilling "
                  f"{', '.join(drilling)}")
        finally:
            viewer.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
