"""Run, in a fresh process, the first jobs a job step would run, and print (one JSON line)
which compiled kernels numba loaded from its cache and which it had to compile.

Run as a script (``python kernel_probe.py``, or its text with ``python -c``) in the process
under test: the source tree with a ``NUMBA_CACHE_DIR`` (tests/deploy/test_kernel_cache.py),
or a container of the image (tests/deploy/test_docker_image.py). It starts as a job step's
process starts (``app.jobs.warm_kernels``: every kind registered, ``planning.warm.warm_up``)
and then runs a workspace, a motion and a sequence job through ``app.jobs.kinds.execute``,
the function a step runs. numba counts, per kernel, the signatures it loaded from the cache
(``Dispatcher.stats.cache_hits``) and those it compiled (``cache_misses``: not in the cache,
or the cache not usable).
"""

from __future__ import annotations

import gc
import json

#: The jobs, as ``POST /jobs`` bodies' ``kind`` and ``params``.
JOBS = [
    ("workspace", {"robot": "glt_palletizer", "samples": 5000, "seed": 3}),
    ("motion", {"robot": "glt_palletizer", "start": [0, 0, 0, 0, 0.5, 0],
                "goal": {"q": [1, 0.3, -0.3, 0, 0.5, 0]}, "time_limit": 5, "seed": 1,
                "scene": {"objects": [
                    {"type": "box", "id": "crate", "size": [300, 300, 300],
                     "pose": [[1, 0, 0, 2500], [0, 1, 0, 0], [0, 0, 1, 400], [0, 0, 0, 1]]}]}}),
    ("sequence", {"holes": [[1000.0 * i, 600.0 * j, 0.0] for i in range(4) for j in range(3)],
                  "start": [9000, 0, -1000]}),
]


def kernel_stats(packages: tuple[str, ...]) -> dict[str, dict[str, list[str]]]:
    """``{"loaded": {kernel: [signature, ...]}, "compiled": {...}}`` over every numba
    dispatcher of ``packages`` alive in this process."""
    from numba.core.dispatcher import Dispatcher

    out: dict[str, dict[str, list[str]]] = {"loaded": {}, "compiled": {}}
    for obj in gc.get_objects():
        if not isinstance(obj, Dispatcher):
            continue
        module = getattr(obj.py_func, "__module__", "") or ""
        if module.split(".")[0] not in packages:
            continue
        name = f"{module}.{obj.py_func.__qualname__}"
        stats = obj.stats
        if stats.cache_hits:
            out["loaded"][name] = sorted(str(sig) for sig in stats.cache_hits)
        if stats.cache_misses:
            out["compiled"][name] = sorted(str(sig) for sig in stats.cache_misses)
    return out


def main() -> None:
    import app.jobs.warm_kernels  # noqa: F401 - as a job step's process starts
    from app.jobs.catalog import KINDS
    from app.jobs.kinds import JobPayload, execute
    from kinematics.library import builtin_model

    succeeded = []
    for kind, params in JOBS:
        spec = KINDS[kind]
        checked = spec.load_params(params)
        robot = spec.robot_id(checked)
        payload = JobPayload(params=checked.model_dump(mode="json"),
                             robot_model=builtin_model(robot).to_dict() if robot else None)
        json.loads(execute(kind, payload.model_dump(mode="json"), lambda done, message: None))
        succeeded.append(kind)
    print(json.dumps({"jobs": succeeded, **kernel_stats(("kinematics", "planning"))}))


if __name__ == "__main__":
    main()
