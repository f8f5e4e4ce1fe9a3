"""The running world: its models in the physics, their systems in the loop, create and remove.

`SimWorld` loads a world and its robots, builds every system (the world's plugins, the built-in
world systems, each model's plugins and sensors, a described model's robot systems) from one kind
of `SystemContext`, and puts them in the simulation loop. It is the one owner of the models: when
a model enters (at start, or through world control's `create`) or leaves (`remove`, a reset), it
tells the world systems that follow models (`ModelObserver`) with a `ModelEvent` that carries the
model's bodies and systems. No system is named here: the built-in ones come from their entry-point
groups (`simbot.sim.registry`), and each finds what it serves among a model's systems by Protocol.
"""

from __future__ import annotations

import itertools
import logging
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path

from simbot.description import DescriptionError, load_description
from simbot.description.model import Link, Model, Plugin, Sensor, Visual, World
from simbot.description.poses import Pose
from simbot.sim.bus_view import SimBus
from simbot.sim.control import CreateRequest
from simbot.sim.naming import scoped_key, scoped_rng
from simbot.sim.physics import Physics
from simbot.sim.physics.kinematic_stepper import KINEMATIC, kinematic
from simbot.sim.plugin_params import plugin_priority
from simbot.sim.registry import ROBOT_GROUP, WORLD_GROUP, builtin, lookup, sensor_lookup
from simbot.sim.simulation import Mode, Scheduled, Simulation
from simbot.sim.system import (
    ModelEvent,
    ModelObserver,
    RunOptions,
    System,
    SystemConfigError,
    SystemContext,
    SystemFactory,
    priority,
)

log = logging.getLogger(__name__)


def load_robot(path: Path) -> Model:
    """The robot from SDF, URDF or xacro."""
    description = load_description(path)
    if not isinstance(description, Model):
        raise DescriptionError(path, "expected a robot model, found a world", "sdf")
    return description


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


@dataclass(frozen=True)
class Placement:
    """A robot to put in the world: as `name`, at `pose`, its keys and frames under `namespace`."""

    name: str
    pose: Pose
    namespace: str = ""


@dataclass
class Placed:
    """A model in the running world: its bodies (one per joint tree), the bus view of its systems
    (its namespace), and the systems that go with it when it is removed."""

    name: str
    bodies: list[str]
    bus: SimBus
    describe: bool
    """Whether it gets the robot systems (its description and tf): the robot, a namespaced model."""
    systems: list[Scheduled] = field(default_factory=list)
    sensors: dict[str, System] = field(default_factory=dict)
    created: bool = False
    """Created through world control: a reset removes it."""

    def event(self) -> ModelEvent:
        return ModelEvent(self.name, tuple(self.bodies), tuple(s.system for s in self.systems), self.created)


class SimWorld:
    """The models of a running world and their systems; see the module docstring."""

    def __init__(
        self,
        world: World,
        robot: Model | None,
        placements: list[Placement],
        sim_bus: SimBus,
        seed: int = 0,
        options: RunOptions | None = None,
        mode: Mode = Mode.REALTIME,
    ) -> None:
        self.description = kinematic(world) if world.physics.type == KINEMATIC else world
        self.physics = Physics(self.description)
        self.sim = Simulation(self.physics, mode)
        self.bus = sim_bus
        self._seed = seed
        self._options = options or RunOptions()
        self._skipped_plugins: set[Plugin] = set()
        self.models: dict[str, Placed] = {}
        self._world_systems: list[Scheduled] = []
        try:
            self._load(robot, placements)
        except BaseException:
            self.close()
            raise

    def _load(self, robot: Model | None, placements: list[Placement]) -> None:
        """The world's models and the robots into the physics, then every system into the loop;
        the world systems hear of every model."""
        for model in self.description.models:
            self._place(model, model.name)
        if robot is not None:
            for place in placements:
                self._place(robot, place.name, place.pose, place.namespace, describe=True)
        self.physics.save_initial_state()
        self._world_systems = self._scheduled(self._plugins(None) + self._builtin(WORLD_GROUP, self._context()))
        for placed in self.models.values():
            self._build(placed)
        self.sim.add_systems([*self._world_systems, *(s for p in self.models.values() for s in p.systems)])
        for placed in self.models.values():
            self._tell_added(placed)

    @property
    def observers(self) -> list[ModelObserver]:
        return [entry.system for entry in self._world_systems if isinstance(entry.system, ModelObserver)]

    @property
    def systems(self) -> list[System]:
        """The world's systems, then each model's."""
        every = [*self._world_systems, *(s for p in self.models.values() for s in p.systems)]
        return [entry.system for entry in every]

    @property
    def sensors(self) -> dict[str, System]:
        """Every sensor system of the world, by scoped name `model/link/sensor`."""
        return {name: sensor for placed in self.models.values() for name, sensor in placed.sensors.items()}

    # models in and out

    def _place(
        self, model: Model, name: str, pose: Pose | None = None, namespace: str = "", describe: bool = False
    ) -> Placed:
        """Adds `model` to the physics as `name`, its keys and frames under `namespace`; no systems yet (`_build`)."""
        before = set(self.physics.body_names())
        try:
            self.physics.add_model(model, name, pose)
        except BaseException:
            if name in self.physics.body_names():  # a model of several joint trees failed after the first
                self.physics.remove_model(name)
            raise
        bodies = [body for body in self.physics.body_names() if body not in before]
        self.models[name] = Placed(name, bodies, self.bus.scoped(namespace), describe or bool(namespace))
        return self.models[name]

    def _build(self, placed: Placed) -> None:
        """The systems of a placed model: its plugins, its sensors, its robot systems; if one fails, those built close."""
        systems: list[tuple[System, int | None]] = []
        try:
            systems += self._plugins(placed)
            placed.sensors = self._sensors(placed)
            systems += [(sensor, None) for sensor in placed.sensors.values()]
            if placed.describe:  # its main tree of joints: what a URDF can hold (see Physics.add_model)
                model = self.physics.model_of(placed.name)
                systems += self._builtin(ROBOT_GROUP, self._context(model, placed.name, bus=placed.bus))
        except BaseException:
            Simulation.close_all([system for system, _ in systems])
            placed.bus.close()
            raise
        placed.systems = self._scheduled(systems)

    def _tell_added(self, placed: Placed) -> None:
        event = placed.event()
        for observer in self.observers:
            observer.model_added(event)

    def create(self, request: CreateRequest) -> str:
        """World control's create (Gazebo's EntityFactory), between steps: loads the requested model
        with its systems; returns its name in the world. A bad request raises ValueError naming the
        field, with the world as it was."""
        model = _load_requested(request)
        name = self._free_name(request.name or model.name, request.allow_renaming)
        try:
            placed = self._place(model, name, request.pose, request.namespace)
        except (DescriptionError, ValueError) as exc:
            raise ValueError(f"sdf: model {name!r} cannot be loaded: {exc}") from None
        try:
            self._build(placed)
        except (SystemConfigError, DescriptionError, ValueError) as exc:
            self.physics.remove_model(name)
            del self.models[name]
            raise ValueError(f"sdf: model {name!r}: {exc}") from None
        placed.created = True
        self.sim.add_systems(placed.systems)
        self._tell_added(placed)
        log.info("created %s%s", name, f" in namespace {request.namespace}" if request.namespace else "")
        return name

    def _free_name(self, name: str, allow_renaming: bool) -> str:
        """`name`, or with allow_renaming the first free `name_1`, `name_2`, ... (as Gazebo renames)."""
        if name not in self.models and name not in self.physics.body_names():
            return name
        if not allow_renaming:
            raise ValueError(f"name: a model named {name!r} is already in the world (set allow_renaming)")
        return next(f"{name}_{i}" for i in itertools.count(1) if f"{name}_{i}" not in self.models)

    def remove(self, name: str) -> None:
        """Takes a model, its systems and its keys out of the world; ValueError naming the field if unknown."""
        placed = self.models.get(name)
        if placed is None:
            raise ValueError(f"name: no model named {name!r} in the world (models: {', '.join(self.models)})")
        systems = [entry.system for entry in placed.systems]
        self.sim.remove_systems(systems)
        Simulation.close_all(systems)
        event = placed.event()
        for observer in self.observers:
            observer.model_removed(event)
        placed.bus.close()
        self.physics.remove_model(name)
        del self.models[name]
        log.info("removed %s", name)

    def reset(self) -> None:
        """Gazebo's reset: the world as it started, so models created since leave it."""
        for placed in [p for p in self.models.values() if p.created]:
            self.remove(placed.name)
        self.sim.reset()

    def close(self) -> None:
        Simulation.close_all(self.systems)
        self.physics.close()

    # building systems

    def _context(
        self,
        model: Model | None = None,
        name: str | None = None,
        plugin: Plugin | None = None,
        sensor: tuple[Link, Sensor] | None = None,
        bus: SimBus | None = None,
        visual: tuple[Link, Visual] | None = None,
    ) -> SystemContext:
        link, sdf_sensor = sensor if sensor else (None, None)
        if visual is not None:
            link = visual[0]
        leaf = (link.name, sdf_sensor.name) if link and sdf_sensor else (plugin.name,) if plugin else ()
        if visual is not None:
            leaf = (visual[0].name, visual[1].name, *leaf)
        rng = scoped_rng(self._seed, name or "world", *leaf)
        return SystemContext(
            self.physics,
            bus or self.bus,
            self.description,
            rng,
            model,
            name,
            plugin,
            link,
            sdf_sensor,
            self._options,
            visual[1] if visual else None,
        )

    def _scheduled(self, systems: list[tuple[System, int | None]]) -> list[Scheduled]:
        """Each system with its priority: the SDF's where it states one, else its class's."""
        return [Scheduled(system, priority(system) if stated is None else stated) for system, stated in systems]

    def _builtin(self, group: str, ctx: SystemContext) -> list[tuple[System, int | None]]:
        """The systems every world (or every described model) gets, by their entry-point names."""
        return _started([partial(_make, factory, ctx, None) for factory in builtin(group)])

    def _plugins(self, placed: Placed | None) -> list[tuple[System, int | None]]:
        """A system for each plugin of the world (`placed` None) or of each body of a placed model
        and of its visuals, with the priority its SDF states."""
        makers = []
        for ctx in self._plugin_contexts(placed):
            assert ctx.plugin is not None
            factory = lookup(ctx.plugin)
            if factory is None:
                continue
            if ctx.visual is not None and not getattr(factory, "runs_on_visuals", False):
                self._skip_visual_plugin(ctx.plugin, ctx.visual)
                continue
            makers.append(partial(_make, factory, ctx, plugin_priority(ctx.plugin)))
        return _started(makers)

    def _plugin_contexts(self, placed: Placed | None) -> list[SystemContext]:
        if placed is None:
            return [self._context(plugin=p) for p in self.description.plugins]
        contexts = []
        for name in placed.bodies:
            model = self.physics.model_of(name)
            contexts += [self._context(model, name, p, bus=placed.bus) for p in model.plugins]
            contexts += [
                self._context(model, name, p, bus=placed.bus, visual=(link, visual))
                for link in model.links
                for visual in link.visuals
                for p in visual.plugins
            ]
        return contexts

    def _skip_visual_plugin(self, plugin: Plugin, visual: Visual) -> None:
        """Once per plugin (a nested model's goes to each of its visuals)."""
        if plugin not in self._skipped_plugins:
            self._skipped_plugins.add(plugin)
            log.warning(
                "plugin %s on visual %r (or its nested model) is not run: only a visual's systems "
                "(Label, Thermal) run there, as simbot flattens nested models",
                plugin.name,
                visual.name,
            )

    def _sensors(self, placed: Placed) -> dict[str, System]:
        """A system for each `<sensor>` of each body of a placed model, by scoped name `model/link/sensor`
        (two models may hold sensors of one name); if one fails, those already started stop."""
        sensors: dict[str, System] = {}
        try:
            for body_name in placed.bodies:
                model = self.physics.model_of(body_name)
                for link, sensor in model.sensors():
                    factory = sensor_lookup(sensor)
                    if factory is not None:
                        scoped = "/".join(map(scoped_key, (body_name, link.name, sensor.name)))
                        context = self._context(model, body_name, sensor=(link, sensor), bus=placed.bus)
                        try:
                            sensors[scoped] = factory(context)
                        except SystemConfigError as exc:
                            _drop(exc)
        except BaseException:
            Simulation.close_all(list(sensors.values()))
            raise
        return sensors


Maker = Callable[[], tuple[System, int | None]]
"""Builds one system, with the priority its SDF states (None: its class's)."""


def _make(factory: SystemFactory, ctx: SystemContext, stated: int | None) -> tuple[System, int | None]:
    return factory(ctx), stated


def _drop(error: SystemConfigError) -> None:
    """A system whose SDF parameters are bad is left out, with one line naming it and the element:
    the rest of the world runs (as Gazebo runs a world with a sensor that failed to load)."""
    log.error("%s; the world runs without it", " ".join(str(error).split()))


def _started(makers: Sequence[Maker]) -> list[tuple[System, int | None]]:
    """Builds each system in turn, leaving out one with bad parameters (`_drop`); if one fails
    otherwise, those already built close."""
    built: list[tuple[System, int | None]] = []
    try:
        for make in makers:
            try:
                built.append(make())
            except SystemConfigError as exc:
                _drop(exc)
    except BaseException:
        Simulation.close_all([system for system, _ in built])
        raise
    return built
