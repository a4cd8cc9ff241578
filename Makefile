# Everything installs into ./.venv. torch==2.13.0 goes in first when torch is missing: on these machines it is a
# local CPU wheel, and letting pip resolve a bare `torch` would pull gigabytes of CUDA wheels.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
PIP := $(PY) -m pip
STAMP := $(VENV)/.installed
PORT ?= 8080

.PHONY: install demo test lint format browser stress bench paper screenshot aeon-golden clean

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PIP) install -q --upgrade pip
	$(PY) -c "import torch" 2>/dev/null || $(PIP) install -q torch==2.13.0
	$(PIP) install -q -e '.[dev]'
	touch $(STAMP)

install: $(STAMP)

# Debian's Chromium drives the browser tests (playwright's own browser download cannot work here).
browser:
	@command -v chromium >/dev/null 2>&1 || { \
	  if [ "$$(id -u)" = 0 ]; then apt-get update -q && apt-get install -y -q chromium; \
	  else echo "chromium missing and not root: browser tests will be skipped (sudo apt-get install chromium)"; fi; }

demo: install
	$(VENV)/bin/workbench demo --session demo-session --port $(PORT)

# two pytest workers on the two cores (each runs torch on one thread: tests/conftest.py); a test file runs on one
# worker, in order, so its module fixtures are made once and a module's last test sees what the others measured
test: install browser
	$(PY) -m ruff check .
	$(PY) -m ruff format --check .
	$(PY) -m pytest -n 2 --dist loadfile --no-loadscope-reorder -m "not slow"

lint: install
	$(PY) -m ruff check .
	$(PY) -m ruff format --check .

format: install
	$(PY) -m ruff check --fix .
	$(PY) -m ruff format .

# every promise of issue 7 at full length (200 server kills, the long hostile corpus with a 2 GB line, thousands of
# fuzz examples); ends with one summary line per promise; then the ML backend against a real Label Studio
stress: install browser
	WORKBENCH_FUZZ_EXAMPLES=5000 $(PY) -m pytest tests/safety -m "slow or not slow"
	$(PY) -m pytest tests/workbench/label_studio -m slow  # a real Label Studio, in its own environment

# every figure beside a reference measured in the same run; the table goes to benchmarks/results/speed.md (speed-$(DEVICE).md on another device)
DEVICE ?= cpu
bench: install
	for f in benchmarks/speed/bench_*.py; do $(PY) $$f --device $(DEVICE) || exit 1; done
	$(PY) benchmarks/speed/report.py $(DEVICE)

# the studies: paper-scale evaluation runs (about an hour each on 2 cores); raw outputs in benchmarks/results/raw/<question>/
paper: install
	$(PY) benchmarks/studies/paper_borealtc.py all
	$(PY) benchmarks/studies/interval_coverage.py
	for s in 1 2; do $(PY) benchmarks/studies/loop_borealtc.py spliced --motor-only --piece-s 5 30 --per-terrain 3 \
	  --seed $$s > benchmarks/results/raw/loop/borealtc-motor-spliced-s$$s-$$(date +%F).txt || exit 1; done

# the README's picture (docs/workbench.png), taken by the first-screen browser test
screenshot: install browser
	WORKBENCH_DOCS_SCREENSHOT=1 $(PY) -m pytest -q tests/browser/test_first_screen.py -k test_the_first_screen_is_drawn

# the numbers aeon's MiniRocket computes, that tests/training/test_rocket_transform.py checks ours against; in an
# environment of its own, since aeon 1.6 pins NumPy below the version the workbench runs
aeon-golden:
	test -x .venv-aeon/bin/python || $(PYTHON) -m venv .venv-aeon
	.venv-aeon/bin/python -m pip install -q aeon==1.6.0
	.venv-aeon/bin/python tests/training/golden/make_minirocket_golden.py

clean:
	rm -rf $(VENV) .venv-aeon demo-session test-artifacts .pytest_cache .ruff_cache
