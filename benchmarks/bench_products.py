"""Benchmark of the BLAS-free products (issue 35): what computing every published value without
numpy's BLAS costs, against the old forms put back, in one run on one in-process server.

numpy hands `@`, `np.dot` and the norm of a vector to OpenBLAS, whose kernel (and with it the last
bit of a sum) is chosen per CPU at run time; simbot.transform's `matmul`, `norm` and `rotate_into`
sum term by term in index order instead. Measured here, each as shipped and with the old form:

1. an IMU sample, `Imu.post_update` (pose, velocity, two rotations into the sensor frame, noise,
   encode, publish): shipped, `rotate_into`; old, Rᵀ from `quaternion_to_matrix` (the quaternion
   normalised by `np.linalg.norm`) once a sample, then `Rᵀ @ v` for the rates and the acceleration;
2. a lidar scan, `Lidar.post_update` (720 rays): the fan turned by `matmul`, old by `@`;
3. the bare products: 3×3 @ 3-vector, Rᵀv from a quaternion, 4×4 @ 4×4 (a pose composed), the
   lidar's 720 directions @ 3×3, and a 640×480 image's luminance (float32 rows @ 3 weights).

The old forms are put back by patching the modules' names (`simbot.transform.norm`,
`simbot.sim.systems.imu.rotate_into`, `simbot.sim.systems.lidar.matmul`): the code measured is the
shipped code but for the products. Shipped and old are measured in alternation, `--rounds` times;
the table gives the medians and the median of the rounds' ratios (shipped ÷ old).

    python benchmarks/bench_products.py [--rounds N]
"""

from __future__ import annotations

import argparse
import statistics
from collections.abc import Callable, Iterator
from contextlib import contextmanager, nullcontext
from typing import Any
from unittest import mock

import numpy as np
import numpy.typing as npt
from bench_sensors import Costs, imu_costs, lidar_costs
from in_process import in_process_server
from live_runs import IMU, LIDARS, count_topics
from tables import publish
from timing import per_call_ms

import simbot.transform
from simbot.sim.render.outputs import LUMA
from simbot.sim.systems import imu, lidar
from simbot.transform import Transform, matmul, quaternion_to_matrix, rotate_into

BATCH_S = 2e-4
"""Seconds of calls timed together for a bare product (a few µs each: a clock read per call would weigh)."""


def blas_norm(vector: Any) -> float:
    return float(np.linalg.norm(vector))


def blas_matmul(a: Any, b: Any) -> npt.NDArray[np.float64]:
    return np.asarray(a) @ np.asarray(b)


class BlasRotation:
    """Rᵀv as the IMU computed it before: `quaternion_to_matrix(q).T @ v`, the matrix built once a
    sample for its two vectors (a sample's two calls share one quaternion object; each sample's
    pose is a new one)."""

    def __init__(self) -> None:
        self.quat: object = None
        self.turn = np.eye(3)

    def __call__(self, xyzw: Any, vector: Any) -> npt.NDArray[np.float64]:
        if xyzw is not self.quat:
            self.quat, self.turn = xyzw, quaternion_to_matrix(xyzw).T
        return self.turn @ np.asarray(vector)


@contextmanager
def blas_forms() -> Iterator[None]:
    """The products as they were before issue 35: BLAS's norm, `@`."""
    with (
        mock.patch.object(simbot.transform, "norm", blas_norm),
        mock.patch.object(imu, "rotate_into", BlasRotation()),
        mock.patch.object(lidar, "matmul", blas_matmul),
    ):
        yield


def bare_us(work: Callable[[], object], repeats: int = 50) -> float:
    """Median µs of one call, timed in batches of about `BATCH_S`."""
    once = per_call_ms(work, 3) * 1e-3
    batch = max(1, round(BATCH_S / max(once, 1e-9)))
    return per_call_ms(lambda: [work() for _ in range(batch)], repeats) * 1e3 / batch


def bare_products() -> dict[str, tuple[Callable[[], object], Callable[[], object]]]:
    """Each bare product: (shipped, old); the old one is called under `blas_forms`."""
    rng = np.random.default_rng(35)
    quat = tuple(rng.normal(size=4).tolist())
    vector = rng.normal(size=3)
    turn = quaternion_to_matrix(quat)
    a, b = (Transform.of(rng.normal(size=3).tolist(), rng.normal(size=4).tolist()).matrix() for _ in range(2))
    rays, pixels = rng.normal(size=(720, 3)), rng.uniform(0.0, 255.0, size=(480, 640, 3)).astype(np.float32)
    luma = np.asarray(LUMA, dtype=np.float32)
    with blas_forms():
        assert np.allclose(rotate_into(quat, vector), quaternion_to_matrix(quat).T @ vector, rtol=0.0, atol=1e-12)
    return {
        "3×3 @ 3-vector": (lambda: matmul(turn, vector), lambda: turn @ vector),
        "Rᵀv from a quaternion (`rotate_into`; old: `quaternion_to_matrix(q).T @ v`)": (
            lambda: rotate_into(quat, vector),
            lambda: quaternion_to_matrix(quat).T @ vector,
        ),
        "4×4 @ 4×4 (a pose composed)": (lambda: matmul(a, b), lambda: a @ b),
        "720 ray directions @ 3×3 (a lidar's fan turned)": (lambda: matmul(rays, turn.T), lambda: rays @ turn.T),
        "640×480 luminance (float32 rows @ 3 weights)": (lambda: matmul(pixels, luma), lambda: pixels @ luma),
    }


def sensor_us(server: Any) -> dict[str, float]:
    """An IMU sample's and a lidar scan's µs, as the modules compute them now."""
    costs = Costs()
    imu_costs(server, costs, 2000)
    lidar_costs(server, costs, 100)
    return {
        "IMU sample, `Imu.post_update`": costs.imu_ms * 1e3,
        "lidar scan of 720 rays, `Lidar.post_update`": costs.lidar_ms * 1e3,
    }


def measure(rounds: int) -> dict[str, tuple[list[float], list[float]]]:
    """{measurement: (shipped figures, old figures)}, one of each a round; which of the two goes
    first alternates from round to round, so that a machine slowing down weighs on both."""
    found: dict[str, tuple[list[float], list[float]]] = {}
    with in_process_server() as (server, client):
        count_topics(client, [*LIDARS, IMU])  # the bytes really leave, as they do for a subscriber
        products = bare_products()
        for round_ in range(rounds):
            for old in (False, True) if round_ % 2 == 0 else (True, False):
                with blas_forms() if old else nullcontext():
                    figures = sensor_us(server)
                    figures.update((name, bare_us(pair[old])) for name, pair in products.items())
                for name, figure in figures.items():
                    found.setdefault(name, ([], []))[old].append(figure)
    return found


def table(found: dict[str, tuple[list[float], list[float]]], rounds: int) -> list[str]:
    lines = [
        f"| measurement | shipped, BLAS-free (µs) | old form, BLAS (µs) | shipped ÷ old (median of {rounds} rounds) |",
        "| --- | --- | --- | --- |",
    ]
    for name, (shipped, old) in found.items():
        ratio = statistics.median(s / o for s, o in zip(shipped, old, strict=True))
        lines.append(f"| {name} | {statistics.median(shipped):.1f} | {statistics.median(old):.1f} | {ratio:.2f} |")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=15, help="shipped/old pairs measured (default 15)")
    args = parser.parse_args()
    publish("products", table(measure(args.rounds), args.rounds))


if __name__ == "__main__":
    main()
