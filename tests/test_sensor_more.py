"""The sensors of issue 15 item 7 against physics: a real server in lockstep on a real Zenoh bus.

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

import math
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from bus_helpers import endpoint, free_port, unique_namespace
from server_helpers import Collector, dropped, keyed_payload, raw_samples, stamp_ns

from simbot.bus import BusOptions, Node, decode, messages
from simbot.description import load_sdf, load_world
from simbot.description.errors import DescriptionError
from simbot.description.model import Atmosphere, Model, SphericalCoordinates
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


# --- 3-D lidar -------------------------------------------------------------------------------

WALL_FACE_X = 1.9
LIDAR_HEIGHT = 0.5  # the sensor 0.5 m above the probe's frame, itself at z 0.5: 1 m above the floor
H_SAMPLES, H_MAX = 41, 0.5


def lidar(name: str, vertical: int, horizontal: int = H_SAMPLES) -> str:
    """A noiseless lidar `name` with `vertical` rows over ±0.2 rad (1: planar, in the horizontal plane)."""
    rows = (
        f"<vertical><samples>{vertical}</samples><min_angle>-0.2</min_angle><max_angle>0.2</max_angle></vertical>"
        if vertical > 1
        else ""
    )
    body = (
        f"<lidar><scan><horizontal><samples>{horizontal}</samples><min_angle>-{H_MAX}</min_angle>"
        f"<max_angle>{H_MAX}</max_angle></horizontal>{rows}</scan><range><min>0.1</min><max>10</max></range></lidar>"
    )
    return sensor(name, "gpu_lidar", body, f"0 0 {LIDAR_HEIGHT} 0 0 0")


def test_3d_lidar_sees_a_wall_point_by_point(tmp_path: Path) -> None:
    """5 rows × 41 columns of points, each on the wall's face x = 1.9 where its ray meets it, ring = row;
    the middle-plane scan is the middle row's ranges and equals a planar lidar's scan."""
    with probe(tmp_path, lidar("odd", 5) + lidar("flat", 1)) as sim:
        t = sim.step(10)
        cloud = messages.lidar_points_array(sim.at("odd/points", t))
        scan, flat = sim.at("odd", t), sim.at("flat", t)
    assert cloud.shape == (5, H_SAMPLES)
    azimuth = np.linspace(-H_MAX, H_MAX, H_SAMPLES)[None, :]
    elevation = np.linspace(-0.2, 0.2, 5)[:, None]
    distance = WALL_FACE_X / (np.cos(azimuth) * np.cos(elevation))  # along each ray to the plane x = 1.9
    assert np.abs(cloud["x"] - WALL_FACE_X).max() < 1e-5
    assert np.abs(cloud["y"] - distance * np.cos(elevation) * np.sin(azimuth)).max() < 1e-5
    assert np.abs(cloud["z"] - distance * np.sin(elevation)).max() < 1e-5
    assert (cloud["ring"] == np.arange(5)[:, None]).all() and (cloud["intensity"] == 0).all()
    middle = np.sqrt(cloud["x"][2] ** 2 + cloud["y"][2] ** 2 + cloud["z"][2] ** 2)
    assert np.asarray(scan.ranges) == pytest.approx(middle, abs=1e-5)
    assert np.asarray(scan.ranges) == pytest.approx(np.asarray(flat.ranges), abs=1e-6)
    assert (scan.angle_min, scan.angle_max, len(scan.ranges)) == (flat.angle_min, flat.angle_max, H_SAMPLES)


def test_even_rows_cast_the_middle_plane_apart(tmp_path: Path) -> None:
    """4 rows (none horizontal): the cloud has 4 rows, the scan is the horizontal plane all the same;
    rays above the wall's top read nothing: NaN in the cloud."""
    with probe(tmp_path, lidar("even", 4) + lidar("flat", 1), spawn=(0.0, 0.0, 0.75, 0.0)) as sim:
        t = sim.step(10)
        cloud = messages.lidar_points_array(sim.at("even/points", t))
        scan, flat = sim.at("even", t), sim.at("flat", t)
    assert cloud.shape == (4, H_SAMPLES)
    assert np.asarray(scan.ranges) == pytest.approx(np.asarray(flat.ranges), abs=1e-6)
    # the sensor is 1.25 m up: the top row (+0.2 rad) passes over the 2 m wall's top only if
    # 1.25 + 1.9·tan(0.2) > 2, which it is not: every ray hits, on the face
    assert np.isfinite(cloud["x"]).all() and np.abs(cloud["x"] - WALL_FACE_X).max() < 1e-5


def test_more_rays_than_one_pybullet_batch(tmp_path: Path) -> None:
    """9 × 2001 = 18009 rays, over PyBullet's 16384 a batch: cast in parts, every point still on the wall
    where its own ray meets it (a ray lost or shifted at a part's edge would misplace the rest)."""
    with probe(tmp_path, lidar("odd", 9, 2001)) as sim:
        cloud = messages.lidar_points_array(sim.sample("odd/points"))
    azimuth = np.linspace(-H_MAX, H_MAX, 2001)[None, :]
    assert cloud.shape == (9, 2001) and np.abs(cloud["x"] - WALL_FACE_X).max() < 1e-5
    assert np.abs(cloud["y"] - WALL_FACE_X * np.tan(azimuth)).max() < 1e-5


def test_rays_that_hit_nothing_are_nan_points(tmp_path: Path) -> None:
    """Turned away from the wall, the upper rows see nothing: NaN, and the cloud says it is not dense."""
    with probe(tmp_path, lidar("odd", 5), spawn=(0.0, 0.0, 0.5, math.pi)) as sim:
        t = sim.step(10)
        msg = sim.at("odd/points", t)
    cloud = messages.lidar_points_array(msg)
    # the lowest row (−0.2 rad) meets the floor 1 m below at 1/sin 0.2 = 5.0 m; the next (−0.1 rad)
    # only at 10.02 m, past range_max; level and up there is nothing
    assert np.isfinite(cloud["x"][0]).all() and np.isnan(cloud["x"][1:]).all()
    assert np.abs(cloud["z"][0] + 1.0).max() < 1e-5 and not msg.is_dense


# --- altimeter -------------------------------------------------------------------------------


def test_altimeter_reads_a_lift_and_a_fall(tmp_path: Path) -> None:
    """Lifted by 1.234 m it reads 1.234 over its reference, less 10 steps of free fall (semi-implicit
    Euler, as PyBullet integrates: −g·dt²·n(n+1)/2); falling 0.5 s more, the body's own height and
    vertical speed, and the same free fall over all 510 steps (bodies are undamped, as in SDF)."""
    with probe(tmp_path, sensor("alt", "altimeter"), static=False, spawn=(0.0, 0.0, 20.0, 0.0)) as sim:
        first = sim.sample("alt")
        sim.teleport((0.0, 0.0, 21.234))
        lifted = sim.sample("alt", 10)
        fallen = sim.sample("alt", 500)
        (position, _), velocity, _ = sim.server.physics.frame_motion(ROBOT_NAME, "body")
    dt = STEP_NS / 1e9
    assert first.vertical_reference == pytest.approx(20.0, abs=1e-6)
    assert lifted.vertical_position == pytest.approx(1.234 - G * dt**2 * 10 * 11 / 2, abs=4e-6)  # float32 at 21 m
    assert fallen.vertical_position == pytest.approx(position[2] - 20.0, abs=1e-9)
    assert fallen.vertical_velocity == pytest.approx(velocity[2], abs=1e-9)
    assert 1.234 - fallen.vertical_position == pytest.approx(G * dt**2 * 510 * 511 / 2, abs=4e-6)


# --- air pressure ----------------------------------------------------------------------------

SEA_LEVEL_PA = 101325.0
TABLE_1000_M_PA = 89876.0  # US Standard Atmosphere 1976 at 1000 m geometric altitude
SEA_LEVEL_DENSITY = 1.2250  # kg/m³, the same table


def test_air_pressure_follows_the_standard_atmosphere(tmp_path: Path) -> None:
    """101325 Pa at sea level; −ρ₀·g per metre just above it; the 1976 table's 89876 Pa at 1 km
    (through `<reference_altitude>` 1000 on a sensor at z 0)."""
    sensors = sensor("baro", "air_pressure", pose="0 0 -0.5 0 0 0") + sensor(
        "km", "air_pressure", "<air_pressure><reference_altitude>1000</reference_altitude></air_pressure>",
        "0 0 -0.5 0 0 0",
    )  # fmt: skip
    with probe(tmp_path, sensors) as sim:
        sim.teleport((0.0, 0.0, 0.5))  # the sensors at z 0
        sea, km = sim.sample("baro"), sim.sample("km", 0)
        sim.teleport((0.0, 0.0, 10.5))
        ten = sim.sample("baro")
    assert sea.fluid_pressure == pytest.approx(SEA_LEVEL_PA, abs=1e-6)
    assert km.fluid_pressure == pytest.approx(TABLE_1000_M_PA, abs=1.0)
    slope = (ten.fluid_pressure - sea.fluid_pressure) / 10.0
    assert slope == pytest.approx(-SEA_LEVEL_DENSITY * 9.80665, abs=0.01)
    assert sea.variance == 0.0 and sea.header.frame_id == "baro"


# --- magnetometer ----------------------------------------------------------------------------

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


# --- navsat ----------------------------------------------------------------------------------

LAT, LON, ELEVATION = 47.3, 8.5, 400.0
WGS84_A, WGS84_E2 = 6378137.0, 0.00669437999014


@pytest.mark.parametrize("heading_deg", [0.0, 90.0, -30.0])
def test_navsat_converts_a_displacement_to_latitude_and_longitude(tmp_path: Path, heading_deg: float) -> None:
    """At (30, 40) in the world: east and north by the heading (gz-math: ENU = Rz(heading)·world), then
    Δφ = north/(M + h), Δλ = east/((N + h)·cos φ), within 1e-7°; the altitude is elevation + z."""
    world = (
        f"<spherical_coordinates><surface_model>EARTH_WGS84</surface_model><latitude_deg>{LAT}</latitude_deg>"
        f"<longitude_deg>{LON}</longitude_deg><elevation>{ELEVATION}</elevation>"
        f"<heading_deg>{heading_deg}</heading_deg></spherical_coordinates>"
    )
    with probe(tmp_path, sensor("fix", "navsat"), world=world) as sim:
        sim.teleport((0.0, 0.0, 0.0))
        origin = sim.sample("fix")
        sim.teleport((30.0, 40.0, 0.0))
        moved = sim.sample("fix")
    h = math.radians(heading_deg)
    east, north = 30.0 * math.cos(h) - 40.0 * math.sin(h), 30.0 * math.sin(h) + 40.0 * math.cos(h)
    phi = math.radians(LAT)
    w = math.sqrt(1 - WGS84_E2 * math.sin(phi) ** 2)
    meridian, normal = WGS84_A * (1 - WGS84_E2) / w**3, WGS84_A / w
    assert (origin.latitude, origin.longitude) == (pytest.approx(LAT, abs=1e-9), pytest.approx(LON, abs=1e-9))
    assert origin.altitude == pytest.approx(ELEVATION, abs=1e-6)
    assert moved.latitude == pytest.approx(LAT + math.degrees(north / (meridian + ELEVATION)), abs=1e-7)
    assert moved.longitude == pytest.approx(LON + math.degrees(east / ((normal + ELEVATION) * math.cos(phi))), abs=1e-7)
    assert moved.altitude == pytest.approx(ELEVATION, abs=1e-3)  # the Earth's curvature: 50²/2R = 0.2 mm
    assert moved.status.status == 0 and moved.position_covariance_type == 0  # FIX; no noise: UNKNOWN


def test_navsat_noise_in_metres(tmp_path: Path) -> None:
    """σ 2 m horizontally and 3 m vertically: the spread of 300 fixes of a probe at rest, in metres
    (±20 %: an estimate from N samples is within ~1/√(2N) = 4 %), and σ² on the covariance's diagonal."""
    body = (
        '<navsat><position_sensing><horizontal><noise type="gaussian"><stddev>2</stddev></noise></horizontal>'
        '<vertical><noise type="gaussian"><stddev>3</stddev></noise></vertical></position_sensing></navsat>'
    )
    with probe(tmp_path, sensor("fix", "navsat", body)) as sim:
        fixes = [sim.sample("fix") for _ in range(300)]
    # at the world's default origin, 0° 0°: the meridian radius is a(1 − e²), the prime vertical's a
    north = np.radians([f.latitude for f in fixes]) * WGS84_A * (1 - WGS84_E2)
    east = np.radians([f.longitude for f in fixes]) * WGS84_A
    up = np.array([f.altitude for f in fixes])
    assert np.std(north) == pytest.approx(2.0, rel=0.2) and np.std(east) == pytest.approx(2.0, rel=0.2)
    assert np.std(up) == pytest.approx(3.0, rel=0.2)
    assert list(fixes[0].position_covariance) == [4.0, 0, 0, 0, 4.0, 0, 0, 0, 9.0]
    assert fixes[0].position_covariance_type == 2


# --- force/torque ----------------------------------------------------------------------------

LOAD_KG, ARM = 2.0, 0.3


def load(name: str, y: float, body: str) -> str:
    """A 2 kg load hung on a fixed joint at (0, y, 0.5) of the probe, its centre of mass 0.3 m along x."""
    return f"""<link name="{name}"><pose>0 {y} 0.5 0 0 0</pose>
      <inertial><pose>{ARM} 0 0 0 0 0</pose><mass>{LOAD_KG}</mass>
        <inertia><ixx>0.01</ixx><iyy>0.01</iyy><izz>0.01</izz></inertia></inertial></link>
    <joint name="{name}_joint" type="fixed"><parent>body</parent><child>{name}</child>
      {sensor(name, "force_torque", body)}</joint>"""


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


# --- contact ---------------------------------------------------------------------------------


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
            ROBOT_NAME, ((x, y, z), (0.0, math.sin(RAMP_PITCH / 2), 0.0, math.cos(RAMP_PITCH / 2)))
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


# --- bad SDF ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("sensors", "extra", "message"),
    [
        (sensor("bump", "contact", "<contact><collision>nope</collision></contact>"), "",
         "sensor bump: <contact><collision> 'nope' is not a collision of link 'body'"),
        (sensor("bump", "contact", "<contact/>"), "", "sensor bump: <contact><collision> is required"),
        (sensor("ft", "force_torque"), "", "sensor ft: a force_torque sensor belongs in a <joint>"),
        ("", load("held", 0.5, "<force_torque><frame>world</frame></force_torque>"),
         "sensor held: <force_torque><frame> must be one of child, parent, sensor, got 'world'"),
        (sensor("alt", "altimeter", "<altimeter><vertical_position><noise><stddev>x</stddev></noise>"
                "</vertical_position></altimeter>"), "",
         "sensor alt: <altimeter><vertical_position><noise><stddev> expected a number, got 'x'"),
    ],
)  # fmt: skip
def test_bad_sdf_is_one_line_naming_sensor_and_element(
    tmp_path: Path, sensors: str, extra: str, message: str, caplog: pytest.LogCaptureFixture
) -> None:
    """The sensor is left out with one line naming it and the element; the rest of the world runs."""
    with probe(tmp_path, sensors, extra=extra) as running:
        running.step(10)
    (line,) = dropped(caplog)
    assert line.startswith(message) and "\n" not in line, line


# --- what the sensors read from the description ----------------------------------------------


def test_world_earth_magnetic_field_and_atmosphere_are_read(tmp_path: Path) -> None:
    """`<spherical_coordinates>`, `<magnetic_field>` and `<atmosphere>` into the World; SDF's defaults
    where a world leaves them out; a world frame other than ENU is an error naming the file."""
    world = (
        "<spherical_coordinates><surface_model>EARTH_WGS84</surface_model><world_frame_orientation>ENU"
        "</world_frame_orientation><latitude_deg>-33.9</latitude_deg><longitude_deg>151.2</longitude_deg>"
        "<elevation>58</elevation><heading_deg>12.5</heading_deg></spherical_coordinates>"
        "<magnetic_field>1e-6 2e-6 -3e-6</magnetic_field>"
        '<atmosphere type="adiabatic"><temperature>300</temperature><pressure>100000</pressure>'
        "<temperature_gradient>-0.005</temperature_gradient></atmosphere>"
    )
    given, bare = tmp_path / "given.sdf", tmp_path / "bare.sdf"
    given.write_text(WORLD.format(world=world))
    bare.write_text(WORLD.format(world=""))
    read, default = load_world(given), load_world(bare)
    assert read.spherical_coordinates == SphericalCoordinates("EARTH_WGS84", "ENU", -33.9, 151.2, 58.0, 12.5)
    assert read.magnetic_field == (1e-6, 2e-6, -3e-6)
    assert read.atmosphere == Atmosphere(300.0, 100000.0, -0.005)
    assert default.spherical_coordinates == SphericalCoordinates()
    assert default.magnetic_field == (5.5645e-6, 22.8758e-6, -42.3884e-6)
    assert default.atmosphere == Atmosphere(288.15, 101325.0, -0.0065)
    ned = tmp_path / "ned.sdf"
    ned.write_text(
        WORLD.format(
            world="<spherical_coordinates><world_frame_orientation>NED</world_frame_orientation></spherical_coordinates>"
        )
    )
    with pytest.raises(DescriptionError, match="world_frame_orientation 'NED' is not supported"):
        load_world(ned)


def test_a_joints_sensor_is_posed_from_the_joint_on_its_child_link(tmp_path: Path) -> None:
    """A `<sensor>` in a `<joint>` is the joint's (`joint_of`), listed with the joint's child link, its
    pose relative to the joint frame by default (SDF), kept in the child link's frame."""
    extra = (
        load("held", 0.5, "")
        .replace("<child>held</child>", "<child>held</child><pose>0.1 0 0 0 0 0</pose>")
        .replace('type="force_torque"><pose>0 0 0 0 0 0</pose>', 'type="force_torque"><pose>0 0 0.2 0 0 0</pose>')
    )
    robot = tmp_path / "probe.sdf"
    robot.write_text(PROBE.format(static="true", mass=1.0, sensors="", extra=extra))
    model = load_sdf(robot)
    assert isinstance(model, Model)
    ((link, held),) = model.sensors()
    assert (link.name, held.type, model.joint_of(held)) == ("held", "force_torque", model.joint("held_joint"))
    assert held.pose.xyz == pytest.approx((0.1, 0.0, 0.2))
