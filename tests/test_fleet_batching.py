"""A fleet's systems stepped together: the same messages as each stepped alone, and the same
whoever listened before.

Three kinematic Flexley Tugs side by side before a wall, one of them driven, in
a lockstep world on a `LocalNode` (in this process, as `simbot-server` builds it): the IMUs and
lidars of all tugs run as one batch (`BatchedPostUpdate`), and every sensor samples and draws its
noise whether anyone subscribes or not, building a message only for a subscriber.
"""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path
from typing import Any

import pytest

from simbot.bus import decode, encode, messages
from simbot.bus.local import LocalNode
from simbot.sim.loop.bus_view import SimBus
from simbot.sim.loop.plan import Slot
from simbot.sim.loop.system import PostUpdate
from simbot.sim.server import build_world, parse_config

WORLD = Path(__file__).parent / "fixtures" / "lidar_boxes.sdf"
"""A wall 3 m ahead of a robot at the origin, y −2 … 3: every tug's front lidar sees it."""
ARGS = ["--world", str(WORLD), "--robots", "3", "--spawn", "0", "0", "0.1", "0"]
ARGS += ["--physics", "kinematic", "--mode", "lockstep", "--seed", "11"]
STEPS = 240
"""1.2 s of 5 ms steps: seven scans of each lidar, 240 IMU samples, odometry at 50 Hz."""
DRIVE_AT = 20
LATE_AT = 121
"""A subscriber that comes in the middle of a sample period of every sensor."""
TUG = Path(__file__).parent.parent / "urdf" / "flexley_tug.sdf"
LEAVES = ("imu_scan", "lidar_front", "lidar_back", "odom", "tf", "joint_states")
KEYS = [f"tug_{robot}/{leaf}" for robot in (1, 2, 3) for leaf in LEAVES]

Recording = dict[str, list[tuple[int, bytes]]]


def stamp_ns(msg: Any) -> int:
    header = msg.transforms[0].header if hasattr(msg, "transforms") else msg.header
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def run(robot: Path, *, batched: bool, listen_from: int, alone_from: int | None = None) -> Recording:
    """Every message on KEYS from step `listen_from` on, CDR-encoded, with its stamp; from step
    `alone_from` on (or from the start where not `batched`) each system stepped alone."""
    node = LocalNode()
    world = build_world(parse_config([*ARGS, "--robot", str(robot)]), SimBus(node))
    sim = world.sim
    if not batched:
        alone_from = 0
    got: Recording = defaultdict(list)
    command = node.publisher("tug_2/cmd_vel", messages.Twist)
    try:
        for step in range(STEPS):
            if step == listen_from:
                for key in KEYS:

                    def deliver(msg: Any, key: str = key) -> None:
                        got[key].append((stamp_ns(msg), encode(msg)))

                    node.hub.listen(key, deliver)
            if step == DRIVE_AT:
                command.put(messages.twist((0.8, 0.0, 0.0), (0.0, 0.0, 0.6)))
            if step == alone_from:  # each system alone and asked every step, as before systems could batch
                sim._post = [Slot(system.post_update, 0) for system in sim.systems if isinstance(system, PostUpdate)]
                sim._plan = None  # made again from the slots above
            sim.step()
    finally:
        world.close()
    return got


@pytest.fixture(scope="module")
def noisy_tug(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The Flexley Tug with gaussian noise on its lidars too (its IMU has its own), so that every
    sensor draws from its random stream."""
    text = TUG.read_text(encoding="utf-8").replace("../meshes/", f"{TUG.parent.parent / 'meshes'}/")
    noise = "<noise type='gaussian'><mean>0</mean><stddev>0.01</stddev></noise>"
    assert text.count("</range>") == 2, "the tug has two lidars"
    path = tmp_path_factory.mktemp("robot") / "noisy_tug.sdf"
    path.write_text(text.replace("</range>", "</range>" + noise), encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def batched(noisy_tug: Path) -> Recording:
    return run(noisy_tug, batched=True, listen_from=0)


def test_a_fleet_stepped_as_one_batch_sends_what_each_robot_stepped_alone_sends(
    noisy_tug: Path, batched: Recording
) -> None:
    alone = run(noisy_tug, batched=False, listen_from=0)
    for key in KEYS:
        assert alone[key], f"{key}: nothing published"
        assert batched[key] == alone[key], f"{key}: the batch differs from each system stepped alone"
    assert len(batched["tug_1/imu_scan"]) == STEPS, "an IMU at 200 Hz samples every 5 ms step"
    assert len(batched["tug_3/lidar_front"]) == 7, "a 5 Hz lidar scans at the first step, then each 0.2 s to 1.2 s"
    scan = messages_of(batched, "tug_1/lidar_front", "sensor_msgs/msg/LaserScan")[0]
    assert min(scan.ranges) == pytest.approx(3.0, abs=0.05), "tug_1's front lidar sees the wall 3 m ahead"
    assert len({round(r, 6) for r in scan.ranges if r < 3.2}) > 10, "the wall's ranges carry noise"
    imu = messages_of(batched, "tug_2/imu_scan", "sensor_msgs/msg/Imu")
    assert max(abs(msg.angular_velocity.z) for msg in imu) == pytest.approx(0.6, abs=0.05), "tug_2 turns"


def test_sensors_that_leave_their_batch_mid_run_carry_their_state_and_noise_streams_on(
    noisy_tug: Path, batched: Recording
) -> None:
    """The IMUs sampled together hold their state as rows (last velocity, noise drawn ahead); each
    stepped alone from a step in the middle of a noise block on gets it back, and sends the same."""
    split = run(noisy_tug, batched=True, listen_from=0, alone_from=LATE_AT)
    for key in KEYS:
        assert split[key] == batched[key], f"{key}: leaving the batch changed what was sent"


def test_what_a_late_subscriber_gets_does_not_depend_on_who_listened_before(
    noisy_tug: Path, batched: Recording
) -> None:
    late = run(noisy_tug, batched=True, listen_from=LATE_AT)
    for key in KEYS:
        first = late[key][0][0]
        assert first >= LATE_AT * 5_000_000, f"{key}: a message from before the subscriber came"
        assert late[key] == [(stamp, data) for stamp, data in batched[key] if stamp >= first], (
            f"{key}: the noise or the stamps depend on whether someone listened before"
        )


def messages_of(recording: Recording, key: str, typename: str) -> list[Any]:
    return [decode(data, typename) for _, data in recording[key]]
