"""Every compiled kernel of kinoplan, loaded (or compiled) in one call.

The numba kernels live in three places: the kinematics kernels (``kinematics._kernels``,
readied by ``kinematics.fast.warm_up``), the motion planner's collision checks and searches
(``planning.motion._kernels`` and ``_rrt``, by ``planning.motion.warm_up``) and the hole
sequencing search (``planning.sequencing.oropt``, by its ``warm_up``). Each is compiled once
per machine into numba's cache (``cache=True``; tens of seconds in all, the first time) and
then loaded in about a second per process. Every process that serves requests or runs job
steps calls ``warm_up`` here (or ``start_warm_up`` when it must answer at once), and so does
the Docker image at build time (``python -m kinoplan warm-up``), so that no request, job step
or plan's time limit pays for either.

This module sits in ``planning`` because it is the lowest package that sees every kernel:
the service (``app``) and the viewer call it, it calls nothing above itself.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

__all__ = ["WarmUpReport", "warm_up", "start_warm_up", "PARTS"]

log = logging.getLogger(__name__)


def _kinematics() -> bool:
    from kinematics import fast

    thread = _kinematics_thread
    if thread is not None:  # a background load is under way (start_warm_up): wait for it
        thread.join()
    return fast.warm_up().enabled


def _motion() -> bool:
    from kinematics import fast
    from planning.motion.warm import warm_up as warm_motion

    warm_motion()
    return fast.kernels() is not None  # the motion kernels run where these do


def _sequencing() -> bool:
    from planning.sequencing.oropt import HAVE_NUMBA
    from planning.sequencing.oropt import warm_up as warm_sequencing

    warm_sequencing()
    return HAVE_NUMBA


#: The parts, in the order they load: name -> the function that readies them (True when
#: compiled kernels were loaded, False when the library runs without them).
PARTS: dict[str, Callable[[], bool]] = {
    "kinematics": _kinematics,
    "motion": _motion,
    "sequencing": _sequencing,
}


@dataclass(frozen=True)
class WarmUpReport:
    """What ``warm_up`` did: the seconds each part of ``PARTS`` took in this process (about
    a second in all from numba's cache; tens of seconds when it compiled them) and whether
    each ran compiled kernels (False: numba missing or ``KINOPLAN_JIT=0``, the numpy path)."""

    seconds: dict[str, float] = field(default_factory=dict)
    compiled: dict[str, bool] = field(default_factory=dict)

    @property
    def total_seconds(self) -> float:
        return sum(self.seconds.values())


_lock = threading.Lock()
_seconds: dict[str, float] = {}  # part -> seconds it took to load in this process
_compiled: dict[str, bool] = {}
_kinematics_thread: threading.Thread | None = None


def warm_up(parts: Iterable[str] | None = None) -> WarmUpReport:
    """Load (or, the first time on a machine, compile) every numba kernel of kinematics,
    the motion planner and the sequencing search, each run once on a small problem with the
    argument types the service's requests and job kinds use.

    Call it before the first request or job step a process serves. ``parts`` (names of
    ``PARTS``; default all of them) limits it to some, for a module that needs only its own
    at import. Each part loads once per process: safe to call again and from several
    threads (later calls wait for the first). The report gives the seconds each asked part
    took when it loaded."""
    names = list(PARTS) if parts is None else list(parts)
    unknown = [name for name in names if name not in PARTS]
    if unknown:
        raise ValueError(f"unknown kernel parts {unknown}; known: {list(PARTS)}")
    with _lock:
        for name in names:
            if name not in _seconds:
                t0 = time.perf_counter()
                _compiled[name] = PARTS[name]()
                _seconds[name] = time.perf_counter() - t0
        return WarmUpReport({name: _seconds[name] for name in names},
                            {name: _compiled[name] for name in names})


def start_warm_up(parts: Iterable[str] | None = None) -> threading.Thread:
    """``warm_up(parts)`` in a background daemon thread, for a process that must answer at
    once even while the kernels load: until the kinematics kernels are ready its calls take
    the numpy path (``kinematics.fast.start_warm_up``: the same answers, slower); the motion
    and sequencing kernels follow. Returns the thread."""
    global _kinematics_thread
    from kinematics import fast

    names = list(PARTS) if parts is None else list(parts)
    with _lock:
        if "kinematics" in names and "kinematics" not in _seconds and _kinematics_thread is None:
            _kinematics_thread = fast.start_warm_up()
    thread = threading.Thread(target=_warm_in_background, args=(names,),
                              name="kinoplan-warm-up", daemon=True)
    thread.start()
    return thread


def _warm_in_background(parts: list[str]) -> None:
    try:
        warm_up(parts)
    except Exception:  # noqa: BLE001 - each call then loads the kernels it needs itself
        log.exception("loading the compiled kernels failed; calls will load them as needed")
