# mechsim entry points. Everything runs from ./.venv, created and kept current by
# tools/bootstrap.py (a no-op in well under a second when nothing changed).

PYTHON3 ?= python3
VENV    := .venv
PROFILE := $(CURDIR)/src/mechsim/data/fastdds_loopback.xml
# Three workers on two cores: a third of the suite's time is spent waiting (DDS discovery,
# real-time runs, timeouts under test), which the third worker fills (cold suite 290 s against
# 253 s). The tests that expect a start refused give the graph check a long discovery window
# (MECHSIM_GRAPH_WAIT), which a conflict ends at once: a loaded machine's slow discovery made
# them fail with three workers before.
PYTEST_ARGS ?= -n 3

# A guard variable of the ros-wheels .pth (it re-execs python with LD_LIBRARY_PATH set): when
# inherited from another environment it would stop this venv's python from doing so.
unexport _ROS_WHEELS_BOOTSTRAP_COMPLETE

.PHONY: bootstrap test-tools run test lint bench

# The venv and mechsim in it: everything inside the checkout (no system package, no npm).
bootstrap:
	@$(PYTHON3) tools/bootstrap.py

# What only the tests need, also inside the checkout: Foxglove's decoders (npm), Debian's
# chromium unpacked under .cache/test-tools (apt-get download, no root), the ros2 command and
# colcon; each skipped where it cannot be installed (or with NO_TEST_TOOLS=1), and the tests
# that need it skip with the reason.
NO_TEST_TOOLS ?=
test-tools: bootstrap
	@if [ -n "$(NO_TEST_TOOLS)" ]; then \
	  echo "make test: NO_TEST_TOOLS set: no test-only tools installed (their tests skip)"; \
	else \
	  echo "make test: installing the test-only tools into the checkout (tools/test_tools.py):"; \
	  echo "  Foxglove's decoders (npm ci in tests/foxglove), Debian's chromium and the libraries"; \
	  echo "  this machine lacks (apt-get download + dpkg -x into .cache/test-tools), the real"; \
	  echo "  ros2 command (../shared/ros2cli, into .ros2tools) and colcon (.cache/colcon)"; \
	  $(VENV)/bin/python tools/test_tools.py; \
	fi

run: bootstrap
	$(VENV)/bin/mechsim run scenes/default.yaml

# Per-run ROS_DOMAIN_ID from the shell's PID, in 1..101 (0 is everyone's default;
# 102..214 are unusable), unless the caller set one. Exit 5 (no tests collected) is a pass.
test: test-tools
	@$(VENV)/bin/ruff check src tests tools
	@$(VENV)/bin/mypy
	@export FASTDDS_DEFAULT_PROFILES_FILE="$(PROFILE)"; \
	export ROS_DOMAIN_ID="$${ROS_DOMAIN_ID:-$$(( $$$$ % 101 + 1 ))}"; \
	echo "make test: ROS_DOMAIN_ID=$$ROS_DOMAIN_ID"; \
	$(VENV)/bin/python -m pytest $(PYTEST_ARGS); rc=$$?; \
	if [ $$rc -eq 5 ]; then echo "make test: no tests collected"; rc=0; fi; \
	exit $$rc

lint: bootstrap
	$(VENV)/bin/ruff check src tests tools
	$(VENV)/bin/mypy

# Every benchmark report in one run (docs/bench, about half an hour on a quiet 2-core machine;
# the peers of `.[bench]` are measured where installed), then README.md's performance table
# from those pages.
bench: bootstrap
	@export FASTDDS_DEFAULT_PROFILES_FILE="$(PROFILE)"; \
	export ROS_DOMAIN_ID="$${ROS_DOMAIN_ID:-$$(( $$$$ % 101 + 1 ))}"; \
	$(VENV)/bin/mechsim bench --all --out docs/bench --force && \
	$(VENV)/bin/python tools/readme_performance.py
