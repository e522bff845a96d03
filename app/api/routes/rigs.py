"""Rigs: several arms on one carrier (the three-boom tunnel jumbo)."""

from __future__ import annotations

from typing import Any

from fastapi import APIRouter

from ...responses import FastJSONRoute
from ..deps import RegistryDep
from ..errors import not_found

router = APIRouter(prefix="/rigs", tags=["robots"], route_class=FastJSONRoute)


def _summary(rig) -> dict[str, Any]:
    return {
        "id": rig.id,
        "name": rig.name,
        "arms": [
            {"name": name, "robot": model.id, "model": rig.arm_models[name],
             "base": rig.mounts[name].tolist()}
            for name, model in rig.arms.items()
        ],
    }


@router.get("")
def list_rigs(registry: RegistryDep) -> list[dict[str, Any]]:
    """Every rig: its arms, each a robot id usable on every /robots endpoint, and mounts."""
    return [_summary(rig) for rig in registry.rigs.values()]


@router.get("/{rig_id}")
def get_rig(rig_id: str, registry: RegistryDep) -> dict[str, Any]:
    """A rig's description (as stored) with the robot id of each arm."""
    rig = registry.rigs.get(rig_id)
    if rig is None:
        raise not_found("rig", rig_id)
    return rig.to_dict() | {"robots": {name: m.id for name, m in rig.arms.items()}}
