"""The steady turn a diff-driven model's SDF implies: its contacts' loads at rest, and where a
turn at a commanded speed and radius is centred, how far the body slides sideways and how its yaw
rate falls short of the command (docs/robot.md, "How the tug turns", derives it).

Why this exists: a skid-steer's turn is set by its tyres and loads, not by its drive's kinematics,
so the tests and the benchmark need the turn the SDF's masses, contacts and friction predict to
hold the simulated tug to. It solves the same tyre curve the physics applies (`tyre.Tyre`).
"""

from __future__ import annotations

import cmath
import logging
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from simbot.description.drive_params import DiffDriveParams
from simbot.description.model import Cylinder, Friction, Link, Model, Sphere
from simbot.description.naming import plugin_named
from simbot.sim.physics.loading import ball_castors
from simbot.sim.physics.tyre import G, Tyre
from simbot.transform import inverse3, matmul, yaw_of

logger = logging.getLogger(__name__)

Placed = tuple[tuple[float, ...], tuple[float, ...]]
"""A model's position (x, y, z) and quaternion (x, y, z, w), as the physics reports its pose."""

DAMPING = 1e-12
"""Levenberg-Marquardt's damping, relative to the Jacobian's scale: enough to step where it is singular."""

TOUCHING = 1e-3
"""m: a castor whose sphere's bottom is within this of the wheels' contact plane carries load."""


@dataclass(frozen=True)
class Contact:
    """Where a wheel or castor meets the floor, in the model frame (x, y); a castor has no tyre."""

    link: str
    x: float
    y: float
    tyre: Tyre | None
    side: float
    """−1 on DiffDrive's left, +1 on its right, 0 for a castor."""


@dataclass(frozen=True)
class Chassis:
    """What the turn depends on: the contacts, the mass and its centre (x, y, and z above the floor)."""

    contacts: tuple[Contact, ...]
    mass: float
    centre: tuple[float, float, float]
    separation: float
    """DiffDrive's wheel separation: the commanded wheel speeds are v ∓ ω · separation / 2."""

    @staticmethod
    def of(model: Model) -> Chassis:
        """The chassis of a model with a DiffDrive, its wheels cylinders about their axles."""
        plugin = plugin_named(model.plugins, "DiffDrive")
        if plugin is None:
            raise ValueError(f"model {model.name!r} has no DiffDrive")
        params = DiffDriveParams.parse(plugin, model, model.name)
        joints = {joint.name: joint for joint in model.joints}
        links = {link.name: link for link in model.links}
        wheels = [(links[joints[j].child], -1.0) for j in params.left] + [
            (links[joints[j].child], 1.0) for j in params.right
        ]
        floor = min(link.pose.xyz[2] - _radius(link.collisions[0].geometry) for link, _ in wheels)
        contacts = [_wheel(link, side) for link, side in wheels]
        for name in ball_castors(model):
            castor = links[joints[name].child]
            if castor.pose.xyz[2] - _radius(castor.collisions[0].geometry) - floor < TOUCHING:
                contacts.append(Contact(castor.name, castor.pose.xyz[0], castor.pose.xyz[1], None, 0.0))
        mass, centre = _mass_centre(model)
        return Chassis(tuple(contacts), mass, (centre[0], centre[1], centre[2] - floor), params.separation)

    def loads(self, lateral: float = 0.0, longitudinal: float = 0.0) -> npt.NDArray[np.float64]:
        """Each contact's normal force (N) under the weight and the inertial force of an
        acceleration (m/s², body frame) at the centre of mass: equal tyre compliances under a rigid
        chassis make the loads linear in position, N = a + b x + c y."""
        xs = np.array([c.x for c in self.contacts])
        ys = np.array([c.y for c in self.contacts])
        basis = np.stack([np.ones_like(xs), xs, ys])
        weight = self.mass * G
        x, y, h = self.centre
        wanted = np.array([weight, weight * x - self.mass * longitudinal * h, weight * y - self.mass * lateral * h])
        coefficients = matmul(inverse3(matmul(basis, basis.T)), wanted[:, np.newaxis])
        return matmul(coefficients.T, basis)[0]


@dataclass(frozen=True)
class SteadyTurn:
    """A turn held at a commanded speed and yaw rate: the body's velocity at the model frame's origin."""

    commanded_speed: float
    commanded_yaw_rate: float
    speed: float
    side_speed: float
    yaw_rate: float

    @property
    def pivot(self) -> float:
        """m ahead of the model frame: the point of the body's x axis that moves straight ahead."""
        return -self.side_speed / self.yaw_rate

    @property
    def side_slip(self) -> float:
        """The model frame's sideways over forward travel."""
        return abs(self.side_speed / self.speed)

    @property
    def yaw_ratio(self) -> float:
        """The yaw rate over the command."""
        return self.yaw_rate / self.commanded_yaw_rate

    @property
    def odom_yaw_ratio(self) -> float:
        """Wheel odometry's yaw rate, (v_right − v_left) / separation, over the true one."""
        return self.commanded_yaw_rate / self.yaw_rate

    @property
    def radius(self) -> float:
        """m: the true radius of the model frame's path."""
        return math.hypot(self.speed, self.side_speed) / abs(self.yaw_rate)


REFERENCE_TURN = (0.5, 3.0)
"""m/s and m: the turn odometry's error is stated for (walking speed, an aisle's corner)."""


@dataclass(frozen=True)
class SkidError:
    """How wheel odometry errs in a skid turn, per rad/s of its yaw rate: the yaw rate it over-
    reports (a fraction of it) and the sideways speed it misses (m/s per rad/s: the pivot's offset)."""

    yaw: float = 0.0
    side: float = 0.0


def skid_error(model: Model, step: float = 0.001) -> SkidError | None:
    """Odometry's error in the reference turn of `model`, what the twist's covariance says; None
    where the derivation does not apply (a wheel without the tyre: SDF μ = μ2 leaves it to
    PyBullet's friction) or finds no steady turn."""
    speed, radius = REFERENCE_TURN
    try:
        turn = steady_turn(Chassis.of(model), speed, speed / radius, step)
    except (ValueError, ArithmeticError) as exc:
        logger.info("model %r: no skid error for its odometry's covariance (%s)", model.name, exc)
        return None
    return SkidError(1.0 - turn.yaw_ratio, abs(turn.pivot))


def turn_centre(before: Placed, after: Placed) -> tuple[float, float]:
    """The measured counterpart of `SteadyTurn.pivot`: the point, in the model frame at `before`
    (x ahead, y to the left), that a rigid planar turn from pose `before` to `after` keeps in place.
    As complex numbers, p1 − c = e^{iθ}(p0 − c), so c − p0 = (p1 − p0) / (1 − e^{iθ})."""
    turn = yaw_of(after[1]) - yaw_of(before[1])
    moved = complex(after[0][0] - before[0][0], after[0][1] - before[0][1])
    centre = moved / (1.0 - cmath.exp(1j * turn)) * cmath.exp(-1j * yaw_of(before[1]))
    return centre.real, centre.imag


def steady_turn(chassis: Chassis, speed: float, yaw_rate: float, step: float = 0.001) -> SteadyTurn:
    """The steady turn at a commanded `speed` (m/s) and `yaw_rate` (rad/s, positive to the left)
    with the physics' explicit `step` (s): the body velocity at which the tyres' forces keep the
    centre of mass on its circle and balance their moments about it."""
    solution = _solve(lambda q: _residual(chassis, speed, yaw_rate, q, step), np.array([speed, 0.0, yaw_rate]))
    return SteadyTurn(speed, yaw_rate, float(solution[0]), float(solution[1]), float(solution[2]))


def _residual(
    chassis: Chassis, speed: float, yaw_rate: float, q: npt.NDArray[np.float64], step: float
) -> npt.NDArray[np.float64]:
    """Newton's second law in the turning body frame: Σ F = m ω × v_centre, Σ M_centre = 0 (N, N·m)."""
    u, v, w = q
    cx, cy, _ = chassis.centre
    centre_u, centre_v = u - w * cy, v + w * cx
    along, across = -w * centre_v, w * centre_u  # the centre's acceleration, m/s²
    fx = fy = moment = 0.0
    for contact, load in zip(chassis.contacts, chassis.loads(across, along)):
        if contact.tyre is None:
            continue
        surface = speed + contact.side * yaw_rate * chassis.separation / 2.0
        ground_u, ground_v = u - w * contact.y, v + w * contact.x
        f1, f2 = contact.tyre.forces(ground_u - surface, ground_v, max(abs(ground_u), abs(surface)), load, step)
        fx, fy = fx + f1, fy + f2
        moment += (contact.x - cx) * f2 - (contact.y - cy) * f1
    mass = chassis.mass
    return np.array([fx - mass * along, fy - mass * across, moment])


def _solve(
    residual: Callable[[npt.NDArray[np.float64]], npt.NDArray[np.float64]], guess: npt.NDArray[np.float64]
) -> npt.NDArray[np.float64]:
    """Levenberg-Marquardt's damped Newton steps with a numerical Jacobian, halving steps that do
    not reduce the residual (the tyre curve has kinks where it saturates; where every tyre slides
    sideways, as in a turn on the spot, the turn's centre is free and the damping picks the
    nearest)."""
    q, r = guess, residual(guess)
    for _ in range(200):
        if np.max(np.abs(r)) < 1e-9:
            return q
        h = 1e-7
        jacobian = np.stack([(residual(q + h * e) - residual(q - h * e)) / (2 * h) for e in np.eye(3)], axis=1)
        normal = matmul(jacobian.T, jacobian)
        delta = -matmul(
            inverse3(normal + DAMPING * np.trace(normal) * np.eye(3)), matmul(jacobian.T, r[:, np.newaxis])
        )[:, 0]
        for _ in range(40):
            trial = q + delta
            trial_r = residual(trial)
            if np.max(np.abs(trial_r)) < np.max(np.abs(r)):
                q, r = trial, trial_r
                break
            delta = delta / 2
        else:
            break
    if np.max(np.abs(r)) > 1e-6:
        raise ArithmeticError(f"no steady turn: residual {r} at {q}")
    return q


def _wheel(link: Link, side: float) -> Contact:
    """A wheel on the tyre, as the physics gives one to a wheel whose SDF μ and μ2 differ."""
    friction = next((c.friction for c in link.collisions if c.friction is not None), Friction())
    if friction.mu == friction.mu2:
        raise ValueError(f"wheel {link.name!r} has μ = μ2: PyBullet's friction, not the tyre")
    return Contact(link.name, link.pose.xyz[0], link.pose.xyz[1], Tyre.of(friction), side)


def _radius(geometry: object) -> float:
    if isinstance(geometry, (Cylinder, Sphere)):
        return geometry.radius
    raise ValueError(f"a wheel or castor must be a cylinder or a sphere, not {type(geometry).__name__}")


def _mass_centre(model: Model) -> tuple[float, tuple[float, float, float]]:
    """The model's mass and its centre in the model frame."""
    total, moment = 0.0, np.zeros(3)
    for link in model.links:
        if link.inertial is None:
            continue
        placed = (link.pose @ link.inertial.pose).xyz
        total += link.inertial.mass
        moment += link.inertial.mass * np.asarray(placed)
    x, y, z = (float(c) for c in moment / total)
    return total, (x, y, z)
