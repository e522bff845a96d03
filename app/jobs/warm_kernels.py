"""Imported once by the processes that job steps start from (the local backend's forkserver,
a Dask worker's step runner): imports every job kind and loads every compiled kernel
(``planning.warm.warm_up``: kinematics, the motion planner, the sequencing search) from
numba's cache, so that each step's process starts with them instead of paying about a second
each."""

from __future__ import annotations

import logging

from planning.warm import warm_up

from . import catalog  # noqa: F401 - every kind registered

log = logging.getLogger(__name__)

try:
    warm_up()
except Exception:  # noqa: BLE001 - steps then load the kernels themselves
    log.exception("loading the compiled kernels failed; job steps will load them")
