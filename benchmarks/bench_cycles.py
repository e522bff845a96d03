"""Work cycles planned whole, every answer re-checked; ``main()`` prints each section: the
pallet below and the pile plans of ``bench_piles.py`` (``--skip-pallet``, ``--skip-piles``,
``--quick-piles``).

**Pallet** (``pallet_section``): the GLT palletizer, on a 500 mm pedestal (its base raised
500 mm: on the floor it cannot hold a box level over a fourth layer of 250 mm boxes, its
forearm passing under its wrist there), fills a EUR pallet (1200 x 800 x 144 mm on the floor,
10 mm of overhang, 5 mm between boxes) from a conveyor (``planning.cycles.pallet``): the
pallet's centre 800 mm in front of the robot turned 90° (its length across), the pick on a
700 mm conveyor 900 mm to the robot's right; the pedestal and the conveyor are obstacles. Three
pallets: ``column`` and ``interlocked`` with 400 x 300 x 250 mm boxes, ``interlocked``
with 600 x 400 x 300 mm boxes, 4 layers each (``--layers``). Each is re-checked here,
outside the planner:

* **placed**: every box of the pattern placed (``placed/total``);
* **contacts**: the planner keeps 2 mm from everything (``margin_mm``); python-fcl
  distances, every carry and every return densified to 0.01 rad per joint step, of the
  robot's link capsules (60 mm, between consecutive frames) and of the carried box (at FK
  of the state with the grasp) against the pallet, the pedestal, the conveyor and every box
  resting at that moment (pairs whose bounding spheres are apart skipped); ``min_mm`` the
  least distance measured, and its pair;
* **tilt**: the carried box's largest tilt along its densified carry (rad), against the
  tolerance (0.05 rad);
* **boxes/h**: placed boxes per hour of the cycle times (time-optimal trajectories within
  the robot's limits), beside a **baseline** that a teach-in program would run: rest to
  rest quintic point-to-point moves (``quintic_segments``, each stretched uniformly to the
  robot's limits, ``fit_to_limits(per_segment=True)``) from the pick up to a fixed safe
  height (the box's bottom 50 mm over the full stack), across to above the place at that
  height, down to the place, and back the same way to the next pick. The baseline's
  configurations are IK solutions nearest the one before; its motions are not
  collision-checked (a measure of time only).

Run: ``python benchmarks/bench_cycles.py [--layers N] [--time-limit S]`` (a few minutes).
"""

from __future__ import annotations

import argparse
import math
import time
from typing import Any

import numpy as np

from kinematics.fk import fk, fk_frames
from kinematics.library import builtin_model
from planning.cycles.pallet import (
    EUR_PALLET,
    Box,
    Pallet,
    plan_pallet,
)

#: The cell (module docstring).
PALLET_POSE = np.array([[0.0, -1, 0, 800], [1, 0, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]])
PEDESTAL = 500.0
PICK_XY = (0.0, -900.0)
CONVEYOR_TOP = 700.0
TILT = 0.05
GRIP, CLEAR = 65.0, 5.0
#: Closer than this counts as a collision for the planner (mm).
MARGIN = 2.0
SAFE_MARGIN = 50.0
LINK_RADIUS = 60.0
PALLETS = (("column", (400.0, 300.0, 250.0)), ("interlocked", (400.0, 300.0, 250.0)),
           ("interlocked", (600.0, 400.0, 300.0)))


def _conveyor() -> dict:
    return {"type": "box", "id": "conveyor", "size": [500.0, 700.0, CONVEYOR_TOP],
            "pose": [[1, 0, 0, PICK_XY[0]], [0, 1, 0, PICK_XY[1]],
                     [0, 0, 1, CONVEYOR_TOP / 2], [0, 0, 0, 1]]}


def _pedestal() -> dict:
    return {"type": "box", "id": "pedestal", "size": [500.0, 500.0, PEDESTAL],
            "pose": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, PEDESTAL / 2], [0, 0, 0, 1]]}


def glt_on_pedestal() -> Any:
    """The GLT palletizer with its base raised ``PEDESTAL`` mm."""
    from kinematics.model import RobotModel

    data = builtin_model("glt_palletizer").to_dict()
    data["base"][2][3] += PEDESTAL
    data["id"] = "glt_palletizer_pedestal"
    return RobotModel.from_dict(data)


def _pick(box: tuple) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = (*PICK_XY, CONVEYOR_TOP + box[2] / 2)
    return T


def _dense(path: np.ndarray, step: float = 0.01) -> np.ndarray:
    out = [path[:1]]
    for a, b in zip(path[:-1], path[1:]):
        n = max(1, int(math.ceil(np.abs(b - a).max() / step)))
        out.append(a + (b - a) * np.linspace(0, 1, n + 1)[1:, None])
    return np.concatenate(out)


# ---- the exact re-check ------------------------------------------------------------------
class _Obstacles:
    """FCL boxes with bounding spheres."""

    def __init__(self) -> None:
        self.objects: list = []
        self.centres: list = []
        self.radii: list = []
        self.names: list = []

    def add(self, size, T, name: str) -> None:
        import fcl

        self.objects.append(fcl.CollisionObject(fcl.Box(*size),
                                                fcl.Transform(T[:3, :3], T[:3, 3])))
        self.centres.append(np.asarray(T[:3, 3], dtype=float))
        self.radii.append(0.5 * float(np.linalg.norm(size)))
        self.names.append(name)

    def extend(self, other: _Obstacles) -> None:
        for key in ("objects", "centres", "radii", "names"):
            getattr(self, key).extend(getattr(other, key))


def _bodies(model: Any, q: np.ndarray, G: np.ndarray, box: tuple | None) -> list:
    """(fcl object, centre, radius, name) of the link capsules and the carried box at
    ``q``."""
    import fcl

    F = fk_frames(model, q)
    out = []
    for k in range(1, model.dof):
        a, b = F[k, :3, 3], F[k + 1, :3, 3]
        L = float(np.linalg.norm(b - a))
        if L < 1e-6:
            continue
        z = (b - a) / L
        x = np.cross(z, [1, 0, 0]) if abs(z[0]) < 0.9 else np.cross(z, [0, 1, 0])
        x /= np.linalg.norm(x)
        R = np.column_stack([x, np.cross(z, x), z])
        c = (a + b) / 2
        out.append((fcl.CollisionObject(fcl.Capsule(LINK_RADIUS, L), fcl.Transform(R, c)),
                    c, L / 2 + LINK_RADIUS, f"link{k}"))
    if box is not None:
        T = F[-1] @ G
        out.append((fcl.CollisionObject(fcl.Box(*box), fcl.Transform(T[:3, :3], T[:3, 3])),
                    T[:3, 3], 0.5 * float(np.linalg.norm(box)), "carried box"))
    return out


def _recheck(model: Any, path: np.ndarray, G: np.ndarray, box: tuple | None,
             obstacles: _Obstacles) -> tuple[int, float, str]:
    """(states in contact, least distance measured, its pair) along ``path`` densified."""
    import fcl

    C = np.array(obstacles.centres)
    Rr = np.array(obstacles.radii)
    contacts, least, pair = 0, math.inf, ""
    for q in _dense(path):
        hit = False
        for obj, c, r, name in _bodies(model, q, G, box):
            near = np.flatnonzero(np.linalg.norm(C - c, axis=1) - Rr - r < 100.0)
            for j in near:
                d = fcl.distance(obj, obstacles.objects[j], fcl.DistanceRequest(),
                                 fcl.DistanceResult())
                if d < least:
                    least, pair = d, f"{name} - {obstacles.names[j]}"
                hit |= d <= 0.0
        contacts += hit
    return contacts, least, pair


# ---- the baseline ------------------------------------------------------------------------
def _ik_near(model: Any, T: np.ndarray, q: np.ndarray) -> np.ndarray | None:
    from kinematics.ik import solve_ik

    r = solve_ik(model, T, q0=q, all_solutions=True)[0]
    if r.q is None or not len(r.solutions):
        return None
    S = np.asarray(r.solutions)
    ok = np.all((S >= model.lower - 1e-9) & (S <= model.upper + 1e-9), axis=1)
    if not ok.any():
        return None
    S = S[ok]
    return S[int(np.argmin(np.abs(S - q).max(axis=1)))]


def _baseline_cycle(model: Any, q_pick: np.ndarray, q_place: np.ndarray,
                    q_next: np.ndarray, safe_tool_z: float) -> float | None:
    """Seconds of the baseline's pick -> safe -> safe -> place -> safe -> safe -> next pick,
    rest to rest quintics stretched to the robot's limits (None: the safe height is out of
    reach there)."""
    from planning.trajectories.polynomials import quintic_segments
    from planning.trajectories.time_scaling import fit_to_limits
    from planning.trajectories.trajectory import ARM_ACCELERATION, Limits

    def at_safe(q: np.ndarray) -> np.ndarray | None:
        T = fk(model, q)
        T[2, 3] = safe_tool_z
        return _ik_near(model, T, q)

    ways = [q_pick]
    for q in (q_pick, q_place):
        s = at_safe(q)
        if s is None:
            return None
        ways.append(s)
    ways.append(q_place)
    for q in (q_place, q_next):
        s = at_safe(q)
        if s is None:
            return None
        ways.append(s)
    ways.append(q_next)
    W = np.array(ways)
    keep = np.concatenate([[True], np.abs(np.diff(W, axis=0)).max(axis=1) > 1e-9])
    W = W[keep]
    traj = quintic_segments(W, np.ones(len(W) - 1))
    acc = np.where(model.revolute, ARM_ACCELERATION[0], ARM_ACCELERATION[1])
    limits = Limits(velocity=np.asarray(model.velocity_limits), acceleration=acc)
    return float(fit_to_limits(traj, limits, per_segment=True).duration)


# ---- the section -------------------------------------------------------------------------
def pallet_row(model: Any, pattern: str, size: tuple, layers: int, time_limit: float
               ) -> dict[str, Any]:
    """Plan one pallet, re-check it, time the baseline: one row of the table."""
    pallet = Pallet(EUR_PALLET, PALLET_POSE, overhang=10.0)
    box = Box(size)
    t0 = time.perf_counter()
    res = plan_pallet(model, _pick(size), box, pallet, pattern, layers=layers, gap=5.0,
                      approach_mm=100.0, retreat_mm=100.0, tilt_tolerance=TILT,
                      grip_offset_mm=GRIP, clearance_mm=CLEAR, margin_mm=MARGIN,
                      obstacles=[_conveyor(), _pedestal()],
                      time_limit=time_limit,
                      progress=lambda f, m: print(f"  {pattern} {size[0]:g}x{size[1]:g}: {m}",
                                                  flush=True))
    plan_s = time.perf_counter() - t0
    G = res.T_tool_box
    fixed = _Obstacles()
    fixed.add(pallet.size, np.asarray(pallet.object()["pose"]), "pallet")
    for o in (_conveyor(), _pedestal()):
        fixed.add(o["size"], np.asarray(o["pose"]), o["id"])
    contacts, least, tilt, nearest = 0, math.inf, 0.0, ""
    resting: list = []
    stack_top = pallet.top + size[2] * (max(b.layer for b in res.boxes
                                            if b.layer is not None) + 1)
    safe_tool_z = stack_top + SAFE_MARGIN + size[2] + GRIP
    base_s, base_missing = 0.0, 0
    t1 = time.perf_counter()
    for b in res.boxes:
        if not b.placed:
            continue
        obs = _Obstacles()
        for o in (fixed, *resting):
            obs.extend(o)
        c, d, p = _recheck(model, b.carry.path, G, size, obs)
        contacts += c
        if d < least:
            least, nearest = d, f"box {b.index}'s carry: {p}"
        Q = _dense(b.carry.path)
        T = fk(model, Q) @ G
        tilt = max(tilt, float(np.arccos(np.clip(T[:, 2, 2], -1, 1)).max()))
        mine = _Obstacles()
        mine.add(size, b.placed_pose, f"box {b.index}")
        resting.append(mine)
        obs.extend(mine)
        if b.back is not None and len(b.back.path) > 1:
            c, d, p = _recheck(model, b.back.path, G, None, obs)
            contacts += c
            if d < least:
                least, nearest = d, f"box {b.index}'s return: {p}"
        q_next = b.back.path[-1] if b.back is not None else b.q_pick
        s = _baseline_cycle(model, b.q_pick, b.q_place, q_next, safe_tool_z)
        if s is None:
            base_missing += 1
        else:
            base_s += s
    check_s = time.perf_counter() - t1
    placed = res.placed
    counted = placed - base_missing
    return {"pattern": pattern, "box": f"{size[0]:g}x{size[1]:g}x{size[2]:g}",
            "layers": layers, "placed": placed, "total": len(res.boxes),
            "contacts": contacts, "min_mm": least, "nearest": nearest, "tilt": tilt,
            "cycle_s": res.pallet_s / max(placed, 1), "per_hour": res.boxes_per_hour,
            "base_per_hour": 3600.0 * counted / base_s if base_s > 0 else float("nan"),
            "base_missing": base_missing, "plan_s": plan_s, "check_s": check_s,
            "failures": [(b.index, b.status, b.reason[:120]) for b in res.boxes
                         if not b.placed]}


def pallet_section(layers: int = 4, time_limit: float = 10.0) -> list[dict[str, Any]]:
    """The pallet half: the three pallets of the module docstring, a table printed."""
    from planning.warm import warm_up

    warm_up(["kinematics", "motion"])
    model = glt_on_pedestal()
    rows = [pallet_row(model, pattern, size, layers, time_limit) for pattern, size in PALLETS]
    print(f"\nPallet: GLT palletizer on a {PEDESTAL:g} mm pedestal, EUR pallet 1200 x 800, "
          f"{layers} layers, tilt tolerance {TILT} rad")
    head = (f"{'pattern':<12} {'box mm':<12} {'placed':>7} {'contacts':>8} {'min mm':>7} "
            f"{'tilt rad':>8} {'cycle s':>7} {'boxes/h':>7} {'baseline/h':>10} "
            f"{'plan s':>7} {'check s':>7}")
    print(head)
    print("-" * len(head))
    for r in rows:
        print(f"{r['pattern']:<12} {r['box']:<12} {r['placed']:>3}/{r['total']:<3} "
              f"{r['contacts']:>8} {r['min_mm']:>7.2f} {r['tilt']:>8.4f} {r['cycle_s']:>7.2f} "
              f"{r['per_hour']:>7.0f} {r['base_per_hour']:>10.0f} {r['plan_s']:>7.0f} "
              f"{r['check_s']:>7.0f}")
        print(f"  nearest: {r['nearest']} ({r['min_mm']:.3f} mm)")
        if r["base_missing"]:
            print(f"  baseline: safe height out of reach for {r['base_missing']} box(es), "
                  "left out of its rate")
        for f in r["failures"]:
            print(f"  box {f[0]}: {f[1]}: {f[2]}")
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--layers", type=int, default=4)
    parser.add_argument("--time-limit", type=float, default=10.0,
                        help="s of planning per task")
    parser.add_argument("--skip-pallet", action="store_true")
    parser.add_argument("--skip-piles", action="store_true")
    parser.add_argument("--quick-piles", action="store_true", help="the 60-pile plan only")
    args = parser.parse_args()
    if not args.skip_pallet:
        pallet_section(args.layers, args.time_limit)
    if not args.skip_piles:
        from bench_piles import piles_section  # the pile driver's half (bench_piles.py)

        print("\n".join(piles_section(args.quick_piles)))


if __name__ == "__main__":
    main()
