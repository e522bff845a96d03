"""The status family (``kinematics.status``): every status enum of the code base extends
``Status``, draws its values from one vocabulary and keeps the strings the API emits."""

from __future__ import annotations

import ast
import enum
import importlib
import pkgutil
from pathlib import Path

import pytest

from kinematics.status import OK, STATUS_VALUES, Status

ROOT = Path(__file__).resolve().parents[2]

#: The strings each status enum emits (results' ``status``), written out by hand: a change
#: here is a change of the API.
EMITTED = {
    "kinematics.ik.result.IKStatus": ["ok", "unreachable", "out_of_limits", "not_converged"],
    "planning.status.PlanStatus": ["ok", "no_path", "budget_spent", "collision", "unreachable",
                                   "out_of_limits", "invalid_input"],
    "planning.motion.planner.MotionStatus": ["ok", "start_in_collision", "goal_in_collision",
                                             "goal_unreachable", "out_of_limits", "no_path",
                                             "timeout"],
    "planning.trajectories.topp.ToppStatus": ["ok", "infeasible", "unbounded"],
    "planning.motion.cartesian.CartesianStatus": ["ok", "unreachable", "out_of_limits",
                                                  "discontinuous", "collision", "timeout"],
    "planning.motion.constraints.ConstrainedStatus": [
        "ok", "out_of_limits", "start_violates_constraint", "goal_violates_constraint",
        "start_in_collision", "goal_in_collision", "timeout"],
}


def _modules(package: str):
    """Every module of ``package`` (imported)."""
    pkg = importlib.import_module(package)
    yield pkg
    for info in pkgutil.walk_packages(pkg.__path__, prefix=package + "."):
        yield importlib.import_module(info.name)


def _enums() -> dict[str, type[enum.Enum]]:
    """Every enum class defined in ``kinematics`` and ``planning``, by qualified name."""
    found = {}
    for package in ("kinematics", "planning"):
        for mod in _modules(package):
            for obj in vars(mod).values():
                if (isinstance(obj, type) and issubclass(obj, enum.Enum)
                        and obj.__module__ == mod.__name__):
                    found[f"{obj.__module__}.{obj.__qualname__}"] = obj
    return found


@pytest.fixture(scope="module")
def enums():
    return _enums()


def _is_status(cls: type[enum.Enum]) -> bool:
    """A status enum: named so, or saying how a run ended (it has an ``ok`` member)."""
    return cls.__name__.endswith("Status") or any(m.value == OK for m in cls)


def test_every_status_enum_extends_the_base(enums):
    statuses = {name: cls for name, cls in enums.items() if _is_status(cls)}
    # The walk must find the known ones (an empty walk would pass anything).
    assert set(EMITTED) <= set(statuses)
    outside = sorted(name for name, cls in statuses.items() if not issubclass(cls, Status))
    assert outside == []


def test_status_values_are_the_emitted_strings(enums):
    for name, values in EMITTED.items():
        assert [m.value for m in enums[name]] == values, name


def test_every_value_comes_from_the_vocabulary(enums):
    for name, cls in enums.items():
        if issubclass(cls, Status):
            unknown = [m.value for m in cls if m.value not in STATUS_VALUES]
            assert unknown == [], name


def test_a_shared_value_is_one_outcome(enums):
    from kinematics.ik import IKStatus
    from planning.motion import MotionStatus
    from planning.status import PlanStatus
    from planning.trajectories.topp import ToppStatus

    assert IKStatus.OK == PlanStatus.OK == MotionStatus.OK == ToppStatus.OK == "ok"
    assert PlanStatus.NO_PATH == MotionStatus.NO_PATH
    assert IKStatus.OUT_OF_LIMITS.meaning == MotionStatus.OUT_OF_LIMITS.meaning
    for cls in (IKStatus, PlanStatus, MotionStatus, ToppStatus):
        assert [m.succeeded for m in cls] == [m.value == "ok" for m in cls]
        assert isinstance(cls.OK, str) and isinstance(cls.OK, Status)


@pytest.mark.slow
def test_the_service_and_viewer_define_no_status_enum_of_their_own():
    """``app`` and ``web`` are read, not imported (the viewer pulls in its GUI stack): any
    class there named ``...Status`` must not be a fresh enum."""
    enum_bases = {"Enum", "StrEnum", "IntEnum", "Flag", "IntFlag"}
    found = []
    for package in ("app", "web"):
        for path in sorted((ROOT / package).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, ast.ClassDef) and node.name.endswith("Status"):
                    bases = {getattr(b, "id", getattr(b, "attr", "")) for b in node.bases}
                    if bases & enum_bases:
                        found.append(f"{path.relative_to(ROOT)}:{node.name}")
    assert found == []
