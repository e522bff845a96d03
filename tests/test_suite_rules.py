"""Rules the test modules keep, checked on their source.

* Every property-based test (hypothesis's ``@given``, schemathesis's ``parametrize``) runs
  the same examples on every run: ``@settings(derandomize=True, database=None)``, so a
  failure repeats and no example database carries state between runs.
* Speed goals are benchmarks (benchmarks/bench_speed_goals.py), not tests: no test module
  reads ``time.perf_counter`` or ``time.process_time``. ``time.monotonic`` stays for
  deadlines that stop a test from hanging and for checks that a timeout fires.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parent
MODULES = sorted(TESTS.rglob("*.py"))
SPEED_CLOCKS = {"perf_counter", "perf_counter_ns", "process_time", "process_time_ns"}


def _name(node: ast.expr) -> str:
    """``given`` for ``given(...)``, ``parametrize`` for ``schema.parametrize()``."""
    if isinstance(node, ast.Call):
        node = node.func
    if isinstance(node, ast.Attribute):
        return node.attr
    return node.id if isinstance(node, ast.Name) else ""


def unrepeatable_property_tests(source: str) -> list[str]:
    """Property-based tests of ``source`` without derandomize=True and database=None."""
    out = []
    for node in ast.walk(ast.parse(source)):
        if not isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            continue
        names = [_name(d) for d in node.decorator_list]
        generated = "given" in names or any(
            _name(d) == "parametrize" and isinstance(d, ast.Call)
            and isinstance(d.func, ast.Attribute) and _name(d.func.value) != "mark"
            for d in node.decorator_list)
        if not generated:
            continue
        settings = [d for d in node.decorator_list
                    if isinstance(d, ast.Call) and _name(d) == "settings"]
        keywords = {k.arg: k.value for s in settings for k in s.keywords}
        repeatable = (isinstance(keywords.get("derandomize"), ast.Constant)
                      and keywords["derandomize"].value is True
                      and isinstance(keywords.get("database"), ast.Constant)
                      and keywords["database"].value is None)
        if not repeatable:
            out.append(node.name)
    return out


def speed_clock_uses(source: str) -> list[int]:
    """Lines of ``source`` that read a clock meant for timing code."""
    lines = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom) and node.module == "time":
            if any(alias.name in SPEED_CLOCKS for alias in node.names):
                lines.add(node.lineno)
        elif isinstance(node, ast.Attribute | ast.Name):
            if (node.attr if isinstance(node, ast.Attribute) else node.id) in SPEED_CLOCKS:
                lines.add(node.lineno)
    return sorted(lines)


def test_the_checks_catch_what_they_look_for():
    loose = ("@settings(max_examples=5, deadline=None)\n@given(st.integers())\n"
             "def test_a(x): pass\n"
             "@schema.parametrize()\n@settings(derandomize=True)\ndef test_b(case): pass\n")
    tight = ("@settings(derandomize=True, database=None)\n@given(st.integers())\n"
             "def test_c(x): pass\n"
             "@pytest.mark.parametrize('x', [1])\ndef test_d(x): pass\n")
    assert unrepeatable_property_tests(loose) == ["test_a", "test_b"]
    assert unrepeatable_property_tests(tight) == []
    assert speed_clock_uses("import time\nt = time.perf_counter()\n"
                            "from time import process_time\nu = process_time()\n") == [2, 3, 4]
    assert speed_clock_uses("import time\nend = time.monotonic() + 5\n") == []


@pytest.mark.slow
@pytest.mark.parametrize("path", MODULES, ids=[str(p.relative_to(TESTS)) for p in MODULES])
def test_property_tests_repeat_and_speed_goals_live_in_benchmarks(path):
    source = path.read_text()
    assert unrepeatable_property_tests(source) == [], \
        "add derandomize=True, database=None to their @settings"
    if path.name != Path(__file__).name:
        assert speed_clock_uses(source) == [], \
            "time goals belong in benchmarks/bench_speed_goals.py"
