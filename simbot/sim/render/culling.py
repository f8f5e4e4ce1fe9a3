"""Which parts of the scene a camera's view can show: each part's bounding sphere against the view's
frustum, and the static world cut into cells so that there is something to cut.

llvmpipe shades every vertex it is given and bins every triangle, seen or not: the robot's own
links (half the warehouse's vertices) lie behind or beside most of its six cameras, and a shelf
row behind a camera is as costly to skip as it is to draw. A part whose sphere lies wholly
outside one of the frustum's six planes is not drawn. The spheres are loose (centred on the
vertices' box, radius to the farthest vertex), so a part that shows a single pixel is drawn.

The static world is batched per material and per cell of `CELL_M` metres (a visual falls in the
cell of its centre, whole): a camera draws the cells it can see, nearest first.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from simbot.transform import Matrix, matmul

CELL_M = 16.0
"""Edge of a cell of the static world: two shelf rows. Smaller cells cull more and cost more
draws (about 7.5 µs each on llvmpipe); 4, 8, 16 m and one cell cost the same within the noise
on the warehouse at 640×480, where the pixels, not the vertices, take most of a frame."""

Cell = tuple[int, int]


def cell_of(positions: npt.NDArray[np.floating]) -> Cell:
    """The cell (x, y) of the middle of the points' box, in the world frame."""
    middle = _middle(positions)
    return (math.floor(float(middle[0]) / CELL_M), math.floor(float(middle[1]) / CELL_M))


def _middle(points: npt.NDArray[np.floating]) -> npt.NDArray[np.floating]:
    """The middle of the points' axis-aligned box."""
    middle: npt.NDArray[np.floating] = (points.min(axis=0) + points.max(axis=0)) / 2.0
    return middle


def sphere(positions: npt.NDArray[np.floating]) -> tuple[npt.NDArray[np.float64], float]:
    """A sphere that holds the points: centred on their box, to the farthest of them."""
    points = np.asarray(positions, dtype=np.float64)
    if not len(points):
        return np.zeros(3), 0.0
    centre = _middle(points).astype(np.float64, copy=False)
    offsets = points - centre
    return centre, float(np.sqrt((offsets * offsets).sum(axis=1).max()))


def frustum_planes(view_projection: Matrix) -> Matrix:
    """The six planes (a, b, c, d; unit normal pointing inwards) of clip space's −w ≤ x, y, z ≤ w, in the
    frame the matrix takes points from (Gribb and Hartmann's rows)."""
    m = np.asarray(view_projection, dtype=np.float64)
    planes = np.array([m[3] + m[0], m[3] - m[0], m[3] + m[1], m[3] - m[1], m[3] + m[2], m[3] - m[2]])
    lengths = np.sqrt((planes[:, :3] * planes[:, :3]).sum(axis=1))
    return planes / lengths[:, np.newaxis]


def visible(planes: Matrix, centres: npt.NDArray[np.float64], radii: npt.NDArray[np.float64]) -> npt.NDArray[np.bool_]:
    """Which spheres reach inside every plane (N centres, N radii)."""
    if not len(centres):
        return np.zeros(0, dtype=bool)
    distances = matmul(centres, planes[:, :3].T) + planes[:, 3]
    return np.all(distances >= -radii[:, np.newaxis], axis=1)
