"""Figures that stay true: each benchmark writes the table it owns into docs/speed.md.

The page holds each table between `<!-- bench:NAME -->` and `<!-- /bench:NAME -->`; `publish`
prints the table (the benchmark's output as before) and replaces what lies between the markers
with a line saying when and on what machine it was measured, then the table. Nothing outside the
markers changes, so the prose around a table stays the author's. A page without the markers is
an error naming the page and the block: the table must have a place before a benchmark owns it.
"""

from __future__ import annotations

import datetime
import os
import platform
import re
from collections.abc import Sequence
from pathlib import Path

SPEED_PAGE = Path(__file__).resolve().parents[1] / "docs" / "speed.md"


class MissingMarkers(ValueError):
    """The page has no `<!-- bench:NAME -->` … `<!-- /bench:NAME -->` block for the table."""


def markers(name: str) -> tuple[str, str]:
    """The opening and closing markers of block `name`."""
    return f"<!-- bench:{name} -->", f"<!-- /bench:{name} -->"


def cpu_model() -> str:
    """The CPU's model name from /proc/cpuinfo (Linux), else what the platform module says."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def provenance(today: datetime.date | None = None) -> str:
    """The line above a table: the date it was measured, the CPU, how many cores this process may use, and
    the load average when it finished (a shared machine's other work slows every absolute figure)."""
    date = (today or datetime.date.today()).isoformat()
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    load = f", load average {os.getloadavg()[0]:.1f}" if hasattr(os, "getloadavg") else ""
    return f"*Measured {date} on {cpu_model()}, {cores} cores{load}, Python {platform.python_version()}.*"


def replace_block(text: str, name: str, body: str) -> str:
    """`text` with what lies between block `name`'s markers replaced by `body` (markers kept); a marker
    counts only on a line of its own, so prose that names one (in `code`) is never taken for it."""
    opening, closing = markers(name)
    block = re.compile(rf"^({re.escape(opening)}\n).*?^(?={re.escape(closing)}$)", re.MULTILINE | re.DOTALL)
    if not block.search(text):
        raise MissingMarkers(f"no {opening} … {closing} block")
    return block.sub(lambda match: match[1] + body.rstrip("\n") + "\n", text, count=1)


def publish(name: str, lines: Sequence[str], page: Path = SPEED_PAGE) -> None:
    """Prints the table `lines` and writes it, with its provenance, into block `name` of `page`."""
    print("\n".join(lines))
    body = provenance() + "\n\n" + "\n".join(lines)
    try:
        page.write_text(replace_block(page.read_text(), name, body))
    except MissingMarkers as exc:
        raise SystemExit(f"{page}: {exc}") from None
    print(f"(table written into {page.name}, block {name})")
