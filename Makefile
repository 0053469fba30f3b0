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

test: install-dev
	@$(VENV)/bin/python -m pytest $(PYTEST_ARGS)

test-fast: install-dev
	@$(VENV)/bin/python -m pytest -m "not integration and not browser and not slow" $(PYTEST_ARGS)

# the documentation site into site/ (strict: a broken link or reference fails the build)
docs: install-dev
	@NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict

clean:
	rm -rf $(VENV) build site
