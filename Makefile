# relight: the two commands of the README, each creating its own virtual environment.
#   make run   -- the main job: the service on http://127.0.0.1:8000 with the sample maps loaded
#   make test  -- lint, type-check and the whole test suite (what CI runs)
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: run test lint typecheck pytest jstest bench system-deps clean wheel

# Debian packages the tests need: chromium (real-browser tests, never a downloaded browser), Mesa's EGL
# (headless moderngl), libllvm19 (Mitsuba 3's fast llvm_ad_rgb variant for the oracle test), filament's cmgen and
# postgresql (the service tests' real PostgreSQL, tests/service/postgres.py). Installed with apt when missing and we
# are root (CI is); otherwise say what is missing.
SYSTEM_PKGS := chromium libegl1 libegl-mesa0 libgl1-mesa-dri libllvm19 libfilament-tools postgresql
system-deps:
	@if [ ! -x /usr/bin/chromium ] || ! ldconfig -p | grep -q libEGL_mesa || ! ldconfig -p | grep -q libLLVM.so.19 \
	    || [ ! -x /usr/bin/cmgen ] || ! ls /usr/lib/postgresql/*/bin/initdb >/dev/null 2>&1; then \
	  if [ "$$(id -u)" = 0 ]; then \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $(SYSTEM_PKGS) >/dev/null; \
	  else echo "need root to apt-get install $(SYSTEM_PKGS)" >&2; exit 1; fi; \
	fi

web/node_modules/.installed: web/package.json web/package-lock.json
	npm ci --prefix web --no-audit --no-fund
	touch $@

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[dev]'
	touch $(STAMP)

run: $(STAMP) web/node_modules/.installed
	$(BIN)/relight serve --host 127.0.0.1 --port 8000 --data .relight-data

# mypy and import-linter read the installed layout (relight.server from server/, ...): tools/pkgview.py links it
# under build/pkgview. lint-imports checks the layering contracts of pyproject.toml [tool.importlinter].
# eslint (web/eslint.config.js) lints the viewer and its unit tests. lint includes typecheck (mypy --strict on every
# package), so that `make lint` is the whole static check.
lint: $(STAMP) web/node_modules/.installed typecheck
	$(BIN)/ruff check relight server worker client contract tests bench tools
	$(BIN)/python tools/pkgview.py build/pkgview >/dev/null
	cd build/pkgview && PYTHONPATH=. ../../$(BIN)/lint-imports --no-cache ../../pyproject.toml
	cd web && node_modules/.bin/eslint src test eslint.config.js packages/relight-three/src packages/relight-three/test packages/relight-three/scripts

typecheck: $(STAMP)
	$(BIN)/python tools/pkgview.py build/pkgview >/dev/null
	cd build/pkgview && ../../$(BIN)/mypy --config-file ../../pyproject.toml -p relight

# A self-contained wheel (viewer, shaders, three.js, sample data as package data) in build/dist.
wheel: $(STAMP) web/node_modules/.installed
	$(BIN)/pip wheel --no-deps --quiet --wheel-dir build/dist .

jstest: web/node_modules/.installed
	node --test web/test/

pytest: $(STAMP) system-deps web/node_modules/.installed
	$(BIN)/python -m pytest -q --timeout=900

test: lint typecheck pytest  # pytest also runs the JavaScript unit tests (tests/web/test_js_units.py)

bench: $(STAMP) web/node_modules/.installed
	$(BIN)/python bench/table4.py
	$(BIN)/python bench/table5.py
	$(BIN)/python bench/service.py
	$(BIN)/python bench/viewer.py
	$(BIN)/python bench/startup.py
	$(BIN)/python bench/blas_threads.py

clean:
	rm -rf $(VENV) out .pytest_cache .mypy_cache .ruff_cache web/node_modules
