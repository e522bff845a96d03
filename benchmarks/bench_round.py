"""Benchmark the whole drilling round (``planning.cycles.round.plan_round``) of the built-in
three-boom jumbo on two faces:

* ``sample``: the IREDES plan ``/work/shared/drill-plans/sample_round.xml`` (83 holes, 4.5-4.7 m
  deep, contour holes looking out 3 degrees), read with ``planning.drilling.plans.read_iredes``
  (a small local reader if that module is missing) and placed in the rig frame by the pose
  its README gives (the rig at x = 503,000, z = 21,500 mm of the site frame);
* ``paper``: paper 002's 132-hole face (``face_pattern`` 9.8 m x 7.8 m at 470 mm spacing),
  holes 3.5 m deep, contour holes looking out 3 degrees;
* ``face60``, ``face90``: generated full faces (``face_pattern``, horseshoe profiles of 60 and
  90 m^2 with cut, stoping, helper, contour and lifter holes, 4 and 5 m deep, contour and
  lifters looking out 3 degrees), each written to IREDES and read back before planning
  (``--faces face60,face90``).

For each: the round planned (booms at once, prioritised waits) beside (a) one boom at a time
(the same holes, moves and drilling back to back: the sum of the booms' busy times), (b) the
paper's allocation (equal counts; 40 / 52 / 40 on the paper face) and shortest-path order with
the booms moving one after another (middle, left, right: never two at once), and (c) the
lower bound (drilling time summed over the booms). Checked here: every hole drilled once, the
tool axis within 0.5 degrees of the hole axis and the tip on the hole's line over every feed
(by FK), and zero contacts by an exact re-check of the whole timeline (10 ms, 5 mm).

A report: it exits 0 whatever the numbers. ``.venv/bin/python benchmarks/bench_round.py
[--faces sample,paper,face60,face90] [--skip-baseline]``. Planning times depend on the
machine's load.
"""

from __future__ import annotations

import argparse
import math
import re
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from kinematics.fk import fk  # noqa: E402
from kinematics.rigs import builtin_rig  # noqa: E402
from planning.cycles.round import RoundOptions, plan_round, round_clearance  # noqa: E402
from planning.cycles.round_timeline import BoomGeometry  # noqa: E402

SAMPLE = Path("/work/shared/drill-plans/sample_round.xml")
#: The rig's origin in the sample plan's site frame, mm (its README).
SAMPLE_RIG_AT = np.array([503_000.0, 0.0, 21_500.0])
PAPER_FACE = {"width": 9_800.0, "height": 7_800.0, "spacing": 470.0}
PAPER_COUNTS = {"left": 40, "middle": 52, "right": 40}
LOOK_OUT_DEG = 3.0


def sample_holes() -> tuple[np.ndarray, np.ndarray, list[str], list[str]]:
    """The sample plan's collars, toes (rig frame, mm), ids and types."""
    text = SAMPLE.read_text()
    try:
        from planning.drilling.plans import read_iredes

        plan = read_iredes(text, verify_checksum=False)
        C, T, ids = plan.collars(), plan.toes(), plan.ids()
        types = [h.type for h in plan.holes]
    except ImportError:   # a tiny reader: Hole / HoleId / StartPoint / EndPoint, metres
        C, T, ids, types = [], [], [], []
        for block in re.findall(r"<Hole>(.*?)</Hole>", text, re.S):
            ids.append(re.search(r"<HoleId>(.*?)</HoleId>", block).group(1))
            types.append((re.search(r"<Type>(.*?)</Type>", block) or [None, ""])[1])
            for tag, out in (("StartPoint", C), ("EndPoint", T)):
                part = re.search(rf"<{tag}>(.*?)</{tag}>", block, re.S).group(1)
                out.append([float(re.search(rf"<IR:Point{a}>(.*?)</IR:Point{a}>",
                                            part).group(1)) * 1000.0 for a in "XYZ"])
        C, T = np.array(C), np.array(T)
    return np.asarray(C) - SAMPLE_RIG_AT, np.asarray(T) - SAMPLE_RIG_AT, list(ids), types


def paper_holes() -> tuple[np.ndarray, np.ndarray, list[str], list[str]]:
    """Paper 002's 132-hole face, 3.5 m deep holes, the contour looking out 3 degrees."""
    from planning.drilling.patterns import face_pattern

    pat = face_pattern(**PAPER_FACE)
    C = pat.holes
    centre = np.array([C[:, 1].mean(), C[:, 2].mean()])
    depth = 3_500.0
    T = C + np.array([depth, 0.0, 0.0])
    for k, kind in enumerate(pat.kinds):
        if kind == "contour":
            out = C[k, 1:] - centre
            out = out / np.linalg.norm(out)
            T[k, 1:] += depth * math.tan(math.radians(LOOK_OUT_DEG)) * out
    return C, T, [f"{k}" for k in range(len(C))], list(pat.kinds)


#: Generated full faces: horseshoe profiles of 60 and 90 m^2 (width, height mm; the area is
#: width x (height - width / 2) + pi (width / 2)^2 / 2), contour spacing (mm) and depth (mm).
FULL_FACES = {"face60": {"width": 8_000.0, "height": 8_360.0, "spacing": 600.0,
                         "depth": 4_000.0},
              "face90": {"width": 11_000.0, "height": 9_360.0, "spacing": 600.0,
                         "depth": 5_000.0}}


def full_face_holes(name: str) -> tuple[np.ndarray, np.ndarray, list[str], list[str]]:
    """A generated full face (``FULL_FACES``: cut, stoping, helper, contour and lifter holes
    of ``face_pattern``), the contour and lifters looking out ``LOOK_OUT_DEG`` (the lifters
    down), written to IREDES (``write_iredes``) and read back (checksum verified) before
    planning: collars, toes (rig frame, mm), ids and types."""
    from planning.drilling.patterns import face_pattern
    from planning.drilling.plans import DrillPlan, Hole, read_iredes, write_iredes

    spec = dict(FULL_FACES[name])
    depth = spec.pop("depth")
    pat = face_pattern(shape="horseshoe", **spec)
    C = pat.holes
    centre = np.array([C[:, 1].mean(), C[:, 2].mean()])
    T = C + np.array([depth, 0.0, 0.0])
    look = depth * math.tan(math.radians(LOOK_OUT_DEG))
    for k, kind in enumerate(pat.kinds):
        if kind == "contour":
            out = C[k, 1:] - centre
            T[k, 1:] += look * out / np.linalg.norm(out)
        elif kind == "lifter":
            T[k, 2] -= look
    holes = tuple(Hole(f"{kind[0].upper()}{k + 1}", "", C[k], T[k], kind.capitalize())
                  for k, kind in enumerate(pat.kinds))
    text = write_iredes(DrillPlan(name, f"{name} generated face", np.eye(4), "rig", holes),
                        created="2026-01-01T00:00:00")
    plan = read_iredes(text.encode("utf-8"))
    return plan.collars(), plan.toes(), plan.ids(), [h.type for h in plan.holes]


def check_round(rig, res, C, T, ids) -> tuple[int, float, int, float]:
    """Holes drilled more than once or not at all (besides the unreachable), the worst
    axis angle (deg) and off-line distance (mm) over the feeds by FK; contacts by an exact
    re-check of the whole timeline."""
    drilled = [h.id for h in res.holes]
    missing = set(ids) - set(drilled) - {u["id"] for u in res.unreachable}
    bad = (len(drilled) - len(set(drilled))) + len(missing)
    worst_angle, worst_off = 0.0, 0.0
    for name, bp in res.booms.items():
        model = rig.arms[name]
        for p in bp.timeline.phases:
            if p.kind != "drill":
                continue
            k = ids.index(p.hole)
            axis = (T[k] - C[k]) / np.linalg.norm(T[k] - C[k])
            F = fk(model, bp.timeline.evaluate(np.linspace(p.t0, p.t1, 50)))
            ang = np.degrees(np.arccos(np.clip(F[:, :3, 2] @ axis, -1, 1))).max()
            off = np.linalg.norm(np.cross(F[:, :3, 3] - C[k], axis), axis=1).max()
            worst_angle, worst_off = max(worst_angle, ang), max(worst_off, off)
    from planning.collision import RobotCollisionModel

    geometry = {a: BoomGeometry.of(RobotCollisionModel.from_model(
        rig.arms[a], link_radius=RoundOptions().link_radii)) for a in res.booms}
    least, _, _, count, step = round_clearance({a: b.timeline for a, b in res.booms.items()},
                                               geometry)
    contacts = 0 if least is None or least > 0 else 1
    return bad, worst_angle, contacts, least if least is not None else math.nan


def run_face(name: str, C, T, ids, types, baseline: bool) -> None:
    rig = builtin_rig("tunnel_jumbo")
    print(f"\n== {name}: {len(ids)} holes, depth {np.linalg.norm(T - C, axis=1).min():.0f}-"
          f"{np.linalg.norm(T - C, axis=1).max():.0f} mm ==", flush=True)
    last = [time.perf_counter()]

    def progress(f, m):
        now = time.perf_counter()
        if now - last[0] > 20:
            print(f"   {100 * f:3.0f} % {m}", flush=True)
            last[0] = now

    t0 = time.perf_counter()
    res = plan_round(rig, C, T, ids, RoundOptions(), types=types, progress=progress)
    t_plan = time.perf_counter() - t0
    bad, ang, contacts, least = check_round(rig, res, C, T, ids)
    busy = sum(bp.end_s - bp.wait_s for bp in res.booms.values())
    print(f"drilled {len(res.holes)}, unreachable {len(res.unreachable)} "
          f"({', '.join(sorted({u['reason'] for u in res.unreachable})) or '-'}); per boom "
          + ", ".join(f"{a} {len(b.holes)} (wait {b.wait_s:.0f} s)"
                      for a, b in res.booms.items()), flush=True)
    rows = [("booms at once, prioritised waits (ours)", res.cycle_time_s, t_plan)]
    rows.append(("(a) one boom at a time (same moves, back to back)", busy, math.nan))
    if baseline:
        from planning.drilling.allocation import allocate_holes

        counts = PAPER_COUNTS if len(ids) == sum(PAPER_COUNTS.values()) else None
        drilled = [ids.index(h.id) for h in res.holes]
        alloc = allocate_holes(rig, C[drilled], counts=counts)
        assignment = {ids[drilled[k]]: alloc.arms[alloc.arm_of[k]] for k in range(len(drilled))}
        t0 = time.perf_counter()
        base = plan_round(rig, C, T, ids, RoundOptions(
            assignment=assignment, order="distance", schedule="sequential",
            priority=("middle", "left", "right")), types=types, progress=progress)
        t_base = time.perf_counter() - t0
        b_bad, b_ang, b_contacts, b_least = check_round(rig, base, C, T, ids)
        rows.append(("(b) paper allocation + shortest-path order, booms in turn",
                     base.cycle_time_s, t_base))
        print(f"(b): drilled {len(base.holes)}, per boom "
              + ", ".join(f"{a} {len(b.holes)}" for a, b in base.booms.items())
              + f"; holes wrong {b_bad}, worst axis {b_ang:.4f} deg, contacts {b_contacts}, "
              f"least clearance {b_least:.0f} mm", flush=True)
    rows.append(("(c) lower bound (drilling time / booms)", res.lower_bound_s, math.nan))
    print("\n| schedule | cycle time | / lower bound | planning time |")
    print("|---|---:|---:|---:|")
    for label, cyc, tp in rows:
        tp_s = "" if math.isnan(tp) else f"{tp:.0f} s"
        print(f"| {label} | {cyc:.0f} s | {cyc / res.lower_bound_s:.3f} | {tp_s} |")
    print(f"\nours: holes drilled wrongly or twice {bad}; worst tool axis {ang:.4f} deg off the "
          f"hole axis; contacts {contacts}; least boom-boom clearance {least:.0f} mm "
          f"({res.clearance_pair} at {res.clearance_t_s:.1f} s; planner's "
          f"{res.min_boom_clearance_mm:.0f} mm over {res.checked_instants} instants, largest "
          f"step {res.max_step_mm:.2f} mm); delay checks {res.stats['delay_checks']}; "
          f"priority {', '.join(res.stats['priority'])}; notes {res.notes or '-'}",
          flush=True)
    for u in res.unreachable[:5]:
        print(f"   unreachable {u['id']}: {u['reason']} ({u['detail'][:150]})")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--faces", default="sample,paper")
    ap.add_argument("--skip-baseline", action="store_true")
    args = ap.parse_args()
    for face in args.faces.split(","):
        if face == "sample":
            if not SAMPLE.exists():
                print(f"(no {SAMPLE}: sample face skipped)")
                continue
            run_face("sample_round.xml", *sample_holes(), not args.skip_baseline)
        elif face == "paper":
            run_face("paper 002 face", *paper_holes(), not args.skip_baseline)
        elif face in FULL_FACES:
            f = FULL_FACES[face]
            run_face(f"{face}: horseshoe {f['width'] / 1000:g} m x {f['height'] / 1000:g} m, "
                     f"{f['depth'] / 1000:g} m holes", *full_face_holes(face),
                     not args.skip_baseline)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
