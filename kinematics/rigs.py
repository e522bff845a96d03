"""Rigs: several arms on one carrier, each a ``RobotModel`` placed by its mount.

A rig description (JSON, in ``kinematics/robots/<id>.json`` for the built-ins) names each
arm, the model it is an instance of and its mount: the pose ``T_rig_mount (4, 4)`` in the
rig frame (mm) of the arm's own world frame, the frame its model's ``base`` is given in. The
rig's arms are full ``RobotModel`` values with the mount folded into their base
(``base = T_rig_mount @ arm.base``), so ``fk``, IK and every other function work on them
unchanged and report poses in the rig frame, their world frame:
``T_rig_tool = mount · base · chain(q) · tool`` (docs/conventions.md).

Arm ids are ``"<rig id>-<arm name>"`` (the model id check allows letters, digits, '_' and
'-', so not ``"<rig>.<arm>"``).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cache
from importlib import resources
from typing import Any

import numpy as np

from .library import builtin_model
from .model import ModelError, RobotModel, pose_field

__all__ = ["BUILTIN_RIG_IDS", "Rig", "builtin_rig"]

BUILTIN_RIG_IDS = ("tunnel_jumbo",)

_RIG_KEYS = {"id", "name", "arms"}
_ARM_KEYS = {"name", "model", "base"}


@dataclass(frozen=True, eq=False)
class Rig:
    """Arms on one carrier. ``arms`` maps an arm name to its model (mount applied, poses in
    the rig frame); ``mounts`` maps it to ``T_rig_mount (4, 4)`` and ``arm_models`` to the id
    of the model it instantiates. ``extras`` keeps the description's other fields (source,
    notes)."""

    id: str
    name: str
    arms: dict[str, RobotModel]
    mounts: dict[str, np.ndarray] = field(default_factory=dict)
    arm_models: dict[str, str] = field(default_factory=dict)
    extras: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "id": self.id,
            "name": self.name,
            "arms": [
                {"name": n, "model": self.arm_models[n], "base": self.mounts[n].tolist()}
                for n in self.arms
            ],
        }
        out.update(self.extras)
        return out

    @classmethod
    def from_dict(
        cls, data: dict[str, Any], models: Callable[[str], RobotModel] = builtin_model
    ) -> Rig:
        """Build and validate a rig; ``models`` resolves an arm's model id (default: the
        built-ins). Raises ``ModelError`` (a ``ValueError``) naming the field at fault."""
        if not isinstance(data, dict):
            raise ModelError("rig", "must be a JSON object")
        rig_id = data.get("id")
        if not isinstance(rig_id, str) or not rig_id:
            raise ModelError("id", "must be a non-empty string")
        if not all(c.isalnum() or c in "_-" for c in rig_id):
            raise ModelError("id", "use letters, digits, '_' or '-'")
        name = data.get("name", rig_id)
        if not isinstance(name, str):
            raise ModelError("name", "must be a string")
        arms_data = data.get("arms")
        if not isinstance(arms_data, list) or not arms_data:
            raise ModelError("arms", "must be a non-empty list")
        arms: dict[str, RobotModel] = {}
        mounts: dict[str, np.ndarray] = {}
        arm_models: dict[str, str] = {}
        for k, arm in enumerate(arms_data):
            path = f"arms[{k}]"
            if not isinstance(arm, dict):
                raise ModelError(path, "must be a JSON object")
            unknown = set(arm) - _ARM_KEYS
            if unknown:
                raise ModelError(f"{path}.{sorted(unknown)[0]}", "unknown arm field")
            arm_name = arm.get("name")
            if not isinstance(arm_name, str) or not arm_name:
                raise ModelError(f"{path}.name", "must be a non-empty string")
            if not all(c.isalnum() or c in "_-" for c in arm_name):
                raise ModelError(f"{path}.name", "use letters, digits, '_' or '-'")
            if arm_name in arms:
                raise ModelError(f"{path}.name", f"arm name {arm_name!r} is used twice")
            model_id = arm.get("model")
            if not isinstance(model_id, str):
                raise ModelError(f"{path}.model", "must be a model id")
            try:
                model = models(model_id)
            except KeyError as exc:
                raise ModelError(f"{path}.model", f"unknown model {model_id!r}") from exc
            mount = pose_field(arm.get("base"), f"{path}.base")
            data_arm = model.to_dict()
            data_arm["id"] = f"{rig_id}-{arm_name}"
            data_arm["name"] = f"{model.name}: {arm_name} arm of {name}"
            data_arm["base"] = (mount @ model.base).tolist()
            arms[arm_name] = RobotModel.from_dict(data_arm)
            mounts[arm_name] = mount
            arm_models[arm_name] = model_id
        extras = {k: v for k, v in data.items() if k not in _RIG_KEYS}
        return cls(rig_id, name, arms, mounts, arm_models, extras)


@cache
def builtin_rig(rig_id: str) -> Rig:
    """The built-in rig ``rig_id`` (from ``kinematics/robots/<id>.json``); ``KeyError`` if
    there is none."""
    if rig_id not in BUILTIN_RIG_IDS:
        raise KeyError(rig_id)
    text = resources.files(__package__).joinpath("robots", f"{rig_id}.json").read_text()
    return Rig.from_dict(json.loads(text))
