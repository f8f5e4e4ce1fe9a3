"""Benchmark of `simbot record`: what one message costs the recorder, against a bare file write in the same run.

Per message the recorder does two things on its own: the tap checks the payload (one CDR decode,
`tap.check`), and the loop writes it into the MCAP bag (`Bag.write`, rosbags' writer). Both are
timed for the three sizes the bus carries (an IMU sample, a 720-ray scan, a 640×480 image) and
set against the least a recorder must do: `write()` of the same bytes to a file on the same disk.
The last line is what recording the whole bus would take of one core: each key's rate times its
cost, summed (SPEC §4 rates; cameras at the 12 images/s the server renders at 640×480 on one
worker, as bench_sensors measures).

    python benchmarks/bench_record.py [--repeats N]
"""

from __future__ import annotations

import argparse
import functools
import tempfile
from pathlib import Path

import numpy as np
from tables import publish
from timing import per_call_ms

from simbot.bus import encode, messages
from simbot.clients import tap
from simbot.clients.record import Bag
from simbot.clients.tap import RawSample
from simbot.clients.topics import Topic

RATES_HZ = {"imu_scan": 200.0, "lidar_front": 10.0, "camera_front": 12.0}
"""Messages per second of each kind on the whole bus: the IMU, both lidars, all six cameras together."""


def samples() -> dict[str, RawSample]:
    """One payload of each kind, as it arrives on the bus."""
    rng = np.random.default_rng(0)
    imu = messages.imu(0, "imu_link", (0.0, 0.0, 0.0, 1.0), (0.0, 0.0, 0.01), (0.0, 0.0, 9.81))
    scan = messages.laser_scan(
        0, "base_scan_front", (-1.396, 1.396, 0.00389), (0.0, 0.2), (0.08, 10.0), rng.uniform(1, 9, 720)
    )
    image = messages.image(0, "camera_front_optical", rng.integers(0, 255, (480, 640, 3), dtype=np.uint8))
    return {
        name: RawSample(name, msg.__msgtype__, encode(msg), 0)
        for name, msg in (("imu_scan", imu), ("lidar_front", scan), ("camera_front", image))
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=300)
    repeats = parser.parse_args().repeats
    kinds = samples()
    table = [
        "| message | bytes | bag write (rosbags, MCAP) | tap check (one CDR decode) | bare file write |",
        "| --- | --- | --- | --- | --- |",
    ]
    load_ms = 0.0
    with tempfile.TemporaryDirectory() as tmp:
        bag = Bag(Path(tmp) / "bag")
        with (Path(tmp) / "raw").open("wb") as raw:
            for name, sample in kinds.items():
                topic = Topic(name, name, sample.typename, ("pub",))
                bag.add(topic, transient_local=False)
                bare = per_call_ms(functools.partial(raw.write, sample.data), repeats)
                write = per_call_ms(functools.partial(bag.write, sample), repeats)
                check = per_call_ms(functools.partial(tap.check, topic, sample.data, ""), repeats)
                load_ms += RATES_HZ[name] * (write + check)
                table.append(
                    f"| {name} | {len(sample.data)} | {write:.4f} ms = {write / bare:.0f}× bare "
                    f"| {check:.4f} ms = {check / bare:.0f}× bare | {bare:.4f} ms |"
                )
        bag.close()
    table += ["", f"Recording the whole bus (IMU 200/s, scans 10/s, images 12/s): {load_ms / 10:.1f} % of one core."]
    publish("record", table)


if __name__ == "__main__":
    main()
