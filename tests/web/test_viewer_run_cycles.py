"""The viewer's work-cycle buttons: **Run round**, **Run pallet** and **Run piles** where the
robot or rig shown has a stored plan (``web.cycles``), each submitting that whole job to the
service's job manager, following its progress and drawing its answer.

The viewers here get tiny stored plans (two holes, one box, two piles) so that the jobs,
run in this process as a worker runs them (``execute`` on the payload the manager stored),
take about a second. The shipped plans are checked against the sample files of
``examples/`` and the job kinds' own validation. In a real browser, pressing **Run piles**
runs the job in the service's pool and the plan's nodes appear.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from chromium_setup import served_viewer

from app.config import Settings
from app.jobs.catalog import KINDS
from app.jobs.kinds import execute
from app.main import create_app
from web.cycles import CYCLE_KINDS, StoredPlan, check_plans, stored_plans
from web.viewer import Viewer

ROOT = Path(__file__).resolve().parents[2]

#: Two holes the left and middle booms reach (rig frame, mm), one 1.2 m deep each.
TINY_HOLES = [{"id": "L1", "collar": [9000, 3000, 1500], "toe": [10200, 3000, 1500]},
              {"id": "M1", "collar": [9000, 0, 2500], "toe": [10200, 0, 2500]}]
PICK = [[1, 0, 0, 0], [0, 1, 0, -1100], [0, 0, 1, 825], [0, 0, 0, 1]]
TINY_PILES_CSV = "id,x,y,z,rake,azimuth\nA1,1600,0,0,,\nA2,0,1600,0,,"


def tiny_plans() -> dict[str, StoredPlan]:
    """A stored plan per work cycle, each planned in about a second."""
    return {
        "tunnel_jumbo": StoredPlan("round", "two holes", lambda: {
            "rig": "tunnel_jumbo", "holes": TINY_HOLES, "transfer_time_limit": 0.5}),
        "glt_palletizer": StoredPlan("pallet", "one box", lambda: {
            "robot": "glt_palletizer", "box": {"size": [400, 300, 250]}, "pick": PICK,
            "count": 1, "time_limit": 2.0}),
        "pile_driver": StoredPlan("piles", "two piles", lambda: {
            "robot": "pile_driver", "plan_csv": TINY_PILES_CSV,
            "setups": {"positions": [[0, 0, 0]]}, "drive_time": 30}),
    }


#: Nodes each cycle's drawer adds (docs/viewer.md, "Node names").
NODES = {
    "round": ["/plan/round/holes", "/plan/round/left/tool_path",
              "/plan/round/middle/tool_path"],
    "pallet": ["/plan/pallet/pallet/pallet", "/plan/pallet/loads/box0"],
    "piles": ["/plan/piles/piles", "/plan/piles/setups/0/carrier",
              "/plan/piles/setups/0/piles/0", "/plan/piles/setups/0/piles/1",
              "/plan/piles/setups/0/arm"],
}
ROBOT_OF = {"round": "tunnel_jumbo", "pallet": "glt_palletizer", "piles": "pile_driver"}


def _app(data_dir: Path, cycles=None):
    """An application whose jobs stay queued (no pool started) and a viewer over it."""
    app = create_app(Settings(no_viewer=True, data_dir=data_dir, workers=1))
    app.state.viewer = Viewer.start("127.0.0.1", 0, app.state, environment_map=False,
                                    cycles=cycles)
    return app


@pytest.fixture
def tiny(tmp_path):
    app = _app(tmp_path, tiny_plans())
    yield app
    app.state.viewer.stop()


def _visible(viewer: Viewer) -> list[str]:
    return [kind for kind, button in viewer.gui.run_cycle.items() if button.visible]


def _run_as_a_worker(app, job_id: str) -> None:
    """Run the running job in this process from the payload the manager stored, reporting
    progress, and finish it in the store, as the job pool does."""
    store = app.state.store
    job = store.get_job(job_id)
    assert job.status == "running"
    payload = store.job_payload(job_id)
    text = execute(job.kind, payload, lambda f, m: store.set_progress(job_id, f, m))
    store.finish_job(job_id, "succeeded", result_json=text)


# ---- the stored plans ----------------------------------------------------------------------
def test_the_shipped_plans_are_the_documented_examples():
    plans = stored_plans()
    assert {k: p.kind for k, p in plans.items()} == {
        "tunnel_jumbo": "round", "glt_palletizer": "pallet", "pile_driver": "piles"}
    assert [p.label for p in plans.values()] == ["Run round", "Run pallet", "Run piles"]
    # The round: the 22 holes of examples/drill_face.csv, in its order and rig frame.
    holes = plans["tunnel_jumbo"].params()["holes"]
    with open(ROOT / "examples" / "drill_face.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 22 and [h["id"] for h in holes] == [r["id"] for r in rows]
    for h, r in zip(holes, rows, strict=True):
        np.testing.assert_allclose(h["collar"], [float(r[f"collar_{a}"]) for a in "xyz"])
        np.testing.assert_allclose(h["toe"], [float(r[f"toe_{a}"]) for a in "xyz"])
        assert h["type"] == r["type"]
    # ... the holes of the IREDES plan examples/drill_round.xml (metres in the file).
    from planning.drilling.plans import read_iredes

    plan = read_iredes((ROOT / "examples" / "drill_round.xml").read_bytes().decode())
    assert plan.ids() == [h["id"] for h in holes]
    np.testing.assert_allclose([h.collar for h in plan.holes],
                               [h["collar"] for h in holes], atol=0.5)
    # Every shipped plan is a valid job of its kind (as POST /jobs checks it).
    pallet = KINDS["pallet"].load_params(plans["glt_palletizer"].params())
    assert (pallet.robot, pallet.count, pallet.pattern) == ("glt_palletizer", 4, "interlocked")
    piles = KINDS["piles"].load_params(plans["pile_driver"].params())
    assert [p for p in piles.pile_plan().ids] == ["A1", "A2", "A3", "F1"]
    KINDS["round"].load_params(plans["tunnel_jumbo"].params())


def test_only_stored_plans_of_the_work_cycle_kinds_are_taken():
    assert set(check_plans(tiny_plans())) == set(ROBOT_OF.values())
    with pytest.raises(ValueError, match=r"cycles\['pile_driver'\]\.kind"):
        check_plans({"pile_driver": StoredPlan("motion", "x", dict)})
    with pytest.raises(ValueError, match=r"cycles\['pile_driver'\]: expected a StoredPlan"):
        check_plans({"pile_driver": ("piles", dict)})


def test_a_viewer_refuses_stored_plans_of_another_kind(tmp_path):
    app = create_app(Settings(no_viewer=True, data_dir=tmp_path, workers=1))
    with pytest.raises(ValueError, match=r"cycles\['glt_palletizer'\]\.kind"):
        Viewer.start("127.0.0.1", 0, app.state, environment_map=False,
                     cycles={"glt_palletizer": StoredPlan("workspace", "x", dict)})


# ---- buttons -------------------------------------------------------------------------------
def test_the_shipped_service_shows_a_button_where_a_plan_is_stored(viewer):
    for key, kind in ROBOT_OF.items():
        viewer.select(kind)
        assert _visible(viewer) == [key]
        assert "Stored plan of" in viewer.gui.cycle_plan.content
    viewer.select("hyper_redundant_9dof")
    assert _visible(viewer) == []
    text = viewer.gui.cycle_plan.content
    assert "No stored plan" in text and all(k in text for k in ROBOT_OF.values())
    assert list(viewer.gui.run_cycle) == list(CYCLE_KINDS)


def test_a_viewer_without_stored_plans_shows_no_button(tmp_path):
    app = _app(tmp_path, {})
    try:
        v = app.state.viewer
        for key in ("pile_driver", "tunnel_jumbo", "glt_palletizer"):
            v.select(key)
            assert _visible(v) == [] and "No stored plans" in v.gui.cycle_plan.content
        assert v.run_cycle() is None and "has no stored plan" in v.gui.cycle.content
    finally:
        app.state.viewer.stop()


@pytest.mark.parametrize("kind", CYCLE_KINDS)
def test_a_press_submits_the_plans_job_and_draws_its_answer(tiny, kind):
    v: Viewer = tiny.state.viewer
    key = ROBOT_OF[kind]
    v.select(key)
    assert _visible(v) == [kind]
    job_id = v.run_cycle(kind)
    assert job_id is not None
    job = tiny.state.jobs.get(job_id)
    assert job.kind == kind and job.status == "queued"
    asked = tiny_plans()[key].params()
    checked = KINDS[kind].load_params(asked).model_dump(mode="json")
    for field in asked:   # the plan's params as the kind reads them
        assert job.params[field] == checked[field], field
    assert job_id in v.gui.cycle.content and "queued" in v.gui.cycle.content
    assert v.gui.cycle_progress.visible and v.gui.cycle_progress.value == 0.0
    # Busy: one work cycle at a time from the viewer, whichever button.
    assert v.run_cycle(kind) is None
    assert "still running" in v.gui.cycle.content and job_id in v.gui.cycle.content
    # Progress as the job reports it.
    assert tiny.state.store.claim_next_job().id == job_id
    tiny.state.store.set_progress(job_id, 0.4, "half way there")
    v._poll_cycle()
    assert v.gui.cycle_progress.value == pytest.approx(40.0)
    assert "running, 40 %" in v.gui.cycle.content and "half way there" in v.gui.cycle.content
    # Done: its plan is drawn, and another press starts again.
    _run_as_a_worker(tiny, job_id)
    assert v.plan_nodes == []
    v._poll_cycle()
    assert set(NODES[kind]) <= set(v.plan_nodes), v.plan_nodes
    assert v.current["job"] == job_id and v.current["kind"] == kind
    assert "Planned" in v.gui.cycle.content and not v.gui.cycle_progress.visible
    assert v.run_cycle(kind) is not None


def test_a_press_of_another_robots_button_is_refused(tiny):
    """A stale button (another tab switched the robot meanwhile) starts nothing."""
    v: Viewer = tiny.state.viewer
    v.select("pile_driver")
    assert v.run_cycle("pallet") is None
    assert "has no stored pallet plan" in v.gui.cycle.content
    v.select("hyper_redundant_9dof")
    assert v.run_cycle() is None and "has no stored plan" in v.gui.cycle.content
    assert tiny.state.store.list_jobs() == []


def test_refused_params_name_the_field(tmp_path):
    plans = {"pile_driver": StoredPlan("piles", "no set-ups", lambda: {
        "robot": "pile_driver", "plan_csv": TINY_PILES_CSV})}
    app = _app(tmp_path, plans)
    try:
        v = app.state.viewer
        v.select("pile_driver")
        assert v.run_cycle("piles") is None
        text = v.gui.cycle.content
        assert "Not started" in text and "`params.setups`" in text, text
        assert not v.gui.cycle_progress.visible
    finally:
        app.state.viewer.stop()


def test_a_plan_that_cannot_be_built_says_why(tmp_path):
    def broken() -> dict:
        raise OSError("the drill plan file is gone")

    app = _app(tmp_path, {"tunnel_jumbo": StoredPlan("round", "lost", broken)})
    try:
        v = app.state.viewer
        v.select("tunnel_jumbo")
        assert v.run_cycle("round") is None
        assert "cannot be built" in v.gui.cycle.content
        assert "the drill plan file is gone" in v.gui.cycle.content
    finally:
        app.state.viewer.stop()


def test_a_failed_job_says_why_and_draws_nothing(tiny):
    v: Viewer = tiny.state.viewer
    v.select("glt_palletizer")
    job_id = v.run_cycle("pallet")
    tiny.state.store.finish_job(job_id, "failed", error="time limit of 5 s exceeded")
    v._poll_cycle()
    text = v.gui.cycle.content
    assert "Not planned" in text and job_id in text and "time limit of 5 s exceeded" in text
    assert v.plan_nodes == [] and not v.gui.cycle_progress.visible
    assert v.run_cycle("pallet") is not None   # free again


# ---- in a real browser -----------------------------------------------------------------------
@pytest.fixture(scope="module")
def service(tmp_path_factory):
    """The API with its job pool started and a viewer holding the tiny plans."""
    with served_viewer(tmp_path_factory.mktemp("data"), cycles=tiny_plans()) as served:
        yield served


@pytest.mark.browser
@pytest.mark.slow
def test_run_piles_pressed_in_the_browser_draws_the_pile_plan(service):
    """Run piles: the job runs in the service's pool, and the pile plan's nodes appear in the
    browser; the other cycles' buttons are not offered for the pile driver."""
    sync_api = pytest.importorskip("playwright.sync_api", reason="Playwright is in the "
                                   "'test' extra: pip install -e '.[test]'")
    from chromium_setup import CHROMIUM, CHROMIUM_ARGS, TIMEOUT_MS

    api, client = service
    viewer: Viewer = api.state.viewer
    viewer.select("pile_driver")
    with sync_api.sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport={"width": 640, "height": 400})
            page.set_default_timeout(TIMEOUT_MS)
            page.goto(f"http://127.0.0.1:{viewer.port}")
            page.bring_to_front()  # viser's client connects only while its page has the focus
            page.get_by_text("Connected").wait_for()
            page.wait_for_function("() => window.__viserSceneTree !== undefined")
            button = page.get_by_role("button", name="Run piles", exact=True)
            button.wait_for()
            assert page.get_by_role("button", name="Run round").count() == 0
            assert page.get_by_role("button", name="Run pallet").count() == 0
            button.click()
            page.wait_for_function(
                "(names) => names.every(n => n in window.__viserSceneTree.getState())",
                arg=NODES["piles"], timeout=60_000)
            page.get_by_text("Planned").wait_for()
        finally:
            browser.close()
    job_id = viewer.current["job"]
    job = client.get(f"/jobs/{job_id}").json()
    assert job["kind"] == "piles" and job["status"] == "succeeded"
    result = client.get(f"/jobs/{job_id}/result").json()
    assert result["piles_reached"] == 2
