"""The composition root: ``python -m kinoplan`` wires the viewer into the service, and the
layers point one way (``web`` builds on ``app``; ``app`` never imports ``web`` or
``kinoplan``, not even inside a function)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from app.__main__ import build_parser
from app.config import Settings
from kinoplan import __main__ as root

REPO = Path(__file__).resolve().parents[2]


def _imports(path: Path) -> set[str]:
    """Absolute module names imported anywhere in ``path`` (functions included; relative
    imports stay inside their package and are left out)."""
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            out.add(node.module)
    return out


def test_the_scan_sees_imports_inside_functions(tmp_path):
    module = tmp_path / "m.py"
    module.write_text("import os\n\ndef f():\n    from web.viewer import Viewer\n"
                      "    import kinoplan.x\n    from . import y\n")
    assert _imports(module) == {"os", "web.viewer", "kinoplan.x"}


@pytest.mark.slow
@pytest.mark.parametrize("package", ["app", "kinematics", "planning"])
def test_the_service_never_imports_the_viewer_or_the_root(package):
    offenders = sorted(
        f"{path.relative_to(REPO)} imports {name}"
        for path in (REPO / package).rglob("*.py")
        for name in _imports(path) if name.split(".")[0] in ("web", "kinoplan"))
    assert not offenders, offenders


def test_web_raises_the_exception_the_route_catches():
    from app.viewer import JobNotReady
    from web import viewer

    assert viewer.JobNotReady is JobNotReady


def _options(parser) -> dict[str, str]:
    return {o: a.dest for a in parser._actions for o in a.option_strings}


def test_kinoplan_takes_the_flags_of_app_and_names_itself(monkeypatch, capsys):
    with pytest.raises(SystemExit) as done:
        root.main(["--help"])
    assert done.value.code == 0
    text = " ".join(capsys.readouterr().out.split())
    assert text.startswith("usage: python -m kinoplan ")
    assert "python -m kinoplan warm-up" in text
    assert "API and its 3D viewer" in text
    for name in Settings.model_fields:
        assert "--" + name.replace("_", "-") in text, name
    assert set(_options(build_parser())) >= {"--viewer-port", "--no-viewer"}


def test_kinoplan_starts_the_viewer_it_hands_the_service(tmp_path, monkeypatch):
    import uvicorn

    started, served = [], []

    class FakeViewer:
        port = 4321

        def stop(self) -> None:
            started.append("stopped")

    def fake_start(settings, state):
        started.append((settings.viewer_port, state.registry is not None))
        return FakeViewer()

    monkeypatch.setattr(root, "start_viewer", fake_start)
    monkeypatch.setattr(uvicorn, "run", lambda api, **kwargs: served.append(api))
    assert root.main(["--data-dir", str(tmp_path), "--viewer-port", "9124"]) == 0
    assert started == [(9124, True), "stopped"]
    assert isinstance(served[0].state.viewer, FakeViewer)

    started.clear()
    assert root.main(["--data-dir", str(tmp_path), "--no-viewer"]) == 0
    assert started == []


def test_warm_up_command_reports_each_part(monkeypatch, capsys):
    from planning import warm

    monkeypatch.setattr(warm, "warm_up", lambda parts=None: warm.WarmUpReport(
        {"kinematics": 0.3, "motion": 1.0, "sequencing": 0.5},
        {"kinematics": True, "motion": True, "sequencing": True}))
    assert root.main(["warm-up"]) == 0
    out = capsys.readouterr().out
    assert out.strip() == ("compiled kernels: kinematics 0.3 s, motion 1.0 s, sequencing 0.5 s "
                           "(total 1.8 s)")

    monkeypatch.setattr(warm, "warm_up", lambda parts=None: warm.WarmUpReport(
        {"kinematics": 0.0, "motion": 0.0, "sequencing": 0.1},
        {"kinematics": False, "motion": False, "sequencing": True}))
    assert root.main(["warm-up"]) == 1
    captured = capsys.readouterr()
    assert "kinematics off, motion off, sequencing 0.1 s" in captured.out
    assert "KINOPLAN_JIT=0" in captured.err


def test_warm_up_command_takes_parts(monkeypatch, capsys):
    """``warm-up motion`` readies only that part (make kernels runs two at once); an unknown
    part is a usage error naming it."""
    from planning import warm

    asked = []
    monkeypatch.setattr(warm, "warm_up", lambda parts=None: asked.append(parts) or
                        warm.WarmUpReport({"motion": 1.0}, {"motion": True}))
    assert root.main(["warm-up", "motion"]) == 0
    assert asked == [["motion"]]
    assert "compiled kernels: motion 1.0 s" in capsys.readouterr().out
    with pytest.raises(SystemExit) as stop:
        root.main(["warm-up", "graphics"])
    assert stop.value.code == 2
    assert "unknown part 'graphics'" in capsys.readouterr().err


def test_warm_up_parts_are_checked():
    from planning import warm

    with pytest.raises(ValueError, match="unknown kernel parts \\['graphics'\\]"):
        warm.warm_up(["graphics"])
    assert list(warm.PARTS) == ["kinematics", "motion", "sequencing"]
