"""The step runner: the child process a Dask worker runs each job step in."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest

from app.jobs import runner as runner_module
from app.jobs.kinds import run_echo, run_sleep
from app.jobs.runner import Runner, StepCancelled, StepFailed


@pytest.fixture(scope="module")
def runner():
    r = Runner()
    yield r
    r.kill()


def _gone(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().split(") ")[1][0] == "Z"
    except OSError:
        return True


@pytest.mark.slow
def test_a_step_runs_in_the_child_with_progress_and_its_value(runner):
    seen = []
    text = runner.run("job-a", "sleep", {"params": {"seconds": 0.2, "steps": 4}}, run_sleep, (),
                      True, lambda f, m: seen.append(f), lambda: False)
    assert '"slept":0.2' in text and f'"pid":{runner.process.pid}' in text
    assert seen and seen[-1] == 1.0
    # Not final: the step's own value (the params stay loaded for the job's next step).
    value = runner.run("job-a", "sleep", None, run_sleep, (), False, lambda f, m: None,
                       lambda: False)
    assert value.slept == 0.2 and value.pid == runner.process.pid


@pytest.mark.slow
def test_the_child_needs_the_params_of_a_new_job(runner):
    with pytest.raises(StepFailed, match="lost the job's params"):
        runner.run("job-b", "echo", None, run_echo, (), True, lambda f, m: None, lambda: False)
    assert runner.alive()
    assert runner.run("job-b", "echo", {"params": {"value": [1, 2]}}, run_echo, (), True,
                      lambda f, m: None, lambda: False) == '{"value":[1,2]}'


def test_a_failing_step_says_why(runner):
    with pytest.raises(StepFailed, match="^RuntimeError: the sleep job was asked to fail$"):
        runner.run("job-c", "sleep", {"params": {"seconds": 0, "outcome": "raise"}}, run_sleep,
                   (), True, lambda f, m: None, lambda: False)
    assert runner.alive()


@pytest.mark.slow
def test_a_stop_kills_the_child_at_once():
    r = Runner()
    pid = r.process.pid
    asked = time.monotonic() + 0.5
    t0 = time.monotonic()
    with pytest.raises(StepCancelled):
        r.run("job-d", "sleep", {"params": {"seconds": 60, "steps": 1}}, run_sleep, (), True,
              lambda f, m: None, lambda: time.monotonic() > asked)
    # The step reports no progress for 60 s: the stop is seen between reports.
    assert time.monotonic() - t0 < 0.5 + 2 * runner_module.CHECK_EVERY_S + 1.0
    assert _gone(pid) and not r.alive()


@pytest.mark.slow
def test_a_dead_child_is_reported():
    r = Runner()
    with pytest.raises(runner_module.RunnerDied, match="died"):
        r.run("job-e", "sleep", {"params": {"seconds": 0, "outcome": "exit"}}, run_sleep, (),
              True, lambda f, m: None, lambda: False)


@pytest.mark.slow
def test_the_child_dies_with_its_parent(tmp_path):
    """A worker killed with SIGKILL leaves no step running on its CPU."""
    pid_file = tmp_path / "pid"
    script = textwrap.dedent(f"""
        import time
        from app.jobs.runner import take_runner
        r = take_runner()
        open({str(pid_file)!r}, "w").write(str(r.process.pid))
        time.sleep(60)
    """)
    parent = subprocess.Popen([sys.executable, "-c", script], cwd=os.getcwd())
    try:
        deadline = time.monotonic() + 60
        while not pid_file.exists() or not pid_file.read_text():
            assert time.monotonic() < deadline and parent.poll() is None
            time.sleep(0.05)
        child = int(pid_file.read_text())
        assert not _gone(child)
        os.kill(parent.pid, signal.SIGKILL)
        parent.wait()
        deadline = time.monotonic() + 2
        while not _gone(child):
            assert time.monotonic() < deadline, "the runner outlived its worker"
            time.sleep(0.02)
    finally:
        if parent.poll() is None:
            parent.kill()


@pytest.mark.slow
def test_the_pool_hands_out_prestarted_runners_and_takes_them_back():
    runner_module.prestart(1)
    r = runner_module.take_runner()
    try:
        assert r.alive()
        runner_module.give_back(r)
        assert runner_module.take_runner() is r
    finally:
        r.kill()
    runner_module.give_back(r)  # a killed runner is not pooled
    assert not any(f.done() and f.result() is r for f in runner_module._POOL)
