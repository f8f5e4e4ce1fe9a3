"""`simbot-server`: loads a world and the robot, runs its systems, serves it all on the bus.

    simbot-server [--world NAME|PATH] [--robot PATH|none] [--spawn X Y Z YAW] [--namespace NS]
                  [--mode realtime|fast|lockstep] [--seed N] [--renderer auto|gl|tiny]
                  [--camera-size WxH] [--camera-rate HZ] [--render-workers N] [--listen E] [--connect E] [--zenoh-config F]

`--robot none` runs the world alone, with the models it holds or includes.

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
from dataclasses import dataclass, field, replace
from pathlib import Path

from simbot.bus import BusConfigError, BusOpenError, BusOptions, Node, add_bus_arguments
from simbot.description import DescriptionError, load_description, load_world
from simbot.description.model import Link, Model, Plugin, Sensor, World
from simbot.description.poses import Pose
from simbot.description.resources import asset
from simbot.rotations import yaw_of
from simbot.sim.control import WorldControl
from simbot.sim.physics import Physics
from simbot.sim.registry import lookup, sensor_lookup
from simbot.sim.render import RENDERERS
from simbot.sim.simulation import Mode, Simulation
from simbot.sim.system import (
    Reporting,
    SensorSettings,
    SimBus,
    SystemConfigError,
    SystemContext,
    plugin_priority,
    scoped_key,
    scoped_rng,
)
from simbot.sim.systems.clock_publisher import ClockPublisher
from simbot.sim.systems.pose_publisher import PosePublisher
from simbot.sim.systems.rendering import Rendering, world_light
from simbot.sim.systems.robot_state_publisher import RobotStatePublisher

log = logging.getLogger("simbot.server")

EXIT_USAGE = 2
ROBOT_NAME = "flexley_tug"
"""The robot's name in the running world, whatever its SDF calls it (SPEC §1)."""
DEFAULT_SPAWN = (-2.5, 0.0, 0.1, 0.0)
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
    sensors: SensorSettings = field(default_factory=SensorSettings)
    """The command line's sensor options; whether cameras run in lockstep follows `mode`."""

    def sensor_settings(self) -> SensorSettings:
        return replace(self.sensors, lockstep=self.mode is Mode.LOCKSTEP)


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
        robot = load_robot(config.robot) if config.robot is not None else None
        self.physics = Physics(self.world)
        for model in self.world.models:
            self.physics.add_model(model)
        if robot is not None:
            x, y, z, yaw = config.spawn
            self.physics.add_model(robot, ROBOT_NAME, Pose((x, y, z), (0.0, 0.0, yaw)))
        self.physics.save_initial_state()
        self.bus = SimBus(node)
        self._seed = config.seed
        self._settings = config.sensor_settings()
        self.rendering = Rendering(self.physics, self._settings, world_light(self.world))
        plugins = self._plugins()
        self.sensors = self._sensors()
        systems = [*plugins, *self.sensors.values(), *self._own_systems(with_robot=robot is not None)]
        self.sim = Simulation(self.physics, systems, config.mode)
        reporting = {name: s for name, s in self.sensors.items() if isinstance(s, Reporting)}
        self.control = WorldControl(node, self.world.name, self.sim, self.bus, reporting)

    def _context(
        self,
        model: Model | None = None,
        name: str | None = None,
        plugin: Plugin | None = None,
        sensor: tuple[Link, Sensor] | None = None,
    ) -> SystemContext:
        link, sdf_sensor = sensor if sensor else (None, None)
        leaf = (link.name, sdf_sensor.name) if link and sdf_sensor else (plugin.name,) if plugin else ()
        rng = scoped_rng(self._seed, name or "world", *leaf)
        return SystemContext(
            self.physics,
            self.bus,
            self.world,
            rng,
            model,
            name,
            plugin,
            link,
            sdf_sensor,
            self._settings,
            self.rendering,
        )

    def _plugins(self) -> list[object]:
        """A system for each world plugin, then for each model's plugins."""
        systems: list[object] = []
        placed: list[tuple[Model | None, str | None, Plugin]] = [(None, None, p) for p in self.world.plugins]
        for body_name, body in self.physics.bodies.items():
            placed += [(body.model, body_name, p) for p in body.model.plugins]
        for model, name, plugin in placed:
            factory = lookup(plugin)
            if factory is not None:
                systems.append(factory(self._context(model, name, plugin)))
                if (stated := plugin_priority(plugin)) is not None:
                    setattr(systems[-1], "priority", stated)  # noqa: B010 (any class may be a system; the SDF overrides its priority)
        return systems

    def _own_systems(self, with_robot: bool) -> list[object]:
        """The rendering (where there are cameras), clock and poses; the robot's description and
        static frames only where there is a robot."""
        systems: list[object] = [self.rendering] if self.rendering.cameras else []
        world_ctx = self._context()
        systems += [ClockPublisher(world_ctx), PosePublisher(world_ctx)]
        if with_robot:  # its main tree of joints: what a URDF can hold (see Physics.add_model)
            systems.append(RobotStatePublisher(self._context(self.physics.body(ROBOT_NAME).model, ROBOT_NAME)))
        return systems

    def _sensors(self) -> dict[str, object]:
        """A system for each `<sensor>` of each model, by scoped name `model/link/sensor` (two models may
        hold sensors of one name); if one fails, those already started stop."""
        sensors: dict[str, object] = {}
        try:
            for body_name, body in self.physics.bodies.items():
                for link, sensor in body.model.sensors():
                    factory = sensor_lookup(sensor)
                    if factory is not None:
                        scoped = "/".join(map(scoped_key, (body_name, link.name, sensor.name)))
                        sensors[scoped] = factory(self._context(body.model, body_name, sensor=(link, sensor)))
        except BaseException:
            Simulation.close_all(list(sensors.values()))
            raise
        return sensors

    def run(self, stop: threading.Event, status: bool = False) -> None:
        """Until `stop`; with `status`, one line a second on stdout."""
        self.sim.run(stop, self.control.poll, self.print_status if status else None)

    def print_status(self) -> None:
        mode = "paused" if self.sim.paused else self.sim.mode.value
        line = f"sim {self.sim.clock.now_ns / 1e9:9.3f} s | rtf {self.sim.rtf.value():5.2f} | {mode}"
        if ROBOT_NAME in self.physics.bodies:
            (x, y, _), quat = self.physics.model_pose(ROBOT_NAME)
            line += f" | {ROBOT_NAME} x {x:+7.3f} y {y:+7.3f} yaw {math.degrees(yaw_of(quat)):+7.1f}°"
        print(line, flush=True)

    def close(self) -> None:
        self.sim.close()
        self.physics.close()


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="simbot-server", description="simbot's simulator: a world, the Flexley Tug, and the bus"
    )
    parser.add_argument(
        "--world", default="warehouse", help="world file, or a built-in world: warehouse (default), empty"
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
        "--mode",
        choices=[m.value for m in Mode],
        default=Mode.REALTIME.value,
        help="realtime (default), fast, or lockstep",
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of every random process (sensor noise)")
    parser.add_argument(
        "--renderer",
        choices=RENDERERS,
        default="auto",
        help="camera renderer: gl (OpenGL on EGL: the GPU, else Mesa on the CPU), tiny (PyBullet's TinyRenderer), auto (default: gl where an EGL context opens, else tiny)",
    )
    parser.add_argument(
        "--camera-size", type=_size, metavar="WxH", help="every camera's image size instead of the SDF's, e.g. 320x240"
    )
    parser.add_argument("--camera-rate", type=_rate, metavar="HZ", help="every camera's rate instead of the SDF's")
    parser.add_argument(
        "--render-workers", type=_count, metavar="N", help="camera render processes (default: every core but one)"
    )
    parser.add_argument("--quiet", action="store_true", help="no status line")
    parser.add_argument("-v", "--verbose", action="store_true", help="log debug messages")
    add_bus_arguments(parser)
    return parser


MAX_CAMERA_SIDE = 8192


def _size(text: str) -> tuple[int, int]:
    """`WxH` in pixels, each 1..8192."""
    parts = text.lower().split("x")
    if len(parts) != 2 or not all(p.strip().isdigit() for p in parts):
        raise argparse.ArgumentTypeError(f"expected WxH such as 320x240, got {text!r}")
    width, height = (int(p) for p in parts)
    if not (1 <= width <= MAX_CAMERA_SIDE and 1 <= height <= MAX_CAMERA_SIDE):
        raise argparse.ArgumentTypeError(f"width and height must be 1..{MAX_CAMERA_SIDE}, got {text!r}")
    return width, height


def _rate(text: str) -> float:
    """A positive finite rate in Hz."""
    try:
        rate = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a rate in Hz, got {text!r}") from None
    if not (math.isfinite(rate) and rate > 0):
        raise argparse.ArgumentTypeError(f"the rate must be a positive number of Hz, got {text!r}")
    return rate


def _count(text: str) -> int:
    """A whole number from 1 to 64."""
    if not text.strip().isdigit() or not 1 <= int(text) <= 64:
        raise argparse.ArgumentTypeError(f"expected a whole number from 1 to 64, got {text!r}")
    return int(text)


def _config(args: argparse.Namespace) -> ServerConfig:
    robot = (
        asset("urdf/flexley_tug.sdf") if args.robot is None else None if args.robot == NO_ROBOT else Path(args.robot)
    )
    sensors = SensorSettings(
        renderer=args.renderer,
        camera_size=args.camera_size,
        camera_rate=args.camera_rate,
        render_workers=args.render_workers,
    )
    return ServerConfig(world_path(args.world), robot, tuple(args.spawn), Mode(args.mode), args.seed, sensors)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of `simbot-server`."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if not all(math.isfinite(v) for v in args.spawn):
        parser.error(f"--spawn expects finite numbers, got {' '.join(map(str, args.spawn))}")
    logging.basicConfig(
        level=logging.DEBUG if args.verbose else logging.INFO, format="%(levelname)s %(name)s: %(message)s"
    )
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    try:
        config = _config(args)
        with Node(BusOptions.from_args(args), "server") as node:
            server = Server(config, node)
            log.info(
                "world %s, robot %s, %s mode, namespace %r",
                server.world.name,
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


if __name__ == "__main__":
    sys.exit(main())
