# ins-cosim: every command sets itself up from nothing (Python 3.11, gcc, make).
PYTHON ?= python3.11
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
FMUDIR := fmus/build
MODEL_SOURCES := $(wildcard models/*.py) $(wildcard models/blocks/*.py) $(wildcard models/native/*.py) \
	$(wildcard models/*.h) $(wildcard models/blocks/*.c) $(wildcard models/native/*.h) $(wildcard cosim/alignment/*.c) \
	cosim/interop/packaging.py

.PHONY: all setup native fmus demo test test-slow bench bench-slow lint check format clean

all: test

# Fall back to python3 when python3.11 is not on PATH under that name.
$(STAMP): pyproject.toml
	@command -v $(PYTHON) >/dev/null 2>&1 || { echo "using python3 ($$(python3 --version))"; }
	@test -x $(PY) || { command -v $(PYTHON) >/dev/null 2>&1 && $(PYTHON) -m venv $(VENV) || python3 -m venv $(VENV); }
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	@touch $(STAMP)

setup: $(STAMP) native

# The compiled kernels of models/native's table (models/native/build/kernels-<hash>.so); a no-op
# when the library of the current source exists. Without gcc the models run numpy.
native: $(STAMP)
	$(PY) -m cosim.models.native

$(FMUDIR)/.built: $(STAMP) $(MODEL_SOURCES) | native
	$(VENV)/bin/ins-cosim fmus --build --dir $(FMUDIR)
	@touch $@

fmus: $(FMUDIR)/.built

# The main job: one run in-process and from the FMUs, then a campaign that decides: the
# north-finding requirements of demo_north_finding.toml judged at 20, 40 and 80 runs until
# every verdict is decided (exit 0: all satisfied; docs/design.md, "The main job decides"). DEMO_VERIFY is the
# command alone (tests/integration/test_ci.py runs it).
DEMO_VERIFY = $(VENV)/bin/ins-cosim verify scenarios/demo_north_finding.toml --until-decided \
	--max-runs 80 --workers 2 --report out/demo/verification --no-progress

demo: fmus
	$(VENV)/bin/ins-cosim run scenarios/demo.toml --out out/demo
	$(VENV)/bin/ins-cosim run scenarios/demo.toml --fmu-dir $(FMUDIR) --out out/demo_fmu --no-plot
	rm -rf out/demo/verification
	$(DEMO_VERIFY)
	@echo "demo: out/demo/results.{csv,json,png}; the verification report:"
	@echo "      $(CURDIR)/out/demo/verification/report.html"

# The suite runs on every core (pytest-xdist, tests handed out as workers free up);
# TEST_JOBS=0 runs it in this one process.
TEST_JOBS ?= auto

test: fmus
	$(VENV)/bin/pytest -n $(TEST_JOBS) --dist worksteal

test-slow: fmus
	$(VENV)/bin/pytest -n $(TEST_JOBS) --dist worksteal -m slow

bench: fmus
	$(PY) -m benchmarks

# A 1000-run transfer-alignment campaign on 2 workers, and the characterisation of a
# generated 24-hour 200 Hz log (minutes each; not in bench's table).
bench-slow: fmus
	$(PY) -m benchmarks.bench_campaign_slow
	$(PY) -m benchmarks.bench_characterize_slow

# What CI checks before the tests (.ci/check): ruff check, ruff format --check, mypy.
lint: $(STAMP)
	.ci/check

check: lint

format: $(STAMP)
	$(VENV)/bin/ruff format cosim models tests benchmarks tools
	$(VENV)/bin/ruff check --fix cosim models tests benchmarks tools

# The documentation site (mkdocs.yml): first the generated pages, models/docs/<Model>.md and
# docs/filters/<Filter>.md, from the blocks' own docstrings and declarations (run after
# changing a model's or a filter's parameters), then the site, built strictly (a broken link
# or a page missing from the nav fails) into site/.
.PHONY: docs
docs: $(STAMP)
	$(PY) -m cosim.interop.modeldocs
	$(PY) -m cosim.interop.filterdocs
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict --site-dir site

clean:
	rm -rf $(FMUDIR) out site .pytest_cache
