# make demo  — set up .venv if needed, run the default scene on 2 MPI ranks
# make test  — set up .venv if needed, lint (below), run the test suite (JOBS=2 pytest-xdist
#              workers, a test file per worker at a time; JOBS=1: one process)
# make test-perturbed — the tests whose outcome hangs on Newton converging, as another CPU may
#              round them: once per run of PERTURBED (ε:seed:threads), the load perturbed by a
#              relative ε (CONTACT_TEST_PERTURB, tests/perturb) with OMP/OpenBLAS threads (CI)
# make test-perturbed-full — the same for the whole suite (docs/development.md)
# make lint  — ruff (lint, format) on contact/ tests/ demos/ docs/ and mypy on contact/ (pyproject.toml);
#              every variant of the C kernels compiled with -Wall -Wextra -Werror
#              (tools/check_kernels.py; again only when the sources or the compiler changed)
# make docs  — the documentation site into docs/_build/html (Sphinx; warnings are errors, the
#              demos executed at small sizes; docs/README.md)
# make bench — every benchmark and study, then demos/RESULTS.md (demos/run_bench.py, about 2 hours)
# make venv-latest — the newest release of every dependency in .venv-latest (test-latest: its tests)
# make lock  — after test-latest passed: .venv-latest's versions become constraints.txt
SHELL := /bin/bash
VENV  ?= .venv
PY    := $(VENV)/bin/python
LOCK  := constraints.txt
LATEST ?= .venv-latest
NP    ?= 2
SCENE ?= configs/signorini_free_boundary.yaml
JOBS  ?= 2
PYTEST = $(VENV)/bin/python -m pytest -q $(if $(filter 1,$(JOBS)),,-n $(JOBS) --dist loadfile)
# two perturbations of the load, each with its own seed and thread count (the plain suite
# runs with the libraries' default: as many OpenBLAS threads as cores)
PERTURBED ?= 1e-13:20261125:1 1e-12:7:2
# the tests whose outcome hangs on a Newton iteration converging: solvers, cycles, friction,
# stress scenes, load paths, finite strain, bodies, parallel agreement (make test-perturbed, CI;
# docs/development.md says why these)
PERTURBED_TESTS ?= $(addprefix tests/test_,$(addsuffix .py,\
  semismooth_newton newton_min_cycle ncp convergence polish linear_solvers stress_scenes \
  semicoercive friction friction_cycle friction_speed friction_estimator loadpath sequencing \
  energy_search hyperelastic current_contact bodies agreement baselines))

.PHONY: demo test test-perturbed test-perturbed-full lint docs bench venv venv-latest test-latest \
  lock clean

venv: $(VENV)/.installed

# the tested versions (constraints.txt): a change of it or of pyproject.toml re-installs
$(VENV)/.installed: pyproject.toml $(LOCK)
	@tools/find-python >/dev/null || exit 1
	@[ -x $(PY) ] || $$(tools/find-python) -m venv $(VENV)
	$(PY) -m pip install --quiet -c $(LOCK) pip
	$(PY) -m pip install --quiet -c $(LOCK) -e '.[test,docs]'
	$(PY) -c "import contact, dolfinx; print('contact ready: DOLFINx', dolfinx.__version__)"
	@touch $@

demo: venv
	$(VENV)/bin/mpirun -n $(NP) $(VENV)/bin/contact run $(SCENE) -o results/demo

test: venv lint
	$(PYTEST) tests

# $(call perturbed,TESTS): pytest on TESTS once per run of PERTURBED; every run goes to its
# end, and the target fails naming the runs that failed
perturbed = @failed=""; for run in $(PERTURBED); do \
	  IFS=: read -r eps seed threads <<< "$$run"; \
	  echo "== CONTACT_TEST_PERTURB=$$eps CONTACT_TEST_PERTURB_SEED=$$seed, $$threads thread(s)"; \
	  CONTACT_TEST_PERTURB=$$eps CONTACT_TEST_PERTURB_SEED=$$seed OMP_NUM_THREADS=$$threads \
	    OPENBLAS_NUM_THREADS=$$threads MKL_NUM_THREADS=$$threads $(PYTEST) $(1) \
	    || failed="$$failed $$run"; \
	done; \
	[ -z "$$failed" ] || { echo "$@: failed:$$failed" >&2; exit 1; }

test-perturbed: venv
	$(call perturbed,$(PERTURBED_TESTS))

test-perturbed-full: venv
	$(call perturbed,tests)

lint: venv
	$(VENV)/bin/ruff check contact tests demos docs/conf.py docs/paraview tools/check_kernels.py
	$(VENV)/bin/ruff format --check contact tests demos docs/conf.py docs/paraview tools/check_kernels.py
	$(VENV)/bin/mypy
	$(PY) tools/check_kernels.py --stamp $(VENV)/.kernels-checked

# the newest releases, in a venv of their own (never the tested .venv): upgrades are deliberate
venv-latest:
	@tools/find-python >/dev/null || exit 1
	rm -rf $(LATEST)
	$$(tools/find-python) -m venv $(LATEST)
	$(LATEST)/bin/python -m pip install --quiet --upgrade pip
	$(LATEST)/bin/python -m pip install --quiet --upgrade -e '.[test,docs]'
	$(LATEST)/bin/python -c "import contact, dolfinx; print('latest: DOLFINx', dolfinx.__version__)"
	@tools/lock $(LATEST) | diff <(grep -v '^#' $(LOCK)) <(grep -v '^#' -) \
	  && echo "same versions as $(LOCK)" || echo "(<: $(LOCK), >: $(LATEST))"

test-latest: venv-latest
	$(LATEST)/bin/python -m pytest -q tests

lock:
	@[ -x $(LATEST)/bin/python ] || { echo "make lock: no $(LATEST) (make test-latest)" >&2; exit 1; }
	tools/lock $(LATEST) > $(LOCK)

# -E: a fresh environment, so that every page is read and every warning shown; -n: nitpicky
# (every cross-reference must resolve); -W --keep-going: all warnings reported, then an error
docs: venv
	rm -rf docs/reference
	OMP_NUM_THREADS=1 $(VENV)/bin/sphinx-build -b html -E -n -W --keep-going docs docs/_build/html

bench: venv
	$(VENV)/bin/python demos/run_bench.py

clean:
	rm -rf results bench .pytest_cache docs/_build docs/reference docs/demos/generated docs/results.md
