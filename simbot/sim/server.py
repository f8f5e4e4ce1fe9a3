"""`simbot-server`: loads a world and the robot, runs its systems, serves it all on the bus.

    simbot-server [--world NAME|PATH] [--add NAME|PATH ...] [--robot PATH|none] [--robots N] [--columns C] [--spawn X Y Z YAW]
                  [--zone NAME:XMIN:XMAX] [--namespace NS]
                  [--mode realtime|fast|lockstep] [--physics dynamic|kinematic] [--seed N] [--randomise SEED[:PROFILE]] [--renderer auto|gl|tiny]
                  [--camera-size WxH] [--camera-rate HZ] [--render-workers N] [--render-threads N] [--listen E] [--connect E] [--zenoh-config F]

`--robot none` runs the world alone, with the models it holds or includes. `--add` (repeatable)
puts the models and actors of another SDF file into the world as if its file held them: SDF has
no way for one world to include another, so the warehouse's people (`--add warehouse_people`,
worlds/additions/) live in a file of their own and the plain warehouse stays still for the tests.

`--zone NAME:XMIN:XMAX` runs one zone of a fleet split by x (docs/fleets.md): of the `--robots N`
fleet only the robots standing in XMIN ≤ x < XMAX, the world's own keys (world control, clock)
under NAME/, each robot's keys as in one server (`tug_7/cmd_vel`), whichever zone holds it.

`--randomise SEED[:PROFILE]` loads the world that SEED draws from a variation profile (the world's
own `<world>.variation.toml` beside it when PROFILE is left out; simbot.variation): the sun, the
textures, clutter on free floor, the trolley's pose, the people's pace and routes, the cameras' noise.
With a profile, world control's `reset` takes a seed and loads that seed's world.

A user's mistake (a world that is not there, a broken SDF, bad plugin parameters, a bad Zenoh
config) is one line on stderr and exit code 2. SIGINT and SIGTERM end it cleanly.
"""

from __future__ import annotations

import argparse
import gc
import logging
import math
import signal
import sys
import threading
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from simbot import memory
from simbot.arguments import image_size, number, whole
from simbot.bus import BusConfigError, BusOpenError, BusOptions, Node, add_bus_arguments
from simbot.description import DescriptionError, World, load_world
from simbot.description.additions import addition_path, with_additions, world_path
from simbot.description.fleet import DEFAULT_SPAWN, MAX_FLEET, TUG_BYTES, WORLD_BYTES, Zone, fleet, in_zone, zone
from simbot.description.model import Model
from simbot.description.poses import Pose
from simbot.description.resources import asset
from simbot.sim.loop.bus_view import SimBus
from simbot.sim.loop.simulation import Mode
from simbot.sim.loop.system import RunOptions, System, SystemConfigError
from simbot.sim.loop.world import Placement, SimWorld, load_robot
from simbot.sim.loop.world_control import WorldControl
from simbot.sim.physics.kinematic_world import KINEMATIC, kinematic
from simbot.sim.render import RENDERERS
from simbot.sim.zone_keys import ZoneBus
from simbot.transform import yaw_of
from simbot.variation import Variations, profile_beside, read_profile, seed_option

log = logging.getLogger("simbot.server")

EXIT_USAGE = 2
ROBOT_NAME = "flexley_tug"
"""The robot's name in the running world, whatever its SDF calls it (SPEC §1)."""
NO_ROBOT = "none"
"""`--robot none`: the world alone."""


@dataclass(frozen=True)
class ServerConfig:
    world: Path
    robot: Path | None
    """The robot's SDF, URDF or xacro; None: the world alone (`--robot none`)."""
    spawn: tuple[float, float, float, float] = DEFAULT_SPAWN
    mode: Mode = Mode.REALTIME
    seed: int = 0
    overrides: Mapping[str, Any] = field(default_factory=dict)
    """The command line's parameters over the SDF's, by `<system>.<parameter>` (`RunOptions.overrides`)."""
    robots: int = 0
    """`--robots N`: N tugs `tug_1..tug_N` in namespaces of their names; 0: the one `flexley_tug`."""
    additions: tuple[Path, ...] = ()
    """`--add`: SDF files whose models and actors join the world's own (`with_additions`)."""
    randomise: tuple[int, Path] | None = None
    """`--randomise SEED[:PROFILE]`: the variant to start with and the profile it is drawn from."""
    kinematic: bool = False
    """`--physics kinematic`: robots move by their drives' commands (simbot.sim.physics.kinematic_world),
    as a world's `<physics type="kinematic">` asks."""
    columns: int = 1
    zone: Zone | None = None
    """`--zone`: the band of x whose robots this server holds, and the prefix of the world's own keys."""

    def run_options(self) -> RunOptions:
        """What every system is told: lockstep follows the mode."""
        return RunOptions(self.mode is Mode.LOCKSTEP, self.overrides)


def robot_places(
    spawn: tuple[float, float, float, float], robots: int, columns: int = 1, band: Zone | None = None
) -> list[Placement]:
    """Where the robots go: the one `flexley_tug` at `spawn`; with `--robots N`, `tug_1..tug_N` in a
    grid from `spawn` (simbot.description.fleet), each under its own namespace, those in `band` alone."""
    x, y, z, yaw = spawn
    if robots == 0:
        return [Placement(ROBOT_NAME, Pose((x, y, z), (0.0, 0.0, yaw)))]
    return [Placement(spot.name, spot.pose, spot.name) for spot in in_zone(fleet(spawn, robots, columns), band)]


def _variations(config: ServerConfig, world: World, robot: Model | None) -> Variations | None:
    """The variants a seeded reset may load: from `--randomise`'s profile, else the world's own when it has one."""
    if config.randomise is not None:
        return Variations(world, robot, read_profile(config.randomise[1]))
    own = profile_beside(config.world)
    return Variations(world, robot, read_profile(own)) if own.is_file() else None


def build_world(config: ServerConfig, bus: SimBus) -> SimWorld:
    """The running world `config` describes, its systems on `bus`: the server's on its node, a
    learning environment's on a node within its process (simbot.gym.local)."""
    robot = load_robot(config.robot) if config.robot is not None else None
    world = with_additions(load_world(config.world), config.additions)
    world = kinematic(world) if config.kinematic else world
    variations = _variations(config, world, robot)
    variant = variations.draw(config.randomise[0]) if variations and config.randomise else None
    sim_world = SimWorld(
        variant.world if variant else world,
        variant.robot if variant else robot,
        robot_places(config.spawn, config.robots, config.columns, config.zone),
        bus,
        config.seed,
        config.run_options(),
        config.mode,
        variations,
    )
    sim_world.variant = variant
    return sim_world


class Server:
    """A running world (`SimWorld`), its loop and world control, all on one bus node."""

    def __init__(self, config: ServerConfig, node: Node) -> None:
        zone = config.zone.name if config.zone else ""
        self.world = build_world(config, ZoneBus(node, zone=zone) if zone else SimBus(node))
        self.physics, self.bus, self.sim = self.world.physics, self.world.bus, self.world.sim
        self.control = WorldControl(node, self.world.description.name, self.sim, self.world.bus, self.world)

    @property
    def sensors(self) -> dict[str, System]:
        return self.world.sensors

    def run(self, stop: threading.Event, status: bool = False) -> None:
        """Until `stop`; with `status`, one line a second on stdout."""
        self.sim.run(stop, self.control.poll, self.print_status if status else None)

    def print_status(self) -> None:
        mode = "paused" if self.sim.paused else self.sim.mode.value
        line = f"sim {self.sim.clock.now_ns / 1e9:9.3f} s | rtf {self.sim.rtf.value():5.2f} | {mode}"
        if ROBOT_NAME in self.physics.body_names():
            (x, y, _), quat = self.physics.model_pose(ROBOT_NAME)
            line += f" | {ROBOT_NAME} x {x:+7.3f} y {y:+7.3f} yaw {math.degrees(yaw_of(quat)):+7.1f}°"
        print(line, flush=True)

    def close(self) -> None:
        self.world.close()


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="simbot-server", description="simbot's simulator: a world, the Flexley Tug, and the bus"
    )
    parser.add_argument(
        "--world", default="warehouse", help="world file, or a built-in world: warehouse (default), empty"
    )
    parser.add_argument(
        "--add",
        action="append",
        default=[],
        metavar="NAME|PATH",
        help="an SDF file whose models and actors join the world (repeatable), or a built-in one: warehouse_people",
    )
    parser.add_argument(
        "--robot",
        help="robot SDF, URDF or xacro (default: simbot's Flexley Tug); none: the world alone, with the models it holds",
    )
    parser.add_argument(
        "--spawn",
        nargs=4,
        type=float,
        metavar=("X", "Y", "Z", "YAW"),
        default=DEFAULT_SPAWN,
        help="robot pose in the world",
    )
    parser.add_argument(
        "--robots",
        type=whole(1, MAX_FLEET),
        metavar="N",
        help="N robots tug_1..tug_N in a row from --spawn along y (--columns: a grid), each in the namespace of its name (tug_2/cmd_vel, tug_2/base_link)",
    )
    parser.add_argument(
        "--columns",
        type=whole(1),
        default=1,
        metavar="C",
        help="--robots N in C columns along x, 5 m apart, filled row by row (default 1)",
    )
    parser.add_argument(
        "--zone", type=zone, metavar="NAME:XMIN:XMAX", help="one zone of a fleet split by x (docs/fleets.md)"
    )
    parser.add_argument(
        "--mode",
        choices=[m.value for m in Mode],
        default=Mode.REALTIME.value,
        help="realtime (default), fast, or lockstep",
    )
    parser.add_argument(
        "--physics",
        choices=["dynamic", KINEMATIC],
        help="dynamic (default, or as the world's <physics type> says): forces, friction, contacts; "
        "kinematic: robots move by their drives' commands and stop at contact (fleets of a hundred)",
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of every random process (sensor noise)")
    parser.add_argument(
        "--randomise",
        type=seed_option,
        metavar="SEED[:PROFILE]",
        help="start in the world SEED draws from a variation profile (default: the world's own <world>.variation.toml)",
    )
    parser.add_argument(
        "--renderer",
        choices=RENDERERS,
        default="auto",
        help="camera renderer: gl (OpenGL on EGL: the GPU, else Mesa on the CPU), tiny (PyBullet's TinyRenderer), auto (default: gl where an EGL context opens, else tiny)",
    )
    parser.add_argument(
        "--camera-size",
        type=image_size,
        metavar="WxH",
        help="every camera's image size instead of the SDF's, e.g. 320x240",
    )
    parser.add_argument(
        "--camera-rate", type=number(float, unit="Hz"), metavar="HZ", help="every camera's rate instead of the SDF's"
    )
    parser.add_argument(
        "--render-workers",
        type=whole(1, 64),
        metavar="N",
        help="camera render processes (default: one per core, as docs/speed.md measured)",
    )
    parser.add_argument(
        "--render-threads",
        type=whole(1, 64),
        metavar="N",
        help="llvmpipe rasteriser threads of each render process (default: as docs/speed.md's measurement chose)",
    )
    parser.add_argument("--quiet", action="store_true", help="no status line")
    parser.add_argument("-v", "--verbose", action="store_true", help="log debug messages")
    add_bus_arguments(parser)
    return parser


def parse_config(argv: Sequence[str]) -> ServerConfig:
    """The configuration of a server started with `argv` (what a learning environment runs in its
    own process, from the command line it would give a server)."""
    return _config(build_parser().parse_args(argv))


def _config(args: argparse.Namespace) -> ServerConfig:
    robot = (
        asset("urdf/flexley_tug.sdf") if args.robot is None else None if args.robot == NO_ROBOT else Path(args.robot)
    )
    overrides = {
        key: value
        for key, value in (
            ("rendering.renderer", args.renderer),
            ("rendering.workers", args.render_workers),
            ("rendering.threads", args.render_threads),
            ("camera.size", args.camera_size),
            ("camera.rate", args.camera_rate),
        )
        if value is not None
    }
    if args.robots and robot is None:
        raise DescriptionError(Path(NO_ROBOT), "--robots N needs a robot; --robot none holds none")
    spawn = tuple(args.spawn)
    additions = tuple(addition_path(name) for name in args.add)
    world = world_path(args.world)
    randomise = None
    if args.randomise is not None:
        seed, profile = args.randomise
        randomise = (seed, profile or profile_beside(world))
    return ServerConfig(
        world,
        robot,
        spawn,
        Mode(args.mode),
        args.seed,
        overrides,
        args.robots or 0,
        additions,
        randomise,
        args.physics == KINEMATIC,
        args.columns,
        args.zone,
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of `simbot-server`."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not all(math.isfinite(v) for v in args.spawn):
        parser.error(f"--spawn expects finite numbers, got {' '.join(map(str, args.spawn))}")
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.INFO, format="%(levelname)s %(name)s: %(message)s"
    )
    try:
        config = _config(args)
    except DescriptionError as exc:
        print(f"simbot-server: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    held = len(robot_places(config.spawn, config.robots, config.columns, config.zone)) if config.robots else 0
    if (problem := memory.shortfall("--robots", held, TUG_BYTES, WORLD_BYTES, "a tug")) is not None:
        print(f"simbot-server: error: {problem}", file=sys.stderr)
        return EXIT_USAGE
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    try:
        with Node(BusOptions.from_args(args), "server") as node:
            server = Server(config, node)
            _freeze_built_world()
            log.info(
                "world %s, robot %s, %s mode, namespace %r",
                server.world.description.name,
                config.robot.name if config.robot is not None else NO_ROBOT,
                config.mode.value,
                node.namespace,
            )
            try:
                server.run(stop, status=not args.quiet)
            finally:
                server.close()
    except (DescriptionError, SystemConfigError, BusConfigError, BusOpenError) as exc:
        print(f"simbot-server: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    return 0


def _freeze_built_world() -> None:
    """Out of the cyclic collector's sight, the world as built (never garbage while the server runs).
    Its oldest generation's collections walk every live object: a thousand tugs' world is 0.8
    million of them, 0.43 s a walk (AMD EPYC, 2026-12-03), a stall of the loop each time. What is
    made later (a created model) is collected as before. The server's process alone does it: one
    that builds and closes worlds (a test, a learning run's envs) would keep their cycles for ever."""
    gc.freeze()


if __name__ == "__main__":
    sys.exit(main())
