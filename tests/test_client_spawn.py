"""`simbot spawn` and `simbot remove` against a real lockstep server (no robot of its own)."""

from __future__ import annotations

import subprocess
from collections.abc import Iterator

import pytest
from client_helpers import bus_args, client_command
from conftest import REPO
from server_helpers import SimServer, running_server

TUG = str(REPO / "urdf" / "flexley_tug.sdf")
RUN_TIMEOUT_S = 120


@pytest.fixture(scope="module", name="sim")
def bare_server() -> Iterator[SimServer]:
    with running_server("empty", extra=("--robot", "none", "--camera-size", "8x6", "--camera-rate", "1")) as server:
        yield server


def run(sim: SimServer, name: str, *args: str) -> subprocess.CompletedProcess[str]:
    command = client_command(name, *args, *bus_args(sim))
    return subprocess.run(command, check=False, capture_output=True, text=True, cwd=REPO, timeout=RUN_TIMEOUT_S)


def test_spawn_in_a_namespace_then_remove(sim: SimServer) -> None:
    """spawn prints the name; the tug is where asked and takes commands on its namespace; remove takes it out."""
    spawned = run(sim, "spawn", TUG, "--name", "tug_7", "--robot-namespace", "tug_7", "--pose", "2", "3", "0.1", "0")
    assert (spawned.returncode, spawned.stdout.strip()) == (0, "tug_7"), spawned.stderr
    state = sim.state()
    assert sim.pose("tug_7", state)[0][:2] == pytest.approx((2.0, 3.0), abs=1e-6)
    assert sim.key("tug_7/cmd_vel") in state["received"]
    removed = run(sim, "remove", "tug_7")
    assert (removed.returncode, removed.stdout.strip()) == (0, "tug_7"), removed.stderr
    assert "tug_7" not in sim.state()["models"]


@pytest.mark.parametrize(
    ("command", "field"),
    [
        (("spawn", "/nonexistent.sdf"), "sdf_filename"),
        (("spawn", TUG, "--robot-namespace", "not a key"), "namespace"),
        (("spawn", TUG, "--pose", "nan", "0", "0", "0"), "--pose"),
        (("remove", "no_such_model"), "name"),
    ],
    ids=["missing file", "bad namespace", "nan pose", "unknown model"],
)
def test_mistakes_are_one_line_and_exit_2(sim: SimServer, command: tuple[str, ...], field: str) -> None:
    models = set(sim.state()["models"])
    result = run(sim, *command)
    assert result.returncode == 2, result.stderr
    (line,) = result.stderr.strip().splitlines()
    assert field in line and "Traceback" not in result.stderr
    assert set(sim.state()["models"]) == models
