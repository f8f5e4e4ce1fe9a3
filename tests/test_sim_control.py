"""World control alone (simbot/sim/loop/world_control.py): its three queryables over a real Zenoh pair, on a
real lockstep Simulation of a tiny world, with no server process around it.

The loop runs in a thread (`Simulation.run` with `WorldControl.poll`), as in the server; the test
asks from a client node and checks each reply against the world it can see directly.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import pytest
from bus_helpers import node_pair
from conftest import TROLLEY_SDF

from simbot.bus import Node
from simbot.description import load_model, load_world
from simbot.description.poses import Pose
from simbot.description.resources import asset
from simbot.sim.loop.bus_view import SimBus
from simbot.sim.loop.sdf_systems import LeftOut
from simbot.sim.loop.simulation import Mode, Simulation
from simbot.sim.loop.world_control import MAX_STEPS, CreateRequest, WorldControl
from simbot.sim.physics import Physics

WORLD = "empty"
CONTROL, SET_POSE, STATE = (f"world/{WORLD}/{name}" for name in ("control", "set_pose", "state"))
TROLLEY_AT = (1.0, 0.2, 0.0)


@dataclass(frozen=True)
class Controlled:
    """A client node on the bus of a world whose loop polls its world control."""

    client: Node
    sim: Simulation
    control_key: str

    def ask(self, key: str, body: dict[str, Any] | bytes) -> dict[str, Any]:
        return self.client.call(key, body, timeout=10.0)


@dataclass
class BareWorld:
    """The world control's view of a world without a server around it: no sensors, none left out, no
    models made at run time."""

    sim: Simulation
    sensors: dict[str, object] = field(default_factory=dict)
    left_out: list[LeftOut] = field(default_factory=list)
    variant: None = None
    """No variation profile: the world as its file says."""

    def create(self, request: CreateRequest) -> str:
        raise ValueError("sdf: this test world makes no models")

    def remove(self, name: str) -> None:
        raise ValueError(f"name: no model named {name!r}")

    def reset(self, seed: int | None = None) -> None:
        if seed is not None:
            raise ValueError("reset.seed: this test world has no variation profile")
        self.sim.reset()


@pytest.fixture
def world() -> Iterator[Controlled]:
    physics = Physics(load_world(asset(f"worlds/{WORLD}.sdf")))
    physics.add_model(load_model(TROLLEY_SDF), "trolley", Pose(TROLLEY_AT, (0.0, 0.0, 0.0)))
    physics.save_initial_state()
    stop = threading.Event()
    with node_pair() as pair:
        sim = Simulation(physics, Mode.LOCKSTEP)
        control = WorldControl(pair.server, WORLD, sim, SimBus(pair.server), BareWorld(sim))
        loop = threading.Thread(target=sim.run, args=(stop, control.poll), daemon=True)
        loop.start()
        try:
            yield Controlled(pair.client, sim, pair.server.key(CONTROL))
        finally:
            stop.set()
            loop.join(10.0)
            physics.close()


def test_multi_step_replies_when_the_steps_are_done(world: Controlled) -> None:
    """Lockstep: nothing moves until asked; the reply carries the time after exactly N steps of 1 ms."""
    assert world.ask(STATE, {})["iterations"] == 0
    reply = world.ask(CONTROL, {"multi_step": 25})
    assert reply == {"ok": True, "sim_time": pytest.approx(0.025, abs=1e-12), "iterations": 25}
    assert world.ask(CONTROL, {"step": True})["iterations"] == 26 == world.sim.clock.iterations


def test_state_reports_time_mode_and_every_model(world: Controlled) -> None:
    state = world.ask(STATE, b"")
    assert (state["ok"], state["paused"], state["mode"], state["dropped"]) == (True, False, "lockstep", {})
    assert state["systems_left_out"] == []
    assert set(state["models"]) == {"trolley"}
    assert state["models"]["trolley"]["position"][:2] == pytest.approx(TROLLEY_AT[:2], abs=1e-6)


def test_set_pose_moves_a_model_and_reset_brings_it_back(world: Controlled) -> None:
    """set_pose normalises the quaternion; reset puts time and models back where they began."""
    moved = world.ask(
        SET_POSE, {"name": "trolley", "position": {"x": -2.0, "y": 3.0, "z": 0.5}, "orientation": {"z": 2.0, "w": 0.0}}
    )
    assert moved["ok"]
    (x, y, z), quat = world.sim.physics.model_pose("trolley")
    assert (x, y, z) == pytest.approx((-2.0, 3.0, 0.5), abs=1e-6) and quat == pytest.approx(
        (0.0, 0.0, 1.0, 0.0), abs=1e-6
    )
    world.ask(CONTROL, {"multi_step": 10})
    assert world.ask(CONTROL, {"reset": {"all": True}}) == {"ok": True, "sim_time": 0.0, "iterations": 0}
    assert world.sim.physics.model_pose("trolley")[0][:2] == pytest.approx(TROLLEY_AT[:2], abs=1e-6)


@pytest.mark.parametrize(
    ("key", "body", "error"),
    [
        (CONTROL, {"pause": False}, "in lockstep mode the world advances only on step or multi_step"),
        (CONTROL, {"multi_step": MAX_STEPS + 1}, "multi_step expects an integer"),
        (CONTROL, {"multi_step": True}, "multi_step expects an integer"),
        (CONTROL, {"warp": 9}, "unknown field(s) warp"),
        (CONTROL, {"reset": "yes"}, "reset expects true"),
        (CONTROL, b"{not json", ""),
        (SET_POSE, {"position": {"x": 1}}, 'set_pose needs a model "name"'),
        (SET_POSE, {"name": "trolley", "position": {"x": 1e9}}, "position.x expects a number within"),
        (SET_POSE, {"name": "trolley", "orientation": {"w": 0.0}}, "orientation must be a non-zero quaternion"),
    ],
)
def test_a_bad_request_is_refused_counted_and_changes_nothing(
    world: Controlled, key: str, body: dict[str, Any] | bytes, error: str
) -> None:
    reply = world.ask(key, body)
    assert reply["ok"] is False and error in reply["error"], reply
    state = world.ask(STATE, {})
    assert state["iterations"] == 0 and state["models"]["trolley"]["position"][:2] == pytest.approx(
        TROLLEY_AT[:2], abs=1e-6
    )
    assert (
        state["dropped"] == {world.client.key(key): 1} and state["last_errors"][world.client.key(key)] == reply["error"]
    )
