"""How the world steps: by PyBullet's forces (dynamic) or by the drives' commands (kinematic).

The two modes differ in a handful of operations, which a `Stepper` answers; `Physics` holds one,
chosen once when it is created (`stepper`), and otherwise knows nothing of the mode. The contract:

- `add` and `forget`: a body entered the world (with its wheels' friction model, if it has
  wheels) or left it; nothing of a forgotten body is stepped again;
- `bases`: bodies' bases (centre of mass, its velocity) as rows, what every reader of a base
  reads; `moved`: bodies were placed or set moving from outside the stepping (a teleport);
  `restored`: the world came back from a saved state (a reset);
- `joint_states` and `set_joint_positions`: joints read and put, what every reader of a joint
  reads; `sync`: PyBullet told of what the stepping holds apart from it, before anything reads
  PyBullet itself (a link's pose, a cast, a contact, a saved state);
- `step`: the world one step on (the world's step size);
- `joint_velocity`: a joint turns at a velocity from now on, with at most an effort where forces count;
- `drive`: the planar twist a drive commands of a model frame, after its own clamping and ramps;
- `carry` and `release`: `attach` made a fixed PyBullet joint (its constraint, already in the
  world) between two bodies, or `detach` removed one.

`DynamicStepper` (here) integrates forces: wheel friction from the last contacts, joint motors,
constraints, then `stepSimulation`; a drive moves its base through the wheels, so it ignores the
twist. `KinematicWorld` (`kinematic_world`) integrates nothing: bodies move by their twists and joint
velocities and stop at contact, their bases held as arrays.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import Protocol

from simbot.description.model import World
from simbot.sim.bullet import pb
from simbot.sim.physics.body import Bases, Body, read_joint_states, write_joint_positions
from simbot.sim.physics.kinematic_world import KINEMATIC, KinematicWorld
from simbot.sim.physics.wheel_friction import WheelFriction, wheel_loads


class Stepper(Protocol):
    """What differs between dynamic and kinematic stepping (see the module docstring)."""

    def add(self, body: Body, wheels: WheelFriction | None) -> None: ...

    def forget(self, body: int) -> None: ...

    def bases(self, ids: Sequence[int]) -> Bases: ...

    def moved(self, ids: Sequence[int]) -> None: ...

    def restored(self) -> None: ...

    def sync(self) -> None: ...

    def joint_states(self, body: int, joints: Sequence[int]) -> list[tuple[float, float, float]]: ...

    def set_joint_positions(self, body: int, joints: Sequence[int], values: Sequence[float]) -> None: ...

    def step(self, bodies: dict[str, Body]) -> None: ...

    def joint_velocity(self, body: int, joint: int, velocity: float, max_effort: float) -> None: ...

    def drive(self, body: Body, others: Iterable[Body], forward: float, lateral: float, turn: float) -> None: ...

    def carry(self, constraint: int, parent: int, child: int) -> None: ...

    def release(self, constraint: int) -> None: ...


def stepper(world: World, client: int) -> Stepper:
    """The stepping `world` asks for (`<physics type="kinematic">`, or dynamic) of the PyBullet world `client`."""
    if world.physics.type == KINEMATIC:
        return KinematicWorld(client, world.physics.max_step_size)
    return DynamicStepper(client)


@dataclass
class DynamicStepper:
    """PyBullet's forces and `stepSimulation`, with the wheels' anisotropic friction it lacks."""

    client: int
    wheels: dict[int, WheelFriction] = field(default_factory=dict)
    """The wheels' friction model of each body that has wheels, by PyBullet body id."""

    def add(self, body: Body, wheels: WheelFriction | None) -> None:
        if wheels is not None:
            self.wheels[body.id] = wheels

    def forget(self, body: int) -> None:
        self.wheels.pop(body, None)

    def bases(self, ids: Sequence[int]) -> Bases:
        return Bases.read(self.client, ids)

    def moved(self, ids: Sequence[int]) -> None:
        """Nothing: PyBullet holds every state."""

    def restored(self) -> None:
        """Nothing: PyBullet holds every state."""

    def sync(self) -> None:
        """Nothing: PyBullet holds every state."""

    def joint_states(self, body: int, joints: Sequence[int]) -> list[tuple[float, float, float]]:
        return read_joint_states(self.client, body, joints)

    def set_joint_positions(self, body: int, joints: Sequence[int], values: Sequence[float]) -> None:
        write_joint_positions(self.client, body, joints, values)

    def step(self, bodies: dict[str, Body]) -> None:
        """Wheel friction from the last step's contacts, then PyBullet's step (its time step set at creation)."""
        if self.wheels:
            loads = wheel_loads(self.client, self.wheels)
            for wheels in self.wheels.values():
                wheels.apply(loads)
        pb.stepSimulation(physicsClientId=self.client)

    def joint_velocity(self, body: int, joint: int, velocity: float, max_effort: float) -> None:
        """A velocity servo: PyBullet's motor, its force capped at `max_effort`."""
        pb.setJointMotorControl2(
            body, joint, pb.VELOCITY_CONTROL, targetVelocity=velocity, force=max_effort, physicsClientId=self.client
        )

    def drive(self, body: Body, others: Iterable[Body], forward: float, lateral: float, turn: float) -> None:
        """Nothing: the drive's wheel velocities (`joint_velocity`) move the base through friction."""

    def carry(self, constraint: int, parent: int, child: int) -> None:
        """Nothing: PyBullet's solver holds the constraint."""

    def release(self, constraint: int) -> None:
        """Nothing: the constraint is gone from PyBullet."""
