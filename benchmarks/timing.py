"""What the benchmarks share: the median cost of one call."""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable


def per_call_ms(work: Callable[[], object], repeats: int) -> float:
    """Median milliseconds of one call (median: one preemption on a shared machine is not a cost)."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        work()
        times.append(time.perf_counter() - start)
    return statistics.median(times) * 1e3
