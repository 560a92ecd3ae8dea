# make demo  — set up .venv if needed, run the default scene on 2 MPI ranks
# make test  — set up .venv if needed, run the test suite
# make bench — every benchmark and study, then demos/RESULTS.md (demos/run_bench.py, about 2 hours)
SHELL := /bin/bash
VENV  ?= .venv
PY    := $(VENV)/bin/python
NP    ?= 2
SCENE ?= configs/signorini_free_boundary.yaml

.PHONY: demo test bench venv clean

venv: $(VENV)/.installed

$(VENV)/.installed: pyproject.toml
	@tools/find-python >/dev/null || exit 1
	@[ -x $(PY) ] || $$(tools/find-python) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	$(PY) -c "import contact, dolfinx; print('contact ready: DOLFINx', dolfinx.__version__)"
	@touch $@

demo: venv
	$(VENV)/bin/mpirun -n $(NP) $(VENV)/bin/contact run $(SCENE) -o results/demo

test: venv
	$(VENV)/bin/python -m pytest -q tests

bench: venv
	$(VENV)/bin/python demos/run_bench.py

clean:
	rm -rf results bench .pytest_cache
