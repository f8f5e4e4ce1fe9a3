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
from simbot.description.footprints import Rectangle, collision_corners
from simbot.description.model import Model, Param, Plugin, Sensor
from simbot.gym.errors import EnvConfigError
from simbot.transform import matmul

log = logging.getLogger(__name__)

LIDAR_TYPES = ("gpu_lidar", "lidar", "ray", "gpu_ray")
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
    def read(path: Path) -> RobotFacts:
        model = load_model(path)
        drive = _plugin(model, "DiffDrive")
        if drive is None:
            raise EnvConfigError(f"robot {path}: no DiffDrive plugin; the environments drive a differential robot")
        joint = _plugin(model, "DetachableJoint")
        shapes = _collision_boxes(model)
        lowest = min(float(c[:, 2].min()) for _, c in shapes)
        top = max(float(c[:, 2].max()) for _, c in shapes)
        corners = np.vstack([c for _, c in shapes])
        bumpers = {
            link: name
            for (link, name), c in _by_link(shapes).items()
            if float(c[:, 2].min()) > lowest + BUMPER_CLEARANCE
        }
        sensors = [(link.name, sensor) for link in model.links for sensor in link.sensors]
        return RobotFacts(
            source=path,
            limits=_drive_limits(model, drive),
            cmd_topic=_text(drive, "topic") or f"model/{model.name}/cmd_vel",
            odom_topic=_text(drive, "odom_topic") or f"model/{model.name}/odometry",
            odom_rate=float(_text(drive, "odom_publish_frequency", "update_rate") or 50.0),
            cameras={s.name: _topic(s) for _, s in sensors if s.type in CAMERA_TYPES},
            lidars={s.name: _topic(s) for _, s in sensors if s.type in LIDAR_TYPES},
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
            attach_topic=_text(joint, "attach_topic") if joint else None,
            attach_state_topic=_text(joint, "output_topic") if joint else None,
        )


def _plugin(model: Model, kind: str) -> Plugin | None:
    """The model's plugin of a Gazebo system (`gz::sim::systems::DiffDrive`, its library name, ...)."""
    library = "-".join(part.lower() for part in _words(kind))
    for plugin in model.plugins:
        if plugin.name.split("::")[-1] == kind or library in plugin.filename.replace("_", "-").lower():
            return plugin
    return None


def _words(name: str) -> list[str]:
    """CamelCase → its words (DiffDrive → Diff, Drive)."""
    words: list[str] = []
    for char in name:
        if char.isupper() or not words:
            words.append(char)
        else:
            words[-1] += char
    return words


def _text(plugin: Plugin | None, *tags: str) -> str | None:
    if plugin is None:
        return None
    return next((text.strip() for tag in tags if (text := plugin.get(tag)) and text.strip()), None)


def _topic(sensor: Sensor) -> str:
    """A sensor's stated `<topic>` (simbot's robot states each); its name where none is stated."""
    return (sensor.topic or "").strip().strip("/") or sensor.name


def _drive_limits(model: Model, drive: Plugin) -> DriveLimits:
    """DiffDrive's `max_linear_velocity` / `max_angular_velocity` (the smaller magnitude of max and
    min); where it states none, what the wheels allow: the wheel joints' `<velocity>` limit × radius,
    and that speed on both sides in opposite directions for turning."""
    radius = float(_text(drive, "wheel_radius") or "nan")
    separation = float(_text(drive, "wheel_separation") or "nan")
    wheels = [model.joint(j) for j in drive.get_all("left_joint") + drive.get_all("right_joint")]
    wheel_speeds = [j.axis.velocity for j in wheels if j.axis is not None and j.axis.velocity is not None]
    wheel = min(wheel_speeds) * radius if wheel_speeds and math.isfinite(radius) else None
    linear = _stated(drive, "linear", ("max_velocity",)) or wheel
    turn = 2 * wheel / separation if wheel is not None and math.isfinite(separation) else None
    angular = _stated(drive, "angular", ()) or turn
    if linear is None or angular is None:
        raise EnvConfigError(
            f"robot {model.name}: its DiffDrive states no velocity limits and its wheel joints none either; "
            "the action space needs them"
        )
    return DriveLimits(float(linear), float(angular))


def _stated(drive: Plugin, kind: str, legacy: tuple[str, ...]) -> float | None:
    maximum = _text(drive, f"max_{kind}_velocity", *legacy)
    minimum = _text(drive, f"min_{kind}_velocity")
    values = [abs(float(v)) for v in (maximum, minimum) if v is not None]
    return min(values) if values else None


def _collision_boxes(model: Model) -> list[tuple[tuple[str, str], np.ndarray]]:
    """((link, collision), the corners of the box holding it in the model frame) for each sized collision."""
    found = []
    for link in model.links:
        for collision in link.collisions:
            corners = collision_corners(collision, link.pose.matrix())
            if corners is not None:
                found.append(((link.name, collision.name), corners))
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


def _param(params: tuple[Param, ...], *path: str) -> str | None:
    """The text at a path of nested `<sensor>` children (`lidar`, `range`, `max`)."""
    for param in params:
        if param.tag == path[0]:
            return param.text if len(path) == 1 else _param(param.children, *path[1:])
    return None


def _lidar_reach(model: Model) -> float:
    """The largest range a lidar can report plus its distance from the model's z axis."""
    reach = 0.0
    for link in model.links:
        for sensor in link.sensors:
            if sensor.type not in LIDAR_TYPES:
                continue
            text = _param(sensor.params, "lidar", "range", "max") or _param(sensor.params, "ray", "range", "max")
            where = matmul(link.pose.matrix(), sensor.pose.matrix())[:2, 3]
            reach = max(reach, float(text or 0.0) + math.hypot(float(where[0]), float(where[1])))
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
