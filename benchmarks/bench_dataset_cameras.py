"""Benchmark of the dataset cameras: what a frame of each costs against a colour camera of the same
size, measured in the same run, as ratios.

One world (written to a temporary folder): a row of labelled crates (Gazebo's Label system) before
a static model that carries one camera per row of `ROWS`, each with its own `<topic>`, all at one
size. A server is built in this process as `simbot-server` builds it (lockstep, so that the step
that takes a frame waits for it). For each row in turn its keys are subscribed (so that camera
alone renders) and the world steps `--frames` of its frames; a frame's cost is the worker's time on
it (scene update, render, the outputs' finishing steps, the copy: `Frame.render_s`) and the
server's in the camera's `publish` (messages; for boxes their geometry and the drawn image).
Rounds interleave the rows and the median frame is kept, so a busy machine moves every row alike.

A new kind of dataset camera adds a `Row` (its SDF sensor type, what it needs inside `<camera>`,
the keys it publishes under its topic); the colour camera stays the first row, the baseline.

    python benchmarks/bench_dataset_cameras.py [--size WxH] [--frames N] [--rounds R] [--renderer auto|gl|tiny]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
import uuid
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from bench_server import free_port
from live_runs import count_topics
from tables import publish

from simbot.bus import BusOptions, Node
from simbot.sim.loop.simulation import Mode
from simbot.sim.render import Frame
from simbot.sim.server import Server, ServerConfig
from simbot.sim.systems.camera import Camera

RATE_HZ = 30
STEPS_PER_FRAME = 34
"""1 ms steps: one tick of a 30 Hz camera every 33 or 34 steps."""
FIRST_FRAME_TIMEOUT_S = 120.0
"""The render pool starts with the first subscription (seconds on a small machine)."""


@dataclass(frozen=True)
class Row:
    """One camera measured: its SDF sensor type, its elements inside `<camera>`, and its keys (each
    its topic plus a suffix, e.g. `/labels_map`, or "" for the topic itself)."""

    name: str
    sensor: str
    camera: str = ""
    keys: tuple[str, ...] = ("",)

    @property
    def topic(self) -> str:
        return self.name.replace(" ", "_")


ROWS = (
    Row("colour", "camera"),
    Row(
        "segmentation semantic",
        "segmentation",
        "<segmentation_type>semantic</segmentation_type>",
        ("/labels_map", "/colored_map"),
    ),
    Row(
        "segmentation panoptic",
        "segmentation",
        "<segmentation_type>panoptic</segmentation_type>",
        ("/labels_map", "/colored_map"),
    ),
    Row("boxes visible_2d", "boundingbox_camera", "<box_type>visible_2d</box_type>", ("", "_image")),
    Row("boxes full_2d", "boundingbox_camera", "<box_type>full_2d</box_type>", ("", "_image")),
    Row("boxes 3d", "boundingbox_camera", "<box_type>3d</box_type>", ("", "_image")),
)
"""The colour camera (the baseline) first."""

CRATES = 12
LABEL = '<plugin filename="gz-sim-label-system" name="gz::sim::systems::Label"><label>{}</label></plugin>'


def _sensor(row: Row, size: tuple[int, int]) -> str:
    return f"""<sensor name="{row.topic}" type="{row.sensor}"><topic>{row.topic}</topic>
      <update_rate>{RATE_HZ}</update_rate><camera><horizontal_fov>1.2</horizontal_fov>
      <image><width>{size[0]}</width><height>{size[1]}</height></image><clip><near>0.1</near><far>50</far></clip>
      {row.camera}</camera></sensor>"""


def _crate(i: int) -> str:
    """Crates in two rows across the view, labels 1..4, one in three lying behind another."""
    x, y = 4.0 + 2.0 * (i % 3), -3.0 + 0.55 * i
    return f"""<model name="crate_{i}"><static>true</static><pose>{x} {y} 0.5 0 0 {0.3 * i}</pose>
      <link name="link"><visual name="v"><geometry><box><size>0.5 0.5 1</size></box></geometry></visual></link>
      {LABEL.format(1 + i % 4)}</model>"""


def world(rows: tuple[Row, ...], size: tuple[int, int]) -> str:
    sensors = "".join(_sensor(row, size) for row in rows)
    return f"""<?xml version="1.0"?>
<sdf version="1.10"><world name="dataset_bench">
  <physics name="1ms" type="ignore"><max_step_size>0.001</max_step_size></physics>
  <light type="directional" name="sun"><direction>-0.5 0.1 -0.9</direction></light>
  <model name="ground_plane"><static>true</static><link name="link">
    <visual name="v"><geometry><plane><normal>0 0 1</normal><size>50 50</size></plane></geometry></visual>
  </link></model>
  <model name="eye"><static>true</static><pose>0 0 1 0 0 0</pose><link name="link">{sensors}</link></model>
  {"".join(_crate(i) for i in range(CRATES))}
</world></sdf>
"""


@contextmanager
def server(rows: tuple[Row, ...], size: tuple[int, int], renderer: str) -> Iterator[tuple[Server, Node]]:
    """The benchmark world's server in this process (lockstep, no robot) and a client node on it."""
    endpoint, namespace = f"tcp/127.0.0.1:{free_port()}", f"bench_{uuid.uuid4().hex[:8]}"
    with tempfile.TemporaryDirectory(prefix="bench-dataset-") as folder:
        path = Path(folder) / "dataset_bench.sdf"
        path.write_text(world(rows, size))
        config = ServerConfig(path, None, mode=Mode.LOCKSTEP, overrides={"rendering.renderer": renderer})
        with Node(BusOptions(listen=(endpoint,), namespace=namespace), "server") as node:
            built = Server(config, node)
            try:
                with Node(BusOptions(connect=(endpoint,), namespace=namespace), "client") as client:
                    yield built, client
            finally:
                built.close()


def step_frames(built: Server, frames: int) -> None:
    for _ in range(frames * STEPS_PER_FRAME):
        built.sim.step()


def frame_ms(built: Server, client: Node, row: Row, frames: int) -> list[float]:
    """Milliseconds of each of `frames` frames of `row`'s camera, its keys subscribed: the worker's
    time on it (`Frame.render_s`) and the server's in the camera's `publish`."""
    camera = next(s for s in built.sim.systems if isinstance(s, Camera) and s.spec.name == row.topic)
    costs: list[float] = []
    publish = camera.publish

    def timed(frame: Frame) -> None:
        start = time.perf_counter()
        publish(frame)
        costs.append((frame.render_s + time.perf_counter() - start) * 1e3)

    setattr(camera, "publish", timed)  # noqa: B010 - an instance's method, timed for this row only
    counters = count_topics(client, [row.topic + key for key in row.keys])
    deadline = time.monotonic() + FIRST_FRAME_TIMEOUT_S
    while len(costs) < 2:  # the subscription is seen, the pool runs, frames come out
        if time.monotonic() > deadline:
            raise SystemExit(f"{row.name}: no frames within {FIRST_FRAME_TIMEOUT_S} s of subscribing")
        step_frames(built, 1)
    del costs[:]
    step_frames(built, frames)
    for counter in counters.values():
        counter.subscriber.undeclare()  # type: ignore[attr-defined]
    del camera.publish
    return costs


def measure(rows: tuple[Row, ...], size: tuple[int, int], frames: int, rounds: int, renderer: str) -> dict[str, float]:
    """Median milliseconds per frame of each row, over every frame of every round."""
    costs: dict[str, list[float]] = {row.name: [] for row in rows}
    with server(rows, size, renderer) as (built, client):
        for _ in range(rounds):
            for row in rows:
                costs[row.name] += frame_ms(built, client, row, frames)
    return {name: statistics.median(values) for name, values in costs.items()}


def table(costs: dict[str, float]) -> list[str]:
    baseline = costs[ROWS[0].name]
    lines = [f"{'camera':<24} {'ms/frame':>9} {'× colour':>9}"]
    lines += [f"{name:<24} {ms:9.1f} {ms / baseline:9.2f}" for name, ms in costs.items()]
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", default="640x480", help="every camera's image size, WxH")
    parser.add_argument("--frames", type=int, default=30, help="frames per row per round")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--renderer", default="auto", choices=("auto", "gl", "tiny"))
    args = parser.parse_args()
    width, height = (int(v) for v in args.size.lower().split("x"))
    costs = measure(ROWS, (width, height), args.frames, args.rounds, args.renderer)
    print(f"dataset cameras at {width}×{height}, {args.frames} frames × {args.rounds} rounds, renderer {args.renderer}")
    publish("dataset_cameras", table(costs))


if __name__ == "__main__":
    main()
