# Two commands for users: `make run` (the main job) and `make test` (every test).
# Both set the workspace up first; setup is idempotent and quick when nothing changed.
SHELL := /bin/bash
.SHELLFLAGS := -o pipefail -ec
PYTHON ?= python3
VENV := .venv
ENV := ./env.sh
SETUP_STAMP := $(VENV)/.requirements-stamp
BUILD_STAMP := install/.build-stamp
PKG_FILES := $(shell find src -name package.xml -o -name setup.py -o -name setup.cfg 2>/dev/null)

.PHONY: setup build test lint colcon-test system-test run clean

setup: $(SETUP_STAMP) $(BUILD_STAMP) $(ENV)

ifeq ($(STNS_SYSTEM_ROS),1)
# docker/: ROS from /opt/ros/jazzy, the other packages installed by the Dockerfile.
RUFF := ruff
$(SETUP_STAMP):
	mkdir -p $(VENV) && touch $@
else
RUFF := $(VENV)/bin/ruff
$(SETUP_STAMP): requirements.txt constraints.txt
	@$(PYTHON) -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else "Python 3.11+ is needed, found " + sys.version)'
	test -x $(VENV)/bin/python || $(PYTHON) -m venv $(VENV)
	$(VENV)/bin/python -m pip install --quiet --disable-pip-version-check -r requirements.txt -c constraints.txt
	touch $@
endif

$(ENV): scripts/make_env.sh
	STNS_SYSTEM_ROS=$(STNS_SYSTEM_ROS) bash scripts/make_env.sh > $@.tmp && mv $@.tmp $@

# colcon with --symlink-install: edits to Python sources need no rebuild;
# new entry points or package files do (tracked by PKG_FILES).
$(BUILD_STAMP): $(SETUP_STAMP) $(PKG_FILES) colcon.meta $(ENV)
	source $(ENV) && colcon build --symlink-install --event-handlers console_stderr- 2>&1 | tail -n 3
	touch $@

build: setup

lint: setup
	$(RUFF) check src test

colcon-test: setup
	source $(ENV) && colcon test --event-handlers console_direct- --return-code-on-test-failure ; rc=$$? ; \
	  colcon test-result --all --verbose ; rc2=$$? ; [ $$rc -eq 0 ] && [ $$rc2 -eq 0 ]
	@# every package must report real tests: a missing or empty result fails the run
	@for p in $$(ls src); do grep -qE '<testsuite[^>]* tests="[1-9]' build/$$p/pytest.xml 2>/dev/null \
	  || { echo "colcon test: no test results for package $$p" >&2; exit 1; }; done

system-test: setup
	source $(ENV) && python -m pytest -q test

test: lint colcon-test system-test

run: setup
	source $(ENV) && stns_bringup --config config/default.yaml --out runs/default

clean:
	rm -rf build install log $(ENV)
