"""Shared fixtures: the repository's files, the reference description, and the CLI."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest

from simbot.description import load_world
from simbot.sim.physics import Physics

REPO = Path(__file__).resolve().parents[1]
ROBOT_SDF = REPO / "urdf" / "flexley_tug.sdf"
ROBOT_URDF = REPO / "urdf" / "flexley_tug.urdf"
TROLLEY_SDF = REPO / "worlds" / "models" / "trolley" / "model.sdf"
REFERENCE = REPO.parent / "shared" / "reference" / "simbot-gazebo"
CAMERAS = (
    "camera_front",
    "camera_back",
    "camera_front_right",
    "camera_back_right",
    "camera_front_left",
    "camera_back_left",
)
"""The tug's six cameras, as its SDF lists them; each publishes on its own name."""


def pytest_configure(config: pytest.Config) -> None:
    """The tests' own simbot cache (render workers keep textures' mip chains in $XDG_CACHE_HOME/simbot), made
    once for the run and shared by its xdist workers and the servers they start (they inherit the environment);
    Mesa's shader cache stays where it was."""
    if os.environ.get(TEST_CACHE):
        return
    home = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    os.environ.setdefault("MESA_SHADER_CACHE_DIR", str(Path(home) / "mesa_shader_cache"))
    os.environ[TEST_CACHE] = os.environ["XDG_CACHE_HOME"] = tempfile.mkdtemp(prefix="simbot-test-cache-")
    config.stash[_MADE_CACHE] = os.environ[TEST_CACHE]


def pytest_unconfigure(config: pytest.Config) -> None:
    made = config.stash.get(_MADE_CACHE, None)
    if made is not None:
        shutil.rmtree(made, ignore_errors=True)


TEST_CACHE = "SIMBOT_TEST_CACHE"
_MADE_CACHE = pytest.StashKey[str]()


@pytest.fixture
def reference() -> Path:
    """The original Gazebo description; CI has it beside the repository, a fresh clone may not."""
    if not REFERENCE.is_dir():
        pytest.skip(
            f"reference description not found at {REFERENCE} (it sits in ../shared beside the repository in CI)"
        )
    return REFERENCE


@pytest.fixture
def clean_resource_path(monkeypatch: pytest.MonkeyPatch) -> None:
    """No resource-path variables from the developer's shell."""
    for name in ("SIMBOT_RESOURCE_PATH", "GZ_SIM_RESOURCE_PATH", "IGN_GAZEBO_RESOURCE_PATH"):
        monkeypatch.delenv(name, raising=False)


def run_cli(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    """`simbot ARGS` in a subprocess, as a user runs it."""
    return subprocess.run(
        [sys.executable, "-m", "simbot.cli", *args], capture_output=True, text=True, cwd=cwd, timeout=120
    )


def settled_physics(world_file: Path, steps: int) -> Iterator[Physics]:
    """A module fixture's body: every model of `world_file` in PyBullet, stepped `steps` times, closed after."""
    world = load_world(world_file)
    physics = Physics(world)
    for model in world.models:
        physics.add_model(model)
    for _ in range(steps):
        physics.step()
    yield physics
    physics.close()
