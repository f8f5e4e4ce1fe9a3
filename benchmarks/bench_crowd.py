"""Benchmark of the crowd: what ten people walking by the social-force model (SocialForce) cost the
server per step against ten walking their scripts, in one run.

Servers built in this process exactly as `simbot-server` builds them (`Server`, lockstep, a
real Zenoh session): the warehouse with the Flexley Tug standing (its lidars, IMU, odometry, tf,
poses and clock running; cameras idle) and `--actors` workers created through world control, each
on bench_actors' 4 m beat, a row of them 1 m apart: in one server they walk their scripts rigid (the
Actors system, as people walked before issue 41), in the others each is animated (the worker's walk
cycle, legs for the lidar) and has a SocialForce `<plugin>` with its forces from the others,
the tug and the warehouse's racks updated at one of RATES (its default every 20 ms, every 10 ms,
every 1 ms step), the position at every step. Each server steps `--steps` steps at a time, the
four interleaved `--repeats` times; the figure is the median milliseconds per step of each, their
ratio to the scripted, and the crowd's own cost per person per step (the difference over the
number of people). Then the six cameras' frame sets (bench_actors' `frame_sets`: the robot's
cameras drawn in-process by the OpenGL renderer, `--frame-steps` steps between sets) with the
scripted rigid workers and with the animated crowd-driven ones, interleaved, medians and their ratio.
Last, what one think of the social force costs a person when a world's crowd of CROWDS people thinks
in one pass (the forces, the detours round robots, the hard constraint and what each sees: the
system's `_think`, timed alone), against one person thinking alone in the same run; and the same
for WORLDS worlds of three people thinking in one pass, each seeing only its own world (a vector
env's sub-envs, stepped together), against one such world alone.

    python benchmarks/bench_crowd.py [--actors N] [--steps S] [--repeats R]
"""

from __future__ import annotations

import argparse
import statistics
import timeit
from contextlib import ExitStack

from bench_actors import FRAME_SIZE, ms_per_step, paired_frame_costs, server
from tables import publish

from simbot.description.crowd_params import Crowd
from simbot.sim.kit.crowd_view import Poses
from simbot.sim.systems import crowd as crowd_system

PLUGIN = '<plugin name="simbot::systems::SocialForce" filename="simbot-social-force-system">{}</plugin>'
RATES = (Crowd().update_rate, 100.0, 1000.0)
"""Hz: the plugin's forces updated at its default, every 10 ms and at every 1 ms step."""
CROWDS = (1, 3, 10, 30)
"""People thinking in one pass (the warehouse with its people has three)."""
PEOPLE_A_WORLD = 3
WORLDS = (1, 4, 8)
"""Worlds of PEOPLE_A_WORLD people each thinking in one pass, as a vector env's sub-envs do."""


def step_costs(actors: int, steps: int, repeats: int) -> list[float]:
    """Median ms per step: `actors` scripted rigid workers (as before animation), then the same
    animated and crowd-driven with the forces at each of RATES."""
    plugins = [PLUGIN.format(f"<update_rate>{rate:g}</update_rate>") for rate in RATES]
    runs: list[list[float]] = [[] for _ in range(len(plugins) + 1)]
    with ExitStack() as stack:
        built = [stack.enter_context(server(actors))]
        built += [stack.enter_context(server(actors, animated=True, plugin=plugin)) for plugin in plugins]
        for one in built:  # past the first steps' one-off costs
            ms_per_step(one, 200)
        for _ in range(repeats):
            for one, figures in zip(built, runs, strict=True):
                figures.append(ms_per_step(one, steps))
    return [statistics.median(figures) for figures in runs]


def frame_costs(actors: int, seconds: float, frame_steps: int) -> tuple[float, float]:
    """Median ms per six-camera frame set: `actors` scripted rigid workers, then animated and crowd-driven."""
    with server(actors) as scripted, server(actors, animated=True, plugin=PLUGIN.format("")) as crowd:
        return paired_frame_costs(scripted, crowd, frame_steps, seconds)


def think_cost(people: int, repeats: int, worlds: int = 1) -> float:
    """Median µs a person for one think of `worlds` worlds' crowds of `people` each in one pass
    (100 thinks a timing), as a vector env's sub-envs think."""
    with ExitStack() as stack:
        built = [stack.enter_context(server(people, animated=True, plugin=PLUGIN.format(""))) for _ in range(worlds)]
        for one in built:
            ms_per_step(one, 200)
        crowds = [[s for s in one.sim.systems if isinstance(s, crowd_system.SocialForce)] for one in built]
        period = round(1e9 / Crowd().update_rate)
        clock = [max(one.sim.clock.now_ns for one in built)]

        def think() -> None:
            clock[0] += period
            crowd_system._think(
                [
                    crowd_system.WorldStep(crowd, clock[0], Poses(one.sim.physics), False)
                    for one, crowd in zip(built, crowds, strict=True)
                ]
            )

        timings = timeit.repeat(think, number=100, repeat=repeats)
    return statistics.median(timings) / 100 / (people * worlds) * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--actors", type=int, default=10)
    parser.add_argument("--steps", type=int, default=500)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--seconds", type=float, default=10.0, help="timed frame sets of each kind")
    parser.add_argument("--frame-steps", type=int, default=33, help="server steps between frame sets")
    args = parser.parse_args()
    scripted, *crowd = step_costs(args.actors, args.steps, args.repeats)
    rigid, walking = frame_costs(args.actors, args.seconds, args.frame_steps)
    thinks = [think_cost(people, args.repeats) for people in CROWDS]
    together = [think_cost(PEOPLE_A_WORLD, args.repeats, worlds) for worlds in WORLDS]
    table = [
        f"| warehouse, tug standing, {args.actors} workers | ms per server step | ratio | ms per person per step over scripted |",
        "| --- | --- | --- | --- |",
        f"| walking their scripts, rigid (Actors; as before animation) | {scripted:.3f} | 1.00 | — |",
        *(
            f"| animated and crowd-driven (SocialForce), forces every {1000 / rate:g} ms{' (default)' * (i == 0)} "
            f"| {ms:.3f} | "
            f"{ms / scripted:.2f} | {(ms - scripted) / args.actors:.3f} |"
            for i, (rate, ms) in enumerate(zip(RATES, crowd, strict=True))
        ),
        f"| six cameras {FRAME_SIZE[0]}×{FRAME_SIZE[1]} (GL, one llvmpipe thread), scripted rigid workers "
        f"| {rigid:.1f} ms a set | 1.00 | — |",
        f"| the same, animated crowd-driven workers | {walking:.1f} ms a set | {walking / rigid:.2f} | — |",
        "",
        "| a crowd thinking in one pass (the warehouse, the tug standing) | µs a person a think | "
        "against one person alone |",
        "| --- | --- | --- |",
        *(
            f"| {people} {'person' if people == 1 else 'people'} | {cost:.0f} | {cost / thinks[0]:.2f} |"
            for people, cost in zip(CROWDS, thinks, strict=True)
        ),
        "",
        f"| worlds of {PEOPLE_A_WORLD} people thinking in one pass (a vector env's sub-envs) | µs a person a think | "
        "against one world alone |",
        "| --- | --- | --- |",
        *(
            f"| {worlds} {'world' if worlds == 1 else 'worlds'} | {cost:.0f} | {cost / together[0]:.2f} |"
            for worlds, cost in zip(WORLDS, together, strict=True)
        ),
    ]
    publish("crowd", table)


if __name__ == "__main__":
    main()
