"""`simbot-server`: loads a world and the robot, runs its systems, serves it all on the bus.

    simbot-server [--world NAME|PATH] [--robot PATH] [--spawn X Y Z YAW] [--namespace NS]
                  [--mode realtime|fast|lockstep] [--seed N] [--listen E] [--connect E] [--zenoh-config F]

A user's mistake (a world that is not there, a broken SDF, bad plugin parameters, a bad Zenoh
config) is one line on stderr and exit code 2. SIGINT and SIGTERM end it cleanly.
"""

from __future__ import annotations

import argparse
import logging
import math
import signal
import sys
import threading
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from simbot.bus import BusConfigError, BusOpenError, BusOptions, Node, add_bus_arguments
from simbot.description import DescriptionError, load_description, load_world
from simbot.description.model import Model, Plugin, World
from simbot.description.poses import Pose, yaw_of
from simbot.description.resources import asset
from simbot.sim.control import WorldControl
from simbot.sim.physics import Physics
from simbot.sim.registry import lookup
from simbot.sim.simulation import Mode, Simulation
from simbot.sim.system import SimBus, SystemConfigError, SystemContext
from simbot.sim.systems.clock_publisher import ClockPublisher
from simbot.sim.systems.pose_publisher import PosePublisher
from simbot.sim.systems.robot_state_publisher import RobotStatePublisher

log = logging.getLogger("simbot.server")

EXIT_USAGE = 2
ROBOT_NAME = "flexley_tug"
"""The robot's name in the running world, whatever its SDF calls it (SPEC §1)."""
DEFAULT_SPAWN = (-2.5, 0.0, 0.1, 0.0)


@dataclass(frozen=True)
class ServerConfig:
    world: Path
    robot: Path
    spawn: tuple[float, float, float, float] = DEFAULT_SPAWN
    mode: Mode = Mode.REALTIME
    seed: int = 0


def world_path(name_or_path: str) -> Path:
    """A world file, or the name of one of simbot's own worlds (`warehouse`, `empty`)."""
    path = Path(name_or_path)
    if path.suffix == ".sdf" or path.exists():
        return path
    own = asset(f"worlds/{name_or_path}.sdf")
    if own.is_file():
        return own
    known = sorted(p.stem for p in asset("worlds").glob("*.sdf"))
    raise DescriptionError(path, f"no such world file or built-in world (built-in: {', '.join(known)})")


def load_robot(path: Path) -> Model:
    """The robot from SDF, URDF or xacro."""
    description = load_description(path)
    if not isinstance(description, Model):
        raise DescriptionError(path, "expected a robot model, found a world", "sdf")
    return description


class Server:
    """A running world: physics, systems, world control, all on one bus node."""

    def __init__(self, config: ServerConfig, node: Node) -> None:
        self.world: World = load_world(config.world)
        robot = load_robot(config.robot)
        self.physics = Physics(self.world)
        for model in self.world.models:
            self.physics.add_model(model)
        x, y, z, yaw = config.spawn
        self.physics.add_model(robot, ROBOT_NAME, Pose((x, y, z), (0.0, 0.0, yaw)))
        self.physics.save_initial_state()
        self.bus = SimBus(node)
        self._seeds = np.random.SeedSequence(config.seed)
        systems = self._systems(robot)
        self.sim = Simulation(self.physics, systems, config.mode)
        self.control = WorldControl(node, self.world.name, self.sim, self.bus.drops)

    def _context(self, model: Model | None = None, name: str | None = None, plugin: Plugin | None = None) -> SystemContext:
        rng = np.random.default_rng(self._seeds.spawn(1)[0])
        return SystemContext(self.physics, self.bus, self.world, rng, model, name, plugin)

    def _systems(self, robot: Model) -> list[object]:
        """World plugins, then each model's plugins, then the server's own publishers."""
        systems: list[object] = []
        placed: list[tuple[Model | None, str | None, Plugin]] = [(None, None, p) for p in self.world.plugins]
        for body_name, body in self.physics.bodies.items():
            placed += [(body.model, body_name, p) for p in body.model.plugins]
        for model, name, plugin in placed:
            factory = lookup(plugin)
            if factory is not None:
                systems.append(factory(self._context(model, name, plugin)))
        robot_ctx = self._context(robot, ROBOT_NAME)
        systems += [ClockPublisher(robot_ctx), PosePublisher(robot_ctx), RobotStatePublisher(robot_ctx)]
        return systems

    def run(self, stop: threading.Event, status: bool = False) -> None:
        """Until `stop`; with `status`, one line a second on stdout."""
        self.sim.run(stop, self.control.poll, self.print_status if status else None)

    def print_status(self) -> None:
        (x, y, _), quat = self.physics.model_pose(ROBOT_NAME)
        mode = "paused" if self.sim.paused else self.sim.mode.value
        print(
            f"sim {self.sim.clock.now_ns / 1e9:9.3f} s | rtf {self.sim.rtf.value():5.2f} | {mode} | "
            f"{ROBOT_NAME} x {x:+7.3f} y {y:+7.3f} yaw {math.degrees(yaw_of(quat)):+7.1f}°",
            flush=True,
        )

    def close(self) -> None:
        self.physics.close()


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="simbot-server", description="simbot's simulator: a world, the Flexley Tug, and the bus")
    parser.add_argument("--world", default="warehouse", help="world file, or a built-in world: warehouse (default), empty")
    parser.add_argument("--robot", type=Path, help="robot SDF, URDF or xacro (default: simbot's Flexley Tug)")
    parser.add_argument("--spawn", nargs=4, type=float, metavar=("X", "Y", "Z", "YAW"), default=DEFAULT_SPAWN, help="robot pose in the world")
    parser.add_argument("--mode", choices=[m.value for m in Mode], default=Mode.REALTIME.value, help="realtime (default), fast, or lockstep")
    parser.add_argument("--seed", type=int, default=0, help="seed of every random process (sensor noise)")
    parser.add_argument("--quiet", action="store_true", help="no status line")
    parser.add_argument("-v", "--verbose", action="store_true", help="log debug messages")
    add_bus_arguments(parser)
    return parser


def _config(args: argparse.Namespace) -> ServerConfig:
    robot = args.robot if args.robot is not None else asset("urdf/flexley_tug.sdf")
    return ServerConfig(world_path(args.world), robot, tuple(args.spawn), Mode(args.mode), args.seed)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of `simbot-server`."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not all(math.isfinite(v) for v in args.spawn):
        parser.error(f"--spawn expects finite numbers, got {' '.join(map(str, args.spawn))}")
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    try:
        config = _config(args)
        with Node(BusOptions.from_args(args), "server") as node:
            server = Server(config, node)
            log.info("world %s, robot %s, %s mode, namespace %r", server.world.name, config.robot.name, config.mode.value, node.namespace)
            try:
                server.run(stop, status=not args.quiet)
            finally:
                server.close()
    except (DescriptionError, SystemConfigError, BusConfigError, BusOpenError) as exc:
        print(f"simbot-server: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    return 0


if __name__ == "__main__":
    sys.exit(main())
