"""The PyBullet world: the one package that loads bodies into PyBullet and steps it.

Systems never see body or link indices: they name a model, a link or a joint (`WorldAccess`), and
this package maps names to PyBullet's indices. Poses are always those of the SDF frames (PyBullet
reports a body's centre of mass; the offset is undone here once).

- `loading`: an SDF model's trees of joints into PyBullet bodies (`Body`), with `dynamics` (friction,
  wheels, castors) and `heightfields`;
- `engine`: `Physics`, the world itself: bodies in and out, stepping, reset, the read-only phase;
- `stepping`: what differs between dynamic and kinematic stepping (`Stepper`), chosen once per world;
  `kinematic_world`: the kinematic fleet mode's stepper, its moving bases held as arrays;
- `queries` and `commands`: its read and command halves, by name; `protocols`: the same as systems see them;
- `bullet_transforms`: transforms by PyBullet's math; `rays`, `contacts`, `wheel_friction`: the parts.

PyBullet itself comes from `simbot.sim.bullet`, which the render workers share.
"""

from simbot.sim.physics.bullet_transforms import compose, invert, pose_to_transform
from simbot.sim.physics.contacts import ContactPoint
from simbot.sim.physics.engine import Physics
from simbot.sim.physics.guard import PhysicsReadOnly
from simbot.sim.physics.loading import ball_castors
from simbot.sim.physics.protocols import WorldAccess, WorldCommands, WorldReader

__all__ = [
    "ContactPoint",
    "Physics",
    "PhysicsReadOnly",
    "WorldAccess",
    "WorldCommands",
    "WorldReader",
    "ball_castors",
    "compose",
    "invert",
    "pose_to_transform",
]
