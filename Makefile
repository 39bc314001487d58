# relight: the two commands of the README, each creating its own virtual environment.
#   make run   -- the main job
#   make test  -- lint, type-check and the whole test suite (what CI runs)
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: run test lint typecheck pytest bench clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[dev]'
	touch $(STAMP)

run: $(STAMP)
	$(BIN)/relight prefilter data/envmaps/city.exr --brdf phong:s=64 --epsilon 0.001 --out out/city_phong64.exr --report out/city_phong64.json

lint: $(STAMP)
	$(BIN)/ruff check relight tests bench

typecheck: $(STAMP)
	$(BIN)/mypy relight

pytest: $(STAMP)
	$(BIN)/python -m pytest -q --timeout=900

test: lint typecheck pytest

bench: $(STAMP)
	$(BIN)/python bench/table4.py

clean:
	rm -rf $(VENV) out .pytest_cache .mypy_cache .ruff_cache
