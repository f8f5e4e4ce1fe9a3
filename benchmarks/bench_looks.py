"""Benchmark of what the warehouse's looks cost: textures and the sun's shadows on and off, side by
side in one run, with six 640×480 cameras and every other sensor subscribed, in real time.

Four copies of the warehouse are written to a temporary folder (the world and its models, so
that `model://` finds the copies first through SIMBOT_RESOURCE_PATH): as shipped (textures and
shadows), without shadows (`<scene><shadows>false</shadows>`), without textures (every
`<pbr>` albedo map taken out, so each surface shows its colour), and without either, the
baseline. Each runs under `simbot-server` as bench_sensors.py runs it (`run_server`); the figures
are each camera's images per wall second, the real-time factor, and the render workers' CPU per
image, that last one also as a ratio to the baseline measured in the same run.

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
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_sensors import CAMERAS, IMU, LIDARS, RTF_TARGET, Run, camera_fps, describe, run_server, verdict

from simbot.description.resources import asset

log = logging.getLogger("bench_looks")

CAMERA_TARGET_HZ = 25.0
VARIANTS = {
    "textures off, shadows off": (False, False),
    "textures on, shadows off": (True, False),
    "textures off, shadows on": (False, True),
    "textures on, shadows on (as shipped)": (True, True),
}
BASELINE = "textures off, shadows off"


def write_variant(folder: Path, textures: bool, shadows: bool) -> Path:
    """A copy of worlds/ under `folder` with the albedo maps and the shadows as asked; its world file."""
    shutil.copytree(asset("worlds"), folder)
    for sdf in folder.rglob("*.sdf"):
        text = sdf.read_text()
        if not textures:
            text = re.sub(r"\s*<pbr>.*?</pbr>", "", text, flags=re.S)
        if not shadows and sdf.name == "warehouse.sdf":
            text, count = re.subn(r"<shadows>true</shadows>", "<shadows>false</shadows>", text)
            if count != 1:
                raise RuntimeError(f"{sdf}: expected one <scene><shadows>true</shadows>, found {count}")
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


def measure(seconds: float) -> dict[str, Run]:
    """Each variant in turn, every sensor subscribed, six cameras at 640×480."""
    everything = [*CAMERAS, *LIDARS, IMU]
    runs = {}
    with tempfile.TemporaryDirectory(prefix="bench-looks-") as tmp:
        for index, (label, (textures, shadows)) in enumerate(VARIANTS.items()):
            world = write_variant(Path(tmp) / f"variant_{index}", textures, shadows)
            log.info("server: real time, every sensor subscribed, 640x480, %s", label)
            with resources_from(world.parent / "models"):
                runs[label] = run_server(
                    "realtime", everything, seconds, ["--camera-size", "640x480"], world=str(world)
                )
    return runs


def worker_ms_per_image(run: Run) -> float:
    """Render-worker CPU milliseconds per image received (scene update, draw, read-back, finishing)."""
    return 1e3 * run.worker_cpu / camera_fps(run)


def table(runs: dict[str, Run]) -> list[str]:
    """One markdown table, ready for the README."""
    base = worker_ms_per_image(runs[BASELINE])
    lines = [
        "| world | images/s per camera (min–max of six) | real-time factor (worst half second) "
        "| render-worker CPU per image | ÷ baseline |",
        "| --- | --- | --- | --- | --- |",
    ]
    for label, run in runs.items():
        rates = [run.per_second(c) for c in CAMERAS]
        ms = worker_ms_per_image(run)
        lines.append(
            f"| {label} | {min(rates):.1f}–{max(rates):.1f} ({verdict(min(rates) >= CAMERA_TARGET_HZ)}) "
            f"| {run.rtf:.3f} ({min(run.intervals):.2f}; {verdict(run.rtf >= RTF_TARGET)}) "
            f"| {ms:.1f} ms | {'baseline' if label == BASELINE else f'{ms / base:.2f}'} |"
        )
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="wall seconds measured per variant")
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    runs = measure(args.seconds)
    print()
    print("\n".join(table(runs)))
    print(f"\ntargets: ≥ {CAMERA_TARGET_HZ:.0f} images/s each camera (aim 30), real-time factor ≥ {RTF_TARGET}")
    for label, run in runs.items():
        describe(label, run)


if __name__ == "__main__":
    main()
