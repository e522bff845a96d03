"""tools/api_snapshot.py, the before/after comparison of the API's answers: the same build
records the same answers, a changed answer is reported with its request and place, and the
normalisation masks, rounds and relabels what it says it does."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import pytest

TOOL = Path(__file__).resolve().parents[1] / "tools" / "api_snapshot.py"


@pytest.fixture(scope="module")
def snap():
    """The tool as a module (tools/ is not a package; its dataclass needs it in sys.modules)."""
    spec = importlib.util.spec_from_file_location("api_snapshot", TOOL)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    yield module
    del sys.modules[spec.name]


#: A few cases of each answer type: JSON (with masked store sizes), 4xx, 405, 415, .npy.
ONLY = ["health", "fk", "ik.not_rigid", "trajectories.quintic", "rigs"]


@pytest.fixture(scope="module")
def recorded(snap, tmp_path_factory) -> tuple[Path, Path]:
    """The same cases recorded twice, each time by a freshly built app."""
    out = tmp_path_factory.mktemp("snap")
    a, b = out / "a.json", out / "b.json"
    for path in (a, b):
        assert snap.record(path, ONLY, verbose=False, timeout_s=60) == 0
    return a, b


@pytest.mark.slow
def test_the_same_build_records_the_same_answers(snap, recorded, capsys):
    a, b = recorded
    records = json.loads(a.read_text())["records"]
    names = [r["name"] for r in records]
    assert "fk.npy" in names and "rigs.get.unknown" in names
    assert all(any(n.startswith(o) for o in ONLY) for n in names)
    by_name = {r["name"]: r for r in records}
    assert by_name["health"]["answer"]["store"]["bytes"] == "<masked>"
    assert by_name["fk.npy"]["answer"]["npy"]["shape"] == [2, 4, 4]
    assert by_name["ik.not_rigid"]["status"] == 422
    # the README's FK of the palletizer (x of the tool: 783.709 mm), to 9 significant digits
    x = by_name["fk"]["answer"]["poses"][0][0][3]
    assert abs(x - 783.709) < 1e-3 and x == float(f"{x:.9g}")
    capsys.readouterr()
    assert snap.compare(a, b, limit=0) == 0
    assert "0 difference(s)" in capsys.readouterr().out


def test_compare_reports_each_change_with_its_request_and_place(snap, recorded, tmp_path,
                                                                   capsys):
    a, _ = recorded
    doctored = json.loads(a.read_text())
    by_name = {r["name"]: r for r in doctored["records"]}
    x = by_name["fk"]["answer"]["poses"][0][0][3]
    by_name["fk"]["answer"]["poses"][0][0][3] = x + 0.5
    by_name["ik.not_rigid"]["status"] = 400
    del by_name["rigs.get"]["answer"]["name"]
    doctored["records"] = [r for r in doctored["records"] if r["name"] != "fk.wrong_length"]
    b = tmp_path / "doctored.json"
    b.write_text(json.dumps(doctored))
    capsys.readouterr()
    assert snap.compare(a, b, limit=0) == 1
    out = capsys.readouterr().out
    assert "== fk: POST /robots/glt_palletizer/fk" in out
    assert f"answer.poses.0.0.3: a={x}  b={x + 0.5}" in out
    assert "status: a=422  b=400" in out
    assert "answer.name: a=Three-boom tunnel drilling jumbo (paper 002)  b=<absent>" in out
    assert "== fk.wrong_length: only in a" in out
    assert "4 difference(s)" in out


def test_normalise_masks_rounds_and_relabels(snap):
    ids = {"0123456789abcdef": "{job:echo}"}
    raw = {"id": "0123456789abcdef", "created": "2026-01-01T00:00:00Z", "finished": None,
           "jobs": [{"started": "2026-01-01T00:00:01Z", "x": 1}],
           "error": "job 0123456789abcdef is failed", "stats": {"runtime_s": 0.5},
           "v": [0.1234567891234, -0.0, 2, 1e-20 / 3, True]}
    assert snap.normalise(raw, ids) == {
        "id": "{job:echo}", "created": "<masked>", "finished": None,
        "jobs": [{"started": "<masked>", "x": 1}],
        "error": "job {job:echo} is failed", "stats": {"runtime_s": "<masked>"},
        "v": [0.123456789, 0.0, 2, 3.33333333e-21, True]}


def test_differences_compare_numbers_by_value_and_other_types_strictly(snap):
    assert snap.differences({"a": [1, 2.0]}, {"a": [1.0, 2]}) == []
    assert snap.differences({"a": True}, {"a": 1}) == [("a", True, 1)]
    assert snap.differences([1, 2], [1]) == [(".<length>", 2, 1)]
    assert snap.differences({"a": {"b": "x"}}, {"a": {"b": "y"}}) == [("a.b", "x", "y")]


def test_a_reordered_list_is_one_difference_then_each_item_against_its_namesake(snap):
    a = [{"kind": "echo", "v": 1}, {"kind": "sleep", "v": 2}]
    b = [{"kind": "sleep", "v": 2}, {"kind": "echo", "v": 3}]
    assert snap.differences({"k": a}, {"k": b}) == [
        ("k.<order of kind>", ["echo", "sleep"], ["sleep", "echo"]), ("k.echo.v", 1, 3)]
    # other items, or an item named twice: index by index
    assert len(snap.differences(a, b[:1])) == 3


def test_every_job_kind_has_a_payload_and_every_case_name_is_unique(snap):
    from app.jobs.catalog import KINDS

    assert set(snap.JOB_PAYLOADS) == set(KINDS)
    names = [c.name for c in snap.cases()]
    assert len(names) == len(set(names))


def test_coverage_names_operations_without_a_valid_or_an_invalid_request(snap):
    document = {"paths": {"/jobs": {"get": {}, "post": {}}, "/jobs/kinds": {"get": {}},
                          "/jobs/{job_id}": {"get": {}}}}
    case = snap.Case
    sent = [(case("a", "GET", "/jobs?limit=2"), 200), (case("b", "PUT", "/jobs"), 405),
            (case("c", "POST", "/jobs", json={"kind": "echo"}), 202),
            (case("d", "GET", "/jobs/kinds"), 200),
            (case("e", "GET", "/jobs/{job:echo}"), 200),
            (case("f", "GET", "/jobs/0000000000000000"), 404)]
    assert snap._coverage(document, ["echo", "sleep"], sent) == {
        "valid": [], "invalid": ["GET /jobs/kinds"], "kinds": ["sleep"]}
