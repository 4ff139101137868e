# Set-up is part of every target: a fresh clone needs only `make run` / `make test`.
# PETSc (petsc4py in the wheel dolfinx-solver-real, the iterative contact method) needs Python >= 3.12:
# the first of python3.13, python3.12, python3 and pyenv's installed versions that is at least 3.12.
PYTHON ?= $(shell for p in python3.13 python3.12 python3 $$HOME/.pyenv/versions/3.1[2-9]*/bin/python3; do \
  command -v $$p >/dev/null 2>&1 && $$p -c 'import sys; sys.exit(sys.version_info < (3, 12))' 2>/dev/null \
  && { echo $$p; break; }; done)
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
STUDY  ?= studies/tunnel-fault.yaml
NAME   := $(basename $(notdir $(STUDY)))

.PHONY: run test validate bench clean

$(STAMP): pyproject.toml
	@test -n "$(PYTHON)" || { echo "wcs needs Python >= 3.12 (python3.12 or python3.13 on PATH, or make PYTHON=/path/to/python3.12)"; exit 2; }
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

# The tunnel study end to end, started afresh (--fresh: an earlier run of it is discarded): search, HTML report, figures of the fault
# and of the stresses at the tunnel. `make run STUDY=studies/knee-replacement.yaml` runs another.
run: $(STAMP)
	@mkdir -p results
	$(VENV)/bin/wcs run $(STUDY) -o results/$(NAME).nc --fresh
	$(VENV)/bin/wcs report results/$(NAME).nc -o results/$(NAME).html
	@if [ "$(NAME)" = "tunnel-fault" ]; then $(PY) studies/figures.py results/$(NAME).nc -o results; fi
	@echo
	@echo "results: $(CURDIR)/results/$(NAME).nc   (NetCDF: x, phi, status, worst_value, worst_x, fields)"
	@echo "report:  $(CURDIR)/results/$(NAME).html (open in a browser)"
	@if [ "$(NAME)" = "tunnel-fault" ]; then \
	  echo "figures: $(CURDIR)/results/tunnel-slip.png $(CURDIR)/results/tunnel-stress.png"; fi

# Two workers (pytest-xdist), one per core: every test is independent (its own tmp_path, one BLAS
# thread a process); the suite took 4 min 25 s in one process on the 2-core machine, 2 min 12 s so.
test: $(STAMP)
	$(PY) -m pytest -m "not slow and not bench" -q -n 2

# Every study run at a small budget, the tunnel's qualitative picture, the report in Chromium.
validate: $(STAMP)
	$(PY) -m pytest -m slow -q

bench: $(STAMP)
	$(PY) -m pytest tests/bench -m bench -q -s

clean:
	rm -rf $(VENV) build *.egg-info
