"""The altimeter in the probe world (probe_helpers.py): a lift and a free fall against semi-implicit
Euler, as PyBullet integrates; PyBullet's float32 poses hold 4e-6 m at 21 m."""

from __future__ import annotations

from pathlib import Path

import pytest
from probe_helpers import STEP_NS, G, assert_left_out, probe, sensor

from simbot.sim.server import ROBOT_NAME


def test_altimeter_reads_a_lift_and_a_fall(tmp_path: Path) -> None:
    """Lifted by 1.234 m it reads 1.234 over its reference, less 10 steps of free fall (semi-implicit
    Euler, as PyBullet integrates: −g·dt²·n(n+1)/2); falling 0.5 s more, the body's own height and
    vertical speed, and the same free fall over all 510 steps (bodies are undamped, as in SDF)."""
    with probe(tmp_path, sensor("alt", "altimeter"), static=False, spawn=(0.0, 0.0, 20.0, 0.0)) as sim:
        first = sim.sample("alt")
        sim.teleport((0.0, 0.0, 21.234))
        lifted = sim.sample("alt", 10)
        fallen = sim.sample("alt", 500)
        (position, _), velocity, _ = sim.server.physics.frame_motion(ROBOT_NAME, "body")
    dt = STEP_NS / 1e9
    assert first.vertical_reference == pytest.approx(20.0, abs=1e-6)
    assert lifted.vertical_position == pytest.approx(1.234 - G * dt**2 * 10 * 11 / 2, abs=4e-6)  # float32 at 21 m
    assert fallen.vertical_position == pytest.approx(position[2] - 20.0, abs=1e-9)
    assert fallen.vertical_velocity == pytest.approx(velocity[2], abs=1e-9)
    assert 1.234 - fallen.vertical_position == pytest.approx(G * dt**2 * 510 * 511 / 2, abs=4e-6)


def test_bad_noise_is_one_line_naming_sensor_and_element(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    body = "<altimeter><vertical_position><noise><stddev>x</stddev></noise></vertical_position></altimeter>"
    message = "sensor alt: <altimeter><vertical_position><noise><stddev> expected a number, got 'x'"
    assert_left_out(tmp_path, sensor("alt", "altimeter", body), "", message, caplog)
