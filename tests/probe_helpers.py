"""The probe world of the sensor tests (test_sensor_lidar_3d, _altimeter, _air_pressure, _magnetometer,
_navsat, _force_torque, _contact): a real server in lockstep on a real Zenoh bus.

Each test builds a tiny world and a probe robot carrying the sensors under test, in this process
as `simbot-server` builds them (`Server`, lockstep, a fresh loopback port and namespace), steps it
and reads what the sensors published, by key, from a subscriber on the server's own session
(waiting for each stamp, never sleeping). No noise in the SDF where values are compared exactly.
Most probes are static models, moved by teleport between steps (`Physics.set_model_pose`), so
their poses are exact; the falling probe is checked against semi-implicit Euler, which is how
PyBullet integrates.

Tolerances, from the physics:
- PyBullet is built in single precision: every pose comes back rounded to float32, 2e-6 m at 20 m
  and 1.2e-7 of a rotation;
- geometry (lidar): PyBullet's ray test against a box is exact to float precision, and a LaserScan
  or cloud holds float32: 1e-5 m on metres;
- navsat: the expected latitude and longitude come from the meridian and prime-vertical radii of
  curvature at the origin (M + h, (N + h)·cos φ): exact to first order; over 50 m the second order
  is d²/2R ≈ 2e-4 m ≈ 2e-9°, far inside the 1e-7° asked;
- air pressure: the US Standard Atmosphere 1976 tables give 5 significant digits (±1 Pa at 1 km,
  ±0.0005 kg/m³ for the sea-level density whose hydrostatic slope −ρg is checked);
- force/torque: a fixed joint's reaction in PyBullet's articulated-body solver is exact statics:
  1e-3 N, 1e-3 N·m;
- contact: the sum of the contact forces on a resting box balances m·g within the solver's
  residual, 2 % after 0.5 s of settling.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from bus_helpers import endpoint, free_port, unique_namespace
from server_helpers import Collector, dropped, keyed_payload, raw_samples, stamp_ns

from simbot.bus import BusOptions, Node, decode
from simbot.description.poses import Pose
from simbot.sim.loop.simulation import Mode
from simbot.sim.physics import pose_to_transform
from simbot.sim.server import ROBOT_NAME, Server, ServerConfig

G = 9.8
STEP_NS = 1_000_000

WORLD = """<?xml version="1.0"?>
<sdf version="1.10">
  <world name="probe_world">
    <physics name="1ms" type="ignore"><max_step_size>0.001</max_step_size></physics>
    {world}
    <model name="ground_plane">
      <static>true</static>
      <link name="link">
        <collision name="c"><geometry><plane><normal>0 0 1</normal><size>50 50</size></plane></geometry></collision>
      </link>
    </model>
    <model name="wall">
      <static>true</static>
      <pose>2 0 1 0 0 0</pose>
      <link name="link">
        <collision name="c"><geometry><box><size>0.2 8 2</size></box></geometry></collision>
      </link>
    </model>
  </world>
</sdf>
"""

PROBE = """<?xml version="1.0"?>
<sdf version="1.10">
  <model name="probe">
    <static>{static}</static>
    <link name="body">
      <inertial><mass>{mass}</mass><inertia><ixx>0.1</ixx><iyy>0.1</iyy><izz>0.1</izz></inertia></inertial>
      <collision name="box"><geometry><box><size>0.4 0.4 0.2</size></box></geometry></collision>
      {sensors}
    </link>
    {extra}
  </model>
</sdf>
"""

TYPES = {
    "alt": "ros_gz_interfaces/msg/Altimeter",
    "baro": "sensor_msgs/msg/FluidPressure",
    "km": "sensor_msgs/msg/FluidPressure",
    "compass": "sensor_msgs/msg/MagneticField",
    "fix": "sensor_msgs/msg/NavSatFix",
    "bump": "ros_gz_interfaces/msg/Contacts",
    "held": "geometry_msgs/msg/WrenchStamped",
    "pulled": "geometry_msgs/msg/WrenchStamped",
    "flat": "sensor_msgs/msg/LaserScan",
    "odd": "sensor_msgs/msg/LaserScan",
    "even": "sensor_msgs/msg/LaserScan",
    "odd/points": "sensor_msgs/msg/PointCloud2",
    "even/points": "sensor_msgs/msg/PointCloud2",
}
"""The sensors' keys (their `<topic>`s) and types."""


def sensor(name: str, kind: str, body: str = "", pose: str = "0 0 0 0 0 0") -> str:
    """A sensor publishing on its name at 100 Hz."""
    return (
        f'<sensor name="{name}" type="{kind}"><pose>{pose}</pose><update_rate>100</update_rate>'
        f"<topic>{name}</topic>{body}</sensor>"
    )


@dataclass
class Probe:
    """A lockstep server and what its sensors published, decoded, by key."""

    server: Server
    namespace: str
    received: Collector[tuple[str, bytes]]

    def step(self, count: int) -> int:
        """Runs `count` physics steps; returns the sim time reached."""
        for _ in range(count):
            self.server.sim.step()
        return self.server.sim.clock.now_ns

    def teleport(self, xyz: tuple[float, float, float], yaw: float = 0.0) -> None:
        """Puts the probe's model frame at `xyz`, turned by `yaw`, at rest."""
        self.server.physics.set_model_pose(ROBOT_NAME, pose_to_transform(Pose(xyz, (0.0, 0.0, yaw))))

    def at(self, key: str, ns: int) -> Any:
        """The message on `key` stamped `ns` (waits for it)."""
        prefix = f"{self.namespace}/{key}"

        def found(items: list[tuple[str, bytes]]) -> list[Any]:
            decoded = [decode(data, TYPES[key]) for k, data in items if k == prefix]
            return [m for m in decoded if stamp_ns(m) == ns]

        self.received.wait_for(found, what=f"{key} stamped {ns / 1e9:.3f} s")
        return found(self.received.messages())[0]

    def sample(self, key: str, steps: int = 10) -> Any:
        """Steps `steps` (a multiple of the sensors' 10 ms period) and returns the sample taken then."""
        return self.at(key, self.step(steps))


@contextmanager
def probe(
    tmp: Path,
    sensors: str = "",
    *,
    world: str = "",
    extra: str = "",
    static: bool = True,
    mass: float = 3.0,
    spawn: tuple[float, float, float, float] = (0.0, 0.0, 0.5, 0.0),
) -> Iterator[Probe]:
    """A server of the probe world with the probe robot carrying `sensors` (and `extra` links and joints)."""
    world_file, robot_file = tmp / "world.sdf", tmp / "probe.sdf"
    world_file.write_text(WORLD.format(world=world))
    robot_file.write_text(PROBE.format(static=str(static).lower(), mass=mass, sensors=sensors, extra=extra))
    config = ServerConfig(world_file, robot_file, spawn, Mode.LOCKSTEP, 0, {"rendering.workers": 1})
    options = BusOptions(listen=(endpoint(free_port()),), namespace=unique_namespace())
    with (
        Node(options, "server") as node,
        raw_samples(node.session, f"0/{node.namespace}/**", keyed_payload) as received,
    ):
        server = Server(config, node)
        try:
            yield Probe(server, node.namespace, received)
        finally:
            server.close()


def vector(msg: Any) -> np.ndarray:
    return np.array([msg.x, msg.y, msg.z])


LOAD_KG, ARM = 2.0, 0.3


def load(name: str, y: float, body: str) -> str:
    """A 2 kg load hung on a fixed joint at (0, y, 0.5) of the probe, its centre of mass 0.3 m along x."""
    return f"""<link name="{name}"><pose>0 {y} 0.5 0 0 0</pose>
      <inertial><pose>{ARM} 0 0 0 0 0</pose><mass>{LOAD_KG}</mass>
        <inertia><ixx>0.01</ixx><iyy>0.01</iyy><izz>0.01</izz></inertia></inertial></link>
    <joint name="{name}_joint" type="fixed"><parent>body</parent><child>{name}</child>
      {sensor(name, "force_torque", body)}</joint>"""


def assert_left_out(tmp: Path, sensors: str, extra: str, message: str, caplog: pytest.LogCaptureFixture) -> None:
    """A sensor with bad SDF is left out with one line naming it and the element; the rest of the world runs."""
    with probe(tmp, sensors, extra=extra) as running:
        running.step(10)
    (line,) = dropped(caplog)
    assert line.startswith(message) and "\n" not in line, line
