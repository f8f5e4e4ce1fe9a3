"""The contact sensor in the probe world (probe_helpers.py): the sum of the contact forces on a
resting box balances m·g within the solver's residual, 2 % after 0.5 s of settling."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from probe_helpers import G, assert_left_out, probe, sensor, vector

from simbot.sim.server import ROBOT_NAME
from simbot.transform import Transform


def test_contact_of_a_box_resting_on_the_ground(tmp_path: Path) -> None:
    """A 3 kg box at rest on the floor: one contact, box against ground by scoped names, points on the
    floor under the box, normals up, the forces on the box summing to m·g up."""
    with probe(
        tmp_path, sensor("bump", "contact", "<contact><collision>box</collision></contact>"),
        static=False, spawn=(0.0, 0.0, 0.1, 0.0),
    ) as sim:  # fmt: skip
        msg = sim.sample("bump", 500)
    assert len(msg.contacts) == 1
    contact = msg.contacts[0]
    assert (contact.collision1.name, contact.collision2.name) == ("flexley_tug::body::box", "ground_plane::link::c")
    points = np.array([vector(p) for p in contact.positions])
    assert len(points) >= 3 and np.abs(points[:, 2]).max() < 1e-3
    assert np.abs(points[:, :2]).max() <= 0.2 + 1e-3
    assert np.array([vector(n) for n in contact.normals]) == pytest.approx(np.tile([0.0, 0.0, 1.0], (len(points), 1)))
    assert np.abs(contact.depths).max() < 1e-3
    total = sum(vector(w.body_1_wrench.force) for w in contact.wrenches)
    assert total == pytest.approx([0.0, 0.0, 3.0 * G], abs=0.02 * 3.0 * G)


RAMP_PITCH = 0.2
RAMP = f"""<model name="ramp"><static>true</static><pose>-5 0 0.5 0 {RAMP_PITCH} 0</pose>
  <link name="link"><collision name="c"><geometry><box><size>2 2 0.2</size></box></geometry></collision></link></model>"""


def test_contact_on_a_ramp_includes_friction(tmp_path: Path) -> None:
    """A 3 kg box held by friction on a ramp pitched 0.2 rad (μ 1 > tan 0.2): normals along the ramp's,
    and normal force plus friction summing to m·g straight up (friction's sign as PyBullet reports it
    is the other body's when it swaps the pair: this catches that)."""
    normal = np.array([math.sin(RAMP_PITCH), 0.0, math.cos(RAMP_PITCH)])
    centre = np.array([-5.0, 0.0, 0.5]) + 0.2 * normal  # the ramp's half thickness and the box's
    x, y, z = (float(v) for v in centre)
    contact = sensor("bump", "contact", "<contact><collision>box</collision></contact>")
    with probe(tmp_path, contact, world=RAMP, static=False, spawn=(x, y, z, 0.0)) as sim:
        sim.server.physics.set_model_pose(
            ROBOT_NAME, Transform((x, y, z), (0.0, math.sin(RAMP_PITCH / 2), 0.0, math.cos(RAMP_PITCH / 2)))
        )
        msg = sim.sample("bump", 500)
        (position, _), _, _ = sim.server.physics.frame_motion(ROBOT_NAME, "body")
    assert np.linalg.norm(np.array(position) - centre) < 2e-3  # it stayed where it was put
    (touch,) = msg.contacts
    assert touch.collision2.name == "ramp::link::c"
    assert np.array([vector(n) for n in touch.normals]) == pytest.approx(
        np.tile(normal, (len(touch.normals), 1)), abs=1e-3
    )
    total = sum(vector(w.body_1_wrench.force) for w in touch.wrenches)
    assert total == pytest.approx([0.0, 0.0, 3.0 * G], abs=0.02 * 3.0 * G)


def test_no_contact_no_message(tmp_path: Path) -> None:
    """Falling through the air, the sensor says nothing (as Gazebo's); on the floor it speaks."""
    contact = sensor("bump", "contact", "<contact><collision>box</collision></contact>")
    with probe(tmp_path, contact, static=False, spawn=(0.0, 0.0, 2.0, 0.0)) as sim:
        sim.step(50)
        assert not [k for k, _ in sim.received.messages() if k.endswith("/bump")]
        sim.teleport((0.0, 0.0, 0.1))
        assert sim.sample("bump").contacts


@pytest.mark.parametrize(
    ("body", "message"),
    [
        ("<contact><collision>nope</collision></contact>",
         "sensor bump: <contact><collision> 'nope' is not a collision of link 'body'"),
        ("<contact/>", "sensor bump: <contact><collision> is required"),
    ],
)  # fmt: skip
def test_bad_sdf_is_one_line_naming_sensor_and_element(
    tmp_path: Path, body: str, message: str, caplog: pytest.LogCaptureFixture
) -> None:
    assert_left_out(tmp_path, sensor("bump", "contact", body), "", message, caplog)
