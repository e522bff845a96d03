"""Work sites of the heavy machines as collision scenes for ``plan_motion``.

Each function returns a ``planning.collision.CollisionScene`` whose objects carry readable
ids (``wall``, ``trench_bottom``, ``tunnel``, ``pallet_left`` ...), so a colliding pair names
what was hit. Every length is in mm, in the machine's world frame (the frame ``fk``
reports in: z up); every parameter has a documented default sized from the machine's own
geometry, found by FK over a seeded sample of its configurations (``reach_band``).

* ``pile_driver_site``: the ground with a trench cut into it where the piles go, and a wall
  standing beside the machine on a line from its swing axis, so that swinging from one side
  of the wall to the other means lifting the arm over it;
* ``tunnel_site``: a horseshoe tunnel (vertical walls, semicircular roof, flat floor, the
  profile of ``planning.sequencing.patterns.FacePattern``) as one triangle mesh around the
  drilling jumbo, with the rock face closing it, for ``tunnel_drill_arm`` and the
  ``tunnel_jumbo``'s arms (the rig frame: x along the tunnel towards the face);
* ``pallet_station``: the floor, an infeed conveyor and one or two pallets with their loads
  around the GLT palletizer;
* ``jumbo_site``: the tunnel with the jumbo's other arms standing in it as capsules (one
  per link, ``arm_capsules``), for planning one arm's moves while the others wait.

``pile_driver_problems``, ``tunnel_problems`` and ``pallet_problems`` draw seeded sets of
typical moves in these sites (``SiteProblem``: start and goal configurations, both within
the joint limits and free by the given ``MotionChecker``): swinging over the wall, down
into the trench; from one collaring pose of the face to another; from the conveyor to a
pallet.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from kinematics.drilling import drill_ik
from kinematics.fk import fk, fk_frames
from kinematics.model import RobotModel
from planning.collision import CollisionScene
from planning.sequencing.patterns import FacePattern, face_pattern

__all__ = ["ReachBand", "reach_band", "pile_driver_site", "tunnel_site", "tunnel_profile",
           "pallet_station", "arm_capsules", "jumbo_site", "TUNNEL_MESH_RESOLUTION",
           "SiteProblem", "pile_driver_problems", "tunnel_problems", "pallet_problems"]

#: Configurations sampled (seeded) to measure a machine's reach.
REACH_SAMPLES = 20_000
#: Cube size (mm) of the balls standing for the tunnel mesh in the sphere stage: the tunnel's
#: ~450 m² of surface at the scene default of 15 mm would be two million balls; at 150 mm it
#: is about twenty thousand, and the exact stage decides what they flag.
TUNNEL_MESH_RESOLUTION = 150.0
#: The face plan whose profile the tunnel takes by default (10 m x 8 m horseshoe, face at
#: x = 9000 mm, floor 1500 mm below the booms' mounts).
_FACE = FacePattern()


@dataclass(frozen=True)
class ReachBand:
    """Where a machine's tool point goes (mm, world frame): ``inner`` and ``outer`` radius
    from the base's vertical axis through ``center (3,)``, lowest and highest ``z``."""

    center: np.ndarray
    inner: float
    outer: float
    z_min: float
    z_max: float


@lru_cache(maxsize=8)
def reach_band(model: RobotModel, samples: int = REACH_SAMPLES, seed: int = 7) -> ReachBand:
    """The tool point's reach over ``samples`` seeded in-limit configurations (unbounded
    joints over one turn)."""
    lo = np.where(np.isfinite(model.lower), model.lower, -math.pi)
    hi = np.where(np.isfinite(model.upper), model.upper, math.pi)
    Q = np.random.default_rng(seed).uniform(lo, hi, size=(samples, model.dof))
    P = fk(model, Q)[:, :3, 3]
    c = model.base[:3, 3]
    r = np.hypot(P[:, 0] - c[0], P[:, 1] - c[1])
    return ReachBand(c.copy(), float(r.min()), float(r.max()), float(P[:, 2].min()),
                     float(P[:, 2].max()))


def _box(oid: str, lower, upper) -> dict:
    lower, upper = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    T = np.eye(4)
    T[:3, 3] = (lower + upper) / 2
    return {"type": "box", "id": oid, "size": (upper - lower).tolist(), "pose": T.tolist()}


def _rotated_box(oid: str, center, size, yaw: float) -> dict:
    T = np.eye(4)
    c, s = math.cos(yaw), math.sin(yaw)
    T[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    T[:3, 3] = center
    return {"type": "box", "id": oid, "size": [float(v) for v in size], "pose": T.tolist()}


# ---- the pile driver ----------------------------------------------------------------------
def pile_driver_site(model: RobotModel, *, ground_z: float | None = None,
                     ground_half: float | None = None, slab: float = 300.0,
                     trench_x: float | None = None, trench_width: float = 500.0,
                     trench_depth: float = 700.0, wall_angle: float = math.pi / 2,
                     wall_from: float | None = None, wall_to: float | None = None,
                     wall_thickness: float = 250.0, wall_height: float = 800.0
                     ) -> CollisionScene:
    """The pile driver's site (module docstring), sized from ``reach_band(model)``:

    * the ground, ``slab`` mm thick, its top at ``ground_z`` (default 400 mm above the
      lowest tool point, so the tool can go 400 mm into the trench) over a square of half
      side ``ground_half`` (default the outer reach + 700) around the swing axis;
    * a trench across it, parallel to y, centred at ``x = trench_x`` (default the middle of
      the reach band), ``trench_width`` wide and ``trench_depth`` deep: the ground is two
      slabs (``ground_near``, ``ground_far``) and the trench's bottom (``trench_bottom``);
    * a wall (``wall``) standing on the ground along the line from the swing axis at
      ``wall_angle`` (rad from +x, default +y), from ``wall_from`` (default 0.7 of the inner
      reach) to ``wall_to`` (default the outer reach + 500) from the axis,
      ``wall_thickness`` thick and ``wall_height`` high above the ground."""
    band = reach_band(model)
    cx, cy = float(band.center[0]), float(band.center[1])
    gz = band.z_min + 400.0 if ground_z is None else float(ground_z)
    G = band.outer + 700.0 if ground_half is None else float(ground_half)
    tx = cx + (band.inner + band.outer) / 2 if trench_x is None else float(trench_x)
    a, b = tx - trench_width / 2, tx + trench_width / 2
    y0, y1 = cy - G, cy + G
    objects = [
        _box("ground_near", [cx - G, y0, gz - slab], [a, y1, gz]),
        _box("ground_far", [b, y0, gz - slab], [max(cx + G, b + slab), y1, gz]),
        _box("trench_bottom", [a, y0, gz - trench_depth - slab], [b, y1, gz - trench_depth]),
    ]
    r0 = 0.7 * band.inner if wall_from is None else float(wall_from)
    r1 = band.outer + 500.0 if wall_to is None else float(wall_to)
    mid = (r0 + r1) / 2
    centre = [cx + mid * math.cos(wall_angle), cy + mid * math.sin(wall_angle),
              gz + wall_height / 2]
    objects.append(_rotated_box("wall", centre, [r1 - r0, wall_thickness, wall_height],
                                wall_angle))
    return CollisionScene.from_dicts(objects)


# ---- the tunnel ---------------------------------------------------------------------------
def tunnel_profile(width: float = _FACE.width, height: float = _FACE.height,
                   roof_segments: int = 24) -> np.ndarray:
    """The horseshoe outline ``(n, 2)`` as ``(u, v)`` mm (u across from the centre line,
    v up from the floor), counter-clockwise seen from the face, closed implicitly: the
    floor, the right wall, the semicircular roof of radius ``width / 2`` in
    ``roof_segments`` chords, the left wall. Needs ``height > width / 2``."""
    if not (width > 0 and height > width / 2):
        raise ValueError("height: a horseshoe needs width > 0 and height > width / 2")
    R = width / 2
    spring = height - R
    t = np.linspace(0.0, math.pi, roof_segments + 1)
    roof = np.column_stack([R * np.cos(t), spring + R * np.sin(t)])
    return np.vstack([[[-R, 0.0], [R, 0.0]], roof])


def tunnel_site(*, width: float = _FACE.width, height: float = _FACE.height,
                floor_z: float = _FACE.floor_z, center_y: float = _FACE.center_y,
                face_x: float = _FACE.face_x, back_x: float = -4000.0,
                rings: int = 8, roof_segments: int = 24, face: bool = True,
                mesh_resolution: float = TUNNEL_MESH_RESOLUTION) -> CollisionScene:
    """The tunnel around the jumbo (module docstring) as one mesh ``tunnel``: the horseshoe
    ``tunnel_profile(width, height)`` with its floor at ``z = floor_z`` and centre line at
    ``y = center_y`` (defaults: ``FacePattern``'s, so its holes lie on the face), extruded
    along x from ``back_x`` (behind the carrier) to ``face_x`` in ``rings`` lengths, and,
    with ``face``, the rock face at ``x = face_x`` closing it (a fan of triangles). The
    mesh is a surface: the arm collides with the rock's surface, the inside is free. A drill
    tip on a hole of the face touches it: plan to collaring poses a little before the face.
    ``mesh_resolution``: the scene's ball size for the mesh (``TUNNEL_MESH_RESOLUTION``)."""
    uv = tunnel_profile(width, height, roof_segments)
    n = len(uv)
    yz = np.column_stack([center_y + uv[:, 0], floor_z + uv[:, 1]])
    xs = np.linspace(back_x, face_x, rings + 1)
    V = np.concatenate([np.column_stack([np.full(n, x), yz]) for x in xs])
    F = []
    for r in range(rings):
        for k in range(n):
            i0, i1 = r * n + k, r * n + (k + 1) % n
            j0, j1 = i0 + n, i1 + n
            F += [[i0, i1, j1], [i0, j1, j0]]
    if face:
        centre = len(V)
        c_uv = uv.mean(axis=0)
        V = np.vstack([V, [[face_x, center_y + c_uv[0], floor_z + c_uv[1]]]])
        last = rings * n
        F += [[centre, last + k, last + (k + 1) % n] for k in range(n)]
    obj = {"type": "mesh", "id": "tunnel", "vertices": V.tolist(), "faces": F}
    return CollisionScene(CollisionScene.from_dicts([obj]).objects, mesh_resolution)


def arm_capsules(model: RobotModel, q, link_radius: float = 60.0, prefix: str = "arm"
                 ) -> list[dict]:
    """An arm standing at ``q (dof,)`` as capsule objects (API format), one per link of
    non-zero length between consecutive ``fk_frames`` origins, ``link_radius`` mm: the
    capsules ``RobotCollisionModel.from_model`` gives that arm, ids ``<prefix>_link<k>``."""
    F = fk_frames(model, np.asarray(q, dtype=float)[None])[0, :, :3, 3]
    out = []
    for k in range(model.dof):
        a, b = F[k], F[k + 1]
        if np.linalg.norm(b - a) > 1e-9:
            out.append({"type": "capsule", "id": f"{prefix}_link{k}", "a": a.tolist(),
                        "b": b.tolist(), "radius": float(link_radius)})
    return out


def jumbo_site(rig, parked: dict, *, link_radius: float = 60.0, **tunnel) -> CollisionScene:
    """``tunnel_site(**tunnel)`` (in the rig frame) with the arms of ``rig``
    (``kinematics.rigs.Rig``) named in ``parked`` standing at their configurations
    (``{arm name: q (dof,)}``) as ``arm_capsules`` of ``link_radius`` mm, ids
    ``<arm>_link<k>``: the scene one arm of the jumbo moves in while these wait. Plan for
    that arm with its rig model ``rig.arms[name]`` (its mount folded into its base)."""
    site = tunnel_site(**tunnel)
    capsules = [c for name, q in parked.items()
                for c in arm_capsules(rig.arms[name], q, link_radius, name)]
    extra = CollisionScene.from_dicts(capsules).objects
    return CollisionScene(site.objects + extra, site.mesh_resolution)


# ---- the palletizer -------------------------------------------------------------------------
def pallet_station(model: RobotModel, *, floor_z: float = 0.0,
                   pallet_size: tuple[float, float, float] = (1200.0, 800.0, 144.0),
                   pallet_radius: float | None = None, pallet_angles: tuple[float, ...] = (
                       -math.pi / 2, math.pi / 2), load_height: float = 500.0,
                   conveyor_angle: float = 0.0, conveyor_from: float | None = None,
                   conveyor_length: float = 1600.0, conveyor_width: float = 600.0,
                   conveyor_height: float = 750.0) -> CollisionScene:
    """The GLT palletizer's station (module docstring), sized from ``reach_band(model)``:

    * the floor (``floor``, 100 mm thick, its top at ``floor_z``) under the reach;
    * a pallet (``pallet_<k>``, a EUR pallet by default: ``pallet_size`` = length, width,
      height) at each of ``pallet_angles`` (rad from +x), its centre ``pallet_radius``
      (default 0.55 of the outer reach) from the base axis and its length across that
      line, carrying a load ``load_height`` high (``load_<k>``: the layers already
      stacked, 50 mm inside the pallet's edges);
    * the infeed conveyor (``conveyor``) along the line at ``conveyor_angle``, from
      ``conveyor_from`` (default 0.45 of the outer reach) outwards for
      ``conveyor_length``, ``conveyor_width`` wide, its belt ``conveyor_height`` above the
      floor."""
    band = reach_band(model)
    cx, cy = float(band.center[0]), float(band.center[1])
    G = band.outer + 500.0
    objects = [_box("floor", [cx - G, cy - G, floor_z - 100.0], [cx + G, cy + G, floor_z])]
    r = 0.55 * band.outer if pallet_radius is None else float(pallet_radius)
    L, W, H = (float(v) for v in pallet_size)
    for k, angle in enumerate(pallet_angles):
        c = np.array([cx + r * math.cos(angle), cy + r * math.sin(angle)])
        # Length across the line from the axis: the box's x axis along the tangent.
        yaw = angle + math.pi / 2
        objects.append(_rotated_box(f"pallet_{k}", [c[0], c[1], floor_z + H / 2],
                                    [L, W, H], yaw))
        if load_height > 0:
            objects.append(_rotated_box(f"load_{k}", [c[0], c[1], floor_z + H +
                                                      load_height / 2],
                                        [L - 100.0, W - 100.0, load_height], yaw))
    r0 = 0.45 * band.outer if conveyor_from is None else float(conveyor_from)
    mid = r0 + conveyor_length / 2
    objects.append(_rotated_box(
        "conveyor", [cx + mid * math.cos(conveyor_angle), cy + mid * math.sin(conveyor_angle),
                     floor_z + conveyor_height / 2],
        [conveyor_length, conveyor_width, conveyor_height], conveyor_angle))
    return CollisionScene.from_dicts(objects)


# ---- typical moves ----------------------------------------------------------------------------
@dataclass(frozen=True)
class SiteProblem:
    """A move to plan: ``start`` and ``goal`` configurations ``(dof,)`` (free, within the
    limits) and ``kind``, what the move is (``over_wall``, ``cut->helper`` ...)."""

    kind: str
    start: np.ndarray
    goal: np.ndarray


#: Configurations drawn per batch while looking for problems, and most batches.
_DRAW = 4096
_BATCHES = 64


def _object(scene: CollisionScene, oid: str):
    for o in scene.objects:
        if o.id == oid:
            return o
    raise KeyError(f"the scene has no object '{oid}'")


def _draw(checker, rng: np.random.Generator, accept, swing: tuple[float, float] | None = None
          ) -> np.ndarray:
    """One free in-limit configuration that ``accept(Q, T) -> (B,) bool`` takes (``T`` the
    tool poses ``(B, 4, 4)``), the first joint drawn in ``swing`` when given;
    ``RuntimeError`` when none turns up."""
    model = checker.robot_model
    lo = np.where(np.isfinite(checker.lower), checker.lower, -math.pi)
    hi = np.where(np.isfinite(checker.upper), checker.upper, math.pi)
    for _ in range(_BATCHES):
        Q = rng.uniform(lo, hi, size=(_DRAW, checker.dof))
        if swing is not None:
            Q[:, 0] = np.clip(rng.uniform(min(swing), max(swing), size=_DRAW), lo[0], hi[0])
        ok = accept(Q, fk(model, Q))
        for i in np.flatnonzero(ok)[:32]:
            if checker.free(Q[i]):
                return Q[i]
    raise RuntimeError("no free configuration of that kind found")


def pile_driver_problems(checker, n: int, seed: int = 0) -> list[SiteProblem]:
    """``n`` moves of the pile driver in ``checker``'s ``pile_driver_site`` scene, kinds in
    turn: ``over_wall`` (from one side of the wall to the other, the tool lower than the
    wall's top at both ends and the straight joint-space move blocked) and ``into_trench``
    (from the tool above the ground, at least 1 rad of swing away, to the tool in the
    trench below the ground's top)."""
    scene = checker.scene
    rng = np.random.default_rng(seed)
    wall = _object(scene, "wall")
    yaw = math.atan2(wall.pose[1, 0], wall.pose[0, 0])
    top = wall.pose[2, 3] + wall.size[2] / 2
    bottom = _object(scene, "trench_bottom")
    a = bottom.pose[0, 3] - bottom.size[0] / 2
    b = bottom.pose[0, 3] + bottom.size[0] / 2
    ground = _object(scene, "ground_near")
    gz = ground.pose[2, 3] + ground.size[2] / 2
    out: list[SiteProblem] = []
    while len(out) < n:
        if len(out) % 2 == 0:
            side = 1.0 if rng.random() < 0.5 else -1.0

            def low(Q, T):
                return T[:, 2, 3] < top

            s = _draw(checker, rng, low, (yaw - side * 1.2, yaw - side * 0.35))
            g = _draw(checker, rng, low, (yaw + side * 0.35, yaw + side * 1.2))
            if checker.segment_free(s, g):
                continue
            out.append(SiteProblem("over_wall", s, g))
        else:
            def in_trench(Q, T):
                x = T[:, 0, 3]
                return (x > a + 80) & (x < b - 80) & (T[:, 2, 3] < gz)

            g = _draw(checker, rng, in_trench)

            def away(Q, T, g=g):
                turn = np.abs((Q[:, 0] - g[0] + math.pi) % (2 * math.pi) - math.pi)
                return (T[:, 2, 3] > gz + 100) & (turn > 1.0)

            s = _draw(checker, rng, away)
            out.append(SiteProblem("into_trench", s, g))
    return out


def tunnel_problems(checker, n: int, seed: int = 0, *, pattern: FacePattern | None = None,
                    standoff: float = 300.0, min_distance: float = 2000.0
                    ) -> list[SiteProblem]:
    """``n`` moves of a drilling arm (``checker``'s robot, e.g. ``tunnel_drill_arm``, in its
    ``tunnel_site``) between collaring poses: the drill tip ``standoff`` mm before a hole of
    ``pattern``'s face (default ``FacePattern()``), perpendicular to the face
    (``kinematics.drilling.drill_ik``), the two holes at least ``min_distance`` apart; only
    holes whose collaring pose is free take part. ``kind``: ``"<hole kind>-><hole kind>"``."""
    face = face_pattern(pattern or FacePattern())
    H = face.holes.copy()
    H[:, 0] -= standoff
    res = drill_ik(checker.robot_model, H)
    usable = [k for k, r in enumerate(res) if r.q is not None]
    Q = np.array([res[k].q for k in usable]).reshape(-1, checker.dof)
    free = np.atleast_1d(checker.free(Q)) if len(Q) else np.zeros(0, dtype=bool)
    idx = [usable[i] for i in np.flatnonzero(free)]
    q_of = {usable[i]: Q[i] for i in range(len(usable))}
    if len(idx) < 2:
        raise RuntimeError("fewer than two free collaring poses")
    rng = np.random.default_rng(seed)
    out: list[SiteProblem] = []
    for _ in range(1000 * n):
        if len(out) == n:
            break
        i, j = rng.choice(idx, size=2, replace=False)
        if np.linalg.norm(face.holes[i] - face.holes[j]) < min_distance:
            continue
        out.append(SiteProblem(f"{face.kinds[i]}->{face.kinds[j]}", q_of[i], q_of[j]))
    return out


def pallet_problems(checker, n: int, seed: int = 0, *, clearance: float = 150.0
                    ) -> list[SiteProblem]:
    """``n`` moves of the palletizer in ``checker``'s ``pallet_station`` scene: from a
    configuration with the tool point between ``clearance`` and ``clearance + 300`` mm
    above the conveyor's belt to one with the tool likewise above a pallet's load (the
    pallets in turn), the tool pointing down (within 30 degrees) at both."""
    scene = checker.scene
    rng = np.random.default_rng(seed)
    conveyor = _object(scene, "conveyor")
    loads = [o for o in scene.objects if o.id.startswith("load_")] or \
        [o for o in scene.objects if o.id.startswith("pallet_")]

    def above(obj):
        T_inv = np.linalg.inv(obj.pose)
        half = np.asarray(obj.size) / 2

        def accept(Q, T):
            L = T[:, :3, 3] @ T_inv[:3, :3].T + T_inv[:3, 3]
            inside = np.all(np.abs(L[:, :2]) < half[:2] - 50.0, axis=1)
            h = L[:, 2] - half[2]
            down = T[:, 2, 2] < -math.cos(math.radians(30))
            return inside & (h > clearance) & (h < clearance + 300.0) & down
        return accept

    out: list[SiteProblem] = []
    while len(out) < n:
        s = _draw(checker, rng, above(conveyor))
        g = _draw(checker, rng, above(loads[len(out) % len(loads)]))
        out.append(SiteProblem("conveyor->pallet", s, g))
    return out
