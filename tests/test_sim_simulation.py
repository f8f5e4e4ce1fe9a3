"""The loop alone (simbot/sim/simulation.py): the order of one step, reset and requested steps.

Stand-ins for the physics and the systems record every call with the sim time they were given,
so the order is checked exactly, without PyBullet or a bus.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from typing import Any, cast

from simbot.sim.physics import Physics
from simbot.sim.simulation import Mode, Simulation

STEP_NS = 1_000_000
Calls = list[tuple[str, ...]]


@dataclass
class StandInPhysics:
    """What the loop asks of the physics: its step size, a step, a reset."""

    calls: Calls
    step_size: float = STEP_NS / 1e9

    def step(self) -> None:
        self.calls.append(("physics.step",))

    def reset(self) -> None:
        self.calls.append(("physics.reset",))


@dataclass
class PreOnly:
    """A system with only pre_update (the runner keeps one list per phase, by the methods a system has)."""

    name: str
    calls: Calls

    def pre_update(self, now_ns: int) -> None:
        self.calls.append(("pre", self.name, str(now_ns)))


@dataclass
class PostOnly:
    """A system with only post_update."""

    name: str
    calls: Calls

    def post_update(self, now_ns: int) -> None:
        self.calls.append(("post", self.name, str(now_ns)))


class Both(PreOnly, PostOnly):
    """A system with every phase, reset included."""

    def reset(self, now_ns: int) -> None:
        self.calls.append(("reset", self.name, str(now_ns)))


@dataclass
class World:
    calls: Calls = field(default_factory=list)
    sim: Simulation = field(init=False)

    def __post_init__(self) -> None:
        systems: list[Any] = [
            Both("a", self.calls),
            PreOnly("b", self.calls),
            PostOnly("c", self.calls),
            Both("d", self.calls),
        ]
        self.sim = Simulation(cast(Physics, StandInPhysics(self.calls)), systems, Mode.LOCKSTEP)


def test_a_step_runs_pre_update_physics_clock_post_update_in_system_order() -> None:
    """Commands in before the physics at the old time; state out after it at the new time; the system list's order."""
    world = World()
    world.sim.step()
    world.sim.step()
    one = [
        ("pre", "a", "0"),
        ("pre", "b", "0"),
        ("pre", "d", "0"),
        ("physics.step",),
        ("post", "a", "1000000"),
        ("post", "c", "1000000"),
        ("post", "d", "1000000"),
    ]
    two = [(*call[:2], str(int(call[2]) + STEP_NS)) if len(call) == 3 else call for call in one]
    assert world.calls == one + two
    assert (world.sim.clock.now_ns, world.sim.clock.iterations) == (2 * STEP_NS, 2)


def test_reset_resets_the_physics_then_each_resettable_system_at_time_zero() -> None:
    world = World()
    world.sim.step()
    world.calls.clear()
    world.sim.reset()
    assert world.calls == [("physics.reset",), ("reset", "a", "0"), ("reset", "d", "0")]
    assert (world.sim.clock.now_ns, world.sim.clock.iterations) == (0, 0)


def test_requested_steps_run_in_lockstep_and_reply_after_the_last() -> None:
    """A lockstep world does nothing of itself: `run` takes exactly the steps requested, then calls `done`."""
    world, stop = World(), threading.Event()
    done: list[int] = []
    world.sim.request_steps(0, lambda: done.append(-1))  # nothing to do: answered at once
    world.sim.request_steps(3, lambda: (done.append(world.sim.clock.iterations), stop.set()))
    loop = threading.Thread(target=world.sim.run, args=(stop, lambda: None))
    loop.start()
    loop.join(10.0)
    assert not loop.is_alive() and done == [-1, 3]
    assert world.calls.count(("physics.step",)) == 3
