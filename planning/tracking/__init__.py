"""Tool-path tracking of a redundant arm by a PI resolved-rate law (paper 003).

* ``simulator``: the tasks (``LineTask``, ``EllipseTask``), the PI gains, the controllers
  and ``simulate``, vectorised over a population of gain candidates; eq. 24's fitness;
* ``tuning``: the gain tuners (``tune_gains``: HGSO, PSO, GA, ACO_R, GWO) and their search
  box (``GainBounds``);
* ``stats``: repeated tunings and the statistics of paper 003's Table 3.

The names below load their module on first use.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from kinematics.lazy import lazy_names

if TYPE_CHECKING:
    from .simulator import DEFAULT_GAINS as DEFAULT_GAINS
    from .simulator import MAX_STEPS as MAX_STEPS
    from .simulator import NO_PI_GAINS as NO_PI_GAINS
    from .simulator import PAPER_PI_GAINS as PAPER_PI_GAINS
    from .simulator import UNTUNED_PI_GAINS as UNTUNED_PI_GAINS
    from .simulator import Controller as Controller
    from .simulator import EllipseTask as EllipseTask
    from .simulator import LineTask as LineTask
    from .simulator import PIGains as PIGains
    from .simulator import Task as Task
    from .simulator import TrackingConfig as TrackingConfig
    from .simulator import TrackingResult as TrackingResult
    from .simulator import default_start as default_start
    from .simulator import desired_path as desired_path
    from .simulator import simulate as simulate
    from .simulator import tracking_fitness as tracking_fitness
    from .stats import LABELS as LABELS
    from .stats import SIGNIFICANCE as SIGNIFICANCE
    from .stats import TrackingTable as TrackingTable
    from .stats import TunerStats as TunerStats
    from .stats import format_table3 as format_table3
    from .stats import tracking_table as tracking_table
    from .tuning import TUNERS as TUNERS
    from .tuning import GainBounds as GainBounds
    from .tuning import TuningResult as TuningResult
    from .tuning import make_tuner as make_tuner
    from .tuning import tune_gains as tune_gains
    from .tuning import tuner_budget as tuner_budget

#: Public name -> the module it loads from on first use.
_LAZY = {
    "Controller": "simulator",
    "DEFAULT_GAINS": "simulator",
    "EllipseTask": "simulator",
    "LineTask": "simulator",
    "MAX_STEPS": "simulator",
    "NO_PI_GAINS": "simulator",
    "PAPER_PI_GAINS": "simulator",
    "PIGains": "simulator",
    "Task": "simulator",
    "TrackingConfig": "simulator",
    "TrackingResult": "simulator",
    "UNTUNED_PI_GAINS": "simulator",
    "default_start": "simulator",
    "desired_path": "simulator",
    "simulate": "simulator",
    "tracking_fitness": "simulator",
    "LABELS": "stats",
    "SIGNIFICANCE": "stats",
    "TrackingTable": "stats",
    "TunerStats": "stats",
    "format_table3": "stats",
    "tracking_table": "stats",
    "GainBounds": "tuning",
    "TUNERS": "tuning",
    "TuningResult": "tuning",
    "make_tuner": "tuning",
    "tune_gains": "tuning",
    "tuner_budget": "tuning",
}

__all__ = sorted(_LAZY)


__getattr__, __dir__ = lazy_names(__name__, _LAZY, globals())
