"""Make ``docs/viewer_piles.png``: a pile plan's site map in the viewer, drawn by headless
Chromium: ten piles, four of them raked, driven from three set-ups of the pile driver.

Each pile is made where the pile driver's arm holds it from its set-up (its head the tool
point, its axis the mast's direction, by FK), so every pile is reachable; the ``piles``
job kind, run in this process as a worker runs it, picks the fewest set-ups among four
candidate positions (the fourth, in the middle, is left out), orders the piles and times
them. The viewer shows the site from above and to the side: each pile a stroke down its
axis in its set-up's colour, the carrier at each set-up (a post up to the arm's base), the
arm at its first pile and the carrier's route. The ground grid and the robot model (not
moved to the set-ups) are hidden: the piles run below the ground. The viewer and Chromium
steps are ``tools/screenshots.py``'s.

    .venv/bin/python tools/screenshot_piles.py                 # docs/viewer_piles.png
    .venv/bin/python tools/screenshot_piles.py --out /tmp/x.png --width 1600 --height 1000
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from screenshots import FOLDED, run_job, screenshot  # noqa: E402
from screenshots import parser as screenshot_parser  # noqa: E402

ROBOT = "pile_driver"
BASE_HEIGHT = 500.0
#: The set-ups the piles are made from, ``[x, y, heading]`` (mm, rad).
SETUPS = [(0.0, 0.0, 0.0), (5000.0, 0.0, 0.5), (2500.0, 4000.0, -0.3)]
#: Per set-up, the arm's configurations holding its piles: ``[0, 0.1, -0.8, -0.8, e, w]``
#: with the last joint -1.5 holds the mast vertical, -1.2 raked 17° towards the base (and
#: wrist joint e = 0.15 turns the rake aside); the waist (first joint) sets the direction.
PILES = [
    [(-0.6, 0.0, -1.5), (0.0, 0.0, -1.5), (0.6, 0.0, -1.2), (1.2, 0.0, -1.5)],
    [(-0.4, 0.0, -1.5), (0.3, 0.15, -1.2), (1.0, 0.0, -1.5)],
    [(-1.0, 0.0, -1.2), (-0.3, 0.0, -1.5), (0.4, 0.15, -1.2)],
]
#: The camera (m): south-west of the site, above, looking at its middle.
CAMERA = (0.6, -2.9, 4.7)
LOOK_AT = (3.2, 0.9, -0.3)


def pile_rows() -> list[dict]:
    """The plan's rows: each pile where the arm holds it from its set-up (site frame)."""
    from kinematics.fk import fk
    from kinematics.library import builtin_model

    model = builtin_model(ROBOT)
    rows = []
    for s, ((x, y, h), qs) in enumerate(zip(SETUPS, PILES, strict=True)):
        c, si = math.cos(h), math.sin(h)
        R = np.array([[c, -si, 0.0], [si, c, 0.0], [0.0, 0.0, 1.0]])
        for k, (waist, e, w) in enumerate(qs):
            T = fk(model, np.array([waist, 0.1, -0.8, -0.8, e, w]))
            d = R @ T[:3, 1]                   # the mast: the tool's y axis
            p = R @ T[:3, 3] + np.array([x, y, BASE_HEIGHT])
            rows.append({"id": f"P{s + 1}{k + 1}", "x": round(float(p[0]), 1),
                         "y": round(float(p[1]), 1), "z": round(float(p[2]), 1),
                         "inclination": math.acos(min(1.0, -float(d[2]))),
                         "azimuth": math.atan2(d[1], d[0])})
    return rows


def piles_params() -> dict:
    """The ``piles`` params: the rows, the three set-ups and a fourth candidate between them."""
    positions = [list(s) for s in SETUPS] + [[2500.0, 1500.0, 0.0]]
    return {"robot": ROBOT, "plan": pile_rows(), "setups": {"positions": positions},
            "base_height": BASE_HEIGHT, "drive_time": 60.0, "travel_speed": 500.0}


def main(argv: list[str] | None = None) -> int:
    parser = screenshot_parser(__doc__, "docs/viewer_piles.png")
    args = parser.parse_args(argv)

    started = time.monotonic()
    params, result = run_job("piles", piles_params(), ROBOT)
    planned = time.monotonic() - started

    def site_only(viewer) -> None:
        viewer._grid.visible = False           # the piles run below the ground

    screenshot("piles", params, result, args.out, job="piles", camera=CAMERA,
               look_at=LOOK_AT, wait_node="/plan/piles/route", width=args.width,
               height=args.height, hide_robot=True, ready=site_only,
               folded=(*FOLDED, "Hydraulic cylinders"))
    raked = sum(r["inclination"] > 0.01 for r in params["plan"] or [])
    print(f"{args.out}: {result['piles_reached']} of {result['piles_total']} piles "
          f"({raked} raked) from {len(result['setups'])} set-ups, planned in "
          f"{planned:.1f} s; cycle {result['cycle_time_s']:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
