"""The simulation loop: the sim clock, the three run modes, and a step (its order: `plan`).

One step: the clock advances, every system's `pre_update` (commands in), the physics step, every
system's `post_update` (state out) with the physics read-only. Every phase gets the same
`UpdateInfo`; within a phase systems run by priority (see `simbot.sim.loop.system`). The loop only
schedules; what happens in a step is the systems' and the physics module's business.
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from enum import Enum
from typing import cast

from simbot.sim.loop.plan import Plan, Scheduled, Slot, add_to_batch, insert_slot, phases_of, run_phase
from simbot.sim.loop.system import (
    BatchedPostUpdate,
    BatchedPreUpdate,
    Closable,
    Periodic,
    PostUpdate,
    PreUpdate,
    Resettable,
    System,
    UpdateInfo,
)
from simbot.sim.physics import Physics

log = logging.getLogger(__name__)

IDLE_SLEEP_S = 0.001
"""How often a paused or lockstep world looks for requests."""
POLL_EVERY = 10
"""A freely running world looks for requests every this many steps (10 ms of sim time at 1 kHz)."""
MAX_LAG_S = 0.5
"""In real time, a loop behind the wall clock catches up (a step takes a fraction of its period);
one that falls this far behind (a stall, a debugger) starts afresh rather than rushing."""
RTF_WINDOW_S = 1.0


class Mode(str, Enum):
    REALTIME = "realtime"
    FAST = "fast"
    LOCKSTEP = "lockstep"


@dataclass
class SimClock:
    """Sim time in integer nanoseconds: float seconds would lose steps after a few days."""

    step_ns: int
    now_ns: int = 0
    iterations: int = 0

    def advance(self) -> None:
        self.now_ns += self.step_ns
        self.iterations += 1

    def info(self, paused: bool = False) -> UpdateInfo:
        return UpdateInfo(self.now_ns, self.step_ns, self.iterations, paused)

    def reset(self) -> None:
        self.now_ns = self.iterations = 0


@dataclass
class RealTimeFactor:
    """Sim seconds per wall second over the last second."""

    samples: deque[tuple[float, int]] = field(default_factory=deque)

    def sample(self, wall: float, sim_ns: int) -> None:
        if self.samples and wall - self.samples[-1][0] < 0.05:
            return
        self.samples.append((wall, sim_ns))
        while len(self.samples) > 2 and wall - self.samples[1][0] >= RTF_WINDOW_S:
            self.samples.popleft()

    def value(self) -> float:
        if len(self.samples) < 2:
            return 0.0
        (w0, s0), (w1, s1) = self.samples[0], self.samples[-1]
        return (s1 - s0) / 1e9 / (w1 - w0) if w1 > w0 else 0.0

    def clear(self) -> None:
        self.samples.clear()


@dataclass
class Pacer:
    """Holds sim time to wall time in real-time mode."""

    wall0: float = 0.0
    sim0_ns: int = 0

    def anchor(self, sim_ns: int) -> None:
        self.wall0, self.sim0_ns = time.perf_counter(), sim_ns

    def wait(self, sim_ns: int) -> None:
        ahead = (sim_ns - self.sim0_ns) / 1e9 - (time.perf_counter() - self.wall0)
        if ahead > IDLE_SLEEP_S:
            time.sleep(ahead)
        elif ahead < -MAX_LAG_S:
            log.debug("real time lost by %.3f s; re-anchoring", -ahead)
            self.anchor(sim_ns)


@dataclass
class StepRequest:
    """Steps asked for through world control, and what to do when they are done (reply)."""

    left: int
    done: Callable[[], None]


@dataclass
class Simulation:
    """The world, its systems, and the loop that advances them."""

    physics: Physics
    mode: Mode = Mode.REALTIME
    scheduled: list[Scheduled] = field(default_factory=list)
    clock: SimClock = field(init=False)
    paused: bool = False
    rtf: RealTimeFactor = field(default_factory=RealTimeFactor)
    _pre: list[Slot] = field(init=False)
    _post: list[Slot] = field(init=False)
    _batches: tuple[dict[tuple[type, int], Slot], dict[tuple[type, int], Slot]] = field(init=False)
    """The batched slots of each phase (pre, post) by class and priority."""
    _plan: Plan | None = None
    """The slots as a step calls them, made again after they change."""
    _steps: deque[StepRequest] = field(default_factory=deque)
    _pacer: Pacer = field(default_factory=Pacer)

    def __post_init__(self) -> None:
        self.clock = SimClock(round(self.physics.step_size * 1e9))
        self._order()

    @property
    def systems(self) -> list[System]:
        """Every system in the loop, by priority, ties in the order they came (a created model's last)."""
        return [entry.system for entry in sorted(self.scheduled, key=lambda entry: entry.priority)]

    def _order(self) -> None:
        """The per-phase slots, afresh; a batched class's instances of one priority run as one call,
        in the place of the first of them."""
        self._pre, self._post, self._batches, self._plan = [], [], ({}, {}), None
        for entry in sorted(self.scheduled, key=lambda entry: entry.priority):
            self._slot(entry)

    def _slot(self, entry: Scheduled) -> None:
        """`entry`'s system into the phases it implements, after those of its priority already there."""
        system, priority = entry.system, entry.priority
        phases, self._plan = phases_of(system), None
        if BatchedPreUpdate in phases:
            add_to_batch(self._pre, self._batches[0], system, priority)
        elif PreUpdate in phases:
            insert_slot(self._pre, Slot(cast(PreUpdate, system).pre_update, priority))
        if BatchedPostUpdate in phases:
            add_to_batch(self._post, self._batches[1], system, priority)
        elif PostUpdate in phases:
            paced = cast(Periodic, system) if Periodic in phases else None
            insert_slot(self._post, Slot(cast(PostUpdate, system).post_update, priority, paced=paced))

    def add_systems(self, systems: list[Scheduled]) -> None:
        """Systems join the loop (a created model's between steps: world control calls it from
        `poll`), each slotted in where a fresh ordering would put it: among a thousand tugs' 13 000
        systems, ordering all again at each create cost a tenth of a second."""
        self.scheduled += systems
        for entry in sorted(systems, key=lambda entry: entry.priority):
            self._slot(entry)

    def remove_systems(self, systems: list[System]) -> None:
        """A removed model's systems leave the loop; closing them is their owner's business."""
        leaving = {id(s) for s in systems}
        self.scheduled = [entry for entry in self.scheduled if id(entry.system) not in leaving]
        self._order()

    def step(self) -> None:
        """One step of every system and the physics; `paused` in the record when world control stepped a paused world."""
        step_together([self])

    @property
    def plan(self) -> Plan:
        """The slots as a step calls them (kept until they change)."""
        if self._plan is None:
            self._plan = Plan.of(self._pre, self._post)
        return self._plan

    def request_steps(self, count: int, done: Callable[[], None]) -> None:
        """`count` more steps, then `done()`; these run even when paused or in lockstep."""
        if count <= 0:
            done()
            return
        self._steps.append(StepRequest(count, done))

    def set_paused(self, paused: bool) -> None:
        self.paused = paused
        self._pacer.anchor(self.clock.now_ns)
        self.rtf.clear()

    def reset(self) -> None:
        """Time to zero, every model where it began, every system forgets."""
        self.physics.reset()
        self.clock.reset()
        self._plan = None  # every rate starts again: the paced slots wait anew
        info = self.clock.info(self.paused)
        for system in self.systems:
            if isinstance(system, Resettable):
                system.reset(info)
        self._pacer.anchor(0)
        self.rtf.clear()

    def close(self) -> None:
        """Every system that holds something outside the process (render workers) lets it go."""
        self.close_all(self.systems)

    @staticmethod
    def close_all(systems: list[System]) -> None:
        for system in systems:
            if isinstance(system, Closable):
                system.close()

    @property
    def runs_freely(self) -> bool:
        return not self.paused and self.mode is not Mode.LOCKSTEP

    def run(
        self, stop: threading.Event, poll: Callable[[], None], every_second: Callable[[], None] | None = None
    ) -> None:
        """Steps until `stop` is set; `poll` handles requests between steps."""
        self._pacer.anchor(self.clock.now_ns)
        next_tick = time.monotonic() + 1.0
        while not stop.is_set():
            if not self.runs_freely or self.clock.iterations % POLL_EVERY == 0:
                poll()
            if self._steps:
                self._step_requested()
            elif self.runs_freely:
                self.step()
                if self.mode is Mode.REALTIME:
                    self._pacer.wait(self.clock.now_ns)
            else:
                time.sleep(IDLE_SLEEP_S)
            wall = time.monotonic()
            self.rtf.sample(wall, self.clock.now_ns)
            if every_second is not None and wall >= next_tick:
                next_tick = wall + 1.0
                every_second()

    def _step_requested(self) -> None:
        request = self._steps[0]
        self.step()
        request.left -= 1
        if request.left == 0:
            self._steps.popleft()
            request.done()
        if self.mode is Mode.REALTIME:
            self._pacer.anchor(self.clock.now_ns)


def step_together(sims: Sequence[Simulation]) -> None:
    """One step of each of `sims`, phase by phase: worlds of the same systems (a vector env's
    sub-envs) call each batched class once for all their instances, each world's with its own info;
    the others step one after the other. Each world comes out as if stepped alone."""
    plans = [sim.plan for sim in sims]
    if any(plan.keys != plans[0].keys for plan in plans[1:]):  # no hashing of a fleet's keys each step
        for sim in sims:
            step_together([sim])
        return
    infos = []
    for sim in sims:
        sim.clock.advance()
        infos.append(sim.clock.info(sim.paused))
    run_phase([plan.pre for plan in plans], infos, "pre_update_all")
    for sim in sims:
        sim.physics.step()
    with contextlib.ExitStack() as reading:
        for sim in sims:
            reading.enter_context(sim.physics.reading())
        run_phase([plan.post for plan in plans], infos, "post_update_all")
