"""The lidar merger (clients/merger.py): a real server, a real merger process, the geometry of known boxes.

`tests/fixtures/merger_boxes.sdf` stands boxes 1 m tall around a robot spawned at the origin,
yaw 0 (its header lists them). In `scan`, the bin toward a box reads the distance from
base_link's origin to the box along that bearing, computed here with a 2-D slab test from the
robot's ground-truth pose: the scan is planar, so only bearings and XY distances count, and
base_link is base_footprint lifted 0.09 m, the same XY. The tolerance, 0.03 m, covers the
lidar's quantisation (0.005), the spread of a bin (a return anywhere within ±0.125° of the bin's
bearing: up to 3.1 m · tan 46° · 0.0022 = 0.007 on the most oblique face read) and the robot's
settled pose (< 2 mm); measured errors are printed.

Bins toward faces a lidar sees at a grazing angle may be empty (its rays are sparser there than
the bins), so the geometry test checks every *finite* bin against the boxes, and asks each box
for a reading at one bearing where its lidar sees it well.

The bad-input and missing-partner tests also go through the bus: garbage on `lidar_front` next to
a real server, and synthetic front scans alone on a stand-in bus (a server-role node of the test
that publishes its own latched `tf_static`). Pure-function tests cover what the bus cannot show
cheaply: NaN and out-of-range returns, inconsistent fields, the rays cache, the bin wrap at ±π.
"""

from __future__ import annotations

import math
import os
import re
import subprocess
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
import pytest
from bus_helpers import endpoint, free_port, unique_namespace
from client_helpers import client_command, client_process
from conftest import REPO
from server_helpers import Collector, SimServer, running_server, stamp_ns, wait_until

from simbot.bus import BusOptions, Node, decode, encode, messages
from simbot.scan_merge import BadScan, Binning, ScanMerger
from simbot.transform import Transform

WORLD = REPO / "tests" / "fixtures" / "merger_boxes.sdf"
LASER_SCAN = "sensor_msgs/msg/LaserScan"
LIDARS = ("lidar_front", "lidar_back")
AT_ORIGIN = ("--spawn", "0", "0", "0.1", "0")
CHEAP_CAMERAS = ("--camera-size", "8x6", "--camera-rate", "1")
SETTLE_STEPS = 500  # spawned 0.1 m up, the robot settles on its tyres first
SCAN_STEPS = 200  # one scan period (5 Hz) of 1 ms steps
SCAN_NS = 200_000_000
TOLERANCE = 0.03
WAIT_S = 20.0  # generous: two cores shared with other test runs

BINS = 1440
BEARINGS = -math.pi + np.arange(BINS) * 2 * math.pi / BINS
SAMPLES, ANGLE_MAX = 720, 1.396263  # the Tug's lidars (SPEC §1)
SENSORS_IN_BASE_LINK = {  # SPEC §1, base_link being 0.09 m above base_footprint: xyz, yaw
    "base_scan_front": ((0.99, 0.0, 0.17), 0.0),
    "base_scan_back": ((-0.95, 0.0, 0.17), math.pi),
}

# the fixture's boxes in the XY plane: (min corner, max corner)
BOXES = {
    "front_wall": ((3.0, -1.0), (3.2, 1.5)),
    "front_left_box": ((1.6, 2.2), (2.0, 2.6)),
    "back_box": ((-3.2, -0.8), (-3.0, 0.4)),
    "back_right_box": ((-2.4, -2.6), (-2.0, -2.2)),
    "left_post": ((-0.2, 3.0), (0.2, 3.4)),
    "right_post": ((-0.2, -3.4), (0.2, -3.0)),
}
SEEN = {  # a bearing (degrees) where each box's face is seen well by its lidar, and the distance there
    "front_wall": (0.0, 3.0),
    "front_wall oblique": (15.0, 3.0 / math.cos(math.radians(15))),
    "front_left_box": (50.0, 2.2 / math.sin(math.radians(50))),
    "back_box": (180.0, 3.0),
    "back_right_box": (-135.0, 2.2 / math.sin(math.radians(45))),
}
NEAR_AXIS = 1e-4  # the Tug's rays nearest the axis are ±0.0019 rad off it: their returns are a few µm shorter than the axis reading
UNSEEN_HALF_WIDTH = math.radians(15)  # around ±90°: neither lidar's rays come back from there

Floats = npt.NDArray[np.float64]


# --- geometry --------------------------------------------------------------------------------


def ray_to_boxes(origin: Floats, directions: Floats, grow: float = 0.0) -> Floats:
    """2-D slab test: the distance along each direction from `origin` to the nearest box (grown by `grow`), or inf."""
    best = np.full(len(directions), np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        for low, high in BOXES.values():
            t1 = (np.asarray(low) - grow - origin) / directions
            t2 = (np.asarray(high) + grow - origin) / directions
            near = np.nanmax(np.minimum(t1, t2), axis=1)
            far = np.nanmin(np.maximum(t1, t2), axis=1)
            best = np.where((far >= near) & (near > 0) & (near < best), near, best)
    return best


def truth_in_bins(robot_xy: Floats, yaw: float) -> tuple[Floats, npt.NDArray[np.bool_]]:
    """Per bin: the distance from base_link to the boxes along its bearing, and whether that is
    unambiguous (the same box face with the boxes 2 cm bigger or smaller: not at an edge)."""
    world = BEARINGS + yaw
    directions = np.stack([np.cos(world), np.sin(world)], axis=1)
    nominal = ray_to_boxes(robot_xy, directions)
    grown, shrunk = ray_to_boxes(robot_xy, directions, 0.02), ray_to_boxes(robot_xy, directions, -0.02)
    with np.errstate(invalid="ignore"):
        clear = (np.isfinite(grown) == np.isfinite(shrunk)) & (~np.isfinite(nominal) | (np.abs(grown - shrunk) < 0.1))
    return nominal, clear


def bin_of(degrees: float) -> int:
    return round((math.radians(degrees) + math.pi) / (2 * math.pi / BINS)) % BINS


def ranges_of(scan: Any) -> Floats:
    return np.asarray(scan.ranges, dtype=np.float64)


def yaw_quaternion(yaw: float) -> tuple[float, float, float, float]:
    return (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))


def sensor_pose(frame: str) -> Floats:
    xyz, yaw = SENSORS_IN_BASE_LINK[frame]
    return Transform.of(xyz, yaw_quaternion(yaw)).matrix()


def synthetic_scan(ns: int, frame: str, ranges: Sequence[float] | Floats, half_angle: float = ANGLE_MAX) -> Any:
    """A LaserScan like the Tug's lidars' (0.08–10 m, 5 Hz), its rays evenly over ±`half_angle`."""
    increment = 2 * half_angle / (len(ranges) - 1)
    return messages.laser_scan(ns, frame, (-half_angle, half_angle, increment), (0.0, 0.2), (0.08, 10.0), ranges)


# --- the merger on a real server -------------------------------------------------------------


@pytest.fixture(scope="module", name="sim")
def sim_fixture() -> Iterator[SimServer]:
    with running_server(str(WORLD), extra=(*AT_ORIGIN, *CHEAP_CAMERAS)) as server:
        server.step(SETTLE_STEPS)
        yield server


@dataclass
class Outputs:
    scan: Collector[Any]
    front: Collector[Any]
    back: Collector[Any]


def _outputs(sim: SimServer) -> Outputs:
    return Outputs(
        sim.subscribe("scan", LASER_SCAN),
        sim.subscribe("lidar_front_fixed", LASER_SCAN),
        sim.subscribe("lidar_back_fixed", LASER_SCAN),
    )


def _now_ns(sim: SimServer) -> int:
    return round(sim.state()["sim_time"] * 1e9)


def _step_one_scan(sim: SimServer) -> int:
    """Steps to the next multiple of the scan period (both lidars scan then); that sim time."""
    now = _now_ns(sim)
    target = (now // SCAN_NS + 1) * SCAN_NS
    sim.step((target - now) // 1_000_000)
    return target


def _first_merge(sim: SimServer, outputs: Outputs) -> int:
    """Steps a scan at a time until the starting merger publishes one (its subscriptions are live); its stamp."""
    deadline = time.monotonic() + WAIT_S
    while True:
        t = _step_one_scan(sim)
        try:
            outputs.scan.wait_stamp(t, timeout=1.0)
            return t
        except AssertionError:
            if time.monotonic() > deadline:
                raise AssertionError(f"the merger published no scan within {WAIT_S} s") from None


def test_merged_scan_reads_the_boxes(sim: SimServer) -> None:
    """`scan`: base_link, −π..π in 1440 bins; every finite bin within 0.03 m of the boxes' geometry, each
    box read where its lidar sees it, ±90° empty though posts stand there; `scan` = min of the two `_fixed`."""
    outputs = _outputs(sim)
    with client_process(sim, "merger"):
        _first_merge(sim, outputs)
        t = _step_one_scan(sim)
        merged = outputs.scan.wait_stamp(t, timeout=WAIT_S)
        front = outputs.front.wait_stamp(t, timeout=WAIT_S)
        back = outputs.back.wait_stamp(t, timeout=WAIT_S)
    (x, y, _), quat = sim.pose()
    yaw = math.atan2(2 * (quat[3] * quat[2] + quat[0] * quat[1]), 1 - 2 * (quat[1] ** 2 + quat[2] ** 2))
    truth, clear = truth_in_bins(np.array([x, y]), yaw)

    for scan in (merged, front, back):
        assert scan.header.frame_id == "base_link" and stamp_ns(scan) == t
        assert len(scan.ranges) == BINS
        assert scan.angle_min == pytest.approx(-math.pi) and scan.angle_increment == pytest.approx(2 * math.pi / BINS)
        assert scan.angle_max == pytest.approx(math.pi - 2 * math.pi / BINS)
        assert scan.scan_time == pytest.approx(0.2) and scan.time_increment == 0.0
    # a return r of a lidar 0.99 m (front) or 0.95 m (back) from base_link lies within r ± that offset of it
    assert (merged.range_min, merged.range_max) == (0.0, pytest.approx(10.0 + 0.99))
    assert (back.range_min, back.range_max) == (0.0, pytest.approx(10.0 + 0.95))

    r, f, b = ranges_of(merged), ranges_of(front), ranges_of(back)
    # every finite bin is a box, at the right distance (edge bins aside, whose verdict depends on a cm)
    finite = np.isfinite(r) & clear
    assert not np.any(finite & ~np.isfinite(truth)), (
        f"readings where no box stands: {np.degrees(BEARINGS[finite & ~np.isfinite(truth)])}"
    )
    error = np.abs(r[finite] - truth[finite])
    worst = BEARINGS[finite][error.argmax()]
    assert error.max() <= TOLERANCE, f"worst bin {math.degrees(worst):+.2f}° off by {error.max():.4f} m"
    assert finite.sum() > 250, f"only {finite.sum()} bins read a box"
    for name, (degrees, distance) in SEEN.items():
        assert r[bin_of(degrees)] == pytest.approx(distance, abs=TOLERANCE), f"{name} at {degrees}°"
    # the sides: posts stand at ±90° (the geometry says so), but no lidar looks there
    side = np.abs(np.abs(BEARINGS) - math.pi / 2) < UNSEEN_HALF_WIDTH
    assert np.isfinite(truth[side]).sum() >= 2 * 20, "the posts stand in the unseen sectors"
    assert np.isposinf(r[side]).all()
    # each lidar alone, and the merge as their union
    assert np.all(np.isposinf(f[np.abs(BEARINGS) > math.pi / 2])), "the front lidar sees nothing behind base_link"
    assert np.all(np.isposinf(b[np.abs(BEARINGS) < math.pi / 2])), "the back lidar sees nothing ahead of base_link"
    assert np.array_equal(r, np.minimum(f, b))
    for alone in (f, b):
        assert np.all(alone[np.isfinite(alone)] >= r[np.isfinite(alone)])
    print(
        f"\nmeasured: {finite.sum()} bins on boxes, worst error {error.max() * 1000:.1f} mm (median "
        f"{np.median(error) * 1000:.1f} mm); seen bearings: "
        + ", ".join(f"{d:+.0f}° {r[bin_of(d)]:.3f}/{m:.3f}" for d, m in SEEN.values())
        + f"; empty bins on boxes (grazing faces): {int((np.isinf(r) & np.isfinite(truth) & clear & ~side).sum())}"
    )


def test_garbage_on_the_lidar_keys_is_dropped_and_counted(sim: SimServer) -> None:
    """Random bytes on lidar_front and a truncated LaserScan on lidar_back: warned (once a key) and counted;
    the next pair merges as usual."""
    outputs = _outputs(sim)
    with client_process(sim, "merger") as merger:
        _first_merge(sim, outputs)
        whole = encode(synthetic_scan(0, "base_scan_back", np.full(SAMPLES, 2.0)))
        sim.send_raw("lidar_front", "sensor_msgs/msg/LaserScan", os.urandom(97))
        sim.send_raw("lidar_back", "sensor_msgs/msg/LaserScan", whole[: len(whole) // 2])
        warnings = [f"{sim.key(topic)}: dropped a payload that is not a valid {LASER_SCAN}" for topic in LIDARS]
        wait_until(lambda: all(w in merger.stderr() for w in warnings), WAIT_S, "the merger's warning on each key")
        t = _step_one_scan(sim)
        merged = outputs.scan.wait_stamp(t, timeout=WAIT_S)
        outputs.front.wait_stamp(t, timeout=WAIT_S)
        outputs.back.wait_stamp(t, timeout=WAIT_S)
        assert merger.alive()
        assert merger.stop() == 0
        log = merger.stderr()
    r = ranges_of(merged)
    assert r[bin_of(0.0)] == pytest.approx(3.0, abs=TOLERANCE) and r[bin_of(180.0)] == pytest.approx(3.0, abs=TOLERANCE)
    assert "dropped 2 undecodable payloads" in log, log
    assert "Traceback" not in log
    print(
        f"\nmeasured: after 2 garbage payloads, scan at {t / 1e9:.1f} s reads {r[bin_of(0.0)]:.3f} ahead, {r[bin_of(180.0)]:.3f} behind"
    )


# --- a missing partner, on a bus of the test's own -------------------------------------------


@dataclass(frozen=True)
class StandIn:
    """A bus with no simulator: a server-role node that the merger connects to (endpoint and namespace
    are all that client_process needs of a SimServer)."""

    node: Node
    port: int
    namespace: str

    @property
    def endpoint(self) -> str:
        return endpoint(self.port)


@contextmanager
def stand_in_bus() -> Iterator[StandIn]:
    port, namespace = free_port(), unique_namespace()
    with Node(BusOptions(listen=(endpoint(port),), namespace=namespace), "server") as node:
        yield StandIn(node, port, namespace)


def _tf_static(node: Node) -> None:
    """The two lidar frames under base_link, latched, as the server publishes them."""
    transforms = [
        messages.transform_stamped(0, "base_link", frame, xyz, yaw_quaternion(yaw))
        for frame, (xyz, yaw) in SENSORS_IN_BASE_LINK.items()
    ]
    node.publisher("tf_static", messages.TFMessage, latched=True).put(messages.tf_message(transforms))


def _collect(node: Node, topic: str) -> Collector[Any]:
    collector: Collector[Any] = Collector()
    node.subscribe(topic, LASER_SCAN, collector)
    return collector


def test_front_alone_still_makes_a_scan() -> None:
    """Only lidar_front publishes (a circle of 2 m about the lidar, with NaN, inf and out-of-range rays):
    `scan` still comes, one per front scan, equal to `lidar_front_fixed`; no `lidar_back_fixed`."""
    ranges = np.full(SAMPLES, 2.0)
    ranges[[0, 100, 200, 300]] = [np.nan, np.inf, 0.05, 10.5]  # none of these may show
    with stand_in_bus() as bus:
        _tf_static(bus.node)
        merged, front, back = (_collect(bus.node, t) for t in ("scan", "lidar_front_fixed", "lidar_back_fixed"))
        publisher = bus.node.publisher("lidar_front", LASER_SCAN, drop=False)
        with client_process(bus, "merger") as merger:
            deadline, k = time.monotonic() + WAIT_S, 0
            while len(merged) < 3:
                assert time.monotonic() < deadline, f"no scan from front scans alone within {WAIT_S} s"
                k += 1
                publisher.put(synthetic_scan(k * SCAN_NS, "base_scan_front", ranges))
                time.sleep(0.1)
            assert merger.stop() == 0
            log = merger.stderr()
        scans, fixed = merged.messages(), {stamp_ns(m): m for m in front.messages()}
    assert len(back) == 0
    sent = decode(
        encode(synthetic_scan(0, "base_scan_front", ranges)), LASER_SCAN
    )  # its angles as float32, as on the wire
    expected = ScanMerger(Binning(BINS)).rebin(sent, sensor_pose("base_scan_front"))
    for scan in scans:
        assert stamp_ns(scan) % SCAN_NS == 0 and stamp_ns(scan) < k * SCAN_NS, (
            "each comes out when the next front scan is in"
        )
        assert np.array_equal(ranges_of(scan), ranges_of(fixed[stamp_ns(scan)]))
        assert np.array_equal(ranges_of(scan), expected.ranges.astype(np.float32))
    r = ranges_of(scans[-1])
    assert r[bin_of(0.0)] == pytest.approx(0.99 + 2.0, abs=NEAR_AXIS)
    # the circle's nearest points to base_link are its ends, ±80° off the lidar's axis: nothing of the 0.05 m ray
    assert np.nanmin(r) == pytest.approx(
        math.sqrt(0.99**2 + 2.0**2 + 2 * 0.99 * 2.0 * math.cos(ANGLE_MAX)), abs=NEAR_AXIS
    )
    assert np.isfinite(r).sum() > 440  # the circle spans ±55.8° about base_link: 446 bins, less the 3 rays left out
    summary = re.search(r"published (\d+) merged scans \((\d+) from one lidar alone\)", log)
    assert summary and int(summary[1]) == int(summary[2]) >= len(scans), log
    print(f"\nmeasured: {len(scans)} scans from {k} front scans alone; {np.isfinite(r).sum()} finite bins")


# --- the merge as a function -----------------------------------------------------------------


def _merger() -> ScanMerger:
    return ScanMerger(Binning(BINS))


def test_one_scan_merges_to_itself_and_two_to_their_minimum() -> None:
    front = synthetic_scan(0, "base_scan_front", np.full(SAMPLES, 2.0))
    back = synthetic_scan(0, "base_scan_back", np.full(SAMPLES, 1.5))
    merger = _merger()
    (alone,), merged = merger.merge([(front, sensor_pose("base_scan_front"))])
    assert np.array_equal(alone.ranges, merged.ranges)
    (f, b), both = merger.merge([(front, sensor_pose("base_scan_front")), (back, sensor_pose("base_scan_back"))])
    assert np.array_equal(both.ranges, np.minimum(f.ranges, b.ranges))
    assert both.range_min == 0.0 and both.range_max == pytest.approx(10.99)
    assert both.ranges[bin_of(180.0)] == pytest.approx(0.95 + 1.5) and both.ranges[bin_of(0.0)] == pytest.approx(2.99)


def test_inf_nan_and_out_of_range_returns_contribute_nothing() -> None:
    ranges = np.full(SAMPLES, np.inf)
    ranges[[10, 20, 30, 40, 50, 360]] = [np.nan, -1.0, 0.079, 10.01, -np.inf, 4.0]
    out = _merger().rebin(synthetic_scan(0, "base_scan_front", ranges), sensor_pose("base_scan_front")).ranges
    assert np.isfinite(out).sum() == 1 and out[bin_of(0.0)] == pytest.approx(4.99, abs=NEAR_AXIS)
    assert not np.isnan(out).any()


def test_inconsistent_fields_are_refused() -> None:
    """Ray count that does not fit the angles, non-finite angles: BadScan, not a wrong scan."""
    merger, pose = _merger(), sensor_pose("base_scan_front")
    short = synthetic_scan(0, "base_scan_front", np.full(SAMPLES, 2.0))
    short.ranges = short.ranges[:700]
    with pytest.raises(BadScan, match="do not end at angle_max"):
        merger.rebin(short, pose)
    broken = synthetic_scan(0, "base_scan_front", np.full(SAMPLES, 2.0))
    broken.angle_increment = math.nan
    with pytest.raises(BadScan, match="not finite"):
        merger.rebin(broken, pose)


def test_a_moved_sensor_or_new_angles_are_not_served_stale_rays() -> None:
    """The rays are cached per scan geometry; a new pose or new angles must still land in the right bins."""
    merger = _merger()
    scan = synthetic_scan(0, "base_scan_front", np.full(SAMPLES, 2.0))
    first = merger.rebin(scan, sensor_pose("base_scan_front")).ranges
    again = merger.rebin(scan, sensor_pose("base_scan_front")).ranges
    looking_back = Transform.of((0.99, 0.0, 0.17), yaw_quaternion(math.pi)).matrix()
    turned = merger.rebin(scan, looking_back).ranges
    assert np.array_equal(first, again)
    assert np.isposinf(turned[bin_of(0.0)]) and np.isfinite(first[bin_of(0.0)])
    # looking back from 0.99 m ahead, its nearest return is the one straight back, 2 − 0.99 m behind base_link
    assert turned.min() == pytest.approx(2.0 - 0.99, abs=NEAR_AXIS)
    assert abs(abs(BEARINGS[turned.argmin()]) - math.pi) < 3 * 2 * math.pi / BINS
    narrow = synthetic_scan(0, "base_scan_front", np.full(361, 2.0), half_angle=0.5)
    out = merger.rebin(narrow, sensor_pose("base_scan_front")).ranges
    bearings = BEARINGS[np.isfinite(out)]
    # 2 m from a lidar 0.99 m ahead, ±0.5 rad about it is ±0.33 rad about base_link
    assert bearings.max() == pytest.approx(
        math.atan2(2 * math.sin(0.5), 0.99 + 2 * math.cos(0.5)), abs=2 * math.pi / BINS
    )


def test_bins_wrap_at_pi() -> None:
    """A return straight behind base_link lands in bin 0 (−π), from either side of the ±π seam."""
    for ranges in ([2.0, np.inf, np.inf], [np.inf, np.inf, 2.0]):  # 0.001 rad right of −x, then left of it
        scan = synthetic_scan(0, "base_scan_back", ranges, half_angle=0.001)
        out = _merger().rebin(scan, sensor_pose("base_scan_back")).ranges
        assert np.flatnonzero(np.isfinite(out)).tolist() == [0], "bin 0 holds ±π"
        assert out[0] == pytest.approx(2.95, abs=1e-5)
    assert Binning(BINS).angle_max == pytest.approx(math.pi - 2 * math.pi / BINS)


# --- the command line ------------------------------------------------------------------------


@pytest.mark.parametrize(("option", "value"), [("--bins", "0"), ("--scan-period", "nan")])
def test_bad_option_is_one_line_and_exit_2(option: str, value: str) -> None:
    done = subprocess.run(
        client_command("merger", option, value), check=False, capture_output=True, text=True, cwd=REPO, timeout=60
    )
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert option in lines[-1] and "Traceback" not in done.stderr, done.stderr
