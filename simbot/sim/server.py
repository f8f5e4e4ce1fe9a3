"""`simbot-server`: loads a world and the robot, runs its systems, serves it all on the bus.

    simbot-server [--world NAME|PATH] [--robot PATH|none] [--robots N] [--spawn X Y Z YAW] [--namespace NS]
                  [--mode realtime|fast|lockstep] [--seed N] [--renderer auto|gl|tiny]
                  [--camera-size WxH] [--camera-rate HZ] [--render-workers N] [--listen E] [--connect E] [--zenoh-config F]

`--robot none` runs the world alone, with the models it holds or includes.

A user's mistake (a world that is not there, a broken SDF, bad plugin parameters, a bad Zenoh
config) is one line on stderr and exit code 2. SIGINT and SIGTERM end it cleanly.
"""

from __future__ import annotations

import argparse
import itertools
import logging
import math
import signal
import sys
import tempfile
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

from simbot.bus import BusConfigError, BusOpenError, BusOptions, Node, add_bus_arguments
from simbot.description import DescriptionError, load_description, load_world
from simbot.description.model import Link, Model, Plugin, Sensor, World
from simbot.description.poses import Pose
from simbot.description.resources import asset
from simbot.rotations import yaw_of
from simbot.sim.control import CreateRequest, WorldControl
from simbot.sim.physics import Physics
from simbot.sim.registry import lookup, sensor_lookup
from simbot.sim.render import RENDERERS
from simbot.sim.simulation import Mode, Simulation
from simbot.sim.system import (
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
ROW_SPACING = 1.5
"""Metres between the tugs of `--robots N` (a tug is 0.5 m wide; its side cameras and lidars see the next)."""
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
    robots: int = 0
    """`--robots N`: N tugs `tug_1..tug_N` in namespaces of their names; 0: the one `flexley_tug`."""

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


def robot_places(spawn: tuple[float, float, float, float], robots: int) -> list[tuple[str, str, Pose]]:
    """(name, namespace, pose) of each robot: the one `flexley_tug` at `spawn`; with `--robots N`,
    `tug_1..tug_N` in a row along y from `spawn`, ROW_SPACING apart, each under its own namespace."""
    x, y, z, yaw = spawn
    if robots == 0:
        return [(ROBOT_NAME, "", Pose((x, y, z), (0.0, 0.0, yaw)))]
    return [
        (f"tug_{i}", f"tug_{i}", Pose((x, y + (i - 1) * ROW_SPACING, z), (0.0, 0.0, yaw))) for i in range(1, robots + 1)
    ]


def _load_requested(request: CreateRequest) -> Model:
    """The model a create request names: a file, or SDF text (read from a temporary file, so that
    its `model://` URIs resolve as a file's do)."""
    field_name = "sdf" if request.sdf is not None else "sdf_filename"
    try:
        if request.sdf is None:
            assert request.sdf_filename is not None
            return load_robot(Path(request.sdf_filename))
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "model.sdf"
            path.write_text(request.sdf)
            return load_robot(path)
    except DescriptionError as exc:
        raise ValueError(f"{field_name}: {' '.join(str(exc).split())}") from None


def load_robot(path: Path) -> Model:
    """The robot from SDF, URDF or xacro."""
    description = load_description(path)
    if not isinstance(description, Model):
        raise DescriptionError(path, "expected a robot model, found a world", "sdf")
    return description


@dataclass
class Placed:
    """A model in the running world: its bodies (one per joint tree), the bus view of its systems
    (its namespace), and the systems that go with it when it is removed."""

    name: str
    bodies: list[str]
    bus: SimBus
    describe: bool
    """Whether it publishes its description and tf (`RobotStatePublisher`): the robot, a namespaced model."""
    systems: list[object] = field(default_factory=list)
    sensors: dict[str, object] = field(default_factory=dict)
    created: bool = False
    """Created through world control: a reset removes it."""


class Server:
    """A running world: physics, systems, world control, all on one bus node."""

    def __init__(self, config: ServerConfig, node: Node) -> None:
        self.world: World = load_world(config.world)
        robot = load_robot(config.robot) if config.robot is not None else None
        self.physics = Physics(self.world)
        self.bus = SimBus(node)
        self._seed = config.seed
        self._settings = config.sensor_settings()
        self.rendering = Rendering(self.physics, self._settings, world_light(self.world))
        self.models: dict[str, Placed] = {}
        for model in self.world.models:
            self.place(model, model.name)
        if robot is not None:
            for name, namespace, pose in robot_places(config.spawn, config.robots):
                self.place(robot, name, pose, namespace, describe=True)
        self.physics.save_initial_state()
        world_systems = [*self._plugins(None), self.rendering, *self._world_systems()]
        for placed in self.models.values():
            self.build(placed)
        self.sim = Simulation(
            self.physics, [*world_systems, *(s for p in self.models.values() for s in p.systems)], config.mode
        )
        self.control = WorldControl(node, self.world.name, self.sim, self.bus, self)

    def place(
        self, model: Model, name: str, pose: Pose | None = None, namespace: str = "", describe: bool = False
    ) -> Placed:
        """Adds `model` to the physics as `name`, its keys and frames under `namespace`; no systems yet (`build`)."""
        before = set(self.physics.bodies)
        try:
            self.physics.add_model(model, name, pose)
        except BaseException:
            if name in self.physics.bodies:  # a model of several joint trees failed after the first
                self.physics.remove_model(name)
            raise
        bodies = [body for body in self.physics.bodies if body not in before]
        self.rendering.add_model(bodies)
        self.models[name] = Placed(name, bodies, self.bus.scoped(namespace), describe or bool(namespace))
        return self.models[name]

    def build(self, placed: Placed) -> None:
        """The systems of a placed model: its plugins, its sensors, its description; if one fails, those built close."""
        try:
            placed.systems = self._plugins(placed)
            placed.sensors = self._sensors(placed)
            placed.systems += placed.sensors.values()
            if placed.describe:  # its main tree of joints: what a URDF can hold (see Physics.add_model)
                body = self.physics.body(placed.name)
                placed.systems.append(RobotStatePublisher(self._context(body.model, placed.name, bus=placed.bus)))
        except BaseException:
            self.unbuild(placed)
            raise

    def unbuild(self, placed: Placed) -> None:
        """Its systems close (workers end, a trolley goes free), its cameras stop, its keys leave the graph."""
        Simulation.close_all(placed.systems)
        self.rendering.remove_model(placed.name, placed.bodies)
        placed.bus.close()

    @property
    def sensors(self) -> dict[str, object]:
        """Every sensor system of the world, by scoped name `model/link/sensor`."""
        return {name: sensor for placed in self.models.values() for name, sensor in placed.sensors.items()}

    def _context(
        self,
        model: Model | None = None,
        name: str | None = None,
        plugin: Plugin | None = None,
        sensor: tuple[Link, Sensor] | None = None,
        bus: SimBus | None = None,
    ) -> SystemContext:
        link, sdf_sensor = sensor if sensor else (None, None)
        leaf = (link.name, sdf_sensor.name) if link and sdf_sensor else (plugin.name,) if plugin else ()
        rng = scoped_rng(self._seed, name or "world", *leaf)
        return SystemContext(
            self.physics,
            bus or self.bus,
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

    def _plugins(self, placed: Placed | None) -> list[object]:
        """A system for each plugin of the world (`placed` None) or of each body of a placed model."""
        if placed is None:
            found: list[tuple[Model | None, str | None, Plugin]] = [(None, None, p) for p in self.world.plugins]
        else:
            bodies = [(self.physics.body(name).model, name) for name in placed.bodies]
            found = [(model, name, p) for model, name in bodies for p in model.plugins]
        systems: list[object] = []
        try:
            for model, name, plugin in found:
                factory = lookup(plugin)
                if factory is not None:
                    systems.append(factory(self._context(model, name, plugin, bus=placed.bus if placed else None)))
                    if (stated := plugin_priority(plugin)) is not None:
                        setattr(systems[-1], "priority", stated)  # noqa: B010 (any class may be a system; the SDF overrides its priority)
        except BaseException:
            Simulation.close_all(systems)
            raise
        return systems

    def _world_systems(self) -> list[object]:
        """The clock and the ground truth of every model."""
        world_ctx = self._context()
        self.poses = PosePublisher(world_ctx)
        return [ClockPublisher(world_ctx), self.poses]

    def _sensors(self, placed: Placed) -> dict[str, object]:
        """A system for each `<sensor>` of each body of a placed model, by scoped name `model/link/sensor`
        (two models may hold sensors of one name); if one fails, those already started stop."""
        sensors: dict[str, object] = {}
        try:
            for body_name in placed.bodies:
                body = self.physics.body(body_name)
                for link, sensor in body.model.sensors():
                    factory = sensor_lookup(sensor)
                    if factory is not None:
                        scoped = "/".join(map(scoped_key, (body_name, link.name, sensor.name)))
                        context = self._context(body.model, body_name, sensor=(link, sensor), bus=placed.bus)
                        sensors[scoped] = factory(context)
        except BaseException:
            Simulation.close_all(list(sensors.values()))
            raise
        return sensors

    # world control's create and remove (Gazebo's EntityFactory), between steps

    def create(self, request: CreateRequest) -> str:
        """Loads the requested model with its systems; returns its name in the world. A bad request
        raises ValueError naming the field, with the world as it was."""
        model = _load_requested(request)
        name = self._free_name(request.name or model.name, request.allow_renaming)
        try:
            placed = self.place(model, name, request.pose, request.namespace)
        except (DescriptionError, ValueError) as exc:
            raise ValueError(f"sdf: model {name!r} cannot be loaded: {exc}") from None
        try:
            self.build(placed)
        except (SystemConfigError, DescriptionError, ValueError) as exc:
            self.physics.remove_model(name)
            del self.models[name]
            raise ValueError(f"sdf: model {name!r}: {exc}") from None
        placed.created = True
        self.sim.add_systems(placed.systems)
        self.poses.track(placed.bodies)
        log.info("created %s%s", name, f" in namespace {request.namespace}" if request.namespace else "")
        return name

    def _free_name(self, name: str, allow_renaming: bool) -> str:
        """`name`, or with allow_renaming the first free `name_1`, `name_2`, ... (as Gazebo renames)."""
        if name not in self.models and name not in self.physics.bodies:
            return name
        if not allow_renaming:
            raise ValueError(f"name: a model named {name!r} is already in the world (set allow_renaming)")
        return next(f"{name}_{i}" for i in itertools.count(1) if f"{name}_{i}" not in self.models)

    def remove(self, name: str) -> None:
        """Takes a model, its systems and its keys out of the world; ValueError naming the field if unknown."""
        placed = self.models.get(name)
        if placed is None:
            raise ValueError(f"name: no model named {name!r} in the world (models: {', '.join(self.models)})")
        self.sim.remove_systems(placed.systems)
        self.unbuild(placed)
        self.poses.untrack(placed.bodies)
        self.physics.remove_model(name)
        del self.models[name]
        log.info("removed %s", name)

    def reset(self) -> None:
        """Gazebo's reset: the world as it started, so models created since leave it."""
        for placed in [p for p in self.models.values() if p.created]:
            self.remove(placed.name)
        self.sim.reset()

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
        "--robots",
        type=_whole(MAX_ROBOTS),
        metavar="N",
        help="N robots tug_1..tug_N in a row from --spawn along y, each in the namespace of its name (tug_2/cmd_vel, tug_2/base_link)",
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
        "--render-workers", type=_whole(64), metavar="N", help="camera render processes (default: every core but one)"
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


MAX_ROBOTS = 100


def _whole(most: int) -> Callable[[str], int]:
    """An argparse type: a whole number from 1 to `most`."""

    def parse(text: str) -> int:
        if not text.strip().isdigit() or not 1 <= int(text) <= most:
            raise argparse.ArgumentTypeError(f"expected a whole number from 1 to {most}, got {text!r}")
        return int(text)

    return parse


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
    if args.robots and robot is None:
        raise DescriptionError(Path(NO_ROBOT), "--robots N needs a robot; --robot none holds none")
    spawn = tuple(args.spawn)
    return ServerConfig(world_path(args.world), robot, spawn, Mode(args.mode), args.seed, sensors, args.robots or 0)


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
