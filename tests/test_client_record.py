"""`simbot record` and `simbot play` against a real server in real time, read back with rosbags.

One server for the module (the empty world, cameras unwatched). The recorder runs as a real
process for 5 s while the test watches the same keys on the bus; the bag is then opened with
rosbags' reader, as `ros2 bag` and Foxglove would read it.

Rates. A loaded machine may hold the server below real time, so rates are read in sim time, from
the stamps: each key's consecutive stamps are one period of its rate apart (to the 1 ms physics
step a rate like 30 Hz rounds to), so no message is lost or repeated, and each key's stamps span
the sim time the bag's own `/clock` (100 Hz) spans, but for `TAP_SKEW_S`: the recorder taps the
keys one after another and lets go of them one after another, so a key may start or end a little
after or before the clock.
"""

from __future__ import annotations

import math
import re
import signal
import subprocess
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from bus_helpers import unique_namespace
from client_helpers import client_command, client_process
from rosbags.interfaces import QosDurability
from rosbags.rosbag2 import Reader
from server_helpers import (
    REPO,
    SimServer,
    data_keys,
    keyed_payload,
    payload,
    raw_samples,
    running_server,
    stamp_ns,
    wait_until,
)

from simbot.bus import decode

RECORD_S = 5.0
RATES_HZ = {
    "clock": 100.0,
    "imu_scan": 200.0,
    "odom": 50.0,
    "joint_states": 30.0,
    "lidar_front": 5.0,
    "lidar_back": 5.0,
}
LATCHED = ("tf_static", "robot_description")
TYPES = {
    "clock": "rosgraph_msgs/msg/Clock",
    "imu_scan": "sensor_msgs/msg/Imu",
    "odom": "nav_msgs/msg/Odometry",
    "joint_states": "sensor_msgs/msg/JointState",
    "lidar_front": "sensor_msgs/msg/LaserScan",
    "lidar_back": "sensor_msgs/msg/LaserScan",
    "tf_static": "tf2_msgs/msg/TFMessage",
    "robot_description": "std_msgs/msg/String",
}
STEP_NS = 1_000_000
"""The physics step: a sensor's sample falls on a step, so a period that is not a whole number of
steps (30 Hz: 33.3 ms) comes out as 33 and 34 ms."""
TAP_SKEW_S = 0.5
"""How much of the clock's span a key may miss at its ends: on a loaded two-core machine the taps'
start and end differed by up to 0.34 s of sim time (a lidar at 5 Hz, 23 scans where 4.94 s of
clock asks 24.7); a key recorded for less than all but half a second of the bag fails."""
RUN_TIMEOUT_S = 60.0
GARBAGE = b"\x00\x01\x00\x00not a LaserScan"


def bag_messages(path: Path) -> list[tuple[str, str, int, bytes]]:
    """(topic, type, timestamp, data) of every message, in the reader's order."""
    with Reader(path) as reader:
        return [(c.topic, c.msgtype, t, data) for c, t, data in reader.messages()]


def _stamps(messages: list[tuple[str, str, int, bytes]], key: str) -> list[int]:
    """The sim-time stamps (ns) of `key`'s messages in the bag: a header's, or a Clock's clock."""
    return [stamp_ns(decode(data, TYPES[key])) for topic, _, _, data in messages if topic == f"/{key}"]


def run(*args: str, timeout: float = RUN_TIMEOUT_S) -> subprocess.CompletedProcess[str]:
    return subprocess.run(client_command(*args), check=False, capture_output=True, text=True, cwd=REPO, timeout=timeout)


@pytest.fixture(scope="module")
def sim() -> Iterator[SimServer]:
    with running_server("empty", mode="realtime", extra=("--camera-size", "160x120")) as server:
        yield server


@pytest.fixture(scope="module")
def recorded(sim: SimServer, tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Path, list[bytes], str]]:
    """A 5 s recording of the chosen keys, the lidar_front payloads the test saw meanwhile, and the recorder's stderr.

    A malformed payload is put on lidar_front once the recorder taps it and two scans have gone by: the
    recorder must drop it (its warning shows it came while recording) and keep the rest.
    """
    bag = tmp_path_factory.mktemp("record") / "bag"
    with (
        raw_samples(sim.node.session, sim.any_type_key("lidar_front"), payload) as seen,
        client_process(sim, "record", "-o", str(bag), "--duration", str(RECORD_S), *RATES_HZ, *LATCHED) as recorder,
    ):
        wait_until(lambda: "recording /lidar_front" in recorder.stderr(), 20.0, "the recorder to tap lidar_front")
        tapped = len(seen)
        seen.wait_count(tapped + 2, 10.0, "lidar_front scans while the recorder taps it")
        sim.send_raw("lidar_front", "sensor_msgs/msg/LaserScan", GARBAGE)
        wait_until(
            lambda: f"{sim.key('lidar_front')}: dropped a sample" in recorder.stderr(),
            RECORD_S,
            "the recorder to drop the garbage",
        )
        code = recorder.process.wait(timeout=RUN_TIMEOUT_S)
        assert code == 0, recorder.stderr()[-2000:]
        stderr = recorder.stderr()
    yield bag, seen.messages(), stderr


def test_the_bag_holds_every_chosen_key_with_its_type_at_its_rate(recorded: tuple[Path, list[bytes], str]) -> None:
    """rosbags opens the MCAP bag; each key has its ROS 2 type, latched keys are transient-local, and
    each other key's samples come one period of its rate apart, none lost, over the bag's span."""
    bag, _, stderr = recorded
    assert (bag / "metadata.yaml").is_file() and (bag / "bag.mcap").is_file()
    with Reader(bag) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        durability = {c.topic: c.ext.offered_qos_profiles[0].durability for c in reader.connections}  # type: ignore[union-attr]
        counts = {c.topic: c.msgcount for c in reader.connections}
        assert reader.message_count == sum(counts.values())
    assert types == {f"/{key}": typename for key, typename in TYPES.items()}
    assert {topic for topic, d in durability.items() if d == QosDurability.TRANSIENT_LOCAL} == {
        f"/{key}" for key in LATCHED
    }
    assert all(counts[f"/{key}"] == 1 for key in LATCHED), counts

    messages = bag_messages(bag)
    clock = _stamps(messages, "clock")
    span_s = (clock[-1] - clock[0]) / 1e9
    assert span_s > RECORD_S / 2, f"the bag spans only {span_s:.2f} s of sim time"
    for key, rate in RATES_HZ.items():
        stamps = _stamps(messages, key)
        steps = np.diff(stamps)
        period = 1e9 / rate / STEP_NS
        allowed = [math.floor(period) * STEP_NS, math.ceil(period) * STEP_NS]
        assert len(stamps) == counts[f"/{key}"] and np.all(np.isin(steps, allowed)), (
            f"{key}: stamps not {1e3 / rate:.1f} ms apart: {sorted(set(steps.tolist()))}"
        )
        missed = (stamps[0] - clock[0]) / 1e9, (clock[-1] - stamps[-1]) / 1e9
        assert max(missed) <= TAP_SKEW_S, (
            f"{key}: begins {missed[0]:.2f} s after the clock, ends {missed[1]:.2f} s before"
        )
    assert re.search(
        rf"wrote {re.escape(str(bag))}: 8 topics, {len(messages)} messages, .*dropped 1 malformed", stderr
    ), stderr[-800:]


def test_a_laserscan_read_back_is_the_one_published(recorded: tuple[Path, list[bytes], str]) -> None:
    """Every recorded lidar_front payload is byte for byte one the bus carried, and decodes to the same scan; the garbage is not in the bag."""
    bag, seen, _ = recorded
    published = {stamp_ns(decode(data, TYPES["lidar_front"])): data for data in seen if data != GARBAGE}
    scans = [data for topic, _, _, data in bag_messages(bag) if topic == "/lidar_front"]
    stamps = sorted(stamp_ns(decode(data, TYPES["lidar_front"])) for data in scans)
    spanned_s = (stamps[-1] - stamps[0]) / 1e9  # sim time: a loaded machine runs the world slower than the wall
    assert spanned_s > RECORD_S / 2 and len(scans) >= (RATES_HZ["lidar_front"] * spanned_s + 1) * 0.8, (
        f"{len(scans)} scans over {spanned_s:.2f} s of sim time"
    )
    assert GARBAGE not in scans and GARBAGE in seen
    for data in scans:
        scan = decode(data, TYPES["lidar_front"])
        assert published.get(stamp_ns(scan)) == data, f"the scan stamped {stamp_ns(scan)} ns differs from the bus's"
    bus_scan, bag_scan = decode(published[stamp_ns(scan)], TYPES["lidar_front"]), scan
    assert bag_scan.ranges.shape == (720,) and np.array_equal(bus_scan.ranges, bag_scan.ranges)
    assert (bag_scan.angle_min, bag_scan.angle_increment, bag_scan.header.frame_id) == (
        bus_scan.angle_min,
        bus_scan.angle_increment,
        bus_scan.header.frame_id,
    )


def test_sigint_midway_leaves_a_bag_that_opens_with_everything_received(sim: SimServer, tmp_path: Path) -> None:
    """Ctrl-C: exit 0, the bag opens, and it holds as many messages as the recorder said it received."""
    bag = tmp_path / "interrupted"
    with client_process(sim, "record", "-o", str(bag), "imu_scan", "odom") as recorder:
        wait_until(lambda: "recording /odom" in recorder.stderr(), 20.0, "the recorder to tap odom")
        wait_until(lambda: "recording /imu_scan" in recorder.stderr(), 20.0, "the recorder to tap imu_scan")
        with raw_samples(sim.node.session, sim.any_type_key("imu_scan"), payload) as imu:
            imu.wait_count(400, 30.0, "2 s of sim time on imu_scan while the recorder taps it")
        assert recorder.stop(signal.SIGINT) == 0
        stderr = recorder.stderr()
    found = re.search(r"wrote \S+: 2 topics, (\d+) messages", stderr)
    assert found, stderr[-800:]
    messages = bag_messages(bag)
    assert len(messages) == int(found[1]) > 200  # 2 s of a 200 Hz IMU went by while it tapped
    assert {topic for topic, *_ in messages} == {"/imu_scan", "/odom"}
    assert all(decode(data, typename) is not None for _, typename, _, data in messages)


def test_play_publishes_the_same_messages_in_the_same_order(
    sim: SimServer, recorded: tuple[Path, list[bytes], str]
) -> None:
    """`simbot play` into a fresh namespace: a subscriber gets every message of the bag, byte for byte, in the bag's order."""
    bag, _, _ = recorded
    namespace = unique_namespace()
    with raw_samples(sim.node.session, data_keys(namespace), keyed_payload) as received:
        done = run("play", "--connect", sim.endpoint, "--namespace", namespace, str(bag), "--rate", "4")
        assert done.returncode == 0, done.stderr
        expected = [(f"{namespace}{topic}", data) for topic, _, _, data in bag_messages(bag)]
        received.wait_count(len(expected), 10.0, "the played messages")
    assert received.messages() == expected
    assert f"played {len(expected)} of {len(expected)} messages" in done.stderr


def test_bad_output_and_bad_bags_are_one_line_and_exit_2(sim: SimServer, tmp_path: Path) -> None:
    """An existing bag is not overwritten; a missing or non-bag directory is no bag; all without a traceback."""
    (tmp_path / "taken").mkdir()
    (tmp_path / "not_a_bag").mkdir()
    cases = [
        (("record", "--connect", sim.endpoint, "-o", str(tmp_path / "taken")), "exists already"),
        (("play", "--connect", sim.endpoint, str(tmp_path / "missing")), "cannot open the bag"),
        (("play", "--connect", sim.endpoint, str(tmp_path / "not_a_bag")), "cannot open the bag"),
        (("play", "--connect", sim.endpoint, str(tmp_path), "--rate", "0"), "--rate"),
    ]
    for args, reason in cases:
        done = run(*args)
        assert done.returncode == 2, (args, done.stderr)
        last = done.stderr.strip().splitlines()[-1]  # argparse's own errors come after its usage line
        assert reason in last and last.startswith("simbot ") and "Traceback" not in done.stderr, (args, done.stderr)
