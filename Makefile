# The two set-up commands: `make demo` and `make test`. Both build .venv when it is missing.
# `make docs` builds the documentation site into site/ (mkdocs.yml); `make results` writes docs/results.md from
# the record of measurements (benchmarks/results/*.jsonl, appended by any benchmark run with --record).
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test test-fast bench results docs clean

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[test,docs]"  # docs: tests/test_docs_site.py builds the site
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/chaser-bt rehearse trees/chase.yaml --scenario sitl/scenarios/chase.yaml --seed 1 --time-limit 120 --report out/demo --progress always

# One worker per core; a test file stays on one worker (its servers, ports and Ray clusters are its own).
test: $(STAMP)
	$(BIN)/python -m pytest -q -n auto --dist loadfile

test-fast: $(STAMP)
	$(BIN)/python -m pytest -q -m "not slow"

bench: $(STAMP)
	$(BIN)/python benchmarks/bench_sitl.py

# The results page: generated from benchmarks/results/*.jsonl, never edited (tools/results_page.py).
results: $(STAMP)
	$(BIN)/python tools/results_page.py

# Strict: a broken link, a missing anchor or page, or a reference that does not resolve fails the build.
# The reference pages (CLI, node catalogue, scenario keys, API) are generated during the build (tools/docs_site.py).
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/python -m mkdocs build --strict --site-dir site

clean:
	rm -rf $(VENV) build *.egg-info
