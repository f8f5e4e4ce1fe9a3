"""Seeded lockstep camera runs repeat byte for byte under load (issue 46): `pytest -m stress`.

Every camera kind's conformance case (`test_conformance.CASES`) runs as `SIMBOT_STRESS_PAIRS`
seeded pairs (default 20) while a busy loop holds every core, and each pair must publish the same
bytes on every key: the first frame included, whenever the render worker's session learns of the
subscriber. It takes about 15 minutes on two cores, so `make test` runs its short form instead:
`test_conformance.py` runs one pair of every camera kind among the suite's three workers (where
the late first frame was seen), and `test_render_publishing.py` holds the window open on every run
(a worker's first frame put the instant its publishers are declared, before its session can know
of the subscriber: the code before the fix lost 42 of 50 frames there).
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


@pytest.mark.stress
@pytest.mark.parametrize("kind", CAMERA_KINDS)
def test_many_seeded_camera_pairs_repeat_on_busy_cores(kind: str, busy_cores: int, tmp_path: Path) -> None:
    """`SIMBOT_STRESS_PAIRS` pairs per camera kind with every core spinning: none differs."""
    differences = _differences(tmp_path, kind, STRESS_PAIRS)
    assert differences == [], f"{len(differences)} of {STRESS_PAIRS} pairs differ: " + "; ".join(differences)
