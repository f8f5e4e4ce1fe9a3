"""Rates in sim time: a system's own period (`Every`), the rate a subscriber sees (`RateMeter`), and what
every sensor shares (`Sampled`)."""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from simbot.sim.loop.system import UpdateInfo


@dataclass
class Every:
    """Fires at a fixed sim-time period: a system's own rate, independent of the step size."""

    period_ns: int
    next_ns: int = 0

    @staticmethod
    def hz(rate: float) -> Every:
        return Every(max(1, round(1e9 / rate)))

    def due(self, now_ns: int) -> bool:
        """True at the first step at or after each multiple of the period (so 30 Hz stays 30 Hz on 1 ms steps)."""
        if now_ns < self.next_ns:
            return False
        self.fired(now_ns)
        return True

    def fired(self, now_ns: int) -> None:
        """It fired at `now_ns` (due then): next at the period's next multiple."""
        self.next_ns = (now_ns // self.period_ns + 1) * self.period_ns

    def restart(self) -> None:
        self.next_ns = 0

    def catch_up(self, now_ns: int, step_ns: int, since_ns: int = 0) -> None:
        """Where `due` would stand at the step of `now_ns` had it been asked at every step from the
        one after `since_ns` (when it came into the world; 0: the clock's start) on: due now if a
        multiple of the period came since the last step. One never asked (0) would have fired at
        that first step and stood on the grid after it; asked at that step, it is due."""
        if self.next_ns == 0:
            first_ns = since_ns + step_ns
            if now_ns <= first_ns:
                return
            self.next_ns = (first_ns // self.period_ns + 1) * self.period_ns
        self.next_ns = max(self.next_ns, ((now_ns - step_ns) // self.period_ns + 1) * self.period_ns)


@dataclass
class RateMeter:
    """Messages per second of sim time over the last 3 s: the rate a subscriber sees.

    Three seconds, because a camera's frames are published up to a few hundred milliseconds
    after their stamps, and a one-second window would hold too few of a slow camera's frames."""

    window_ns: int = 3_000_000_000
    stamps: deque[int] = field(default_factory=deque)
    count: int = 0

    def tick(self, stamp_ns: int) -> None:
        self.count += 1
        self.stamps.append(stamp_ns)
        while self.stamps and self.stamps[0] <= stamp_ns - self.window_ns:
            self.stamps.popleft()

    def rate(self, now_ns: int) -> float:
        """Intervals per second between the stamps of the window ending `now_ns`; 0 with fewer than two."""
        recent = [stamp for stamp in self.stamps if stamp > now_ns - self.window_ns]
        if len(recent) < 2 or recent[-1] == recent[0]:
            return 0.0
        return (len(recent) - 1) * 1e9 / (recent[-1] - recent[0])

    def reset(self) -> None:
        self.stamps.clear()


class Paced:
    """A system that works at its own period (`every`) after the physics step and not between:
    the loop calls its `post_update` only from `next_due_ns` on (`Periodic`), so a fleet's hundred
    tf publishers at 30 Hz cost nothing in the 200 Hz steps between their samples."""

    every: Every

    @property
    def next_due_ns(self) -> int:
        """Sim time from which `every.due` says True."""
        return self.every.next_ns


class Sampled(Paced):
    """What every sensor shares: its name, its rate, the rate it achieved, and forgetting on reset.

    A sensor system derives from it, calls `due(info)` each step it is called and `published(stamp_ns)`
    for each message; world state's `sensors` reports what it achieved. Its `post_update` does
    nothing but when due (`Paced`).
    """

    def __init__(self, name: str, rate_hz: float) -> None:
        self.name = name
        self.every = Every.hz(rate_hz)
        self.meter = RateMeter()
        self._now_ns = 0

    def due(self, info: UpdateInfo) -> bool:
        self._now_ns = info.sim_time_ns
        return self.every.due(info.sim_time_ns)

    def published(self, stamp_ns: int) -> None:
        self.meter.tick(stamp_ns)

    @staticmethod
    def sampled_all(sensors: Sequence[Sampled], stamps: Sequence[int]) -> None:
        """`due` (asked when due) then `published` of many sensors at once, each at its stamp: the
        bookkeeping of a fleet's batch (the loop hands it only those due) in one pass."""
        for sensor, now_ns in zip(sensors, stamps):
            sensor._now_ns = now_ns
            sensor.every.fired(now_ns)
            sensor.meter.tick(now_ns)

    def resume(self, info: UpdateInfo, since_ns: int = 0) -> None:
        """Asked again after steps in which it was passed over: its rate where asking at every step
        after `since_ns` (when it came into the world) would have put it (`Every.catch_up`)."""
        self.every.catch_up(info.sim_time_ns, info.step_ns, since_ns)
        self._now_ns = info.sim_time_ns

    def report(self) -> dict[str, Any]:
        return {"rate_hz": round(self.meter.rate(self._now_ns), 3), "messages": self.meter.count}

    def reset(self, info: UpdateInfo) -> None:
        self.every.restart()
        self.meter.reset()
        self._now_ns = info.sim_time_ns
