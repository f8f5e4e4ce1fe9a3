"""SDF heightmaps as PyBullet heightfields: URDF has no heightmap, so each is a body of its own."""

from __future__ import annotations

import logging

import numpy as np

from simbot.description.generated_meshes import heightmap_heights
from simbot.description.model import Collision, Heightmap, Link, Model
from simbot.description.poses import Pose
from simbot.sim.bullet import pb
from simbot.sim.physics.bullet_transforms import compose, pose_to_transform
from simbot.sim.physics.dynamics import SDF_DEFAULT_MU
from simbot.transform import Transform

logger = logging.getLogger(__name__)


def add_heightfields(client: int, model: Model, frame: Transform) -> list[int]:
    """The heightmaps of a tree's collisions (the tree's model frame at `frame`), each a body of its own."""
    bodies = []
    for link in model.links:
        for collision in link.collisions:
            if isinstance(collision.geometry, Heightmap):
                body = _add_heightfield(client, model, link, collision, collision.geometry, frame)
                if body is not None:
                    bodies.append(body)
    return bodies


def _add_heightfield(
    client: int, model: Model, link: Link, collision: Collision, heightmap: Heightmap, frame: Transform
) -> int | None:
    """A heightmap's collision as a PyBullet heightfield fixed in the world, URDF having none;
    only in a static model, as Gazebo has it (the URDF carries the heightmap's visual)."""
    if not model.static:
        logger.warning(
            "model %r: heightmap %r is in a model that moves; Gazebo collides only static ones, and so does simbot",
            model.name,
            collision.name,
        )
        return None
    heights = heightmap_heights(heightmap, model.source)
    rows, cols = heights.shape
    shape = pb.createCollisionShape(
        pb.GEOM_HEIGHTFIELD,
        meshScale=(heightmap.size[0] / (cols - 1), heightmap.size[1] / (rows - 1), 1.0),
        heightfieldData=np.flipud(heights).ravel().tolist(),  # PyBullet's rows run along +x, from −y up
        numHeightfieldRows=cols,
        numHeightfieldColumns=rows,
        physicsClientId=client,
    )
    centre = (
        heightmap.pos[0],
        heightmap.pos[1],
        heightmap.pos[2] + (heights.min() + heights.max()) / 2.0,
    )  # Bullet centres its height range
    pose = compose(frame, pose_to_transform(link.pose @ collision.pose @ Pose(centre, (0.0, 0.0, 0.0))))
    body = pb.createMultiBody(0.0, shape, -1, *pose, physicsClientId=client)
    mu = collision.friction.mu if collision.friction else SDF_DEFAULT_MU
    pb.changeDynamics(body, -1, lateralFriction=mu, physicsClientId=client)
    return int(body)
