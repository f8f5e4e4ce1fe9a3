"""Anisotropic wheel friction: SDF's μ along the rolling direction and μ2 across it.

Why this exists: PyBullet's multibody contacts have one isotropic friction coefficient and ignore
`anisotropicFriction`. With isotropic friction the four-wheel tug (wheels 1.16 m apart along x,
0.4 m across) cannot turn in place: scrubbing the wheels sideways needs more moment than the
wheels' traction gives (measured: 0.006 rad of 3.0 commanded in 6 s). The real wheels have μ 0.9
along and 0.25 across, and then the traction wins.

So for each wheel, PyBullet's own contact keeps only the normal force (its friction is 0), and
this model applies the friction force at the contact point before each step, as ODE's friction
pyramid does for SDF `mu`/`mu2`: along and across independently, each through the tyre's slip
curve (`tyre.Tyre`: linear in the slip ratio along and in the slip angle across, then saturating
at μ·N and μ2·N). Along and across turn by the angle of SDF's `fdir1` where a wheel states one
(mecanum rollers); the slip velocity is the wheel surface's over the ground at the contact (the
wheel's spin included, so a wheel driven faster than the ground under it pushes the robot), N the
wheel's normal force PyBullet reported at the last step (all its contact points summed, applied
at their load-weighted centre). Traction is bounded by μ × load, so walls and a pulled trolley
push back and the wheels spin.

The wheels' contacts are also given a tyre's vertical compliance (TYRE_STIFFNESS, critically
damped): a rigid four-wheeled chassis on rigid ground rocks between its diagonals, so the loads,
and with them the friction, flicker between pairs of wheels from step to step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from simbot.sim.bullet import pb
from simbot.sim.physics.tyre import Tyre
from simbot.transform import Vec3

TYRE_STIFFNESS = 2.0e5
"""N/m of vertical tyre compliance: a 110 kg tug sinks 1.3 mm on its four wheels."""


@dataclass(frozen=True)
class Wheel:
    """A wheel link (PyBullet index) and its SDF friction."""

    link: int
    tyre: Tyre
    axle: Vec3
    """The wheel's axis of rotation in its link frame."""
    fdir1: float = 0.0
    """Radians from the rolling direction to SDF's fdir1, about the contact normal: μ acts along
    fdir1 and μ2 across it. A mecanum wheel's rollers give 45° with μ2 0 (Gazebo's mecanum example)."""


Loads = dict[tuple[int, int], list[float]]
"""Per (body, wheel link): the normal force N summed over its contact points, then N × point and
N × normal summed (x, y, z each): the load-weighted centre and normal, seen from the wheel."""


class WheelFriction:
    """The wheels of one body; `apply` once before every physics step (plain floats: it runs at 1 kHz)."""

    def __init__(self, client: int, body: int, wheels: tuple[Wheel, ...], step: float) -> None:
        self._client = client
        self._step = step
        self.body = body
        self._wheels = {w.link: w for w in wheels}
        self.links = frozenset(self._wheels)
        self._links = list(self._wheels)

    def apply(self, loads: Loads) -> None:
        """Friction forces from the last step's contacts (`wheel_loads`) and the current velocities."""
        mine = [loads.get((self.body, link)) for link in self._links]
        if not any(mine):
            return
        states = pb.getLinkStates(self.body, self._links, computeLinkVelocity=1, physicsClientId=self._client)
        for link, state, acc in zip(self._links, states, mine):
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
        """One wheel's friction force, its vectors in plain floats (it runs for every wheel at 1 kHz)."""
        (cx, cy, cz), (qx, qy, qz, qw), (vx, vy, vz), (wx, wy, wz) = state[0], state[5], state[6], state[7]
        (px, py, pz), (nx, ny, nz), (ax, ay, az) = point, normal, wheel.axle
        tx, ty, tz = 2.0 * (qy * az - qz * ay), 2.0 * (qz * ax - qx * az), 2.0 * (qx * ay - qy * ax)
        ax, ay, az = (  # the axle in the world: a + w t + q × t, t = 2 q × a
            ax + qw * tx + qy * tz - qz * ty,
            ay + qw * ty + qz * tx - qx * tz,
            az + qw * tz + qx * ty - qy * tx,
        )
        lx, ly, lz = ay * nz - az * ny, az * nx - ax * nz, ax * ny - ay * nx  # along = axle × normal
        norm = (lx * lx + ly * ly + lz * lz) ** 0.5
        if norm < 1e-6:  # touching with its side: no rolling direction
            return
        lx, ly, lz = lx / norm, ly / norm, lz / norm
        sx, sy, sz = ny * lz - nz * ly, nz * lx - nx * lz, nx * ly - ny * lx  # across = normal × along
        if wheel.fdir1:
            c, s = math.cos(wheel.fdir1), math.sin(wheel.fdir1)
            lx, ly, lz, sx, sy, sz = (
                c * lx + s * sx, c * ly + s * sy, c * lz + s * sz, c * sx - s * lx, c * sy - s * ly, c * sz - s * lz,
            )  # fmt: skip
        rx, ry, rz = px - cx, py - cy, pz - cz
        ux, uy, uz = vx + wy * rz - wz * ry, vy + wz * rx - wx * rz, vz + wx * ry - wy * rx  # slip: v + ω × r
        ground = vx * lx + vy * ly + vz * lz  # the wheel centre's speed along
        along = ux * lx + uy * ly + uz * lz
        rolling = max(abs(ground), abs(ground - along))  # the ground's, or the wheel surface's
        f1, f2 = wheel.tyre.forces(along, ux * sx + uy * sy + uz * sz, rolling, load, self._step)
        force = (f1 * lx + f2 * sx, f1 * ly + f2 * sy, f1 * lz + f2 * sz)
        pb.applyExternalForce(self.body, wheel.link, force, point, pb.WORLD_FRAME, physicsClientId=self._client)


def wheel_loads(client: int, models: dict[int, WheelFriction]) -> Loads:
    """Every wheel's load from one contact query for the whole world. PyBullet answers a query
    for one body by walking every contact manifold of the world, so a query per robot cost a
    fleet O(robots²) a step (0.36 ms against 0.09 ms for twenty tugs). Seen from the wheel: where
    the wheel is PyBullet's body B, its point is the one on B and the normal turned round, as
    PyBullet's query for that body reports them."""
    loads: Loads = {}
    for c in pb.getContactPoints(physicsClientId=client):
        n = c[9]
        if n <= 0:
            continue
        model = models.get(c[1])
        if model is not None and c[3] in model.links:
            (nx, ny, nz) = c[7]
            _add_load(loads, (c[1], c[3]), n, c[5], (nx, ny, nz))
        model = models.get(c[2])
        if model is not None and c[4] in model.links:
            (nx, ny, nz) = c[7]
            _add_load(loads, (c[2], c[4]), n, c[6], (-nx, -ny, -nz))
    return loads


def _add_load(loads: Loads, key: tuple[int, int], n: float, point: Vec3, normal: Vec3) -> None:
    (px, py, pz), (nx, ny, nz) = point, normal
    acc = loads.get(key)
    if acc is None:
        loads[key] = [n, n * px, n * py, n * pz, n * nx, n * ny, n * nz]
        return
    acc[0] += n
    acc[1] += n * px
    acc[2] += n * py
    acc[3] += n * pz
    acc[4] += n * nx
    acc[5] += n * ny
    acc[6] += n * nz
