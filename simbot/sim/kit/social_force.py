"""Helbing & Molnár's social-force model of people walking, in the plane: the arithmetic alone, for
every person of a crowd in one pass (arrays, a row a person), however many there are.

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

Integrated by semi-implicit Euler (the velocity first, its speed clamped to `max_speed_factor`·v0:
`steered`; then the heading, `turned`, and the position at each of the caller's steps), after which
a hard constraint holds: the person is put back outside every other person (2·radius between
centres) and obstacle grown by its radius (`kept_clear`), and outside the robots' footprints at
every step (`outside`), so that a person the tug drives at steps aside rather than being walked
through. Numpy, no physics: the same inputs give the same outputs, bit for bit, on one machine.

Everyone thinks at once (`accelerations`): people against people as an n × m table, obstacles and
robots' outlines as pairs (a shadow and the person it is near), their forces summed per person.
Each person keeps its own parameters (`Params`: v0 is each script's own speed).

Shadows are rectangles (`Boxes`): a collision's box, or the box holding a round or tilted shape.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass, fields

import numpy as np
import numpy.typing as npt

from simbot.description.crowd_params import Crowd
from simbot.description.footprints import in_world

Floats = npt.NDArray[np.float64]
Bools = npt.NDArray[np.bool_]
Ints = npt.NDArray[np.int64]

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

    def take(self, index: Ints | Bools) -> Boxes:
        """The rectangles `index` picks (indices or a mask)."""
        return Boxes(self.centres[index], self.axes[index], self.halves[index])

    def placed(self, x: float, y: float, yaw: float) -> Boxes:
        """These rectangles, given in a body's frame, where the body stands at (x, y, yaw)."""
        return Boxes(in_world(self.centres, (x, y, yaw)), in_world(self.axes, (0.0, 0.0, yaw)), self.halves)

    def posed(self, frames: Floats) -> Boxes:
        """Each rectangle, given in its own body's frame, where that body stands (frames: n × (x, y, yaw))."""
        cos, sin = np.cos(frames[:, 2]), np.sin(frames[:, 2])
        (cx, cy), (ax, ay) = self.centres.T, self.axes.T
        centres = np.stack([cos * cx - sin * cy + frames[:, 0], sin * cx + cos * cy + frames[:, 1]], axis=1)
        return Boxes(centres, np.stack([cos * ax - sin * ay, sin * ax + cos * ay], axis=1), self.halves)

    def within(self, point: Floats, reach: Floats | float) -> Bools:
        """Which may have their nearest point within `reach` of `point` (by their bounding circles;
        one point and reach for all, or one each)."""
        offset = self.centres - point
        far = np.hypot(offset[:, 0], offset[:, 1]) - np.hypot(self.halves[:, 0], self.halves[:, 1])
        near: Bools = far <= reach
        return near

    def local(self, points: Floats) -> Floats:
        """`points` (… × 2, broadcast against the rectangles) in each rectangle's own frame."""
        offset = points - self.centres
        cos, sin = self.axes[:, 0], self.axes[:, 1]
        return np.stack([offset[..., 0] * cos + offset[..., 1] * sin, offset[..., 1] * cos - offset[..., 0] * sin], -1)

    def nearest(self, points: Floats) -> tuple[Floats, Floats]:
        """(distance, normal) of `points` (one point, a point a rectangle, or … × 1 × 2 against all)
        from each rectangle: the distance to its nearest point (negative inside, by the depth to its
        nearest side) and the unit vector from there out towards the point."""
        at = self.local(points)
        lx, ly = at[..., 0], at[..., 1]
        hx, hy = self.halves[:, 0], self.halves[:, 1]
        ox, oy = lx - np.clip(lx, -hx, hx), ly - np.clip(ly, -hy, hy)
        distance = np.hypot(ox, oy)
        out = distance > 0.0
        safe = np.where(out, distance, 1.0)
        depth_x, depth_y = hx - np.abs(lx), hy - np.abs(ly)
        by_y = depth_y < depth_x  # inside: out through the nearest side
        nx = np.where(out, ox / safe, np.where(by_y, 0.0, np.where(lx < 0, -1.0, 1.0)))
        ny = np.where(out, oy / safe, np.where(by_y, np.where(ly < 0, -1.0, 1.0), 0.0))
        distance = np.where(out, distance, -np.where(by_y, depth_y, depth_x))
        cos, sin = self.axes[:, 0], self.axes[:, 1]
        return distance, np.stack([nx * cos - ny * sin, nx * sin + ny * cos], -1)


@dataclass(frozen=True)
class Params:
    """Each of `Crowd`'s parameters as an array, a value a person (`Params.of`), and each one's
    `reach` and `obstacle_reach`: people of one crowd may differ (v0 is each script's own speed)."""

    values: dict[str, Floats]

    @staticmethod
    @functools.lru_cache(maxsize=64)
    def of(crowds: tuple[Crowd, ...]) -> Params:
        """The parameters of `crowds`, a person each (kept: a crowd thinks with the same people again)."""
        names = [item.name for item in fields(Crowd)] + ["reach", "obstacle_reach"]
        return Params({name: np.array([getattr(c, name) for c in crowds], dtype=np.float64) for name in names})

    def __getattr__(self, name: str) -> Floats:
        if name == "values":  # not yet set (a copy being made)
            raise AttributeError(name)
        try:
            return self.values[name]
        except KeyError:
            raise AttributeError(name) from None


@dataclass(frozen=True)
class People:
    """n people's state: positions and velocities (n × 2: m, m/s, in the world's plane), headings (n, rad)."""

    positions: Floats
    velocities: Floats
    yaws: Floats


@dataclass(frozen=True)
class Surroundings:
    """What n people keep their distance from, at one step."""

    others: Floats
    """m × 2: where everyone who may push stands (the n among them, or other people too)."""
    motions: Floats
    """n × m × 2: each one's velocity as each person saw it."""
    seen: Bools
    """n × m: whom each person looks at (not itself)."""
    obstacles: Boxes
    """The static shadows near the people, a rectangle a pair (the same rectangle again for another person)."""
    obstacle_of: Ints
    """The person each of `obstacles` is near."""
    outlines: Boxes
    """The robots' outlines (one rectangle holding a robot's footprint) near the people, a pair each."""
    outline_of: Ints


def block_diagonal(worlds: Sequence[tuple[Floats, Floats, Bools]]) -> tuple[Floats, Floats, Bools]:
    """Several worlds' people as one `Surroundings`' others, motions and seen (each world's m × 2,
    n × m × 2, n × m), its people numbered on: each person sees only its own world's others, so each
    comes out as in its world alone."""
    if len(worlds) == 1:
        return worlds[0]
    rows = np.cumsum([0] + [len(seen) for _, _, seen in worlds])
    columns = np.cumsum([0] + [len(others) for others, _, _ in worlds])
    seen = np.zeros((rows[-1], columns[-1]), bool)
    motions = np.zeros((rows[-1], columns[-1], 2))
    for (others, moved, looked), row, column in zip(worlds, rows, columns):
        seen[row : row + len(looked), column : column + len(others)] = looked
        motions[row : row + len(looked), column : column + len(others)] = moved
    return np.concatenate([others for others, _, _ in worlds]), motions, seen


def driving(p: Params, people: People, goals: Floats, arriving: Bools) -> tuple[Floats, Floats]:
    """(the driving accelerations, e): towards `goals` at the desired speed, slowing into those `arriving`."""
    to_goal = goals - people.positions
    distance = np.hypot(to_goal[:, 0], to_goal[:, 1])
    direction = to_goal / np.where(distance > 0, distance, 1.0)[:, None]
    speed = np.where(arriving, np.minimum(p.desired_speed, distance / p.relaxation_time), p.desired_speed)
    return (speed[:, None] * direction - people.velocities) / p.relaxation_time[:, None], direction


def _repulsion(
    strength: Floats, reach: Floats, gaps: Floats, normals: Floats, weights: Floats, cutoff: Floats | float = math.inf
) -> Floats:
    """strength·(exp(−gap/reach) − exp(−cutoff/reach))·w·n for each gap (none past `cutoff`)."""
    magnitude = strength * np.maximum(np.exp(-gaps / reach) - np.exp(-cutoff / reach), 0.0) * weights
    pushed: Floats = normals * magnitude[..., None]
    return pushed


def _anisotropy(anisotropy: Floats, direction: Floats, normals: Floats) -> Floats:
    """λ + (1 − λ)(1 + cos φ)/2, φ between the walking direction and the way to each other (−n)."""
    cos = -(normals * direction).sum(axis=-1)
    weights: Floats = anisotropy + (1 - anisotropy) * (1 + cos) / 2
    return weights


def _look_ahead(offset: Floats, distance: Floats, motion: Floats, step: Floats) -> tuple[Floats, Floats]:
    """Helbing & Molnár's ellipse through me with foci at each other person and where it will be `step`
    seconds on: (its semi-minor axis b, 2b = √((|r| + |r − v·Δt|)² − |v·Δt|²), and the direction b
    grows fastest, the bisector of r and r − v·Δt). Someone walking towards me is nearer than they
    stand, and pushes me aside of their path rather than back along it."""
    ahead = motion * step[..., None]
    later = offset - ahead
    gone = np.hypot(later[..., 0], later[..., 1])
    semi: Floats = 0.5 * np.sqrt(np.maximum((distance + gone) ** 2 - (ahead**2).sum(axis=-1), 0.0))
    bisector = offset / np.maximum(distance, 1e-9)[..., None] + later / np.maximum(gone, 1e-9)[..., None]
    length = np.hypot(bisector[..., 0], bisector[..., 1])
    normal: Floats = np.where(
        (length > 1e-9)[..., None],
        bisector / np.maximum(length, 1e-9)[..., None],
        offset / np.maximum(distance, 1e-9)[..., None],
    )
    return semi, normal


def _per_person(count: int, owners: Ints, forces: Floats) -> Floats:
    """The pairs' `forces` (k × 2) summed for each of `count` people (`owners`: each pair's person)."""
    return np.stack([np.bincount(owners, forces[:, axis], minlength=count) for axis in range(2)], axis=1)


def _people_near(p: Params, positions: Floats, around: Surroundings) -> tuple[Floats, Floats, Bools]:
    """(offsets from each other person, n × m × 2; distances; whom each person sees within its reach)."""
    offset = positions[:, None, :] - around.others[None, :, :]
    distance = np.hypot(offset[..., 0], offset[..., 1])
    return offset, distance, around.seen & (distance <= p.reach[:, None])


def accelerations(p: Params, people: People, goals: Floats, arriving: Bools, around: Surroundings) -> Floats:
    """The social force on each person per unit mass (see the module docstring)."""
    drive, direction = driving(p, people, goals, arriving)
    offset, distance, seen = _people_near(p, people.positions, around)
    semi, normal = _look_ahead(offset, distance, around.motions, p.look_ahead[:, None])
    row = (slice(None), None)
    pushed = _repulsion(
        p.people_strength[row],
        p.people_range[row],
        semi - 2 * p.radius[row],
        normal,
        _anisotropy(p.anisotropy[row], direction[:, None, :], normal) * seen,
    )
    total: Floats = drive + pushed.sum(axis=1)
    for boxes, owner, kind in (
        (around.obstacles, around.obstacle_of, "obstacle"),
        (around.outlines, around.outline_of, "robot"),
    ):
        if not len(boxes):
            continue
        gap, normal = boxes.nearest(people.positions[owner])
        cutoff = p.obstacle_cutoff[owner] if kind == "obstacle" else math.inf
        forces = _repulsion(
            p.values[f"{kind}_strength"][owner],
            p.values[f"{kind}_range"][owner],
            gap - p.radius[owner],
            normal,
            _anisotropy(p.anisotropy[owner], direction[owner], normal),
            cutoff,
        )
        total = total + _per_person(len(total), owner, forces)
    return total


def steered(p: Params, velocities: Floats, accel: Floats, dt: Floats | float, kicks: Floats) -> Floats:
    """The velocities after `dt` s of `accel`, plus the random `kicks`: no speed over `max_speed_factor`·v0."""
    velocities = velocities + accel * np.reshape(dt, (-1, 1)) + kicks
    speed = np.hypot(velocities[:, 0], velocities[:, 1])
    top = p.max_speed_factor * p.desired_speed
    scale: Floats = np.where(speed > top, top / np.where(speed > 0, speed, 1.0), 1.0)
    return velocities * scale[:, None]


def turned(p: Params, yaws: Floats, velocities: Floats, dt: Floats | float) -> Floats:
    """The headings turned towards the velocities at no more than `turn_rate`; kept when barely moving."""
    wanted = np.arctan2(velocities[:, 1], velocities[:, 0])
    error = np.arctan2(np.sin(wanted - yaws), np.cos(wanted - yaws))
    limit = p.turn_rate * dt
    turn = yaws + np.clip(error, -limit, limit)
    moving = np.hypot(velocities[:, 0], velocities[:, 1]) >= RESTING_SPEED
    result: Floats = np.where(moving, np.arctan2(np.sin(turn), np.cos(turn)), yaws)
    return result


def crosses(start: Floats, end: Floats, half: Floats) -> Bools:
    """Whether each segment start → end (… × 2, in a rectangle's frame) passes through the rectangle
    of `half` extents (… × 2)."""
    span = end - start
    flat = np.abs(span) < 1e-12
    with np.errstate(divide="ignore", invalid="ignore"):
        a, b = (-half - start) / span, (half - start) / span
    clear = np.abs(start) >= half  # parallel to a side: in its slab or never
    low = np.where(flat, np.where(clear, np.inf, -np.inf), np.minimum(a, b))
    high = np.where(flat, np.where(clear, -np.inf, np.inf), np.maximum(a, b))
    through: Bools = np.maximum(low.max(axis=-1), 0.0) < np.minimum(high.min(axis=-1), 1.0)
    return through


CORNERS = np.array([(-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)])


def detours(p: Params, positions: Floats, goals: Floats, outlines: Boxes, outline_of: Ints) -> tuple[Floats, Bools]:
    """(where each person heads for on the way to its goal, whether that is round a robot): round the nearest robot whose footprint,
    grown by the radius and as far again as its repulsion is half the drive, lies across the straight
    way, by its corner that makes the way round shortest (one not yet reached; from a corner reached,
    those seen along the sides from it); the goal itself when the way is clear. The forces alone would
    hold a person still before a long machine across its way (the social-force model's local minimum).
    Every pair is tested at once; the corners are chosen for the few whose way is crossed."""
    margin = p.radius + p.robot_range * np.log(
        np.maximum(1.0, 2 * p.robot_strength * p.relaxation_time / p.desired_speed)
    )
    headings = goals.copy()
    best = np.full(len(positions), np.inf)
    if not len(outlines):
        return headings, best < np.inf
    half = outlines.halves + margin[outline_of][:, None]
    start = outlines.local(positions[outline_of])
    end = outlines.local(goals[outline_of])
    across = ~np.all(np.abs(start) < half, axis=1) & crosses(start, end, half)
    for pair in np.flatnonzero(across):
        person = int(outline_of[pair])
        found = _corner(p.waypoint_tolerance[person], start[pair], end[pair], half[pair])
        if found is not None and found[0] < best[person]:
            (cos, sin), centre = outlines.axes[pair], outlines.centres[pair]
            best[person] = found[0]
            headings[person] = np.array([[cos, -sin], [sin, cos]]) @ found[1] + centre
    return headings, best < np.inf


def _corner(tolerance: float, start: Floats, end: Floats, half: Floats) -> tuple[float, Floats] | None:
    """(how far, which) corner of the rectangle of `half` extents the way from `start` to `end` goes
    round (its frame), or None where no corner is seen from where the person stands."""
    corners = CORNERS * half
    distances = np.hypot(*(corners - start).T)
    reached = np.flatnonzero(distances <= tolerance)
    origin = start if not len(reached) else corners[reached[0]]  # on at a corner: what lies along the side from it
    seen = ~crosses(np.broadcast_to(origin, corners.shape), corners, np.broadcast_to(half * (1 - 1e-6), corners.shape))
    if len(reached):
        seen[reached[0]] = False
    if not seen.any():
        return None
    ways = np.where(seen, distances + np.hypot(*(end - corners).T), np.inf)
    chosen = int(np.argmin(ways))
    return float(distances[chosen]), corners[chosen]


def kept_clear(p: Params, positions: Floats, around: Surroundings) -> Floats:
    """`positions` moved out of every other person (2·radius), then every obstacle grown by the
    radius: the hard constraint after the force step."""
    offset, distance, seen = _people_near(p, positions, around)
    normal = np.where((distance > 0)[..., None], offset / np.where(distance > 0, distance, 1.0)[..., None], (1.0, 0.0))
    gap = np.where(seen, 2 * p.radius[:, None] - distance, 0.0)
    moved: Floats = positions + (normal * np.maximum(gap, 0.0)[..., None]).sum(axis=1)
    return outside(p.radius, moved, around.obstacles, around.obstacle_of)


def outside(radius: Floats, positions: Floats, boxes: Boxes, owners: Ints) -> Floats:
    """`positions` moved out of the `boxes` grown by each one's `radius`, in turn (`owners`: the
    person each box is for)."""
    if not len(boxes):
        return positions
    positions = positions.copy()
    gaps, _ = boxes.nearest(positions[owners])
    for pair in np.flatnonzero(gaps < radius[owners]):  # rare: only these are looked at again
        person = owners[pair]
        gap, normal = boxes.take(np.array([pair])).nearest(positions[person])
        if gap[0] < radius[person]:
            positions[person] = positions[person] + (radius[person] - gap[0]) * normal[0]
    return positions


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
