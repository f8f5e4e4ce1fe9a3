"""`robot_description` (the URDF) and `tf_static` (its fixed joints and the sensor frames), for late joiners too.

What ROS's robot_state_publisher would do for the static part of the tree: every fixed joint of the
URDF on `robot_description` becomes a transform, so the two always agree. A sensor whose frame
is not a link (the cameras) adds its link → frame transform at the sensor's SDF pose; a sensor
whose frame is its link (the lidars) already has it, as the URDF puts that link's frame at the
sensor. Each camera also gets its optical frame (z forward, x right, y down), which its images
are stamped in.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

from simbot.bus import messages
from simbot.bus.frames import OPTICAL_RPY, optical_frame
from simbot.description.model import Model
from simbot.description.poses import Pose
from simbot.description.urdf_writer import link_frame
from simbot.sim.physics import pose_to_transform
from simbot.sim.system import SystemContext, sensor_frame


def _numbers(text: str | None) -> tuple[float, float, float]:
    x, y, z = (float(v) for v in (text or "0 0 0").split())
    return x, y, z


def static_transforms(model: Model, urdf: str) -> list[tuple[str, str, Pose]]:
    """(parent, child, child pose in parent) for the URDF's fixed joints and the non-link sensor frames."""
    root = ET.fromstring(urdf)
    found = []
    for joint in root.iter("joint"):
        if joint.get("type") != "fixed":
            continue
        origin = joint.find("origin")
        pose = Pose(_numbers(origin.get("xyz")), _numbers(origin.get("rpy"))) if origin is not None else Pose()
        found.append((joint.find("parent").get("link", ""), joint.find("child").get("link", ""), pose))  # type: ignore[union-attr]
    links = {link.get("name") for link in root.iter("link")}
    for link, sensor in model.sensors():
        frame = sensor_frame(sensor)
        if frame not in links:
            found.append((link.name, frame, link_frame(link).inverse() @ link.pose @ sensor.pose))
        if sensor.type == "camera":
            found.append((frame, optical_frame(frame), Pose(rpy=OPTICAL_RPY)))
    return found


class RobotStatePublisher:
    """Built into the server for the robot; publishes once, latched."""

    def __init__(self, ctx: SystemContext) -> None:
        model, name = ctx.require_model("RobotStatePublisher")
        urdf = ctx.physics.body(name).urdf
        ctx.bus.publisher("robot_description", messages.String, latched=True).put(messages.string(urdf))
        transforms = [messages.transform_stamped(0, parent, child, *pose_to_transform(pose)) for parent, child, pose in static_transforms(model, urdf)]
        ctx.bus.publisher("tf_static", messages.TFMessage, latched=True).put(messages.tf_message(transforms))
