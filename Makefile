# Set-up is part of every target: a fresh clone needs only `make run` / `make test`.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
STUDY  ?= studies/heated-plate.yaml

.PHONY: run test validate bench clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

run: $(STAMP)
	$(VENV)/bin/wcs solve $(STUDY) -o results/nominal.nc

test: $(STAMP)
	$(PY) -m pytest -m "not slow and not bench" -q

validate: $(STAMP)
	$(PY) -m pytest -m slow -q

bench: $(STAMP)
	$(PY) -m pytest tests/bench -m bench -q -s

clean:
	rm -rf $(VENV) build *.egg-info
