"""The loop alone (simbot/sim/loop/simulation.py): the order of one step, priorities, the update
record, reset and requested steps.

Stand-ins for the physics and the systems record every call with the sim time they were given,
so the order is checked exactly, without PyBullet or a bus. The read-only physics of post_update
is checked on a real PyBullet world.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any, cast

import pytest

from simbot.description.model import Box, Collision, Inertial, Link, Model, Param, Plugin
from simbot.description.model import World as SdfWorld
from simbot.description.plugin_params import plugin_priority
from simbot.description.poses import Pose
from simbot.sim.kit.rates import Every, Paced
from simbot.sim.loop.plan import Scheduled
from simbot.sim.loop.simulation import Mode, Simulation
from simbot.sim.loop.system import LAST_PRIORITY, Batch, SystemConfigError, UpdateInfo, priority
from simbot.sim.physics import Physics, PhysicsReadOnly
from simbot.transform import Transform

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

    @contextmanager
    def reading(self) -> Iterator[None]:
        self.calls.append(("physics.read_only",))
        yield


@dataclass
class PreOnly:
    """A system with only pre_update (the runner keeps one list per phase, by the methods a system has)."""

    name: str
    calls: Calls

    def pre_update(self, info: UpdateInfo) -> None:
        self.calls.append(("pre", self.name, str(info.sim_time_ns)))


@dataclass
class PostOnly:
    """A system with only post_update."""

    name: str
    calls: Calls

    def post_update(self, info: UpdateInfo) -> None:
        self.calls.append(("post", self.name, str(info.sim_time_ns)))


class Both(PreOnly, PostOnly):
    """A system with every phase, reset included."""

    def reset(self, info: UpdateInfo) -> None:
        self.calls.append(("reset", self.name, str(info.sim_time_ns)))


def in_loop(systems: list[Any]) -> list[Scheduled]:
    """Systems as the world schedules them: at their class's priority."""
    return [Scheduled(system, priority(system)) for system in systems]


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
        self.sim = Simulation(cast(Physics, StandInPhysics(self.calls)), Mode.LOCKSTEP, in_loop(systems))


def test_a_step_runs_pre_update_physics_post_update_in_system_order() -> None:
    """Commands in before the physics, state out after it with the physics read-only, both phases
    at the time the step reaches (one record for the step); the system list's order."""
    world = World()
    world.sim.step()
    world.sim.step()
    one = [
        ("pre", "a", "1000000"),
        ("pre", "b", "1000000"),
        ("pre", "d", "1000000"),
        ("physics.step",),
        ("physics.read_only",),
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


class PacedPost(PostOnly, Paced):
    """A post-update system at its own period: the loop calls it only from `next_due_ns` on; one
    that `lazy` leaves its rate where it was (it did nothing) and is called again at the next step."""

    def __init__(self, name: str, calls: Calls, period_ns: int, lazy: bool = False) -> None:
        super().__init__(name, calls)
        self.every, self.lazy = Every(period_ns), lazy

    def post_update(self, info: UpdateInfo) -> None:
        super().post_update(info)
        if not self.lazy or info.iterations >= 3:
            self.every.due(info.sim_time_ns)

    def reset(self, info: UpdateInfo) -> None:
        self.every.restart()


def test_paced_systems_run_when_due_among_the_others_in_their_order_and_from_the_start_after_a_reset() -> None:
    """Three systems of one run: one every 3 steps, one at every step, one at 10 steps that stays
    due until its third step: each step calls what is due, in the systems' order; a reset starts
    every rate again."""
    calls: Calls = []
    systems = [
        PacedPost("slow", calls, 3 * STEP_NS),
        PostOnly("each", calls),
        PacedPost("lazy", calls, 10 * STEP_NS, True),
    ]
    sim = Simulation(cast(Physics, StandInPhysics(calls)), Mode.LOCKSTEP, in_loop(systems))

    def steps(count: int) -> list[list[str]]:
        called = []
        for _ in range(count):
            calls.clear()
            sim.step()
            called.append([call[1] for call in calls if call[0] == "post"])
        return called

    slow = ["slow", "each"]
    expected = [[*slow, "lazy"], ["each", "lazy"], [*slow, "lazy"], ["each"], ["each"], slow, ["each"]]
    assert steps(7) == expected
    sim.reset()
    assert steps(3) == expected[:3]


class PacedBatch(PacedPost):
    """A batched paced class: the loop hands `post_update_all` the instances due at the step."""

    @classmethod
    def post_update_all(cls, batches: Sequence[Batch]) -> None:
        for systems, info in batches:
            systems[0].calls.append(("batch",))
            for system in systems:
                system.post_update(info)


def test_a_batched_paced_class_is_handed_only_its_instances_due_and_not_called_when_none_is() -> None:
    """Two instances at 2 and 3 steps: each step's call has those due, in their order; at a step
    where neither is, no call."""
    calls: Calls = []
    systems = [PacedBatch("two", calls, 2 * STEP_NS), PacedBatch("three", calls, 3 * STEP_NS)]
    sim = Simulation(cast(Physics, StandInPhysics(calls)), Mode.LOCKSTEP, in_loop(systems))
    called = []
    for _ in range(7):
        calls.clear()
        sim.step()
        called.append([call[1] if call[0] == "post" else "batch" for call in calls if call[0] in ("post", "batch")])
    both, two, three = ["batch", "two", "three"], ["batch", "two"], ["batch", "three"]
    assert called == [both, two, three, two, [], both, []]


def test_requested_steps_run_in_lockstep_and_reply_after_the_last() -> None:
    """A lockstep world does nothing of itself: `run` takes exactly the steps requested, then calls `done`."""
    world, stop = World(), threading.Event()
    done: list[int] = []
    world.sim.request_steps(0, lambda: done.append(-1))  # nothing to do: answered at once

    def note_then_stop() -> None:
        done.append(world.sim.clock.iterations)
        stop.set()

    world.sim.request_steps(3, note_then_stop)
    loop = threading.Thread(target=world.sim.run, args=(stop, lambda: None))
    loop.start()
    loop.join(10.0)
    assert not loop.is_alive() and done == [-1, 3]
    assert world.calls.count(("physics.step",)) == 3


@dataclass
class Recorder:
    """Keeps every UpdateInfo it is given, in both phases."""

    infos: list[tuple[str, UpdateInfo]] = field(default_factory=list)

    def pre_update(self, info: UpdateInfo) -> None:
        self.infos.append(("pre", info))

    def post_update(self, info: UpdateInfo) -> None:
        self.infos.append(("post", info))


def test_every_phase_of_a_step_gets_one_update_record() -> None:
    """Sim time reached, step size, iterations, and paused when world control steps a paused world."""
    recorder = Recorder()
    calls: Calls = []
    sim = Simulation(cast(Physics, StandInPhysics(calls)), Mode.LOCKSTEP, in_loop([recorder]))
    sim.step()
    sim.set_paused(True)
    sim.step()
    first, second = UpdateInfo(STEP_NS, STEP_NS, 1, False), UpdateInfo(2 * STEP_NS, STEP_NS, 2, True)
    assert recorder.infos == [("pre", first), ("post", first), ("pre", second), ("post", second)]


def test_systems_run_by_priority_lower_first_ties_in_given_order() -> None:
    """A class's priority, or the one the world schedules it with (the SDF's <gz:system_priority>), orders each phase."""
    calls: Calls = []
    late, early, plain, plain2 = (
        Both("late", calls),
        Both("early", calls),
        Both("plain", calls),
        PostOnly("plain2", calls),
    )
    early.priority = -10  # type: ignore[attr-defined]
    scheduled = [Scheduled(late, LAST_PRIORITY), *in_loop([plain, early, plain2])]
    sim = Simulation(cast(Physics, StandInPhysics(calls)), Mode.LOCKSTEP, scheduled)
    sim.step()
    order = [(phase, name) for phase, name, *_ in (c for c in calls if len(c) == 3)]
    assert order == [
        ("pre", "early"), ("pre", "plain"), ("pre", "late"),
        ("post", "early"), ("post", "plain"), ("post", "plain2"), ("post", "late"),
    ]  # fmt: skip


def test_a_plugin_states_its_priority_as_gazebo_does() -> None:
    """`<gz:system_priority>` (or `gz::`), an integer; anything else is an error naming the element."""

    def plugin(*params: tuple[str, str]) -> Plugin:
        return Plugin("gz::sim::systems::DiffDrive", "gz-sim-diff-drive-system", tuple(Param(t, x) for t, x in params))

    assert plugin_priority(plugin()) is None
    assert plugin_priority(plugin(("gz:system_priority", "-5"))) == -5
    assert plugin_priority(plugin(("gz::system_priority", " 12 "))) == 12
    with pytest.raises(SystemConfigError, match=r"DiffDrive: <gz:system_priority> expected an integer, got 'soon'"):
        plugin_priority(plugin(("gz:system_priority", "soon")))


@dataclass
class Meddler:
    """A post-update system that tries to change the world it may only read."""

    physics: Physics
    refused: list[str] = field(default_factory=list)

    def post_update(self, info: UpdateInfo) -> None:
        try:
            self.physics.set_model_pose("box", Transform((0.0, 0.0, 5.0), (0.0, 0.0, 0.0, 1.0)))
        except PhysicsReadOnly as exc:
            self.refused.append(str(exc))


def test_post_update_sees_the_physics_read_only() -> None:
    """A real PyBullet world: changing it in post_update raises and leaves it as the step left it;
    between steps (world control, pre_update) it may be changed again."""
    box = Model("box", links=(Link("l", inertial=Inertial(1.0), collisions=(Collision("c", Box((0.2, 0.2, 0.2))),)),))
    physics = Physics(SdfWorld("w"))
    try:
        physics.add_model(box, "box", Pose((0.0, 0.0, 1.0), (0.0, 0.0, 0.0)))
        meddler = Meddler(physics)
        sim = Simulation(physics, Mode.LOCKSTEP, in_loop([meddler]))
        sim.step()
        assert meddler.refused == ["Physics.set_model_pose: the physics is read-only after the step (post_update)"]
        (_, _, z), _ = physics.model_pose("box")
        assert z == pytest.approx(1.0 - 9.8 * 0.001**2, abs=1e-4)  # one step of free fall, not 5 m up
        assert not physics.read_only
        physics.set_model_pose("box", Transform((0.0, 0.0, 2.0), (0.0, 0.0, 0.0, 1.0)))
        assert physics.model_pose("box")[0][2] == pytest.approx(2.0)
    finally:
        physics.close()
