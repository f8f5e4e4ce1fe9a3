"""The contract between the simulation loop and its systems, as in Gazebo Sim.

A system is a class built once from a `SystemContext` (its SDF element, the model it belongs to,
the world, the bus, the physics' narrow interfaces): that is its configure step, and a
`SystemFactory` is anything that builds one so (a class, registered under an entry point). It
has a `name`, and implements only the phases it needs, each a small Protocol given the step's one
`UpdateInfo` (sim time, step size, iterations, paused: Gazebo's UpdateInfo):

- `pre_update(info)`: before the physics step; drain commands, write joint targets.
- `pre_update_all(batches)`, a classmethod, in place of `pre_update`: the class steps all its
  instances of one priority at once (`BatchedPreUpdate`), given as a `Batch` (the instances and
  the step's info) per world that steps: a world's people, or every sub-env's, think in one pass.
- `post_update(info)`: after the step; read state, publish at its own rate. The physics is
  read-only here (`PhysicsReadOnly` if a system tries to change it), as Gazebo's PostUpdate
  sees a const entity-component manager: every system reads the same, finished step.
- `post_update_all(batches)`, a classmethod, in place of `post_update`: the class steps
  all its instances of one priority at once (`BatchedPostUpdate`), a `Batch` per world. A fleet
  of a hundred tugs has a hundred IMUs; one call does their frame queries, rotations and noise as
  arrays. Worlds of the same systems step together (`simbot.sim.loop.simulation.step_together`,
  a vector env's sub-envs): each batched class is called once per phase for all of them, each
  world's instances with its own info (sub-envs' clocks differ after their resets). A class
  whose instances are `Periodic` gets only those due at the step, and no call where none is.
- `reset(info)`: the world was reset; forget what was integrated.
- `model_added(event)`, `model_removed(event)`: a model entered the world (at start, or created
  through world control) or is about to leave it, with its bodies and its systems
  (`ModelObserver`). The world's systems hear of every model; a model's own systems of none.
- `report()`: figures for world control's `state` (a sensor's achieved rate).
- `close()`: the server is stopping, or the system's model leaves; let go of what it holds.

Order: within each phase, systems run by priority (lower first, as Gazebo's
`<gz:system_priority>`, which a `<plugin>` may set, else the class's `priority`), and in the order
they were added where priorities tie. The phases give the coarse order Gazebo's priorities exist
for: commands act before the physics step, sensors see its result after.

Systems come from SDF `<plugin>` elements (by plugin name), `<sensor>` elements (by sensor type),
and the built-in groups every world or described model gets (`simbot.sim.loop.registry`); all get the
same context, a sensor's with its link and sensor filled in. A `<plugin>` inside a `<visual>` (or
on a nested model, which simbot flattens: it goes to the nested model's visuals) runs only where its
class says `runs_on_visuals = True` (Label, Thermal), with its link and visual filled in. Each
gets its own random stream from the seed and its scoped name (`simbot.description.naming.scoped_rng`),
started again at each reset. Bus callbacks only queue (`simbot.sim.loop.bus_view.Input`); systems act in the loop, so everything a system does happens at a
definite sim time.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, NamedTuple, Protocol, runtime_checkable

import numpy as np

from simbot.description.errors import SystemConfigError
from simbot.description.model import Link, Model, Plugin, Sensor, Visual, World
from simbot.description.naming import model_topic, sensor_topic
from simbot.sim.loop.bus_view import SimBus
from simbot.sim.physics.protocols import WorldAccess

DEFAULT_PRIORITY = 0
"""A system's place in each phase when neither its class nor its SDF says otherwise (Gazebo's default)."""
LAST_PRIORITY = 1_000_000
"""After every other system: the clock, so that a client that sees sim time t has every message stamped t."""


@dataclass(frozen=True)
class UpdateInfo:
    """One step as every phase of it sees it (Gazebo's UpdateInfo).

    `sim_time_ns` is the time the step reaches, the stamp of what post_update publishes; a reset
    is told time zero."""

    sim_time_ns: int
    step_ns: int
    iterations: int
    paused: bool = False


@runtime_checkable
class System(Protocol):
    """Every system: built from a `SystemContext`, named (in logs and world state)."""

    name: str


@runtime_checkable
class PreUpdate(Protocol):
    def pre_update(self, info: UpdateInfo) -> None: ...


@runtime_checkable
class PostUpdate(Protocol):
    def post_update(self, info: UpdateInfo) -> None: ...


class Batch(NamedTuple):
    """A world's instances of one batched class at one priority, and that world's step."""

    systems: Sequence[Any]
    info: UpdateInfo


@runtime_checkable
class BatchedPreUpdate(Protocol):
    """A pre-update system whose class steps all its instances of one priority in one call, where the
    first of them would have run (as `BatchedPostUpdate`, before the physics step)."""

    @classmethod
    def pre_update_all(cls, batches: Sequence[Batch]) -> None: ...


@runtime_checkable
class BatchedPostUpdate(Protocol):
    """A post-update system whose class steps all its instances of one priority in one call, where
    the first of them would have run: each instance must come out as if stepped alone (its own
    rate, random stream and outputs), only cheaper together."""

    @classmethod
    def post_update_all(cls, batches: Sequence[Batch]) -> None: ...


@runtime_checkable
class Periodic(Protocol):
    """A post-update system that does nothing before `next_due_ns` (its next sample, in sim time):
    the loop does not call it until then (`simbot.sim.kit.rates.Paced`)."""

    @property
    def next_due_ns(self) -> int: ...


@runtime_checkable
class Resettable(Protocol):
    def reset(self, info: UpdateInfo) -> None: ...


@dataclass(frozen=True)
class ModelEvent:
    """A model entering or leaving the running world."""

    name: str
    """Its name in the world (the robot is `flexley_tug` whatever its SDF says)."""
    bodies: tuple[str, ...]
    """Its bodies in the physics: `name`, and `name::<root>` for each further joint tree."""
    systems: tuple[System, ...]
    """Its own systems (plugins, sensors, description): an observer finds the ones it serves by Protocol."""
    created: bool = False
    """Created through world control (not there at start)."""


@runtime_checkable
class ModelObserver(Protocol):
    """A world system that follows models: told of each one at start and of each created or removed."""

    def model_added(self, event: ModelEvent) -> None:
        """After the physics holds the model's bodies and its systems are built."""
        ...

    def model_removed(self, event: ModelEvent) -> None:
        """Before the physics lets its bodies go, after its systems left the loop."""
        ...


@runtime_checkable
class Reporting(Protocol):
    name: str

    def report(self) -> dict[str, Any]: ...


@runtime_checkable
class Closable(Protocol):
    def close(self) -> None: ...


def priority(system: System) -> int:
    """Where a system runs within a phase when its SDF says nothing: its class's `priority`, else the default."""
    value = getattr(system, "priority", DEFAULT_PRIORITY)
    return value if isinstance(value, int) else DEFAULT_PRIORITY


@dataclass(frozen=True)
class RunOptions:
    """What the command line says to every system: the run mode, and parameters over the SDF's.

    `overrides` holds command-line values by `<system>.<parameter>` (`camera.size`,
    `rendering.renderer`, ...); each system's docstring names the ones it reads."""

    lockstep: bool = False
    """Lockstep: a sensor delivers every message at its sim time, whatever it costs (cameras render every frame)."""
    overrides: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class SystemContext:
    """Everything a system is built from."""

    physics: WorldAccess
    bus: SimBus
    world: World
    rng: np.random.Generator
    model: Model | None = None
    model_name: str | None = None
    """The model's name in the running world (the robot is `flexley_tug` whatever its SDF says)."""
    plugin: Plugin | None = None
    link: Link | None = None
    sensor: Sensor | None = None
    options: RunOptions = field(default_factory=RunOptions)
    visual: Visual | None = None
    """The `<visual>` a visual's plugin sits in (its `link` filled in too)."""

    def require_model(self, system: str) -> tuple[Model, str]:
        """The model a model-level system belongs to."""
        if self.model is None or self.model_name is None:
            raise SystemConfigError(f"{system} belongs in a <model>, not in the <world>")
        return self.model, self.model_name

    def require_sensor(self) -> tuple[str, Link, Sensor]:
        """(running model name, link, sensor) of a sensor system."""
        if self.model_name is None or self.link is None or self.sensor is None:
            raise SystemConfigError("a sensor system needs the <sensor> element of a model's link")
        return self.model_name, self.link, self.sensor

    def override(self, key: str) -> Any:
        """The command line's value of `key` (`<system>.<parameter>`), or None."""
        return self.options.overrides.get(key)

    def model_topic(self, leaf: str) -> str:
        """Gazebo's default key of a model's system: `model/<model>/<leaf>` (a nested `a::b` as `a/b`)."""
        _, name = self.require_model(leaf)
        return model_topic(name, leaf)

    def sensor_topic(self, kind: str) -> str:
        """The sensor's key (`simbot.description.naming.sensor_topic`: its `<topic>`, else Gazebo's default)."""
        name, link, sensor = self.require_sensor()
        return sensor_topic(self.world.name, name, self.model, link, sensor, kind)


SystemFactory = Callable[[SystemContext], System]
"""What an entry point names: a system class, built from its context."""
