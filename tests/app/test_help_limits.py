"""What ``--help`` says about the limits is what the service does: a full job queue answers
429, and the body cap it states is the largest one a route enforces. ``make run`` says where
the API, its docs and the viewer are."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _help(capsys, main, argv) -> str:
    with pytest.raises(SystemExit) as done:
        main(argv)
    assert done.value.code == 0
    return " ".join(capsys.readouterr().out.split())  # argparse wraps lines


@pytest.fixture(params=["app", "kinoplan"])
def help_text(request, capsys) -> str:
    if request.param == "app":
        from app.__main__ import parse_args

        return _help(capsys, parse_args, ["--help"])
    from kinoplan.__main__ import main

    return _help(capsys, main, ["--help"])


def _flag_help(text: str, flag: str) -> str:
    """The help of one flag: from its name (in the options list, after the usage line) to
    the next flag's."""
    start = text.rindex(f"{flag} {flag.lstrip('-').upper().replace('-', '_')}")
    nxt = re.search(r" --[a-z]", text[start + len(flag) + 1:])
    return text[start:start + len(flag) + 1 + (nxt.start() if nxt else len(text))]


def test_help_says_a_full_queue_answers_429(help_text, tmp_path):
    part = _flag_help(help_text, "--max-queued-jobs")
    assert "429" in part and "503" not in part
    # ... and it does: a service that takes one queued job refuses the second with 429
    from fastapi.testclient import TestClient

    from app.config import Settings
    from app.main import create_app

    api = create_app(Settings(no_viewer=True, data_dir=tmp_path, max_queued_jobs=1))
    client = TestClient(api)   # not entered: the first job stays queued
    body = {"kind": "workspace", "params": {"robot": "glt_palletizer", "samples": 1000}}
    assert client.post("/jobs", json=body).status_code == 202
    assert client.post("/jobs", json=body).status_code == 429


def test_help_states_the_body_cap_the_routes_enforce(help_text, ro_client):
    part = _flag_help(help_text, "--max-body-bytes")
    assert "80 MiB" not in part and "83886080" not in part
    caps = {path: op["x-max-body-bytes"]
            for path, ops in ro_client.get("/openapi.json").json()["paths"].items()
            for method, op in ops.items() if "x-max-body-bytes" in op}
    largest_route = max(caps, key=caps.get)
    mib = caps[largest_route] / 2**20
    assert f"at most {mib:g} MiB ({largest_route})" in part
    default = int(re.search(r"default (\d+)", part).group(1))
    assert default == caps[largest_route]   # the default lowers no route's cap


def test_make_run_says_where_the_api_docs_and_viewer_are(tmp_path):
    if shutil.which("make") is None:
        pytest.skip("needs make")
    recipe = subprocess.run(["make", "-n", "-o", ".venv/.installed", "run"], cwd=ROOT,
                            capture_output=True, text=True, timeout=30, check=True).stdout
    lines = recipe.splitlines()
    start = lines.index(next(line for line in lines if "-m kinoplan" in line))
    said = subprocess.run(["sh", "-c", "\n".join(lines[:start])], capture_output=True,
                          text=True, timeout=30, check=True,
                          env={"PATH": "/usr/bin:/bin", "KINOPLAN_PORT": "9123"}).stdout
    assert "http://127.0.0.1:9123" in said
    assert "http://127.0.0.1:9123/docs" in said
    assert "http://127.0.0.1:8080" in said and "viewer" in said
