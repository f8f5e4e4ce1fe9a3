"""The order of a step: which systems a phase calls, in what order and when (`Plan`).

A phase is a list of runs: a batched class's instances of one priority in one call (`BatchRun`), or
systems' own slots one after the other (`SlotRun`). A paced system (`Periodic`) waits in a heap by
when it is next due, so a step looks only at what is due now, however many a fleet holds.
"""

from __future__ import annotations

import heapq
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any, Generic, TypeVar, cast

from simbot.sim.loop.system import (
    Batch,
    BatchedPostUpdate,
    BatchedPreUpdate,
    Periodic,
    PostUpdate,
    PreUpdate,
    System,
    UpdateInfo,
)


@dataclass(frozen=True)
class Scheduled:
    """A system in the loop, with its place in each phase (lower first)."""

    system: System
    priority: int


_PHASES: dict[type, frozenset[type]] = {}
"""Each system class's phase Protocols, looked at once a class."""


def phases_of(system: System) -> frozenset[type]:
    """The phase Protocols `system`'s class implements, checked on its first instance: a runtime
    Protocol's isinstance looks at every member, and a thousand tugs' 13 000 systems are ordered
    again at each create."""
    kind = type(system)
    if kind not in _PHASES:
        phases = (PreUpdate, BatchedPreUpdate, PostUpdate, BatchedPostUpdate, Periodic)
        _PHASES[kind] = frozenset(phase for phase in phases if isinstance(system, phase))
    return _PHASES[kind]


@dataclass(frozen=True)
class Slot:
    """One call of a phase: a system's own, or its batched class's for the `batch` of one priority
    (`key`: the class and priority, which worlds of the same systems share)."""

    call: Callable[[UpdateInfo], None] | None
    priority: int
    batch: list[System] | None = None
    key: tuple[type, int] | None = None
    paced: Periodic | None = None
    """What says when a post-update call is next due (None: every step)."""


def insert_slot(slots: list[Slot], slot: Slot) -> None:
    """`slot` after every slot of its priority or a lower one (the list is by priority)."""
    index = len(slots)
    while index and slots[index - 1].priority > slot.priority:
        index -= 1
    slots.insert(index, slot)


def add_to_batch(slots: list[Slot], batches: dict[tuple[type, int], Slot], system: System, priority: int) -> None:
    """`system` into its class's batch of `priority`, a new slot where it is the first (it runs in
    that place)."""
    key = (type(system), priority)
    if key in batches:
        cast(list[System], batches[key].batch).append(system)
        return
    batches[key] = Slot(None, priority, [system], key)
    insert_slot(slots, batches[key])


T = TypeVar("T")


class Waiting(Generic[T]):
    """Things due from a sim time on (`due_ns` of each), each with its place in a run, in a heap by
    that time: a step looks only at what is due now, not at a fleet's thousands of paced systems (a
    plan is made again after a reset, which puts every rate back to its start)."""

    def __init__(self, items: Iterable[tuple[int, T]], due_ns: Callable[[T], int]) -> None:
        self._due_ns = due_ns
        self._heap = [(due_ns(item), place, item) for place, item in items]
        heapq.heapify(self._heap)

    def due(self, now_ns: int) -> list[tuple[int, T]]:
        """What is due at `now_ns`, in the order of its places, out of the heap until `again`."""
        heap, due = self._heap, []
        while heap and heap[0][0] <= now_ns:
            _, place, item = heapq.heappop(heap)
            due.append((place, item))
        due.sort(key=_place)
        return due

    def again(self, place: int, item: T) -> None:
        """`item`, called, waits for its next time."""
        heapq.heappush(self._heap, (self._due_ns(item), place, item))


def _place(entry: tuple[int, Any]) -> int:
    return int(entry[0])


Own = tuple[Callable[[UpdateInfo], None], Periodic | None]
"""A system's own slot as a run calls it: its call, and what says when it is next due (None: every step)."""


def _own(slot: Slot) -> Own:
    assert slot.call is not None, "a batched slot is not a system's own"
    return slot.call, slot.paced


def _next_due_ns(own: Own) -> int:
    return cast(Periodic, own[1]).next_due_ns


class SlotRun:
    """Systems' own slots one after the other, as a step calls them: each unpaced one at every step,
    each paced one from when it is next due (`Waiting`), in the order of the slots."""

    def __init__(self, slots: list[Slot]) -> None:
        owns = [_own(slot) for slot in slots]
        self._always = [(place, own) for place, own in enumerate(owns) if own[1] is None]
        self._waiting = Waiting(((place, own) for place, own in enumerate(owns) if own[1] is not None), _next_due_ns)

    def call(self, info: UpdateInfo) -> None:
        """The slots due at `info`'s time, in their order; each paced one waits again for its next time."""
        due = self._waiting.due(info.sim_time_ns)
        for place, own in heapq.merge(self._always, due, key=_place) if due else self._always:
            own[0](info)
            if own[1] is not None:
                self._waiting.again(place, own)


class BatchRun:
    """A batched class's slot: its instances of one priority in one call. A paced class's (its
    instances `Periodic`, in the post-update phase) gets only the instances due now, and no call
    at all at a step where none is. A fleet's instances share their times (a hundred IMUs due at
    every step, a hundred lidars at the same 5 Hz): the earliest and latest of them say whether
    none, all or some are due, and only the last needs a look at each."""

    def __init__(self, slot: Slot, paced: bool) -> None:
        self.kind = cast(tuple[type, int], slot.key)[0]
        self.paced = paced
        self._batch = cast(list[Any], slot.batch)
        self._span = (0, 0)
        """(earliest, latest) next due time of the instances, as of the last call."""
        self._handed = paced
        self.called()

    def systems(self, info: UpdateInfo) -> Sequence[Any]:
        """The instances to call at `info`'s time."""
        now_ns, (earliest, latest) = info.sim_time_ns, self._span
        self._handed = self.paced and now_ns >= earliest
        if not self.paced or now_ns >= latest:
            return self._batch
        if now_ns < earliest:
            return ()
        return [system for system in self._batch if system.next_due_ns <= now_ns]

    def called(self) -> None:
        """The span of the next due times again, after a call that handed instances out."""
        if self._handed:
            times = [system.next_due_ns for system in self._batch]
            self._span, self._handed = (min(times), max(times)), False


Run = BatchRun | SlotRun
"""A batched class's slot, or systems' own slots one after the other (what a step calls in a row)."""


@dataclass(frozen=True)
class Plan:
    """A world's slots as a step calls them: each phase's runs, and the batched slots' keys in order
    (worlds whose keys match step together)."""

    pre: list[Run]
    post: list[Run]
    keys: tuple[tuple[tuple[type, int] | None, ...], tuple[tuple[type, int] | None, ...]]

    @staticmethod
    def of(pre: list[Slot], post: list[Slot]) -> Plan:
        keys = (tuple(s.key for s in pre), tuple(s.key for s in post))
        return Plan(_runs(pre, paced=False), _runs(post, paced=True), keys)


def _runs(slots: list[Slot], paced: bool) -> list[Run]:
    """`slots` with each stretch of systems' own slots in one run; a batched slot of a paced class
    calls only its instances due where `paced` (the post-update phase)."""
    runs: list[Slot | list[Slot]] = []
    for slot in slots:
        if slot.key is not None:
            runs.append(slot)
        elif runs and isinstance(runs[-1], list):
            runs[-1].append(slot)
        else:
            runs.append([slot])
    return [
        SlotRun(run) if isinstance(run, list) else BatchRun(run, paced and Periodic in phases_of(_first(run)))
        for run in runs
    ]


def _first(slot: Slot) -> System:
    return cast(list[System], slot.batch)[0]


def run_phase(worlds: list[list[Run]], infos: list[UpdateInfo], batched: str) -> None:
    """One phase of each world: a batched class's slot once for every world's batch, each world's
    run of systems' own slots in turn (a paced one only when due)."""
    for across in zip(*worlds):
        first = across[0]
        if isinstance(first, SlotRun):
            for run, info in zip(across, infos):
                run.call(info)  # the same kind of run in each world: worlds of one plan
            continue
        batches = [Batch(systems, info) for run, info in zip(across, infos) if (systems := run.systems(info))]
        if batches:
            getattr(first.kind, batched)(batches)
        for run in across:
            run.called()
