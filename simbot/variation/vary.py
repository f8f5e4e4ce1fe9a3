"""A world drawn from its variation profile and a seed: the same seed, the same world, byte for byte.

`vary` returns new typed descriptions (the world and the robot), which the server loads as it loads
any world: nothing downstream knows a world was varied. The draws come from one NumPy generator
seeded with the seed, in a fixed order (sun, ambient, textures, moved models, people, clutter,
cameras), so adding clutter to a profile leaves the sun of every seed as it was.

- The sun: the profile's `<light>` (directional) turned to an elevation and azimuth and its
  intensity scaled; the scene's ambient scaled.
- Textures: every visual whose albedo map belongs to a surface kind takes one of the kind's maps,
  and its colour the kind's tint (one per kind and world, per channel).
- Models moved: a named model's pose offset in x, y and yaw.
- People: each actor's script paced (times divided by the speed factor), its loop walked the other
  way round at the profile's chance, started a drawn fraction of the way round its loop (the
  script's `played`, exact whatever the spline), its whole route shifted.
- Clutter: models placed on free floor (`clutter.py`).
- Cameras: each camera sensor's gaussian pixel noise.
"""

from __future__ import annotations

import functools
import logging
import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from simbot.description.actor_scripts import ActorModel, Trajectory, Waypoint
from simbot.description.model import Link, Material, Model, Param, Sensor, Visual, World
from simbot.description.poses import Pose
from simbot.variation.clutter import place_clutter
from simbot.variation.profile import Profile, ProfileError, Range

log = logging.getLogger(__name__)

NOISY_CAMERAS = {"camera", "rgbd", "rgbd_camera", "wideanglecamera", "wide_angle_camera"}
"""Sensor types whose `<camera><noise>` is pixel noise."""


@dataclass(frozen=True)
class Variant:
    """One drawn world: its seed, the descriptions to load, and the clutter's names."""

    seed: int
    world: World
    robot: Model | None
    clutter: tuple[str, ...] = ()


def vary(world: World, robot: Model | None, profile: Profile, seed: int) -> Variant:
    """The variant of `world` (and of the robot's cameras) that `seed` draws from `profile`."""
    check_profile(world, profile)
    rng = np.random.default_rng(seed)
    world = _lit(world, profile, rng)
    world = _textured(world, profile, rng)
    world = replace(world, models=tuple(_moved(model, profile, rng) for model in world.models))
    world = replace(world, models=tuple(_paced(model, profile, rng) for model in world.models))
    clutter = place_clutter(world, profile.clutter, rng) if profile.clutter is not None else ()
    world = replace(world, models=world.models + clutter)
    if profile.camera_noise is not None:
        noise = profile.camera_noise
        world = replace(world, models=tuple(_noisy(model, noise, rng) for model in world.models))
        robot = _noisy(robot, noise, rng) if robot is not None else None
    return Variant(seed, world, robot, tuple(model.name for model in clutter))


def check_profile(world: World, profile: Profile) -> None:
    """ProfileError naming the key when the profile names a light or model the world lacks."""
    names = {model.name for model in world.models}
    for name in profile.moved:
        if name not in names:
            raise ProfileError(profile.path, f"models.{name}: world {world.name!r} has no model {name!r}")
    if profile.sun is not None and not any(light.name == profile.sun.light for light in world.lights):
        raise ProfileError(profile.path, f"sun.light: world {world.name!r} has no light {profile.sun.light!r}")


def _uniform(rng: np.random.Generator, bounds: Range) -> float:
    return float(rng.uniform(bounds[0], bounds[1]))


def _lit(world: World, profile: Profile, rng: np.random.Generator) -> World:
    """The sun turned and dimmed, the ambient scaled."""
    if profile.sun is not None:
        sun = profile.sun
        elevation = math.radians(_uniform(rng, sun.elevation_deg))
        azimuth = math.radians(_uniform(rng, sun.azimuth_deg))
        gain = _uniform(rng, sun.intensity)
        travel = (
            -math.cos(elevation) * math.cos(azimuth),
            -math.cos(elevation) * math.sin(azimuth),
            -math.sin(elevation),
        )
        lights = tuple(
            replace(light, pose=Pose(light.pose.xyz), direction=travel, intensity=light.intensity * gain)
            if light.name == sun.light
            else light
            for light in world.lights
        )
        world = replace(world, lights=lights)
    if profile.ambient is not None:
        gain = _uniform(rng, profile.ambient)
        r, g, b, a = world.scene.ambient
        world = replace(
            world, scene=replace(world.scene, ambient=(min(1.0, r * gain), min(1.0, g * gain), min(1.0, b * gain), a))
        )
    return world


def _textured(world: World, profile: Profile, rng: np.random.Generator) -> World:
    """Each surface of a kind takes one of the kind's maps and the kind's tint."""
    if not profile.kinds:
        return world
    tints = {kind: rng.uniform(*(profile.tint or (1.0, 1.0)), size=3) for kind in sorted(profile.kinds)}
    kind_of = {path: kind for kind, paths in profile.kinds.items() for path in paths}

    def retexture(visual: Visual) -> Visual:
        material = visual.material
        if material is None or material.albedo_map is None:
            return visual
        kind = kind_of.get(_resolved(material.albedo_map))
        if kind is None:
            return visual
        maps = profile.kinds[kind]
        chosen = maps[int(rng.integers(len(maps)))]
        return replace(visual, material=_tinted(replace(material, albedo_map=chosen), tints[kind]))

    return replace(world, models=tuple(_each_visual(model, retexture) for model in world.models))


@functools.lru_cache(maxsize=4096)
def _resolved(path: Path) -> Path:
    """A texture's path as the profile's kinds name it, resolved once (each draw asks for every surface)."""
    return path.resolve()


def _tinted(material: Material, tint: np.ndarray) -> Material:
    def times(rgba: tuple[float, float, float, float] | None) -> tuple[float, float, float, float] | None:
        if rgba is None:
            return None
        r, g, b = (float(min(1.0, c * t)) for c, t in zip(rgba[:3], tint, strict=True))
        return (r, g, b, rgba[3])

    return replace(material, diffuse=times(material.diffuse), ambient=times(material.ambient))


def _each_visual(model: Model, change: Callable[[Visual], Visual]) -> Model:
    links = tuple(replace(link, visuals=tuple(change(v) for v in link.visuals)) for link in model.links)
    return replace(model, links=links)


def _moved(model: Model, profile: Profile, rng: np.random.Generator) -> Model:
    moved = profile.moved.get(model.name)
    if moved is None:
        return model
    dx, dy, dyaw = _uniform(rng, moved.x), _uniform(rng, moved.y), math.radians(_uniform(rng, moved.yaw_deg))
    (x, y, z), (roll, pitch, yaw) = model.pose.xyz, model.pose.rpy
    return replace(model, pose=Pose((x + dx, y + dy, z), (roll, pitch, yaw + dyaw)))


def _paced(model: Model, profile: Profile, rng: np.random.Generator) -> Model:
    """An actor's script at another pace, maybe the other way round, its route shifted."""
    people = profile.people
    if people is None or not isinstance(model, ActorModel) or not model.script.trajectories:
        return model
    speed = _uniform(rng, people.speed)
    backwards = bool(rng.random() < people.reverse)
    dx, dy = _uniform(rng, people.shift), _uniform(rng, people.shift)
    phase = _uniform(rng, people.phase)
    trajectories = tuple(_walked(t, speed, backwards) for t in model.script.trajectories)
    (x, y, z), rpy = model.pose.xyz, model.pose.rpy
    played = phase * sum(t.waypoints[-1].time for t in trajectories if t.waypoints) if model.script.loop else 0.0
    script = replace(model.script, trajectories=trajectories, played=played)
    return replace(model, pose=Pose((x + dx, y + dy, z), rpy), script=script)


def _walked(trajectory: Trajectory, speed: float, backwards: bool) -> Trajectory:
    """The trajectory `speed` times as fast; backwards: the same path the other way, facing the other way."""
    points = trajectory.waypoints
    if backwards and len(points) > 1:
        end = points[-1].time
        points = tuple(
            Waypoint(end - p.time, Pose(p.pose.xyz, (p.pose.rpy[0], p.pose.rpy[1], p.pose.rpy[2] + math.pi)))
            for p in reversed(points)
        )
    return replace(trajectory, waypoints=tuple(Waypoint(p.time / speed, p.pose) for p in points))


def _noisy(model: Model, stddev: Range, rng: np.random.Generator) -> Model:
    """Each camera sensor of the model with gaussian pixel noise of a drawn deviation."""

    def sensor(one: Sensor) -> Sensor:
        if one.type not in NOISY_CAMERAS:
            return one
        noise = Param(
            "noise",
            children=(Param("type", "gaussian"), Param("mean", "0"), Param("stddev", f"{_uniform(rng, stddev):.6g}")),
        )
        params = tuple(
            replace(p, children=tuple(c for c in p.children if c.tag != "noise") + (noise,)) if p.tag == "camera" else p
            for p in one.params
        )
        return replace(one, params=params)

    links: tuple[Link, ...] = tuple(
        replace(link, sensors=tuple(sensor(s) for s in link.sensors)) for link in model.links
    )
    joints = tuple(replace(joint, sensors=tuple(sensor(s) for s in joint.sensors)) for joint in model.joints)
    return replace(model, links=links, joints=joints)


@dataclass(frozen=True)
class Variations:
    """A world, its robot and a profile: every variant a seed draws (what a server's seeded reset loads)."""

    world: World
    robot: Model | None
    profile: Profile

    def draw(self, seed: int) -> Variant:
        return vary(self.world, self.robot, self.profile, seed)
