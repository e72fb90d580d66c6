# Two commands set up and run everything: `make demo` and `make test`.
# Each creates the virtual environment .venv when it is missing.
PYTHON ?= python3.11
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: demo test test-fast fuzz lint bench reproduce screenshots clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

# Reinstall only when the project's dependencies change.
$(STAMP): pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/beambench demo --out demo-out

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy
	$(BIN)/lint-imports

# pytest exits 5 when it collected no tests: a broken suite, not a pass; say so.
test: lint
	@$(BIN)/python -m pytest -q; rc=$$?; \
	if [ $$rc -eq 5 ]; then echo "error: pytest collected no tests" >&2; fi; exit $$rc

# The fuzz suite (tests/fuzz) runs in `make test` with 40 cases a category (160 rig files);
# this runs it with FUZZ_CASES a category (4x that many rig files) and prints the counts.
FUZZ_CASES ?= 1000
fuzz: $(STAMP)
	BEAMBENCH_FUZZ_CASES=$(FUZZ_CASES) $(BIN)/python -m pytest -q -s -p no:cacheprovider tests/fuzz

test-fast: $(STAMP)
	$(BIN)/python -m pytest -q -m "not slow"

bench: $(STAMP)
	$(BIN)/beambench bench sim
	$(BIN)/beambench bench vision
	$(BIN)/beambench bench daq

# The README's pictures of the Rerun review (needs Debian's chromium).
screenshots: $(STAMP)
	$(BIN)/python sample_data/screenshots.py demo-out

reproduce: $(STAMP)
	$(BIN)/beambench reproduce --out reproduce-out

clean:
	rm -rf $(VENV) demo-out reproduce-out .pytest_cache .mypy_cache .ruff_cache
