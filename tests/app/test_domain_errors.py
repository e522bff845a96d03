"""Domain checks deep in kinematics and planning answer 422 at the exact field they name
(``FieldError.loc``), with no route reading an error message: trajectories, the Cartesian
path, drilling IK, cylinders, robot models and job params."""

from __future__ import annotations

import copy
import math
import pickle

import pytest

from kinematics.cylinders import CylinderError
from kinematics.errors import FieldError
from kinematics.library import builtin_model
from kinematics.model import ModelError, RobotModel

GLT = builtin_model("glt_palletizer")
Q3 = [[0.0] * 6, [0.3] * 6, [0.6] * 6]


def first_error(r, status: int = 422) -> dict:
    assert r.status_code == status, r.text[:500]
    return r.json()["detail"][0]


# ---- the errors themselves -----------------------------------------------------------------
def test_model_and_cylinder_errors_are_field_errors_that_pickle_whole():
    with pytest.raises(ModelError) as err:
        RobotModel.from_dict(GLT.to_dict() | {"joints": [
            j | ({"lower": 5.0} if k == 2 else {}) for k, j in
            enumerate(GLT.to_dict()["joints"])]})
    model_error = err.value
    assert isinstance(model_error, FieldError)
    assert model_error.field == "joints[2].lower" and model_error.loc == ("joints", 2, "lower")
    cylinder_error = CylinderError(("lengths", "boom.main"), "outside the stroke")
    assert cylinder_error.loc == ("lengths", "boom.main")  # a dotted name stays whole
    assert str(cylinder_error) == "lengths.boom.main: outside the stroke"
    for error in (model_error, cylinder_error):
        again = pickle.loads(pickle.dumps(error))
        assert type(again) is type(error)
        assert (again.loc, again.field, again.message, str(again)) == \
            (error.loc, error.field, error.message, str(error))


# ---- trajectories --------------------------------------------------------------------------
def plan_body(**kw) -> dict:
    return {"method": "quintic", "waypoints": Q3, "durations": [1.0, 1.0], "dt": 0.01} | kw


@pytest.mark.parametrize("change, loc, words", [
    ({"durations": [1.0]}, ["body", "durations"], "one per segment (2 for 3 waypoints)"),
    ({"durations": [1.0] * 3, "method": "bspline5"}, ["body", "durations"],
     "one per segment"),
    ({"durations": [1.0] * 4, "method": "sextic", "waypoints": Q3 * 2}, ["body", "durations"],
     "one per segment"),
    ({"method": "sextic", "waypoints": Q3 * 2, "durations": [1.0] * 5,
      "accelerations": [[0.0] * 6] * 6}, ["body", "accelerations"], "only be given with"),
])
def test_trajectory_planning_names_the_field(ro_client, change, loc, words):
    err = first_error(ro_client.post("/trajectories", json=plan_body(**change)))
    assert err["loc"] == loc and words in err["msg"] and err["type"] == "value_error", err


@pytest.mark.slow
def test_a_field_error_raised_in_a_worker_process_names_its_field(ro_client):
    """Time scaling always runs in a compute worker: its FieldError crosses back whole."""
    err = first_error(ro_client.post("/trajectories", json=plan_body(time_scaling=True)))
    assert err["loc"] == ["body", "limits"] and "finite velocity" in err["msg"], err
    err = first_error(ro_client.post("/trajectories/plot", json=plan_body(durations=[1.0])))
    assert err["loc"] == ["body", "durations"], err


def test_cartesian_helpers_name_the_path_field(ro_client):
    robot = "glt_palletizer"
    same = [1000.0, 0.0, 900.0]
    err = first_error(ro_client.post("/trajectories/cartesian", json={
        "robot": robot, "path": {"kind": "line", "start": same, "end": same}}))
    assert err["loc"] == ["body", "path", "end"] and "distinct" in err["msg"], err
    err = first_error(ro_client.post("/trajectories/cartesian", json={
        "robot": robot, "points": 2,
        "path": {"kind": "ellipse", "center": same, "radii": [100, 50]}}))
    assert err["loc"] == ["body", "path", "points"] and "3 points" in err["msg"], err


# ---- drilling IK, cylinders, robot models ------------------------------------------------
def test_drill_ik_checks_name_their_field(ro_client, monkeypatch):
    import app.api.routes.kinematics as routes
    from kinematics.drilling import drill_ik

    arm = builtin_model("tunnel_drill_arm")
    for kw, loc in (({"d7": math.nan}, ("d7",)), ({"roll": math.inf}, ("roll",))):
        with pytest.raises(FieldError) as err:
            drill_ik(arm, [9000.0, 0.0, 1000.0], **kw)
        assert err.value.loc == loc
    with pytest.raises(FieldError) as err:
        drill_ik(arm, [[9000.0, 0.0, 1000.0], [9000.0, math.nan, 0.0]])
    assert err.value.loc == ("holes", 1)
    # The route hands drill_ik's FieldError on as it is: a feed value the IK refuses.
    monkeypatch.setattr(routes, "drill_ik", lambda model, holes, d7, roll: drill_ik(
        model, holes, d7=math.nan, roll=roll))
    err = first_error(ro_client.post("/robots/tunnel_drill_arm/drill-ik",
                                  json={"holes": [[9000.0, 0.0, 1000.0]]}))
    assert err["loc"] == ["body", "d7"] and "finite" in err["msg"], err


def test_cylinder_names_with_dots_are_named_whole(client):
    data = copy.deepcopy(builtin_model("pile_driver").to_dict())
    data["id"] = "dotted_pile_driver"
    data["cylinders"][0]["name"] = "boom.main"
    assert client.post("/robots", json=data).status_code == 201
    err = first_error(client.post("/robots/dotted_pile_driver/cylinders/inverse",
                                  json={"lengths": {"boom.main": 5000.0}}))
    assert err["loc"] == ["body", "lengths", "boom.main"] and "stroke" in err["msg"], err


def test_robot_model_errors_name_the_field(client):
    data = copy.deepcopy(GLT.to_dict()) | {"id": "bad_glt"}
    data["joints"][2]["lower"] = data["joints"][2]["upper"] + 1
    err = first_error(client.post("/robots", json=data))
    assert err["loc"] == ["body", "joints", 2, "lower"] and "below upper" in err["msg"], err
    data = copy.deepcopy(builtin_model("pile_driver").to_dict()) | {"id": "bad_pile"}
    data["cylinders"][1]["r1"] = -5
    err = first_error(client.post("/robots", json=data))
    assert err["loc"] == ["body", "cylinders", 1, "r1"], err


# ---- job params ----------------------------------------------------------------------------
SCENE = {"bounds": [[0, 0, 0], [100, 100, 100]],
         "obstacles": [{"center": [30, 30, 30], "radius": 12}]}
SIDES = {"left": [[9000, 3000, 1000], [9000, 3500, 2500]],
         "right": [[9000, -3000, 1000], [9000, -3500, 2500]]}


def submit(client, kind: str, params: dict):
    return client.post("/jobs", json={"kind": kind, "params": params})


@pytest.mark.parametrize("kind, params, loc, words", [
    # An obstacle grown over the start: planning.paths.scene names the start.
    ("path", {"scene": SCENE | {"obstacles": [{"center": [30, 30, 30], "radius": 60}]},
              "start": [1, 1, 1], "goal": [100, 100, 100]},
     ["start"], "start is inside obstacles[0]"),
    ("path", {"scene": SCENE | {"safety_margin": 3}, "start": [1, 1, 1],
              "goal": [30, 30, 44]}, ["goal"], "within safety_margin"),
    # Sequencing parameters within their caps but wrong together: the sequencer names them.
    ("sequence", {"holes": [[0, 0, 0], [1000, 0, 0], [0, 1000, 0]], "algorithm": "iga",
                  "params": {"population": 5}}, ["params", "population"], "even number"),
    ("sequence", {"holes": [[0, 0, 0], [1000, 0, 0], [0, 1000, 0]], "algorithm": "aga",
                  "params": {"crossover": 0.5, "crossover_min": 0.6}},
     ["params", "crossover_min"], "must not exceed crossover"),
    ("sequence", {"holes": [[0, 0, 0], [1000, 0, 0], [0, 0, 0.5]]}, ["holes", 2],
     "holes[2]: duplicate of holes[0]"),
    ("multiarm", {"holes": {"left": [[9000, -7000, 1000]], "right": [[9000, -3000, 1000]]}},
     ["holes", "left", 0], "out of reach of the left arm"),
])
def test_job_params_checked_by_planning_name_the_field(client, kind, params, loc, words):
    err = first_error(submit(client, kind, params))
    assert err["loc"] == ["body", "params", *loc], err
    assert words in err["msg"], err


def test_a_field_error_naming_another_field_keeps_pydantics_location(client):
    """The sequencers call their parameters ``params``; under multiarm's
    ``sequencer_params`` the location pydantic gives stands (never a field that the request
    does not have), and an obstacle's own check stays at the obstacle."""
    err = first_error(submit(client, "multiarm", {
        "holes": SIDES, "sequencer": "iga", "sequencer_params": {"population": 5}}))
    assert err["loc"] == ["body", "params", "sequencer_params"], err
    assert "even number" in err["msg"], err
    scene = SCENE | {"obstacles": [{"type": "box", "lower": [1, 2, 3]}]}
    err = first_error(submit(client, "path", {"scene": scene, "start": [1, 1, 1],
                                              "goal": [100, 100, 100]}))
    assert err["loc"] == ["body", "params", "scene", "obstacles", 0], err
    assert "upper is required for a box" in err["msg"] and "obstacle." not in err["msg"], err
