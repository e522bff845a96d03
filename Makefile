# Fresh clone: `make run` or `make test` create .venv and install on first use.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: install run test lint bench clean chromium fuzz

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e ".[test]"
	touch $(STAMP)

install: $(STAMP)

run: $(STAMP)
	$(BIN)/python -m app

# The browser test drives Debian's Chromium (not Playwright's download); CI runs as root.
chromium:
	@command -v chromium >/dev/null 2>&1 || (apt-get update && apt-get install -y chromium)

test: $(STAMP) chromium
	$(BIN)/python -m ruff check app kinematics planning web tests benchmarks tools
	$(BIN)/python -m pytest -q

lint: $(STAMP)
	$(BIN)/python -m ruff check app kinematics planning web tests benchmarks tools

# The long fuzz of the whole API (tools/fuzz.py: about 5 minutes on 2 cores): fails on any
# 5xx or answer off its response schema, or if fewer than 2,000 requests were sent.
fuzz: $(STAMP)
	$(BIN)/python tools/fuzz.py

bench: $(STAMP)
	$(BIN)/pip install --quiet -e ".[test,bench]"
	$(BIN)/python benchmarks/bench_glt_kinematics.py

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache
