"""What an environment needs to know of the robot, read from its SDF (never hard-coded), and the
copy of that SDF the environment's server runs.

`RobotFacts` holds the drive's velocity limits (the action space), its topics, its cameras and
lidars by name, its shadow on the floor and its resting height (placement), and which links can
bump into things. `write_gym_robot` writes the robot's SDF with two changes an environment needs:

- every lidar scans once per environment step (`<update_rate>` = 1 / control period), so that the
  scan an observation holds was taken at the step just ended (see docs/learning.md);
- a contact sensor on each link that touches nothing in normal driving (its lowest point more
  than `BUMPER_CLEARANCE` above the wheels'), publishing on `gym/contact`: any contact it reports
  is a collision. The wheels and castors, always on the floor, get none.

Relative `<uri>`s become absolute, as the copy lives in a folder of its own.
"""

from __future__ import annotations

import logging
import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from simbot.description import load_model
from simbot.description.drive_params import DiffDriveParams
from simbot.description.errors import SystemConfigError
from simbot.description.footprints import Rectangle, collision_boxes
from simbot.description.lidar_params import LIDAR_TYPES, LidarParams
from simbot.description.model import Model
from simbot.description.naming import plugin_named, sensor_topic
from simbot.description.plugin_params import param
from simbot.gym.errors import EnvConfigError
from simbot.transform import matmul

log = logging.getLogger(__name__)

ROBOT = "flexley_tug"
"""The robot's name in the running world, whatever its SDF calls it."""
CAMERA_TYPES = ("camera",)
CONTACT_TOPIC = "gym/contact"
CONTACT_SENSOR = "gym_contact"
BUMPER_CLEARANCE = 0.03
"""Metres above the lowest point of the robot (its wheels on the floor) from which a link is a
bumper: the tug's chassis is 0.07 m up, its castors 0.02 m (they may touch the floor when it tilts)."""


@dataclass(frozen=True)
class DriveLimits:
    """The most the drive takes: |v| ≤ linear (m/s), |ω| ≤ angular (rad/s)."""

    linear: float
    angular: float


@dataclass(frozen=True)
class RobotFacts:
    """The robot as an environment sees it; see the module docstring."""

    source: Path
    limits: DriveLimits
    cmd_topic: str
    odom_topic: str
    odom_rate: float
    cameras: dict[str, str]
    """Camera sensor name → its topic."""
    lidars: dict[str, str]
    """Lidar sensor name → its topic."""
    lidar_reach: float
    """The farthest a lidar return can be from base_link's axis: range max + the sensor's offset."""
    footprint: Rectangle
    rest_height: float
    """Height of the model frame above the floor when the robot stands on its wheels."""
    top: float
    """Height of its highest collision above the model frame."""
    bumpers: dict[str, str]
    """Link → the collision its contact sensor watches."""
    attach_topic: str | None
    attach_state_topic: str | None

    @staticmethod
    def read(path: Path, world: str) -> RobotFacts:
        """The robot's facts from its SDF, running as ROBOT in the world named `world`: its plugins'
        and sensors' parameters read, and its keys named, as the server does; EnvConfigError naming
        the file for one the environments cannot use."""
        try:
            return RobotFacts._read(path, load_model(path), world)
        except SystemConfigError as exc:
            raise EnvConfigError(f"robot {path}: {exc}") from None

    @staticmethod
    def _read(path: Path, model: Model, world: str) -> RobotFacts:
        plugin = plugin_named(model.plugins, "DiffDrive")
        if plugin is None:
            raise EnvConfigError(f"robot {path}: no DiffDrive plugin; the environments drive a differential robot")
        drive = DiffDriveParams.parse(plugin, model, ROBOT)
        joint = plugin_named(model.plugins, "DetachableJoint")
        shapes = _collision_boxes(model)
        lowest = min(float(c[:, 2].min()) for _, c in shapes)
        top = max(float(c[:, 2].max()) for _, c in shapes)
        corners = np.vstack([c for _, c in shapes])
        bumpers = {
            link: name
            for (link, name), c in _by_link(shapes).items()
            if float(c[:, 2].min()) > lowest + BUMPER_CLEARANCE
        }
        sensors = [(link, sensor) for link in model.links for sensor in link.sensors]
        return RobotFacts(
            source=path,
            limits=_drive_limits(model, drive),
            cmd_topic=drive.topic,
            odom_topic=drive.odom_topic,
            odom_rate=drive.odom_rate,
            cameras={
                s.name: sensor_topic(world, ROBOT, model, link, s, "image")
                for link, s in sensors
                if s.type in CAMERA_TYPES
            },
            lidars={
                s.name: sensor_topic(world, ROBOT, model, link, s, "scan")
                for link, s in sensors
                if s.type in LIDAR_TYPES
            },
            lidar_reach=_lidar_reach(model),
            footprint=Rectangle(
                float(corners[:, 0].min()),
                float(corners[:, 0].max()),
                float(corners[:, 1].min()),
                float(corners[:, 1].max()),
            ),
            rest_height=-lowest,
            top=top,
            bumpers=bumpers,
            attach_topic=param(joint, "attach_topic") if joint else None,
            attach_state_topic=param(joint, "output_topic") if joint else None,
        )


def _drive_limits(model: Model, drive: DiffDriveParams) -> DriveLimits:
    """DiffDrive's `max_linear_velocity` / `max_angular_velocity` (the smaller magnitude of max and
    min); where it states none, what the wheels allow: the wheel joints' `<velocity>` limit × radius,
    and that speed on both sides in opposite directions for turning."""
    wheels = [model.joint(j) for j in drive.left + drive.right]
    wheel_speeds = [j.axis.velocity for j in wheels if j.axis is not None and j.axis.velocity is not None]
    wheel = min(wheel_speeds) * drive.radius if wheel_speeds else None
    linear = drive.linear.magnitude or wheel
    turn = 2 * wheel / drive.separation if wheel is not None else None
    angular = drive.angular.magnitude or turn
    if linear is None or angular is None:
        raise EnvConfigError(
            f"robot {model.name}: its DiffDrive states no velocity limits and its wheel joints none either; "
            "the action space needs them"
        )
    return DriveLimits(float(linear), float(angular))


def _collision_boxes(model: Model) -> list[tuple[tuple[str, str], np.ndarray]]:
    """((link, collision), the corners of the box holding it in the model frame) for each sized collision."""
    found = [((link.name, collision.name), corners) for link, collision, corners in collision_boxes(model)]
    if not found:
        raise EnvConfigError(f"robot {model.name}: no collision of a known size; placement needs its shape")
    return found


def _by_link(shapes: list[tuple[tuple[str, str], np.ndarray]]) -> dict[tuple[str, str], np.ndarray]:
    """Each link's first collision (the one a contact sensor names) with the corners of all its collisions."""
    first: dict[str, str] = {}
    corners: dict[str, list[np.ndarray]] = {}
    for (link, name), c in shapes:
        first.setdefault(link, name)
        corners.setdefault(link, []).append(c)
    return {(link, first[link]): np.vstack(corners[link]) for link in first}


def _lidar_reach(model: Model) -> float:
    """The largest range a lidar can report plus its distance from the model's z axis."""
    reach = 0.0
    for link in model.links:
        for sensor in link.sensors:
            if sensor.type not in LIDAR_TYPES:
                continue
            where = matmul(link.pose.matrix(), sensor.pose.matrix())[:2, 3]
            reach = max(reach, LidarParams.from_sdf(sensor).range_max + math.hypot(float(where[0]), float(where[1])))
    return reach


def write_gym_robot(facts: RobotFacts, lidar_rate: float, folder: Path) -> Path:
    """The robot's SDF as the environment's server runs it (see the module docstring), in `folder`."""
    tree = ET.parse(facts.source)
    model = tree.getroot().find("model")
    if model is None:
        raise EnvConfigError(f"robot {facts.source}: no <model> element")
    for element in tree.getroot().iter("uri"):
        text = (element.text or "").strip()
        if text and "://" not in text and not Path(text).is_absolute():
            element.text = str((facts.source.parent / text).resolve())
    for link in model.iter("link"):
        for sensor in link.iter("sensor"):
            if sensor.get("type") in LIDAR_TYPES:
                rate = sensor.find("update_rate")
                if rate is None:
                    rate = ET.SubElement(sensor, "update_rate")
                rate.text = repr(lidar_rate)
        collision = facts.bumpers.get(link.get("name") or "")
        if collision is not None:
            link.append(_contact_sensor(collision))
    path = folder / "gym_robot.sdf"
    tree.write(path, encoding="utf-8", xml_declaration=True)
    load_model(path)  # the copy must read as the original does
    return path


def _contact_sensor(collision: str) -> ET.Element:
    sensor = ET.Element("sensor", name=CONTACT_SENSOR, type="contact")
    ET.SubElement(sensor, "always_on").text = "true"
    ET.SubElement(sensor, "topic").text = CONTACT_TOPIC
    ET.SubElement(ET.SubElement(sensor, "contact"), "collision").text = collision
    return sensor
