"""The force/torque sensor in the probe world (probe_helpers.py): a fixed joint's reaction in
PyBullet's articulated-body solver is exact statics, 1e-3 N and 1e-3 N·m."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from probe_helpers import ARM, LOAD_KG, G, assert_left_out, load, probe, sensor, vector


def test_force_torque_reads_the_weight_a_joint_holds(tmp_path: Path) -> None:
    """Child to parent (the default): the load pushes down on the probe with m·g and twists it by
    m·g·0.3 about +y; parent to child, in the parent's frame: the opposite."""
    extra = load("held", 0.5, "") + load(
        "pulled",
        -0.5,
        "<force_torque><frame>parent</frame><measure_direction>parent_to_child</measure_direction></force_torque>",
    )
    with probe(tmp_path, extra=extra) as sim:
        t = sim.step(10)
        held, pulled = sim.at("held", t), sim.at("pulled", t)
    weight, twist = LOAD_KG * G, LOAD_KG * G * ARM
    assert vector(held.wrench.force) == pytest.approx([0.0, 0.0, -weight], abs=1e-3)
    assert vector(held.wrench.torque) == pytest.approx([0.0, twist, 0.0], abs=1e-3)
    assert vector(pulled.wrench.force) == pytest.approx([0.0, 0.0, weight], abs=1e-3)
    assert vector(pulled.wrench.torque) == pytest.approx([0.0, -twist, 0.0], abs=1e-3)
    assert held.header.frame_id == "held"


def test_force_torque_turns_with_the_child_or_the_sensor_frame(tmp_path: Path) -> None:
    """The child link turned by π/2 about x (its y axis up): the weight reads along its −y. A sensor
    turned by π/2 about z in `sensor` frame: the lever's twist, +y in the world, reads along its +x."""
    held = load("held", 0.5, "").replace("<pose>0 0.5 0.5 0 0 0</pose>", f"<pose>0 0.5 0.5 {math.pi / 2} 0 0</pose>")
    pulled = load("pulled", -0.5, "<force_torque><frame>sensor</frame></force_torque>").replace(
        'type="force_torque"><pose>0 0 0 0 0 0</pose>', f'type="force_torque"><pose>0 0 0 0 0 {math.pi / 2}</pose>'
    )
    with probe(tmp_path, extra=held + pulled) as sim:
        t = sim.step(10)
        turned, sensed = sim.at("held", t), sim.at("pulled", t)
    assert vector(turned.wrench.force) == pytest.approx([0.0, -LOAD_KG * G, 0.0], abs=1e-3)
    assert vector(sensed.wrench.force) == pytest.approx([0.0, 0.0, -LOAD_KG * G], abs=1e-3)
    assert vector(sensed.wrench.torque) == pytest.approx([LOAD_KG * G * ARM, 0.0, 0.0], abs=1e-3)


@pytest.mark.parametrize(
    ("sensors", "extra", "message"),
    [
        (sensor("ft", "force_torque"), "", "sensor ft: a force_torque sensor belongs in a <joint>"),
        ("", load("held", 0.5, "<force_torque><frame>world</frame></force_torque>"),
         "sensor held: <force_torque><frame> must be one of child, parent, sensor, got 'world'"),
    ],
)  # fmt: skip
def test_bad_sdf_is_one_line_naming_sensor_and_element(
    tmp_path: Path, sensors: str, extra: str, message: str, caplog: pytest.LogCaptureFixture
) -> None:
    assert_left_out(tmp_path, sensors, extra, message, caplog)
