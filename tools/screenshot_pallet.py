"""Make ``docs/viewer_pallet.png``: the GLT palletizer filling a EUR pallet with 400 x 300 x
250 mm boxes in two interlocked layers, caught in the viewer while it carries a box of the
second layer over the boxes already placed, drawn by headless Chromium.

The pallet (docs/pallet.md's example: the box taken from a conveyor at (0, -1100, 825) mm,
the pallet 850 mm in front of the robot, turned 90°, 10 mm of overhang) is planned by the
``pallet`` job kind run in this process as a worker runs it (two layers: 8 boxes, then 6,
about 20 s); the viewer shows its result at ``--share`` of box ``--box``'s carry, seen from
the front right, above. The viewer and Chromium steps are ``tools/screenshots.py``'s.

    .venv/bin/python tools/screenshot_pallet.py                 # docs/viewer_pallet.png
    .venv/bin/python tools/screenshot_pallet.py --out /tmp/x.png --box 5 --share 0.3
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from screenshots import parser as screenshot_parser  # noqa: E402
from screenshots import run_job, screenshot  # noqa: E402

ROBOT = "glt_palletizer"
#: The camera (m): from the front right of the cell, above, looking at the pallet and the
#: pick station beside the robot.
CAMERA = (1.95, -1.5, 1.4)
LOOK_AT = (0.62, 0.0, 0.5)


def pallet_params(layers: int) -> dict:
    """The ``pallet`` params of docs/pallet.md's example, ``layers`` interlocked layers."""
    return {"robot": ROBOT, "box": {"size": [400, 300, 250], "mass": 12.5},
            "pick": [[1, 0, 0, 0], [0, 1, 0, -1100], [0, 0, 1, 825], [0, 0, 0, 1]],
            "pallet": {"overhang": 10}, "pattern": "interlocked", "layers": layers}


def carry_moment(params: dict, result: dict, box: int, share: float) -> float:
    """The plan's time at ``share`` of box ``box``'s carry, on the viewer's clock (each
    placed box in turn: dwell, carry, dwell, return)."""
    dwell = params["dwell_s"]
    clock = 0.0
    for b in result["boxes"]:
        if b["status"] != "placed":
            continue
        if b["index"] == box:
            return clock + dwell + share * b["carry_s"]
        clock += 2 * dwell + b["carry_s"] + b["return_s"]
    raise SystemExit(f"box {box} was not placed")


def main(argv: list[str] | None = None) -> int:
    parser = screenshot_parser(__doc__, "docs/viewer_pallet.png")
    parser.add_argument("--layers", type=int, default=2, help="interlocked layers planned")
    parser.add_argument("--box", type=int, default=11, help="the box carried (its index)")
    parser.add_argument("--share", type=float, default=0.6,
                        help="where in that box's carry (0..1)")
    args = parser.parse_args(argv)

    started = time.monotonic()
    params, result = run_job("pallet", pallet_params(args.layers), ROBOT)
    planned = time.monotonic() - started
    t = carry_moment(params, result, args.box, args.share)
    resting = []

    def note(viewer) -> None:
        resting.extend(k for k, pose in viewer.loads.items()
                       if pose is not None and k != f"box{args.box}")

    screenshot("pallet", params, result, args.out, job="pallet", camera=CAMERA,
               look_at=LOOK_AT, wait_node=f"/plan/pallet/loads/box{args.box}", time_s=t,
               width=args.width, height=args.height, ready=note)
    print(f"{args.out}: {result['placed']} of {result['total']} boxes placed "
          f"(per layer {result['per_layer']}), planned in {planned:.1f} s; t = {t:.1f} s "
          f"of {result['pallet_s']:.1f} s: box {args.box} carried, {len(resting)} resting")
    return 0


if __name__ == "__main__":
    sys.exit(main())
