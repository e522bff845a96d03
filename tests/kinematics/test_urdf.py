"""URDF export: an independent URDF reader (yourdfpy) reproduces our FK from the XML alone."""

from __future__ import annotations

import io
import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from kinematics.fk import fk, fk_frames
from kinematics.library import BUILTIN_IDS, builtin_model
from kinematics.model import RobotModel
from kinematics.transforms import rot_x, rot_y, rot_z
from kinematics.urdf import MM_PER_M, UNLIMITED, rotation_to_rpy, to_urdf

yourdfpy = pytest.importorskip("yourdfpy")

MDH_PRISMATIC = RobotModel.from_dict({
    "id": "mdh_prismatic",
    "convention": "mdh",
    "joints": [
        {"name": "swing", "a": 0, "alpha": 0, "d": 300, "offset": 0.1, "lower": -3,
         "upper": 3, "velocity": 1.5},
        {"name": "slide", "type": "prismatic", "a": 150, "alpha": -np.pi / 2, "theta": 0.3,
         "offset": 40, "lower": 0, "upper": 800, "velocity": 250},
        # alpha and offset a hair off pi/2: the origin's rotation is near gimbal lock.
        {"name": "pitch", "a": 90, "alpha": 1.5707963, "d": 20, "offset": 1.5707963,
         "lower": -2, "upper": 2},
        {"name": "roll", "a": 0, "alpha": np.pi / 2, "d": 120, "offset": np.pi,
         "lower": -3, "upper": 3},
    ],
    "base": [[0, -1, 0, 100], [1, 0, 0, -50], [0, 0, 1, 20], [0, 0, 0, 1]],
    "tool": [[1, 0, 0, 10], [0, 0, -1, 0], [0, 1, 0, 60], [0, 0, 0, 1]],
})
SDH_PRISMATIC = RobotModel.from_dict({
    "id": "sdh_prismatic",
    "convention": "sdh",
    "joints": [
        {"a": 50, "alpha": -np.pi / 2, "d": 300, "offset": -0.7, "lower": -3, "upper": 3},
        {"type": "prismatic", "a": 30, "alpha": np.pi / 2, "theta": 0.3, "offset": 25,
         "lower": 0, "upper": 500},
        {"a": 120, "alpha": 0.4, "d": 10, "offset": 0.2, "lower": -2, "upper": 2},
        {"a": 0, "alpha": np.pi / 2, "d": 80, "lower": -2, "upper": 2},
    ],
    "base": [[1, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 450], [0, 0, 0, 1]],
    "tool": [[1, 0, 0, 10], [0, 1, 0, 0], [0, 0, 1, 60], [0, 0, 0, 1]],
})
POE_PRISMATIC = RobotModel.from_dict({
    "id": "poe_prismatic",
    "convention": "poe",
    "joints": [
        {"axis": [0, 0, 1], "point": [10, 0, 0], "offset": 0.25, "lower": -3, "upper": 3},
        {"axis": [0, 1, 0], "point": [0, 0, 400], "lower": -2, "upper": 2},
        {"type": "prismatic", "axis": [0.6, 0, 0.8], "offset": 15, "lower": 0, "upper": 300},
        {"axis": [1, 0, 0], "point": [500, 0, 400], "offset": -0.5, "lower": -3, "upper": 3},
    ],
    "home": [[0, 0, 1, 600], [0, 1, 0, 0], [-1, 0, 0, 400], [0, 0, 0, 1]],
    "tool": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 50], [0, 0, 0, 1]],
    "base": [[1, 0, 0, 5], [0, 1, 0, 6], [0, 0, 1, 7], [0, 0, 0, 1]],
})
MODELS = [builtin_model(rid) for rid in BUILTIN_IDS] + [MDH_PRISMATIC, SDH_PRISMATIC,
                                                        POE_PRISMATIC]
IDS = [m.id for m in MODELS]


def load(model: RobotModel):
    return yourdfpy.URDF.load(io.StringIO(to_urdf(model)), load_meshes=False)


def urdf_cfg(model: RobotModel, q: np.ndarray) -> dict[str, float]:
    """Our ``q`` (rad, mm) as URDF joint values (rad, m)."""
    scale = np.where(model.revolute, 1.0, 1.0 / MM_PER_M)
    return {j.name: float(v) for j, v in zip(model.joints, q * scale)}


@pytest.mark.parametrize("model", MODELS, ids=IDS)
def test_yourdfpy_fk_equals_ours(model):
    urdf = load(model)
    assert urdf.actuated_joint_names == [j.name for j in model.joints]
    qs = np.random.default_rng(7).uniform(model.lower, model.upper, (20, model.dof))
    for q, T_ours in zip(qs, fk(model, qs)):
        urdf.update_cfg(urdf_cfg(model, q))
        T_urdf = urdf.get_transform("tool", "base_link")
        np.testing.assert_allclose(T_urdf[:3, 3] * MM_PER_M, T_ours[:3, 3], rtol=0, atol=1e-6)
        np.testing.assert_allclose(T_urdf[:3, :3], T_ours[:3, :3], rtol=0, atol=1e-9)


@pytest.mark.parametrize("model", [m for m in MODELS if m.convention != "sdh"],
                         ids=[m.id for m in MODELS if m.convention != "sdh"])
def test_links_are_our_frames(model):
    """For modified D-H and POE models ``link_i`` is ``fk_frames`` entry i."""
    urdf = load(model)
    q = model.mid_configuration() + 0.1 * (model.upper - model.lower)
    urdf.update_cfg(urdf_cfg(model, q))
    frames = fk_frames(model, q)
    for i in range(model.dof):
        T_urdf = urdf.get_transform(f"link_{i}", "base_link")
        np.testing.assert_allclose(T_urdf[:3, 3] * MM_PER_M, frames[i, :3, 3], atol=1e-6)
        np.testing.assert_allclose(T_urdf[:3, :3], frames[i, :3, :3], atol=1e-9)


def test_limits_units_and_tree():
    root = ET.fromstring(to_urdf(MDH_PRISMATIC))
    assert root.tag == "robot" and root.get("name") == "mdh_prismatic"
    joints = {j.get("name"): j for j in root.iter("joint")}
    assert list(joints) == ["base", "swing", "slide", "pitch", "roll", "tool"]
    assert joints["base"].find("parent").get("link") == "base_link"
    assert joints["tool"].find("child").get("link") == "tool"
    assert joints["base"].get("type") == joints["tool"].get("type") == "fixed"
    slide = joints["slide"]
    assert slide.get("type") == "prismatic"
    limit = {k: float(v) for k, v in slide.find("limit").attrib.items()}
    assert limit == {"lower": 0.0, "upper": 0.8, "velocity": 0.25, "effort": UNLIMITED}
    swing = {k: float(v) for k, v in joints["swing"].find("limit").attrib.items()}
    assert swing == {"lower": -3.0, "upper": 3.0, "velocity": 1.5, "effort": UNLIMITED}
    assert float(joints["roll"].find("limit").get("velocity")) == UNLIMITED
    base_xyz = [float(v) for v in joints["base"].find("origin").get("xyz").split()]
    assert base_xyz == [0.1, -0.05, 0.02]


def test_fixed_joint_names_avoid_model_joint_names():
    data = MDH_PRISMATIC.to_dict()
    data["joints"][0]["name"] = "base"
    data["joints"][1]["name"] = "tool"
    model = RobotModel.from_dict(data)
    names = [j.get("name") for j in ET.fromstring(to_urdf(model)).iter("joint")]
    assert names == ["base_joint", "base", "tool", "pitch", "roll", "tool_joint"]
    urdf = load(model)
    q = model.mid_configuration()
    urdf.update_cfg(urdf_cfg(model, q))
    np.testing.assert_allclose(urdf.get_transform("tool", "base_link")[:3, :3],
                               fk(model, q)[:3, :3], atol=1e-9)


def _rpy_matrix(rpy) -> np.ndarray:
    return (rot_z(rpy[2]) @ rot_y(rpy[1]) @ rot_x(rpy[0]))[:3, :3]


@pytest.mark.parametrize("pitch", [math.pi / 2, -math.pi / 2, 1.5707963, -1.5707963,
                                   math.pi / 2 - 1e-12, 0.0, 1.0, -2.5])
def test_rotation_to_rpy_round_trips_near_gimbal_lock(pitch):
    """With round-off in every entry (as after a chain of products), the textbook formulas
    (roll from R21, R22; yaw from R10, R00) lose ~1e-8 at pitch = 1.5707963; ours must not."""
    rng = np.random.default_rng(3)
    for roll, yaw in rng.uniform(-math.pi, math.pi, (100, 2)):
        A = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        R = A @ (A.T @ _rpy_matrix([roll, pitch, yaw]))
        np.testing.assert_allclose(_rpy_matrix(rotation_to_rpy(R)), R, rtol=0, atol=1e-14)


def test_rotation_to_rpy_of_random_rotations():
    rng = np.random.default_rng(5)
    for _ in range(200):
        R = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        R *= np.sign(np.linalg.det(R))
        rpy = rotation_to_rpy(R)
        assert -math.pi <= rpy[0] <= math.pi and abs(rpy[1]) <= math.pi / 2
        np.testing.assert_allclose(_rpy_matrix(rpy), R, rtol=0, atol=1e-14)
