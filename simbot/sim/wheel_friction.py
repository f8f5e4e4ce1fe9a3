"""Anisotropic wheel friction: SDF's μ along the rolling direction and μ2 across it.

Why this exists: PyBullet's multibody contacts have one isotropic friction coefficient and ignore
`anisotropicFriction`. With isotropic friction the four-wheel tug (wheels 1.16 m apart along x,
0.4 m across) cannot turn in place: scrubbing the wheels sideways needs more moment than the
wheels' traction gives (measured: 0.006 rad of 3.0 commanded in 6 s). The real wheels have μ 0.9
along and 0.25 across, and then the traction wins.

So for each wheel, PyBullet's own contact keeps only the normal force (its friction is 0), and
this model applies the friction force at the contact point before each step, as ODE's friction
pyramid does for SDF `mu`/`mu2`:

    F_along  = −μ  · N · clip(v_along  / v_slip, −1, 1)
    F_across = −μ2 · N · clip(v_across / v_slip, −1, 1)

along and across turn by the angle of SDF's `fdir1` where a wheel states one (mecanum rollers);
where v is the slip velocity of the wheel surface over the ground at the contact (the wheel's spin
included, so a wheel driven faster than the ground under it pushes the robot), N the wheel's normal force
PyBullet reported at the last step (all its contact points summed, applied at their load-weighted
centre), and v_slip a small regularising slip speed (a tyre's slip
stiffness; Coulomb friction with an infinitely sharp switch cannot be integrated explicitly).
Traction is bounded by μ × load, so walls and a pulled trolley push back and the wheels spin.

The wheels' contacts are also given a tyre's vertical compliance (TYRE_STIFFNESS, critically
damped): a rigid four-wheeled chassis on rigid ground rocks between its diagonals, so the loads,
and with them the friction, flicker between pairs of wheels from step to step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from simbot.sim.bullet import pb

SLIP_SPEED = 0.01
"""m/s of slip at which friction saturates. Small enough that the tug tracks commands within
a few percent; large enough to be stable at a 1 ms explicit step (stiffness μN/v_slip ≈ 2.4e4 N·s/m
per wheel on the 110 kg robot)."""


Vec3 = tuple[float, float, float]


TYRE_STIFFNESS = 2.0e5
"""N/m of vertical tyre compliance: a 110 kg tug sinks 1.3 mm on its four wheels."""


@dataclass(frozen=True)
class Wheel:
    """A wheel link (PyBullet index) and its SDF friction."""

    link: int
    mu: float
    mu2: float
    axle: Vec3
    """The wheel's axis of rotation in its link frame."""
    fdir1: float = 0.0
    """Radians from the rolling direction to SDF's fdir1, about the contact normal: μ acts along
    fdir1 and μ2 across it. A mecanum wheel's rollers give 45° with μ2 0 (Gazebo's mecanum example)."""


def _cross(a: Vec3, b: Vec3) -> Vec3:
    return a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]


class WheelFriction:
    """The wheels of one body; `apply` once before every physics step (plain floats: it runs at 1 kHz)."""

    def __init__(self, client: int, body: int, wheels: tuple[Wheel, ...]) -> None:
        self._client = client
        self.body = body
        self._wheels = {w.link: w for w in wheels}
        self._links = list(self._wheels)

    def apply(self) -> None:
        """Friction forces from the last step's contacts and the current velocities."""
        loads: dict[int, list[float]] = {}
        for c in pb.getContactPoints(bodyA=self.body, physicsClientId=self._client):
            n = c[9]
            if n > 0 and c[3] in self._wheels:
                (px, py, pz), (nx, ny, nz) = c[5], c[7]
                acc = loads.get(c[3])
                if acc is None:
                    loads[c[3]] = [n, n * px, n * py, n * pz, n * nx, n * ny, n * nz]
                else:
                    acc[0] += n
                    acc[1] += n * px
                    acc[2] += n * py
                    acc[3] += n * pz
                    acc[4] += n * nx
                    acc[5] += n * ny
                    acc[6] += n * nz
        if not loads:
            return
        states = pb.getLinkStates(self.body, self._links, computeLinkVelocity=1, physicsClientId=self._client)
        for link, state in zip(self._links, states):
            acc = loads.get(link)
            if acc is not None:
                n = acc[0]
                self._apply_one(
                    self._wheels[link],
                    (acc[1] / n, acc[2] / n, acc[3] / n),
                    (acc[4] / n, acc[5] / n, acc[6] / n),
                    n,
                    state,
                )

    def _apply_one(self, wheel: Wheel, point: Vec3, normal: Vec3, load: float, state: tuple[Any, ...]) -> None:
        centre, linear, angular = state[0], state[6], state[7]
        m = pb.getMatrixFromQuaternion(state[5])
        a = wheel.axle
        axle = (
            m[0] * a[0] + m[1] * a[1] + m[2] * a[2],
            m[3] * a[0] + m[4] * a[1] + m[5] * a[2],
            m[6] * a[0] + m[7] * a[1] + m[8] * a[2],
        )
        along = _cross(axle, normal)
        norm = (along[0] * along[0] + along[1] * along[1] + along[2] * along[2]) ** 0.5
        if norm < 1e-6:  # touching with its side: no rolling direction
            return
        along = (along[0] / norm, along[1] / norm, along[2] / norm)
        across = _cross(normal, along)
        if wheel.fdir1:
            c, s = math.cos(wheel.fdir1), math.sin(wheel.fdir1)
            along, across = (
                (c * along[0] + s * across[0], c * along[1] + s * across[1], c * along[2] + s * across[2]),
                (c * across[0] - s * along[0], c * across[1] - s * along[1], c * across[2] - s * along[2]),
            )
        spin = _cross(angular, (point[0] - centre[0], point[1] - centre[1], point[2] - centre[2]))
        sx, sy, sz = linear[0] + spin[0], linear[1] + spin[1], linear[2] + spin[2]
        slip_along = (sx * along[0] + sy * along[1] + sz * along[2]) / SLIP_SPEED
        slip_across = (sx * across[0] + sy * across[1] + sz * across[2]) / SLIP_SPEED
        f1 = -wheel.mu * load * max(-1.0, min(1.0, slip_along))
        f2 = -wheel.mu2 * load * max(-1.0, min(1.0, slip_across))
        force = (f1 * along[0] + f2 * across[0], f1 * along[1] + f2 * across[1], f1 * along[2] + f2 * across[2])
        pb.applyExternalForce(self.body, wheel.link, force, point, pb.WORLD_FRAME, physicsClientId=self._client)
