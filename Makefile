# The two commands a newcomer needs: `make run` and `make test`.
# Both create .venv on first use and (re)install the project with its test
# extra only when pyproject.toml changed, so the second call starts fast.

PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: run test lint install clean browser-deps

# compileall: the package's bytecode, so the TUI starts without compiling its
# modules (an editable install never writes it, nor Python under
# PYTHONDONTWRITEBYTECODE; 0.1 s of the first frame); only changed files are redone.
run: $(STAMP)
	$(BIN)/python -m compileall -q quadtank_tui
	$(BIN)/quadtank

# The suite, one pytest session on every core (pytest-xdist: `-n auto` is a worker a
# core and one more, none on a single core), in two phases (docs/development.md): the
# tests off the wall clock, then the `wallclock` tests among themselves (they mostly
# wait; tests/conftest.py holds them back until the first phase is over); a test
# marked `alone` (a bound another test beside it would miss) runs with none beside it.
test: $(STAMP)
	$(BIN)/python -m pytest -n auto --durations=30

# Errors (ruff), types (mypy, pyproject's options: the package, its tests and the
# benchmarks; then each folder's conftest.py alone, as they are all named `conftest`),
# the layer contract (import-linter).
lint: $(STAMP)
	$(BIN)/ruff check quadtank_tui tests benchmarks
	$(BIN)/mypy
	for conftest in tests/conftest.py tests/*/conftest.py; do $(BIN)/mypy $$conftest || exit 1; done
	$(BIN)/lint-imports

install: $(STAMP)

# What tests/serve needs beyond Python (Debian's packages, installed only where
# missing and only as root; elsewhere those tests skip and say why): headless
# Chromium and its driver for the browser test, acl (setfacl) for test users to
# reach an interpreter kept under /root.
BROWSER_DEBS := chromium chromium-driver acl
browser-deps:
	@missing=""; for p in $(BROWSER_DEBS); do dpkg -s $$p >/dev/null 2>&1 || missing="$$missing $$p"; done; \
	if [ -z "$$missing" ]; then exit 0; fi; \
	if [ "$$(id -u)" != 0 ] || ! command -v apt-get >/dev/null; then \
	  echo "browser-deps:$$missing missing (needs root and apt-get): tests/serve's browser test will skip"; exit 0; fi; \
	apt-get update -q >/dev/null && DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends $$missing >/dev/null \
	  || echo "browser-deps: could not install$$missing: tests/serve's browser test will skip"

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test,lint]'
	$(BIN)/python -m compileall -q quadtank_tui
	touch $(STAMP)

clean:
	rm -rf $(VENV) build *.egg-info
