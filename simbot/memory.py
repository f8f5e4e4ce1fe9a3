"""How much memory this process may still take, and whether so many of something fit in it: the one
line that names the option asking for too many (the server's `--robots`, a vector env's
`num_envs`), said before anything is built, rather than a machine that swaps or an OOM kill later."""

from __future__ import annotations

import os
from pathlib import Path


def available() -> int:
    """Bytes this process may still take without swapping: Linux's MemAvailable (else the free
    pages), and no more than its container's cgroup leaves (memory.max less memory.current); a
    terabyte where nothing can be read (a bound that is not known holds nothing back)."""
    bounds = [_meminfo_available(), _cgroup_left()]
    known = [bound for bound in bounds if bound is not None]
    return min(known) if known else 1 << 40


def shortfall(option: str, count: int, each: int, base: int, unit: str) -> str | None:
    """Why `count` of something taking `each` bytes (`unit`: "a tug"), over `base` bytes of their
    process, do not fit in what is `available`: one line naming `option` and how many would; None
    where they fit."""
    free, needed = available(), base + count * each
    if needed <= free:
        return None
    fits = max(0, (free - base) // each)
    return (
        f"{option} {count}: about {needed / 2**30:.1f} GiB for them ({each >> 20} MiB {unit}), "
        f"and {free / 2**30:.1f} GiB is available: {fits} fit"
    )


def _meminfo_available() -> int | None:
    try:
        with open("/proc/meminfo") as meminfo:
            for line in meminfo:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def _cgroup_left() -> int | None:
    """What the cgroup (v2) this process runs in leaves it, or None without a limit."""
    try:
        limit = Path("/sys/fs/cgroup/memory.max").read_text().strip()
        used = Path("/sys/fs/cgroup/memory.current").read_text().strip()
    except OSError:
        return None
    return None if limit == "max" else max(0, int(limit) - int(used))
