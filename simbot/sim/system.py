"""The contract between the simulation loop and its systems, as in Gazebo Sim.

A system is a class built once from a `SystemContext` (its SDF element, the model it belongs to,
the world and the bus). It then implements only the phases it needs, each given the step's one
`UpdateInfo` (sim time, step size, iterations, paused: Gazebo's UpdateInfo):

- `pre_update(info)`: before the physics step; drain commands, write joint targets.
- `post_update(info)`: after the step; read state, publish at its own rate. The physics is
  read-only here (`PhysicsReadOnly` if a system tries to change it), as Gazebo's PostUpdate
  sees a const entity-component manager: every system reads the same, finished step.
- `reset(info)`: the world was reset; forget what was integrated.
- `report()`: figures for world control's `state` (a sensor's achieved rate).
- `close()`: the server is stopping; end worker processes.

Order: within each phase, systems run by `priority` (lower first, as Gazebo's
`<gz:system_priority>`, which a `<plugin>` may set), and in the order the SDF lists them where
priorities tie. The phases give the coarse order Gazebo's priorities exist for: commands act
before the physics step, sensors see its result after.

Systems come from SDF `<plugin>` elements (by plugin name) and `<sensor>` elements (by sensor
type); both kinds get the same context, a sensor's with its link and sensor filled in. Each gets
its own random stream from the seed and its scoped name (`scoped_rng`).

The loop keeps one list per phase. Bus callbacks only queue (see `Input`); systems act in the
loop, so everything a system does happens at a definite sim time.
"""

from __future__ import annotations

import hashlib
import logging
import math
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np

from simbot.bus import DecodeError, Node, Publisher, decode
from simbot.description.model import Link, Model, Plugin, Sensor, World
from simbot.description.xml import parse_flag
from simbot.sim.physics import Physics

if TYPE_CHECKING:
    from simbot.sim.systems.rendering import Rendering

log = logging.getLogger(__name__)

WARN_INTERVAL_S = 1.0
"""At most one warning per key and second about dropped input: a flood must not flood the log."""


class SystemConfigError(ValueError):
    """A system's SDF parameters are unusable; the message names the plugin and the parameter."""


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
class PreUpdate(Protocol):
    def pre_update(self, info: UpdateInfo) -> None: ...


@runtime_checkable
class PostUpdate(Protocol):
    def post_update(self, info: UpdateInfo) -> None: ...


@runtime_checkable
class Resettable(Protocol):
    def reset(self, info: UpdateInfo) -> None: ...


def priority(system: object) -> int:
    """Where a system runs within a phase: its `priority` attribute, else the default."""
    value = getattr(system, "priority", DEFAULT_PRIORITY)
    return value if isinstance(value, int) else DEFAULT_PRIORITY


def in_order(systems: list[object]) -> list[object]:
    """Systems by priority, lower first; ties keep their given (SDF) order."""
    return sorted(systems, key=priority)


@runtime_checkable
class Reporting(Protocol):
    name: str

    def report(self) -> dict[str, Any]: ...


@runtime_checkable
class Closable(Protocol):
    def close(self) -> None: ...


@dataclass
class Drops:
    """Dropped inputs per key, with the last reason: world control's `state` reports them."""

    counts: dict[str, int] = field(default_factory=dict)
    last_error: dict[str, str] = field(default_factory=dict)
    _last_warning: dict[str, float] = field(default_factory=dict)

    def drop(self, key: str, reason: str, count: int = 1) -> None:
        """Counts dropped inputs and warns, rate-limited per key."""
        self.counts[key] = self.counts.get(key, 0) + count
        self.last_error[key] = reason
        now = time.monotonic()
        if now - self._last_warning.get(key, -math.inf) >= WARN_INTERVAL_S:
            self._last_warning[key] = now
            log.warning("dropped input on %s (%d so far): %s", key, self.counts[key], reason)


Check = Callable[[Any], "str | None"]
"""Returns why a decoded message is unacceptable, or None."""


class Input:
    """Commands on one key: queued by the bus, decoded and checked in the loop; bad ones dropped and counted."""

    def __init__(self, node: Node, drops: Drops, topic: str, typename: str, check: Check | None = None) -> None:
        self.key = node.key(topic)
        self._inbox = node.inbox(topic, typename)
        self._drops = drops
        self._typename = typename
        self._check = check
        self._overflowed = 0

    @property
    def received(self) -> int:
        """Payloads that reached the server on this key, valid or not, drained or not."""
        return self._inbox.received

    def close(self) -> None:
        self._inbox.close()

    def drain(self) -> list[Any]:
        """The valid messages that arrived since the last call, oldest first."""
        if self._inbox.overflowed != self._overflowed:
            lost, self._overflowed = self._inbox.overflowed - self._overflowed, self._inbox.overflowed
            self._drops.drop(
                self.key, "more commands arrived within one step than the queue holds; the oldest were dropped", lost
            )
        messages = []
        for payload in self._inbox.drain():
            try:
                message = decode(payload, self._typename)
            except DecodeError as exc:
                self._drops.drop(self.key, f"not a {self._typename}: {exc}")
                continue
            problem = self._check(message) if self._check else None
            if problem:
                self._drops.drop(self.key, problem)
                continue
            messages.append(message)
        return messages


@dataclass
class SimBus:
    """What systems may do on the bus: publish, and take commands through an `Input`.

    `scoped(namespace)` gives the view one model's systems get: its keys under the namespace
    (`tug_2/cmd_vel`), the frame ids of what it publishes prefixed (`tug_2/base_link`), and what
    it declared undeclared together by `close()` when the model leaves the world."""

    node: Node
    drops: Drops = field(default_factory=Drops)
    inputs: list[Input] = field(default_factory=list)
    namespace: str = ""
    _declared: list[Publisher | Input] = field(default_factory=list)

    def scoped(self, namespace: str) -> SimBus:
        """A view for one model's systems (`namespace` empty: the world's keys and frames); shares
        the dropped-input counters and the list of inputs world state reports."""
        return SimBus(self.node, self.drops, self.inputs, namespace)

    def topic(self, topic: str) -> str:
        return f"{self.namespace}/{topic}" if self.namespace else topic

    def publisher(self, topic: str, msgtype: type[Any], *, latched: bool = False) -> Publisher:
        """A publisher of `msgtype` (a `messages` class) on `topic`, on the graph from the start."""
        publisher = self.node.publisher(self.topic(topic), msgtype, latched=latched, frame_prefix=self.namespace)
        self._declared.append(publisher)
        return publisher

    def input(self, topic: str, typename: str, check: Check | None = None) -> Input:
        self.inputs.append(Input(self.node, self.drops, self.topic(topic), typename, check))
        self._declared.append(self.inputs[-1])
        return self.inputs[-1]

    def close(self) -> None:
        """Undeclares every key this view declared: they leave the graph."""
        for entity in self._declared:
            entity.close()
            if isinstance(entity, Input):
                self.inputs.remove(entity)
        self._declared.clear()


@dataclass(frozen=True)
class SensorSettings:
    """What the command line may say over the SDF, for every sensor of the world."""

    lockstep: bool = False
    """Lockstep renders every camera frame at its sim time; otherwise a busy camera skips frames."""
    renderer: str = "auto"
    """`gl` (OpenGL 3.3 on EGL: the GPU, else Mesa on the CPU), `tiny` (PyBullet's TinyRenderer), or `auto` (gl where an EGL context opens)."""
    camera_size: tuple[int, int] | None = None
    """(width, height) for every camera instead of the SDF's."""
    camera_rate: float | None = None
    """Hz for every camera instead of the SDF's update_rate."""
    render_workers: int | None = None
    """Render worker processes; None: every core but one."""


@dataclass(frozen=True)
class SystemContext:
    """Everything a system is built from."""

    physics: Physics
    bus: SimBus
    world: World
    rng: np.random.Generator
    model: Model | None = None
    model_name: str | None = None
    """The model's name in the running world (the robot is `flexley_tug` whatever its SDF says)."""
    plugin: Plugin | None = None
    link: Link | None = None
    sensor: Sensor | None = None
    settings: SensorSettings = field(default_factory=SensorSettings)
    rendering: Rendering | None = None
    """The world's one rendering system, which camera-type sensors register with."""

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

    def model_topic(self, leaf: str) -> str:
        """Gazebo's default key of a model's system: `model/<model>/<leaf>` (a nested `a::b` as `a/b`)."""
        _, name = self.require_model(leaf)
        return model_topic(name, leaf)

    def sensor_topic(self, kind: str) -> str:
        """A sensor's `<topic>`, else Gazebo's default `world/<w>/model/<m>/link/<l>/sensor/<s>/<kind>`
        (`scan`, `image`, `imu`, `points`, ...; an empty kind, as Gazebo's RGBD camera has, ends at `<s>`);
        a joint's sensor: `.../joint/<j>/sensor/<s>/<kind>`."""
        name, link, sensor = self.require_sensor()
        stated = (sensor.topic or "").strip().strip("/")
        if stated:
            return stated
        joint = self.model.joint_of(sensor) if self.model else None
        owner = f"joint/{scoped_key(joint.name)}" if joint else f"link/{scoped_key(link.name)}"
        scope = (self.world.name, name)
        prefix = "world/{}/model/{}/".format(*map(scoped_key, scope)) + f"{owner}/sensor/{scoped_key(sensor.name)}"
        return f"{prefix}/{kind}" if kind else prefix

    def require_rendering(self) -> Rendering:
        """The rendering system a camera registers with."""
        if self.rendering is None:
            raise SystemConfigError("a camera sensor needs the world's rendering system")
        return self.rendering


def scoped_rng(seed: int, *scope: str) -> np.random.Generator:
    """The random generator of one system: a function of the seed and its scoped name alone
    (model, link, sensor or plugin), so that adding, removing or reordering other systems never
    changes its noise. The names, joined by NUL (which no SDF name holds), are hashed with SHA-256,
    which, unlike `hash()`, is the same in every process."""
    digest = hashlib.sha256("\0".join(scope).encode()).digest()
    return np.random.default_rng(np.random.SeedSequence([seed, *np.frombuffer(digest, dtype=np.uint32).tolist()]))


def scoped_key(name: str) -> str:
    """A scoped SDF name (`outer::inner`) as key segments (`outer/inner`), as Gazebo names its topics."""
    return "/".join(part for part in name.split("::") if part)


def model_topic(model: str, leaf: str) -> str:
    """Gazebo's default key of a system of the model running as `model`: `model/<model>/<leaf>`."""
    return f"model/{scoped_key(model)}/{leaf}"


def sensor_frame(sensor: Sensor) -> str:
    """The frame its data are stamped in: `<frame_name>`, else the sensor's name (tf_static places it)."""
    return (sensor.frame_name or "").strip() or sensor.name


def sensor_rate(sensor: Sensor, default: float) -> float:
    """The SDF update_rate; 0 (SDF: "as fast as possible") or absent gives `default`."""
    return sensor.update_rate if sensor.update_rate > 0 else default


def param(plugin: Plugin, *tags: str, default: str | None = None) -> str | None:
    """The first of `tags` the plugin sets (Gazebo renamed several; the old names still work)."""
    for tag in tags:
        value = plugin.get(tag)
        if value is not None and value.strip() != "":
            return value.strip()
    return default


def number_param(plugin: Plugin, *tags: str, default: float | None = None, positive: bool = False) -> float | None:
    """A numeric parameter; a value that is not a (positive) number is an error naming it."""
    text = param(plugin, *tags)
    if text is None:
        return default
    try:
        value = float(text)
    except ValueError:
        raise SystemConfigError(f"{plugin.name}: <{tags[0]}> expected a number, got {text!r}") from None
    if not math.isfinite(value) or (positive and value <= 0):
        raise SystemConfigError(
            f"{plugin.name}: <{tags[0]}> must be a {'positive ' if positive else ''}finite number, got {text!r}"
        )
    return value


PRIORITY_TAGS = ("gz:system_priority", "gz::system_priority")
"""Where a `<plugin>` states its priority: Gazebo's element, written either way Gazebo accepts."""


def plugin_priority(plugin: Plugin) -> int | None:
    """The priority the SDF gives a plugin's system, if any; a value that is not an integer is an error naming it."""
    text = param(plugin, *PRIORITY_TAGS)
    if text is None:
        return None
    try:
        return int(text)
    except ValueError:
        raise SystemConfigError(f"{plugin.name}: <{PRIORITY_TAGS[0]}> expected an integer, got {text!r}") from None


def bool_param(plugin: Plugin, *tags: str, default: bool) -> bool:
    """SDF booleans: true/false/1/0."""
    text = param(plugin, *tags)
    if text is None:
        return default
    flag = parse_flag(text)
    if flag is None:
        raise SystemConfigError(f"{plugin.name}: <{tags[0]}> expected true or false, got {text!r}")
    return flag


@dataclass
class Every:
    """Fires at a fixed sim-time period: a system's own rate, independent of the step size."""

    period_ns: int
    next_ns: int = 0

    @staticmethod
    def hz(rate: float) -> Every:
        return Every(max(1, round(1e9 / rate)))

    def due(self, now_ns: int) -> bool:
        """True at the first step at or after each multiple of the period (so 30 Hz stays 30 Hz on 1 ms steps)."""
        if now_ns < self.next_ns:
            return False
        self.next_ns = (now_ns // self.period_ns + 1) * self.period_ns
        return True

    def restart(self) -> None:
        self.next_ns = 0


@dataclass
class RateMeter:
    """Messages per second of sim time over the last 3 s: the rate a subscriber sees.

    Three seconds, because a camera's frames are published up to a few hundred milliseconds
    after their stamps, and a one-second window would hold too few of a slow camera's frames."""

    window_ns: int = 3_000_000_000
    stamps: deque[int] = field(default_factory=deque)
    count: int = 0

    def tick(self, stamp_ns: int) -> None:
        self.count += 1
        self.stamps.append(stamp_ns)
        while self.stamps and self.stamps[0] <= stamp_ns - self.window_ns:
            self.stamps.popleft()

    def rate(self, now_ns: int) -> float:
        """Intervals per second between the stamps of the window ending `now_ns`; 0 with fewer than two."""
        recent = [stamp for stamp in self.stamps if stamp > now_ns - self.window_ns]
        if len(recent) < 2 or recent[-1] == recent[0]:
            return 0.0
        return (len(recent) - 1) * 1e9 / (recent[-1] - recent[0])

    def reset(self) -> None:
        self.stamps.clear()


class Sampled:
    """What every sensor shares: its name, its rate, the rate it achieved, and forgetting on reset.

    A sensor system derives from it, calls `due(info)` each step and `published(stamp_ns)` for
    each message; world state's `sensors` reports what it achieved.
    """

    def __init__(self, name: str, rate_hz: float) -> None:
        self.name = name
        self.every = Every.hz(rate_hz)
        self.meter = RateMeter()
        self._now_ns = 0

    def due(self, info: UpdateInfo) -> bool:
        self._now_ns = info.sim_time_ns
        return self.every.due(info.sim_time_ns)

    def published(self, stamp_ns: int) -> None:
        self.meter.tick(stamp_ns)

    def report(self) -> dict[str, Any]:
        return {"rate_hz": round(self.meter.rate(self._now_ns), 3), "messages": self.meter.count}

    def reset(self, info: UpdateInfo) -> None:
        self.every.restart()
        self.meter.reset()
        self._now_ns = info.sim_time_ns
