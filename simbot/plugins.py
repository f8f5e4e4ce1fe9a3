"""simbot's plug-in points: what installed packages declare under an entry-point group (systems,
sensors, camera outputs; simbot's own in its pyproject.toml, a third party's in theirs), loaded so
that a broken package is a warning naming it, never a server that does not start."""

from __future__ import annotations

import logging
from importlib.metadata import entry_points
from typing import Any

log = logging.getLogger(__name__)


def load_group(group: str) -> dict[str, Any]:
    """Name → object, for every entry point of `group` that loads."""
    loaded = {}
    for point in entry_points(group=group):
        try:
            loaded[point.name] = point.load()
        except Exception as exc:  # noqa: BLE001 - a broken third-party package must not stop the server
            log.warning("%s entry point %s = %s cannot be loaded: %s", group, point.name, point.value, exc)
    return loaded
