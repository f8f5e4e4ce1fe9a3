"""Benchmark of what the warehouse's looks cost: textures and the sun's shadows on and off, side by
side in one run, with six 640×480 cameras and every other sensor subscribed, in real time.

Four copies of the warehouse are written to a temporary folder (the world and its models, so
that `model://` finds the copies first through SIMBOT_RESOURCE_PATH): with and without the sun's
shadows (`<scene><shadows>`; the shipped world has them off), each with and without textures
(every `<pbr>` albedo map taken out, so each surface shows its colour); without either is the
baseline. Each copy is drawn first by the OpenGL renderer alone in this process, the robot's six
views in turn (in_process.py's bare loop: CPU per frame, the figure least moved by a busy
machine), then run under `simbot-server` as live_runs.py runs it (`run_server`): each
camera's images per wall second, the real-time factor, and the render workers' CPU per image.
The costs are also given as ratios to the baseline measured in the same run.

    python benchmarks/bench_looks.py [--seconds S]
"""

from __future__ import annotations

import argparse
import logging
import os
import re
import shutil
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from in_process import bare_gl_fps, in_process_server, robot_views, systems_of
from live_runs import CAMERAS, IMU, LIDARS, RTF_TARGET, Run, camera_fps, describe, run_server, verdict
from tables import publish

from simbot.description.resources import asset
from simbot.sim.systems.camera_rendering import Rendering

log = logging.getLogger("bench_looks")

CAMERA_TARGET_HZ = 25.0
VARIANTS = {
    "textures off, shadows off": (False, False),
    "textures on, shadows off (as shipped)": (True, False),
    "textures off, shadows on": (False, True),
    "textures on, shadows on": (True, True),
}
BASELINE = "textures off, shadows off"


def write_variant(folder: Path, textures: bool, shadows: bool) -> Path:
    """A copy of worlds/ under `folder` with the albedo maps and the shadows as asked; its world file."""
    shutil.copytree(asset("worlds"), folder)
    for sdf in folder.rglob("*.sdf"):
        text = sdf.read_text()
        if not textures:
            text = re.sub(r"\s*<pbr>.*?</pbr>", "", text, flags=re.S)
        if sdf.name == "warehouse.sdf":
            text, count = re.subn(r"<shadows>\w+</shadows>", f"<shadows>{str(shadows).lower()}</shadows>", text)
            if count != 1:
                raise RuntimeError(f"{sdf}: expected one <scene><shadows>, found {count}")
        sdf.write_text(text)
    return folder / "warehouse.sdf"


@contextmanager
def resources_from(models: Path) -> Iterator[None]:
    """The server started inside finds `model://` in `models` before simbot's own."""
    before = os.environ.get("SIMBOT_RESOURCE_PATH")
    os.environ["SIMBOT_RESOURCE_PATH"] = str(models) + (os.pathsep + before if before else "")
    try:
        yield
    finally:
        if before is None:
            del os.environ["SIMBOT_RESOURCE_PATH"]
        else:
            os.environ["SIMBOT_RESOURCE_PATH"] = before


@dataclass(frozen=True)
class Looks:
    """One copy of the world measured: the bare draw, and the server in real time."""

    bare_ms: float
    """The OpenGL renderer alone in this process, the robot's six views in turn: CPU ms per frame."""
    device: str
    run: Run


def bare_gl_ms(world: Path, seconds: float) -> tuple[float, str]:
    """CPU milliseconds per 640×480 frame of the OpenGL renderer alone on `world`, and its device."""
    with in_process_server(str(world)) as (server, _client):
        light = systems_of(server, Rendering)[0].light
        views = robot_views(server.physics, (640, 480))
        _wall, cpu_fps, device = bare_gl_fps(server.physics, views, light, seconds)
    return 1e3 / cpu_fps, device


def measure(seconds: float) -> dict[str, Looks]:
    """Each variant in turn: the bare draw, then the server with every sensor subscribed, six
    cameras at 640×480."""
    everything = [*CAMERAS, *LIDARS, IMU]
    looks = {}
    with tempfile.TemporaryDirectory(prefix="bench-looks-") as tmp:
        for index, (label, (textures, shadows)) in enumerate(VARIANTS.items()):
            world = write_variant(Path(tmp) / f"variant_{index}", textures, shadows)
            with resources_from(world.parent / "models"):
                log.info("bare GL, six views, %s", label)
                bare_ms, device = bare_gl_ms(world, seconds / 2)
                log.info("server: real time, every sensor subscribed, 640x480, %s", label)
                run = run_server("realtime", everything, seconds, ["--camera-size", "640x480"], world=str(world))
            looks[label] = Looks(bare_ms, device, run)
    return looks


def worker_ms_per_image(run: Run) -> float:
    """Render-worker CPU milliseconds per image received (scene update, draw, read-back, finishing)."""
    return 1e3 * run.worker_cpu / camera_fps(run)


def _ratio(value: float, base: float, label: str) -> str:
    return "baseline" if label == BASELINE else f"{value / base:.2f}×"


def table(looks: dict[str, Looks]) -> list[str]:
    """One markdown table, ready for the README."""
    bare0, worker0 = looks[BASELINE].bare_ms, worker_ms_per_image(looks[BASELINE].run)
    lines = [
        "| world | bare GL draw, CPU per frame (÷ baseline) | images/s per camera (min–max of six) "
        "| real-time factor (worst half second) | render-worker CPU per image (÷ baseline) |",
        "| --- | --- | --- | --- | --- |",
    ]
    for label, look in looks.items():
        run, rates, worker = look.run, [look.run.per_second(c) for c in CAMERAS], worker_ms_per_image(look.run)
        lines.append(
            f"| {label} | {look.bare_ms:.1f} ms ({_ratio(look.bare_ms, bare0, label)}) "
            f"| {min(rates):.1f}–{max(rates):.1f} ({verdict(min(rates) >= CAMERA_TARGET_HZ)}) "
            f"| {run.rtf:.3f} ({min(run.intervals):.2f}; {verdict(run.rtf >= RTF_TARGET)}) "
            f"| {worker:.1f} ms ({_ratio(worker, worker0, label)}) |"
        )
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="wall seconds measured per variant")
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    looks = measure(args.seconds)
    print()
    publish("looks", table(looks))
    print(f"\ntargets: ≥ {CAMERA_TARGET_HZ:.0f} images/s each camera (aim 30), real-time factor ≥ {RTF_TARGET}")
    print(f"GL device: {looks[BASELINE].device}")
    for label, look in looks.items():
        describe(label, look.run)


if __name__ == "__main__":
    main()
