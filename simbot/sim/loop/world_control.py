"""World control: Gazebo's `/world/<name>/control`, `set_pose` and `state` as JSON Zenoh queryables.

Keys (with the namespace prefix when one is set) and payloads, shaped like Gazebo's messages:

- `world/<name>/control`: `{"pause": true}`, `{"pause": false}`, `{"step": true}`,
  `{"multi_step": N}`, `{"reset": {"all": true}}` (or `"reset": true`), `{"reset": {"seed": N}}`
  (the world N draws from its variation profile, simbot.variation). The reply comes when the steps
  are done: `{"ok": true, "sim_time": s, "iterations": n}`.
- `world/<name>/set_pose`: `{"name": "trolley", "position": {"x": 1, "y": 0, "z": 0},
  "orientation": {"x": 0, "y": 0, "z": 0, "w": 1}}`; orientation defaults to identity.
- `world/<name>/create`: `{"sdf_filename": PATH}` or `{"sdf": TEXT}`, with optional `"name"`
  (default: the SDF's), `"namespace"` (every key of its systems under it, its frames prefixed),
  `"pose"` (`{"position": {...}, "orientation": {...}}`) and `"allow_renaming"` (a taken name
  becomes `name_1`, ...), as Gazebo's EntityFactory. The model loads with its plugins and sensors
  between two steps; the reply `{"ok": true, "name": ...}` comes once it is in the world.
- `world/<name>/remove`: `{"name": ...}`; its systems close, its keys leave the graph.
- `world/<name>/state`: any payload; replies with sim time, iterations, pause, mode, real-time
  factor, every model's pose, each sensor's figures by its scoped name `model/link/sensor` (its
  achieved rate in messages per sim second, frames skipped), the payloads each input key has
  received (counted on arrival, so a client can tell that its command is in before it asks for
  steps), the dropped-input counters with their last reasons, and `systems_left_out`: each
  system the world runs without because its SDF parameters are bad, as `{"name", "kind",
  "reason"}` (its scoped name, its sensor type or plugin filename, the one-line error; an empty
  list when none), and `variation`: the seed, profile and clutter of the variant loaded (null for
  the world as its file says).

A malformed request gets `{"ok": false, "error": "..."}` and is counted with the dropped inputs.
A reset removes the models created since the start, as Gazebo's does.
Requests are polled by the simulation loop between steps, never acted on in a bus callback.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

from simbot.bus import BadRequest, Node, Request
from simbot.description.poses import Pose
from simbot.sim.loop.bus_view import SimBus
from simbot.sim.loop.ros_world_control import RosWorldControl
from simbot.sim.loop.sdf_systems import LeftOut
from simbot.sim.loop.simulation import Mode, Simulation
from simbot.sim.loop.system import Reporting
from simbot.sim.physics import Physics
from simbot.transform import Transform
from simbot.variation import Variant

MAX_STEPS = 10_000_000
"""A multi_step beyond this (2.8 h at 1 kHz) is a mistake, not a request."""

MAX_COORDINATE = 1e5
"""Metres (and quaternion components) beyond which a pose is absurd: PyBullet's floats lose the world there."""

Handler = Callable[[Request, dict[str, Any]], None]

KEY_SEGMENTS = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z_][A-Za-z0-9_]*)*")
"""A namespace: ROS name tokens joined by `/`, so that every key under it is a ROS topic and a Zenoh key."""
NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
"""A created model's name: one token (it names a key segment, `model/<name>/pose`, and a file)."""


@dataclass(frozen=True)
class CreateRequest:
    """A checked `create` request: exactly one of `sdf_filename` and `sdf`."""

    sdf_filename: str | None
    sdf: str | None
    name: str | None
    namespace: str
    pose: Pose | None
    allow_renaming: bool


class Models(Protocol):
    """What world control asks of the server about its models."""

    @property
    def sensors(self) -> Mapping[str, object]: ...

    @property
    def left_out(self) -> Sequence[LeftOut]: ...

    def create(self, request: CreateRequest) -> str: ...

    def remove(self, name: str) -> None: ...

    @property
    def variant(self) -> Variant | None: ...

    def reset(self, seed: int | None = None) -> None: ...


class WorldControl:
    """The queryables of one world, and its ROS 2 services (`ros_world_control.py`)."""

    def __init__(self, node: Node, world: str, sim: Simulation, bus: SimBus, models: Models) -> None:
        self.sim = sim
        self.models = models
        self.bus = bus
        self._node = node
        self.drops = bus.drops
        handlers = (
            ("control", self._control),
            ("set_pose", self._set_pose),
            ("state", self._state),
            ("create", self._create),
            ("remove", self._remove),
        )
        base = bus.topic(f"world/{world}")  # under a zone's name in a zone server
        self._handlers: dict[str, tuple[Any, Handler]] = {
            name: (node.queryable(f"{base}/{name}"), handler) for name, handler in handlers
        }
        self._keys = {name: node.key(f"{base}/{name}") for name in self._handlers}
        self.ros = RosWorldControl(node, base, sim, models, bus.drops)

    def poll(self) -> None:
        """Handles every request that arrived since the last call."""
        for name, (queryable, handler) in self._handlers.items():
            for request in queryable.poll():
                self._handle(name, request, handler)
        self.ros.poll()

    def _handle(self, name: str, request: Request, handler: Handler) -> None:
        try:
            body = request.json() if name != "state" else {}
            handler(request, body)
        except (BadRequest, ValueError, TypeError, KeyError) as exc:
            reason = str(exc.args[0]) if isinstance(exc, KeyError) and exc.args else str(exc)
            self.drops.drop(self._keys[name], reason)
            request.reply({"ok": False, "error": reason})

    def _control(self, request: Request, body: dict[str, Any]) -> None:
        unknown = set(body) - {"pause", "step", "multi_step", "reset"}
        if unknown:
            raise ValueError(f"unknown field(s) {', '.join(sorted(unknown))}; expected pause, step, multi_step, reset")
        reset, seed = _reset(body["reset"]) if "reset" in body else (False, None)
        pause = _pause(body["pause"]) if "pause" in body else None
        if pause is False and self.sim.mode is Mode.LOCKSTEP:
            raise ValueError("in lockstep mode the world advances only on step or multi_step")
        steps = _steps(body)
        # Everything is valid: only now does anything change.
        if reset:
            self.models.reset(seed)
        if pause is not None:
            self.sim.set_paused(pause)
        self._node.refresh_subscribers()
        self.sim.request_steps(steps, lambda: request.reply(self._time(ok=True)))

    def _set_pose(self, request: Request, body: dict[str, Any]) -> None:
        name = body.get("name")
        if not isinstance(name, str):
            raise TypeError('set_pose needs a model "name"')
        position = _vector(body.get("position", {}), "xyz", "position", 0.0)
        quat = unit_quaternion(_vector(body.get("orientation", {"w": 1.0}), "xyzw", "orientation", 0.0))
        self.sim.physics.set_model_pose(name, Transform((position[0], position[1], position[2]), quat))
        request.reply(self._time(ok=True))

    def _state(self, request: Request, body: dict[str, Any]) -> None:
        state = self._time(ok=True) | {
            "paused": self.sim.paused,
            "mode": self.sim.mode.value,
            "real_time_factor": self.sim.rtf.value(),
            "models": model_states(self.sim.physics),
            "sensors": {
                name: sensor.report() for name, sensor in self.models.sensors.items() if isinstance(sensor, Reporting)
            },
            "received": {i.key: i.received for i in self.bus.inputs},
            "dropped": dict(self.drops.counts),
            "last_errors": dict(self.drops.last_error),
            "systems_left_out": [entry.as_dict() for entry in self.models.left_out],
            "variation": _variation(self.models.variant),
        }
        request.reply(state)

    def _create(self, request: Request, body: dict[str, Any]) -> None:
        request.reply({"ok": True, "name": self.models.create(create_request(body))})

    def _remove(self, request: Request, body: dict[str, Any]) -> None:
        unknown = set(body) - {"name"}
        if unknown:
            raise ValueError(f"unknown field(s) {', '.join(sorted(unknown))}; expected name")
        name = body.get("name")
        if not isinstance(name, str):
            raise TypeError(f'name: remove needs a model "name", got {name!r}')
        self.models.remove(name)
        request.reply({"ok": True, "name": name})

    def _time(self, ok: bool) -> dict[str, Any]:
        return {"ok": ok, "sim_time": self.sim.clock.now_ns / 1e9, "iterations": self.sim.clock.iterations}


CREATE_FIELDS = {"sdf_filename", "sdf", "name", "namespace", "pose", "allow_renaming"}


def create_request(body: dict[str, Any]) -> CreateRequest:
    """A create request's fields checked, each error naming its field; nothing is loaded yet."""
    unknown = set(body) - CREATE_FIELDS
    if unknown:
        raise ValueError(f"unknown field(s) {', '.join(sorted(unknown))}; expected {', '.join(sorted(CREATE_FIELDS))}")
    if ("sdf" in body) == ("sdf_filename" in body):
        raise ValueError("sdf_filename or sdf: give exactly one, the model's file or its SDF text")
    for field_name in ("sdf_filename", "sdf", "name", "namespace"):
        if field_name in body and (not isinstance(body[field_name], str) or not body[field_name].strip()):
            raise TypeError(f"{field_name}: expected a non-empty string, got {body[field_name]!r}")
    namespace = body.get("namespace", "").strip("/")
    if "namespace" in body and not KEY_SEGMENTS.fullmatch(namespace):
        raise ValueError(f"namespace: expected key segments of letters, digits and _ joined by /, got {namespace!r}")
    name = body.get("name")
    if name is not None and not NAME.fullmatch(name):
        raise ValueError(f"name: expected letters, digits and _ (one key segment), got {name!r}")
    renaming = body.get("allow_renaming", False)
    if not isinstance(renaming, bool):
        raise TypeError(f"allow_renaming: expected true or false, got {renaming!r}")
    pose = _pose(body["pose"]) if "pose" in body else None
    return CreateRequest(body.get("sdf_filename"), body.get("sdf"), name, namespace, pose, renaming)


def _pose(value: Any) -> Pose:
    """`{"position": {...}, "orientation": {...}}` as a Pose; missing parts at the origin, identity."""
    if not isinstance(value, dict) or set(value) - {"position", "orientation"}:
        raise TypeError(f"pose: expected an object with position and orientation, got {value!r}")
    position = _vector(value.get("position", {}), "xyz", "pose.position", 0.0)
    quat = unit_quaternion(_vector(value.get("orientation", {"w": 1.0}), "xyzw", "pose.orientation", 0.0))
    return Pose.from_transform(Transform.of(position, quat))


def unit_quaternion(values: list[float]) -> tuple[float, float, float, float]:
    """`values` (x, y, z, w) scaled to unit length, as world control takes an orientation."""
    norm = math.sqrt(sum(v * v for v in values))
    if norm < 1e-9:
        raise ValueError("orientation must be a non-zero quaternion")
    x, y, z, w = (v / norm for v in values)
    return x, y, z, w


def _reset(value: Any) -> tuple[bool, int | None]:
    """Whether a reset field asks for a reset (Gazebo's all, model_only and time_only all reset
    everything here), and the seed of the variant to load (None: the world as it started)."""
    if value is True:
        return True, None
    if isinstance(value, dict) and set(value) <= {"all", "model_only", "time_only", "seed"}:
        seed = value.get("seed")
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < 2**63):
            raise ValueError(f"reset.seed expects a whole number from 0 to 2^63 - 1, got {seed!r}")
        if seed is not None or value.get("all") or value.get("model_only") or value.get("time_only"):
            return True, seed
    raise ValueError(f'reset expects true, {{"all": true}} or {{"seed": N}}, got {value!r}')


def _variation(variant: Variant | None) -> dict[str, Any] | None:
    if variant is None:
        return None
    return {"seed": variant.seed, "clutter": list(variant.clutter)}


def _pause(value: Any) -> bool:
    if not isinstance(value, bool):
        raise TypeError(f"pause expects true or false, got {value!r}")
    return value


def _steps(body: dict[str, Any]) -> int:
    """The number of steps a control request asks for (0 when none)."""
    count = body.get("multi_step", 1 if body.get("step") is True else 0)
    if isinstance(count, bool) or not isinstance(count, int) or not 0 <= count <= MAX_STEPS:
        raise ValueError(f"multi_step expects an integer from 0 to {MAX_STEPS}, got {count!r}")
    if "step" in body and not isinstance(body["step"], bool):
        raise ValueError(f"step expects true or false, got {body['step']!r}")
    return count


def _vector(value: Any, axes: str, field: str, default: float) -> list[float]:
    """{"x": .., "y": .., ...} → finite floats, missing axes at `default`."""
    if not isinstance(value, dict):
        raise TypeError(f"{field} expects an object with {', '.join(axes)}, got {value!r}")
    numbers = []
    for axis in axes:
        number = value.get(axis, default)
        if isinstance(number, bool) or not isinstance(number, (int, float)) or not abs(number) <= MAX_COORDINATE:
            raise ValueError(f"{field}.{axis} expects a number within ±{MAX_COORDINATE:g}, got {number!r}")
        numbers.append(float(number))
    return numbers


def model_states(physics: Physics) -> dict[str, dict[str, list[float | None]]]:
    """Every model's pose as `state` reports it (a learning environment's world in its own process
    answers the same)."""
    models = {}
    for name in physics.body_names():
        xyz, quat = physics.model_pose(name)
        models[name] = {"position": _finite(xyz), "orientation": _finite(quat)}
    return models


def _finite(values: tuple[float, ...]) -> list[float | None]:
    """JSON has no NaN or infinity: a body that has left the world reads as nulls."""
    return [v if math.isfinite(v) else None for v in values]
