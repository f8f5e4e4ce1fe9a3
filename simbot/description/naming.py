"""Names a system derives from the SDF: its keys (Gazebo's defaults), its frame, its rate, its random
stream, and a `<plugin>`'s canonical name.

Gazebo names one system several ways: `gz::sim::systems::DiffDrive`, `ignition::gazebo::systems::
DiffDrive`, and the library files `gz-sim-diff-drive-system`, `libignition-gazebo6-diff-drive-
system.so`. All reduce to one canonical name (`DiffDrive`): the name the server looks the system up
by (simbot/sim/loop/registry.py), and the name by which the gym finds a robot's drive.
"""

from __future__ import annotations

import hashlib
import re
from collections.abc import Iterable

import numpy as np

from simbot.description.model import Link, Model, Plugin, Sensor

_LIBRARY = re.compile(
    r"^(?:lib)?(?:gz-sim|ignition-gazebo|gz-gazebo)\d*-(?P<name>.+?)(?:-system)?(?:\.so|\.dylib|\.dll)?$"
)


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


def sensor_topic(world: str, running: str, model: Model | None, link: Link, sensor: Sensor, kind: str) -> str:
    """A sensor's `<topic>`, else Gazebo's default `world/<w>/model/<m>/link/<l>/sensor/<s>/<kind>`
    for the model running as `running` (`scan`, `image`, `imu`, `points`, ...; an empty kind, as
    Gazebo's RGBD camera has, ends at `<s>`); a joint's sensor: `.../joint/<j>/sensor/<s>/<kind>`.
    The one rule: the server's sensors publish there, and the gym subscribes there."""
    stated = (sensor.topic or "").strip().strip("/")
    if stated:
        return stated
    joint = model.joint_of(sensor) if model is not None else None
    owner = f"joint/{scoped_key(joint.name)}" if joint else f"link/{scoped_key(link.name)}"
    prefix = f"world/{scoped_key(world)}/model/{scoped_key(running)}/{owner}/sensor/{scoped_key(sensor.name)}"
    return f"{prefix}/{kind}" if kind else prefix


def sensor_frame(sensor: Sensor) -> str:
    """The frame its data are stamped in: `<frame_name>`, else the sensor's name (tf_static places it)."""
    return (sensor.frame_name or "").strip() or sensor.name


def sensor_rate(sensor: Sensor, default: float) -> float:
    """The SDF update_rate; 0 (SDF: "as fast as possible") or absent gives `default`."""
    return sensor.update_rate if sensor.update_rate > 0 else default


def canonical_name(plugin: Plugin) -> str:
    """`DiffDrive` for every spelling Gazebo accepts; other names unchanged."""
    if "::" in plugin.name:
        return plugin.name.rsplit("::", 1)[1]
    match = _LIBRARY.match(plugin.filename.rsplit("/", 1)[-1])
    if match:
        return "".join(part.capitalize() for part in match["name"].split("-"))
    return plugin.name or plugin.filename


def plugin_named(plugins: Iterable[Plugin], name: str) -> Plugin | None:
    """The first of `plugins` whose canonical name is `name`."""
    return next((plugin for plugin in plugins if canonical_name(plugin) == name), None)
