"""A third party's sensor, loaded by a real server: examples/simbot-example-sensor, installed beside
simbot (the Makefile's venv installs it), adds `<sensor type="proximity">` through the
`simbot.sensors` entry-point group; its world has a post with one sensor facing a wall 1.8 m
ahead and one facing the sky. Nothing in simbot imports the example: this is the proof that the
entry points are enough."""

from __future__ import annotations

import ast
import math
from importlib.metadata import entry_points
from pathlib import Path

import pytest
from server_helpers import REPO, SimServer, module_server, reset_before_each, stamp_ns

EXAMPLE = REPO / "examples" / "simbot-example-sensor"
WORLD = EXAMPLE / "worlds" / "proximity.sdf"
RANGE = "sensor_msgs/msg/Range"
FRONT = "world/proximity/model/post/link/link/sensor/front/range"
"""simbot's default key of a sensor, with the example's kind (`range`)."""
UP = "proximity/up"
"""The sky sensor's stated `<topic>`."""
WALL_GAP_M = 1.8
"""The wall's near face (x = 1.9 m) less the sensor's x (the post's face, 0.1 m)."""
RAY_TOLERANCE_M = 1e-3
"""Bullet's ray test against a box is exact to float precision; a millimetre is far above that."""
PERIOD_NS = 100_000_000
"""The sensors' `<update_rate>` of 10 Hz, on 1 ms steps."""

if not any(point.name == "proximity" for point in entry_points(group="simbot.sensors")):
    pytest.fail(
        "simbot-example-sensor is not installed (`make test` installs it: pip install -e examples/simbot-example-sensor)",
        pytrace=False,
    )

sim = module_server(str(WORLD), extra=("--robot", "none"))
fresh_world = reset_before_each()


def test_the_front_sensor_reads_the_distance_to_the_wall(sim: SimServer) -> None:
    reading = sim.latest({FRONT: RANGE})[FRONT]
    assert reading.range == pytest.approx(WALL_GAP_M, abs=RAY_TOLERANCE_M)
    assert (reading.min_range, reading.max_range) == (pytest.approx(0.05), pytest.approx(5.0))
    assert reading.radiation_type == 0  # ultrasound, as its SDF says
    assert reading.field_of_view == pytest.approx(0.3)
    assert reading.header.frame_id == "front"


def test_the_reading_follows_the_wall_when_it_moves(sim: SimServer) -> None:
    moved = 3.0
    assert sim.call("set_pose", {"name": "wall", "position": {"x": moved, "y": 0.0, "z": 0.5}})["ok"]
    reading = sim.latest({FRONT: RANGE})[FRONT]
    assert reading.range == pytest.approx(moved - 0.1 - 0.1, abs=RAY_TOLERANCE_M)


def test_nothing_ahead_reads_plus_infinity_on_the_stated_topic(sim: SimServer) -> None:
    reading = sim.latest({UP: RANGE})[UP]
    assert math.isinf(reading.range) and reading.range > 0  # REP 117: no return within max_range
    assert (reading.min_range, reading.max_range) == (pytest.approx(0.02), pytest.approx(4.0))  # the defaults


def test_it_samples_at_its_update_rate_in_sim_time(sim: SimServer) -> None:
    readings = sim.subscribe(FRONT, RANGE)
    sim.prime(readings)
    sim.step(1000)
    stamps = [stamp_ns(r) for r in readings.wait_count(8, 30.0, "ranges")]
    gaps = {b - a for a, b in zip(stamps[1:], stamps[2:])}  # the first sample is the first step's, after the reset
    assert gaps == {PERIOD_NS}, gaps
    assert sim.state()["sensors"]["post/link/front"]["rate_hz"] == pytest.approx(10.0, rel=0.01)


def test_simbot_never_imports_the_example() -> None:
    """The example extends simbot from outside: no module of simbot or its clients names it."""
    package = "simbot_example_sensor"
    for path in [*Path(REPO / "simbot").rglob("*.py"), *Path(REPO / "clients").rglob("*.py")]:
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import | ast.ImportFrom):
                names = [alias.name for alias in node.names] + [getattr(node, "module", None) or ""]
                assert not any(name.split(".")[0] == package for name in names), path
