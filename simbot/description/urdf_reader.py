"""URDF and xacro input: expanded with xacro, validated and walked with yourdfpy, into a Model.

A URDF's link frame is its joint frame, so both get the pose that forward kinematics at the
zero configuration gives; the root link's frame is the model frame.
"""

from __future__ import annotations

import io
import logging
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import xacro

from simbot.description.errors import DescriptionError
from simbot.description.missing_meshes import present_collisions, visuals_with_fallbacks
from simbot.description.model import (
    Axis,
    Box,
    Collision,
    Cylinder,
    Geometry,
    Inertial,
    Joint,
    Link,
    Material,
    Mesh,
    Model,
    Sphere,
    Visual,
)
from simbot.description.poses import IDENTITY, Pose
from simbot.description.resources import resolve
from simbot.description.xml import parse_text
from simbot.transform import norm

if TYPE_CHECKING:
    import yourdfpy

logger = logging.getLogger(__name__)

XACRO_SUFFIXES = (".xacro",)
JOINT_TYPES = ("fixed", "revolute", "continuous", "prismatic")


def is_xacro(path: Path) -> bool:
    """True for `.xacro` and `.urdf.xacro` files."""
    return path.suffix in XACRO_SUFFIXES


def urdf_text(path: Path | str) -> str:
    """The URDF held by `path`, expanded with xacro when it is a xacro file."""
    path = Path(path)
    if not is_xacro(path):
        try:
            return path.read_text()
        except OSError as exc:
            raise DescriptionError(path, f"cannot read file: {exc.strerror or exc}") from None
    try:
        return xacro.process_file(str(path)).toprettyxml(indent="  ")
    except xacro.XacroException as exc:
        raise DescriptionError(path, f"xacro: {exc}") from None
    except Exception as exc:  # xacro reports XML and I/O trouble as plain exceptions
        raise DescriptionError(path, f"xacro: {type(exc).__name__}: {exc}") from None


def load_urdf(path: Path | str) -> yourdfpy.URDF:
    """A validated yourdfpy URDF (xacro expanded), ready for forward kinematics."""
    path = Path(path)
    text = urdf_text(path)
    root = parse_text(text, path)
    if root.tag != "robot":
        raise DescriptionError(path, "not a URDF file: the root element must be <robot>", root.tag, root.sourceline)
    import yourdfpy  # with trimesh, 1.1 s of import that every render worker would pay for a package it never calls

    urdf = yourdfpy.URDF.load(
        io.BytesIO(text.encode()),
        build_scene_graph=True,
        load_meshes=False,
        load_collision_meshes=False,
        filename_handler=lambda fname: _mesh_path(fname, path.parent),
    )
    errors: list[Exception] = []

    def collect(found: list[Exception]) -> bool:
        errors.extend(found)
        return not found

    if not urdf.validate(validation_fn=collect):
        raise DescriptionError(path, f"invalid URDF: {errors[0]}")
    return urdf


def _mesh_path(filename: str, base_dir: Path) -> str:
    found = resolve(filename, base_dir).path
    return str(found) if found is not None else filename


def load_urdf_model(path: Path | str) -> Model:
    """The Model of a URDF or xacro file (sensors and plugins: none, URDF has no place for them)."""
    path = Path(path)
    urdf = load_urdf(path)
    root = urdf.base_link

    def pose_of(link: str) -> Pose:
        return Pose.from_matrix(urdf.get_transform(link, root))

    links = tuple(_link(urdf, link, pose_of(link.name), path) for link in urdf.robot.links)
    joints = tuple(_joint(joint, pose_of(joint.child), path) for joint in urdf.robot.joints)
    return Model(name=urdf.robot.name, canonical_link=root, links=links, joints=joints, source=path)


def _pose(matrix: np.ndarray | None) -> Pose:
    return IDENTITY if matrix is None else Pose.from_matrix(matrix)


def _geometry(geometry: yourdfpy.Geometry, base_dir: Path) -> Geometry:
    if geometry.box is not None:
        return Box(tuple(float(v) for v in geometry.box.size))  # type: ignore[arg-type]
    if geometry.cylinder is not None:
        return Cylinder(float(geometry.cylinder.radius), float(geometry.cylinder.length))
    if geometry.sphere is not None:
        return Sphere(float(geometry.sphere.radius))
    mesh = geometry.mesh
    scale = mesh.scale if mesh.scale is not None else (1.0, 1.0, 1.0)
    scale = (scale,) * 3 if np.isscalar(scale) else tuple(float(s) for s in scale)
    return Mesh(mesh.filename, scale, resolve(mesh.filename, base_dir).path)


def _link(urdf: yourdfpy.URDF, link: yourdfpy.Link, pose: Pose, path: Path) -> Link:
    inertial = None
    if link.inertial is not None and link.inertial.mass:
        i = link.inertial.inertia
        values = (i[0, 0], i[0, 1], i[0, 2], i[1, 1], i[1, 2], i[2, 2])
        inertial = Inertial(float(link.inertial.mass), _pose(link.inertial.origin), tuple(float(v) for v in values))  # type: ignore[arg-type]
    visuals = [
        Visual(
            v.name or f"{link.name}_visual_{k}", _geometry(v.geometry, path.parent), _pose(v.origin), _material(urdf, v)
        )
        for k, v in enumerate(link.visuals)
    ]
    collisions = [
        Collision(c.name or f"{link.name}_collision_{k}", _geometry(c.geometry, path.parent), _pose(c.origin))
        for k, c in enumerate(link.collisions)
    ]
    collisions = present_collisions(path, link.name, collisions)
    visuals = visuals_with_fallbacks(path, link.name, visuals, collisions)
    return Link(link.name, pose, inertial, tuple(collisions), tuple(visuals))


def _material(urdf: yourdfpy.URDF, visual: yourdfpy.Visual) -> Material | None:
    material = visual.material
    if material is not None and material.color is None and material.name in urdf._material_map:
        material = urdf._material_map[material.name]
    if material is None or material.color is None:
        return None
    rgba = tuple(float(v) for v in material.color.rgba)
    return Material(ambient=rgba, diffuse=rgba)  # type: ignore[arg-type]


def _joint(joint: yourdfpy.Joint, pose: Pose, path: Path) -> Joint:
    if joint.type not in JOINT_TYPES:
        raise DescriptionError(path, f"unsupported joint type {joint.type!r} for joint {joint.name!r}", "joint")
    axis = None
    if joint.type != "fixed":
        limit = joint.limit
        xyz = np.asarray(joint.axis, dtype=float)
        axis = Axis(
            xyz=tuple(float(v) for v in xyz / norm(xyz)),  # type: ignore[arg-type]
            lower=None if limit is None or joint.type == "continuous" else limit.lower,
            upper=None if limit is None or joint.type == "continuous" else limit.upper,
            effort=None if limit is None else limit.effort,
            velocity=None if limit is None else limit.velocity,
            damping=float(joint.dynamics.damping or 0.0) if joint.dynamics else 0.0,
            friction=float(joint.dynamics.friction or 0.0) if joint.dynamics else 0.0,
        )
    return Joint(joint.name, joint.type, joint.parent, joint.child, pose, axis)
