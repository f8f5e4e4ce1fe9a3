"""SDF 1.4–1.11 models and worlds into the plain data of simbot.description.model.

Poses follow SDF's frame semantics: a link's pose is relative to the model frame, a joint's
to its child link, a `<frame>`'s to what it is attached to, and `relative_to` (or the older
`frame` attribute) may name any of these frames. What a link holds (inertial, collisions,
visuals, sensors) is placed in the link frame. A link without `<inertial>` is massless here,
as robot descriptions mean it (SDF's own default of 1 kg would be a surprise on `base_footprint`).

A model nested in a model (inline or included, SDF 1.7+) is flattened into its parent: its
links and joints become the parent's under scoped names (`nested::link`), placed by the frame
graph, so a parent's joint may join `nested::link` (or `nested`, meaning its canonical link).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from simbot.description.actor_scripts import read_actor
from simbot.description.errors import DescriptionError
from simbot.description.missing_meshes import present_collisions, visuals_with_fallbacks
from simbot.description.model import (
    EARTH_MAGNETIC_FIELD,
    Axis,
    Collision,
    Inertial,
    Joint,
    Link,
    Model,
    Param,
    Plugin,
    SdfLight,
    Sensor,
    Visual,
    World,
)
from simbot.description.poses import Pose
from simbot.description.resources import resolve
from simbot.description.sdf_elements import (
    model_file,
    read_atmosphere,
    read_friction,
    read_geometry,
    read_light,
    read_material,
    read_physics,
    read_scene,
    read_spherical_coordinates,
    version_key,
)
from simbot.description.sdf_frames import MODEL_FRAME, Frames, read_pose
from simbot.description.xml import Element, Reader, parse_file, sdf_tag
from simbot.transform import matmul, rpy_to_matrix

logger = logging.getLogger(__name__)

SUPPORTED_VERSIONS = ((1, 4), (1, 11))
JOINT_TYPES = ("fixed", "revolute", "continuous", "prismatic", "ball")
UNLIMITED = 1e16
"""SDF writes an unlimited joint as ±1e16 (or more); such limits become None."""
FRAME_ID_TAGS = ("frame_name", "gz_frame_id", "ignition_frame_id", "frameName")


def load_sdf(path: Path | str) -> Model | World:
    """The world or the (first) model of an SDF file."""
    path = Path(path)
    root = parse_file(path)
    reader = Reader(path)
    version = _check_version(reader, root)
    world = root.find("world")
    if world is not None:
        return _read_world(reader, version, world)
    found = root.find("model") if root.find("model") is not None else root.find("actor")
    if found is None:
        raise reader.error(root, "no <world>, <model> or <actor> in this SDF file")
    return _read_model(reader, version, found) if found.tag == "model" else _read_actor(reader, found)


def load_model(path: Path | str) -> Model:
    """The model of an SDF model file (a world file is an error here)."""
    loaded = load_sdf(path)
    if not isinstance(loaded, Model):
        raise DescriptionError(path, "expected an SDF <model>, found a <world>")
    return loaded


def load_world(path: Path | str) -> World:
    """The world of an SDF world file (a model file is an error here)."""
    loaded = load_sdf(path)
    if not isinstance(loaded, World):
        raise DescriptionError(path, "expected an SDF <world>, found a <model>")
    return loaded


def _check_version(reader: Reader, root: Element) -> tuple[int, int]:
    if root.tag != "sdf":
        raise reader.error(root, "not an SDF file: the root element must be <sdf>")
    text = reader.attr(root, "version")
    version = version_key(text)
    if len(version) != 2:
        raise reader.error(root, f"malformed version {text!r}")
    low, high = SUPPORTED_VERSIONS
    if not low <= version <= high:
        raise reader.error(root, f"unsupported SDF version {text} (supported: 1.4 to 1.11)")
    return (version[0], version[1])


# ---------------------------------------------------------------- models


def _read_model(reader: Reader, version: tuple[int, int], element: Element) -> Model:
    name = reader.attr(element, "name")
    pose, _ = read_pose(reader, element)
    link_elements = element.findall("link")
    nested = _read_nested(reader, version, element)
    if not link_elements and not nested:
        raise reader.error(element, f"model {name!r} has no <link>")
    frames = _model_frames(reader, element, link_elements, nested)
    own = tuple(_read_link(reader, frames, e) for e in link_elements)
    links = own + tuple(link for n in nested for link in n.links(frames))
    joint_ends = {link.name: link.name for link in links} | {n.name: n.scoped(n.model.canonical_link) for n in nested}
    joints = tuple(_read_joint(reader, version, frames, e, joint_ends) for e in element.findall("joint"))
    joints += tuple(joint for n in nested for joint in n.joints(frames))
    canonical = element.get("canonical_link") or (
        own[0].name if own else nested[0].scoped(nested[0].model.canonical_link)
    )
    if canonical not in joint_ends:
        raise reader.error(element, f"canonical_link {canonical!r} is not a link of model {name!r}")
    return Model(
        name=name,
        pose=pose,
        static=reader.flag(element, "static", False),
        canonical_link=joint_ends[canonical],
        links=links,
        joints=joints,
        plugins=tuple(_read_plugin(reader, e) for e in element.findall("plugin")),
        source=reader.file,
    )


@dataclass(frozen=True)
class _Nested:
    """A model inside a model (SDF 1.7+), flattened into its parent: its links, joints and frames
    take the scoped names `NAME::link`, as the parent's joints and plugins refer to them."""

    model: Model
    element: Element
    relative_to: str | None

    @property
    def name(self) -> str:
        return self.model.name

    def scoped(self, inner: str) -> str:
        return f"{self.name}::{inner}"

    def add_frames(self, frames: Frames) -> None:
        """The nested model's frame, and its links and joints relative to it."""
        frames.add(self.name, self.model.pose, self.relative_to or MODEL_FRAME, self.element)
        for inner, pose in [(link.name, link.pose) for link in self.model.links] + [
            (j.name, j.pose) for j in self.model.joints
        ]:
            frames.add(self.scoped(inner), pose, self.name, self.element)

    def links(self, frames: Frames) -> list[Link]:
        return [
            replace(link, name=self.scoped(link.name), pose=frames.in_model(self.scoped(link.name), self.element))
            for link in self.model.links
        ]

    def joints(self, frames: Frames) -> list[Joint]:
        return [
            replace(
                joint,
                name=self.scoped(joint.name),
                parent=joint.parent if joint.parent == "world" else self.scoped(joint.parent),
                child=self.scoped(joint.child),
                pose=frames.in_model(self.scoped(joint.name), self.element),
            )
            for joint in self.model.joints
        ]


def _read_nested(reader: Reader, version: tuple[int, int], model: Element) -> list[_Nested]:
    """The models nested in `model`, inline or included. simbot flattens them, so a nested model's
    plugins go to its visuals (`Visual.plugins`, before each visual's own): a Label or Thermal
    there covers the nested model's visuals; the world runs no other plugin of a visual (a warning
    says so)."""
    nested = []
    for element in model:
        if element.tag not in ("model", "include"):
            continue
        inner = _read_model(reader, version, element) if element.tag == "model" else _read_include(reader, element)
        nested.append(_Nested(_plugins_to_visuals(inner), element, read_pose(reader, element)[1]))
    return nested


def _plugins_to_visuals(model: Model) -> Model:
    if not model.plugins:
        return model
    links = tuple(
        replace(link, visuals=tuple(replace(v, plugins=model.plugins + v.plugins) for v in link.visuals))
        for link in model.links
    )
    return replace(model, links=links, plugins=())


def _model_frames(reader: Reader, model: Element, links: list[Element], nested: list[_Nested]) -> Frames:
    frames = Frames(reader)
    for link in links:
        pose, relative_to = read_pose(reader, link)
        frames.add(reader.attr(link, "name"), pose, relative_to or MODEL_FRAME, link)
    for inner in nested:
        inner.add_frames(frames)
    for joint in model.findall("joint"):
        pose, relative_to = read_pose(reader, joint)
        child = reader.text(joint, "child")
        if child is None:
            raise reader.error(joint, "missing required element <child>")
        frames.add(reader.attr(joint, "name"), pose, relative_to or child, joint)
    for frame in model.findall("frame"):
        pose, relative_to = read_pose(reader, frame)
        attached_to = frame.get("attached_to") or MODEL_FRAME
        frames.add(reader.attr(frame, "name"), pose, relative_to or attached_to, frame)
    return frames


def _read_link(reader: Reader, frames: Frames, element: Element) -> Link:
    name = reader.attr(element, "name")
    collisions = [_read_collision(reader, frames, name, e) for e in element.findall("collision")]
    collisions = present_collisions(reader.file, name, collisions)
    visuals = [_read_visual(reader, frames, name, e) for e in element.findall("visual")]
    return Link(
        name=name,
        pose=frames.in_model(name, element),
        inertial=_read_inertial(reader, element.find("inertial")),
        collisions=tuple(collisions),
        visuals=tuple(visuals_with_fallbacks(reader.file, name, visuals, collisions)),
        sensors=tuple(_read_sensor(reader, frames, name, e) for e in element.findall("sensor")),
    )


def _read_inertial(reader: Reader, element: Element | None) -> Inertial | None:
    if element is None:
        return None
    mass = reader.number(element, "mass", 1.0)
    if not mass > 0 or not math.isfinite(mass):
        raise reader.error(element, f"mass must be positive, got {mass}")
    inertia = element.find("inertia")
    tags = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
    defaults = (1.0, 0.0, 0.0, 1.0, 0.0, 1.0)
    values = defaults if inertia is None else tuple(reader.number(inertia, t, d) for t, d in zip(tags, defaults))
    return Inertial(mass=mass, pose=read_pose(reader, element)[0], inertia=values)  # type: ignore[arg-type]


def _read_collision(reader: Reader, frames: Frames, link: str, element: Element) -> Collision:
    return Collision(
        reader.attr(element, "name"),
        read_geometry(reader, element),
        frames.in_link(link, element),
        read_friction(reader, element),
    )


def _read_visual(reader: Reader, frames: Frames, link: str, element: Element) -> Visual:
    material = element.find("material")
    return Visual(
        name=reader.attr(element, "name"),
        geometry=read_geometry(reader, element),
        pose=frames.in_link(link, element),
        material=None if material is None else read_material(reader, material),
        transparency=reader.number(element, "transparency", 0.0),
        cast_shadows=reader.flag(element, "cast_shadows", True),
        plugins=tuple(_read_plugin(reader, e) for e in element.findall("plugin")),
    )


# ---------------------------------------------------------------- joints


def _read_joint(
    reader: Reader, version: tuple[int, int], frames: Frames, element: Element, ends: dict[str, str]
) -> Joint:
    """`ends` maps each name a joint may join (a link, or a nested model: its canonical link) to the link."""
    name = reader.attr(element, "name")
    kind = reader.attr(element, "type")
    if kind not in JOINT_TYPES:
        raise reader.error(
            element, f"unsupported joint type {kind!r} for joint {name!r} (supported: {', '.join(JOINT_TYPES)})"
        )
    parent = reader.text(element, "parent") or ""
    child = reader.text(element, "child") or ""
    for role, link in (("parent", parent), ("child", child)):
        if link not in ends and not (role == "parent" and link == "world"):
            raise reader.error(
                reader.child(element, role), f"joint {name!r}: {role} {link!r} is not a link of this model"
            )
    parent, child = ends.get(parent, parent), ends[child]
    pose = frames.in_model(name, element)
    axis = element.find("axis")
    needs_axis = kind in ("revolute", "continuous", "prismatic")
    if axis is None and needs_axis:
        raise reader.error(element, f"joint {name!r} of type {kind} needs an <axis>")
    return Joint(
        name,
        kind,
        parent,
        child,
        pose,
        _read_axis(reader, version, frames, pose, axis) if needs_axis else None,
        tuple(_read_sensor(reader, frames, child, e, relative_to=name) for e in element.findall("sensor")),
    )


def _read_axis(reader: Reader, version: tuple[int, int], frames: Frames, joint_pose: Pose, axis: Element) -> Axis:
    xyz_element = reader.child(axis, "xyz")
    xyz = np.asarray(reader.floats(xyz_element, 3))
    if not (xyz**2).sum() > 0:
        raise reader.error(xyz_element, "axis must not be zero")
    expressed_in = xyz_element.get("expressed_in")
    if version < (1, 7) and reader.flag(axis, "use_parent_model_frame", False):
        expressed_in = MODEL_FRAME
    if expressed_in:
        frame = frames.in_model(expressed_in, xyz_element)
        xyz = matmul(matmul(rpy_to_matrix(joint_pose.rpy).T, rpy_to_matrix(frame.rpy)), xyz)
    xyz = xyz / (xyz**2).sum() ** 0.5
    limit = axis.find("limit")
    dynamics = axis.find("dynamics")

    def bound(tag: str) -> float | None:
        value = None if limit is None else reader.number(limit, tag, UNLIMITED)
        return None if value is None or abs(value) >= UNLIMITED else value

    def positive(tag: str) -> float | None:
        value = None if limit is None else reader.number(limit, tag, -1.0)
        return value if value is not None and value >= 0 else None

    return Axis(
        xyz=tuple(float(v) for v in xyz),  # type: ignore[arg-type]
        lower=bound("lower"),
        upper=bound("upper"),
        effort=positive("effort"),
        velocity=positive("velocity"),
        damping=0.0 if dynamics is None else reader.number(dynamics, "damping", 0.0),
        friction=0.0 if dynamics is None else reader.number(dynamics, "friction", 0.0),
    )


# ---------------------------------------------------------------- sensors and plugins


def _read_sensor(reader: Reader, frames: Frames, link: str, element: Element, relative_to: str | None = None) -> Sensor:
    """The fields every sensor has; the rest kept whole for the sensor's own module to read. Posed in
    `link`'s frame; its `<pose>` is relative to `relative_to` (a joint's sensor: the joint) by default."""
    frame_name = next((reader.text(element, tag) for tag in FRAME_ID_TAGS if element.find(tag) is not None), None)
    return Sensor(
        name=reader.attr(element, "name"),
        type=reader.attr(element, "type"),
        pose=frames.in_link(link, element, relative_to),
        update_rate=reader.number(element, "update_rate", 0.0),
        always_on=reader.flag(element, "always_on", False),
        topic=reader.text(element, "topic"),
        frame_name=frame_name,
        params=tuple(_read_param(child) for child in element),
    )


def _read_param(element: Element) -> Param:
    return Param(
        tag=sdf_tag(element),
        text=(element.text or "").strip(),
        attrs=tuple(sorted((str(k), str(v)) for k, v in element.attrib.items())),
        children=tuple(_read_param(child) for child in element),
    )


def _read_plugin(reader: Reader, element: Element) -> Plugin:
    return Plugin(
        name=reader.attr(element, "name"),
        filename=element.get("filename", "").strip(),
        params=tuple(_read_param(child) for child in element),
    )


# ---------------------------------------------------------------- worlds


def _read_world(reader: Reader, version: tuple[int, int], element: Element) -> World:
    models = [_read_model(reader, version, e) for e in element.findall("model")]
    models += [_read_include(reader, e) for e in element.findall("include")]
    models += [_read_actor(reader, e) for e in element.findall("actor")]
    seen: set[str] = set()
    for model in models:
        if model.name in seen:
            raise reader.error(element, f"two models are named {model.name!r}")
        seen.add(model.name)
    physics = read_physics(reader, element)
    gravity = reader.vector(element, "gravity", 3)
    return World(
        name=reader.attr(element, "name"),
        physics=physics,
        gravity=gravity or (0.0, 0.0, -9.8),  # type: ignore[arg-type]
        scene=read_scene(reader, element.find("scene")),
        lights=tuple(_read_light(reader, e) for e in element.findall("light")),
        models=tuple(models),
        plugins=tuple(_read_plugin(reader, e) for e in element.findall("plugin")),
        source=reader.file,
        spherical_coordinates=read_spherical_coordinates(reader, element.find("spherical_coordinates")),
        magnetic_field=reader.vector(element, "magnetic_field", 3, EARTH_MAGNETIC_FIELD),  # type: ignore[arg-type]
        atmosphere=read_atmosphere(reader, element.find("atmosphere")),
    )


def _read_light(reader: Reader, element: Element) -> SdfLight:
    return replace(read_light(reader, element), pose=read_pose(reader, element)[0])


def _read_actor(reader: Reader, element: Element) -> Model:
    """An `<actor>` (simbot.description.actor_scripts): its links framed as a model's are, relative to the actor."""
    links = element.findall("link")
    frames = _model_frames(reader, element, links, [])
    plugins = tuple(_read_plugin(reader, e) for e in element.findall("plugin"))
    own = tuple(_read_link(reader, frames, e) for e in links)
    return read_actor(reader, element, read_pose(reader, element)[0], own, plugins)


def _read_include(reader: Reader, element: Element) -> Model:
    uri_element = reader.child(element, "uri")
    uri = (uri_element.text or "").strip()
    resolution = resolve(uri, reader.file.parent)
    if resolution.path is None:
        raise reader.error(uri_element, f"cannot resolve {uri!r} (tried {resolution.describe_tried()})")
    model = load_model(model_file(reader, element, resolution.path))
    pose_element = element.find("pose")
    return replace(
        model,
        name=reader.text(element, "name") or model.name,
        pose=model.pose if pose_element is None else read_pose(reader, element)[0],
        static=reader.flag(element, "static", model.static),
        plugins=model.plugins + tuple(_read_plugin(reader, e) for e in element.findall("plugin")),
        uri=uri,
    )
