# One command each: `make run` (the twin on its embedded default, in the browser viewer) and
# `make test` (the test suite). Both create .venv and install what they need.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
# pytest workers: 2 on CI's 2 cores; one module per worker, so a browser module starts one browser
WORKERS ?= 2

.PHONY: run test bench lint clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

# The acados extra vendors a slim casadi over the official one's files: reinstall the
# official wheel afterwards and check IPOPT is there (docs/psf.md).
CASADI ?= casadi==3.8.2
# `all` holds every extra (rl with the CPU torch, ray, sweep, test, acados): installing it
# also proves the extras resolve together.
$(VENV)/.installed-test: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[all]'
	$(BIN)/python -m pip install --quiet --force-reinstall --no-deps '$(CASADI)'
	$(BIN)/python -c "import casadi; assert casadi.has_nlpsol('ipopt'), 'casadi lost IPOPT'"
	touch $@

# The twin on its embedded default (Trondheim Fjord, synthetic AIS through the NMEA path,
# the synthetic weather fixture, los_psf), served to the browser viewer at the printed URL.
run: $(VENV)/.installed-test
	$(BIN)/asvtwin run

test: $(VENV)/.installed-test
	$(BIN)/python -m pytest -n $(WORKERS) --dist loadfile -q

bench: $(VENV)/.installed-test
	@for b in benchmarks/*.py; do echo "== $$b"; $(BIN)/python $$b; done

lint: $(VENV)/.installed-test
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	$(BIN)/ruff check asvtwin tests benchmarks tools
	$(BIN)/mypy asvtwin

clean:
	rm -rf $(VENV) out .pytest_cache
	find asvtwin -name '*.nbi' -o -name '*.nbc' | xargs rm -f
