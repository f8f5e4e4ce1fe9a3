"""Names a system derives from the SDF: its keys (Gazebo's defaults), its frame, its rate, its random stream."""

from __future__ import annotations

import hashlib

import numpy as np

from simbot.description.model import Sensor


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
