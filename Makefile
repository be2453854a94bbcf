# Two commands for a newcomer (see README):  make quickstart   and   make test
# Both set up everything they need first: Debian packages, a .venv at the repository root, the package.

PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
export MUJOCO_GL ?= osmesa
export PYOPENGL_PLATFORM ?= osmesa
export PYNPUT_BACKEND ?= dummy

SETUP_LOG := $(CURDIR)/build/setup.log
export SETUP_LOG
QUIETLY := bash scripts/quietly.sh $(SETUP_LOG)
TEST_STAMP := $(VENV)/.test-installed

.PHONY: setup test-setup quickstart test lint bench

setup: $(STAMP)

# Each step's output goes to $(SETUP_LOG), shown only when the step fails. torch 2.13.0 is the CPU wheel;
# torchvision 0.28.0 is the release made beside it. Extras: ray (--ray of veragmil-collect, -evaluate, -study;
# tests/test_ray.py), humanoid (robosuite-models, the Unitree G1; tests/test_g1.py), lerobot (veragmil-export-lerobot;
# tests/test_lerobot_export.py). veragmil_suite.private_macros writes robosuite's and robomimic's private macros.
$(STAMP): setup.py
	@echo "setting up: Debian packages, $(VENV), the package and its extras (once; log: $(SETUP_LOG))"
	@bash scripts/install_system_deps.sh
	@$(QUIETLY) $(PYTHON) -m venv $(VENV)
	@$(QUIETLY) $(BIN)/pip install --upgrade pip
	@$(QUIETLY) $(BIN)/pip install torch==2.13.0 torchvision==0.28.0
	@$(QUIETLY) $(BIN)/pip install -e ".[test,ray,humanoid,lerobot]"
	@$(QUIETLY) $(BIN)/python -m veragmil_suite.private_macros
	@touch $(STAMP)

# What only the tests need: FFmpeg's libraries (torchcodec reads the LeRobot export's videos), and Chromium with
# the browser test's npm packages (tests/browser/setup.sh)
test-setup: $(TEST_STAMP)

$(TEST_STAMP): $(STAMP) tests/browser/package-lock.json
	@echo "setting up the tests: FFmpeg's libraries, Chromium, the browser test's npm packages (log: $(SETUP_LOG))"
	@bash scripts/install_system_deps.sh --test
	@bash tests/browser/setup.sh
	@touch $(TEST_STAMP)

quickstart: setup
	@$(BIN)/veragmil-quickstart

# A test (its fixtures included) that runs past this fails with its stack printed and the run goes on; the slowest
# took 244 s beside the other worker's tests
TEST_TIMEOUT_S ?= 600

# The real-time tests (VR device, server, browser: latencies and timeouts) run at normal priority while the rest run
# in two xdist workers under SCHED_IDLE, which take only the CPU the real-time tests leave idle (they wait on sockets
# and clocks most of the time); the real-time tests' report is printed after the rest's.
REALTIME_LOG := build/realtime-tests.log

test: test-setup lint
	@mkdir -p build
	$(BIN)/python -m pytest -q -m realtime --timeout $(TEST_TIMEOUT_S) --durations 10 tests > $(REALTIME_LOG) 2>&1 & realtime_pid=$$!; \
	chrt --idle 0 $(BIN)/python -m pytest -q -n 2 --dist loadgroup -m "not realtime" --timeout $(TEST_TIMEOUT_S) \
		--durations 10 tests; rest=$$?; \
	wait $$realtime_pid; realtime=$$?; echo "real-time tests (run beside the rest):"; cat $(REALTIME_LOG); \
	exit $$(( rest || realtime ))

# The whole tree: the package, tests, scripts, benchmarks, the results folders' probes and the docs' Python blocks
lint: setup
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

bench: setup
	$(BIN)/python -m veragmil_suite.scripts.bench
