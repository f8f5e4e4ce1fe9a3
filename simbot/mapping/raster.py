"""The cells of a grid that convex polygons, discs and closed cross-sections cover, vectorised.

The cell rule, one for every shape: a cell is occupied iff the shape's footprint overlaps the
cell's open square by more than OVERLAP (1 nm) along every axis that could separate them. Touching
an edge or a corner does not count, so a wall whose face lies on a cell boundary (the warehouse's
at ±9.8 m on a 0.05 m grid) fills the cells behind the boundary and not the ones before it.

- Convex polygons: the separating axis test against every candidate cell of the polygon's
  bounding box at once (the cell's two axes and each edge's normal). A polygon may be degenerate:
  a segment (a vertical face cut by a plane) covers the cells it passes through the inside of.
- Discs: a cell is covered where its closest point to the centre is nearer than the radius.
- Closed cross-sections (the loops where a closed mesh crosses a plane): the cells whose centre is
  inside by the even-odd rule, row by row (the cells the loop itself crosses come from the
  surface's own polygons, so together they are the cells the section's area overlaps).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

Floats = npt.NDArray[np.float64]
Ints = npt.NDArray[np.int64]
Cells = npt.NDArray[np.bool_]

OVERLAP = 1e-9
"""Metres by which a footprint must reach into a cell to occupy it (touching does not)."""
SNAP = 1e-9
"""Cells of the resolution: a bound within this fraction of a cell of a cell edge is on it (−10 / 0.05 is not −200.000…1)."""
VALUES_PER_CHUNK = 1 << 21
"""(shape, cell, axis) values computed at once: bounds the memory of one pass (tens of MB)."""
CELL_AXES = np.array([[1.0, 0.0], [0.0, 1.0]])


@dataclass(frozen=True)
class Layout:
    """Where a grid lies: `origin` the world xy of cell (0, 0)'s lower-left corner; row r, column c
    spans x in origin_x + [c, c + 1]·resolution and y in origin_y + [r, r + 1]·resolution."""

    origin: tuple[float, float]
    resolution: float
    width: int
    height: int

    @staticmethod
    def around(bounds: tuple[float, float, float, float], resolution: float) -> Layout:
        """The smallest grid of whole cells, on multiples of `resolution`, holding (xmin, ymin, xmax, ymax)."""
        xmin, ymin, xmax, ymax = bounds
        c0, r0 = math.floor(xmin / resolution + SNAP), math.floor(ymin / resolution + SNAP)
        c1, r1 = math.ceil(xmax / resolution - SNAP), math.ceil(ymax / resolution - SNAP)
        return Layout((c0 * resolution, r0 * resolution), resolution, max(c1 - c0, 1), max(r1 - r0, 1))

    def empty(self) -> Cells:
        return np.zeros((self.height, self.width), dtype=bool)


def _cell_ranges(layout: Layout, lo: Floats, hi: Floats) -> tuple[Ints, Ints, Ints, Ints]:
    """First and last column and row (inclusive, clipped to the grid) of boxes lo..hi (n × 2)."""
    ox, oy = layout.origin
    res = layout.resolution
    c0 = np.clip(np.floor((lo[:, 0] - ox) / res), 0, layout.width).astype(np.int64)
    r0 = np.clip(np.floor((lo[:, 1] - oy) / res), 0, layout.height).astype(np.int64)
    c1 = np.clip(np.floor((hi[:, 0] - ox) / res), -1, layout.width - 1).astype(np.int64)
    r1 = np.clip(np.floor((hi[:, 1] - oy) / res), -1, layout.height - 1).astype(np.int64)
    return c0, c1, r0, r1


def _chunks(counts: Ints, budget: int) -> list[slice]:
    """Consecutive runs of shapes whose candidate cells add up to about `budget`."""
    ends = np.cumsum(counts)
    slices, start = [], 0
    while start < len(counts):
        base = ends[start - 1] if start else 0
        stop = max(int(np.searchsorted(ends, base + budget, side="right")), start + 1)
        slices.append(slice(start, stop))
        start = stop
    return slices


def _candidates(layout: Layout, lo: Floats, hi: Floats, axes: int = 1) -> list[tuple[Ints, Ints, Ints]]:
    """(shape index, column, row) of every cell in each shape's bounding box, in chunks of about
    VALUES_PER_CHUNK values for `axes` values per pair."""
    c0, c1, r0, r1 = _cell_ranges(layout, lo, hi)
    cols, rows = np.maximum(c1 - c0 + 1, 0), np.maximum(r1 - r0 + 1, 0)
    counts = cols * rows
    out = []
    for part in _chunks(counts, max(VALUES_PER_CHUNK // axes, 1)):
        n = counts[part]
        index = np.repeat(np.arange(part.start, part.stop), n)
        local = np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)
        out.append((index, c0[index] + local % cols[index], r0[index] + local // cols[index]))
    return out


def _centres(layout: Layout, cols: Ints, rows: Ints) -> tuple[Floats, Floats]:
    res = layout.resolution
    x = layout.origin[0] + (cols + 0.5).astype(np.float64) * res
    y = layout.origin[1] + (rows + 0.5).astype(np.float64) * res
    return x, y


def ordered(points: Floats) -> Floats:
    """Convex pieces given as the points that span them (n × k × 2, NaN where unused), each's points
    in order around it (by angle about their mean) and its unused ones repeating a used one: as
    `fill_polygons` takes them. A piece flattened to a segment keeps its two ends."""
    used = ~np.isnan(points[..., 0])
    points, used = points[used.any(axis=1)], used[used.any(axis=1)]
    first = points[np.arange(len(points)), used.argmax(axis=1)]
    points = np.where(used[..., None], points, first[:, None, :])
    centre = points.mean(axis=1, keepdims=True)
    angle = np.arctan2(points[..., 1] - centre[..., 1], points[..., 0] - centre[..., 0])
    return np.take_along_axis(points, np.argsort(angle, axis=1, kind="stable")[..., None], axis=1)


def padded(hulls: list[Floats]) -> Floats:
    """Convex polygons of different lengths as one n × k × 2 array, each padded with its last vertex."""
    if not hulls:
        return np.zeros((0, 1, 2))
    most = max(len(hull) for hull in hulls)
    return np.stack([np.vstack([hull, np.repeat(hull[-1:], most - len(hull), axis=0)]) for hull in hulls])


def fill_polygons(cells: Cells, layout: Layout, polygons: Floats) -> None:
    """Occupies the cells that convex polygons (n × k × 2, vertices in order around each, a short
    polygon padded by repeating a vertex) overlap."""
    if len(polygons) == 0:
        return
    edges = np.roll(polygons, -1, axis=1) - polygons
    length = np.hypot(edges[..., 0], edges[..., 1])
    normals = np.stack([-edges[..., 1], edges[..., 0]], axis=-1) / np.maximum(length, 1e-300)[..., None]
    normals[length < 1e-12] = CELL_AXES[0]  # a repeated vertex: no edge, a harmless axis
    axes = np.concatenate([normals, np.broadcast_to(CELL_AXES, (len(polygons), 2, 2))], axis=1)
    projected = axes[:, :, None, 0] * polygons[:, None, :, 0] + axes[:, :, None, 1] * polygons[:, None, :, 1]
    low, high = projected.min(axis=2), projected.max(axis=2)
    reach = layout.resolution / 2 * (np.abs(axes[..., 0]) + np.abs(axes[..., 1]))
    for index, cols, rows in _candidates(layout, polygons.min(axis=1), polygons.max(axis=1), axes.shape[1]):
        x, y = _centres(layout, cols, rows)
        centre = axes[index, :, 0] * x[:, None] + axes[index, :, 1] * y[:, None]
        apart = (centre + reach[index] <= low[index] + OVERLAP) | (centre - reach[index] >= high[index] - OVERLAP)
        hit = ~apart.any(axis=1)
        cells[rows[hit], cols[hit]] = True


def fill_discs(cells: Cells, layout: Layout, discs: Floats) -> None:
    """Occupies the cells that discs (n × 3: x, y, radius) overlap."""
    discs = discs[discs[:, 2] > OVERLAP] if len(discs) else discs
    if len(discs) == 0:
        return
    half = layout.resolution / 2
    for index, cols, rows in _candidates(layout, discs[:, :2] - discs[:, 2:], discs[:, :2] + discs[:, 2:]):
        x, y = _centres(layout, cols, rows)
        dx = np.maximum(np.abs(x - discs[index, 0]) - half, 0.0)
        dy = np.maximum(np.abs(y - discs[index, 1]) - half, 0.0)
        hit = dx * dx + dy * dy < (discs[index, 2] - OVERLAP) ** 2
        cells[rows[hit], cols[hit]] = True


def fill_section(cells: Cells, layout: Layout, segments: Floats) -> bool:
    """Occupies the cells whose centre is inside closed loops of segments (m × 2 × 2), by the
    even-odd rule; False (and nothing filled) where the loops are not closed (a row crossed an odd
    number of times: a mesh with holes has no inside)."""
    if len(segments) == 0:
        return True
    oy, res = layout.origin[1], layout.resolution
    p, q = segments[:, 0], segments[:, 1]
    low, high = np.minimum(p[:, 1], q[:, 1]), np.maximum(p[:, 1], q[:, 1])
    first = np.clip(np.ceil((low - oy) / res - 0.5), 0, layout.height).astype(np.int64)
    stop = np.clip(np.ceil((high - oy) / res - 0.5), 0, layout.height).astype(np.int64)
    n = np.maximum(stop - first, 0)  # rows whose centre is in [low, high): a shared vertex counts once
    index = np.repeat(np.arange(len(segments)), n)
    rows = first[index] + np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)
    if len(rows) == 0:
        return True
    if np.any(np.bincount(rows) % 2):
        return False
    y = oy + (rows + 0.5) * res
    a, b = p[index], q[index]
    x = a[:, 0] + (y - a[:, 1]) * (b[:, 0] - a[:, 0]) / (b[:, 1] - a[:, 1])
    order = np.lexsort((x, rows))
    rows, x = rows[order], x[order]
    ox = layout.origin[0]
    start = np.clip(np.ceil((x[0::2] - ox) / res - 0.5), 0, layout.width).astype(np.int64)
    end = np.clip(np.ceil((x[1::2] - ox) / res - 0.5), 0, layout.width).astype(np.int64)
    steps = np.zeros((layout.height, layout.width + 1), dtype=np.int32)
    np.add.at(steps, (rows[0::2], start), 1)
    np.add.at(steps, (rows[0::2], end), -1)
    cells |= np.cumsum(steps, axis=1)[:, :-1] > 0
    return True
