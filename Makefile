# somersault — the two commands of a fresh clone: `make demo` and `make test`.
SHELL := /bin/bash
# the venv's interpreter: Debian's python3.11 where there is one. It is built with profile-guided and
# link-time optimisation; a plain source build (pyenv's 3.11.7 here) runs the nodes' Python 10-30 %
# slower: controller tick replayed 110 vs 122 us, sim_node + tsc_node standing real-time factor 1.19
# vs 1.07 (docs/architecture.md, Speed). A venv made from another one: `make clean-venv setup`.
PY_BOOT ?= $(firstword $(wildcard /usr/bin/python3.11) python3)
VENV := .venv
PY := $(VENV)/bin/python
PIP := $(VENV)/bin/pip
PKGS := ros_ws/src/cassie_model ros_ws/src/cassie_flip_sim ros_ws/src/fslip_planner ros_ws/src/tsc_controller
TRANSPORT := ros_ws/src/flip_transport
MSGS := ros_ws/src/flip_msgs
MSG_SRCS := $(wildcard $(MSGS)/msg/*.msg $(MSGS)/srv/*.srv) $(MSGS)/CMakeLists.txt $(MSGS)/package.xml $(MSGS)/pyproject.toml ros_ws/cmake/ros_wheels_python.cmake
TF2_MSGS := ros_ws/src/tf2_msgs
TF2_MSG_SRCS := $(wildcard $(TF2_MSGS)/msg/*.msg) $(TF2_MSGS)/CMakeLists.txt $(TF2_MSGS)/package.xml $(TF2_MSGS)/pyproject.toml ros_ws/cmake/ros_wheels_python.cmake
export ROS_AUTOMATIC_DISCOVERY_RANGE ?= LOCALHOST
export MUJOCO_GL ?= egl

.PHONY: setup demo test test-fast clean-venv
setup: $(VENV)/.stamp-system $(VENV)/.stamp-deps $(VENV)/.stamp-msgs $(VENV)/.stamp-tf2-msgs $(VENV)/.stamp-transport $(VENV)/.stamp-pkgs $(VENV)/.stamp-tools

# Debian packages: a C++ toolchain for flip_msgs, GL libraries for offscreen rendering, Debian's
# python3.11 with venv and headers.
$(VENV)/.stamp-system: scripts/install_system_deps.sh
	bash scripts/install_system_deps.sh
	@mkdir -p $(VENV) && touch $@

$(VENV)/.stamp-deps: requirements.txt
	test -x $(PY) || $(PY_BOOT) -m venv $(VENV)
	$(PIP) install -q --upgrade pip
	$(PIP) install -q -r requirements.txt
	touch $@

# rosidl generation of an interface package (1: its directory, 2: the CMake variable that takes this
# interpreter's Python and NumPy include directories) against the ROS wheels, installed straight
# into the venv
rosidl_install = AMENT_PREFIX_PATH=$(CURDIR)/$(VENV) CMAKE_PREFIX_PATH=$(CURDIR)/$(VENV) PATH=$(CURDIR)/$(VENV)/bin:$$PATH \
	$(PIP) install -q --no-build-isolation $(1) \
	  -C cmake.define.$(2)="$$($(PY) -c 'import sysconfig,numpy;print(sysconfig.get_paths()["include"]+";"+numpy.get_include())')" \
	  -C cmake.define.Python3_EXECUTABLE=$(CURDIR)/$(PY)

# flip_msgs
$(VENV)/.stamp-msgs: $(VENV)/.stamp-deps $(MSG_SRCS)
	$(call rosidl_install,$(MSGS),FLIP_MSGS_PYTHON_INCLUDE_DIRS)
	touch $@

# tf2_msgs (TFMessage, for /tf and /tf_static): the PyPI ROS wheels lack it. Generated only where the
# ROS install has none: a tf2_msgs that imports and is not this one (pip's tf2-msgs) is kept.
$(VENV)/.stamp-tf2-msgs: $(VENV)/.stamp-deps $(TF2_MSG_SRCS)
	@if $(PY) -c 'import tf2_msgs.msg' 2>/dev/null && ! $(PIP) show -q tf2-msgs >/dev/null 2>&1; then \
	  echo "tf2_msgs: the ROS install's ($$($(PY) -c 'import tf2_msgs;print(tf2_msgs.__path__[0])')), not generated"; \
	else \
	  echo "tf2_msgs: generating $(TF2_MSGS)"; \
	  $(call rosidl_install,$(TF2_MSGS),ROSIDL_PYTHON_INCLUDE_DIRS); \
	fi
	touch $@

# flip_transport: the lockstep transport with its compiled per-step messages (on the ROS wheels' rcl
# headers and libraries); installed before the packages below, as cassie_flip_sim's compiled step is
# built against its native/stepper_api.h
$(VENV)/.stamp-transport: $(VENV)/.stamp-deps $(TRANSPORT)/setup.py $(TRANSPORT)/setup.cfg $(wildcard $(TRANSPORT)/flip_transport/native/*.cpp $(TRANSPORT)/flip_transport/native/*.h)
	$(PIP) install -q --no-build-isolation --no-deps -e $(TRANSPORT)
	touch $@

# tsc_controller builds its compiled tick (pybind11 on the pin wheel's headers, ~1.5 min) here too, and
# cassie_flip_sim its compiled step (on the mujoco wheel's headers and library)
$(VENV)/.stamp-pkgs: $(VENV)/.stamp-deps $(VENV)/.stamp-transport $(foreach p,$(PKGS),$(p)/setup.py $(p)/setup.cfg) $(wildcard ros_ws/src/cassie_model/cassie_model/native/*.h ros_ws/src/tsc_controller/tsc_controller/native/*.cpp ros_ws/src/tsc_controller/tsc_controller/native/*.hpp ros_ws/src/cassie_flip_sim/cassie_flip_sim/native/*.cpp ros_ws/src/cassie_flip_sim/cassie_flip_sim/native/*.h)
	$(PIP) install -q --no-build-isolation --no-deps $(foreach p,$(PKGS),-e $(p))
	touch $@

# flip_tools (tools/): the `flip` command (.venv/bin/flip; scripts/flip runs the same) and the library the
# bench scripts and tests import; editable, so a change to its sources needs no reinstall
$(VENV)/.stamp-tools: $(VENV)/.stamp-deps tools/pyproject.toml
	$(PIP) install -q --no-build-isolation --no-deps -e tools
	touch $@

# the design-study robot the flips land on today (--robot cassie-legs3-fw260: leg motors x3, 260 N*m
# flywheel motor; apex 1.3 m), not the paper's robot (docs/robots.md); exit 1 of `flip run`
# = the robot did not land (the run itself worked: bag, summary, plots are in runs/demo); any other
# failure fails the target
demo: setup
	@$(PY) scripts/flip run backflip --robot cassie-legs3-fw260 --apex 1.3 --settle 8 --out runs/demo; rc=$$?; \
	if [ $$rc -eq 1 ]; then echo "demo: the backflip did not land (see runs/demo/summary.json, runs/demo/fig6.png)"; \
	elif [ $$rc -ne 0 ]; then exit $$rc; fi

# the unit and offline tiers, then the graph tier, each on TEST_JOBS pytest-xdist workers (a module's
# tests on one worker, so that its module fixtures run once).  Each graph test has its own ROS domain
# (an flock'd claim) and its nodes run in lockstep, so two graphs at once give the same runs.  Both
# tiers always run; the exit code is the first failing one's.
TEST_JOBS ?= 2
test: setup
	@u=0; g=0; \
	echo "$(PY) -m pytest tests/unit tests/offline -q -n $(TEST_JOBS) --dist loadscope"; \
	$(PY) -m pytest tests/unit tests/offline -q -n $(TEST_JOBS) --dist loadscope || u=$$?; \
	echo "$(PY) -m pytest tests/graph -q -n $(TEST_JOBS) --dist loadscope"; \
	$(PY) -m pytest tests/graph -q -n $(TEST_JOBS) --dist loadscope || g=$$?; \
	if [ $$u -ne 0 ]; then exit $$u; fi; exit $$g

# the unit tier (tests/unit: no ROS graph, no long simulation), under a minute
test-fast: setup
	$(PY) -m pytest tests/unit -q -n $(TEST_JOBS) --dist loadscope

clean-venv:
	rm -rf $(VENV)
