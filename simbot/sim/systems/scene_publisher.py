"""`scene`: the world's visuals for viewers, so that RViz and Foxglove draw the warehouse around the scans.

A world system (built in, no `<plugin>`). Every visual of every model is one
visualization_msgs/Marker of one latched MarkerArray on `scene` (late joiners get it, as they get
`robot_description`): its pose, its size, its colour (the SDF material's diffuse, else ambient,
else white as PyBullet draws it; alpha one minus the visual's transparency). Boxes are CUBEs,
cylinders CYLINDERs, spheres and ellipsoids SPHEREs, capsules the CYLINDER that holds them, planes
a CUBE 1 mm thick; meshes are MESH_RESOURCEs naming the file by its `file://` URI (as
`robot_description` does: RViz on this machine loads it, `simbot foxglove` serves it to the app),
drawn with their own materials and textures when the visual has no material. A mesh that did not
resolve is named as written: loading it is the viewer's business. Cones, polylines and heightmaps
have no marker type and are left out (logged once).

Each marker's namespace is its model, its id the visual's place in the model; the array starts
with DELETEALL, so each message is the whole scene and a removed model's markers leave with it.

Moving models (the trolley, created tugs, actors): their markers are in a frame of their own,
`scene/<model>` (the model frame), which goes on `tf` (`world` → `scene/<model>`) at
SCENE_TF_RATE. The other way, markers re-published for them, would re-send whole markers (a
MarkerArray is the whole scene for a late joiner, so all of it) many times a second; a transform
is 60 bytes, the viewers already interpolate tf, and the scene message changes only when a model
comes or goes. A visual is placed in its model's frame by the description (its link's pose, then
its own), so a moving model's jointed parts (a tug's wheels) are drawn where they are at zero
joint positions: the robot's own moving joints are on tf already, for its robot_description. For
each drive's odometry frame (`odom`), tf also carries `world` → `odom`: where the model stood
when dead reckoning began (its entry, or the last reset), so a scan drawn in `odom` lies over the
walls of `world`, drifting off them as odometry drifts, as RViz shows it without a localiser.

Cost: post_update reads model poses (the physics' base pose, no forward kinematics: reading
never perturbs the simulation, which a seeded run's digests check) only at SCENE_TF_RATE, and
only while someone subscribes to `tf` (a fleet's thousand frames are built for no one else); the
scene is rebuilt at most once per step in which models came or went, and its encoding (tens of
ms for the warehouse's 220 visuals) and put happen on a sender thread, never in the physics loop.
"""

from __future__ import annotations

import functools
import logging
import math
from dataclasses import dataclass
from typing import Any

from simbot.bus import messages
from simbot.description.model import Box, Capsule, Cylinder, Ellipsoid, Geometry, Mesh, Plane, Sphere, Visual
from simbot.description.naming import scoped_key
from simbot.description.poses import Pose
from simbot.sim.kit.latest_sender import LatestSender
from simbot.sim.kit.rates import Every
from simbot.sim.loop.system import ModelEvent, SystemContext, UpdateInfo
from simbot.sim.physics import WorldReader, pose_to_transform
from simbot.transform import Transform

log = logging.getLogger(__name__)

SCENE_TOPIC = "scene"
WORLD_FRAME = "world"
SCENE_TF_RATE = 10.0
"""Hz of sim time: the moving models' frames; a viewer interpolates between them."""
PLANE_THICKNESS = 0.001
WHITE = (1.0, 1.0, 1.0, 1.0)
Shape = tuple[int, tuple[float, float, float], str]
"""A marker type, its scale and its mesh URI."""


@dataclass(frozen=True)
class Part:
    """One visual as a marker: its shape, its pose in `frame`, its colour."""

    model: str
    index: int
    frame: str
    shape: Shape
    pose: Transform
    rgba: tuple[float, float, float, float]

    @functools.cached_property
    def _marker(self) -> Any:
        kind, scale, mesh = self.shape
        return messages.marker(0, self.frame, self.model, self.index, kind, *self.pose, scale, self.rgba, mesh)

    def marker(self, stamp: Any) -> Any:
        """The part's marker with the header `stamp` (its frame at the scene's time): built once,
        stamped anew each time the scene is sent (a fleet's scene is thousands of markers)."""
        return messages.restamped(self._marker, stamp)


def shape_of(geometry: Geometry) -> Shape | None:
    """The marker type and scale of an SDF geometry; None for shapes no marker type draws."""
    match geometry:
        case Box(size=size):
            return messages.Marker.CUBE, size, ""
        case Cylinder(radius=r, length=length):
            return messages.Marker.CYLINDER, (2 * r, 2 * r, length), ""
        case Capsule(radius=r, length=length):
            return messages.Marker.CYLINDER, (2 * r, 2 * r, length + 2 * r), ""
        case Sphere(radius=r):
            return messages.Marker.SPHERE, (2 * r, 2 * r, 2 * r), ""
        case Ellipsoid(radii=(a, b, c)):
            return messages.Marker.SPHERE, (2 * a, 2 * b, 2 * c), ""
        case Plane(size=(sx, sy)):
            return messages.Marker.CUBE, (sx, sy, PLANE_THICKNESS), ""
        case Mesh(uri=uri, scale=scale, path=path):
            return messages.Marker.MESH_RESOURCE, scale, path.resolve().as_uri() if path is not None else uri
    return None


def plane_turn(geometry: Geometry) -> Pose:
    """A plane's normal as the turn of the thin box that draws it (identity for every other shape)."""
    if not isinstance(geometry, Plane):
        return Pose()
    nx, ny, nz = geometry.normal
    norm = math.sqrt(nx * nx + ny * ny + nz * nz) or 1.0
    return Pose(rpy=(0.0, math.acos(max(-1.0, min(1.0, nz / norm))), math.atan2(ny, nx)))


def colour_of(visual: Visual, shape: Shape) -> tuple[float, float, float, float]:
    """The material's colour, white without one; a mesh without a material of its own draws its own."""
    material = visual.material
    colour = material.color() if material is not None else None
    if colour is None:
        return messages.NO_COLOUR if shape[0] == messages.Marker.MESH_RESOURCE else WHITE
    r, g, b, a = colour
    return (r, g, b, a * (1.0 - visual.transparency))


def model_frame(body: str) -> str:
    """The tf frame a moving body draws its markers in."""
    return f"scene/{scoped_key(body)}"


def body_parts(physics: WorldReader, body: str, skipped: set[str]) -> list[Part]:
    """A body's visuals as parts: in `world` for a static body, in its own frame for a moving one."""
    model = physics.model_of(body)
    frame = WORLD_FRAME if model.static else model_frame(body)
    origin = Pose.from_transform(physics.model_pose(body)) if model.static else Pose()
    parts: list[Part] = []
    for link in model.links:
        for visual in link.visuals:
            shape = shape_of(visual.geometry)
            if shape is None:
                _skip(skipped, type(visual.geometry).__name__)
                continue
            pose = pose_to_transform(origin @ link.pose @ visual.pose @ plane_turn(visual.geometry))
            parts.append(Part(scoped_key(body), len(parts), frame, shape, pose, colour_of(visual, shape)))
    return parts


def _skip(skipped: set[str], kind: str) -> None:
    if kind not in skipped:
        skipped.add(kind)
        log.info("scene: a %s visual has no marker type; left out", kind.lower())


def odometry_frames(event: ModelEvent) -> list[tuple[str, str]]:
    """(odometry frame, child frame) of each drive of the model, as it publishes them (a fleet's
    robots prefixed with their namespaces): the systems with `odometry_frames` (DiffDrive,
    AckermannSteering, MecanumDrive)."""
    found = []
    for system in event.systems:
        frames = getattr(system, "odometry_frames", None)
        if isinstance(frames, tuple) and len(frames) == 2:
            found.append(frames)
    return found


class ScenePublisher:
    """Keeps `scene` and the moving models' frames current; see the module docstring."""

    name = "ScenePublisher"

    def __init__(self, ctx: SystemContext) -> None:
        self._physics = ctx.physics
        publisher = ctx.bus.publisher(SCENE_TOPIC, messages.MarkerArray, latched=True)
        self._sender = LatestSender(publisher, at_once=ctx.options.lockstep)
        self._tf = ctx.bus.publisher("tf", messages.TFMessage)
        self._parts: dict[str, list[Part]] = {}
        self._moving: list[str] = []
        """The bodies whose frames tf places."""
        self._odometry: dict[str, list[tuple[str, str]]] = {}
        """Per model: (odometry frame, child frame) of each of its drives."""
        self._anchors: dict[str, Transform] = {}
        """world → odometry frame, by frame."""
        self._skipped: set[str] = set()
        self._changed = False
        self._every = Every.hz(SCENE_TF_RATE)

    def model_added(self, event: ModelEvent) -> None:
        for body in event.bodies:
            self._parts[body] = body_parts(self._physics, body, self._skipped)
            if not self._physics.model_of(body).static:
                self._moving.append(body)
        if drives := odometry_frames(event):
            self._odometry[event.name] = drives
            self._anchor(event.name)
        self._changed = True

    def model_removed(self, event: ModelEvent) -> None:
        for body in event.bodies:
            self._parts.pop(body, None)
            if body in self._moving:
                self._moving.remove(body)
        for frame, _ in self._odometry.pop(event.name, []):
            self._anchors.pop(frame, None)
        self._changed = True

    def _anchor(self, model: str) -> None:
        """Each odometry frame of `model` where its child frame is now (dead reckoning starts here)."""
        links = {link.name: link.pose for link in self._physics.model_of(model).links}
        here = Pose.from_transform(self._physics.model_pose(model))
        for frame, child in self._odometry[model]:
            self._anchors[frame] = pose_to_transform(here @ links.get(child.rpartition("/")[2], Pose()))

    def post_update(self, info: UpdateInfo) -> None:
        if self._changed:
            self._changed = False
            now_ns = info.sim_time_ns
            frames = {part.frame for parts in self._parts.values() for part in parts}
            stamps = {frame: messages.header(now_ns, frame) for frame in frames}
            markers = [part.marker(stamps[part.frame]) for parts in self._parts.values() for part in parts]
            self._sender.send(messages.marker_array([messages.delete_all(info.sim_time_ns, WORLD_FRAME), *markers]))
        if self._every.due(info.sim_time_ns) and (self._moving or self._anchors) and self._tf.has_subscribers:
            self._tf.put(messages.tf_message(self._transforms(info.sim_time_ns)))

    def _transforms(self, now_ns: int) -> list[Any]:
        poses = [(model_frame(body), self._physics.model_pose(body)) for body in self._moving]
        poses += list(self._anchors.items())
        return [messages.transform_stamped(now_ns, WORLD_FRAME, frame, *pose) for frame, pose in poses]

    def reset(self, info: UpdateInfo) -> None:
        """Odometry starts again where each model stands now."""
        for model in self._odometry:
            self._anchor(model)
        self._every.restart()

    def close(self) -> None:
        self._sender.close()
        self._tf.close()
