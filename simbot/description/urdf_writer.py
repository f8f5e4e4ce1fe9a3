"""A URDF from a parsed model: same world pose for every link, collision and visual.

URDF cannot say everything SDF can, so a few things are rewritten, each keeping the physics:
- URDF puts a link's frame on its parent joint. Where an SDF joint sits away from its child
  link's origin, the movable joint drives a massless frame link `<joint>__frame` placed at the
  joint, and the child link hangs from it by a fixed joint at its own SDF pose.
- A ball joint becomes three continuous joints `<joint>__yaw`, `__pitch`, `__roll` through
  massless links: a free swivel with a gimbal lock only at ±90° pitch.
- PyBullet gives a link without `<inertial>` 1 kg, so every link states its inertial, a
  massless one as zero. PyBullet also pins a massless base link to the world, so a massless
  root (like base_footprint) gets a token mass of ROOT_TOKEN; on a robot of tens of
  kilograms it changes nothing.
- A plane becomes a thin box whose top face is the plane. A capsule is PyBullet's own URDF
  `<capsule>` (not in ROS's URDF). An ellipsoid, a cone, a polyline and a heightmap's visual
  become OBJ meshes made by generated_meshes, written to `generated_dir`; a polyline's collision
  in a static model is marked `concave="yes"`, so PyBullet collides with the outline itself and
  not its convex hull. A heightmap's collision is left out: URDF has no heightfield, and the
  simulator adds it as a PyBullet heightfield (sim/physics/heightfields.py).
- A link whose one sensor reports in the link's own frame (`<frame_name>` is the link's name)
  has its URDF frame at that sensor, so a message stamped with that frame is where the sensor
  is (the reference lidars sit 0.22 m above their link origin, turned by π). Everything the
  link holds is re-expressed; the physics does not change.
- Limits SDF calls unlimited: a revolute joint becomes continuous; effort or velocity, and a
  prismatic joint's range, are written as ±UNLIMITED.
- A visual's material: URDF's `<material>` holds its colour and its texture (the PBR albedo map);
  the rest of SDF's material and the visual's `<transparency>` and `<cast_shadows>` are attributes
  of an `<sdf_material>` element beside it, which PyBullet and ROS's URDF readers skip. A mesh
  PyBullet cannot read (glTF, GLB, ...) is named by an OBJ stand-in of its triangles, and the file
  itself by `<sdf_material mesh=...>`. (The render workers read no URDF visual: they get the same
  visuals as typed data from `urdf_visuals.py`, which places them with this module's functions.)
Sensors, plugins and friction, which URDF has no place for, stay in the parsed model.
"""

from __future__ import annotations

import logging
import os
import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Callable, Collection, Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from simbot.description.errors import DescriptionError
from simbot.description.generated_meshes import Generated, mesh_file
from simbot.description.model import (
    RGBA,
    Axis,
    Box,
    Capsule,
    Collision,
    Cone,
    Cylinder,
    Ellipsoid,
    Geometry,
    Heightmap,
    Inertial,
    Joint,
    Link,
    Material,
    Mesh,
    Model,
    Plane,
    Polyline,
    Sphere,
    Visual,
)
from simbot.description.model_memo import per_model
from simbot.description.poses import IDENTITY, Pose, Vec3
from simbot.description.stand_in_meshes import needs_stand_in, stand_in
from simbot.transform import matmul, matrix_to_rpy, norm

MASSLESS = Inertial(0.0, IDENTITY, (0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
ROOT_TOKEN = Inertial(1e-3, IDENTITY, (1e-6, 0.0, 0.0, 1e-6, 0.0, 1e-6))
UNLIMITED = 1e16
PLANE_THICKNESS = 0.01
BALL_AXES = (("yaw", (0.0, 0.0, 1.0)), ("pitch", (0.0, 1.0, 0.0)), ("roll", (1.0, 0.0, 0.0)))
GENERATED = (Ellipsoid, Cone, Polyline, Heightmap)
SDF_MATERIAL = "sdf_material"
"""The extension element of a URDF `<visual>` carrying the SDF material and visual settings URDF lacks."""

logger = logging.getLogger(__name__)


def _fmt(value: float) -> str:
    text = f"{round(float(value), 12):.12g}"
    return "0" if text == "-0" else text


def _fmts(values: tuple[float, ...] | np.ndarray) -> str:
    return " ".join(_fmt(v) for v in values)


def as_written(pose: Pose) -> Pose:
    """`pose` as a reader of the URDF gets it back: each number to the digits `_fmt` writes."""
    return Pose(_read_back(pose.xyz), _read_back(pose.rpy))


def _read_back(values: Vec3) -> Vec3:
    x, y, z = (float(_fmt(v)) for v in values)
    return (x, y, z)


@dataclass
class _Urdf:
    """The URDF under construction, with each link's URDF frame in the model frame."""

    model: Model
    mesh_dir: Path | None
    generated_dir: Path
    mesh_uris: bool = False
    robot: ET.Element = field(init=False)
    frames: dict[str, Pose] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.robot = ET.Element("robot", name=self.model.name)

    def origin(self, parent: ET.Element, pose: Pose) -> None:
        if not pose.is_identity(1e-15):
            ET.SubElement(parent, "origin", xyz=_fmts(pose.xyz), rpy=_fmts(pose.rpy))

    def add_link(self, name: str, frame: Pose, link: Link | None = None, token_mass: bool = False) -> None:
        """A URDF link at `frame` (model frame) holding what the SDF link holds."""
        self.frames[name] = frame
        element = ET.SubElement(self.robot, "link", name=name)
        massless = ROOT_TOKEN if token_mass else MASSLESS
        if link is None:
            self.add_inertial(element, IDENTITY, massless)
            return
        to_link = in_urdf_link(link)
        inertial = link.inertial or massless
        self.add_inertial(element, to_link @ inertial.pose, inertial)
        for visual in link.visuals:
            self.add_shape(element, "visual", to_link, visual)
        for collision in link.collisions:
            self.add_shape(element, "collision", to_link, collision)

    def add_inertial(self, link: ET.Element, pose: Pose, inertial: Inertial) -> None:
        element = ET.SubElement(link, "inertial")
        self.origin(element, pose)
        ET.SubElement(element, "mass", value=_fmt(inertial.mass))
        tags = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
        ET.SubElement(element, "inertia", {t: _fmt(v) for t, v in zip(tags, inertial.inertia)})

    def add_shape(self, link: ET.Element, kind: str, to_link: Pose, shape: Visual | Collision) -> None:
        if kind == "collision" and isinstance(shape.geometry, Heightmap):
            logger.debug("%s: heightmap collision %r left to the simulator's heightfield", link.get("name"), shape.name)
            return
        element = ET.SubElement(link, kind, name=shape.name)
        if kind == "collision" and self.model.static and isinstance(shape.geometry, Polyline):
            element.set("concave", "yes")
        self.origin(element, shape_origin(to_link, shape))
        self.add_geometry(ET.SubElement(element, "geometry"), shape.geometry)
        if isinstance(shape, Visual):
            self.add_material(element, f"{link.get('name')}__{shape.name}", shape)

    def add_material(self, element: ET.Element, name: str, visual: Visual) -> None:
        """URDF's own `<material>` (colour, texture: what PyBullet and ROS tools read), and beside
        it `<sdf_material>` with what URDF has no place for (every URDF reader skips it)."""
        material = visual.material or Material()
        color, texture = material.color(), material.albedo_map
        if color is not None or texture is not None:
            urdf_material = ET.SubElement(element, "material", name=name)
            if color is not None:
                ET.SubElement(urdf_material, "color", rgba=_fmts(color))
            if texture is not None:
                ET.SubElement(urdf_material, "texture", filename=self.filename(texture))
        extra = {
            **{tag: _fmts(value) for tag, value in _colours(material).items() if value is not None},
            **{tag: _fmt(value) for tag, value in _numbers(material, visual).items() if value is not None},
            **({"lighting": "false"} if not material.lighting else {}),
            **({"cast_shadows": "false"} if not visual.cast_shadows else {}),
            **({"normal_map": self.filename(material.normal_map)} if material.normal_map else {}),
            **_original_mesh(visual, self.filename),
        }
        if extra:
            ET.SubElement(element, SDF_MATERIAL, extra)

    def add_geometry(self, parent: ET.Element, geometry: Geometry) -> None:
        if isinstance(geometry, Box):
            ET.SubElement(parent, "box", size=_fmts(geometry.size))
        elif isinstance(geometry, Cylinder):
            ET.SubElement(parent, "cylinder", radius=_fmt(geometry.radius), length=_fmt(geometry.length))
        elif isinstance(geometry, Sphere):
            ET.SubElement(parent, "sphere", radius=_fmt(geometry.radius))
        elif isinstance(geometry, Plane):
            self.add_geometry(parent, plane_box(geometry))
        elif isinstance(geometry, Capsule):
            ET.SubElement(parent, "capsule", radius=_fmt(geometry.radius), length=_fmt(geometry.length))
        elif isinstance(geometry, Mesh):
            ET.SubElement(parent, "mesh", filename=self.mesh_filename(geometry), scale=_fmts(geometry.scale))
        elif isinstance(geometry, GENERATED):
            ET.SubElement(parent, "mesh", filename=self.generated_filename(geometry))

    def mesh_filename(self, mesh: Mesh) -> str:
        if mesh.path is None:
            raise DescriptionError(self.model.source, f"mesh {mesh.uri!r} was not resolved", "mesh")
        return self.filename(stand_in(mesh.path, self.generated_dir) if needs_stand_in(mesh.path) else mesh.path)

    def generated_filename(self, shape: Generated) -> str:
        return self.filename(mesh_file(shape, self.generated_dir, self.model.source))

    def filename(self, path: Path) -> str:
        """Relative to the URDF's folder when known, so a committed URDF holds no machine paths;
        `file://` URIs when asked (what ROS tools resolve)."""
        if self.mesh_uris:
            return path.resolve().as_uri()
        if self.mesh_dir is None:
            return str(path.resolve())
        return Path(os.path.relpath(path.resolve(), self.mesh_dir.resolve())).as_posix()

    def add_joint(
        self,
        name: str,
        kind: str,
        parent: str,
        child: str,
        axis: Axis | None = None,
        axis_xyz: tuple[float, ...] | None = None,
    ) -> None:
        """A URDF joint; the child's frame must already be registered."""
        element = ET.SubElement(self.robot, "joint", name=name, type=kind)
        self.origin(element, self.frames[parent].inverse() @ self.frames[child])
        ET.SubElement(element, "parent", link=parent)
        ET.SubElement(element, "child", link=child)
        if kind == "fixed":
            return
        ET.SubElement(element, "axis", xyz=_fmts(axis_xyz or (axis.xyz if axis else (0.0, 0.0, 1.0))))
        if axis is None:
            return
        _add_limit(element, kind, axis)
        if axis.damping or axis.friction:
            ET.SubElement(element, "dynamics", damping=_fmt(axis.damping), friction=_fmt(axis.friction))


def shape_origin(to_link: Pose, shape: Visual | Collision) -> Pose:
    """A visual's or collision's `<origin>` in its URDF link (`to_link`: `in_urdf_link`); a
    plane's is its box's (`plane_box`)."""
    pose = to_link @ shape.pose
    return pose @ _plane_offset(shape.geometry) if isinstance(shape.geometry, Plane) else pose


def plane_box(plane: Plane) -> Box:
    """The thin box a plane is written as: its top face is the plane where `shape_origin` puts it."""
    return Box((*plane.size, PLANE_THICKNESS))


def _original_mesh(visual: Visual, filename: Callable[[Path], str]) -> dict[str, str]:
    """The mesh file itself where the URDF's `<mesh>` names its stand-in (stand_in_meshes.py)."""
    mesh = visual.geometry
    if isinstance(mesh, Mesh) and mesh.path is not None and needs_stand_in(mesh.path):
        return {"mesh": filename(mesh.path)}
    return {}


def _colours(material: Material) -> dict[str, RGBA | None]:
    return {
        "ambient": material.ambient,
        "diffuse": material.diffuse,
        "specular": material.specular,
        "emissive": material.emissive,
    }


def _numbers(material: Material, visual: Visual) -> dict[str, float | None]:
    return {
        "shininess": material.shininess,
        "metalness": material.metalness,
        "roughness": material.roughness,
        "transparency": visual.transparency or None,
    }


def _add_limit(joint: ET.Element, kind: str, axis: Axis) -> None:
    effort = _fmt(axis.effort if axis.effort is not None else UNLIMITED)
    velocity = _fmt(axis.velocity if axis.velocity is not None else UNLIMITED)
    if kind == "continuous":
        if axis.effort is not None or axis.velocity is not None:
            ET.SubElement(joint, "limit", effort=effort, velocity=velocity)
        return
    lower = axis.lower if axis.lower is not None else -UNLIMITED
    upper = axis.upper if axis.upper is not None else UNLIMITED
    ET.SubElement(joint, "limit", lower=_fmt(lower), upper=_fmt(upper), effort=effort, velocity=velocity)


def _plane_offset(plane: Plane) -> Pose:
    """Turns the box's z onto the plane normal and sinks it so its top face is the plane."""
    normal = np.asarray(plane.normal, dtype=float) / norm(plane.normal)
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(z, normal)
    sin, cos = norm(axis), float(matmul(z, normal))
    skew = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    rot = np.eye(3) + skew + matmul(skew, skew) * ((1 - cos) / sin**2 if sin > 1e-12 else 0.0)
    if sin <= 1e-12 and cos < 0:
        rot = np.diag([1.0, -1.0, -1.0])
    return Pose(tuple(-normal * PLANE_THICKNESS / 2), matrix_to_rpy(rot))


def _tree(model: Model) -> tuple[str, dict[str, list[Joint]]]:
    """The root link and each link's child joints; a model that is not one tree is an error."""
    children: dict[str, list[Joint]] = {}
    parents: dict[str, str] = {}
    for joint in model.joints:
        if joint.child in parents:
            raise DescriptionError(
                model.source, f"link {joint.child!r} is the child of two joints; URDF needs a tree", "joint"
            )
        parents[joint.child] = joint.name
        children.setdefault(joint.parent, []).append(joint)
    roots = ["world"] if "world" in children else [link.name for link in model.links if link.name not in parents]
    if len(roots) != 1:
        raise DescriptionError(
            model.source,
            f"model {model.name!r} is not one tree of joints (roots: {', '.join(roots) or 'none, a cycle'}); URDF needs one",
            "model",
        )
    return roots[0], children


def joint_trees(model: Model) -> list[Model]:
    """`model` as one model per tree of its joints: `[model]` when it is one tree, as URDF needs.

    Gazebo simulates links that no joint joins as free bodies of one model (gz-sim's
    `nested_model.sdf`, `graded_buoyancy.sdf`); a URDF holds one tree. So the tree that holds the
    canonical link (else the first link) keeps the model's name and plugins, and each other tree
    becomes a model of its own in the same frame, named by its root's scoped name
    (`model::root`), without plugins. A model with a cycle stays whole, for `_tree` to refuse."""
    groups = _groups_by_root(model)
    if len(groups) <= 1:
        return [model]
    main = next((root for root, links in groups.items() if model.canonical_link in links), next(iter(groups)))
    return [
        _part(model, root, links, root == main) for root, links in sorted(groups.items(), key=lambda g: g[0] != main)
    ]


def _groups_by_root(model: Model) -> dict[str, set[str]]:
    """Link names by the root their parent joints lead to (`world` for a tree fixed to it), in
    file order; empty where the joints make a cycle."""
    parent_of = {joint.child: joint.parent for joint in model.joints}
    groups: dict[str, set[str]] = {}
    for link in model.links:
        root, seen = link.name, {link.name}
        while root in parent_of:
            root = parent_of[root]
            if root in seen:
                return {}
            seen.add(root)
        groups.setdefault(root, set()).add(link.name)
    return groups


def _part(model: Model, root: str, names: set[str], main: bool) -> Model:
    """The tree of `model` rooted at `root` holding the links `names` (see `joint_trees`)."""
    links = tuple(link for link in model.links if link.name in names)
    if main:
        canonical, name, plugins = model.canonical_link, model.name, model.plugins
    else:
        canonical, name, plugins = (root if root in names else links[0].name), f"{model.name}::{root}", ()
    joints = tuple(joint for joint in model.joints if joint.child in names)
    return replace(model, name=name, canonical_link=canonical, links=links, joints=joints, plugins=plugins)


def urdf_root(model: Model) -> str:
    """The link the URDF of `model` is rooted at, or "world" when the model is fixed to it."""
    return _tree(model)[0]


def link_frame(link: Link) -> Pose:
    """The link's URDF frame in the model frame: its SDF pose, or the pose of the one sensor that names the link as its frame."""
    own = [sensor for sensor in link.sensors if sensor.frame_name == link.name]
    return link.pose @ own[0].pose if len(own) == 1 else link.pose


def in_urdf_link(link: Link) -> Pose:
    """The SDF link's frame in its URDF link's (`link_frame`): what re-expresses everything it holds."""
    return link_frame(link).inverse() @ link.pose


def urdf_links(model: Model) -> list[str]:
    """The model's links in the order its URDF lists them: the root ("world" where the model is
    fixed to it), then down the joints, each link before those below it (frame links left out)."""
    root, children = _tree(model)
    return [root, *(joint.child for joint in _descending(children, root))]


def _descending(children: dict[str, list[Joint]], parent: str) -> Iterator[Joint]:
    """The joints below `parent`, each before those below its child."""
    for joint in children.get(parent, []):
        yield joint
        yield from _descending(children, joint.child)


def _add_subtree(urdf: _Urdf, links: dict[str, Link], children: dict[str, list[Joint]], root: str) -> None:
    for joint in _descending(children, root):
        child = links[joint.child]
        if joint.type == "fixed":
            urdf.add_link(child.name, link_frame(child), child)
            urdf.add_joint(joint.name, "fixed", joint.parent, child.name)
        else:
            _add_movable(urdf, joint, child)


def _add_movable(urdf: _Urdf, joint: Joint, child: Link) -> None:
    """The joint as a chain of URDF joints at the SDF joint frame, ending at the child link."""
    frame = link_frame(child)
    on_child = (frame.inverse() @ joint.pose).is_identity(1e-9)
    end = child.name if on_child else f"{joint.name}__frame"
    steps: list[tuple[str, str, str, Axis | None, tuple[float, float, float] | None]]
    if joint.type == "ball":
        names = [f"{joint.name}__{axis_name}" for axis_name, _ in BALL_AXES]
        links = [f"{joint.name}__{axis_name}_link" for axis_name, _ in BALL_AXES[:-1]] + [end]
        steps = [(n, "continuous", link, None, xyz) for n, link, (_, xyz) in zip(names, links, BALL_AXES)]
    else:
        kind = (
            "continuous"
            if joint.type == "revolute" and joint.axis and None in (joint.axis.lower, joint.axis.upper)
            else joint.type
        )
        steps = [(joint.name, kind, end, joint.axis, None)]
    parent = joint.parent
    for name, kind, link, axis, xyz in steps:
        holds = child if link == child.name else None
        urdf.add_link(link, frame if holds else joint.pose, holds)
        urdf.add_joint(name, kind, parent, link, axis, xyz)
        parent = link
    if not on_child:
        urdf.add_link(child.name, frame, child)
        urdf.add_joint(f"{joint.name}__offset", "fixed", end, child.name)


def sdf_joint(urdf_joint: str) -> str:
    """The SDF joint a URDF joint is written for: itself, or the joint its name extends (a ball
    joint's parts JOINT__yaw, JOINT__pitch, JOINT__roll; JOINT__offset to its child link)."""
    return urdf_joint.split("__", 1)[0]


@per_model
def model_to_urdf(
    model: Model, mesh_dir: Path | None = None, generated_dir: Path | None = None, *, mesh_uris: bool = False
) -> str:
    """URDF text of `model`; mesh paths relative to `mesh_dir` (the URDF's folder) if given, absolute otherwise,
    or `file://` URIs with `mesh_uris` (what ROS tools resolve: `robot_description`).

    Meshes for shapes URDF lacks go to `generated_dir`: by default `mesh_dir`, beside the URDF,
    or else a folder in the system's temporary directory."""
    return _text(model, _build(model, mesh_dir, generated_dir, mesh_uris))


@per_model
def model_to_urdf_held(model: Model, held: Collection[str], generated_dir: Path | None = None) -> tuple[str, str]:
    """(URDF text of `model`, the same with the joints `held` (SDF names) written fixed), from one
    writing of it: every part of a held joint keeps its name, links and axis, so a simulator loads
    them fixed (the physics' ball castors) and still knows them by name."""
    robot = _build(model, None, generated_dir, False)
    written = _text(model, robot)
    for joint in robot.iter("joint"):
        if sdf_joint(joint.get("name", "")) in held:
            joint.set("type", "fixed")
    return written, _text(model, robot)


def _build(model: Model, mesh_dir: Path | None, generated_dir: Path | None, mesh_uris: bool) -> ET.Element:
    """The URDF's element tree (see `model_to_urdf`)."""
    root, children = _tree(model)
    links = {link.name: link for link in model.links}
    generated = generated_folder(generated_dir or mesh_dir)
    urdf = _Urdf(model, mesh_dir, generated, mesh_uris)
    if root == "world":
        urdf.robot.append(ET.Element("link", name="world"))
        urdf.frames["world"] = IDENTITY
    else:
        urdf.add_link(root, link_frame(links[root]), links[root], token_mass=True)
    _add_subtree(urdf, links, children, root)
    unreached = [name for name in links if name not in urdf.frames]
    if unreached:
        raise DescriptionError(
            model.source, f"links {', '.join(unreached)} are not joined to {root!r}; URDF needs one tree", "model"
        )
    ET.indent(urdf.robot)
    return urdf.robot


def generated_folder(folder: Path | None = None) -> Path:
    """Where the meshes of shapes URDF lacks are written: `folder`, else one in the system's temporary directory."""
    return folder or Path(tempfile.gettempdir()) / "simbot-meshes"


def _text(model: Model, robot: ET.Element) -> str:
    """The URDF file: its header naming the source, then the element tree."""
    source = model.source.name if model.source else "a parsed model"
    header = (
        f'<?xml version="1.0"?>\n<!-- Generated by simbot sdf2urdf from {source}; edit the SDF, not this file. -->\n'
    )
    return header + ET.tostring(robot, encoding="unicode") + "\n"
