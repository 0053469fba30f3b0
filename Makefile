# RASPV-py. The two commands a user needs: `make demo` and `make test` (both install first).
VENV ?= .venv
PYTEST_ARGS ?=

.PHONY: install demo test test-fast docs clean

install:
	@tools/install.sh

demo: install
	@$(VENV)/bin/raspv demo

test: install
	@$(VENV)/bin/python -m pytest $(PYTEST_ARGS)

test-fast: install
	@$(VENV)/bin/python -m pytest -m "not integration and not browser and not slow" $(PYTEST_ARGS)

# the documentation site into site/ (strict: a broken link or reference fails the build)
docs: install
	@NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict

clean:
	rm -rf $(VENV) build site
