"""Benchmark the pile plans of ``planning.cycles.piles`` on the built-in pile driver.

Two generated plans (seeded): 60 piles (10 x 6, 1.5 m apart) and 300 piles (20 x 15), a
third of them raked (1:6 to 1:12, any azimuth), the rest vertical, on a site with a hut and
a stockpile (boxes). The candidate set-ups: a 500 mm grid over the site and a 2 m border,
those within 1.2 m of an obstacle left out by the planner (``carrier_radius``). For each
plan:

* piles reached / total, and why the others are not;
* the set-ups used beside the lower bound: on the 60-pile plan the exact cover (MILP), on
  the 300-pile plan the greedy cover beside the LP relaxation's bound (and the MILP given
  ``--exact-seconds`` on it too, as a reference);
* every driven pile's mast angle and position error recomputed here by FK, against its
  tolerances (the worst of each);
* the cycle time: total, work at the set-ups, relocations, per pile, and the planning time.

A report: it exits 0 whatever the numbers. ``.venv/bin/python benchmarks/bench_piles.py
[--quick]`` (``--quick``: the 60-pile plan only). Timing figures depend on the machine's
load.
"""

from __future__ import annotations

import argparse
import math
import platform
import time

import numpy as np

from kinematics.fk import fk
from kinematics.library import builtin_model
from planning.collision import CollisionScene
from planning.cycles.piles import cover_setups, parse_plan, plan_piles, setup_grid

BASE_HEIGHT = 500.0
SPACING = 1500.0
CARRIER_RADIUS = 1200.0
OBSTACLES = [  # (id, centre x, y, size x, y, z) in units of the pile spacing, mm
    ("hut", 3.5, 2.5, 1200.0, 900.0, 2600.0),
    ("stockpile", 7.0, 1.0, 1500.0, 1500.0, 1200.0),
]


def site(cols: int, rows: int, seed: int) -> tuple[list[dict], CollisionScene, np.ndarray]:
    """The plan rows, the scene and the candidate set-ups of a ``cols`` x ``rows`` pile
    grid."""
    rng = np.random.default_rng(seed)
    rows_out = []
    k = 0
    for j in range(rows):
        for i in range(cols):
            row = {"id": f"P{k:03d}", "x": i * SPACING + rng.uniform(-150, 150),
                   "y": j * SPACING + rng.uniform(-150, 150), "z": rng.uniform(-100, 100)}
            if rng.random() < 1 / 3:
                row["rake"] = f"1:{int(rng.integers(6, 13))}"
                row["azimuth"] = float(rng.uniform(-math.pi, math.pi))
            rows_out.append(row)
            k += 1
    objects, boxes = [], []
    for name, cx, cy, sx, sy, sz in OBSTACLES:
        x, y = cx * SPACING * cols / 10.0, cy * SPACING * rows / 6.0
        objects.append({"type": "box", "id": name, "size": [sx, sy, sz],
                        "pose": [[1, 0, 0, x], [0, 1, 0, y], [0, 0, 1, sz / 2],
                                 [0, 0, 0, 1]]})
        boxes.append((x, y, sx / 2, sy / 2))
    # Piles on an obstacle's footprint are moved off the plan (nobody drives through a hut).
    rows_out = [r for r in rows_out
                if not any(abs(r["x"] - x) < hx + 300 and abs(r["y"] - y) < hy + 300
                           for x, y, hx, hy in boxes)]
    lo, hi = -2000.0, 2000.0
    poly = [[lo, lo], [(cols - 1) * SPACING + hi, lo],
            [(cols - 1) * SPACING + hi, (rows - 1) * SPACING + hi],
            [lo, (rows - 1) * SPACING + hi]]
    return rows_out, CollisionScene.from_request({"objects": objects}), setup_grid(poly, 500.0)


def fk_check(model, out, plan) -> tuple[float, float, int]:
    """Worst mast angle (rad) and position error (mm) of the driven piles by FK, and how
    many are past their tolerances."""
    worst_a = worst_p = 0.0
    bad = 0
    for p in out.piles:
        if p.setup < 0:
            continue
        x, y, h = out.setups[p.setup]
        T = fk(model, p.q)
        c, s = math.cos(h), math.sin(h)
        R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
        mast = R @ T[:3, 1]
        tip = R @ T[:3, 3] + [x, y, BASE_HEIGHT]
        i, az = plan.inclination[p.index], plan.azimuth[p.index]
        axis = np.array([math.sin(i) * math.cos(az), math.sin(i) * math.sin(az), -math.cos(i)])
        a = math.acos(min(1.0, float(mast @ axis)))
        d = float(np.linalg.norm(tip - plan.heads[p.index]))
        worst_a, worst_p = max(worst_a, a), max(worst_p, d)
        bad += a > plan.tol_angle[p.index] or d > plan.tol_position[p.index]
    return worst_a, worst_p, bad


def run_plan(label: str, cols: int, rows: int, seed: int, exact_max: int,
             exact_seconds: float) -> list[str]:
    model = builtin_model("pile_driver")
    rows_in, scene, cands = site(cols, rows, seed)
    plan = parse_plan(rows_in)
    t0 = time.perf_counter()
    out = plan_piles(model, plan, cands, base_height=BASE_HEIGHT, scene=scene,
                     carrier_radius=CARRIER_RADIUS, drive_time=90.0, travel_speed=300.0,
                     setup_time=120.0,
                     exact_max=exact_max, cover_time_limit=exact_seconds, seed=seed)
    dt = time.perf_counter() - t0
    reached = sum(p.setup >= 0 for p in out.piles)
    raked = int((plan.inclination > 0).sum())
    cov = out.cover
    blocked = out.stats["candidates_blocked"]
    lines = [f"### {label}: {len(plan)} piles ({raked} raked), {len(cands)} candidate "
             f"set-ups ({blocked} too near an obstacle for the carrier)", "",
             "| figure | value |", "|---|---|",
             f"| piles reached / total | {reached} / {len(plan)} |"]
    why: dict[str, int] = {}
    for p in out.unreached:
        key = p.reason.split(":")[0] if "move" in p.reason or "lowered" in p.reason \
            else p.reason
        why[key] = why.get(key, 0) + 1
    for reason, n in sorted(why.items()):
        lines.append(f"| unreached: {reason} | {n} |")
    lines.append(f"| cover ({cov.method}) | {len(cov.chosen)} set-ups; lower bound "
                 f"{cov.lower_bound} (LP {cov.lp_value:.2f}); {cov.note} |")
    if cov.method == "greedy":
        t1 = time.perf_counter()
        ex = cover_setups(out.table.reach, exact_max=10**6, time_limit=exact_seconds)
        lines.append(f"| MILP on the same table ({exact_seconds:g} s) | {len(ex.chosen)} "
                     f"set-ups, {'proven' if ex.method == 'milp' else 'unproven'} "
                     f"({time.perf_counter() - t1:.1f} s) |")
    extra = out.stats.get("extra_setups", 0)
    lines.append(f"| set-ups used (beyond the cover: arm moves blocked) | "
                 f"{len(out.setups)} ({extra}) |")
    wa, wp, bad = fk_check(model, out, plan)
    lines.append(f"| worst mast angle / position error (FK) | {wa:.2e} rad / {wp:.2e} mm; "
                 f"{bad} past tolerance |")
    moves = [p for p in out.piles if p.setup >= 0 and p.move != "first"]
    kinds = {k: sum(p.move == k for p in moves) for k in ("joint", "raised", "planned")}
    lines.append(f"| arm moves: joint / raised / planned | {kinds['joint']} / "
                 f"{kinds['raised']} / {kinds['planned']} |")
    lower = [p.lower_s for p in out.piles if p.setup >= 0]
    lines.append(f"| mast lowering (300 mm) mean / max | {np.mean(lower):.2f} s / "
                 f"{np.max(lower):.2f} s |")
    lines.append(f"| cycle time total | {out.total_s:.0f} s ({out.total_s / 3600:.2f} h) |")
    lines.append(f"| work at set-ups / relocation | {out.work_s:.0f} s / "
                 f"{out.relocation_s:.0f} s ({out.travel_mm / 1000:.1f} m) |")
    lines.append(f"| per pile (work / reached piles) | {out.work_s / max(reached, 1):.1f} s "
                 "(90 s driving) |")
    lines.append(f"| planning time | {dt:.1f} s (reach table {out.stats['reach_s']:.1f} s, "
                 f"{out.stats['ik_poses']:,} IK poses) |")
    return lines


def piles_section(quick: bool = False, exact_seconds: float = 30.0) -> list[str]:
    """The report's lines (markdown)."""
    lines = ["## Pile plans", "",
             f"pile_driver, base {BASE_HEIGHT:g} mm above ground, 300 mm approach, 90 s "
             "driving per pile, carrier 300 mm/s, 120 s per set-up and 1.2 m clear of the "
             "obstacles; "
             f"{platform.processor() or platform.machine()}", ""]
    lines += run_plan("60 piles", 10, 6, 1, exact_max=5000, exact_seconds=exact_seconds)
    if not quick:
        lines += [""]
        lines += run_plan("300 piles", 20, 15, 2, exact_max=0, exact_seconds=exact_seconds)
    return lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="the 60-pile plan only")
    ap.add_argument("--exact-seconds", type=float, default=30.0)
    args = ap.parse_args()
    print("\n".join(piles_section(args.quick, args.exact_seconds)))


if __name__ == "__main__":
    main()
