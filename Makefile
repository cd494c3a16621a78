# The two quick-start commands: `make run` (train a built-in problem on CPU) and `make test`
# (a headless Chromium for the explorer's browser test where it can be installed, lint, then the
# default test suite on two workers, one torch thread each, with Python's bytecode cache on;
# .ci/run calls it).
.PHONY: run test test-slow bench venv clean

VENV := .venv
GINN := $(VENV)/bin/ginn
PYTEST := $(VENV)/bin/python -m pytest

venv:
	@bash scripts/setup-venv.sh

run: venv
	$(GINN) train obstacle --preset demo

test: venv
	@bash scripts/setup-browser.sh
	$(VENV)/bin/ruff check src tests benchmarks scripts
	OMP_NUM_THREADS=1 PYTHONDONTWRITEBYTECODE= $(PYTEST) -q -m "not slow" -n 2 --dist worksteal

test-slow: venv
	$(PYTEST) -m slow -q -p no:cacheprovider

bench: venv
	$(VENV)/bin/python benchmarks/derivatives.py

clean:
	rm -rf $(VENV) runs .pytest_cache
