"""The magnetometer in the probe world (probe_helpers.py): the world's field turned into the sensor's
frame, within a float32 rotation (PyBullet's poses: 1.2e-7 of a rotation)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from probe_helpers import probe, sensor, vector

FIELD = (20e-6, 5e-6, -40e-6)


@pytest.mark.parametrize("yaw", [0.0, math.pi / 2, 2.0])
def test_magnetometer_turns_the_world_field_into_its_frame(tmp_path: Path, yaw: float) -> None:
    """The world's `<magnetic_field>` seen from a body turned by `yaw`: Rz(yaw)ᵀ·B."""
    world = "<magnetic_field>{} {} {}</magnetic_field>".format(*FIELD)
    with probe(tmp_path, sensor("compass", "magnetometer"), world=world) as sim:
        sim.teleport((0.0, 0.0, 0.5), yaw)
        reading = vector(sim.sample("compass").magnetic_field)
    c, s = math.cos(yaw), math.sin(yaw)
    expected = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]]) @ np.array(FIELD)
    assert reading == pytest.approx(expected, abs=5e-7 * np.linalg.norm(FIELD))  # a float32 rotation


def test_magnetometer_reads_sdfs_default_field(tmp_path: Path) -> None:
    """A world without `<magnetic_field>` has SDF's default (5.5645e-6, 22.8758e-6, −42.3884e-6) T."""
    with probe(tmp_path, sensor("compass", "magnetometer")) as sim:
        msg = sim.sample("compass")
    assert vector(msg.magnetic_field) == pytest.approx([5.5645e-6, 22.8758e-6, -42.3884e-6], abs=1e-15)
    assert msg.header.frame_id == "compass"
