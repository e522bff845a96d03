"""Capsule envelopes of a drilling arm's links and distances between arms.

Paper 002 (section 4.2) simplifies each drilling arm to enveloping bodies, one per link, and
checks the shortest distance between the bodies of two arms. Here every link is a capsule:
the segment between two link-frame origins of ``kinematics.fk.fk_frames`` swept by a ball of
the link's radius. For the tunnel drilling arm (frames: 0 base, i after joint i, 7 = tool):

======== ========== ================================================ ==========
link     frames     what it covers                                   radius, mm
======== ========== ================================================ ==========
mount    0 -> 1     the boom bracket on the carrier (a0, d1)         300
swing    1 -> 2     the swing/lift head (a1, d2)                     250
boom     2 -> 3     the telescopic boom, d3 = 4 .. 10 m              200
cradle   3 -> 5     the roll/compensation head (d5)                  250
wrist    5 -> 6     the compensation head to the feed holder (a5, d6) 250
feed     6 -> 7     the feed beam and drill up to the drill tip      200
======== ========== ================================================ ==========

The radii are not printed in the paper; they are round numbers for a boom of about 0.35 m
section and a feed beam with its rock drill (about 0.4 m across), and every function takes
other radii. Frames 3 and 4 coincide (a3 = d4 = 0), so there is no separate roll link.

Distances are signed surface distances in mm: the segment-segment distance (Ericson's
closed form, ``planning.geometry.segments.segment_segment_distance``, the
``("segment", "capsule")`` row of the geometry's pair table) minus both radii; negative
means the envelopes overlap. Batched: configurations lead, ``(S, ...)``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from kinematics.errors import FieldError
from kinematics.fk import fk_frames
from kinematics.model import RobotModel

from ..geometry.segments import segment_segment_distance

__all__ = [
    "DRILL_ARM_LINKS",
    "DRILL_ARM_RADII",
    "ArmEnvelope",
    "drill_arm_envelope",
    "capsules",
    "capsule_distances",
    "min_distance",
]

#: Link name -> (first frame, second frame) in ``fk_frames`` order (tunnel drilling arm).
DRILL_ARM_LINKS: dict[str, tuple[int, int]] = {
    "mount": (0, 1), "swing": (1, 2), "boom": (2, 3), "cradle": (3, 5), "wrist": (5, 6),
    "feed": (6, 7),
}
#: Default capsule radius per link, mm (see the module docstring).
DRILL_ARM_RADII: dict[str, float] = {
    "mount": 300.0, "swing": 250.0, "boom": 200.0, "cradle": 250.0, "wrist": 250.0,
    "feed": 200.0,
}
#: Most configurations one distance call handles at a time (bounds the temporaries).
CHUNK = 20_000


@dataclass(frozen=True)
class ArmEnvelope:
    """Capsules of an arm: ``names (L,)``, frame index pairs ``frames (L, 2)`` into
    ``fk_frames`` and ``radii (L,)`` mm."""

    names: tuple[str, ...]
    frames: np.ndarray
    radii: np.ndarray

    @property
    def size(self) -> int:
        return len(self.names)


def drill_arm_envelope(radii: Mapping[str, float] | None = None) -> ArmEnvelope:
    """The tunnel drilling arm's envelope, with ``radii`` (mm, by link name) overriding the
    defaults. ``FieldError`` naming ``radii.<link>`` for an unknown link or a bad radius."""
    r = dict(DRILL_ARM_RADII)
    for name, value in (radii or {}).items():
        if name not in DRILL_ARM_LINKS:
            raise FieldError(
                ("radii", name), f"radii.{name}: not a link of the drilling arm "
                f"(links: {', '.join(DRILL_ARM_LINKS)})"
            )
        if isinstance(value, bool) or not isinstance(value, (int, float)) or \
                not 0 <= value <= 5_000:
            raise FieldError(("radii", name),
                             f"radii.{name}: must be a number in [0, 5000] mm, got {value!r}")
        r[name] = float(value)
    names = tuple(DRILL_ARM_LINKS)
    frames = np.array([DRILL_ARM_LINKS[n] for n in names])
    radii_arr = np.array([r[n] for n in names])
    frames.setflags(write=False)
    radii_arr.setflags(write=False)
    return ArmEnvelope(names, frames, radii_arr)


def capsules(model: RobotModel, q, envelope: ArmEnvelope) -> np.ndarray:
    """Capsule axes of an arm: ``q (S, dof) -> (S, L, 2, 3)`` (segment end points, mm, in the
    model's world frame, i.e. the rig frame for a rig's arm)."""
    F = fk_frames(model, np.atleast_2d(np.asarray(q, dtype=float)))  # (S, dof+1, 4, 4)
    P = F[:, :, :3, 3]
    return np.stack([P[:, envelope.frames[:, 0]], P[:, envelope.frames[:, 1]]], axis=2)


def capsule_distances(A: np.ndarray, ra: np.ndarray, B: np.ndarray, rb: np.ndarray
                      ) -> np.ndarray:
    """Signed surface distances between every capsule of ``A (S, La, 2, 3)`` and of
    ``B (S, Lb, 2, 3)`` (or ``(Lb, 2, 3)``, the same for all S), radii ``ra (La,)``,
    ``rb (Lb,)`` mm. Returns ``(S, La, Lb)``; negative = overlap."""
    A = np.asarray(A, dtype=float)
    B = np.asarray(B, dtype=float)
    if B.ndim == 3:
        B = B[None]
    S = max(len(A), len(B))
    out = np.empty((S, A.shape[1], B.shape[1]))
    for s0 in range(0, S, CHUNK):
        a = A[s0 : s0 + CHUNK] if len(A) > 1 else A
        b = B[s0 : s0 + CHUNK] if len(B) > 1 else B
        d, _, _ = segment_segment_distance(
            a[:, :, None, 0], a[:, :, None, 1], b[:, None, :, 0], b[:, None, :, 1]
        )
        out[s0 : s0 + CHUNK] = d - ra[None, :, None] - rb[None, None, :]
    return out


def min_distance(A: np.ndarray, ra: np.ndarray, B: np.ndarray, rb: np.ndarray,
                 chunk: int = 256) -> np.ndarray:
    """Smallest signed surface distance between two arms at each sample:
    ``A (S, La, 2, 3)``, ``B (S, Lb, 2, 3)`` -> ``(S,)`` mm; exactly the minimum of
    ``capsule_distances`` over all link pairs, computed faster.

    Per block of ``chunk`` samples, every link's swept box (capsule ends over the block,
    grown by the radius) bounds its distances from below; the pair with the lowest bound is
    computed first, and then only the pairs whose bound is below the largest distance found
    so far (the others cannot hold the minimum at any sample of the block).
    """
    S = len(A)
    out = np.empty(S)
    for s0 in range(0, S, chunk):
        a, b = A[s0 : s0 + chunk], B[s0 : s0 + chunk]
        lo_a = a.min(axis=(0, 2)) - ra[:, None]
        hi_a = a.max(axis=(0, 2)) + ra[:, None]
        lo_b = b.min(axis=(0, 2)) - rb[:, None]
        hi_b = b.max(axis=(0, 2)) + rb[:, None]
        gap = np.maximum(0.0, np.maximum(lo_a[:, None] - hi_b[None], lo_b[None] - hi_a[:, None]))
        bound = np.linalg.norm(gap, axis=2)  # (La, Lb)
        i0, j0 = np.unravel_index(int(np.argmin(bound)), bound.shape)
        d, _, _ = segment_segment_distance(a[:, i0, 0], a[:, i0, 1], b[:, j0, 0], b[:, j0, 1])
        best = d - ra[i0] - rb[j0]
        ii, jj = np.nonzero(bound < best.max())
        if len(ii):
            d, _, _ = segment_segment_distance(a[:, ii, 0], a[:, ii, 1], b[:, jj, 0],
                                               b[:, jj, 1])
            best = np.minimum(best, (d - ra[ii] - rb[jj]).min(axis=1))
        out[s0 : s0 + chunk] = best
    return out
