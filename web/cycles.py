"""The work cycles the viewer can start: per robot or rig it shows, the stored plan it holds.

A ``StoredPlan`` names a whole-job kind (``round``, ``pallet`` or ``piles``: the work cycles
of ``planning.cycles``) and builds that job's params. When the robot or rig shown has one,
the viewer's "Work cycle" folder shows its **Run round**, **Run pallet** or **Run piles**
button; pressing it submits the job to the service's job manager, as ``POST /jobs`` would,
and the viewer follows it and draws its answer (``web.viewer.Viewer.run_cycle``).

The plans the service ships (``stored_plans``) are the examples the product documents, built
here in code so the service needs no file besides its packages:

* ``tunnel_jumbo`` -> ``round``: the sample face of ``examples/drill_face.csv`` (the same 22
  holes as the IREDES plan ``examples/drill_round.xml``, ``FACE-22``), made by
  ``planning.face_pattern`` as ``examples/make_examples.py`` makes it; about 30 s of planning;
* ``glt_palletizer`` -> ``pallet``: docs/pallet.md's example, four 400 x 300 x 250 mm boxes
  from the conveyor onto the EUR pallet of the GLT cell, interlocked; about 30 s;
* ``pile_driver`` -> ``piles``: docs/piles.md's example, four piles (one out of reach) from
  two candidate set-ups; under a second.

The mapping is handed to the viewer (``Viewer.start(..., cycles=...)``), so a test can give
a tiny plan (a hole, a box, a pile) whose job finishes in a second. Its keys are robot or rig
ids as the robot dropdown lists them; a plan's ``params()`` is called at every press, so a
builder may read what it needs then.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

__all__ = [
    "CYCLE_KINDS",
    "StoredPlan",
    "stored_plans",
    "check_plans",
    "sample_face_holes",
    "round_params",
    "pallet_params",
    "piles_params",
    "FACE_DEPTH_MM",
]

#: The job kinds a work-cycle button starts, in the order the panel lists them.
CYCLE_KINDS = ("round", "pallet", "piles")
#: Depth of the sample face's holes along the rig's +x, mm (``examples/make_examples.py``).
FACE_DEPTH_MM = 3200.0


@dataclass(frozen=True)
class StoredPlan:
    """A plan the viewer can run for one robot or rig: the job ``kind`` (one of
    ``CYCLE_KINDS``), what the plan is in a few words (``title``, plain text: the panel shows
    it as written) and ``params``, which builds the job's params (a JSON object) at each
    press."""

    kind: str
    title: str
    params: Callable[[], dict[str, Any]]

    @property
    def label(self) -> str:
        """The button that runs it: ``Run round``, ``Run pallet``, ``Run piles``."""
        return f"Run {self.kind}"


def sample_face_holes() -> list[dict[str, Any]]:
    """The 22 holes of the sample face, rig frame, mm: a 4.5 m x 3.8 m tunnel face
    (``planning.face_pattern``, 900 mm spacing, floor at z = -1500), its contour and
    lifters and every other cut hole, 3.2 m deep along +x; ids ``H01``.. and ``type`` the
    hole's kind. The rows of ``examples/drill_face.csv``."""
    import numpy as np

    from planning import face_pattern

    face = face_pattern(width=4500, height=3800, spacing=900, floor_z=-1500)
    kinds = np.array(face.kinds)
    cut = np.flatnonzero(kinds == "cut")[::2]
    keep = np.concatenate([np.flatnonzero(kinds != "cut"), cut])
    holes = []
    for n, k in enumerate(keep, start=1):
        collar = np.round(face.holes[k], 1) + 0.0   # no -0.0
        toe = collar + np.array([FACE_DEPTH_MM, 0.0, 0.0])
        holes.append({"id": f"H{n:02d}", "collar": collar.tolist(), "toe": toe.tolist(),
                      "type": str(kinds[k])})
    return holes


def round_params() -> dict[str, Any]:
    """The ``round`` params of the sample face for the built-in jumbo, defaults otherwise."""
    return {"rig": "tunnel_jumbo", "holes": sample_face_holes()}


def pallet_params() -> dict[str, Any]:
    """The ``pallet`` params of docs/pallet.md's example: the GLT palletizer takes 12.5 kg
    boxes of 400 x 300 x 250 mm from the conveyor at (0, -1100, 825) mm and stacks four in
    the interlocked pattern on the EUR pallet of its cell (10 mm of overhang)."""
    return {"robot": "glt_palletizer", "box": {"size": [400, 300, 250], "mass": 12.5},
            "pick": [[1, 0, 0, 0], [0, 1, 0, -1100], [0, 0, 1, 825], [0, 0, 0, 1]],
            "pallet": {"overhang": 10}, "pattern": "interlocked", "layers": 2, "count": 4}


def piles_params() -> dict[str, Any]:
    """The ``piles`` params of docs/piles.md's example: four vertical piles, three around
    the origin and one 9 m away (out of reach), two candidate set-ups of the carrier."""
    return {"robot": "pile_driver",
            "plan_csv": "id,x,y,z,rake,azimuth\nA1,1600,0,0,,\nA2,0,1600,0,,\n"
                        "A3,-1600,0,0,,\nF1,9000,0,0,,",
            "setups": {"positions": [[0, 0, 0], [4000, 0, 0]]},
            "drive_time": 45, "travel_speed": 400}


def stored_plans() -> dict[str, StoredPlan]:
    """The plans the service ships, by robot or rig id (module docstring)."""
    return {
        "tunnel_jumbo": StoredPlan("round", "the sample face: 22 holes, 3.2 m deep "
                                   "(examples/drill_round.xml, FACE-22)", round_params),
        "glt_palletizer": StoredPlan("pallet", "four 400 x 300 x 250 mm boxes onto the EUR "
                                     "pallet, interlocked", pallet_params),
        "pile_driver": StoredPlan("piles", "four vertical piles (one out of reach) from two "
                                  "candidate set-ups", piles_params),
    }


def check_plans(plans: Mapping[str, StoredPlan]) -> dict[str, StoredPlan]:
    """``plans`` as a dict, each a ``StoredPlan`` of a kind in ``CYCLE_KINDS`` (the panel has
    a button for those only); ValueError naming the key otherwise."""
    out = dict(plans)
    for key, plan in out.items():
        if not isinstance(plan, StoredPlan):
            raise ValueError(f"cycles[{key!r}]: expected a StoredPlan, got "
                             f"{type(plan).__name__}")
        if plan.kind not in CYCLE_KINDS:
            raise ValueError(f"cycles[{key!r}].kind: {plan.kind!r} is not a work cycle "
                             f"({', '.join(CYCLE_KINDS)})")
    return out
