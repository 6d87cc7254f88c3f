# The whole set-up on a fresh machine is `make demo` or `make test`.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
OUT ?= out/paper

.PHONY: demo test test-fast install install-test browser bench clean docs wheel

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

# the core only: `delayform paper` needs no extra (tests/test_core_install.py runs the commands without them)
$(VENV)/.installed: $(BIN)/python pyproject.toml
	$(BIN)/python -m pip install --quiet -e .
	touch $@

# the test extra brings the core and every extra (all), so make test tests everything: one pip call
# (one resolution, no core install first), and --no-compile: the thousands of modules of the extras
# (Plotly's validators) are not byte-compiled ahead; Python compiles what a test imports, once
$(VENV)/.installed-test: $(BIN)/python pyproject.toml
	$(BIN)/python -m pip install --quiet --no-compile -e ".[test]"
	touch $(VENV)/.installed $@

install: $(VENV)/.installed

install-test: $(VENV)/.installed-test

# Headless Chromium (and a font for its text) for tests/test_report_browser.py and
# tests/test_explorer_browser.py; the latter drives it with Playwright's Python package
# (the `test` extra) through executable_path, so no browser is ever downloaded.
# Installed only when missing, only as root and only where apt-get exists; otherwise
# those tests skip and say why.
browser:
	@command -v chromium >/dev/null 2>&1 || { \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium fonts-liberation >/dev/null) \
	      || echo "note: could not install chromium; the browser test will be skipped"; \
	  else echo "note: chromium missing and not installable here; the browser test will be skipped"; fi; }

demo: install
	$(BIN)/delayform paper --out $(OUT)

# across the cores (pytest-xdist; `make test PYTEST_WORKERS=0` runs in one process); tests/conftest.py
# starts the slow tests first so that no long one runs alone at the end, and groups the tests that
# share a module's fixture (a map, a design, a running explorer) so that one worker builds it once:
# loadgroup hands out one test (or group) at a time in that order (no reordering by group size).
# One worker per core: one more (3 on 2 cores) filled the fleet's and the browser's waits on the
# wall clock and ran the suite in 4 min 47 s instead of about 5.5 min, but then the fleet's
# processes lost the CPU often enough to bend what they measure (3 failed runs of 4, each a
# different fleet test), also with the other workers at niceness 10
PYTEST_WORKERS ?= auto
PYTEST_DIST := --dist loadgroup --no-loadscope-reorder
test: install-test browser
	$(BIN)/python -m pytest -q -n $(PYTEST_WORKERS) $(PYTEST_DIST) src tests

# the edit loop: everything but the tests marked slow (the wheel, the site, whole reports, long runs);
# `make test` still runs them all
test-fast: install-test
	$(BIN)/python -m pytest -q -n $(PYTEST_WORKERS) $(PYTEST_DIST) -m "not slow" src tests

# The documentation site (Sphinx + numpydoc + MyST-NB, docs/conf.py says why): warnings are errors,
# the tutorials in docs/tutorials/ are executed; tests/test_site.py runs the same build.
DOCS_OUT ?= out/docs
docs: install-test
	$(BIN)/python -m sphinx -b html -W --keep-going -q docs $(DOCS_OUT)
	@echo "docs: $(DOCS_OUT)/index.html"

# A wheel and sdist in dist/ (tests/test_wheel.py installs the wheel into a bare venv)
wheel: install-test
	$(BIN)/python -m build --outdir dist .

# the benchmarks time the explorer, Dask runs, MCAP export, the safety filter and python-control loops too
bench: install
	$(BIN)/python -m pip install --quiet -e ".[all,bench]"
	for f in benchmarks/bench_*.py; do $(BIN)/python $$f || exit 1; done

clean:
	rm -rf $(VENV) out .pytest_cache .hypothesis
