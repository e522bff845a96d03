"""The command line: ``python -m kinoplan`` (API and viewer) and ``python -m app`` (the API
alone) share their flags and environment variables; and a real start of each."""

from __future__ import annotations

import socket
import subprocess
import sys
import time
import typing
from pathlib import Path

import httpx
import pytest
from annotated_types import Ge, Gt, Le, Lt

from app.__main__ import build_parser, parse_args
from app.config import Settings

REPO = Path(__file__).resolve().parents[2]

#: The flags that scripts, the Dockerfile and the docs use: each must keep working.
DOCUMENTED_FLAGS = ["--host", "--port", "--viewer-port", "--no-viewer", "--data-dir",
                    "--workers", "--jobs-backend", "--allowed-hosts", "--allowed-origins",
                    "--job-time-limit-s"]


def options() -> dict[str, object]:
    """Option string -> argparse action of the parser ``python -m app`` uses."""
    return {o: a for a in build_parser()._actions for o in a.option_strings}


def test_every_settings_field_has_a_flag_with_its_description():
    actions = options()
    assert set(DOCUMENTED_FLAGS) <= set(actions)
    for name, info in Settings.model_fields.items():
        flag = "--" + "-".join(name.split("_"))
        assert flag in actions, f"Settings.{name} has no flag {flag}"
        assert actions[flag].dest == name
        assert info.description, f"Settings.{name} has no description for its --help"
        assert actions[flag].help.startswith(info.description.replace("%", "%%"))
        assert f"KINOPLAN_{name.upper()}" in actions[flag].help
    # Nothing but the fields (and --help).
    assert {a.dest for a in actions.values()} == set(Settings.model_fields) | {"help"}


def test_help_lists_every_flag_and_never_the_key(monkeypatch, capsys):
    monkeypatch.setenv("KINOPLAN_API_KEY", "do-not-print-me")
    monkeypatch.setenv("KINOPLAN_PORT", "9321")
    with pytest.raises(SystemExit) as done:
        parse_args(["--help"])
    assert done.value.code == 0
    text = " ".join(capsys.readouterr().out.split())  # argparse wraps lines
    for name in Settings.model_fields:
        assert "--" + name.replace("_", "-") in text, name
    assert "default 9321" in text  # the default shown is the environment's
    assert "do-not-print-me" not in text


def _values(name: str) -> tuple[str, list[str], object]:
    """``(environment value, flag arguments, value the flag gives)`` for field ``name``,
    distinct from each other and inside the field's bounds."""
    info = Settings.model_fields[name]
    kind = info.annotation
    if kind in (str | None, int | None, float | None, Path | None):
        kind = next(a for a in kind.__args__ if a is not type(None))
    low = next((float(m.ge if isinstance(m, Ge) else m.gt) for m in info.metadata
                if isinstance(m, Ge | Gt)), 0.0)
    high = next((float(m.le if isinstance(m, Le) else m.lt) for m in info.metadata
                 if isinstance(m, Le | Lt)), float("inf"))
    flag = "--" + name.replace("_", "-")
    if kind is bool:
        return "false", [flag], True
    if kind is int:
        assert low + 3 <= high
        return str(int(low) + 2), [flag, str(int(low) + 3)], int(low) + 3
    if kind is float:
        assert low + 3.5 <= high
        return str(low + 2.5), [flag, str(low + 3.5)], low + 3.5
    if kind is Path:
        return "/env/dir", [flag, "/flag/dir"], Path("/flag/dir")
    if kind is str:
        return "from-env", [flag, "from-flag"], "from-flag"
    if typing.get_origin(kind) is typing.Literal and len(typing.get_args(kind)) >= 2:
        first, second = typing.get_args(kind)[:2]
        return str(first), [flag, str(second)], second
    raise AssertionError(f"Settings.{name}: add values of type {kind} to this test")


@pytest.mark.parametrize("name", list(Settings.model_fields))
def test_a_flag_overrides_its_environment_variable(name, monkeypatch):
    env_value, argv, expected = _values(name)
    monkeypatch.setenv(f"KINOPLAN_{name.upper()}", env_value)
    from_env = getattr(parse_args([]), name)
    assert from_env != expected
    assert str(from_env).lower() == env_value.lower() or from_env == type(expected)(env_value)
    assert getattr(parse_args(argv), name) == expected


def test_bad_values_name_their_flag_or_variable(monkeypatch, capsys):
    with pytest.raises(SystemExit) as done:
        parse_args(["--port", "0"])
    assert done.value.code == 2 and "--port: " in capsys.readouterr().err
    with pytest.raises(SystemExit) as done:
        parse_args(["--workers", "many"])
    assert done.value.code == 2 and "--workers" in capsys.readouterr().err
    monkeypatch.setenv("KINOPLAN_VIEWER_PORT", "70000")
    with pytest.raises(SystemExit) as done:
        parse_args([])
    err = capsys.readouterr().err
    assert done.value.code == 2 and "KINOPLAN_VIEWER_PORT: " in err and "Traceback" not in err


def test_defaults_flags_and_environment(monkeypatch, tmp_path):
    s = parse_args([])
    assert (s.host, s.port, s.viewer_port, s.no_viewer) == ("127.0.0.1", 8000, 8080, False)
    assert s.jobs_backend == "local" and s.workers >= 1
    monkeypatch.setenv("KINOPLAN_PORT", "9123")
    monkeypatch.setenv("KINOPLAN_NO_VIEWER", "true")
    s = parse_args([])
    assert s.port == 9123 and s.no_viewer
    s = parse_args(["--port", "9200", "--data-dir", str(tmp_path), "--workers", "3",
                    "--jobs-backend", "dask://127.0.0.1:8786", "--viewer-port", "9201"])
    assert s.port == 9200 and s.data_dir == tmp_path and s.workers == 3
    assert s.jobs_backend == "dask://127.0.0.1:8786" and s.viewer_port == 9201

    # A setting on by default is turned off by --no-<name>, or by its variable.
    assert parse_args([]).prebuild_collision is True
    assert parse_args(["--no-prebuild-collision"]).prebuild_collision is False
    monkeypatch.setenv("KINOPLAN_PREBUILD_COLLISION", "false")
    assert parse_args([]).prebuild_collision is False
    assert parse_args(["--prebuild-collision"]).prebuild_collision is True


def _free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def test_python_m_app_runs_the_api_alone_and_says_so(tmp_path, monkeypatch, capsys):
    import uvicorn

    from app.__main__ import main

    served = []
    monkeypatch.setattr(uvicorn, "run", lambda api, **kwargs: served.append(api))
    # No --no-viewer: still no viewer, the viewer is python -m kinoplan's.
    assert main(["--data-dir", str(tmp_path), "--viewer-port", str(_free_port())]) == 0
    assert served and served[0].state.viewer is None
    with pytest.raises(SystemExit):
        parse_args(["--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert text.startswith("usage: python -m app ")
    assert "API alone, without the 3D viewer" in text and "python -m kinoplan" in text


@pytest.mark.cluster
@pytest.mark.parametrize("module", ["kinoplan", "app"])
def test_python_m_kinoplan_and_app_serve_health(tmp_path, module):
    port = _free_port()
    proc = subprocess.Popen(
        [sys.executable, "-m", module, "--port", str(port), "--no-viewer",
         "--data-dir", str(tmp_path)],
        cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
    )
    try:
        deadline = time.monotonic() + 60  # as tests/jobs/conftest.py: loaded CI machines
        while True:
            try:
                r = httpx.get(f"http://127.0.0.1:{port}/health", timeout=1)
                break
            except httpx.TransportError:
                assert proc.poll() is None, proc.stdout.read().decode()
                assert time.monotonic() < deadline, "service did not start in 60 s"
                time.sleep(0.2)
        assert r.json()["status"] == "ok"
        assert httpx.get(f"http://127.0.0.1:{port}/robots").status_code == 200
    finally:
        proc.terminate()
        proc.wait(timeout=10)
