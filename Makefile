# Fresh clone: `make run` or `make test` create .venv and install on first use.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

# Python may keep compiled bytecode (and pytest its rewritten test modules) in __pycache__:
# an environment that forbids it makes every process of a test run (the pytest workers,
# each service and job process the tests start) compile the project's sources again.
unexport PYTHONDONTWRITEBYTECODE

.PHONY: install run test test-rest test-fast kernels lint bench clean chromium fuzz

# The install is uv's (from the package index into .venv, as pip would: about 15 s where pip
# takes 90 s on a fresh clone).
$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet "uv>=0.4"
	$(BIN)/uv pip install --quiet --python $(BIN)/python -e ".[test]"
	touch $(STAMP)

install: $(STAMP)

# The API (:8000) and the 3D viewer (:8080); says where they are (KINOPLAN_HOST, _PORT and
# _VIEWER_PORT move them).
run: $(STAMP)
	@h=$${KINOPLAN_HOST:-127.0.0.1}; p=$${KINOPLAN_PORT:-8000}; \
	echo "kinoplan API: http://$$h:$$p  (interactive docs: http://$$h:$$p/docs)"; \
	echo "3D viewer:    http://$$h:$${KINOPLAN_VIEWER_PORT:-8080}"
	$(BIN)/python -m kinoplan

# The browser test drives Debian's Chromium (not Playwright's download); CI runs as root.
chromium:
	@command -v chromium >/dev/null 2>&1 || (apt-get update && apt-get install -y chromium)

# Test tiers (markers in pyproject.toml): `make test` runs every test on 2 pytest-xdist
# workers, a module at a time per worker (--dist loadfile: a module's fixtures, such as its
# Dask cluster or browser page, are built once and its tests run in turn); `make test-fast`
# leaves out the slow, browser, cluster and paper tests: under 2 minutes, for development.
FAST := not slow and not browser and not cluster and not paper

# The API fuzz (marked slow) runs in pytests of its own, after: schemathesis gives its 40
# operations one node id (under pytest 9.2), and pytest-xdist would run only one of them;
# test-fast does not collect it (building its cases takes some 9 s). Two pytests share the
# operations out (KINOPLAN_FUZZ_SHARD 0/2 and 1/2), one a core; the second's output is
# printed after the first's.
FUZZ := tests/app/test_fuzz_api.py
FUZZ_HALF := $(BIN)/python -m pytest -q -p no:xdist -p no:cacheprovider $(FUZZ)

# The numba kernels compiled (a fresh clone: about 2 minutes of CPU, once) or loaded (3 s)
# before the test workers start: otherwise each worker, and each process the tests start,
# compiles them at the same time, some inside tests that have a time limit.
# One command (planning.warm) readies every kernel, as the Docker image does; here in two
# processes, one a core (the motion kernels take about as long as the other two parts).
kernels: $(STAMP)
	@$(BIN)/python -m kinoplan warm-up motion & pid=$$!; \
	$(BIN)/python -m kinoplan warm-up kinematics sequencing; a=$$?; wait $$pid; b=$$?; \
	exit $$((a | b))

# `make test`: the cluster tests (real services and Dask clusters started and killed,
# deadlines and CPU measured) run at normal priority, one at a time, while the rest (the
# parallel run, then the fuzz) runs beside them at the lowest priority (nice 19): the timed
# tests get the CPU whenever they ask for it, and the rest fills the time they spend waiting.
# The cluster tests' output comes first, then the rest's.
test: $(STAMP) chromium kernels
	$(BIN)/python -m ruff check app kinematics planning web kinoplan tests benchmarks tools
	@log=$$(mktemp); \
	nice -n 19 $(MAKE) --no-print-directory test-rest >$$log 2>&1 & rest=$$!; \
	$(BIN)/python -m pytest -q -p no:xdist --durations=10 -m cluster --ignore=$(FUZZ); a=$$?; \
	wait $$rest; b=$$?; cat $$log; rm -f $$log; exit $$((a | b))

# Every test but the cluster ones (part of `make test`).
test-rest: $(STAMP)
	$(BIN)/python -m pytest -q -n 2 --dist loadfile --durations=25 -m "not cluster" \
		--ignore=$(FUZZ)
	@log=$$(mktemp); KINOPLAN_FUZZ_SHARD=1/2 $(FUZZ_HALF) >$$log 2>&1 & \
	KINOPLAN_FUZZ_SHARD=0/2 $(FUZZ_HALF); a=$$?; wait $$!; b=$$?; \
	cat $$log; rm -f $$log; exit $$((a | b))

test-fast: $(STAMP) kernels
	$(BIN)/python -m ruff check app kinematics planning web kinoplan tests benchmarks tools
	$(BIN)/python -m pytest -q -n 2 --dist loadfile --durations=10 -m "$(FAST)" --ignore=$(FUZZ)

lint: $(STAMP)
	$(BIN)/python -m ruff check app kinematics planning web kinoplan tests benchmarks tools

# The long fuzz of the whole API (tools/fuzz.py: about 5 minutes on 2 cores): fails on any
# 5xx or answer off its response schema, or if fewer than 2,000 requests were sent.
fuzz: $(STAMP)
	$(BIN)/python tools/fuzz.py

bench: $(STAMP)
	$(BIN)/pip install --quiet -e ".[test,bench]"
	$(BIN)/python benchmarks/bench_glt_kinematics.py

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache
