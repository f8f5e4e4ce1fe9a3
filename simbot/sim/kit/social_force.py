"""Helbing & Molnár's social-force model of people walking, in the plane: the arithmetic alone.

A person is a disc of `radius` at a position with a velocity. Its acceleration is the sum of

- a driving term (v0·e − v)/τ towards its goal (e the unit vector to it, v0 its desired speed,
  τ its relaxation time), slowing to arrive where the goal is the last;
- a repulsion A·exp((r_ij − d_ij)/B)·n_ij from each other person j (d_ij the distance between
  centres, r_ij the two radii, n_ij the unit vector from j to i), weighted by the anisotropy
  w = λ + (1 − λ)(1 + cos φ)/2 (φ between e and −n_ij: who is ahead counts more than who is behind);
- a repulsion A_w·(exp((r − d)/B_w) − exp(−c/B_w))·w·n from each obstacle whose gap d − r is
  under the cutoff c (d the distance to the nearest point of its shadow on the floor, n the unit
  vector from that point; the taper makes it vanish at c without a jump), so that a person walking
  past a rack face more than c clear keeps its line; and the same with the robots' own strength and
  range, without a cutoff, from each body that moves by itself (a robot, a cart), from the one
  rectangle holding its footprint (its outline: one force a body, however many shapes it has).

Integrated by semi-implicit Euler (the velocity first, its speed clamped to `max_speed_factor`·v0,
then the position with it: `steered`, then `turned` and the position at each of the caller's
steps), after which a hard constraint holds: the person is put back outside
every other person (2·radius between centres), obstacle and robot grown by its radius, robots
last, so that a person the tug drives at steps aside rather than being walked through. Numpy, no
physics: the same inputs give the same outputs, bit for bit, on one machine.

Shadows are rectangles (`Boxes`): a collision's box, or the box holding a round or tilted shape.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from simbot.description.crowd_params import Crowd

Floats = npt.NDArray[np.float64]

RESTING_SPEED = 0.05
"""m/s: below this a person keeps its heading (a standing person does not spin with the jitter)."""


@dataclass(frozen=True)
class Boxes:
    """Rectangles on the floor (n of them): shadows a person keeps out of."""

    centres: Floats
    """n × 2."""
    axes: Floats
    """n × 2: each rectangle's x axis (cos, sin of its yaw)."""
    halves: Floats
    """n × 2: half its extent along its own x and y."""

    @staticmethod
    def of(rectangles: Sequence[tuple[float, float, float, float, float]]) -> Boxes:
        """From (x, y, yaw, half length, half width) each."""
        table = np.asarray(rectangles, dtype=np.float64).reshape(-1, 5)
        axes = np.stack([np.cos(table[:, 2]), np.sin(table[:, 2])], axis=1)
        return Boxes(table[:, :2].copy(), axes, table[:, 3:5].copy())

    @staticmethod
    def joined(parts: Sequence[Boxes]) -> Boxes:
        """All the rectangles of `parts`, in one."""
        if not parts:
            return Boxes.of([])
        return Boxes(*(np.concatenate([getattr(b, name) for b in parts]) for name in ("centres", "axes", "halves")))

    def outline(self) -> Boxes:
        """The one rectangle, along this frame's axes, holding them all (a machine's whole footprint)."""
        if not len(self):
            return self
        extent = np.abs(self.axes[:, :1] * self.halves[:, :1]) + np.abs(self.axes[:, 1:] * self.halves[:, 1:])
        reach = np.abs(self.axes[:, 1:] * self.halves[:, :1]) + np.abs(self.axes[:, :1] * self.halves[:, 1:])
        low = (self.centres - np.hstack([extent, reach])).min(axis=0)
        high = (self.centres + np.hstack([extent, reach])).max(axis=0)
        return Boxes.of([((low[0] + high[0]) / 2, (low[1] + high[1]) / 2, 0.0, *((high - low) / 2))])

    def __len__(self) -> int:
        return len(self.centres)

    def placed(self, x: float, y: float, yaw: float) -> Boxes:
        """These rectangles, given in a body's frame, where the body stands at (x, y, yaw)."""
        c, s = math.cos(yaw), math.sin(yaw)
        rotation = np.array([[c, -s], [s, c]])
        return Boxes(self.centres @ rotation.T + (x, y), self.axes @ rotation.T, self.halves)

    def within(self, point: Floats, reach: float) -> Boxes:
        """Those whose nearest point may lie within `reach` of `point` (by their bounding circles)."""
        far = np.hypot(*(self.centres - point).T) - np.hypot(*self.halves.T)
        keep = far <= reach
        return Boxes(self.centres[keep], self.axes[keep], self.halves[keep])

    def nearest(self, point: Floats) -> tuple[Floats, Floats]:
        """(distance, normal) of `point` from each rectangle: the distance to its nearest point (negative
        inside, by the depth to its nearest side) and the unit vector from there out towards `point`.
        In plain floats, rectangle by rectangle: a person has a handful near it, where numpy's
        per-call cost is most of the work."""
        px, py = float(point[0]), float(point[1])
        rows = [
            _from_rectangle(px - cx, py - cy, cos, sin, hx, hy)
            for (cx, cy), (cos, sin), (hx, hy) in zip(self.centres.tolist(), self.axes.tolist(), self.halves.tolist())
        ]
        table = np.asarray(rows, dtype=np.float64).reshape(-1, 3)
        return table[:, 0].copy(), table[:, 1:].copy()


def _from_rectangle(dx: float, dy: float, cos: float, sin: float, hx: float, hy: float) -> tuple[float, float, float]:
    """(distance, normal x, normal y) of the offset (dx, dy) from a rectangle's centre (see `Boxes.nearest`)."""
    lx, ly = dx * cos + dy * sin, dy * cos - dx * sin
    ox, oy = lx - max(-hx, min(hx, lx)), ly - max(-hy, min(hy, ly))
    distance = math.hypot(ox, oy)
    if distance > 0.0:
        nx, ny = ox / distance, oy / distance
    else:  # inside: out through the nearest side
        depth_x, depth_y = hx - abs(lx), hy - abs(ly)
        if depth_y < depth_x:
            distance, nx, ny = -depth_y, 0.0, (-1.0 if ly < 0 else 1.0)
        else:
            distance, nx, ny = -depth_x, (-1.0 if lx < 0 else 1.0), 0.0
    return distance, nx * cos - ny * sin, nx * sin + ny * cos


@dataclass(frozen=True)
class Walker:
    """A person's state: position and velocity (m, m/s, in the world's plane) and heading (rad)."""

    position: Floats
    velocity: Floats
    yaw: float


@dataclass(frozen=True)
class Surroundings:
    """What a person keeps its distance from, at one step."""

    people: Floats
    """k × 2: the other people's positions."""
    motions: Floats
    """k × 2: their velocities."""
    obstacles: Boxes
    robots: Boxes
    outlines: Boxes
    """One rectangle per robot, holding its footprint: what a person walks round (`detour`)."""


def driving(crowd: Crowd, walker: Walker, goal: Floats, arriving: bool) -> tuple[Floats, Floats]:
    """(the driving acceleration, e): towards `goal` at the desired speed, slowing into it when `arriving`."""
    to_goal = goal - walker.position
    distance = float(np.hypot(*to_goal))
    direction = to_goal / distance if distance > 0 else np.zeros(2)
    speed = crowd.desired_speed
    if arriving:
        speed = min(speed, distance / crowd.relaxation_time)
    return (speed * direction - walker.velocity) / crowd.relaxation_time, direction


def _repulsion(
    strength: float, reach: float, gaps: Floats, normals: Floats, weights: Floats, cutoff: float = math.inf
) -> Floats:
    """Σ strength·(exp(−gap/reach) − exp(−cutoff/reach))·w·n over the gaps under `cutoff`."""
    if len(gaps) == 0:
        return np.zeros(2)
    magnitude = strength * np.maximum(np.exp(-gaps / reach) - math.exp(-cutoff / reach), 0.0) * weights
    total: Floats = (normals * magnitude[:, None]).sum(axis=0)
    return total


def _anisotropy(crowd: Crowd, direction: Floats, normals: Floats) -> Floats:
    """λ + (1 − λ)(1 + cos φ)/2, φ between the walking direction and the way to each other (−n)."""
    cos = -(normals @ direction)
    weights: Floats = crowd.anisotropy + (1 - crowd.anisotropy) * (1 + cos) / 2
    return weights


def _look_ahead(offset: Floats, distance: Floats, motion: Floats, step: float) -> tuple[Floats, Floats]:
    """Helbing & Molnár's ellipse through me with foci at each other person and where it will be `step`
    seconds on: (its semi-minor axis b, 2b = √((|r| + |r − v·Δt|)² − |v·Δt|²), and the direction b
    grows fastest, the bisector of r and r − v·Δt). Someone walking towards me is nearer than they
    stand, and pushes me aside of their path rather than back along it."""
    ahead = motion * step
    later = offset - ahead
    gone = np.hypot(*later.T) if len(later) else np.zeros(0)
    semi: Floats = 0.5 * np.sqrt(np.maximum((distance + gone) ** 2 - (ahead**2).sum(axis=1), 0.0))
    bisector = offset / np.maximum(distance, 1e-9)[:, None] + later / np.maximum(gone, 1e-9)[:, None]
    length = np.hypot(*bisector.T) if len(bisector) else np.zeros(0)
    normal: Floats = np.where(
        (length > 1e-9)[:, None],
        bisector / np.maximum(length, 1e-9)[:, None],
        offset / np.maximum(distance, 1e-9)[:, None],
    )
    return semi, normal


def _from_people(point: Floats, people: Floats) -> tuple[Floats, Floats]:
    """(distance between centres, unit vector from each person to `point`)."""
    offset = point - people
    distance = np.hypot(*offset.T) if len(people) else np.zeros(0)
    safe = np.where(distance > 0, distance, 1.0)
    normal = np.where((distance > 0)[:, None], offset / safe[:, None], np.array([1.0, 0.0]))
    return distance, normal


def acceleration(crowd: Crowd, walker: Walker, goal: Floats, arriving: bool, around: Surroundings) -> Floats:
    """The social force on `walker` per unit mass (see the module docstring)."""
    drive, direction = driving(crowd, walker, goal, arriving)
    distance, normal = _from_people(walker.position, around.people)
    semi, normal = _look_ahead(walker.position - around.people, distance, around.motions, crowd.look_ahead)
    people = _repulsion(
        crowd.people_strength,
        crowd.people_range,
        semi - 2 * crowd.radius,
        normal,
        _anisotropy(crowd, direction, normal),
    )
    distance, normal = around.obstacles.nearest(walker.position)
    walls = _repulsion(
        crowd.obstacle_strength,
        crowd.obstacle_range,
        distance - crowd.radius,
        normal,
        _anisotropy(crowd, direction, normal),
        crowd.obstacle_cutoff,
    )
    distance, normal = around.outlines.nearest(walker.position)
    robots = _repulsion(
        crowd.robot_strength, crowd.robot_range, distance - crowd.radius, normal, _anisotropy(crowd, direction, normal)
    )
    total: Floats = drive + people + walls + robots
    return total


def steered(crowd: Crowd, velocity: Floats, accel: Floats, dt: float, kick: Floats) -> Floats:
    """The velocity after `dt` s of `accel`, plus the random `kick`: the speed no more than `max_speed_factor`·v0."""
    velocity = velocity + accel * dt + kick
    speed = float(np.hypot(*velocity))
    top = crowd.max_speed_factor * crowd.desired_speed
    if speed > top:
        velocity = velocity * (top / speed)
    return velocity


def advance(crowd: Crowd, walker: Walker, accel: Floats, dt: float, kick: Floats) -> Walker:
    """One semi-implicit Euler step of `dt` s (`steered`, then the position with the new velocity),
    the heading turned towards the velocity."""
    velocity = steered(crowd, walker.velocity, accel, dt, kick)
    return Walker(walker.position + velocity * dt, velocity, turned(crowd, walker.yaw, velocity, dt))


def turned(crowd: Crowd, yaw: float, velocity: Floats, dt: float) -> float:
    """The heading turned towards the velocity at no more than `turn_rate`; kept when barely moving."""
    vx, vy = float(velocity[0]), float(velocity[1])
    if math.hypot(vx, vy) < RESTING_SPEED:
        return yaw
    wanted = math.atan2(vy, vx)
    error = math.atan2(math.sin(wanted - yaw), math.cos(wanted - yaw))
    limit = crowd.turn_rate * dt
    turned = yaw + max(-limit, min(limit, error))
    return math.atan2(math.sin(turned), math.cos(turned))


def _crosses(start: Floats, end: Floats, half: Floats) -> bool:
    """Whether the segment start → end (in a rectangle's frame) passes through the rectangle of `half` extents."""
    enter, leave = 0.0, 1.0
    for axis in range(2):
        span = end[axis] - start[axis]
        if abs(span) < 1e-12:
            if abs(start[axis]) >= half[axis]:
                return False
            continue
        a, b = (-half[axis] - start[axis]) / span, (half[axis] - start[axis]) / span
        enter, leave = max(enter, min(a, b)), min(leave, max(a, b))
    return enter < leave


def detour(crowd: Crowd, point: Floats, goal: Floats, robots: Boxes) -> Floats:
    """Where to head for on the way to `goal`: round the nearest robot whose footprint, grown by the
    radius and as far again as its repulsion is half the drive, lies across the straight way, by its
    corner that makes the way round shortest (one not yet reached; from a corner reached, those seen
    along the sides from it); the goal itself when the way is clear. The forces alone would hold a
    person still before a long machine across its way (the social-force model's local minimum)."""
    margin = crowd.radius + crowd.robot_range * math.log(
        max(1.0, 2 * crowd.robot_strength * crowd.relaxation_time / crowd.desired_speed)
    )
    best: tuple[float, Floats] | None = None
    for index in range(len(robots)):
        (cos, sin), half = robots.axes[index], robots.halves[index] + margin
        rotation = np.array([[cos, -sin], [sin, cos]])
        start, end = (point - robots.centres[index]) @ rotation, (goal - robots.centres[index]) @ rotation
        if np.all(np.abs(start) < half) or not _crosses(start, end, half):
            continue
        corners = [np.array((sx * half[0], sy * half[1])) for sx in (-1, 1) for sy in (-1, 1)]
        reached = next((c for c in corners if np.hypot(*(c - start)) <= crowd.waypoint_tolerance), None)
        origin = start if reached is None else reached  # on at a corner: what lies along the side from it
        seen = [c for c in corners if c is not reached and not _crosses(origin, c, half * (1 - 1e-6))]
        if not seen:
            continue
        corner = min(seen, key=lambda c: float(np.hypot(*(c - start)) + np.hypot(*(end - c))))
        away = float(np.hypot(*(corner - start)))
        if best is None or away < best[0]:
            best = (away, rotation @ corner + robots.centres[index])
    return goal if best is None else best[1]


def kept_clear(crowd: Crowd, point: Floats, around: Surroundings) -> Floats:
    """`point` moved out of every other person (2·radius), then every obstacle and robot grown by the
    radius, robots last: the hard constraint after the force step."""
    distance, normal = _from_people(point, around.people)
    for gap, n in zip(2 * crowd.radius - distance, normal):
        if gap > 0:
            point = point + gap * n
    return outside(crowd, outside(crowd, point, around.obstacles), around.robots)


def outside(crowd: Crowd, point: Floats, boxes: Boxes) -> Floats:
    """`point` moved out of each of `boxes` grown by the radius, in turn."""
    if len(boxes):
        distance, _ = boxes.nearest(point)
        for index in np.flatnonzero(distance < crowd.radius):  # rare: only these are looked at again
            one = Boxes(
                boxes.centres[index : index + 1], boxes.axes[index : index + 1], boxes.halves[index : index + 1]
            )
            gap, normal = one.nearest(point)
            if gap[0] < crowd.radius:
                point = point + (crowd.radius - gap[0]) * normal[0]
    return point


@dataclass(frozen=True)
class Route:
    """Waypoints walked in turn (x, y each), from the first again where it loops."""

    points: Floats
    """n × 2."""
    loop: bool

    @staticmethod
    def of(points: Sequence[tuple[float, float]], loop: bool) -> Route:
        """Consecutive repeats dropped (a script turning on the spot), and the closing point where it loops."""
        kept: list[tuple[float, float]] = []
        for point in points:
            if not kept or math.dist(kept[-1], point) > 1e-6:
                kept.append(point)
        if loop and len(kept) > 1 and math.dist(kept[0], kept[-1]) <= 1e-6:
            kept.pop()
        return Route(np.asarray(kept, dtype=np.float64).reshape(-1, 2), loop)

    def arriving(self, index: int) -> bool:
        """Whether waypoint `index` is the last one walked to (no loop)."""
        return not self.loop and index == len(self.points) - 1

    def after(self, index: int, position: Floats, tolerance: float) -> int:
        """The goal's index once the person at `position` has reached waypoint `index` (within `tolerance`)."""
        if float(np.hypot(*(self.points[index] - position))) > tolerance or self.arriving(index):
            return index
        return (index + 1) % len(self.points)

    def ahead(self, position: Floats, tolerance: float) -> int:
        """The waypoint a person standing at `position` on the route walks to first: the end of the
        leg nearest to it (the first such leg on a tie), so that one who starts part of the way round
        (a randomised world's starting phase) walks on, not back to the route's first point."""
        count = len(self.points)
        if count < 2:
            return 0
        legs = range(count if self.loop else count - 1)
        nearest = min(legs, key=lambda i: _to_segment(position, self.points[i], self.points[(i + 1) % count]))
        return self.after((nearest + 1) % count, position, tolerance)


def _to_segment(point: Floats, start: Floats, end: Floats) -> float:
    """The distance from `point` to the segment from `start` to `end`."""
    ax, ay = float(end[0] - start[0]), float(end[1] - start[1])
    px, py = float(point[0] - start[0]), float(point[1] - start[1])
    length2 = ax * ax + ay * ay
    t = 0.0 if length2 == 0.0 else min(1.0, max(0.0, (px * ax + py * ay) / length2))
    return math.hypot(t * ax - px, t * ay - py)
