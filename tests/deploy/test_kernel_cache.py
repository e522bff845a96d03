"""The kernels the image builds in are the kernels its processes run, shown without Docker.

The Dockerfile runs ``python -m kinoplan warm-up`` with ``NUMBA_CACHE_DIR`` set, and every
process of a container later reads that directory. Here the same happens on this machine:
the warm-up fills a fresh cache directory in one process; a second fresh process with the
same directory starts as a job step does and runs a workspace, a motion and a sequence job
(tests/deploy/kernel_probe.py), and numba's own counters must show every kernel those jobs
ran loaded from the cache and none compiled. A first check shows that the counters do see a
compile, so that the main test cannot pass for want of looking. The suite does this in the
cache ``make kernels`` filled (the warm-up then only loads); with ``KINOPLAN_DEPLOY_TESTS=1``
also in an empty directory, compiling everything as the image build does.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
PROBE = Path(__file__).with_name("kernel_probe.py")
#: A cold cache compiles every kernel: about 2 minutes of CPU, more on a loaded machine.
COMPILE_TIMEOUT_S = 1800


def _env(cache: Path) -> dict[str, str]:
    """This environment with numba's cache in ``cache``, the kernels on and this checkout's
    packages first on the path (the probe runs as a script, not from the checkout)."""
    env = {k: v for k, v in os.environ.items() if k != "KINOPLAN_JIT"}
    env["NUMBA_CACHE_DIR"] = str(cache)
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), *filter(None, [env.get("PYTHONPATH")])])
    return env


def _last_json(done: subprocess.CompletedProcess) -> dict:
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.mark.slow
def test_the_counters_see_a_compile_and_a_load(tmp_path):
    """One small cached kernel: compiled in a first process (a miss), loaded in a second
    (a hit), counted by the probe's ``kernel_stats``."""
    package = tmp_path / "src" / "tinykernels"
    package.mkdir(parents=True)
    (package / "__init__.py").write_text(textwrap.dedent("""
        from numba import njit

        @njit(cache=True)
        def twice(x):
            return 2.0 * x
    """))
    script = ("import json, sys; sys.path[:0] = [sys.argv[1], sys.argv[2]]\n"
              "from tinykernels import twice\n"
              "from kernel_probe import kernel_stats\n"
              "assert twice(1.5) == 3.0\n"
              "print(json.dumps(kernel_stats(('tinykernels',))))\n")
    argv = [sys.executable, "-c", script, str(tmp_path / "src"), str(PROBE.parent)]
    env = _env(tmp_path / "numba")
    first = _last_json(subprocess.run(argv, env=env, capture_output=True, text=True,
                                      timeout=120))
    second = _last_json(subprocess.run(argv, env=env, capture_output=True, text=True,
                                       timeout=120))
    assert first == {"loaded": {}, "compiled": {"tinykernels.twice": ["(float64,)"]}}
    assert second == {"loaded": {"tinykernels.twice": ["(float64,)"]}, "compiled": {}}


def _warm_then_probe(env: dict[str, str], cache_files) -> None:
    """``python -m kinoplan warm-up``, then a fresh probe process: its jobs compile nothing
    and load the kernels of every part. ``cache_files``: the index files numba wrote."""
    warm = subprocess.run([sys.executable, "-m", "kinoplan", "warm-up"], cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=COMPILE_TIMEOUT_S)
    assert warm.returncode == 0, warm.stdout + warm.stderr
    assert warm.stdout.startswith("compiled kernels: kinematics "), warm.stdout
    assert any(cache_files()), "the warm-up wrote nothing into numba's cache"

    probe = _last_json(subprocess.run([sys.executable, str(PROBE)], cwd=REPO, env=env,
                                      capture_output=True, text=True,
                                      timeout=COMPILE_TIMEOUT_S))
    assert probe["jobs"] == ["workspace", "motion", "sequence"]
    assert probe["compiled"] == {}, "compiled after the warm-up: " + json.dumps(
        probe["compiled"], indent=1)
    # What the jobs ran came from the cache: the kernels of each part, every one of them.
    loaded = set(probe["loaded"])
    for module in ("kinematics._kernels", "planning.motion._kernels",
                   "planning.sequencing.oropt"):
        assert any(name.startswith(module + ".") for name in loaded), module


@pytest.mark.slow
def test_the_warm_up_readies_every_kernel_the_first_jobs_run():
    """In numba's cache as this checkout uses it (``make kernels`` filled it before the
    suite, so the warm-up only loads here): nothing a job runs is left out of the warm-up."""
    env = {k: v for k, v in os.environ.items() if k != "KINOPLAN_JIT"}
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), *filter(None, [env.get("PYTHONPATH")])])
    cache = env.get("NUMBA_CACHE_DIR")
    _warm_then_probe(env, lambda: Path(cache).rglob("*.nbi") if cache
                     else REPO.glob("*/**/__pycache__/*.nbi"))


@pytest.mark.slow
@pytest.mark.skipif(os.environ.get("KINOPLAN_DEPLOY_TESTS") != "1",
                    reason="compiles every kernel into an empty cache (minutes of CPU), as "
                           "the image build does; set KINOPLAN_DEPLOY_TESTS=1")
def test_a_fresh_process_runs_the_first_jobs_on_warmed_kernels_only(tmp_path):
    """As in the image: the warm-up fills an empty NUMBA_CACHE_DIR, a new process reads it."""
    cache = tmp_path / "numba"
    _warm_then_probe(_env(cache), lambda: cache.rglob("*.nbi"))
