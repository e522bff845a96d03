"""Imported once by the processes that job steps start from (the local backend's forkserver,
a Dask worker's step runner): imports every job kind and loads the compiled kernels of
``kinematics.fast`` and ``planning.motion`` from numba's cache, so that each step's process
starts with them instead of paying about a second each."""

from __future__ import annotations

import logging

from kinematics.fast import warm_up as _warm_kinematics
from planning.motion import warm_up as _warm_motion

from . import catalog  # noqa: F401 - every kind registered

log = logging.getLogger(__name__)

try:
    _warm_kinematics()
    _warm_motion()
except Exception:  # noqa: BLE001 - steps then load the kernels themselves
    log.exception("loading the compiled kernels failed; job steps will load them")
