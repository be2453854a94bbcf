# Two commands for a newcomer (see README):  make quickstart   and   make test
# Both set up everything they need first: Debian packages, a .venv at the repository root, the package.

PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
export MUJOCO_GL ?= osmesa
export PYOPENGL_PLATFORM ?= osmesa
export PYNPUT_BACKEND ?= dummy

.PHONY: setup quickstart test lint bench

setup: $(STAMP)

$(STAMP): setup.py
	bash scripts/install_system_deps.sh
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	# torch 2.13.0 is the CPU wheel; torchvision 0.28.0 is the release made beside it
	$(BIN)/pip install -q torch==2.13.0 torchvision==0.28.0
	# extras: ray (--ray, tests/test_ray.py), humanoid (robosuite-models, the Unitree G1, tests/test_g1.py)
	$(BIN)/pip install -q -e ".[test,ray,humanoid]"
	if [ -f tests/browser/package.json ]; then (cd tests/browser && npm ci --no-audit --no-fund); fi
	touch $(STAMP)

quickstart: setup
	$(BIN)/veragmil-quickstart

test: setup
	$(BIN)/ruff check veragmil_suite tests scripts
	$(BIN)/ruff format --check veragmil_suite tests scripts
	$(BIN)/python -m pytest -q -n 2 -m "not realtime" tests
	$(BIN)/python -m pytest -q -m realtime tests

lint: setup
	$(BIN)/ruff check veragmil_suite tests scripts
	$(BIN)/ruff format --check veragmil_suite tests scripts

bench: setup
	$(BIN)/python -m veragmil_suite.bench
