# The two commands of the README:
#   make demo   set up .venv (first time), then simulate, identify_icr and compare odometry
#   make test   set up .venv (first time) and run the whole test suite
# make stress [RUNS=2 STOPS=40]: the suite RUNS times beside RUNS busy loops, then random stops
# .ci/run calls `make test`.

PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: setup demo test bench stress clean

setup: $(STAMP)

$(STAMP): requirements.txt requirements-test.txt setup.py setup.cfg package.xml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet --no-compile -r requirements.txt -r requirements-test.txt
	$(PY) -m pip install --quiet --no-deps --no-build-isolation -e .
	touch $(STAMP)

demo: setup
	env -u PYTHONDONTWRITEBYTECODE $(VENV)/bin/tracked_kinematics_demo

# Three workers on two cores, each test file whole on one (its module fixtures built once):
# a fifth of the suite's time is ROS tests waiting on other processes, which a third worker
# fills (a fresh clone: 6.8 min with the set-up, 8.5 min with two). Every test holds a ROS
# domain of its own across processes. The suite starts some 150 Python processes (console
# scripts, nodes): with PYTHONDONTWRITEBYTECODE set (as on some CI images) each compiled
# the package anew, 0.4 s of its 1 s of imports, and each worker rewrote every test module;
# the suite writes its bytecode caches (__pycache__, ignored by git) whatever the caller set.
# pip installs without compiling (--no-compile: 20 of its 44 s); the first process to import a
# module writes its cache, so only the modules the package uses are ever compiled.
test: setup
	env -u PYTHONDONTWRITEBYTECODE $(PY) -m pytest -n 3 --dist loadfile

stress: setup
	$(PY) tools/stress.py --runs $(or $(RUNS),2) --stops $(or $(STOPS),40)

bench: setup
	for script in benchmarks/bench_*.py; do $(PY) $$script || exit 1; done

clean:
	rm -rf $(VENV) build install log *.egg-info demo_output
