"""The running world: its models in the physics, their systems in the loop, create and remove.

`SimWorld` loads a world and its robots, builds every system (the world's plugins, the built-in
world systems, each model's plugins and sensors, a described model's robot systems) from one kind
of `SystemContext`, and puts them in the simulation loop. It is the one owner of the models: when
a model enters (at start, or through world control's `create`) or leaves (`remove`, a reset), it
tells the world systems that follow models (`ModelObserver`) with a `ModelEvent` that carries the
model's bodies and systems. No system is named here: the built-in ones come from their entry-point
groups (`simbot.sim.loop.registry`), and each finds what it serves among a model's systems by Protocol.
Which systems the SDF asks for is `simbot.sim.loop.sdf_systems`'s to say (`simbot describe` asks it
too); one whose SDF parameters are bad is left out, and the world keeps why (`left_out`, which
world state reports): a model's entries for as long as the model stays, the world's own for good.
"""

from __future__ import annotations

import itertools
import logging
import math
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from simbot.description import DescriptionError, load_description
from simbot.description.actor_scripts import is_actor
from simbot.description.footprints import in_world, outline, overlap, reach
from simbot.description.model import Model, World
from simbot.description.naming import scoped_key
from simbot.description.poses import Pose
from simbot.sim.loop.bus_view import SimBus
from simbot.sim.loop.plan import Scheduled
from simbot.sim.loop.registry import ROBOT_GROUP, WORLD_GROUP
from simbot.sim.loop.sdf_systems import LeftOut, Wanted, builtins, plugins_of, sensors_of, world_plugins
from simbot.sim.loop.simulation import Mode, Simulation
from simbot.sim.loop.system import ModelEvent, ModelObserver, RunOptions, System, SystemConfigError
from simbot.sim.loop.world_control import CreateRequest
from simbot.sim.loop.world_edit import NotInPlace, Retunable, WorldEdit, WorldFollower, plan_edit, retuned
from simbot.sim.physics import Physics, pose_to_transform
from simbot.sim.physics.kinematic_world import KINEMATIC, kinematic
from simbot.variation import Variant, Variations

log = logging.getLogger(__name__)


def load_robot(path: Path) -> Model:
    """The robot from SDF, URDF or xacro."""
    description = load_description(path)
    if not isinstance(description, Model):
        raise DescriptionError(path, "expected a robot model, found a world", "sdf")
    return description


def _is_robot(model: Model) -> bool:
    """A model that moves by plugins of its own (a tug), not a person."""
    return bool(model.plugins) and not model.static and not is_actor(model)


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


@dataclass(frozen=True)
class RandomStream:
    """A system's random stream as it was made: a reset starts it again from there."""

    generator: np.random.Generator
    state: Mapping[str, Any]

    @staticmethod
    def of(generator: np.random.Generator) -> RandomStream:
        return RandomStream(generator, generator.bit_generator.state)

    def restart(self) -> None:
        self.generator.bit_generator.state = self.state


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
    left_out: list[LeftOut] = field(default_factory=list)
    """Its systems the world runs without, for bad SDF parameters: they leave with it."""
    created: bool = False
    """Created through world control: a reset removes it."""
    streams: list[RandomStream] = field(default_factory=list)
    """Its systems' random streams."""

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
        variations: Variations | None = None,
    ) -> None:
        self.description = kinematic(world) if world.physics.type == KINEMATIC else world
        self.physics = Physics(self.description)
        self.sim = Simulation(self.physics, mode)
        self.bus = sim_bus
        self._seed = seed
        self._options = options or RunOptions()
        self.models: dict[str, Placed] = {}
        self._world_systems: list[Scheduled] = []
        self._world_streams: list[RandomStream] = []
        self._left_out: list[LeftOut] = []
        self._placements = placements
        self.robot = robot
        """The robot's description as loaded (a seeded reset's variant's: its cameras' noise drawn)."""
        self.variations = variations
        self.variant: Variant | None = None
        """The variant loaded by the last seeded reset (or given at start); None: the world as its file says."""
        try:
            self._load(robot, placements)
        except BaseException:
            self.close()
            raise

    def _load(self, robot: Model | None, placements: list[Placement]) -> None:
        """The world's models and the robots into the physics, then every system into the loop;
        the world systems hear of every model. Publishers follow who listens once all are built
        (`Node.listening_later`)."""
        with self.bus.node.listening_later():
            self._load_all(robot, placements)

    def _load_all(self, robot: Model | None, placements: list[Placement]) -> None:
        for model in self.description.models:
            self._place(model, model.name)
        if robot is not None:
            for place in placements:
                self._place(robot, place.name, place.pose, place.namespace, describe=True)
        self.physics.save_initial_state()
        wanted = world_plugins(self.description) + builtins(WORLD_GROUP)
        self._world_systems = [entry for _, entry in self._started(wanted, None)]
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

    @property
    def left_out(self) -> list[LeftOut]:
        """The systems the world runs without, for bad SDF parameters: the world's, then each model's.
        A reset keeps them (they are about the SDF); a model's leave with it."""
        return [*self._left_out, *(entry for placed in self.models.values() for entry in placed.left_out)]

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
        """The systems of a placed model: the plugins of each of its bodies, their sensors (by scoped
        name `model/link/sensor`: two models may hold sensors of one name), its robot systems; if
        one fails, those built close."""
        bodies = [(self.physics.model_of(body), body) for body in placed.bodies]
        systems: list[Scheduled] = []
        try:
            systems += [entry for _, entry in self._started([w for b in bodies for w in plugins_of(*b)], placed)]
            sensors = self._started([w for b in bodies for w in sensors_of(*b)], placed)
            placed.sensors = {wanted.name: entry.system for wanted, entry in sensors}
            systems += [entry for _, entry in sensors]
            if placed.describe:  # its main tree of joints: what a URDF can hold (see Physics.add_model)
                wanted = builtins(ROBOT_GROUP, self.physics.model_of(placed.name), placed.name)
                systems += [entry for _, entry in self._started(wanted, placed)]
        except BaseException:
            Simulation.close_all([entry.system for entry in systems])
            placed.bus.close()
            raise
        placed.systems = systems

    def _tell_added(self, placed: Placed, observers: list[ModelObserver] | None = None) -> None:
        event = placed.event()
        for observer in self.observers if observers is None else observers:
            observer.model_added(event)

    def _tell_removed(self, placed: Placed, observers: list[ModelObserver] | None = None) -> None:
        event = placed.event()
        for observer in self.observers if observers is None else observers:
            observer.model_removed(event)

    def create(self, request: CreateRequest) -> str:
        """World control's create (Gazebo's EntityFactory), between steps: loads the requested model
        with its systems; returns its name in the world. A bad request raises ValueError naming the
        field, with the world as it was."""
        model = _load_requested(request)
        name = self._free_name(request.name or model.name, request.allow_renaming)
        if _is_robot(model):
            self._check_clear(name, model, request.pose or model.pose)
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

    def _check_clear(self, name: str, model: Model, pose: Pose) -> None:
        """ValueError naming both where the robot `name` at `pose` would stand on ground another
        robot takes up (their collisions' outlines on the floor overlap)."""
        (x, y, _), own = pose.xyz, outline(model)
        mine, span = in_world(own, (x, y, pose.rpy[2])), reach(own)
        for other in self.physics.body_names():
            there = self.physics.model_of(other)
            if not _is_robot(there):
                continue
            at, theirs = self.physics.model_pose(other), outline(there)
            if math.hypot(at.position[0] - x, at.position[1] - y) > span + reach(theirs):
                continue  # too far apart to touch: the polygons need no test (a thousand tugs)
            if overlap(mine, in_world(theirs, (at.position[0], at.position[1], at.yaw))):
                raise ValueError(f"pose: {name!r} at ({x:.2f}, {y:.2f}) would overlap the robot {other!r}")

    def _free_name(self, name: str, allow_renaming: bool) -> str:
        """`name`, or with allow_renaming the first free `name_1`, `name_2`, ... (as Gazebo renames)."""
        if name not in self.models and name not in self.physics.body_names():
            return name
        if not allow_renaming:
            raise ValueError(f"name: a model named {name!r} is already in the world (set allow_renaming)")
        return next(f"{name}_{i}" for i in itertools.count(1) if f"{name}_{i}" not in self.models)

    def remove(self, name: str) -> None:
        """Takes a model, its systems and its keys out of the world; ValueError naming the field if unknown."""
        if name not in self.models:
            raise ValueError(f"name: no model named {name!r} in the world (models: {', '.join(self.models)})")
        self._take_out([name])
        log.info("removed %s", name)

    def _take_out(self, names: list[str], observers: list[ModelObserver] | None = None) -> None:
        """Models out: their systems out of the loop (at once) and closed, the observers told,
        their keys and bodies gone."""
        leaving = [self.models[name] for name in names]
        systems = [entry.system for placed in leaving for entry in placed.systems]
        self.sim.remove_systems(systems)
        Simulation.close_all(systems)
        for placed in leaving:
            self._tell_removed(placed, observers)
            placed.bus.close()
            self.physics.remove_model(placed.name)
            del self.models[placed.name]

    def reset(self, seed: int | None = None) -> None:
        """Gazebo's reset: the world as it started, so models created since leave it, and every
        system's random stream starts again where it started (what follows a reset is the same
        whatever came before it: how many steps, how many resets). With a seed, the variant it draws
        from the world's variation profile (simbot.variation) instead, as a server started with
        `--randomise SEED` has it: applied in place where it can be (`world_edit`: the models it
        changes restyled, moved, replaced, added or removed, the lighting changed, the render pool
        kept running), else loaded anew (every model and system out, the variant's in), with a log
        line saying why. ValueError naming the field, with the world as it was, when the world has
        no profile or the profile cannot be drawn from."""
        if seed is not None:
            variant = self._draw(seed)
            try:
                self._edit(
                    variant, plan_edit(self.description, self.robot, self._described(variant.world), variant.robot)
                )
            except NotInPlace as why:
                log.info("seed %d cannot be applied in place (%s): the world is loaded anew", seed, why)
                self._rebuild(variant)
            return
        self._restart()

    def _restart(self) -> None:
        """Models created since the start out, every random stream from where it started, time to zero."""
        for placed in [p for p in self.models.values() if p.created]:
            self.remove(placed.name)
        for stream in [*self._world_streams, *(s for p in self.models.values() for s in p.streams)]:
            stream.restart()
        self.sim.reset()

    def _draw(self, seed: int) -> Variant:
        if self.variations is None:
            raise ValueError(
                f"reset.seed: world {self.description.name!r} has no variation profile (simbot-server --randomise)"
            )
        try:
            return self.variations.draw(seed)
        except DescriptionError as exc:
            raise ValueError(f"reset.seed: {exc}") from None

    def _edit(self, variant: Variant, edit: WorldEdit) -> None:
        """`variant` applied in place (`world_edit`): the world as it started, the models that change
        out of the observers' view (removed ones out of the physics too), restyled and moved in the
        physics, the new ones placed; the start saved; then systems built and observers told, each
        model in the variant's order. A failure on the way loads the world anew."""
        for created in [p for p in self.models.values() if p.created]:
            self.remove(created.name)
        self.physics.reset()  # every body where the world started
        observers = self.observers
        try:
            for change in edit.models:
                if change.restyled:
                    self._tell_removed(self.models[change.name], observers)
            rebuilt = [self.models[c.name] for c in edit.models if c.restyled and not c.retuned]
            self._drop_systems(rebuilt)
            self._take_out([c.name for c in edit.models if c.old is not None and not c.restyled], observers)
            for change in edit.models:
                if change.restyled and change.old is not None and change.new is not None:
                    self._restyle(self.models[change.name], change.old, change.new, change.moved, change.retuned)
            if self.robot is not None and edit.robot is not None:
                for robot in [self.models[p.name] for p in self._placements if p.name in self.models]:
                    self._restyle(robot, self.robot, edit.robot, moved=False, retune=True)
            new = [self._place(c.new, c.name) for c in edit.models if c.new is not None and not c.restyled]
            self.description = self.physics.world = self._described(variant.world)
            self.robot = edit.robot
            self.physics.save_initial_state()
            for entry in self._world_systems:
                if isinstance(entry.system, WorldFollower):
                    entry.system.world_changed(self.description)
            for placed in [*new, *rebuilt]:
                self._build(placed)
            self.sim.add_systems([entry for placed in [*new, *rebuilt] for entry in placed.systems])
            order = {model.name: i for i, model in enumerate(self.description.models)}
            self.models = dict(sorted(self.models.items(), key=lambda item: order.get(item[0], len(order))))
            changed = {change.name for change in edit.models if change.new is not None}
            for name in [name for name in self.models if name in changed]:
                self._tell_added(self.models[name], observers)
        except Exception as exc:  # noqa: BLE001 - whatever stopped it, the world is loaded anew: never half edited
            raise NotInPlace(exc if isinstance(exc, NotInPlace) else f"the edit failed: {exc}") from exc
        self.variant = variant
        self._restart()
        log.info(
            "world %s drawn from seed %d in place: %d models changed, %d clutter models",
            variant.world.name,
            variant.seed,
            len(edit.models),
            len(variant.clutter),
        )

    def _drop_systems(self, models: list[Placed]) -> None:
        """The models' own systems out of the loop and closed, to be built anew (`_build`)."""
        systems = [entry.system for placed in models for entry in placed.systems]
        self.sim.remove_systems(systems)
        Simulation.close_all(systems)
        for placed in models:
            placed.systems, placed.sensors, placed.left_out, placed.streams = [], {}, [], []

    def _restyle(self, placed: Placed, old: Model, model: Model, moved: bool, retune: bool) -> None:
        """A model's description replaced where its body stays: the physics keeps the body (moved
        where its pose changed); where its systems stay (`retune`), each sensor whose parameters
        changed takes them."""
        self.physics.restyle(placed.name, model)
        if moved:
            for body in placed.bodies:
                self.physics.set_model_pose(body, pose_to_transform(model.pose))
        for link, name, sensor in retuned(old, model) if retune else ():
            system = placed.sensors.get("/".join(map(scoped_key, (placed.name, link, name))))
            if not isinstance(system, Retunable) or not system.retune(sensor):
                raise NotInPlace(f"sensor {placed.name}/{link}/{name} cannot take its new parameters in place")

    def _described(self, world: World) -> World:
        return kinematic(world) if world.physics.type == KINEMATIC else world

    def _rebuild(self, variant: Variant) -> None:
        """Every model and system out, `variant`'s in, time at zero."""
        for name in list(self.models):
            self.remove(name)
        systems = [entry.system for entry in self._world_systems]
        self.sim.remove_systems(systems)
        Simulation.close_all(systems)
        self._world_systems, self._world_streams, self._left_out = [], [], []
        world = variant.world
        self.description = self.physics.world = self._described(world)
        self.robot = variant.robot
        self._load(variant.robot, self._placements)
        self.variant = variant
        self.sim.reset()
        log.info("world %s drawn from seed %d: %d clutter models", world.name, variant.seed, len(variant.clutter))

    def close(self) -> None:
        Simulation.close_all(self.systems)
        self.physics.close()

    # building systems

    def _started(self, wanted: Sequence[Wanted], placed: Placed | None) -> list[tuple[Wanted, Scheduled]]:
        """Builds each system of the world (`placed` None) or of a placed model in turn, leaving out
        one with bad parameters (`_drop`); if one fails otherwise, those already built close."""
        bus, left_out = (self.bus, self._left_out) if placed is None else (placed.bus, placed.left_out)
        streams = self._world_streams if placed is None else placed.streams
        built: list[tuple[Wanted, Scheduled]] = []
        try:
            for one in wanted:
                ctx = one.context(self.physics, bus, self.description, self._seed, self._options)
                streams.append(RandomStream.of(ctx.rng))
                try:
                    built.append((one, one.build(ctx)))
                except SystemConfigError as exc:
                    left_out.append(_drop(one, exc))
        except BaseException:
            Simulation.close_all([entry.system for _, entry in built])
            raise
        return built


def _drop(wanted: Wanted, error: SystemConfigError) -> LeftOut:
    """A system whose SDF parameters are bad is left out, with one line naming it and the element:
    the rest of the world runs (as Gazebo runs a world with a sensor that failed to load), and
    world state lists it."""
    entry = LeftOut.of(wanted, error)
    log.error("%s; the world runs without it", entry.reason)
    return entry
