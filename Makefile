# `make run` and `make test` create .venv when missing and install simbot with what it needs.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp

.PHONY: run test lint bench urdf meshes textures layout image clean

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -e '.[test,foxglove,ros2]'
	touch $(STAMP)

## The main job: the simulator in the warehouse with its people (three workers walking their loops, a cart going round), the lidar merger, the camera stitcher, the monitor and the Foxglove bridge on ws://127.0.0.1:8765 (Ctrl-C ends them all).
run: $(STAMP)
	$(BIN)/simbot launch --world warehouse --server-args="--add warehouse_people" --clients merger,stitcher,monitor,foxglove

## The lint first (seconds), then every test.
test: $(STAMP) lint
	$(BIN)/python -m pytest

## ruff's checks and its format check over the tree, mypy over simbot/, clients/ and benchmarks/ (rules and strictness in pyproject.toml).
lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy

## Speed, as ratios against a baseline measured in the same run (figures in the README).
bench: $(STAMP)
	$(BIN)/python benchmarks/bench_server.py
	$(BIN)/python benchmarks/bench_fleet.py
	$(BIN)/python benchmarks/bench_sensors.py
	$(BIN)/python benchmarks/bench_looks.py
	$(BIN)/python benchmarks/bench_wide_angle.py
	$(BIN)/python benchmarks/bench_vo.py
	$(BIN)/python benchmarks/bench_merger.py
	$(BIN)/python benchmarks/bench_stitcher.py
	$(BIN)/python benchmarks/bench_record.py
	$(BIN)/python benchmarks/bench_ros2.py
	$(BIN)/python benchmarks/bench_actors.py
	$(BIN)/python benchmarks/bench_dataset_cameras.py

## An hour of the warehouse in real time, every sensor and the clients running: losses per key, RSS and CPU per process (`make soak MINUTES=2` to try it).
MINUTES ?= 60
.PHONY: soak
soak: $(STAMP)
	$(BIN)/python benchmarks/soak.py --minutes $(MINUTES)

## Regenerate the committed URDF from the SDF (a test checks it is up to date).
urdf: $(STAMP)
	$(BIN)/simbot sdf2urdf urdf/flexley_tug.sdf -o urdf/flexley_tug.urdf

## Regenerate the meshes from primitives.
meshes: $(STAMP)
	$(BIN)/python meshes/make_meshes.py

## Regenerate the warehouse's textures from seeded noise and drawing (a test checks they match).
textures: $(STAMP)
	$(BIN)/python worlds/textures/make_textures.py

## Regenerate the Foxglove layout for `simbot foxglove` (a test checks it is up to date).
layout: $(STAMP)
	$(BIN)/python layouts/make_layout.py

## The container images simbot:test (`make test` inside) and simbot, with docker or podman; where the base image cannot be pulled, the same Debian release debootstrapped from Debian's mirror (docker/README.md).
image:
	docker/build-image.sh

clean:
	rm -rf $(VENV) build dist .pytest_cache .ruff_cache .mypy_cache
