"""The long fuzz run of the whole API (``make fuzz``).

Runs ``tests/app/test_fuzz_api.py`` (schemathesis against the app's own OpenAPI document, in
process: see that module's docstring) with many more generated cases per operation than the
test suite uses, counts the requests actually sent, and fails if

- any case failed: a 5xx answer, an answer that does not conform to the response schema
  the document declares, or a numeric warning in a handler; or
- fewer than ``--min-requests`` (default 2,000) requests were sent.

Usage::

    .venv/bin/python tools/fuzz.py                   # 1,000 cases per operation
    .venv/bin/python tools/fuzz.py --examples 30 --min-requests 500
    .venv/bin/python tools/fuzz.py -- -k "ik or fk"  # anything after -- goes to pytest

The number of generated cases per operation reaches the test module through
``KINOPLAN_FUZZ_EXAMPLES``. Requests are counted with a global schemathesis ``after_call``
hook: every request the fuzz sends, per tested operation, per schemathesis phase (``coverage``:
boundaries, missing fields, unexpected methods; ``fuzzing``: generated cases) and per status
class; the DELETE that cancels a job the fuzz got accepted is counted apart. Failing
cases are listed at the end, each with the ``curl`` command that reproduces it (pass
``-- --tb=short`` for pytest's tracebacks too). About 5 minutes on 2 cores with the defaults.
"""

from __future__ import annotations

import argparse
import os
import sys
import textwrap
import time
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
TEST_MODULE = "tests/app/test_fuzz_api.py"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0].replace("``", ""))
    p.add_argument("--examples", type=int, default=1000,
                   help="generated cases per operation (%(default)s)")
    p.add_argument("--min-requests", type=int, default=2000,
                   help="fail if fewer requests were sent (%(default)s)")
    p.add_argument("pytest_args", nargs="*", help="extra pytest arguments (after --)")
    args = p.parse_args(argv)

    os.environ["KINOPLAN_FUZZ_EXAMPLES"] = str(args.examples)
    os.chdir(ROOT)
    sys.path.insert(0, str(ROOT))

    import pytest
    import schemathesis

    # per tested operation: requests by phase ("coverage", "fuzzing", ...) and status class
    by_phase: dict[str, Counter[str]] = {}
    by_status: dict[str, Counter[str]] = {}
    server_errors: Counter[str] = Counter()
    cleanup = 0

    @schemathesis.hook
    def after_call(context, case, response) -> None:
        nonlocal cleanup
        if case.meta is None:  # built by the test itself: the cancellation of an accepted job
            cleanup += 1
            return
        operation = f"{case.operation.method.upper()} {case.operation.path}"
        status = response.status_code
        by_phase.setdefault(operation, Counter())[str(case.meta.phase.name)] += 1
        by_status.setdefault(operation, Counter())[f"{status // 100}xx"] += 1
        if status >= 500:
            server_errors[f"{case.method.upper()} {case.path} -> {status}"] += 1

    class FailureSummary:
        """The exception of each failing operation, with schemathesis's curl command."""

        def __init__(self) -> None:
            self.failures: list[tuple[str, str, str]] = []

        @pytest.hookimpl(wrapper=True)
        def pytest_runtest_makereport(self, item, call):
            report = yield
            if report.when == "call" and report.failed and call.excinfo is not None:
                exc = call.excinfo.value
                callspec = getattr(item, "callspec", None)
                notes = "\n".join(str(n) for n in getattr(exc, "__notes__", ()))
                self.failures.append((callspec.id if callspec else item.name,
                                      f"{type(exc).__name__}: {exc}", notes))
            return report

    summary = FailureSummary()
    t0 = time.perf_counter()
    code = pytest.main(["-q", "-p", "no:cacheprovider", "--no-header", "--tb=no",
                        TEST_MODULE, *args.pytest_args], plugins=[summary])
    minutes = (time.perf_counter() - t0) / 60
    phases = sorted({p for c in by_phase.values() for p in c})
    classes = ("2xx", "4xx", "5xx")
    print(f"\nrequests sent per operation ({args.examples} generated cases each at most, plus "
          "schemathesis's coverage cases):")
    print(f"  {'operation':<44}" + "".join(f"{h:>10}" for h in (*phases, *classes)))
    totals: Counter[str] = Counter()
    for operation in sorted(by_phase):
        row = by_phase[operation] + by_status[operation]
        totals += row
        print(f"  {operation:<44}" + "".join(f"{row[h]:>10}" for h in (*phases, *classes)))
    print(f"  {'total':<44}" + "".join(f"{totals[h]:>10}" for h in (*phases, *classes)))
    total = sum(totals[p] for p in phases)
    print(f"{total} requests sent in {minutes:.1f} min ({cleanup} job cancellations besides)")
    if server_errors:
        print("server errors: " + "; ".join(f"{k} x{v}" for k, v in server_errors.items()))
    for operation, error, notes in summary.failures:
        print(f"\nFAILED {operation}: {error.strip()}")
        if notes.strip():
            print(textwrap.indent(notes.strip(), "    "))
    if total < args.min_requests:
        print(f"FAIL: {total} requests sent, fewer than {args.min_requests}")
        return 1
    if code != 0:
        print("FAIL: see the failing cases above (each with a curl command to reproduce it)")
        return int(code) or 1
    print("PASS")
    return 0


if __name__ == "__main__":
    sys.exit(main())
