"""A variation profile: what a randomised world may change, and within which ranges (TOML).

A profile lies beside its world (`worlds/warehouse.variation.toml` for `worlds/warehouse.sdf`) or is
named on the command line. Every table is optional; a table left out changes nothing. docs/variation.md
describes each key; the shape, with the warehouse's values:

    [sun]                      # the world's <light> that is the sun, turned and dimmed
    light = "sun"
    elevation_deg = [35, 80]   # every range is [min, max], drawn uniformly
    azimuth_deg = [0, 360]
    intensity = [0.6, 1.3]     # times its <diffuse> and <specular>
    [ambient]
    scale = [0.7, 1.3]         # times the <scene>'s ambient
    [textures]
    tint = [0.85, 1.15]        # each surface kind's colour, per channel, times this
    [textures.kinds]           # albedo maps that may stand for each other (paths beside the profile)
    floor = ["textures/floor_a.jpg", "textures/floor_b.jpg"]
    [clutter]                  # models put on free floor, never in the aisles kept clear
    count = [6, 12]
    area = [-8.5, -6.0, 8.5, 8.0]           # xmin, ymin, xmax, ymax
    keep_clear = [[-10, -1.3, 10, 1.3]]     # rectangles, as area
    clearance = 0.3
    models = [{ uri = "model://carton", label = 20 }]
    [models.trolley]           # a model of the world moved from its pose (metres, degrees)
    x = [-0.4, 0.4]
    [people]                   # every <actor> with a script
    speed = [0.7, 1.3]         # times its script's pace
    reverse = 0.5              # chance of walking its loop the other way round
    shift = [-0.2, 0.2]        # metres, its whole route along x and along y
    phase = [0.0, 1.0]         # where in its loop it starts, a fraction of the loop's time
    [cameras]                  # every camera sensor of the world and the robot
    noise_stddev = [0.0, 0.02]

A mistake (an unknown table or key, a range whose min exceeds its max, a model or light the world
lacks, a file that is not there) is a `ProfileError`: one line naming the file and the key.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import tomllib

from simbot.description.errors import DescriptionError
from simbot.description.resources import resolve

SUFFIX = ".variation.toml"
"""A world's own profile: `<world>.variation.toml` beside `<world>.sdf`."""

Range = tuple[float, float]
Rect = tuple[float, float, float, float]


class ProfileError(DescriptionError):
    """A profile that cannot be used: names the file and the key."""


@dataclass(frozen=True)
class Sun:
    light: str
    elevation_deg: Range
    azimuth_deg: Range
    intensity: Range


@dataclass(frozen=True)
class ClutterModel:
    file: Path
    """The model's SDF."""
    label: int | None
    """Its label for segmentation and bounding-box cameras (Gazebo's Label system); None: none."""


@dataclass(frozen=True)
class Clutter:
    count: tuple[int, int]
    area: Rect
    models: tuple[ClutterModel, ...]
    keep_clear: tuple[Rect, ...] = ()
    clearance: float = 0.3


@dataclass(frozen=True)
class Moved:
    """A world model's pose offsets: x and y in metres, yaw in degrees."""

    x: Range = (0.0, 0.0)
    y: Range = (0.0, 0.0)
    yaw_deg: Range = (0.0, 0.0)


@dataclass(frozen=True)
class People:
    speed: Range = (1.0, 1.0)
    reverse: float = 0.0
    shift: Range = (0.0, 0.0)
    phase: Range = (0.0, 0.0)


@dataclass(frozen=True)
class Profile:
    path: Path
    sun: Sun | None = None
    ambient: Range | None = None
    tint: Range | None = None
    kinds: dict[str, tuple[Path, ...]] = field(default_factory=dict)
    """Surface kind → its albedo maps, resolved."""
    clutter: Clutter | None = None
    moved: dict[str, Moved] = field(default_factory=dict)
    people: People | None = None
    camera_noise: Range | None = None


TABLES = {
    "sun": {"light", "elevation_deg", "azimuth_deg", "intensity"},
    "ambient": {"scale"},
    "textures": {"tint", "kinds"},
    "clutter": {"count", "area", "keep_clear", "clearance", "models"},
    "models": None,
    "people": {"speed", "reverse", "shift", "phase"},
    "cameras": {"noise_stddev"},
}


def seed_option(text: str) -> tuple[int, Path | None]:
    """`--randomise SEED[:PROFILE]` (argparse type): a whole number ≥ 0, and the profile's file if given."""
    seed, _, profile = text.partition(":")
    if not seed.strip().isdigit():
        raise argparse.ArgumentTypeError(f"expected SEED[:PROFILE] with SEED a whole number >= 0, got {text!r}")
    return int(seed), Path(profile) if profile else None


def profile_beside(world: Path) -> Path:
    """Where a world's own profile lies."""
    return world.with_name(world.stem + SUFFIX)


def read_profile(path: Path) -> Profile:
    """The profile in `path`; ProfileError naming the file and key when it cannot be used."""
    if not path.is_file():
        raise ProfileError(path, "no such variation profile")
    try:
        data = tomllib.loads(path.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise ProfileError(path, f"not TOML: {exc}") from None
    _known(path, "", data, set(TABLES))
    for name, keys in TABLES.items():
        if name in data and keys is not None:
            _known(path, name, _table(path, name, data[name]), keys)
    return _Reader(path).profile(data)


def _known(path: Path, where: str, data: dict[str, Any], keys: set[str]) -> None:
    unknown = sorted(set(data) - keys)
    if unknown:
        raise ProfileError(path, f"unknown key {_key(where, unknown[0])} (known: {', '.join(sorted(keys))})")


def _table(path: Path, key: str, value: Any) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise ProfileError(path, f"{key}: expected a table, got {value!r}")
    return value


def _key(where: str, name: str) -> str:
    return f"{where}.{name}" if where else name


class _Reader:
    """Reads each table of one profile file, every error naming the file and the key."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def error(self, key: str, message: str) -> ProfileError:
        return ProfileError(self.path, f"{key}: {message}")

    def profile(self, data: dict[str, Any]) -> Profile:
        textures = data.get("textures", {})
        return Profile(
            path=self.path,
            sun=self.sun(data["sun"]) if "sun" in data else None,
            ambient=self.range("ambient.scale", data["ambient"], "scale", low=0.0) if "ambient" in data else None,
            tint=self.range("textures.tint", textures, "tint", low=0.0) if "tint" in textures else None,
            kinds=self.kinds(textures.get("kinds", {})),
            clutter=self.clutter(data["clutter"]) if "clutter" in data else None,
            moved={
                name: self.moved(name, value)
                for name, value in _table(self.path, "models", data.get("models", {})).items()
            },
            people=self.people(data["people"]) if "people" in data else None,
            camera_noise=self.range("cameras.noise_stddev", data["cameras"], "noise_stddev", low=0.0)
            if "cameras" in data
            else None,
        )

    def number(self, key: str, value: Any, low: float | None = None) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise self.error(key, f"expected a number, got {value!r}")
        if low is not None and value < low:
            raise self.error(key, f"must be at least {low:g}, got {value!r}")
        return float(value)

    def range(self, key: str, table: dict[str, Any], name: str, low: float | None = None) -> Range:
        """`[min, max]` (or one number: that value alone)."""
        if name not in table:
            raise self.error(key, "missing")
        value = table[name]
        if not isinstance(value, list):
            value = [value, value]
        if len(value) != 2:
            raise self.error(key, f"expected [min, max], got {value!r}")
        least, most = (self.number(key, v, low) for v in value)
        if least > most:
            raise self.error(key, f"min {least:g} > max {most:g}")
        return least, most

    def rect(self, key: str, value: Any) -> Rect:
        if not isinstance(value, list) or len(value) != 4:
            raise self.error(key, f"expected [xmin, ymin, xmax, ymax], got {value!r}")
        xmin, ymin, xmax, ymax = (self.number(key, v) for v in value)
        if xmin > xmax or ymin > ymax:
            raise self.error(key, f"min > max in {value!r}")
        return xmin, ymin, xmax, ymax

    def sun(self, table: dict[str, Any]) -> Sun:
        light = table.get("light", "sun")
        if not isinstance(light, str):
            raise self.error("sun.light", f"expected a light's name, got {light!r}")
        return Sun(
            light,
            self.range("sun.elevation_deg", table, "elevation_deg", low=0.0),
            self.range("sun.azimuth_deg", table, "azimuth_deg"),
            self.range("sun.intensity", table, "intensity", low=0.0),
        )

    def kinds(self, table: Any) -> dict[str, tuple[Path, ...]]:
        kinds: dict[str, tuple[Path, ...]] = {}
        for kind, files in _table(self.path, "textures.kinds", table).items():
            key = f"textures.kinds.{kind}"
            if not isinstance(files, list) or not files or not all(isinstance(f, str) for f in files):
                raise self.error(key, f"expected a list of image files, got {files!r}")
            kinds[kind] = tuple(self.file(key, name) for name in files)
        return kinds

    def file(self, key: str, uri: str) -> Path:
        found = resolve(uri, self.path.parent).path
        if found is None:
            raise self.error(key, f"{uri!r} not found")
        return found.resolve()

    def clutter(self, table: dict[str, Any]) -> Clutter:
        low, high = self.range("clutter.count", table, "count", low=0.0)
        if low != int(low) or high != int(high):
            raise self.error("clutter.count", f"expected whole numbers, got {table['count']!r}")
        models = table.get("models")
        if not isinstance(models, list) or not models:
            raise self.error("clutter.models", "expected a list of { uri = ..., label = ... }")
        keep = table.get("keep_clear", [])
        if not isinstance(keep, list):
            raise self.error("clutter.keep_clear", f"expected a list of rectangles, got {keep!r}")
        return Clutter(
            (int(low), int(high)),
            self.rect("clutter.area", table.get("area")),
            tuple(self.clutter_model(f"clutter.models[{i}]", entry) for i, entry in enumerate(models)),
            tuple(self.rect(f"clutter.keep_clear[{i}]", rect) for i, rect in enumerate(keep)),
            self.number("clutter.clearance", table.get("clearance", 0.3), low=0.0),
        )

    def clutter_model(self, key: str, entry: Any) -> ClutterModel:
        if not isinstance(entry, dict) or not isinstance(entry.get("uri"), str) or set(entry) - {"uri", "label"}:
            raise self.error(key, f"expected {{ uri = ..., label = ... }}, got {entry!r}")
        path = self.file(f"{key}.uri", entry["uri"])
        if path.is_dir():
            path = path / "model.sdf"
        if not path.is_file():
            raise self.error(f"{key}.uri", f"{entry['uri']!r} holds no model.sdf")
        label = entry.get("label")
        if label is not None and (isinstance(label, bool) or not isinstance(label, int) or not 0 <= label <= 255):
            raise self.error(f"{key}.label", f"expected a label from 0 to 255, got {label!r}")
        return ClutterModel(path, label)

    def moved(self, name: str, table: Any) -> Moved:
        key = f"models.{name}"
        table = _table(self.path, key, table)
        _known(self.path, key, table, {"x", "y", "yaw_deg"})
        return Moved(
            *(self.range(f"{key}.{axis}", table | {axis: table.get(axis, 0.0)}, axis) for axis in ("x", "y", "yaw_deg"))
        )

    def people(self, table: dict[str, Any]) -> People:
        reverse = self.number("people.reverse", table.get("reverse", 0.0), low=0.0)
        if reverse > 1.0:
            raise self.error("people.reverse", f"a chance from 0 to 1, got {reverse:g}")
        speed = self.range("people.speed", table | {"speed": table.get("speed", 1.0)}, "speed", low=0.0)
        if speed[0] <= 0.0:
            raise self.error("people.speed", f"must be above 0, got {speed[0]:g}")
        phase = self.range("people.phase", table | {"phase": table.get("phase", 0.0)}, "phase", low=0.0)
        if phase[1] > 1.0:
            raise self.error("people.phase", f"fractions of the loop from 0 to 1, got max {phase[1]:g}")
        return People(
            speed, reverse, self.range("people.shift", table | {"shift": table.get("shift", 0.0)}, "shift"), phase
        )
