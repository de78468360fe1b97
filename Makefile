# fluxcal: the two newcomer commands.  Each creates .venv and installs what it needs on first use.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.fluxcal-installed
DOCS_STAMP := $(VENV)/.fluxcal-docs-installed

.PHONY: demo demo-full test lint bench docs wheel-check clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[test,lint,interop,plot,batch,zarr]"
	touch $(STAMP)

$(DOCS_STAMP): $(STAMP)
	$(BIN)/python -m pip install --quiet -e ".[docs]"
	touch $(DOCS_STAMP)

# a first run: a calibrated product, a quicklook and an HTML report per mission (seconds)
demo: $(STAMP)
	$(BIN)/fluxcal demo --out demo-output

# the full tour: fits, batch on Dask, cleaning, archive round trip (minutes)
demo-full: $(STAMP)
	$(BIN)/fluxcal demo --full --out demo-output-full

test: $(STAMP)
	OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 $(BIN)/python -m pytest -q -n 2

lint: $(STAMP)
	$(BIN)/ruff check src tests benchmarks

bench: $(STAMP)
	for b in benchmarks/*.py; do echo "== $$b"; $(BIN)/python $$b || exit 1; done

# the documentation site, warnings as errors (docs/conf.py; the API pages go to docs/api/)
docs: $(DOCS_STAMP)
	$(BIN)/sphinx-build -W --keep-going -b html docs docs/_build/html
	@echo "fluxcal: documentation in docs/_build/html/index.html"

# build the sdist and wheel from a clean clone, install the wheel (core, no extras) in a
# fresh venv, run `fluxcal --version` and a CDF-only edr2cdr; prints the installed size
wheel-check: $(STAMP)
	$(BIN)/python tools/wheel_check.py

clean:
	rm -rf $(VENV) demo-output demo-output-full docs/_build docs/api docs/gallery
