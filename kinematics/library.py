"""The built-in robot models, stored as JSON data files in ``kinematics/robots/``."""

from __future__ import annotations

import json
from functools import cache
from importlib import resources

from .model import RobotModel

__all__ = ["BUILTIN_IDS", "builtin_model", "builtin_models"]

BUILTIN_IDS = ("pile_driver", "glt_palletizer", "hyper_redundant_9dof", "tunnel_drill_arm")


@cache
def builtin_model(robot_id: str) -> RobotModel:
    """The built-in model ``robot_id``; ``KeyError`` if there is none."""
    if robot_id not in BUILTIN_IDS:
        raise KeyError(robot_id)
    text = resources.files(__package__).joinpath("robots", f"{robot_id}.json").read_text()
    return RobotModel.from_dict(json.loads(text))


def builtin_models() -> dict[str, RobotModel]:
    """Every built-in model by id, in a stable order."""
    return {rid: builtin_model(rid) for rid in BUILTIN_IDS}
