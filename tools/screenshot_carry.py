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

import sys

import numpy as np
from screenshots import parser as screenshot_parser  # noqa: E402
from screenshots import run_job, screenshot

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
    params, result = run_job("motion", task_params(), ROBOT)
    if result["status"] != "ok":
        raise SystemExit(f"the task was not planned: {result['message']}")
    return params, result


def main(argv: list[str] | None = None) -> int:
    parser = screenshot_parser(__doc__, "docs/viewer_carry.png")
    parser.add_argument("--share", type=float, default=0.5,
                        help="where in the move from the conveyor to the pallet (0..1)")
    args = parser.parse_args(argv)
    params, result = run_task()
    seen: dict = {}

    def at_the_move(viewer) -> None:
        spans = {s.index: s for s in viewer._plan.task.spans}
        move = spans[4]                        # from above the conveyor to above the pallet
        seen["t"] = move.start + args.share * (move.end - move.start)
        viewer.set_time(seen["t"])
        seen["duration"], seen["pose"] = viewer._plan.duration, viewer.loads["carton"]

    screenshot("motion", params, result, args.out, job="pick-and-place", camera=CAMERA,
               look_at=LOOK_AT, wait_node="/plan/motion/loads/carton/carton",
               width=args.width, height=args.height, ready=at_the_move)
    print(f"{args.out}: t = {seen['t']:.2f} s of {seen['duration']:.2f} s, the box's "
          f"centre at {np.round(seen['pose'][:3, 3], 1).tolist()} mm")
    return 0


if __name__ == "__main__":
    sys.exit(main())
