"""`simbot state` (the container's health check) against a real warehouse server, a bare bus, and nothing.

The server runs in lockstep, so between two steps nothing in its state moves but the real-time
factor (measured on the wall clock): the client's printout can be compared with the state the
test reads itself just before and after. The summary prints positions to the millimetre, so a
model's printed x and y lie within half of that of the server's own.
"""

from __future__ import annotations

import json
import re
import subprocess
from collections.abc import Iterator, Sequence
from typing import Any

import pytest
from bus_helpers import endpoint, free_port, unique_namespace
from client_helpers import bus_args, client_command
from server_helpers import REPO, SimServer, module_server

from simbot.bus import BusOptions, Node

sim = module_server("warehouse")

RUN_TIMEOUT_S = 60.0
STEPS = 1234
STEP_S = 0.001
PRINTED_M = 0.0005
"""Half the last printed digit of a coordinate (millimetres)."""
WALL_CLOCK_FIELDS = ("real_time_factor",)
"""The only reply fields that change while a lockstep world stands still."""


def run_state(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        client_command("state", *args), check=False, capture_output=True, text=True, cwd=REPO, timeout=RUN_TIMEOUT_S
    )


def stable(state: dict[str, Any]) -> dict[str, Any]:
    return {key: value for key, value in state.items() if key not in WALL_CLOCK_FIELDS}


@pytest.fixture(scope="module")
def stepped(sim: SimServer) -> dict[str, Any]:
    """The world reset and stepped STEPS times: its state, which stays put until the next step."""
    sim.reset()
    sim.step(STEPS)
    return sim.state()


def printed_models(lines: Sequence[str]) -> dict[str, tuple[float, float]]:
    """`name  x  y  z  yaw` rows of the summary → {name: (x, y)}."""
    rows = (
        re.fullmatch(r"\s+(\S+)\s+(-?\d+\.\d{3})\s+(-?\d+\.\d{3})\s+(-?\d+\.\d{3})\s+([+-]\d+\.\d{3})", line)
        for line in lines
    )
    return {row[1]: (float(row[2]), float(row[3])) for row in rows if row}


def test_summary_names_the_world_and_its_sim_time_and_where_the_models_are(
    sim: SimServer, stepped: dict[str, Any]
) -> None:
    done = run_state(*bus_args(sim))
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[0].split() == ["world", "warehouse"]
    assert stepped["sim_time"] == pytest.approx(STEPS * STEP_S, abs=1e-9)
    assert lines[1].split()[:4] == ["sim", "time", f"{stepped['sim_time']:.3f}", "s"]
    assert f"({stepped['iterations']} iterations)" in lines[1]
    assert lines[2].startswith("mode      lockstep, steps on request"), lines[2]
    models = printed_models(lines)
    assert set(models) == set(stepped["models"])
    for name, (x, y) in models.items():
        position = stepped["models"][name]["position"]
        assert x == pytest.approx(position[0], abs=PRINTED_M) and y == pytest.approx(position[1], abs=PRINTED_M), name


def test_json_is_the_servers_own_state(sim: SimServer, stepped: dict[str, Any]) -> None:
    done = run_state(*bus_args(sim), "--json")
    assert done.returncode == 0, done.stderr
    after = sim.state()
    assert stable(after) == stable(stepped), "the lockstep world moved while it was not stepped"
    assert stable(json.loads(done.stdout)) == stable(stepped)
    assert json.loads(done.stdout)["models"]["flexley_tug"] == stepped["models"]["flexley_tug"]


def test_a_world_that_is_not_on_the_bus_is_one_line_and_exit_1(sim: SimServer) -> None:
    done = run_state(*bus_args(sim), "--world", "nowhere")
    assert done.returncode == 1
    assert done.stdout == ""
    (line,) = done.stderr.splitlines()
    assert "--world nowhere" in line and "warehouse" in line


@pytest.fixture
def bare_bus() -> Iterator[list[str]]:
    """A test node in the server role on a free port and namespace: a reachable bus with no world on it."""
    port, namespace = free_port(), unique_namespace()
    with Node(BusOptions(listen=(endpoint(port),), namespace=namespace), "server"):
        yield ["--connect", endpoint(port), "--namespace", namespace]


def test_a_bus_without_a_world_is_one_line_and_exit_1(bare_bus: list[str]) -> None:
    done = run_state(*bare_bus)
    assert done.returncode == 1
    assert done.stdout == ""
    (line,) = done.stderr.splitlines()
    assert line.startswith("simbot state: no world control") and "Traceback" not in done.stderr


def test_nothing_listening_is_one_line_and_exit_2() -> None:
    done = run_state("--connect", endpoint(free_port()), "--connect-timeout", "1")
    assert done.returncode == 2
    assert done.stdout == ""
    (line,) = done.stderr.splitlines()
    assert line.startswith("simbot state: error: cannot open the Zenoh client session")
