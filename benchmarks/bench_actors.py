"""Benchmark of actors: what walking people cost the server per step, and what animating them
(skeleton, skinned mesh, a capsule per leg) costs over today's rigid proxy, in one run.

1. Server step. Three servers built in this process exactly as `simbot-server` builds them
   (`Server`, lockstep, a real Zenoh session): the warehouse with the Flexley Tug standing (its
   lidars, IMU, odometry, tf, poses and clock running; cameras idle); the same with `--actors`
   workers (simbot's own skin) created through world control, each walking a 4 m loop at 1 m/s
   as a rigid figure (no `<animation>`: the bind pose and one capsule); the same workers
   animated (the walk cycle with `<interpolate_x>`: the legs posed from the skeleton every
   LEGS_PERIOD_NS of sim time, 10 ms, as `Actors` poses them); and animated with the legs posed
   every 1 ms step (LEGS_PERIOD_NS patched while that server is built: what posing them at the
   physics rate would cost). Each server steps `--steps` steps at a time, the four interleaved
   `--repeats` times; the figure is the median milliseconds per step of each.
2. Camera frames. The warehouse with its people (`--add warehouse_people`), animated and, from a
   copy without their `<animation>`s, rigid: the robot's six cameras drawn at 640×480 by the
   OpenGL renderer (one llvmpipe thread) on a copy of each server's scene. Each frame set, the
   server steps `--frame-steps` steps (not timed), the scene takes the bodies' new states and the
   six cameras are drawn (timed: an animated person's skin is posed once per scene pose, on the
   CPU, `simbot/sim/render/skinning.py`). The two alternate, set by set, for `--seconds` each.

A shared machine is noisy: the median of interleaved runs holds where single runs do not.

    python benchmarks/bench_actors.py [--actors N] [--steps S] [--repeats R] [--seconds T]
"""

from __future__ import annotations

import argparse
import re
import statistics
import tempfile
import time
import uuid
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Any

import numpy as np
from bench_server import free_port
from in_process import gl_on, robot_views
from tables import publish

from simbot.bus import BusOptions, Node
from simbot.description.additions import addition_path
from simbot.description.resources import asset
from simbot.sim.kit.scene_bodies import scene_body
from simbot.sim.loop.simulation import Mode
from simbot.sim.loop.world_control import create_request
from simbot.sim.render.kinds import Raw
from simbot.sim.render.specs import BodyState
from simbot.sim.server import Server, ServerConfig, world_path
from simbot.sim.systems import actors as actors_system
from simbot.sim.systems.camera_rendering import world_light

REPO = Path(__file__).resolve().parents[1]
MESHES = REPO / "worlds" / "models" / "worker" / "meshes"
ANIMATION = f"""<animation name="walk"><filename>{MESHES / "walk.dae"}</filename>
    <interpolate_x>true</interpolate_x></animation>"""
ACTOR = """<?xml version="1.0"?>
<sdf version="1.9">
  <actor name="walker_{index}">
    <pose>{x} {y} 1 0 0 0</pose>
    <skin><filename>{skin}</filename></skin>
    {animation}
    <script><trajectory id="0" type="walk">
      <waypoint><time>0</time><pose>0 0 0 0 0 0</pose></waypoint>
      <waypoint><time>2</time><pose>2 0 0 0 0 0</pose></waypoint>
      <waypoint><time>2.5</time><pose>2 0 0 0 0 3.14159</pose></waypoint>
      <waypoint><time>4.5</time><pose>0 0 0 0 0 3.14159</pose></waypoint>
      <waypoint><time>5</time><pose>0 0 0 0 0 0</pose></waypoint>
    </trajectory></script>
  </actor>
</sdf>
"""
FRAME_SIZE = (640, 480)
EVERY_STEP_NS = 1_000_000


@contextmanager
def legs_posed_every(period_ns: int) -> Iterator[None]:
    """Servers built inside pose animated legs every `period_ns` (`Actors` reads it as it is built)."""
    default = actors_system.LEGS_PERIOD_NS
    actors_system.LEGS_PERIOD_NS = period_ns
    try:
        yield
    finally:
        actors_system.LEGS_PERIOD_NS = default


@contextmanager
def server(
    actors: int = 0, animated: bool = False, additions: tuple[Path, ...] = (), plugin: str = ""
) -> Iterator[Server]:
    """The warehouse and the tug in lockstep, with `actors` workers created in a row 1 m apart, each
    with `plugin` (SDF: a `<plugin>` that drives it) when one is given."""
    options = BusOptions(listen=(f"tcp/127.0.0.1:{free_port()}",), namespace=f"bench_{uuid.uuid4().hex[:8]}")
    config = ServerConfig(
        world_path("warehouse"),
        asset("urdf/flexley_tug.sdf"),
        (-2.5, 0.0, 0.1, 0.0),
        Mode.LOCKSTEP,
        overrides={"camera.size": FRAME_SIZE},
        additions=additions,
    )
    with Node(options, "server") as node:
        built = Server(config, node)
        try:
            for index in range(actors):
                text = ACTOR.format(
                    index=index,
                    x=-6.0 + index,
                    y=2.5 + (index % 2),
                    skin=MESHES / "worker.dae",
                    animation=ANIMATION if animated else "",
                )
                built.world.create(create_request({"sdf": text.replace("</actor>", plugin + "</actor>")}))
            yield built
        finally:
            built.close()


def ms_per_step(built: Server, steps: int) -> float:
    start = time.perf_counter()
    for _ in range(steps):
        built.sim.step()
    return (time.perf_counter() - start) / steps * 1e3


def step_costs(actors: int, steps: int, repeats: int) -> tuple[float, ...]:
    """Median ms per step: the bare warehouse, with `actors` rigid workers, with them animated,
    and animated with their legs posed every step."""
    with ExitStack() as stack:
        built = [stack.enter_context(server()), stack.enter_context(server(actors))]
        built.append(stack.enter_context(server(actors, animated=True)))
        with legs_posed_every(EVERY_STEP_NS):
            built.append(stack.enter_context(server(actors, animated=True)))
        runs: tuple[list[float], ...] = tuple([] for _ in built)
        for one in built:  # past the first steps' one-off costs
            ms_per_step(one, 200)
        for _ in range(repeats):
            for one, figures in zip(built, runs, strict=True):
                figures.append(ms_per_step(one, steps))
    return tuple(statistics.median(figures) for figures in runs)


def rigid_people(folder: Path) -> Path:
    """The warehouse's people without their `<animation>`s: each drawn in its bind pose, one capsule."""
    text = addition_path("warehouse_people").read_text()
    path = folder / "warehouse_people_rigid.sdf"
    path.write_text(re.sub(r"<animation\b.*?</animation>", "", text, flags=re.DOTALL))
    return path


@contextmanager
def frame_sets(built: Server, frame_steps: int) -> Iterator[Callable[[], float]]:
    """A function drawing one frame set of `built`'s six cameras (in_process's OpenGL renderer on a
    copy of its scene) after `frame_steps` untimed steps; it returns the seconds the set took:
    the scene taking the moving bodies' new states (skins posed) and the six frames read back."""
    physics = built.physics
    moving = [name for name in physics.body_names() if not scene_body(physics, name).static]
    light = world_light(built.world.description)
    with gl_on(physics, robot_views(physics, FRAME_SIZE), light) as (renderer, poses):
        pixels: dict[Raw, Any] = {"color": np.zeros(renderer.targets[0].spec.drawn()["color"], dtype=np.uint8)}

        def one_set() -> float:
            for _ in range(frame_steps):
                built.sim.step()
            states = {name: BodyState(*physics.body_state(name)) for name in moving}
            start = time.perf_counter()
            renderer.scene.apply(states)
            for index, pose in enumerate(poses):
                renderer.render(index, pose, pixels)
            return time.perf_counter() - start

        one_set()  # the first set builds the buffers
        yield one_set


def paired_frame_costs(baseline: Server, other: Server, frame_steps: int, seconds: float) -> tuple[float, float]:
    """Median ms per six-camera frame set of each server, their sets alternating (so that both see
    the same load) until `other`'s sets add up to `seconds`."""
    with frame_sets(baseline, frame_steps) as baseline_set, frame_sets(other, frame_steps) as other_set:
        runs: tuple[list[float], list[float]] = ([], [])
        while sum(runs[1]) < seconds:
            runs[0].append(baseline_set())
            runs[1].append(other_set())
    first, second = (statistics.median(figures) * 1e3 for figures in runs)
    return first, second


def frame_costs(seconds: float, frame_steps: int) -> tuple[float, float]:
    """Median ms per six-camera frame set: the warehouse's people rigid, then animated."""
    with tempfile.TemporaryDirectory(prefix="bench-actors-") as folder:
        rigid_file = rigid_people(Path(folder))
        with (
            server(additions=(rigid_file,)) as rigid,
            server(additions=(addition_path("warehouse_people"),)) as animated,
        ):
            return paired_frame_costs(rigid, animated, frame_steps, seconds)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--actors", type=int, default=10)
    parser.add_argument("--steps", type=int, default=1000, help="steps per measurement")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--seconds", type=float, default=20.0, help="timed frame sets of each kind")
    parser.add_argument("--frame-steps", type=int, default=33, help="server steps between frame sets")
    args = parser.parse_args()
    base, rigid, animated, stepwise = step_costs(args.actors, args.steps, args.repeats)
    still, moving = frame_costs(args.seconds, args.frame_steps)
    n = args.actors
    table = [
        "| measurement | figure |",
        "| --- | --- |",
        f"| server step, warehouse and tug (lidars, IMU, odometry, tf, poses, clock) | {base:.3f} ms |",
        f"| the same with {n} walking workers, rigid (bind pose, one capsule) | {rigid:.3f} ms |",
        f"| the same with {n} walking workers, animated (skeleton, a capsule per leg; legs posed every 10 ms) "
        f"| {animated:.3f} ms |",
        f"| the same, legs posed every 1 ms step | {stepwise:.3f} ms |",
        f"| rigid ÷ none | {rigid / base:.2f} |",
        f"| animated ÷ rigid | {animated / rigid:.2f} |",
        f"| cost of one rigid worker per step | {(rigid - base) / n * 1e3:.0f} µs |",
        f"| cost of animating one worker per step | {(animated - rigid) / n * 1e3:.0f} µs |",
        f"| the same, legs posed every step | {(stepwise - rigid) / n * 1e3:.0f} µs |",
        f"| six cameras {FRAME_SIZE[0]}×{FRAME_SIZE[1]}, warehouse people rigid (GL, one llvmpipe thread) "
        f"| {still:.1f} ms a set ({1e3 / still:.2f} sets/s) |",
        f"| the same, its people animated (skins posed per set) | {moving:.1f} ms a set ({1e3 / moving:.2f} sets/s) |",
        f"| camera sets, animated ÷ rigid (time) | {moving / still:.3f} |",
    ]
    publish("actors", table)


if __name__ == "__main__":
    main()
