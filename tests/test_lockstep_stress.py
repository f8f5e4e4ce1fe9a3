"""Seeded lockstep camera runs repeat byte for byte under load (issue 46).

Every camera kind's conformance case (`test_conformance.CASES`) runs as seeded pairs while busy
loops hold every core, and each pair must publish the same bytes on every key: the first frame
included, whenever the render worker's session learns of the subscriber. The suite runs one pair
of each kind; `-m stress` runs `SIMBOT_STRESS_PAIRS` (default 20) of each, the figure the issue asks
for. The window this once slipped through (a worker's first put, before its session knew of the
subscriber) is held wide open in `test_render_pool.py::test_a_workers_first_frame_reaches_a_subscriber_it_has_not_heard_of`.
"""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from test_conformance import CASES, SEED, run

from simbot.sim.loop.registry import SENSOR_GROUP
from simbot.sim.render.pool import usable_cores

CAMERA_KINDS = (
    "camera",
    "depth_camera",
    "rgbd_camera",
    "wide_angle_camera",
    "thermal_camera",
    "segmentation",
    "boundingbox_camera",
)
"""One SDF type per camera module (the aliases, `depth` and `rgbd`, build the same sensor)."""
STRESS_PAIRS = int(os.environ.get("SIMBOT_STRESS_PAIRS", "20"))


@pytest.fixture
def busy_cores() -> Iterator[int]:
    """A spinning process per usable core for the test's length; how many."""
    count = usable_cores()
    loops = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(count)]
    try:
        yield count
    finally:
        for loop in loops:
            loop.kill()
            loop.wait()


def _differences(tmp: Path, kind: str, pairs: int) -> list[str]:
    """For each seeded pair that did not repeat, the keys that differed and how."""
    case = CASES[(SENSOR_GROUP, kind)]
    found = []
    for pair in range(pairs):
        first, second = (run(tmp / f"{pair}_{side}", case, SEED) for side in ("a", "b"))
        assert len(first.get(case.key or "", [])) >= 2, f"{kind}: no frames on {case.key} in pair {pair}"
        keys = sorted(key for key in first.keys() | second.keys() if first.get(key) != second.get(key))
        if keys:
            counts = ", ".join(f"{key} {len(first.get(key, []))}/{len(second.get(key, []))}" for key in keys)
            found.append(f"pair {pair}: {counts}")
    return found


@pytest.mark.parametrize("kind", CAMERA_KINDS)
def test_a_seeded_camera_pair_repeats_on_busy_cores(kind: str, busy_cores: int, tmp_path: Path) -> None:
    """One pair per camera kind with every core spinning: the same bytes on every key."""
    assert _differences(tmp_path, kind, 1) == []


@pytest.mark.stress
@pytest.mark.parametrize("kind", CAMERA_KINDS)
def test_many_seeded_camera_pairs_repeat_on_busy_cores(kind: str, busy_cores: int, tmp_path: Path) -> None:
    """`SIMBOT_STRESS_PAIRS` pairs per camera kind with every core spinning: none differs."""
    differences = _differences(tmp_path, kind, STRESS_PAIRS)
    assert differences == [], f"{len(differences)} of {STRESS_PAIRS} pairs differ: " + "; ".join(differences)
