# Two commands do all the set-up: `make run` and `make test`.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: run test test-quick test-under-load fuzz lint bench clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[sim,hardware,dist,maps,gym,team,create3,mujoco,dev]'
	touch $(STAMP)

run: $(STAMP)
	$(PY) -m experiments.nav_fig3

# the suite runs on every core (pytest-xdist; TEST_WORKERS=0 runs it in one process)
TEST_WORKERS ?= auto

test: $(STAMP)
	$(PY) -m pytest -q -n $(TEST_WORKERS) --dist worksteal

test-quick: $(STAMP)
	$(PY) -m pytest -q -n $(TEST_WORKERS) --dist worksteal -m "not slow and not physics"

test-under-load: $(STAMP)
	bash tests/under_load.sh

# Random fuzzing of every entry point (tests/test_fuzz.py): FUZZ_EXAMPLES per entry point;
# each failing example with its traceback goes to results/fuzz/failures.txt; non-zero exit
# status when anything is found.
FUZZ_EXAMPLES ?= 10000
FUZZ_FAILURES := results/fuzz/failures.txt

fuzz: $(STAMP)
	mkdir -p results/fuzz && rm -f $(FUZZ_FAILURES)
	BOUNCESIM_FUZZ_PROFILE=fuzz BOUNCESIM_FUZZ_EXAMPLES=$(FUZZ_EXAMPLES) \
	BOUNCESIM_FUZZ_FAILURES=$(FUZZ_FAILURES) \
	$(PY) -m pytest -q tests/test_fuzz.py --hypothesis-show-statistics; status=$$?; \
	if [ -s $(FUZZ_FAILURES) ]; then echo "failing examples: $(FUZZ_FAILURES)"; \
	else echo "no failures in $(FUZZ_EXAMPLES) examples per entry point"; fi; exit $$status

lint: $(STAMP)
	$(VENV)/bin/ruff check .

bench: $(STAMP)
	$(PY) -m benchmarks.bench_navigation
	$(PY) -m benchmarks.bench_coverage
	$(PY) -m benchmarks.bench_twin
	$(PY) -m benchmarks.bench_pybullet
	$(PY) -m benchmarks.bench_models
	$(PY) -m benchmarks.bench_turn_load

clean:
	rm -rf $(VENV) build *.egg-info
