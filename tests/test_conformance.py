"""Every registered system and sensor: built from a small SDF of its own, deterministic in lockstep.

The entry points are read from `importlib.metadata` when the tests are collected, so a system
registered later (by simbot or by another package) is tested too, and fails here, by name, until
`CASES` gives it an SDF. Each case is a tiny world (a ground plane, a box to see, a cart) and a
two-wheeled robot carrying the one plugin or sensor; the server is built in this process exactly
as `simbot-server` builds it (`Server`, lockstep) on a real Zenoh session, stepped 0.2 s, twice
with one seed. Every message on the namespace (the system's own and the server's clock, poses,
tf) is collected by a subscriber on the server's own session, and the two runs must agree byte for
byte, key by key. The sensor's own key must be among them, so a case that publishes nothing
cannot pass as deterministic.

A sensor's noise is drawn from a generator made from the seed and the sensor's scoped name
(`scoped_rng`): another sensor or plugin added before it leaves its noise unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib.metadata import entry_points
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import zenoh
from bus_helpers import endpoint, free_port, unique_namespace, wait_until

from simbot.bus import BusOptions, Node, decode, encode, messages
from simbot.description.naming import scoped_rng
from simbot.sim.loop.registry import GROUP, ROBOT_GROUP, SENSOR_GROUP, WORLD_GROUP
from simbot.sim.loop.simulation import Mode
from simbot.sim.loop.world_control import CreateRequest
from simbot.sim.server import Server, ServerConfig

FLUSH = "conformance_flush"
"""A key no system uses, put after the last step: its arrival means the run's messages have all arrived."""
STEPS = 200  # 0.2 s at 1 kHz: several messages of every rate here (camera 30 Hz, lidar 50 Hz, IMU 200 Hz)
SEED = 7
CREATED_AT = 50
WATCHER = """<sdf version="1.9"><model name="watcher"><static>true</static><pose>0 1 0.3 0 0 -0.6</pose>
  <link name="link">{camera}</link></model></sdf>"""
"""A camera on a model created while the world runs (`CREATED_AT`)."""
Published = dict[str, list[bytes]]

WORLD = """<?xml version="1.0"?>
<sdf version="1.9">
  <world name="conformance">
    <physics name="1ms" type="ignore"><max_step_size>0.001</max_step_size></physics>
    {world_plugins}
    <model name="ground_plane">
      <static>true</static>
      <link name="link">
        <collision name="c"><geometry><plane><normal>0 0 1</normal><size>20 20</size></plane></geometry></collision>
        <visual name="v"><geometry><plane><normal>0 0 1</normal><size>20 20</size></plane></geometry></visual>
      </link>
    </model>
    <model name="wall">
      <static>true</static>
      <pose>2 0 0.5 0 0 0</pose>
      <link name="link">
        <collision name="c"><geometry><box><size>0.2 4 1</size></box></geometry></collision>
        <visual name="v"><geometry><box><size>0.2 4 1</size></box></geometry></visual>
      </link>
    </model>
    <model name="cart">
      <pose>-1.5 0 0.1 0 0 0</pose>
      <link name="base">
        <inertial><mass>5</mass><inertia><ixx>0.1</ixx><iyy>0.1</iyy><izz>0.1</izz></inertia></inertial>
        <collision name="c"><geometry><box><size>0.4 0.4 0.2</size></box></geometry></collision>
      </link>
    </model>
  </world>
</sdf>
"""

ROBOT = """<?xml version="1.0"?>
<sdf version="1.9">
  <model name="bot">
    <link name="base_link">
      <pose>0 0 0.1 0 0 0</pose>
      <inertial><mass>10</mass><inertia><ixx>0.2</ixx><iyy>0.3</iyy><izz>0.4</izz></inertia></inertial>
      <collision name="c"><geometry><box><size>0.6 0.3 0.1</size></box></geometry></collision>
      <collision name="skid"><pose>-0.25 0 -0.05 0 0 0</pose><geometry><sphere><radius>0.05</radius></sphere></geometry>
        <surface><friction><ode><mu>0.01</mu><mu2>0.01</mu2></ode></friction></surface></collision>
      {sensors}
    </link>
    <link name="left_wheel">
      <pose>0.1 0.2 0.075 -1.5707963 0 0</pose>
      <inertial><mass>0.5</mass><inertia><ixx>0.001</ixx><iyy>0.001</iyy><izz>0.001</izz></inertia></inertial>
      <collision name="c"><geometry><cylinder><radius>0.075</radius><length>0.04</length></cylinder></geometry></collision>
    </link>
    <link name="right_wheel">
      <pose>0.1 -0.2 0.075 -1.5707963 0 0</pose>
      <inertial><mass>0.5</mass><inertia><ixx>0.001</ixx><iyy>0.001</iyy><izz>0.001</izz></inertia></inertial>
      <collision name="c"><geometry><cylinder><radius>0.075</radius><length>0.04</length></cylinder></geometry></collision>
    </link>
    <joint name="left_wheel_joint" type="revolute">
      <parent>base_link</parent><child>left_wheel</child><axis><xyz>0 0 1</xyz></axis>
    </joint>
    <joint name="right_wheel_joint" type="revolute">
      <parent>base_link</parent><child>right_wheel</child><axis><xyz>0 0 1</xyz></axis>
    </joint>
    {plugins}
  </model>
</sdf>
"""


def _noise(stddev: float) -> str:
    return f'<noise type="gaussian"><mean>0</mean><stddev>{stddev}</stddev></noise>'


def _lidar(kind: str, name: str = "scanner") -> str:
    """A noisy 90-ray planar scanner looking at the wall; `<lidar>` or, for `ray`, `<ray>`."""
    tag = "ray" if kind in ("ray", "gpu_ray") else "lidar"
    return f"""<sensor name="{name}" type="{kind}"><pose>0.3 0 0.1 0 0 0</pose><update_rate>50</update_rate>
      <topic>{name}</topic><{tag}><scan><horizontal><samples>90</samples><min_angle>-0.8</min_angle>
      <max_angle>0.8</max_angle></horizontal></scan><range><min>0.1</min><max>5</max><resolution>0.01</resolution>
      </range>{_noise(0.01)}</{tag}></sensor>"""


def _imu(name: str = "imu") -> str:
    axes = "".join(f"<{a}>{_noise(0.02)}</{a}>" for a in "xyz")
    return f"""<sensor name="{name}" type="imu"><update_rate>200</update_rate><topic>{name}</topic>
      <imu><angular_velocity>{axes}</angular_velocity><linear_acceleration>{axes}</linear_acceleration></imu></sensor>"""


CAMERA = """<sensor name="eye" type="camera"><pose>0.3 0 0.1 0 0 0</pose><update_rate>30</update_rate><topic>eye</topic>
  <camera><horizontal_fov>1.5</horizontal_fov><image><width>64</width><height>48</height><format>R8G8B8</format></image>
  <clip><near>0.05</near><far>20</far></clip><noise type="gaussian"><mean>0</mean><stddev>0.02</stddev></noise></camera></sensor>"""
THERMAL = (
    CAMERA.replace('type="camera"', 'type="thermal"')
    .replace("R8G8B8", "L16")
    .replace(
        "</sensor>",
        '<plugin name="gz::sim::systems::ThermalSensor" filename="gz-sim-thermal-sensor-system">'
        "<min_temp>250</min_temp><max_temp>400</max_temp><resolution>0.05</resolution></plugin></sensor>",
    )
)
"""A thermal camera (issue 26): L16 counts of 0.05 K between 250 and 400 K."""
HOT = """<plugin name="gz::sim::systems::Thermal" filename="gz-sim-thermal-system"><temperature>310</temperature></plugin>"""

WIDE_ANGLE_CAMERA = CAMERA.replace(
    "</clip>",
    "</clip><lens><type>equisolid_angle</type><cutoff_angle>1.2</cutoff_angle><env_texture_size>32</env_texture_size></lens>",
).replace("<horizontal_fov>1.5</horizontal_fov>", "<horizontal_fov>3.0</horizontal_fov>")

SEGMENTATION = CAMERA.replace('type="camera"', 'type="segmentation"').replace(
    "<camera>", "<camera><segmentation_type>panoptic</segmentation_type>"
)
BOUNDING_BOXES = CAMERA.replace('type="camera"', 'type="boundingbox_camera"').replace(
    "<camera>", "<camera><box_type>full_2d</box_type>"
)
LABEL = """<plugin name="gz::sim::systems::Label" filename="gz-sim-label-system"><label>9</label></plugin>"""

DIFF_DRIVE = """<plugin name="gz::sim::systems::DiffDrive" filename="gz-sim-diff-drive-system">
  <left_joint>left_wheel_joint</left_joint><right_joint>right_wheel_joint</right_joint>
  <wheel_separation>0.4</wheel_separation><wheel_radius>0.075</wheel_radius><odom_publish_frequency>50</odom_publish_frequency>
</plugin>"""
JOINT_STATES = """<plugin name="gz::sim::systems::JointStatePublisher" filename="gz-sim-joint-state-publisher-system">
  <update_rate>50</update_rate><joint_name>left_wheel_joint</joint_name><joint_name>right_wheel_joint</joint_name>
</plugin>"""
DETACHABLE = """<plugin name="gz::sim::systems::DetachableJoint" filename="gz-sim-detachable-joint-system">
  <parent_link>base_link</parent_link><child_model>cart</child_model><child_link>base</child_link>
</plugin>"""


def _sensor(kind: str, body: str, name: str | None = None) -> str:
    """A 50 Hz sensor of `kind` on its own key (its name), with `body`: its own element."""
    name = name or kind
    return f'<sensor name="{name}" type="{kind}"><update_rate>50</update_rate><topic>{name}</topic>{body}</sensor>'


def _axes(*tags: str) -> str:
    """Noisy `<x>` `<y>` `<z>` under each of `tags` (or bare when none)."""
    axes = "".join(f"<{a}>{_noise(0.01)}</{a}>" for a in "xyz")
    return "".join(f"<{t}>{axes}</{t}>" for t in tags) if tags else axes


LIDAR_3D = _lidar("gpu_lidar", "scanner3d").replace(
    "</horizontal>",
    "</horizontal><vertical><samples>4</samples><min_angle>-0.2</min_angle><max_angle>0.2</max_angle></vertical>",
)
ALTIMETER = _sensor(
    "altimeter",
    f"<altimeter><vertical_position>{_noise(0.01)}</vertical_position>"
    f"<vertical_velocity>{_noise(0.01)}</vertical_velocity></altimeter>",
)
AIR_PRESSURE = _sensor(
    "air_pressure",
    f"<air_pressure><reference_altitude>100</reference_altitude><pressure>{_noise(1.0)}</pressure></air_pressure>",
)
NAVSAT_WORLD = """<spherical_coordinates><surface_model>EARTH_WGS84</surface_model><latitude_deg>47.3</latitude_deg>
  <longitude_deg>8.5</longitude_deg><elevation>400</elevation><heading_deg>30</heading_deg></spherical_coordinates>"""


def _navsat(kind: str) -> str:
    tag = "gps" if kind == "gps" else "navsat"
    sensing = (
        f"<position_sensing><horizontal>{_noise(0.5)}</horizontal><vertical>{_noise(1.0)}</vertical></position_sensing>"
    )
    return _sensor(kind, f"<{tag}>{sensing}</{tag}>", "fix")


FORCE_TORQUE = f"""<link name="mast"><pose>-0.1 0 0.3 0 0 0</pose>
  <inertial><mass>1</mass><inertia><ixx>0.01</ixx><iyy>0.01</iyy><izz>0.01</izz></inertia></inertial></link>
<joint name="mast_joint" type="fixed"><parent>base_link</parent><child>mast</child>
  {_sensor("force_torque", f"<force_torque><frame>child</frame>{_axes('force', 'torque')}</force_torque>", "wrench")}
</joint>"""
CONTACT = _sensor("contact", "<contact><collision>skid</collision></contact>", "bump")


def _world_plugin(name: str) -> str:
    library = "".join(f"-{c.lower()}" if c.isupper() else c for c in name).lstrip("-")
    return f'<plugin name="gz::sim::systems::{name}" filename="gz-sim-{library}-system"/>'


@dataclass(frozen=True)
class Case:
    """What one entry point is built from, the key it must publish on (None: it publishes nothing of
    its own), and a command sent before the steps (key, message) so that it has something to do."""

    world_plugins: str = ""
    plugins: str = ""
    sensors: str = ""
    key: str | None = None
    command: tuple[str, Any] | None = None


# Gazebo's drive and joint systems (issue 15): the robot is `flexley_tug` in the running world.
BOT = "model/flexley_tug"
KNUCKLES = "".join(
    f"""<link name="{side}_knuckle"><pose>0.25 {y} 0.075 0 0 0</pose>
      <inertial><mass>0.2</mass><inertia><ixx>1e-4</ixx><iyy>1e-4</iyy><izz>1e-4</izz></inertia></inertial></link>
    <joint name="{side}_steer" type="revolute"><parent>base_link</parent><child>{side}_knuckle</child>
      <axis><xyz>0 0 1</xyz><limit><lower>-0.6</lower><upper>0.6</upper></limit></axis></joint>"""
    for side, y in (("left", 0.2), ("right", -0.2))
)
ACKERMANN = (
    KNUCKLES
    + """<plugin name="gz::sim::systems::AckermannSteering" filename="gz-sim-ackermann-steering-system">
  <left_joint>left_wheel_joint</left_joint><right_joint>right_wheel_joint</right_joint>
  <left_steering_joint>left_steer</left_steering_joint><right_steering_joint>right_steer</right_steering_joint>
  <wheel_separation>0.4</wheel_separation><kingpin_width>0.35</kingpin_width><wheel_base>0.35</wheel_base>
  <wheel_radius>0.075</wheel_radius><steer_p_gain>5</steer_p_gain>
</plugin>"""
)
MECANUM = """<plugin name="gz::sim::systems::MecanumDrive" filename="gz-sim-mecanum-drive-system">
  <front_left_joint>left_wheel_joint</front_left_joint><back_left_joint>left_wheel_joint</back_left_joint>
  <front_right_joint>right_wheel_joint</front_right_joint><back_right_joint>right_wheel_joint</back_right_joint>
  <wheelbase>0.35</wheelbase><wheel_separation>0.4</wheel_separation><wheel_radius>0.075</wheel_radius>
</plugin>"""
JOINT_CONTROLLER = """<plugin name="gz::sim::systems::JointController" filename="gz-sim-joint-controller-system">
  <joint_name>left_wheel_joint</joint_name><use_force_commands>true</use_force_commands><p_gain>0.5</p_gain>
</plugin>"""
JOINT_POSITION = """<plugin name="gz::sim::systems::JointPositionController"
  filename="gz-sim-joint-position-controller-system"><joint_name>right_wheel_joint</joint_name></plugin>"""
APPLY_FORCE = """<plugin name="gz::sim::systems::ApplyJointForce" filename="gz-sim-apply-joint-force-system">
  <joint_name>left_wheel_joint</joint_name></plugin>"""
ODOMETRY = """<plugin name="gz::sim::systems::OdometryPublisher" filename="gz-sim-odometry-publisher-system">
  <dimensions>3</dimensions><gaussian_noise>0.01</gaussian_noise></plugin>"""
VELOCITY = """<plugin name="gz::sim::systems::VelocityControl" filename="gz-sim-velocity-control-system"/>"""
DRIVE_CASES = {
    (GROUP, "AckermannSteering"): Case(
        plugins=ACKERMANN, key=f"{BOT}/odometry", command=(f"{BOT}/cmd_vel", messages.twist((0.3, 0, 0), (0, 0, 0.5)))
    ),
    (GROUP, "MecanumDrive"): Case(
        plugins=MECANUM, key=f"{BOT}/odometry", command=(f"{BOT}/cmd_vel", messages.twist((0.2, 0.1, 0), (0, 0, 0.3)))
    ),
    (GROUP, "JointController"): Case(
        plugins=JOINT_CONTROLLER + JOINT_STATES,
        command=(f"{BOT}/joint/left_wheel_joint/cmd_vel", messages.float64(2.0)),
    ),
    (GROUP, "JointPositionController"): Case(
        plugins=JOINT_POSITION + JOINT_STATES,
        command=(f"{BOT}/joint/right_wheel_joint/0/cmd_pos", messages.float64(0.5)),
    ),
    (GROUP, "ApplyJointForce"): Case(
        plugins=APPLY_FORCE + JOINT_STATES, command=(f"{BOT}/joint/left_wheel_joint/cmd_force", messages.float64(0.1))
    ),
    (GROUP, "OdometryPublisher"): Case(plugins=ODOMETRY, key=f"{BOT}/odometry"),
    (GROUP, "VelocityControl"): Case(
        plugins=VELOCITY, command=(f"{BOT}/cmd_vel", messages.twist((0.4, 0.0, 0.0), (0.0, 0.0, 0.5)))
    ),
}


def _actor(name: str, y: float, tension: float) -> str:
    """An actor walking across the world, its skin not found (drawn and cast at as its proxy)."""
    return f"""<actor name="{name}"><pose>0.8 {y} 1 0 0 0</pose><skin><filename>absent.dae</filename></skin>
  <script><delay_start>0.05</delay_start><trajectory id="0" type="walk" tension="{tension}">
  <waypoint><time>0</time><pose>0 0 0 0 0 0</pose></waypoint><waypoint><time>0.1</time><pose>0.3 0.2 0 0 0 1</pose></waypoint>
  <waypoint><time>0.15</time><pose>0.1 0.4 0 0 0 2</pose></waypoint></trajectory></script></actor>"""


ACTORS = _actor("walker", -0.5, 0.0) + _actor("runner", 0.5, 0.7)
FOLLOWER = """<actor name="follower"><pose>1 1 1 0 0 0</pose><skin><filename>absent.dae</filename></skin>
  <plugin name="gz::sim::systems::FollowActor" filename="gz-sim-follow-actor-system"><target>cart</target>
  <min_distance>0.5</min_distance><velocity>1.5</velocity></plugin></actor>"""


def _crowd_person(name: str, x: float) -> str:
    """A SocialForce person walking across to the other side of the origin (its jitter from its own stream)."""
    return f"""<actor name="{name}"><pose>{x} 0.6 1 0 0 0</pose><skin><filename>absent.dae</filename></skin>
  <script><trajectory id="0" type="walk"><waypoint><time>0</time><pose>0 0 0 0 0 0</pose></waypoint>
  <waypoint><time>2</time><pose>{-2 * x} 0 0 0 0 0</pose></waypoint></trajectory></script>
  <plugin name="simbot::systems::SocialForce" filename="simbot-social-force-system"/></actor>"""


CROWD = _crowd_person("walker", -0.8) + _crowd_person("runner", 0.8)
TRAJECTORY_FOLLOWER = """<plugin name="gz::sim::systems::TrajectoryFollower" filename="gz-sim-trajectory-follower-system">
  <link_name>base_link</link_name><loop>true</loop><force>20</force><torque>5</torque>
  <waypoints><waypoint>0.5 0.3</waypoint><waypoint>0 0.6</waypoint></waypoints></plugin>"""
RECOGNISED = ("Physics", "Sensors", "Imu", "SceneBroadcaster", "UserCommands", "Contact")
CASES: dict[tuple[str, str], Case] = {
    (GROUP, "DiffDrive"): Case(
        plugins=DIFF_DRIVE,
        key="model/flexley_tug/odometry",
        command=("model/flexley_tug/cmd_vel", messages.twist((0.3, 0.0, 0.0), (0.0, 0.0, 0.5))),
    ),
    (GROUP, "JointStatePublisher"): Case(plugins=JOINT_STATES, key="world/conformance/model/flexley_tug/joint_state"),
    (GROUP, "DetachableJoint"): Case(
        plugins=DETACHABLE,
        key="model/cart/detachable_joint/state",
        command=("model/flexley_tug/detachable_joint/attach", messages.empty()),
    ),
    **{(GROUP, name): Case(world_plugins=_world_plugin(name)) for name in RECOGNISED},
    **DRIVE_CASES,
    **{
        (SENSOR_GROUP, kind): Case(sensors=_lidar(kind), key="scanner")
        for kind in ("lidar", "gpu_lidar", "ray", "gpu_ray")
    },
    (SENSOR_GROUP, "imu"): Case(sensors=_imu(), key="imu"),
    (SENSOR_GROUP, "camera"): Case(sensors=CAMERA, key="eye"),
    **{
        (SENSOR_GROUP, kind): Case(sensors=CAMERA.replace('type="camera"', f'type="{kind}"'), key="eye")
        for kind in ("depth", "depth_camera")
    },
    **{
        (SENSOR_GROUP, kind): Case(sensors=CAMERA.replace('type="camera"', f'type="{kind}"'), key="eye/points")
        for kind in ("rgbd", "rgbd_camera")
    },
    (GROUP, "Thermal"): Case(plugins=HOT, sensors=THERMAL, key="eye"),
    **{
        (SENSOR_GROUP, kind): Case(sensors=THERMAL.replace('type="thermal"', f'type="{kind}"'), key="eye")
        for kind in ("thermal", "thermal_camera")
    },
    **{
        (SENSOR_GROUP, kind): Case(sensors=WIDE_ANGLE_CAMERA.replace('type="camera"', f'type="{kind}"'), key="eye")
        for kind in ("wideanglecamera", "wide_angle_camera")
    },
    # the sensors of issue 15 item 7: each with noise on every channel it has
    (SENSOR_GROUP, "altimeter"): Case(sensors=ALTIMETER, key="altimeter"),
    (SENSOR_GROUP, "magnetometer"): Case(
        sensors=_sensor("magnetometer", f"<magnetometer>{_axes()}</magnetometer>"), key="magnetometer"
    ),
    (SENSOR_GROUP, "air_pressure"): Case(sensors=AIR_PRESSURE, key="air_pressure"),
    **{
        (SENSOR_GROUP, kind): Case(world_plugins=NAVSAT_WORLD, sensors=_navsat(kind), key="fix")
        for kind in ("navsat", "gps")
    },
    (SENSOR_GROUP, "force_torque"): Case(plugins=FORCE_TORQUE, key="wrench"),
    (SENSOR_GROUP, "contact"): Case(sensors=CONTACT, key="bump"),
    # the dataset cameras of issue 26, and the Label they read (on the robot: its camera sees its own base)
    (SENSOR_GROUP, "segmentation"): Case(sensors=SEGMENTATION, key="eye/labels_map"),
    (SENSOR_GROUP, "boundingbox_camera"): Case(sensors=BOUNDING_BOXES, key="eye"),
    (GROUP, "Label"): Case(plugins=LABEL, sensors=SEGMENTATION, key="eye/labels_map"),
    (WORLD_GROUP, "ClockPublisher"): Case(key="clock"),
    (WORLD_GROUP, "PosePublisher"): Case(key="model/cart/pose"),
    (WORLD_GROUP, "Rendering"): Case(sensors=CAMERA, key="eye"),
    # the scene goes out once (latched, on change); the moving robot's frames go on tf every period
    (WORLD_GROUP, "ScenePublisher"): Case(key="tf"),
    # the map goes out once (latched, at the first step: the static models do not change here), so no
    # key of its own is asked twice; its one message is among the keys whose bytes both runs compare
    (WORLD_GROUP, "MapPublisher"): Case(),
    (GROUP, "FollowActor"): Case(world_plugins=FOLLOWER, key="model/follower/pose"),
    (GROUP, "SocialForce"): Case(world_plugins=CROWD, key="model/runner/pose"),
    (GROUP, "TrajectoryFollower"): Case(plugins=TRAJECTORY_FOLLOWER, key="model/flexley_tug/pose"),
    (WORLD_GROUP, "Actors"): Case(world_plugins=ACTORS, sensors=_lidar("gpu_lidar"), key="model/runner/pose"),
    (ROBOT_GROUP, "RobotStatePublisher"): Case(key="tf"),
}
"""One SDF per entry point of simbot's own. A new one fails `test_entry_point_is_deterministic` until
it has one here; another package's plug-in (the example in examples/) is its own tests' business."""

ENTRY_POINTS = sorted(
    (group, point.name)
    for group in (GROUP, SENSOR_GROUP, WORLD_GROUP, ROBOT_GROUP)
    for point in entry_points(group=group)
    if point.value.startswith("simbot.")
)


def _config(tmp: Path, case: Case, seed: int) -> ServerConfig:
    """The case's world and robot written to `tmp`; a lockstep server of them at the origin."""
    tmp.mkdir()
    world, robot = tmp / "world.sdf", tmp / "robot.sdf"
    world.write_text(WORLD.format(world_plugins=case.world_plugins))
    robot.write_text(ROBOT.format(plugins=case.plugins, sensors=case.sensors))
    return ServerConfig(world, robot, (0.0, 0.0, 0.0, 0.0), Mode.LOCKSTEP, seed, {"rendering.workers": 1})


def _command(server: Server, node: Node, topic: str, message: Any) -> None:
    """Put one command and wait until its input has it, so that the first step applies it in every run."""
    node.session.put(node.data_key(topic, message.__msgtype__), encode(message))
    inputs = [i for i in server.bus.inputs if i.key == node.key(topic)]
    wait_until(lambda: inputs and all(i.received for i in inputs), 5.0, f"{topic} at its input")


def run(tmp: Path, case: Case, seed: int, created: str | None = None) -> Published:
    """Every payload published on the namespace, by key, from the server's start through STEPS steps
    (with the model `created`, an SDF, created through world control's call before step CREATED_AT).

    The subscriber is on the server's own session, declared before the server is built, so it gets
    the latched messages of construction too and nothing is lost in transport; a marker put after
    the last step is waited for, so a loaded machine's late deliveries are counted too.
    """
    published: Published = {}
    config = _config(tmp, case, seed)
    with Node(BusOptions(listen=(endpoint(free_port()),), namespace=unique_namespace()), "server") as node:
        prefix = len(node.namespace) + 1

        def keep(sample: zenoh.Sample) -> None:
            name = node.graph.name_of(str(sample.key_expr)) or str(sample.key_expr).removeprefix("0/")
            published.setdefault(name[prefix:], []).append(sample.payload.to_bytes())

        subscriber = node.session.declare_subscriber(f"0/{node.namespace}/**", keep)
        server = Server(config, node)
        try:
            if case.command is not None:
                _command(server, node, *case.command)
            for step in range(STEPS):
                if created is not None and step == CREATED_AT:
                    server.world.create(CreateRequest(None, created, None, "", None, False))
                server.sim.step()
            # everything put before the marker has been handed to `keep` once the marker has
            node.session.put(f"0/{node.namespace}/{FLUSH}", b"")
            wait_until(lambda: FLUSH in published, 10.0, "the flush marker, after every message of the run")
            del published[FLUSH]
        finally:
            # the run ends at the marker: what closing puts (a joint let go) is not part of it
            subscriber.undeclare()
            server.close()
    return published


@pytest.mark.parametrize(("group", "name"), ENTRY_POINTS, ids=[f"{g}:{n}" for g, n in ENTRY_POINTS])
def test_entry_point_is_deterministic(group: str, name: str, tmp_path: Path) -> None:
    """Two lockstep runs with one seed publish the same bytes on every key; the system's own key among them."""
    case = CASES.get((group, name))
    assert case is not None, f"entry point {name!r} of {group} has no conformance SDF: add a Case for it to CASES"
    first, second = run(tmp_path / "first", case, SEED), run(tmp_path / "second", case, SEED)
    if case.key is not None:
        assert len(first.get(case.key, [])) >= 2, (
            f"{name} published {len(first.get(case.key, []))} messages on {case.key}"
        )
    assert first.keys() == second.keys()
    for key in first:
        assert first[key] == second[key], f"{key}: the runs differ"


def test_a_3d_lidar_publishes_its_cloud_deterministically(tmp_path: Path) -> None:
    """A 4-row lidar: the middle-plane scan and the cloud on `<topic>/points`, the same in two runs."""
    case = Case(sensors=LIDAR_3D, key="scanner3d/points")
    first, second = run(tmp_path / "first", case, SEED), run(tmp_path / "second", case, SEED)
    assert len(first["scanner3d"]) >= 2 and len(first["scanner3d/points"]) >= 2
    assert first == second


def test_every_case_is_a_registered_entry_point() -> None:
    """No stale case: each names an entry point that is installed."""
    assert set(CASES) <= set(ENTRY_POINTS), sorted(set(CASES) - set(ENTRY_POINTS))


def test_a_sensors_noise_depends_on_the_seed_and_its_own_name(tmp_path: Path) -> None:
    """The IMU's samples stay byte for byte the same when a noisy lidar and a plugin are added before it,
    and change with the seed."""
    alone = Case(sensors=_imu(), key="imu")
    crowded = Case(plugins=JOINT_STATES, sensors=_lidar("gpu_lidar", "another") + _imu(), key="imu")
    base = run(tmp_path / "alone", alone, SEED)["imu"]
    assert run(tmp_path / "crowded", crowded, SEED)["imu"] == base
    reseeded = run(tmp_path / "reseeded", alone, SEED + 1)["imu"]
    assert len(reseeded) == len(base) and all(a != b for a, b in zip(reseeded, base))
    spread = np.std([decode(data, "sensor_msgs/msg/Imu").angular_velocity.x for data in base])
    assert 0.01 < spread < 0.04  # the SDF's σ 0.02 on a robot at rest: the noise is there


def test_scoped_rng_is_a_function_of_seed_and_name() -> None:
    """Same seed and scope, same stream; another name or seed, another stream."""
    draw = [scoped_rng(seed, *scope).integers(2**62, size=4).tolist() for seed, scope in (
        (1, ("m", "l", "s")), (1, ("m", "l", "s")), (2, ("m", "l", "s")), (1, ("m", "l", "t")), (1, ("m", "l/s")),
    )]  # fmt: skip
    assert draw[0] == draw[1]
    assert len({tuple(d) for d in draw[1:]}) == 4


@pytest.mark.parametrize("kind", ["camera", "segmentation"])
def test_a_camera_created_at_run_time_publishes_its_first_frame_at_its_first_tick(kind: str, tmp_path: Path) -> None:
    """A model created between steps starts a render worker's session for its camera (a fresh pool
    here: the world has no other camera): its first frame is the one of the first step after it
    came, in both seeded runs, however late that session hears of the subscriber (issue 46)."""
    sensor = CASES[(SENSOR_GROUP, kind)].sensors.replace('name="eye"', 'name="watch"').replace(">eye<", ">watch<")
    watcher, key = WATCHER.format(camera=sensor), "watch" if kind == "camera" else "watch/labels_map"
    first, second = (run(tmp_path / side, Case(sensors=_imu()), SEED, watcher) for side in ("a", "b"))
    frames = first.get(key, [])
    stamps = [decode(payload, "sensor_msgs/msg/Image").header.stamp for payload in frames]
    assert len(stamps) >= 4, f"{key}: {len(stamps)} frames"
    assert (stamps[0].sec, stamps[0].nanosec) == (0, (CREATED_AT + 1) * 1_000_000), stamps[0]
    assert first.keys() == second.keys()
    assert [key for key in first if first[key] != second[key]] == []
