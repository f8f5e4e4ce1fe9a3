"""Gazebo's drive and joint systems against their physics, on a real server in lockstep.

Each test builds a tiny robot for one system (a car with steered front wheels, a mecanum
platform, an arm on a vertical hinge), runs `Server` in this process on a real PyBullet world
and a real Zenoh session (fresh loopback port, own namespace), sends the system's command on its
Gazebo key, steps, and compares what the physics did (ground truth from the world) and what the
system published with what the kinematics or dynamics predict. Tolerances come from the
physics: the integrator's step (1 ms), the wheel friction's regularising slip, the controller's gains.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import zenoh
from bus_helpers import endpoint, free_port, unique_namespace, wait_until
from server_helpers import dropped

from simbot.bus import BusOptions, Node, decode, encode, messages
from simbot.sim.loop.simulation import Mode
from simbot.sim.server import ROBOT_NAME, Server, ServerConfig
from simbot.transform import yaw_of

BOT = f"model/{ROBOT_NAME}"
STEP_S = 0.001

WORLD = """<?xml version="1.0"?>
<sdf version="1.9">
  <world name="drive">
    <physics name="1ms" type="ignore"><max_step_size>0.001</max_step_size></physics>
    <model name="ground_plane">
      <static>true</static>
      <link name="link">
        <collision name="c"><geometry><plane><normal>0 0 1</normal><size>50 50</size></plane></geometry></collision>
      </link>
    </model>
  </world>
</sdf>
"""


def _inertial(mass: float, ixx: float, iyy: float, izz: float) -> str:
    return (
        f"<inertial><mass>{mass}</mass><inertia><ixx>{ixx}</ixx><iyy>{iyy}</iyy><izz>{izz}</izz></inertia></inertial>"
    )


def _wheel(name: str, xyz: tuple[float, float, float], radius: float, surface: str = "") -> str:
    """A wheel link whose axis (its z) points along the model's y."""
    x, y, z = xyz
    return f"""<link name="{name}"><pose>{x} {y} {z} -1.5707963 0 0</pose>{_inertial(1.0, 0.005, 0.005, 0.008)}
      <collision name="c"><geometry><cylinder><radius>{radius}</radius><length>0.05</length></cylinder></geometry>
      {surface}</collision></link>"""


def _hinge(name: str, parent: str, child: str, xyz: str = "0 0 1", limits: str = "") -> str:
    return f"""<joint name="{name}" type="revolute"><parent>{parent}</parent><child>{child}</child>
      <axis><xyz>{xyz}</xyz>{limits}</axis></joint>"""


def _robot(body: str) -> str:
    return f'<?xml version="1.0"?><sdf version="1.9"><model name="bot">{body}</model></sdf>'


@dataclass
class Rig:
    """A lockstep server of one robot in a flat world, with a client on its own session."""

    server: Server
    node: Node
    received: dict[str, list[Any]] = field(default_factory=dict)

    def send(self, topic: str, message: Any) -> None:
        """Puts a command and waits until the server's input holds it: the next step applies it."""
        self.node.session.put(self.node.data_key(topic, message.__msgtype__), encode(message))
        inputs = [i for i in self.server.bus.inputs if i.key == self.node.key(topic)]
        assert inputs, f"no system takes {topic}"
        wait_until(lambda: all(i.received for i in inputs), 5.0, f"{topic} at its input")

    def step(self, seconds: float) -> None:
        for _ in range(round(seconds / self.server.physics.step_size)):
            self.server.sim.step()

    def pose(self) -> tuple[float, float, float]:
        """Ground truth: the model frame's (x, y, yaw) in the world."""
        (x, y, _), quat = self.server.physics.model_pose(ROBOT_NAME)
        return x, y, yaw_of(quat)

    def joints(self, *names: str) -> list[tuple[float, float, float]]:
        return self.server.physics.joint_states(ROBOT_NAME, list(names))

    def collect(self, topic: str, typename: str) -> list[Any]:
        """Every message on `topic` from now on, decoded (delivered on the server's own session)."""
        inbox = self.received.setdefault(topic, [])

        def keep(sample: zenoh.Sample) -> None:
            inbox.append(decode(sample.payload.to_bytes(), typename))

        self.node.session.declare_subscriber(self.node.data_key(topic, typename), keep)
        self.node.refresh_subscribers()  # the server's publishers know of it before the next step
        return inbox


@contextmanager
def lockstep(tmp_path: Path, robot: str, spawn_z: float = 0.0, kinematic: bool = False) -> Iterator[Rig]:
    """The robot alone in a flat world, in lockstep; `kinematic`: moved by its drive's command
    (simbot.sim.physics.kinematic_world) at 5 ms steps, where a dynamic world steps at 1 ms."""
    (tmp_path / "world.sdf").write_text(WORLD)
    (tmp_path / "robot.sdf").write_text(robot)
    spawn = (0.0, 0.0, spawn_z, 0.0)
    config = ServerConfig(tmp_path / "world.sdf", tmp_path / "robot.sdf", spawn, Mode.LOCKSTEP, kinematic=kinematic)
    with Node(BusOptions(listen=(endpoint(free_port()),), namespace=unique_namespace()), "server") as node:
        server = Server(config, node)
        try:
            yield Rig(server, node)
        finally:
            server.close()


def fit_circle(points: np.ndarray) -> tuple[float, float, float]:
    """(cx, cy, r) of the least-squares circle through N×2 points (Kåsa's algebraic fit)."""
    x, y = points[:, 0], points[:, 1]
    a = np.column_stack([x, y, np.ones_like(x)])
    cx2, cy2, c = np.linalg.lstsq(a, x**2 + y**2, rcond=None)[0]
    cx, cy = cx2 / 2, cy2 / 2
    return float(cx), float(cy), float(math.sqrt(c + cx**2 + cy**2))


# --- joints: an arm on a vertical hinge, its centre of mass on the axis ----------------------

ARM_INERTIA = 0.01
"""kg·m² about the hinge; gravity exerts no torque about a vertical axis."""


def _arm(plugin: str) -> str:
    return _robot(f"""
      <joint name="anchor" type="fixed"><parent>world</parent><child>base</child></joint>
      <link name="base"><pose>0 0 0.5 0 0 0</pose>{_inertial(5.0, 0.1, 0.1, 0.1)}</link>
      <link name="arm"><pose>0 0 0.6 0 0 0</pose>{_inertial(0.5, 1e-4, ARM_INERTIA, ARM_INERTIA)}
        <collision name="c"><geometry><box><size>0.4 0.04 0.04</size></box></geometry></collision></link>
      {_hinge("hinge", "base", "arm")}
      {plugin}""")


def test_apply_joint_force_accelerates_the_joint_as_torque_over_inertia(tmp_path: Path) -> None:
    """τ = 0.05 N·m on I = 0.01 kg·m² from rest, held from the command on: ω = τt/I, and θ = τt²/2I
    as the semi-implicit Euler integrator of 1 ms steps sums it (n(n+1)/2 steps of αdt², +0.1 %)."""
    torque, seconds = 0.05, 1.0
    plugin = """<plugin name="gz::sim::systems::ApplyJointForce" filename="gz-sim-apply-joint-force-system">
      <joint_name>hinge</joint_name></plugin>"""
    with lockstep(tmp_path, _arm(plugin)) as rig:
        rig.send(f"{BOT}/joint/hinge/cmd_force", messages.float64(torque))
        rig.step(seconds)
        angle, speed, _ = rig.joints("hinge")[0]
    assert speed == pytest.approx(torque * seconds / ARM_INERTIA, rel=1e-6)
    assert angle == pytest.approx(torque * seconds * (seconds + STEP_S) / (2 * ARM_INERTIA), rel=1e-6)


def _controller(name: str, params: str) -> str:
    library = "".join(f"-{c.lower()}" if c.isupper() else c for c in name).lstrip("-")
    return f"""<plugin name="gz::sim::systems::{name}" filename="gz-sim-{library}-system">
      <joint_name>hinge</joint_name>{params}</plugin>"""


def test_joint_position_controller_settles_as_a_critically_damped_joint(tmp_path: Path) -> None:
    """Gains p = 1 N·m/rad and d = 0.2 N·m·s/rad on I = 0.01 kg·m² (i = 0): ω₀ = √(p/I) = 10 rad/s,
    ζ = d/(2√(pI)) = 1. From rest toward 1 rad: θ(t) = 1 − (1 + ω₀t)e^(−ω₀t) (0.594 at 0.2 s), then
    at the target (error 16e^(−15) at 1.5 s). The 1 ms explicit step shifts the curve by about ω₀·dt = 1 %."""
    gains = "<p_gain>1</p_gain><i_gain>0</i_gain><d_gain>0.2</d_gain>"
    with lockstep(tmp_path, _arm(_controller("JointPositionController", gains))) as rig:
        rig.send(f"{BOT}/joint/hinge/0/cmd_pos", messages.float64(1.0))
        rig.step(0.2)
        early = rig.joints("hinge")[0][0]
        rig.step(1.3)
        late = rig.joints("hinge")[0][0]
    assert early == pytest.approx(1 - 3 * math.exp(-2), abs=0.01)
    assert late == pytest.approx(1.0, abs=1e-3)


def test_joint_position_controller_by_velocity_moves_at_cmd_max(tmp_path: Path) -> None:
    """use_velocity_commands with cmd_max 2 rad/s: 1 rad away, the joint runs at 2 rad/s (0.4 rad
    after 0.2 s) and then stops on the target, closing the last step's error in one step."""
    params = "<use_velocity_commands>true</use_velocity_commands><cmd_max>2</cmd_max>"
    with lockstep(tmp_path, _arm(_controller("JointPositionController", params))) as rig:
        rig.send(f"{BOT}/joint/hinge/0/cmd_pos", messages.float64(1.0))
        rig.step(0.2)
        early, speed, _ = rig.joints("hinge")[0]
        rig.step(0.5)
        late = rig.joints("hinge")[0]
    assert (early, speed) == pytest.approx((0.4, 2.0), abs=2 * STEP_S * 2.0)
    assert late[:2] == pytest.approx((1.0, 0.0), abs=1e-6)


def test_joint_controller_holds_the_commanded_velocity(tmp_path: Path) -> None:
    """Velocity mode: the hinge turns at the command from the first step (an exact velocity command)."""
    with lockstep(tmp_path, _arm(_controller("JointController", ""))) as rig:
        rig.send(f"{BOT}/joint/hinge/cmd_vel", messages.float64(3.0))
        rig.step(0.5)
        angle, speed, _ = rig.joints("hinge")[0]
    assert speed == pytest.approx(3.0, rel=1e-6)
    assert angle == pytest.approx(1.5, abs=3.0 * STEP_S)


def test_joint_controller_by_force_is_a_first_order_lag(tmp_path: Path) -> None:
    """Force mode, p = 0.1 N·m·s/rad on I = 0.01 kg·m²: I·dω/dt = −p(ω − ω*), so ω reaches
    ω*(1 − e^(−t/τ)) with τ = I/p = 0.1 s: 63.2 % at τ, 99.3 % at 5τ (1 ms steps: ±1 %)."""
    params = "<use_force_commands>true</use_force_commands><p_gain>0.1</p_gain>"
    with lockstep(tmp_path, _arm(_controller("JointController", params))) as rig:
        rig.send(f"{BOT}/joint/hinge/cmd_vel", messages.float64(2.0))
        rig.step(0.1)
        at_tau = rig.joints("hinge")[0][1]
        rig.step(0.4)
        at_five_tau = rig.joints("hinge")[0][1]
    assert at_tau == pytest.approx(2.0 * (1 - math.exp(-1)), rel=0.01)
    assert at_five_tau == pytest.approx(2.0 * (1 - math.exp(-5)), rel=0.01)


# --- the model as a whole: a box in the air, moved by VelocityControl -------------------------

FLYER_Z = 1.0
VELOCITY_CONTROL = '<plugin name="gz::sim::systems::VelocityControl" filename="gz-sim-velocity-control-system"/>'
ODOMETRY_PUBLISHER = """<plugin name="gz::sim::systems::OdometryPublisher" filename="gz-sim-odometry-publisher-system">
  <odom_publish_frequency>50</odom_publish_frequency></plugin>"""


def _flyer(plugins: str) -> str:
    return _robot(f"""<link name="body">{_inertial(2.0, 0.02, 0.02, 0.03)}
      <collision name="c"><geometry><box><size>0.4 0.3 0.1</size></box></geometry></collision></link>{plugins}""")


def test_velocity_control_moves_the_model_at_the_commanded_twist(tmp_path: Path) -> None:
    """v = 0.5 m/s forward turning at ω = 0.5 rad/s: an arc of radius v/ω = 1 m, so after 2 s the
    model is at (sin 1, 1 − cos 1) heading 1 rad. The integrator moves each 1 ms step along the
    step's starting heading: a lag of ωdt/2 = 0.25 mrad, 0.3 mm of the path. Gravity acts within
    each step and is undone at the next: the model sinks g·dt per second (19.6 mm in 2 s)."""
    with lockstep(tmp_path, _flyer(VELOCITY_CONTROL), spawn_z=FLYER_Z) as rig:
        rig.send(f"{BOT}/cmd_vel", messages.twist((0.5, 0.0, 0.0), (0.0, 0.0, 0.5)))
        rig.step(2.0)
        x, y, yaw = rig.pose()
        z = rig.server.physics.model_pose(ROBOT_NAME)[0][2]
    assert (x, y) == pytest.approx((math.sin(1.0), 1 - math.cos(1.0)), abs=1e-3)
    assert yaw == pytest.approx(1.0, abs=1e-3)
    assert FLYER_Z - z == pytest.approx(9.81 * STEP_S * 2.0, abs=1e-3)


def test_odometry_publisher_reports_the_true_pose_and_body_twist(tmp_path: Path) -> None:
    """On a model moved by VelocityControl (0.3 m/s forward, 0.2 m/s left, 0.4 rad/s), every
    odometry message equals the ground truth at its stamp: the pose in the world, the twist in
    the body's axes, the commanded one (the frames and keys are Gazebo's defaults). VelocityControl
    sets the world velocity at the step's start; the body has turned ω·dt = 0.4 mrad by its end,
    so the twist reads turned by that much: 0.36 m/s × 0.4 mrad = 0.14 mm/s."""
    with lockstep(tmp_path, _flyer(VELOCITY_CONTROL + ODOMETRY_PUBLISHER), spawn_z=FLYER_Z) as rig:
        odometry = rig.collect(f"{BOT}/odometry", "nav_msgs/msg/Odometry")
        rig.send(f"{BOT}/cmd_vel", messages.twist((0.3, 0.2, 0.0), (0.0, 0.0, 0.4)))
        rig.step(1.0)
        truth = rig.pose()
        wait_until(lambda: len(odometry) >= 50, 5.0, "50 odometry messages in 1 s at 50 Hz")
    last = odometry[-1]
    assert (last.header.frame_id, last.child_frame_id) == (f"{ROBOT_NAME}/odom", f"{ROBOT_NAME}/base_footprint")
    assert messages.stamp_ns(last.header) == 1_000_000_000
    position, orientation = last.pose.pose.position, last.pose.pose.orientation
    yaw = yaw_of((orientation.x, orientation.y, orientation.z, orientation.w))
    assert (position.x, position.y, yaw) == pytest.approx(truth, abs=1e-6)
    twist = last.twist.twist
    assert (twist.linear.x, twist.linear.y, twist.angular.z) == pytest.approx((0.3, 0.2, 0.4), abs=2e-4)


def test_odometry_publisher_refuses_a_fourth_dimension(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    plugin = ODOMETRY_PUBLISHER.replace(
        "<odom_publish_frequency>", "<dimensions>4</dimensions><odom_publish_frequency>"
    )
    with lockstep(tmp_path, _flyer(plugin)) as rig:
        rig.server.sim.step()
    (line,) = dropped(caplog)
    assert "OdometryPublisher: <dimensions> must be 2 or 3" in line


# --- AckermannSteering: a car with steered front wheels ----------------------------------------

WHEEL_BASE, TRACK, KINGPINS, WHEEL_RADIUS = 0.8, 0.6, 0.5, 0.1


def _car() -> str:
    """Rear wheels driven on the model origin's axle, front wheels free on steered knuckles."""
    knuckles = "".join(
        f"""<link name="{side}_knuckle"><pose>{WHEEL_BASE} {sign * KINGPINS / 2} {WHEEL_RADIUS} 0 0 0</pose>
          {_inertial(0.5, 1e-3, 1e-3, 1e-3)}</link>
        {_hinge(f"{side}_steer", "chassis", f"{side}_knuckle", limits="<limit><lower>-0.7</lower><upper>0.7</upper></limit>")}
        {_wheel(f"front_{side}", (WHEEL_BASE, sign * TRACK / 2, WHEEL_RADIUS), WHEEL_RADIUS)}
        {_hinge(f"front_{side}_axle", f"{side}_knuckle", f"front_{side}")}
        {_wheel(f"rear_{side}", (0.0, sign * TRACK / 2, WHEEL_RADIUS), WHEEL_RADIUS)}
        {_hinge(f"rear_{side}_axle", "chassis", f"rear_{side}")}"""
        for side, sign in (("left", 1), ("right", -1))
    )
    return _robot(f"""<link name="chassis"><pose>{WHEEL_BASE / 2} 0 {WHEEL_RADIUS} 0 0 0</pose>
        {_inertial(20.0, 0.3, 1.7, 2.0)}
        <collision name="c"><geometry><box><size>1.0 0.4 0.08</size></box></geometry></collision></link>
      {knuckles}
      <plugin name="gz::sim::systems::AckermannSteering" filename="gz-sim-ackermann-steering-system">
        <left_joint>rear_left_axle</left_joint><right_joint>rear_right_axle</right_joint>
        <left_steering_joint>left_steer</left_steering_joint><right_steering_joint>right_steer</right_steering_joint>
        <wheel_base>{WHEEL_BASE}</wheel_base><wheel_separation>{TRACK}</wheel_separation>
        <kingpin_width>{KINGPINS}</kingpin_width><wheel_radius>{WHEEL_RADIUS}</wheel_radius>
        <steering_limit>0.6</steering_limit><steer_p_gain>10</steer_p_gain>
      </plugin>""")


@pytest.mark.parametrize("kinematic", [False, True], ids=["dynamic", "kinematic"])
def test_ackermann_car_turns_on_the_radius_of_its_wheelbase_and_steering(tmp_path: Path, kinematic: bool) -> None:
    """v = 0.5 m/s, ω = 0.25 rad/s: R = v/ω = 2 m, the bicycle angle φ = atan(L/R). The rear axle's
    centre (the model origin) must run on a circle of radius L/tan φ, both as commanded and as the
    steering joints' angles give it (cot φ = the mean of their cotangents), within 5 %; odometry
    from the rear wheels and the steering must end within 5 % of the path of the true pose. The
    same holds kinematically, where the base turns at v·k as the drive commands."""
    with lockstep(tmp_path, _car(), kinematic=kinematic) as rig:
        odometry = rig.collect(f"{BOT}/odometry", "nav_msgs/msg/Odometry")
        rig.send(f"{BOT}/cmd_vel", messages.twist((0.5, 0.0, 0.0), (0.0, 0.0, 0.25)))
        rig.step(1.5)  # the steering settles: 10/s of gain, 15 time constants
        path = []
        for _ in range(120):
            rig.step(0.05)
            path.append(rig.pose()[:2])
        left, right = (state[0] for state in rig.joints("left_steer", "right_steer"))
        truth = rig.pose()
        wait_until(lambda: len(odometry) >= 7.5 * 50 - 1, 5.0, "odometry at 50 Hz")
    *_, radius = fit_circle(np.array(path))
    cot_phi = (1 / math.tan(left) + 1 / math.tan(right)) / 2
    assert left > right > 0  # the inner (left) wheel steers more
    assert radius == pytest.approx(2.0, rel=0.05)
    assert radius == pytest.approx(WHEEL_BASE * cot_phi, rel=0.05)
    end = odometry[-1].pose.pose.position
    travelled = 0.5 * 7.5
    assert math.dist((end.x, end.y), truth[:2]) < 0.05 * travelled


# --- MecanumDrive: four wheels whose rollers push at 45° ---------------------------------------

MECANUM_RADIUS = 0.06


def _mecanum() -> str:
    """Gazebo's mecanum example in small: μ 1 along fdir1 (at 45° in the chassis frame), μ2 0 across."""
    corners = (("front_left", 0.25, 0.25, "1 -1 0"), ("front_right", 0.25, -0.25, "1 1 0"),
               ("back_left", -0.25, 0.25, "1 1 0"), ("back_right", -0.25, -0.25, "1 -1 0"))  # fmt: skip
    wheels = "".join(
        _wheel(
            name,
            (x, y, MECANUM_RADIUS),
            MECANUM_RADIUS,
            f"<surface><friction><ode><mu>1</mu><mu2>0</mu2><fdir1>{fdir1}</fdir1></ode></friction></surface>",
        )  # fmt: skip
        + _hinge(f"{name}_joint", "chassis", name)
        for name, x, y, fdir1 in corners
    )
    joints = "".join(f"<{name}_joint>{name}_joint</{name}_joint>" for name, *_ in corners)
    return _robot(f"""<link name="chassis"><pose>0 0 {MECANUM_RADIUS + 0.02} 0 0 0</pose>
        {_inertial(10.0, 0.15, 0.3, 0.4)}
        <collision name="c"><geometry><box><size>0.6 0.4 0.04</size></box></geometry></collision></link>
      {wheels}
      <plugin name="gz::sim::systems::MecanumDrive" filename="gz-sim-mecanum-drive-system">{joints}
        <wheelbase>0.5</wheelbase><wheel_separation>0.5</wheel_separation><wheel_radius>{MECANUM_RADIUS}</wheel_radius>
      </plugin>""")


@pytest.mark.parametrize("kinematic", [False, True], ids=["dynamic", "kinematic"])
def test_mecanum_platform_moves_sideways_at_the_commanded_speed(tmp_path: Path, kinematic: bool) -> None:
    """linear.y = 0.3 m/s alone: the wheels turn ∓5 rad/s in pairs and the rollers carry the
    platform sideways at 0.3 m/s, without going forward or turning. The wheel friction saturates at
    0.01 m/s of slip (3 % of the speed); nothing resists steady motion, so the slip, and the
    error, stay well below that: 5 % for the speed, 2 cm and 0.02 rad of drift over 2 m.
    Odometry from the four encoders follows the same path, kinematically too."""
    with lockstep(tmp_path, _mecanum(), kinematic=kinematic) as rig:
        odometry = rig.collect(f"{BOT}/odometry", "nav_msgs/msg/Odometry")
        rig.send(f"{BOT}/cmd_vel", messages.twist((0.0, 0.3, 0.0), (0.0, 0.0, 0.0)))
        rig.step(1.0)
        start = rig.pose()
        rig.step(5.0)
        end = rig.pose()
        wait_until(lambda: len(odometry) >= 6 * 50 - 1, 5.0, "odometry at 50 Hz")
    assert (end[1] - start[1]) / 5.0 == pytest.approx(0.3, rel=0.05)
    assert end[0] - start[0] == pytest.approx(0.0, abs=0.02)
    assert end[2] == pytest.approx(0.0, abs=0.02)
    odom = odometry[-1].pose.pose.position
    assert math.dist((odom.x, odom.y), end[:2]) < 0.05 * 1.8


# --- bad parameters: one line naming the plugin and the element ----------------------------------


def _plugin(name: str, body: str) -> str:
    library = "".join(f"-{c.lower()}" if c.isupper() else c for c in name).lstrip("-")
    return f'<plugin name="gz::sim::systems::{name}" filename="gz-sim-{library}-system">{body}</plugin>'


@pytest.mark.parametrize(
    ("plugin", "message"),
    [
        (_plugin("ApplyJointForce", ""), r"ApplyJointForce: needs at least one <joint_name>"),
        (_plugin("JointController", "<joint_name>elbow</joint_name>"), r"<joint_name> 'elbow': model 'bot' has no"),
        (
            _plugin("JointController", "<joint_name>hinge</joint_name><use_actuator_msg>true</use_actuator_msg>"),
            r"JointController: <use_actuator_msg> is not supported",
        ),
        (
            _plugin("JointPositionController", "<joint_name>hinge</joint_name><p_gain>stiff</p_gain>"),
            r"JointPositionController: <p_gain> expected a number, got 'stiff'",
        ),
        (
            _plugin("JointPositionController", "<joint_name>hinge</joint_name><joint_index>1</joint_index>"),
            r"JointPositionController: <joint_index> must be 0",
        ),
        (
            _plugin("VelocityControl", "<initial_linear>1 0</initial_linear>"),
            r"<initial_linear> expected three numbers",
        ),
        (_plugin("VelocityControl", "<link_name>arm</link_name>"), r"VelocityControl: <link_name> .* not supported"),
        (
            _plugin("MecanumDrive", "<front_left_joint>hinge</front_left_joint>"),
            r"needs at least one <front_right_joint>",
        ),
        (
            _plugin("AckermannSteering", "<left_joint>hinge</left_joint><right_joint>hinge</right_joint>"),
            r"AckermannSteering: needs at least one <left_steering_joint>",
        ),
    ],
)
def test_bad_parameters_are_one_line_errors_naming_plugin_and_element(
    tmp_path: Path, plugin: str, message: str, caplog: pytest.LogCaptureFixture
) -> None:
    """The plugin is left out with one line naming it and the element; the rest of the world runs."""
    with lockstep(tmp_path, _arm(plugin)) as rig:
        rig.server.sim.step()
    (line,) = dropped(caplog)
    assert re.search(message, line) and "\n" not in line, line


def test_ackermann_steering_only_turns_the_wheels_to_the_commanded_angle(tmp_path: Path) -> None:
    """steering_only: a Float64 bicycle angle a on `steer_angle`; the left (inner) and right wheels
    settle at atan(2L·sin a / (2L·cos a ∓ w·sin a)) with w the wheel separation, as in Gazebo; no
    wheel is driven. Gain 10/s: 2 s are 20 time constants."""
    car = _car().replace("<steer_p_gain>", "<steering_only>true</steering_only><steer_p_gain>")
    angle = 0.3
    with lockstep(tmp_path, car) as rig:
        rig.send(f"{BOT}/steer_angle", messages.float64(angle))
        rig.step(2.0)
        left, right = (state[0] for state in rig.joints("left_steer", "right_steer"))
        rear = rig.joints("rear_left_axle", "rear_right_axle")
    twice_l = 2 * WHEEL_BASE
    expected = [
        math.atan(twice_l * math.sin(angle) / (twice_l * math.cos(angle) + s * TRACK * math.sin(angle)))
        for s in (-1, 1)
    ]
    assert (left, right) == pytest.approx(expected, abs=1e-4)
    assert all(effort == 0.0 for *_, effort in rear)
