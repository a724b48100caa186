# The README's two commands are `make reproduce` and `make test`.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: venv install reproduce test lint lab bench docs clean

venv: $(STAMP)

# `all` brings every extra (neural: torch==2.13.0, the CPU wheel; see docs/environment.md for CUDA).
$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[all,dev,benchmarks,browser,docs]'
	touch $(STAMP)

install: $(STAMP)

reproduce: $(STAMP)
	$(BIN)/sunlab reproduce $(ARGS)

test: $(STAMP)
	SUNLAB_QUICK=1 $(BIN)/python -m pytest --doctest-modules sunlab studies tests $(ARGS)

lint: $(STAMP)
	$(BIN)/ruff check sunlab tests benchmarks

lab: $(STAMP)
	$(BIN)/python -m pip install --quiet jupyterlab
	$(BIN)/jupyter lab notebooks

# The site in docs/_build/html: every notebook executed on the small settings, warnings as errors.
docs: $(STAMP)
	SUNLAB_QUICK=1 SUNLAB_DOCS_EXECUTE=force $(BIN)/python -m sphinx -b html -n -W --keep-going \
		docs docs/_build/html

bench: $(STAMP)
	for b in benchmarks/bench_*.py; do $(BIN)/python $$b || exit 1; done

clean:
	rm -rf $(VENV) results .pytest_cache docs/_build docs/api
