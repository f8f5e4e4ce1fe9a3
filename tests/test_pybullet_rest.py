"""The generated URDFs in real PyBullet physics: the robot rests on its wheels, the trolley on its legs."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pybullet as pb
import pytest
from conftest import ROBOT_URDF, TROLLEY_SDF

from simbot.description import load_model, model_to_urdf

STEP = 0.001  # 1 kHz, the worlds' step
SETTLE_STEPS = 2000  # 2 s
WHEEL_RADIUS, WHEEL_Z = 0.075, -0.02  # SPEC §1: the model origin rests 0.095 above the floor


@pytest.fixture
def client() -> Iterator[int]:
    """A DIRECT PyBullet world with gravity and a ground plane (body 0)."""
    cid = pb.connect(pb.DIRECT)
    pb.setGravity(0, 0, -9.8, physicsClientId=cid)
    pb.setTimeStep(STEP, physicsClientId=cid)
    pb.createMultiBody(0, pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=cid), physicsClientId=cid)
    yield cid
    pb.disconnect(cid)


def _load(cid: int, urdf: Path, z: float) -> tuple[int, dict[str, int]]:
    """Loads the URDF free-floating; joints passive (no default velocity motors); links by name."""
    body = pb.loadURDF(str(urdf), [0, 0, z], physicsClientId=cid)
    names = {}
    for j in range(pb.getNumJoints(body, physicsClientId=cid)):
        pb.setJointMotorControl2(body, j, pb.VELOCITY_CONTROL, force=0, physicsClientId=cid)
        names[pb.getJointInfo(body, j, physicsClientId=cid)[12].decode()] = j
    return body, names


def _base_frame(cid: int, body: int) -> tuple[np.ndarray, np.ndarray]:
    """Position and rotation of the URDF root link's frame (PyBullet reports its inertial frame)."""
    pos, orn = pb.getBasePositionAndOrientation(body, physicsClientId=cid)
    local_pos, local_orn = pb.getDynamicsInfo(body, -1, physicsClientId=cid)[3:5]
    inv_pos, inv_orn = pb.invertTransform(local_pos, local_orn)
    frame_pos, frame_orn = pb.multiplyTransforms(pos, orn, inv_pos, inv_orn)
    return np.array(frame_pos), np.array(pb.getMatrixFromQuaternion(frame_orn)).reshape(3, 3)


def _settle(cid: int, body: int) -> np.ndarray:
    """Steps 2 s and returns the root frame height at every step."""
    heights = []
    for _ in range(SETTLE_STEPS):
        pb.stepSimulation(physicsClientId=cid)
        heights.append(_base_frame(cid, body)[0][2])
    return np.array(heights)


def _touching(cid: int, body: int, link: int) -> bool:
    return len(pb.getContactPoints(body, 0, link, -1, physicsClientId=cid)) > 0


def test_robot_rests_on_its_four_wheels(client: int) -> None:
    """Dropped from 0.1 m: after 2 s the base is steady within 5 mm, at wheel height, on four wheels."""
    body, links = _load(client, ROBOT_URDF, 0.1)
    assert pb.getDynamicsInfo(body, -1, physicsClientId=client)[0] > 0, "a massless root would pin the robot"
    heights = _settle(client, body)
    last_second = heights[SETTLE_STEPS // 2 :]
    assert last_second.max() - last_second.min() < 0.005
    assert heights[-1] == pytest.approx(WHEEL_RADIUS - WHEEL_Z, abs=0.002)
    for wheel in ("front_left_wheel", "front_right_wheel", "back_left_wheel", "back_right_wheel"):
        assert _touching(client, body, links[wheel]), f"{wheel} is off the ground"
    for castor in ("castor_front_left", "castor_back_right"):
        assert not _touching(client, body, links[castor]), f"{castor} carries load; the wheels should"
    _, rotation = _base_frame(client, body)
    assert rotation[2, 2] > np.cos(0.01), "the robot should stand level"


def test_robot_is_not_static(client: int) -> None:
    """A push moves it: the token mass of base_footprint keeps PyBullet from pinning the base."""
    body, _ = _load(client, ROBOT_URDF, 0.1)
    _settle(client, body)
    start = _base_frame(client, body)[0]
    for _ in range(500):
        pb.applyExternalForce(body, -1, [400, 0, 0], [0, 0, 0.2], pb.LINK_FRAME, physicsClientId=client)
        pb.stepSimulation(physicsClientId=client)
    assert _base_frame(client, body)[0][0] - start[0] > 0.05


def test_trolley_stands_on_its_legs(client: int, tmp_path: Path) -> None:
    """The trolley settles level with its frame on the floor and all four feet touching it."""
    urdf = tmp_path / "trolley.urdf"
    urdf.write_text(model_to_urdf(load_model(TROLLEY_SDF), tmp_path))
    body, _ = _load(client, urdf, 0.01)
    heights = _settle(client, body)
    assert heights[-1] == pytest.approx(0.0, abs=0.002)
    assert np.ptp(heights[SETTLE_STEPS // 2 :]) < 0.002
    _, rotation = _base_frame(client, body)
    assert rotation[2, 2] > np.cos(0.01)
    contacts = pb.getContactPoints(body, 0, physicsClientId=client)
    corners = {(np.sign(c[5][0]), np.sign(c[5][1])) for c in contacts}
    assert corners == {(1, 1), (1, -1), (-1, 1), (-1, -1)}, "each of the four feet should touch the floor"
