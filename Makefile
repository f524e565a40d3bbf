# ins-cosim: every command sets itself up from nothing (Python 3.11, gcc, make).
PYTHON ?= python3.11
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
FMUDIR := fmus/build
MODEL_SOURCES := $(wildcard models/*.py) $(wildcard models/native/*.py) $(wildcard models/native/*.[ch]) \
	cosim/interop/packaging.py

.PHONY: all setup native fmus demo test test-slow bench bench-slow lint format clean

all: test

# Fall back to python3 when python3.11 is not on PATH under that name.
$(STAMP): pyproject.toml
	@command -v $(PYTHON) >/dev/null 2>&1 || { echo "using python3 ($$(python3 --version))"; }
	@test -x $(PY) || { command -v $(PYTHON) >/dev/null 2>&1 && $(PYTHON) -m venv $(VENV) || python3 -m venv $(VENV); }
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	@touch $(STAMP)

setup: $(STAMP) native

# The models' compiled step kernels (models/native/build/kernels-<hash>.so, gcc); a no-op
# when the library of the current source exists. Without gcc the models run numpy.
native: $(STAMP)
	$(PY) -m cosim.models.native

$(FMUDIR)/.built: $(STAMP) $(MODEL_SOURCES) | native
	$(VENV)/bin/ins-cosim fmus --build --dir $(FMUDIR)
	@touch $@

fmus: $(FMUDIR)/.built

# The main job: verify the seed 003 north-finding requirements over a 20-run campaign and
# write the report (a violated or undecided verdict, exit 1 or 2, is a result, not a failure).
demo: fmus
	$(VENV)/bin/ins-cosim run scenarios/demo.toml --out out/demo
	$(VENV)/bin/ins-cosim run scenarios/demo.toml --fmu-dir $(FMUDIR) --out out/demo_fmu --no-plot
	$(VENV)/bin/ins-cosim verify scenarios/sins_north_finding.toml --runs 20 \
		--report out/demo/verification --no-progress; test $$? -le 2
	@echo "demo: out/demo/results.{csv,json,png} and out/demo/verification/report.html"

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

lint: $(STAMP)
	$(VENV)/bin/ruff check cosim models tests benchmarks
	$(VENV)/bin/ruff format --check cosim models tests benchmarks

format: $(STAMP)
	$(VENV)/bin/ruff format cosim models tests benchmarks
	$(VENV)/bin/ruff check --fix cosim models tests benchmarks

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
