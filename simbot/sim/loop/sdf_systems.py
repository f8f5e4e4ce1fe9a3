"""The systems a world's SDF asks for (`Wanted`), and the ones left out of it (`LeftOut`, issue 37).

A world's systems come from its SDF: the `<plugin>`s of the world, of each body of a model and of
its visuals, and the `<sensor>`s of the body's links (`world_plugins`, `plugins_of`, `sensors_of`),
besides the built-in ones every world or described model gets (`builtins`). `SimWorld` builds each
from a `SystemContext` of the running world (`Wanted.build`); one whose SDF parameters are bad
(`SystemConfigError`) is left out and the world runs without it, as Gazebo runs a world whose
sensor failed to load, but not in silence: the world keeps a `LeftOut` for it, which world
state reports (`systems_left_out`) and `simbot monitor` shows.

`simbot describe` goes through the same lists and builds the same classes, before any server runs
(`left_out_of`): from contexts whose physics and bus are offline, so that a system stops the
moment it reaches for them. A system reads and checks its SDF first (its configure step) and only
then takes its place in the world, so what it refuses before that is what the server would leave
out; what it can check only against the running world (a `<target>` model being there, a folder
it can write) describe cannot tell. Neither PyBullet nor the bus starts.
"""

from __future__ import annotations

import logging
from dataclasses import asdict, dataclass
from typing import NoReturn, cast

from simbot.bus import Node
from simbot.description.model import Link, Model, Plugin, Sensor, Visual, World
from simbot.description.naming import scoped_key, scoped_rng
from simbot.description.plugin_params import plugin_priority
from simbot.description.urdf_writer import joint_trees
from simbot.sim.loop.bus_view import SimBus
from simbot.sim.loop.plan import Scheduled
from simbot.sim.loop.registry import builtin, lookup, sensor_lookup
from simbot.sim.loop.simulation import Simulation
from simbot.sim.loop.system import RunOptions, SystemConfigError, SystemContext, SystemFactory, priority
from simbot.sim.physics.protocols import WorldAccess

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class Wanted:
    """One system the SDF asks for: the class that builds it, and where its SDF is (the fields of
    its `SystemContext`); a built-in system has no plugin or sensor."""

    factory: SystemFactory
    model: Model | None = None
    body: str | None = None
    """The body's name in the running world: the model's, or `<model>::<root>` for a further tree of its joints."""
    plugin: Plugin | None = None
    link: Link | None = None
    sensor: Sensor | None = None
    visual: Visual | None = None

    @property
    def scope(self) -> tuple[str, ...]:
        """Its names below the body: (link, sensor), (plugin,), or a visual's (link, visual, plugin)."""
        if self.link is not None and self.sensor is not None:
            return self.link.name, self.sensor.name
        own = (self.plugin.name,) if self.plugin is not None else ()
        return (self.link.name, self.visual.name, *own) if self.link and self.visual else own

    @property
    def name(self) -> str:
        """A sensor's scoped name `model/link/sensor` (its key in world state's `sensors`); a
        plugin's or a built-in system's name after its model's (and its link's and visual's)."""
        if self.sensor is not None:
            return "/".join(map(scoped_key, (self.body or "", *self.scope)))
        own = self.plugin.name if self.plugin is not None else getattr(self.factory, "__name__", "system")
        return "/".join([*(scoped_key(part) for part in (self.body or "", *self.scope[:-1]) if part), own])

    @property
    def kind(self) -> str:
        """The sensor's type, the plugin's filename, or `built-in`."""
        if self.sensor is not None:
            return self.sensor.type
        return self.plugin.filename if self.plugin is not None else "built-in"

    def context(self, physics: WorldAccess, bus: SimBus, world: World, seed: int, options: RunOptions) -> SystemContext:
        """Its context in `world`; its random stream from the seed and its scoped name."""
        rng = scoped_rng(seed, self.body or "world", *self.scope)
        return SystemContext(
            physics, bus, world, rng, self.model, self.body, self.plugin, self.link, self.sensor, options, self.visual
        )

    def build(self, ctx: SystemContext) -> Scheduled:
        """Its system, with the priority its `<plugin>` states, else its class's; SystemConfigError
        naming the element when its SDF parameters are bad."""
        stated = plugin_priority(self.plugin) if self.plugin is not None else None
        system = self.factory(ctx)
        return Scheduled(system, priority(system) if stated is None else stated)


@dataclass(frozen=True)
class LeftOut:
    """A system the world runs without, because its SDF parameters are bad."""

    name: str
    """`Wanted.name`: `flexley_tug/base_scan_front/lidar_front`, `trolley/gz::sim::systems::DiffDrive`."""
    kind: str
    """`Wanted.kind`: the sensor's type or the plugin's filename."""
    reason: str
    """The SystemConfigError on one line, naming the element."""

    @staticmethod
    def of(wanted: Wanted, error: SystemConfigError) -> LeftOut:
        return LeftOut(wanted.name, wanted.kind, " ".join(str(error).split()))

    def as_dict(self) -> dict[str, str]:
        return asdict(self)


def world_plugins(world: World) -> list[Wanted]:
    """A system for each `<plugin>` of the world whose class is registered."""
    return [Wanted(factory, plugin=plugin) for plugin in world.plugins if (factory := lookup(plugin)) is not None]


def builtins(group: str, model: Model | None = None, body: str | None = None) -> list[Wanted]:
    """The systems of a built-in group, for the world (no model) or for one described body."""
    return [Wanted(factory, model, body) for factory in builtin(group)]


def plugins_of(model: Model, body: str) -> list[Wanted]:
    """A system for each `<plugin>` of one body, then of its visuals where the class runs there
    (`runs_on_visuals`: Label, Thermal)."""
    own = [Wanted(factory, model, body, p) for p in model.plugins if (factory := lookup(p)) is not None]
    found = [
        (factory, link, visual, plugin)
        for link in model.links
        for visual in link.visuals
        for plugin in visual.plugins
        if (factory := lookup(plugin)) is not None
    ]
    _not_run([(plugin, visual) for factory, _, visual, plugin in found if not _runs_on_visuals(factory)])
    on_visuals = [
        Wanted(factory, model, body, plugin, link, visual=visual)
        for factory, link, visual, plugin in found
        if _runs_on_visuals(factory)
    ]
    return own + on_visuals


def _runs_on_visuals(factory: SystemFactory) -> bool:
    return bool(getattr(factory, "runs_on_visuals", False))


def _not_run(skipped: list[tuple[Plugin, Visual]]) -> None:
    """One warning per plugin: a nested model's goes to each of its visuals, as simbot flattens nested models."""
    first: dict[Plugin, Visual] = {}
    for plugin, visual in skipped:
        first.setdefault(plugin, visual)
    for plugin, visual in first.items():
        log.warning(
            "plugin %s on visual %r (or its nested model) is not run: only a visual's systems "
            "(Label, Thermal) run there, as simbot flattens nested models",
            plugin.name,
            visual.name,
        )


def sensors_of(model: Model, body: str) -> list[Wanted]:
    """A system for each `<sensor>` of one body's links (and joints) whose type is registered."""
    return [
        Wanted(factory, model, body, link=link, sensor=sensor)
        for link, sensor in model.sensors()
        if (factory := sensor_lookup(sensor)) is not None
    ]


class Offline(Exception):
    """A system reached for the physics or the bus of a world that is not running (`left_out_of`)."""


class _Offline:
    """The running world's physics and bus, which `simbot describe` has not got: a system that
    reaches for them has checked all it checks of its SDF alone."""

    def __getattr__(self, name: str) -> NoReturn:
        raise Offline(name)


_OFFLINE = _Offline()


def left_out_of(description: Model | World) -> list[LeftOut]:
    """The systems a server would leave out of this world, or of a world holding this model, for
    bad SDF parameters (see the module docstring); every body's as `SimWorld` builds it."""
    if isinstance(description, World):
        world, wanted = description, world_plugins(description)
    else:
        world, wanted = World("default", models=(description,)), []
    for model in world.models:
        for tree in joint_trees(model):  # each tree a body, named as Physics.add_model names it
            wanted += plugins_of(tree, tree.name) + sensors_of(tree, tree.name)
    physics, bus = cast(WorldAccess, _OFFLINE), SimBus(cast(Node, _OFFLINE))
    refused = (_refused(one, one.context(physics, bus, world, 0, RunOptions())) for one in wanted)
    return [entry for entry in refused if entry is not None]


def _refused(wanted: Wanted, ctx: SystemContext) -> LeftOut | None:
    """Why the server would leave `wanted` out, or None: it built, or reached for the running world first."""
    try:
        Simulation.close_all([wanted.build(ctx).system])
    except SystemConfigError as exc:
        return LeftOut.of(wanted, exc)
    except Offline:
        pass
    return None
