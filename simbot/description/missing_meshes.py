"""What a description does with a mesh it cannot find: warn, naming every place looked at.

A collision with a missing mesh is left out; a visual with a missing mesh shows its link's
collision geometry instead, so a robot whose mesh files were not shipped still looks right.
"""

from __future__ import annotations

import logging
from pathlib import Path

from simbot.description.model import Collision, Mesh, Visual
from simbot.description.resources import resolve

logger = logging.getLogger(__name__)


def is_missing(shape: Collision | Visual) -> bool:
    """True when the shape is a mesh whose file was not found."""
    return isinstance(shape.geometry, Mesh) and shape.geometry.path is None


def _warn(source: Path, shape: Collision | Visual, link: str, outcome: str) -> None:
    mesh = shape.geometry
    assert isinstance(mesh, Mesh)
    tried = resolve(mesh.uri, source.parent).describe_tried()
    kind = "collision" if isinstance(shape, Collision) else "visual"
    logger.warning(
        "%s: %s %r of link %r: mesh %r not found (tried %s); %s",
        source,
        kind,
        shape.name,
        link,
        mesh.uri,
        tried,
        outcome,
    )


def present_collisions(source: Path, link: str, collisions: list[Collision]) -> list[Collision]:
    """The collisions whose geometry exists; each one left out is a warning."""
    for collision in filter(is_missing, collisions):
        _warn(source, collision, link, "the collision is left out")
    return [c for c in collisions if not is_missing(c)]


def visuals_with_fallbacks(source: Path, link: str, visuals: list[Visual], collisions: list[Collision]) -> list[Visual]:
    """The visuals, each missing mesh replaced by the link's collision geometry (one visual each)."""
    result: list[Visual] = []
    for visual in visuals:
        if not is_missing(visual):
            result.append(visual)
            continue
        _warn(
            source, visual, link, "showing the collision geometry instead" if collisions else "nothing to show instead"
        )
        result += [
            Visual(
                visual.name if len(collisions) == 1 else f"{visual.name}_{c.name}", c.geometry, c.pose, visual.material
            )
            for c in collisions
        ]
    return result
