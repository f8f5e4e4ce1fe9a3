"""A model's visuals as its URDF draws them, as typed data: what the render workers draw.

A render worker loads a body's URDF into its own PyBullet for the link poses, and draws the
visuals it gets from here (`SceneBody.visuals`), not the URDF's: each visual of the description
whole (its material, transparency, shadows), placed and shaped exactly as `urdf_writer` writes it,
so that every triangle lies where the URDF puts it. Each one is held by the URDF link of its SDF
link's name; its pose is in that link's URDF frame, to the digits the URDF states (`as_written`);
a plane is the thin box the URDF has, and an ellipsoid, a cone, a polyline or a heightmap the OBJ
mesh the URDF names (`generated_meshes`, the same file by content). A mesh stays the file itself,
where the URDF names an OBJ stand-in for PyBullet (`stand_in_meshes`), so its materials are drawn.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

from simbot.description.generated_meshes import mesh_file
from simbot.description.model import Geometry, Link, Mesh, Model, Plane, Visual
from simbot.description.urdf_writer import (
    GENERATED,
    as_written,
    generated_folder,
    in_urdf_link,
    plane_box,
    shape_origin,
    urdf_links,
)


@dataclass(frozen=True)
class UrdfVisual:
    """One visual of a model as its URDF draws it."""

    link: str
    """The URDF link that holds it (its SDF link's name: the name PyBullet knows the link by)."""
    visual: Visual
    """The description's visual, its pose in that link's URDF frame and its geometry as the URDF has them."""


def urdf_visuals(model: Model, generated_dir: Path | None = None) -> tuple[UrdfVisual, ...]:
    """Every visual of `model` (one tree of joints) in the order of its URDF; the meshes of shapes
    URDF lacks are found or written in `generated_dir` (`urdf_writer.generated_folder`)."""
    links = {link.name: link for link in model.links}
    folder = generated_folder(generated_dir)
    return tuple(
        UrdfVisual(name, _as_drawn(links[name], visual, folder, model.source))
        for name in urdf_links(model)
        if name in links
        for visual in links[name].visuals
    )


def _as_drawn(link: Link, visual: Visual, folder: Path, source: Path | None) -> Visual:
    pose = as_written(shape_origin(in_urdf_link(link), visual))
    return replace(visual, pose=pose, geometry=_geometry(visual.geometry, folder, source))


def _geometry(geometry: Geometry, folder: Path, source: Path | None) -> Geometry:
    """The shape as the URDF states it (`urdf_writer.add_geometry`)."""
    if isinstance(geometry, Plane):
        return plane_box(geometry)
    if isinstance(geometry, GENERATED):
        path = mesh_file(geometry, folder, source)
        return Mesh(str(path), path=path)
    return geometry
