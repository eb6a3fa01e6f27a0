# Every target sets itself up: Debian packages (make deps), then a catkin workspace beside
# this directory (make build): ../<this directory's name>_ws, or WORKSPACE=/path. Outside the
# package, so that rospack finds the package once, through the workspace's src/ link.
# Debian's python3 must come first on PATH for catkin and roslaunch (a pyenv one may not).
SHELL := /bin/bash
export PATH := /usr/bin:/bin:$(PATH)

WORKSPACE ?= $(abspath $(CURDIR)/../$(notdir $(CURDIR))_ws)
JOBS ?= 2
RVIZ ?= 0
DEMO_ARGS ?=
FUZZ_SECONDS ?= 300
LOAD_SECONDS ?= 300
LATENCY_S3_SECONDS ?= 30
LATENCY_LOAD_SECONDS ?= 60
SCENE ?= gripper

.PHONY: deps build test fuzz load latency demo bench screenshot clean

deps:
	@bash scripts/install_deps $(if $(filter 1,$(RVIZ)),rviz)

build: deps
	@bash scripts/build_workspace "$(WORKSPACE)" "$(JOBS)"

test: build
	@bash scripts/run_tests "$(WORKSPACE)" "$(JOBS)"

# Each libFuzzer target for FUZZ_SECONDS (make test runs them for 20 s each).
fuzz: build
	@bash scripts/run_sanitized "$(WORKSPACE)" "$(JOBS)" fuzz "$(FUZZ_SECONDS)" "$(WORKSPACE)/fuzz_results"

# 300 tracked objects (LOAD_CONFIG=config/load_600.yaml: 600), clouds at 30 Hz each, the
# node at 100 Hz, for LOAD_SECONDS.
load: build
	@bash scripts/run_load_test "$(WORKSPACE)" "$(LOAD_SECONDS)"

# bench/results/latency.md: cloud arrival to contacts published, S3 through the node for
# LATENCY_S3_SECONDS per mode (cycle_on: clouds, timer), the load test for
# LATENCY_LOAD_SECONDS per mode.
latency: build
	@bash scripts/run_latency "$(WORKSPACE)" bench/results/latency.md "$(LATENCY_S3_SECONDS)" \
	  "$(LATENCY_LOAD_SECONDS)"

demo: build
	@RVIZ=$(RVIZ) bash scripts/run_demo "$(WORKSPACE)" $(DEMO_ARGS)

# The report under bench/results/ (README, Benchmarks). The peers are installed first and
# CMake runs again, so that a workspace configured without them builds bench_collision.
bench:
	@bash scripts/install_deps bench
	@bash scripts/build_workspace "$(WORKSPACE)" "$(JOBS)" --force-cmake
	@bash scripts/run_benchmarks "$(WORKSPACE)" bench/results

# docs/demo.png: the demo in rviz, rendered headless under Xvfb; SCENE=camera_gripper (or
# another scene of demo.launch) writes docs/<scene>.png. camera_gripper is grabbed 5 s after
# rviz's window appears (about 9 s into the scene), while the jaws still press the sponge;
# robot_gripper's fingers keep holding the fruit for the picture. SCENE=folded_strip renders
# launch/folded_strip.launch (a strip folded onto itself) into docs/folded_strip.png.
screenshot: RVIZ := 1
screenshot: build
ifeq ($(SCENE),folded_strip)
	@RENDER_SETTLE_S=$${RENDER_SETTLE_S:-6} RENDER_LAUNCH=folded_strip.launch \
	  bash scripts/render_demo_png "$(WORKSPACE)" docs/folded_strip.png
else
	@RENDER_SETTLE_S=$${RENDER_SETTLE_S:-$(if $(filter camera_gripper,$(SCENE)),5,7)} \
	  bash scripts/render_demo_png "$(WORKSPACE)" \
	  docs/$(if $(filter gripper,$(SCENE)),demo,$(SCENE)).png scene:=$(SCENE) \
	  $(if $(filter robot_gripper,$(SCENE)),gripper_open_at_s:=1000)
endif

clean:
	rm -rf "$(WORKSPACE)"
