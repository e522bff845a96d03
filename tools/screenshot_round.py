"""Make ``docs/viewer_round.png``: the tunnel jumbo's three booms drilling a small round at
once, caught mid-round in the viewer, drawn by headless Chromium.

Nine holes of the sample face (``examples/drill_face.csv``: the upper half of the contour
and two in the middle) are planned by the ``round`` job kind run in this
process as a worker runs it; the viewer shows its result at the moment when the most booms are
drilling (the earliest such moment past ``--share`` of the round), seen from behind the booms
(a little to the side and above) towards the face. Holes are grey until drilled, in their
boom's colour while drilled, dark once done. The viewer and Chromium steps are
``tools/screenshots.py``'s.

    .venv/bin/python tools/screenshot_round.py                 # docs/viewer_round.png
    .venv/bin/python tools/screenshot_round.py --out /tmp/x.png --share 0.3
"""

from __future__ import annotations

import csv
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from screenshots import parser as screenshot_parser  # noqa: E402
from screenshots import run_job, screenshot  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
#: The holes of the sample face drawn: its upper half (the viewer's ground grid lies at the
#: rig frame's z = 0, and hides the holes below it), both flanks of the contour and the
#: middle.
HOLES = ("H03", "H04", "H05", "H06", "H07", "H08", "H09", "H19", "H21")
#: The camera (m): behind the booms, to their right and above, looking at the middle of the
#: face, so each hole shows its length from collar to toe.
CAMERA = (5.5, -5.0, 4.0)
LOOK_AT = (10.5, 0.0, 1.0)


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
    return run_job("round", round_params())


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
    parser = screenshot_parser(__doc__, "docs/viewer_round.png")
    parser.add_argument("--share", type=float, default=0.0,
                        help="look for the busiest moment from this share of the round on")
    args = parser.parse_args(argv)

    started = time.monotonic()
    params, result = run_round()
    planned = time.monotonic() - started
    t = busiest_moment(result, args.share)
    screenshot("round", params, result, args.out, job="round", camera=CAMERA,
               look_at=LOOK_AT, wait_node="/plan/round/holes", time_s=t, width=args.width,
               height=args.height)
    drilling = [h["id"] + " (" + h["boom"] + ")" for h in result["holes"]
                if h["start_s"] <= t < h["end_s"]]
    print(f"{args.out}: {len(result['holes'])} holes planned in {planned:.1f} s; "
          f"t = {t:.1f} s of {result['cycle_time_s']:.1f} s, drilling "
          f"{', '.join(drilling)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
