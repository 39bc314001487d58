# relight: the two commands of the README, each creating its own virtual environment.
#   make run   -- the main job: the service on http://127.0.0.1:8000 with the sample maps loaded
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
	$(BIN)/relight serve --host 127.0.0.1 --port 8000 --data .relight-data

lint: $(STAMP)
	$(BIN)/ruff check relight server worker client tests bench

typecheck: $(STAMP)
	$(BIN)/mypy relight server worker client

pytest: $(STAMP)
	$(BIN)/python -m pytest -q --timeout=900

test: lint typecheck pytest

bench: $(STAMP)
	$(BIN)/python bench/table4.py

clean:
	rm -rf $(VENV) out .pytest_cache .mypy_cache .ruff_cache
