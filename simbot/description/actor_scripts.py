"""SDF `<actor>`: a skin, its animations, a script of trajectories, and links, read as Gazebo reads them.

An actor is a model that moves by itself, kinematically, along its script (gz-sim's actors). It is
read into an `ActorModel`: a `Model` (so the running world loads, poses, removes and creates it like
any other) that also carries the skin, the animations and the script. Its one root link `body`
holds the skin as its visual and a ray-visible collision proxy (placed by `proxy_pose`); the actor's
own `<link>`s hang from `body` by fixed joints at their SDF poses (relative to the actor's frame).
`<joint>`s inside an actor are not simulated: its links are held as they stand.

The proxy is an upright capsule the size of a standing adult (PROXY_RADIUS, PROXY_HEIGHT), its axis
on the actor frame's z axis. Its feet: at the skin's lowest point where the skin is found and
trimesh reads its bounds, else PROXY_FEET below the actor frame, where Gazebo's stock skins
(walk.dae, talk_b.dae: their root at the pelvis, placed at z = 1 in gz-sim's worlds) have theirs.
A skin that cannot be found is one warning naming the file (`missing_meshes`), and the actor is
drawn as its proxy, in PROXY_COLOUR. An actor with no skin has no proxy: its links are its body.

The script, as gz-sim reads it: `<loop>` (default true), `<delay_start>` (0 s), `<auto_start>`
(true), and `<trajectory id type tension>` (tension 0) of `<waypoint>`s, each a `<time>` and a
`<pose>` relative to the actor's frame. A waypoint before or at the time of the one before it, or
one without its time or pose, is an error naming the actor and the element (Gazebo sorts them
silently; here a script out of order is taken for the mistake it usually is).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from simbot.description.actor_legs import ActorRig
from simbot.description.missing_meshes import visuals_with_fallbacks
from simbot.description.model import Capsule, Collision, Joint, Link, Material, Mesh, Model, Plugin, Visual
from simbot.description.poses import Pose
from simbot.description.resources import resolve
from simbot.description.sdf_frames import read_pose
from simbot.description.skeleton_poses import ClipFile, load_rig
from simbot.description.skeletons import SkeletonError, read_skeleton
from simbot.description.stand_in_meshes import skinned_only
from simbot.description.xml import Element, Reader

logger = logging.getLogger(__name__)

BODY = "body"
"""The actor's root link: its skin and its proxy; the actor's own links hang from it."""
PROXY_RADIUS = 0.25
"""Metres: half a standing adult's shoulder width."""
PROXY_HEIGHT = 1.8
"""Metres, from the soles to the top of the head."""
PROXY_COLOUR = (0.95, 0.45, 0.05, 1.0)
"""A high-visibility orange: how a proxy is drawn where its skin cannot be found."""
PROXY_FEET = -1.0
"""Where the proxy's soles are in the actor frame when the skin's bounds are unknown (see the module docstring)."""


@dataclass(frozen=True)
class Waypoint:
    time: float
    """Seconds from the start of its trajectory's script time."""
    pose: Pose
    """Relative to the actor's frame (its `<pose>`)."""


@dataclass(frozen=True)
class Trajectory:
    id: int
    type: str
    """The animation it plays (an `<animation>`'s name)."""
    tension: float = 0.0
    """Of the position spline, clamped to 0..1 (gz-common's PoseAnimation)."""
    waypoints: tuple[Waypoint, ...] = ()


@dataclass(frozen=True)
class Script:
    loop: bool = True
    delay_start: float = 0.0
    auto_start: bool = True
    trajectories: tuple[Trajectory, ...] = ()
    played: float = 0.0
    """Seconds of the script already played at sim time zero: where in its loop the actor starts
    (a randomised world's starting phase, simbot.variation; SDF has no element for it, so 0 from a file)."""


@dataclass(frozen=True)
class Animation:
    name: str
    filename: str
    path: Path | None = None
    scale: float = 1.0
    interpolate_x: bool = False


@dataclass(frozen=True)
class Skin:
    filename: str
    path: Path | None = None
    scale: float = 1.0


@dataclass(frozen=True)
class SkinnedMesh(Mesh):
    """A skin with a skeleton: the cameras pose it as the frame's `body_skin_*` joints say
    (simbot.description.actor_legs), from these animations' clips."""

    animations: tuple[ClipFile, ...] = ()
    """Each `<animation>`'s file, `<interpolate_x>` and `<scale>`, in order; none: the bind pose."""


@dataclass(frozen=True)
class ActorModel(Model):
    """A model that moves along its script, kinematically: what `<actor>` reads into."""

    skin: Skin | None = None
    animations: tuple[Animation, ...] = ()
    script: Script = field(default_factory=Script)


def is_actor(model: Model) -> bool:
    """Whether `model` is an actor: the physics holds it kinematic, the actors system moves it."""
    return isinstance(model, ActorModel)


def read_actor(
    reader: Reader, element: Element, pose: Pose, links: tuple[Link, ...], plugins: tuple[Plugin, ...]
) -> ActorModel:
    """An `<actor>` whose `<link>`s and `<plugin>`s the SDF reader has read (it knows their frames)."""
    name = reader.attr(element, "name")
    skin = _read_skin(reader, element.find("skin"))
    animations = tuple(_read_animation(reader, name, e) for e in element.findall("animation"))
    rig = _rig(reader, name, skin, animations)
    body = _body(reader, skin) if rig is None else _animated_body(skin, animations, rig)  # type: ignore[arg-type]
    if any(link.name == BODY or link.name.startswith(f"{BODY}_") for link in links):
        raise reader.error(element, f"actor {name!r}: a link may not be named {BODY!r} or {BODY}_* (the actor's own)")
    legs = rig.links(BODY) if rig is not None else ((), ())
    joints = tuple(Joint(f"{BODY}_to_{link.name}", "fixed", BODY, link.name, link.pose) for link in links)
    return ActorModel(
        name=name,
        pose=pose,
        canonical_link=BODY,
        links=(body, *legs[0], *links),
        joints=(*legs[1], *joints),
        plugins=plugins,
        source=reader.file,
        skin=skin,
        animations=animations,
        script=_read_script(reader, name, element.find("script")),
    )


def _rig(reader: Reader, actor: str, skin: Skin | None, animations: tuple[Animation, ...]) -> ActorRig | None:
    """The skin's skeleton and clips with its legs found, where the skin has a skeleton and every
    animation is found and fits it; else None (the bind pose and one capsule), with a warning
    naming the actor and the element where there was a skeleton to read."""
    if skin is None or skin.path is None or not animations:
        return None
    missing = next((a for a in animations if a.path is None), None)
    if missing is not None:
        logger.warning(
            "%s: actor %r: <animation name=%r> %s is not found; the skin is drawn unanimated",
            reader.file,
            actor,
            missing.name,
            missing.filename,
        )
        return None
    try:
        rig = ActorRig.of(load_rig(skin.path, _clip_files(animations)), skin.scale)
    except SkeletonError as exc:
        logger.warning("%s: actor %r: <skin>/<animation>: %s; the skin is drawn unanimated", reader.file, actor, exc)
        return None
    if not rig.legs:
        logger.warning(
            "%s: actor %r: <skin> %s: no left and right leg found in its skeleton; one capsule is its proxy",
            reader.file,
            actor,
            skin.filename,
        )
    return rig


def _clip_files(animations: tuple[Animation, ...]) -> tuple[ClipFile, ...]:
    """The animations as the rig plays them (each found: `_rig` has checked)."""
    return tuple(ClipFile(a.path, a.interpolate_x, a.scale) for a in animations if a.path is not None)


def _animated_body(skin: Skin, animations: tuple[Animation, ...], rig: ActorRig) -> Link:
    """The root link of an animated actor: the skinned mesh, and the torso (the legs hang from it)."""
    visual = Visual("skin", SkinnedMesh(skin.filename, (skin.scale,) * 3, skin.path, _clip_files(animations)))
    if not rig.legs:
        proxy = Collision(
            "proxy",
            Capsule(PROXY_RADIUS, PROXY_HEIGHT - 2 * PROXY_RADIUS),
            Pose((0.0, 0.0, rig.lowest() + PROXY_HEIGHT / 2)),
        )
        return Link(BODY, collisions=(proxy,), visuals=(visual,))
    torso = rig.torso()
    return Link(BODY, collisions=() if torso is None else (torso,), visuals=(visual,))


def _read_skin(reader: Reader, element: Element | None) -> Skin | None:
    if element is None:
        return None
    filename = reader.text(element, "filename") or ""
    if not filename:
        raise reader.error(element, "missing required element <filename>")
    return Skin(filename, resolve(filename, reader.file.parent).path, reader.number(element, "scale", 1.0))


def _body(reader: Reader, skin: Skin | None) -> Link:
    """The root link: the skin (or, when it cannot be found, the proxy drawn) and the proxy."""
    if skin is None:
        return Link(BODY)
    proxy = Collision("proxy", Capsule(PROXY_RADIUS, PROXY_HEIGHT - 2 * PROXY_RADIUS), proxy_pose(skin))
    skin_visual = Visual("skin", _unposed(skin))
    if skin.path is not None:
        return Link(BODY, collisions=(proxy,), visuals=(skin_visual,))
    drawn = visuals_with_fallbacks(reader.file, BODY, [skin_visual], [proxy])  # one warning naming the file
    colour = Material(diffuse=PROXY_COLOUR, ambient=PROXY_COLOUR)
    return Link(BODY, collisions=(proxy,), visuals=tuple(replace(v, material=colour) for v in drawn))


def _unposed(skin: Skin) -> Mesh:
    """The skin drawn as it stands: a skinned-only COLLADA file (which mesh loaders read as nothing)
    as its skeleton's bind pose, a `SkinnedMesh` without animations."""
    scale = (skin.scale,) * 3
    if skin.path is not None and skinned_only(skin.path):
        return SkinnedMesh(skin.filename, scale, skin.path)
    return Mesh(skin.filename, scale, skin.path)


def proxy_pose(skin: Skin) -> Pose:
    """The proxy capsule's centre in the actor frame: its soles on the skin's lowest point, or at PROXY_FEET."""
    feet = _lowest_point(skin)
    return Pose((0.0, 0.0, (PROXY_FEET if feet is None else feet) + PROXY_HEIGHT / 2))


def _lowest_point(skin: Skin) -> float | None:
    """The skin's lowest z in the actor frame (scaled), None when it is not found or cannot be read
    (a skinned-only COLLADA by its skeleton's bind pose, any other by trimesh)."""
    if skin.path is None:
        return None
    if skinned_only(skin.path):
        try:
            return min(float(p.positions[:, 2].min()) for p in read_skeleton(skin.path).parts) * skin.scale
        except SkeletonError:
            return None
    try:
        import trimesh

        loaded: Any = trimesh.load(skin.path, force="scene")
        bounds = loaded.bounds
    except Exception as exc:  # noqa: BLE001 - trimesh raises many kinds for a file it cannot read
        logger.warning(
            "%s: skin %s: its bounds cannot be read (%s); the proxy stands at the default height",
            skin.path,
            skin.filename,
            exc,
        )
        return None
    if bounds is None or not math.isfinite(float(bounds[0][2])):
        return None
    return float(bounds[0][2]) * skin.scale


def _read_animation(reader: Reader, actor: str, element: Element) -> Animation:
    filename = reader.text(element, "filename") or ""
    if not filename:
        raise reader.error(element, f"actor {actor!r}: missing required element <filename>")
    return Animation(
        name=reader.attr(element, "name"),
        filename=filename,
        path=resolve(filename, reader.file.parent).path,
        scale=reader.number(element, "scale", 1.0),
        interpolate_x=reader.flag(element, "interpolate_x", False),
    )


def _read_script(reader: Reader, actor: str, element: Element | None) -> Script:
    if element is None:
        return Script()
    delay = reader.number(element, "delay_start", 0.0)
    if not delay >= 0 or not math.isfinite(delay):
        raise reader.error(element.find("delay_start"), f"actor {actor!r}: delay_start must be 0 or more, got {delay}")
    return Script(
        loop=reader.flag(element, "loop", True),
        delay_start=delay,
        auto_start=reader.flag(element, "auto_start", True),
        trajectories=tuple(_read_trajectory(reader, actor, e) for e in element.findall("trajectory")),
    )


def _read_trajectory(reader: Reader, actor: str, element: Element) -> Trajectory:
    ident = reader.attr(element, "id")
    if not ident.lstrip("-").isdigit():
        raise reader.error(element, f"actor {actor!r}: trajectory id must be a whole number, got {ident!r}")
    try:
        tension = float(element.get("tension", "0"))
    except ValueError:
        raise reader.error(
            element, f"actor {actor!r}: tension must be a number, got {element.get('tension')!r}"
        ) from None
    waypoints: list[Waypoint] = []
    for point in element.findall("waypoint"):
        waypoint = _read_waypoint(reader, actor, point)
        if waypoints and not waypoint.time > waypoints[-1].time:
            raise reader.error(
                point,
                f"actor {actor!r}: trajectory {ident}: waypoint at time {waypoint.time:g} s is not after the one "
                f"before it ({waypoints[-1].time:g} s): waypoints must be in time order",
            )
        waypoints.append(waypoint)
    if not waypoints:
        raise reader.error(element, f"actor {actor!r}: trajectory {ident} has no <waypoint>")
    return Trajectory(int(ident), reader.attr(element, "type"), min(max(tension, 0.0), 1.0), tuple(waypoints))


def _read_waypoint(reader: Reader, actor: str, element: Element) -> Waypoint:
    for tag in ("time", "pose"):
        if element.find(tag) is None:
            raise reader.error(element, f"actor {actor!r}: waypoint without its <{tag}>")
    time = reader.required_number(element, "time")
    if not math.isfinite(time) or time < 0:
        raise reader.error(element.find("time"), f"actor {actor!r}: waypoint time must be 0 or more, got {time}")
    return Waypoint(time, read_pose(reader, element)[0])
