# `make run` and `make test` create .venv when missing and install simbot with what each needs:
# `make run` simbot and its Foxglove extra alone (RUN_STAMP), everything else the rest (STAMP).
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
RUN_STAMP := $(VENV)/.run-stamp
STAMP := $(VENV)/.installed-stamp
PIP := $(BIN)/python -m pip install --quiet --disable-pip-version-check

EXAMPLE := examples/simbot-example-sensor

.PHONY: run test test-browser lint bench bench-learning docs urdf meshes textures layout image clean

# The main job's install: simbot and the Foxglove bridge's SDK, nothing of the tests, the docs or ROS 2.
$(RUN_STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(PIP) -e '.[foxglove]'
	touch $(RUN_STAMP)

# The rest over it: the test, docs and ROS 2 extras, and the example plug-in: tests/test_example_plugin.py
# runs a server on its sensor, the proof that a package outside simbot extends it through the entry
# points (docs/write-a-system.md).
$(STAMP): $(RUN_STAMP) pyproject.toml $(EXAMPLE)/pyproject.toml
	$(PIP) -e '.[test,foxglove,ros2,docs]'
	$(PIP) -e $(EXAMPLE)
	touch $(STAMP)

## The main job: the simulator in the warehouse with its people (three workers walking their loops, a cart going round), the lidar merger, the camera stitcher, the monitor and the Foxglove bridge on ws://127.0.0.1:8765 (Ctrl-C ends them all).
run: $(RUN_STAMP)
	$(BIN)/simbot launch --world warehouse --server-args="--add warehouse_people" --clients merger,stitcher,monitor,foxglove

## The lint first (seconds), then every test, in three processes (pytest-xdist; a file stays in one, with its module fixtures): about 10 minutes on two cores, where one process took 18.
test: $(STAMP) lint
	$(BIN)/python -m pytest -n 3 --dist loadfile

## simbot's live view in a real browser: Foxglove Studio 1.48 (from npm) in headless Chromium (Debian's, installed with apt where missing; Playwright drives it) on `simbot foxglove`; the screenshot goes to build/browser/. Skips, saying so, where Chromium, npm or Playwright cannot be had.
test-browser: $(STAMP)
	command -v chromium >/dev/null || { command -v apt-get >/dev/null && [ "$$(id -u)" = 0 ] && apt-get update -qq && apt-get install -y -qq chromium >/dev/null; } || echo "test-browser: Chromium could not be installed; the test will skip"
	$(BIN)/python -m pip install --quiet --disable-pip-version-check playwright || echo "test-browser: Playwright could not be installed; the test will skip"
	$(BIN)/python -m pytest tests/browser -m browser

## ruff's checks and its format check over the tree, mypy over simbot/, clients/, benchmarks/ and tests/ (rules and strictness in pyproject.toml).
lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy

## The documentation site (MkDocs, docs/ and mkdocs.yml) into build/site, strict: a broken link, a page missing from the nav or a docstring the API reference cannot read fails it.
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/python -m mkdocs build --strict --site-dir build/site

## Speed, as ratios against a baseline measured in the same run (each benchmark writes its own table into docs/speed.md, with the date and machine). Installs the localisation extra (Nav2's AMCL, for bench_localisation), which `make test` does not.
bench: $(STAMP)
	$(BIN)/python benchmarks/bench_server.py
	$(BIN)/python benchmarks/bench_fleet.py
	$(BIN)/python benchmarks/bench_fleet_create.py
	$(BIN)/python benchmarks/bench_turn.py
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -e '.[localisation]'
	$(BIN)/python benchmarks/bench_localisation.py
	$(BIN)/python benchmarks/bench_sensors.py
	$(BIN)/python benchmarks/bench_looks.py
	$(BIN)/python benchmarks/bench_cameras.py
	$(BIN)/python benchmarks/bench_wide_angle.py
	$(BIN)/python benchmarks/bench_vo.py
	$(BIN)/python benchmarks/bench_merger.py
	$(BIN)/python benchmarks/bench_codec.py
	$(BIN)/python benchmarks/bench_stitcher.py
	$(BIN)/python benchmarks/bench_record.py
	$(BIN)/python benchmarks/bench_ros2.py
	$(BIN)/python benchmarks/bench_rmw.py
	$(BIN)/python benchmarks/bench_actors.py
	$(BIN)/python benchmarks/bench_crowd.py
	$(BIN)/python benchmarks/bench_map.py
	$(BIN)/python benchmarks/bench_variation.py
	$(BIN)/python benchmarks/bench_dataset_cameras.py
	$(BIN)/python benchmarks/bench_products.py
	$(BIN)/python benchmarks/bench_gym.py
	$(BIN)/python benchmarks/bench_rays.py

## PPO on Navigate-v0's easy variant (empty world, goal 2 m ahead) for a fixed budget of env steps, on the CPU, against the random policy over the same seeded episodes, after Stable-Baselines3's env checker on both environments: about 11 minutes on two cores. Installs the learning extra, which `make test` does not.
# torch first, pinned: 2.13.0 is the CPU build that lies on this machine's disk (pip's find-links), while
# stable-baselines3's plain `torch` requirement, met by nothing installed, would take a CUDA build of several GB.
bench-learning: $(STAMP)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check 'torch==2.13.0'
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -e '.[learning]'
	$(BIN)/python benchmarks/bench_learning.py

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
