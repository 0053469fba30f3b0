# RASPV-py. The two commands a user needs: `make demo` and `make test` (both install first).
# `make install` installs what the demo, graphs, recordings and experiments need; add extras with
# `make install EXTRAS="learn cameras cluster video foxglove"` (dev: all of them + the test tools; make test).
VENV ?= .venv
PYTEST_ARGS ?=
EXTRAS ?=
DEMO_ARGS ?=

.PHONY: install install-dev demo test test-fast docs clean

install:
	@tools/install.sh $(EXTRAS)

install-dev:
	@tools/install.sh dev

demo: install
	@$(VENV)/bin/raspv demo $(DEMO_ARGS)

# Every node process and CLI run of the suite reads its modules' bytecode, written on their first
# import (tools/install.sh installs with --no-compile). With PYTHONDONTWRITEBYTECODE=1 in the
# environment (containers often set it) none was ever written and every process compiled numpy,
# scipy, torch and the project from source again: twice a node's import CPU (spv 1.54 -> 0.71 s),
# three integration test files took 63-66 s of CPU instead of 35-37. The test targets let Python write it.
test: install-dev
	@PYTHONDONTWRITEBYTECODE= $(VENV)/bin/python -m pytest $(PYTEST_ARGS)

test-fast: install-dev
	@PYTHONDONTWRITEBYTECODE= $(VENV)/bin/python -m pytest -m "not integration and not browser and not slow" $(PYTEST_ARGS)

# the documentation site into site/ (strict: a broken link or reference fails the build)
docs: install-dev
	@NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict

clean:
	rm -rf $(VENV) build site
