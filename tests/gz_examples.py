"""gz-sim's example worlds, for the tests that load them as Gazebo users would.

simbot does not ship them (they are Gazebo's), so a test reads them from a copy of
gazebosim/gz-sim: a checkout or a bare git directory, named by GZ_SIM_SOURCE, else the first of
`PLACES` that exists; where there is none, the test skips and says so. Their Fuel `<include>`s are
taken out (simbot downloads nothing)."""

from __future__ import annotations

import os
import re
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PLACES = (REPO.parent / "gz-sim", REPO.parent / "shared" / "gz-sim", Path("/work/.mirror/gazebosim+gz-sim/repo"))
"""Beside the checkout, in the shared folder, or where the project's fetch tool puts its copy."""
FUEL_INCLUDE = re.compile(r"<include>(?:(?!</include>).)*fuel\.gazebosim\.org.*?</include>", flags=re.S)


def gz_sim() -> Path | None:
    named = os.environ.get("GZ_SIM_SOURCE")
    if named:
        return Path(named)
    return next((place for place in PLACES if place.exists()), None)


def gazebo_example(name: str, folder: Path) -> Path:
    """gz-sim's example world `name`, its Fuel includes removed, written into `folder`."""
    source = gz_sim()
    if source is None:
        pytest.skip(
            f"no copy of gz-sim for its example worlds (set GZ_SIM_SOURCE; looked in {', '.join(map(str, PLACES))})"
        )
    path = source / "examples" / "worlds" / name
    if path.is_file():
        text = path.read_text()
    else:  # a bare git directory
        shown = subprocess.run(
            ["git", f"--git-dir={source}", "show", f"HEAD:examples/worlds/{name}"], capture_output=True, text=True
        )
        if shown.returncode != 0:
            pytest.skip(f"the gz-sim copy at {source} has no examples/worlds/{name}: {shown.stderr.strip()}")
        text = shown.stdout
    target = folder / name
    target.write_text(FUEL_INCLUDE.sub("", text))
    return target
