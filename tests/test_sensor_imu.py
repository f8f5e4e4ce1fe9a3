"""The IMU of a real server in lockstep: noise statistics at rest, turn rate, acceleration, orientation, seeds.

The SDF's noise (SPEC §1): white gaussian, σ 2e-4 rad/s on each gyro axis, 1.7e-2 m/s² on each
accelerometer axis, no bias. Over N samples a standard deviation is estimated within ~1/√(2N)
(2 % at N 1200), so ±20 % of σ is far outside chance, yet small enough to catch a wrong σ, a
variance for a deviation or noise that is missing. At rest the specific force is −g, +9.8 up; the
tyres' residual jitter is far below the noise. The physical truth compared against is the ground
truth pose stream (`model/flexley_tug/pose`, 50 Hz, stamped on multiples of 20 ms, which are also
IMU stamps at 200 Hz).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import numpy as np
import numpy.typing as npt
import pytest
from server_helpers import (
    POSE_STAMPED,
    Collector,
    SimServer,
    pose_of,
    reset_before_each,
    running_server,
    stamp_ns,
    unwrap,
)

from simbot.transform import quaternion_to_matrix, yaw_of

IMU = "sensor_msgs/msg/Imu"
CHEAP_CAMERAS = ("--camera-size", "8x6", "--camera-rate", "1")
G = 9.8
GYRO_SIGMA = 2e-4
ACCEL_SIGMA = 1.7e-2
PERIOD_NS = 5_000_000  # 200 Hz
POSE_NS = 20_000_000  # 50 Hz
SETTLE_STEPS = 1000  # the robot spawns 0.1 m up: 1 s to land and settle on its tyres

Floats = npt.NDArray[np.float64]


@pytest.fixture(scope="module", name="sim")
def sim_fixture() -> Iterator[SimServer]:
    with running_server("empty", extra=CHEAP_CAMERAS) as server:
        yield server


fresh_world = reset_before_each(SETTLE_STEPS)


def _now_ns(sim: SimServer) -> int:
    return round(sim.state()["sim_time"] * 1e9)


def _subscribe(sim: SimServer) -> tuple[Collector[Any], Collector[Any]]:
    imu, truth = sim.subscribe("imu_scan", IMU), sim.subscribe("model/flexley_tug/pose", POSE_STAMPED)
    sim.prime(imu, truth)
    now = _now_ns(sim)
    sim.step((POSE_NS - now % POSE_NS) // 1_000_000)  # on to a common stamp of both streams
    return imu, truth


def _between(collector: Collector[Any], t0: int, t1: int) -> list[Any]:
    """Messages stamped in (t0, t1], waiting for the last one; sorted by stamp."""
    collector.wait_for(
        lambda ms: any(stamp_ns(m) >= t1 - t1 % PERIOD_NS for m in ms), what=f"messages up to {t1 / 1e9} s"
    )
    return sorted((m for m in collector.messages() if t0 < stamp_ns(m) <= t1), key=stamp_ns)


def _vec(v: Any) -> list[float]:
    return [v.x, v.y, v.z]


def _accel(ms: list[Any]) -> Floats:
    return np.array([_vec(m.linear_acceleration) for m in ms])


def _gyro(ms: list[Any]) -> Floats:
    return np.array([_vec(m.angular_velocity) for m in ms])


def _quat(q: Any) -> tuple[float, float, float, float]:
    return (q.x, q.y, q.z, q.w)


def _angle_between(a: tuple[float, ...], b: tuple[float, ...]) -> float:
    """The rotation angle between two quaternions (xyzw, sign-agnostic); normalised first, since
    PyBullet's are unit only to ~1e-8, which through acos near 1 alone would read as 3e-4 rad."""
    (x1, y1, z1, w1), (x2, y2, z2, w2) = np.asarray(a) / np.linalg.norm(a), np.asarray(b) / np.linalg.norm(b)
    # the conjugate of a times b
    w = w1 * w2 + x1 * x2 + y1 * y2 + z1 * z2
    v = np.array(
        [
            w1 * x2 - x1 * w2 - y1 * z2 + z1 * y2,
            w1 * y2 - y1 * w2 - z1 * x2 + x1 * z2,
            w1 * z2 - z1 * w2 - x1 * y2 + y1 * x2,
        ]
    )
    return 2 * math.atan2(float(np.linalg.norm(v)), abs(w))


def _fields(m: Any) -> tuple[Any, ...]:
    """Everything an Imu message carries, comparable with ==."""
    return (
        stamp_ns(m),
        m.header.frame_id,
        _quat(m.orientation),
        tuple(_vec(m.angular_velocity)),
        tuple(_vec(m.linear_acceleration)),
        *(
            tuple(np.asarray(c).tolist())
            for c in (m.orientation_covariance, m.angular_velocity_covariance, m.linear_acceleration_covariance)
        ),
    )


def test_at_rest_gravity_and_noise(sim: SimServer) -> None:
    """6 s at rest, 1200 samples: mean z 9.8 ± 0.05, each axis's σ within 20 % of the SDF's; covariances σ²; frame imu_link."""
    imu, _ = _subscribe(sim)
    t0 = _now_ns(sim)
    sim.step(6000)
    ms = _between(imu, t0, t0 + 6_000_000_000)
    assert len(ms) == 1200
    accel, gyro = _accel(ms), _gyro(ms)
    mean_a, std_a = accel.mean(axis=0), accel.std(axis=0, ddof=1)
    mean_w, std_w = gyro.mean(axis=0), gyro.std(axis=0, ddof=1)
    assert mean_a[2] == pytest.approx(G, abs=0.05), f"mean z specific force {mean_a[2]:.4f}"
    # still: the specific force is g seen through the IMU's own orientation (the tug rests pitched by
    # ~2e-4 rad on its tyres and castors: 0.002 m/s² on x), within 5 standard errors (σ/√1200 = 4.9e-4)
    gravity = np.mean([quaternion_to_matrix(_quat(m.orientation)).T @ np.array([0.0, 0.0, G]) for m in ms], axis=0)
    assert np.all(np.abs(mean_a - gravity) < 5 * ACCEL_SIGMA / math.sqrt(len(ms))), (
        f"mean {mean_a}, gravity in the IMU frame {gravity}"
    )
    assert np.all(np.abs(mean_w) < 5 * GYRO_SIGMA / math.sqrt(len(ms)) + 1e-5), mean_w
    assert std_a == pytest.approx([ACCEL_SIGMA] * 3, rel=0.2), f"acceleration σ {std_a}"
    assert std_w == pytest.approx([GYRO_SIGMA] * 3, rel=0.2), f"angular velocity σ {std_w}"

    last = ms[-1]
    assert last.header.frame_id == "imu_link"
    assert np.asarray(last.angular_velocity_covariance) == pytest.approx(
        np.diag([GYRO_SIGMA**2] * 3).ravel(), rel=1e-9, abs=0
    )
    assert np.asarray(last.linear_acceleration_covariance) == pytest.approx(
        np.diag([ACCEL_SIGMA**2] * 3).ravel(), rel=1e-9, abs=0
    )
    print(
        f"\nmeasured at rest over {len(ms)} samples: accel mean {np.round(mean_a, 4)} σ {np.round(std_a, 5)}; "
        f"gyro mean {mean_w} σ {std_w}"
    )


def test_turning_rate_and_orientation(sim: SimServer) -> None:
    """cmd_vel 0.5 rad/s: the gyro's z reads 0.5 ± 0.05 once turning steadily, and the ground truth's yaw rate within 1 %.

    The tug turns at ~0.46 rad/s, not 0.5: its four wheels scrub sideways (μ2 0.25), see
    test_server_drive. The ground truth is the tighter reference: ∫ω dt over 3 s against the change
    of yaw, the gyro's noise adding 2e-4 × √600 × 5 ms ≈ 2.5e-5 rad. Orientation: the IMU's is
    its link's in the world, the same as the model's (imu_link is fixed, unrotated) at the same stamp.
    """
    imu, truth = _subscribe(sim)
    sim.drive(0.0, 0.5)
    sim.step(1000)  # ~0.5 s to reach a steady turn
    t0 = _now_ns(sim)
    sim.step(3000)
    t1 = t0 + 3_000_000_000
    ms = _between(imu, t0, t1)
    poses = [m for m in _between(truth, t0 - POSE_NS, t1) if stamp_ns(m) % POSE_NS == 0]
    gyro = _gyro(ms)
    rate = float(gyro[:, 2].mean())
    assert rate == pytest.approx(0.5, abs=0.05), f"gyro z {rate:.4f} rad/s at a 0.5 rad/s command"
    assert np.all(np.abs(gyro[:, :2].mean(axis=0)) < 0.01), "turning level: no roll or pitch rate"

    yaws = unwrap([yaw_of(pose_of(m.pose)[1]) for m in poses])
    assert stamp_ns(poses[0]) == t0 and stamp_ns(poses[-1]) == t1
    turned = yaws[-1] - yaws[0]
    integrated = float(np.sum(gyro[:, 2]) * PERIOD_NS / 1e9)  # samples at t0+5 ms .. t1: right-hand sum over (t0, t1]
    assert integrated == pytest.approx(turned, rel=0.01), (
        f"gyro ∫ω dt {integrated:.5f} rad vs ground truth {turned:.5f} rad"
    )

    imu_by_stamp = {stamp_ns(m): m for m in ms}
    worst = max(_angle_between(_quat(imu_by_stamp[stamp_ns(p)].orientation), pose_of(p.pose)[1]) for p in poses[1:])
    assert worst < 1e-6, f"IMU orientation differs from the ground truth by up to {worst:.2e} rad"
    print(
        f"\nmeasured turn: gyro z {rate:.4f} rad/s, ground truth {turned / 3:.4f} rad/s, orientation within {worst:.1e} rad"
    )


def test_forward_acceleration(sim: SimServer) -> None:
    """0 → 0.5 m/s: ∫a dt follows the ground truth's velocity (finite differences of its pose); a ≈ 0 once at speed.

    The wheels reach speed in a few tens of milliseconds (several m/s²), faster than the 50 Hz
    ground truth can resolve, so the comparison is integral: the IMU's acceleration is the change
    of its velocity between samples, so its running sum × 5 ms is the velocity gained, which the
    ground truth gives as (x(t + 20 ms) − x(t − 20 ms)) / 40 ms. The specific force is rotated into
    the world by the IMU's own orientation and g added back, so the tug's pitching on its tyres
    does not count as acceleration. Tolerance 0.02 m/s: the central difference's smoothing and
    the imu_link's 0.15 m height over the pitching base_footprint; the noise adds ~5e-4 m/s.
    """
    imu, truth = _subscribe(sim)
    t0 = _now_ns(sim)
    sim.drive(0.5, 0.0)
    sim.step(1000)
    t1 = t0 + 1_000_000_000
    ms = _between(imu, t0, t1)
    poses = {stamp_ns(m): pose_of(m.pose) for m in _between(truth, t0 - POSE_NS, t1)}

    raw = _accel(ms)
    world = np.array([quaternion_to_matrix(_quat(m.orientation)) @ f for m, f in zip(ms, raw)]) + np.array(
        [0.0, 0.0, -G]
    )
    velocity = np.cumsum(world[:, 0]) * PERIOD_NS / 1e9
    stamps = [stamp_ns(m) for m in ms]
    errors = []
    for t in range(t0 + 5 * POSE_NS, t1 - POSE_NS + 1, POSE_NS):  # from 0.1 s: the start is over by then
        truth_v = (poses[t + POSE_NS][0][0] - poses[t - POSE_NS][0][0]) / (2 * POSE_NS / 1e9)
        errors.append(velocity[stamps.index(t)] - truth_v)
    worst = max(errors, key=abs)
    assert abs(worst) < 0.02, f"IMU velocity off the ground truth's by up to {worst:.4f} m/s"
    assert velocity[-1] == pytest.approx(0.5, rel=0.05)

    # raw x: a burst of forward acceleration, the mean over the first 0.1 s that of 0 → ~0.5 m/s
    start = raw[:20, 0]
    assert start.max() > 2.0 and start.mean() == pytest.approx(velocity[19] / 0.1, rel=0.1), (
        f"first 0.1 s: {np.round(start, 2)}"
    )
    steady = raw[100:, 0]  # 0.5..1 s at constant speed
    assert abs(steady.mean()) < 0.05, f"at constant speed the x acceleration averages {steady.mean():.4f}"
    assert ms[-1].header.frame_id == "imu_link"
    worst_q = max(_angle_between(_quat(m.orientation), poses[stamp_ns(m)][1]) for m in ms if stamp_ns(m) in poses)
    assert worst_q < 1e-6
    print(
        f"\nmeasured acceleration: peak {start.max():.2f} m/s², mean {start.mean():.2f} over the first 0.1 s, "
        f"velocity from ∫a {velocity[-1]:.4f} m/s, worst gap to ground truth {worst:+.4f} m/s, steady mean {steady.mean():+.4f}"
    )


def _run(seed: int, steps: int = 300) -> list[Any]:
    with running_server("empty", seed=seed, extra=CHEAP_CAMERAS) as sim:
        imu = sim.subscribe("imu_scan", IMU)
        sim.prime(imu)
        sim.step(steps)
        t = _now_ns(sim)
        return _between(imu, 0, t - t % PERIOD_NS)


def test_seeds() -> None:
    """Same seed: identical messages. Another seed: other noise on the same motion (orientation has no noise)."""
    a, b, c = _run(11), _run(11), _run(12)
    stamps = sorted({stamp_ns(m) for m in a} & {stamp_ns(m) for m in b} & {stamp_ns(m) for m in c})
    assert len(stamps) >= 50
    by = [{stamp_ns(m): m for m in run} for run in (a, b, c)]
    first, same, other = ([by_run[t] for t in stamps] for by_run in by)
    assert [_fields(m) for m in first] == [_fields(m) for m in same], "same seed, different messages"
    assert all(_quat(x.orientation) == _quat(y.orientation) for x, y in zip(first, other)), (
        "the seed changed the physics"
    )
    da, dw = _accel(first) - _accel(other), _gyro(first) - _gyro(other)
    assert np.all(da != 0) and np.all(dw != 0), "another seed, some noise repeated"
    # the difference of two independent noises: σ√2 each
    assert da.std() == pytest.approx(ACCEL_SIGMA * math.sqrt(2), rel=0.25) and dw.std() == pytest.approx(
        GYRO_SIGMA * math.sqrt(2), rel=0.25
    )
