"""Gazebo's default keys and frames on a real server: `--robot none` with two same vehicles.

tests/fixtures/gazebo/two_vehicles.sdf holds two differential-drive vehicles whose DiffDrive and
IMU state no topic, as gz-sim's diff_drive.sdf does. Each takes the keys Gazebo Sim gives under
its own model name, so a command to one moves that one only, and their odometry, tf and IMU
stay apart; world state reports each vehicle's IMU under its scoped name. A rig with one sensor
of each kind and the other model systems, none stating a topic, announces Gazebo's keys.
"""

from __future__ import annotations

import statistics
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from server_helpers import (
    ODOMETRY,
    POSE_STAMPED,
    TF_MESSAGE,
    SimServer,
    planar_distance,
    pose_of,
    running_server,
    stamp_ns,
)

from simbot.bus import messages
from simbot.bus.graph import discover
from simbot.description import load_world
from simbot.description.drive_params import DiffDriveParams
from simbot.description.model import Param, Plugin
from simbot.transform import rotate_into

IMU = "sensor_msgs/msg/Imu"
WORLD = Path(__file__).parent / "fixtures" / "gazebo" / "two_vehicles.sdf"
VEHICLES = ("vehicle_blue", "vehicle_green")
SETTLE_STEPS = 500
"""0.5 s at 1 ms: the vehicles come to rest on their wheels and caster."""
DRIVE_S, SPEED, ACCELERATION = 4.0, 0.5, 1.0
"""The command (0.5 m/s for 4 s) and the SDF's limit on acceleration (its speed limit is 0.5 m/s)."""
EXPECTED_M = SPEED * DRIVE_S - SPEED**2 / (2 * ACCELERATION)
"""1.875 m: 0.125 m ramping up over 0.5 s at 1 m/s², then 3.5 s at 0.5 m/s."""


IMU_PERIOD_NS = 10_000_000
"""The IMUs' `<update_rate>` 100: a reading every 10 ms of sim time, the first at the first step (1 ms)."""
GRAVITY = 9.8
"""The world's (SDF's default): what an accelerometer at rest reads, upwards, in its own frame."""
AT_REST = 1e-3
"""m/s² and rad/s: how far a vehicle standing on its wheels reads from gravity and from no turn
(PyBullet's resting contacts creep by 1e-4 here)."""
RAMP_REL = 0.05
"""How far the mean forward acceleration over the 0.5 s ramp may lie from the SDF's 1 m/s² limit:
the IMU samples every tenth 1 ms step's acceleration, which the wheels' contacts jitter by a few
m/s² (measured: 1.022)."""
CRUISE = 0.05
"""m/s²: the mean forward acceleration at a steady 0.5 m/s (measured: 1e-4)."""


def imu_key(vehicle: str) -> str:
    return f"world/two_vehicles/model/{vehicle}/link/chassis/sensor/imu/imu"


@pytest.fixture(scope="module")
def sim() -> Iterator[SimServer]:
    with running_server(str(WORLD), extra=("--robot", "none")) as server:
        yield server


def test_the_world_runs_alone_with_its_own_vehicles(sim: SimServer) -> None:
    """`--robot none`: no Flexley Tug; the world's models only, each sensor under its scoped name."""
    state = sim.state()
    assert set(state["models"]) == {"ground", *VEHICLES}
    assert {f"{v}/chassis/imu" for v in VEHICLES} <= set(state["sensors"])


def test_one_vehicle_drives_on_its_own_key_and_the_other_stays(sim: SimServer) -> None:
    """0.5 m/s for 4 s on model/vehicle_blue/cmd_vel moves vehicle_blue 1.875 m ± 2 % (its SDF's
    acceleration limit costs 0.125 m) and vehicle_green not at all; odometry and tf of each
    vehicle come on its own keys, in its own frames; each IMU publishes on its own key at its 100 Hz
    and reads its own vehicle's motion (`assert_imu_reads`)."""
    odom = {v: sim.subscribe(f"model/{v}/odometry", ODOMETRY) for v in VEHICLES}
    truth = {v: sim.subscribe(f"model/{v}/pose", POSE_STAMPED) for v in VEHICLES}
    tf = {v: sim.subscribe(f"model/{v}/tf", TF_MESSAGE) for v in VEHICLES}
    imu = {v: sim.subscribe(imu_key(v), IMU) for v in VEHICLES}
    sim.step(SETTLE_STEPS)
    start = {v: sim.pose(v) for v in VEHICLES}
    sim.send("model/vehicle_blue/cmd_vel", messages.twist((SPEED, 0.0, 0.0), (0.0, 0.0, 0.0)))
    sim.step(round(DRIVE_S * 1000))
    sim.send("model/vehicle_blue/cmd_vel", messages.twist((0.0, 0.0, 0.0), (0.0, 0.0, 0.0)))
    end = {v: sim.pose(v) for v in VEHICLES}
    moved = {v: planar_distance(start[v][0], end[v][0]) for v in VEHICLES}
    assert moved["vehicle_blue"] == pytest.approx(EXPECTED_M, rel=0.02), moved
    assert moved["vehicle_green"] < 1e-3, moved
    for vehicle in VEHICLES:  # ground truth on model/<m>/pose, as world state has it
        published = pose_of(truth[vehicle].wait_stamp(round((SETTLE_STEPS / 1000 + DRIVE_S) * 1e9)).pose)[0]
        assert published == pytest.approx(end[vehicle][0], abs=1e-6)
    assert abs(end["vehicle_blue"][0][1] - start["vehicle_blue"][0][1]) < 0.02  # straight along x
    for vehicle in VEHICLES:
        last = odom[vehicle].wait_stamp(round((SETTLE_STEPS / 1000 + DRIVE_S) * 1e9))
        assert (last.header.frame_id, last.child_frame_id) == (f"{vehicle}/odom", f"{vehicle}/chassis")
        frames = {(t.header.frame_id, t.child_frame_id) for m in tf[vehicle].messages() for t in m.transforms}
        assert frames == {(f"{vehicle}/odom", f"{vehicle}/chassis")}
    last_ns = round((SETTLE_STEPS / 1000 + DRIVE_S) * 1e9)
    for vehicle, ramp in (("vehicle_blue", ACCELERATION), ("vehicle_green", 0.0)):
        imu[vehicle].wait_stamp(last_ns)
        assert_imu_reads(imu[vehicle].messages(), ramp)
    blue, green = (odom[v].messages()[-1].pose.pose.position for v in VEHICLES)
    assert blue.x == pytest.approx(EXPECTED_M, rel=0.02) and abs(green.x) < 1e-3
    print(
        f"\nmoved {moved} (expected {EXPECTED_M} m for vehicle_blue); odometry x blue {blue.x:.4f} green {green.x:.4f}"
    )


def assert_imu_reads(readings: list[Any], ramp: float) -> None:
    """IMU readings over settling, then a 0.5 s ramp at `ramp` m/s² forward, then a steady speed: one
    every 10 ms; settled, gravity rotated into the IMU's frame by its own orientation and no turn;
    less that gravity, `ramp` forward on average over the ramp and nothing at the steady speed."""
    stamps = [stamp_ns(m) for m in readings]
    assert stamps == [1_000_000] + [k * IMU_PERIOD_NS for k in range(1, len(stamps))], stamps[:3]
    assert stamps[-1] == round((SETTLE_STEPS / 1000 + DRIVE_S) * 1e9)
    settled_ns = SETTLE_STEPS * 1_000_000
    ramp_end_ns = settled_ns + round(SPEED / ACCELERATION * 1e9)
    forward: dict[str, list[float]] = {"ramp": [], "cruise": []}
    for reading, stamp in zip(readings, stamps, strict=True):
        o, a, w = reading.orientation, reading.linear_acceleration, reading.angular_velocity
        gravity = rotate_into((o.x, o.y, o.z, o.w), (0.0, 0.0, GRAVITY))
        if settled_ns // 2 < stamp and (stamp <= settled_ns or not ramp):  # standing: the second half of settling on
            assert (a.x, a.y, a.z) == pytest.approx(gravity, abs=AT_REST), (stamp, a, gravity)
            assert (w.x, w.y, w.z) == pytest.approx((0.0, 0.0, 0.0), abs=AT_REST), (stamp, w)
        elif stamp > settled_ns:
            forward["ramp" if stamp <= ramp_end_ns else "cruise"].append(a.x - gravity[0])
    if ramp:
        assert statistics.mean(forward["ramp"]) == pytest.approx(ramp, rel=RAMP_REL), statistics.mean(forward["ramp"])
        assert abs(statistics.mean(forward["cruise"])) < CRUISE, statistics.mean(forward["cruise"])


def test_gazebo_defaults_and_a_stated_topic_wins() -> None:
    """The DiffDrive's defaults carry the running model's name; a stated `<topic>` replaces its default only."""
    world = load_world(WORLD)
    model = next(m for m in world.models if m.name == "vehicle_blue")
    plugin = model.plugins[0]
    defaults = DiffDriveParams.parse(plugin, model, "vehicle_blue")
    assert (defaults.topic, defaults.odom_topic, defaults.tf_topic) == (
        "model/vehicle_blue/cmd_vel",
        "model/vehicle_blue/odometry",
        "model/vehicle_blue/tf",
    )
    stated = Plugin(plugin.name, plugin.filename, (*plugin.params, Param("topic", "/drive")))
    assert DiffDriveParams.parse(stated, model, "renamed").topic == "/drive"
    assert DiffDriveParams.parse(stated, model, "renamed").odom_topic == "model/renamed/odometry"


RIG = """<?xml version="1.0"?>
<sdf version="1.9"><world name="keys"><model name="rig"><static>true</static><pose>0 0 1 0 0 0</pose>
  <link name="body">
    {sensors}
  </link>
  <plugin filename="gz-sim-joint-state-publisher-system" name="gz::sim::systems::JointStatePublisher"/>
  <plugin filename="gz-sim-detachable-joint-system" name="gz::sim::systems::DetachableJoint">
    <parent_link>body</parent_link><child_model>cart</child_model><child_link>base</child_link>
  </plugin>
</model></world></sdf>"""
CAMERA = "<camera><image><width>8</width><height>6</height></image></camera>"
SENSORS = {
    "camera": CAMERA,
    "depth_camera": CAMERA,
    "rgbd_camera": CAMERA,
    "gpu_lidar": "<lidar><scan><horizontal><samples>3</samples></horizontal></scan><range><min>0.1</min><max>5</max></range></lidar>",
    "imu": "",
}
"""One sensor of each kind, none stating a topic; each is named after its kind."""


def test_every_system_and_sensor_without_a_topic_takes_gazebos_key(tmp_path: Path) -> None:
    """The keys the server announces for a model `rig` in world `keys` whose systems and sensors state no topic."""
    sensors = "".join(f'<sensor name="{kind}" type="{kind}">{body}</sensor>' for kind, body in SENSORS.items())
    world = tmp_path / "keys.sdf"
    world.write_text(RIG.format(sensors=sensors))
    with running_server(str(world), extra=("--robot", "none", "--render-workers", "1")) as sim:
        prefix = f"{sim.namespace}/"
        announced = {(e.kind, e.key.removeprefix(prefix)) for e in discover(sim.node.session, sim.namespace)}
    scope = "world/keys/model/rig/link/body/sensor"
    expected = {
        ("pub", "world/keys/model/rig/joint_state"),
        ("sub", "model/rig/detachable_joint/attach"),
        ("sub", "model/rig/detachable_joint/detach"),
        ("pub", "model/cart/detachable_joint/state"),
        *(("pub", f"{scope}/camera/{leaf}") for leaf in ("image", "camera_info")),
        *(("pub", f"{scope}/depth_camera/{leaf}") for leaf in ("depth_image", "camera_info")),
        *(("pub", f"{scope}/rgbd_camera/{leaf}") for leaf in ("image", "depth_image", "points", "camera_info")),
        ("pub", f"{scope}/gpu_lidar/scan"),
        ("pub", f"{scope}/imu/imu"),
    }
    assert expected <= announced, sorted(expected - announced)
