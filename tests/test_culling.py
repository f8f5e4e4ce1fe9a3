"""What a camera's view can show (simbot/sim/render/culling.py): bounding spheres against the frustum
of the very matrices the GL renderer draws with, checked against the frustum's geometry worked out
by hand (a camera at the origin looking along +x, SDF's z up)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from simbot.sim.render import culling
from simbot.sim.render.scene import projection_matrix, view_matrix
from simbot.transform import Transform, matmul

VFOV_DEG, ASPECT, NEAR, FAR = 60.0, 4.0 / 3.0, 0.1, 50.0
HALF_WIDTH = ASPECT * math.tan(math.radians(VFOV_DEG) / 2.0)
"""tan of half the horizontal field of view: the side planes are y = ±HALF_WIDTH·x."""
MARGIN = 1e-6
"""Either side of a sphere just touching a plane (the planes are normalised in float64)."""


@pytest.fixture(scope="module")
def planes() -> np.ndarray:
    pose = Transform((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))
    return culling.frustum_planes(matmul(projection_matrix(VFOV_DEG, ASPECT, NEAR, FAR), view_matrix(pose)))


def _seen(planes: np.ndarray, centre: tuple[float, float, float], radius: float) -> bool:
    (inside,) = culling.visible(planes, np.array([centre], dtype=np.float64), np.array([radius]))
    return bool(inside)


def test_a_sphere_ahead_is_seen_and_one_behind_is_not(planes: np.ndarray) -> None:
    assert _seen(planes, (5.0, 0.0, 0.0), 0.1)
    assert not _seen(planes, (-5.0, 0.0, 0.0), 0.1)
    assert _seen(planes, (-0.05, 0.0, 0.0), 0.2), "a sphere round the eye reaches past the near plane"


def test_the_far_plane_cuts_at_its_distance(planes: np.ndarray) -> None:
    assert not _seen(planes, (FAR + 1.0, 0.0, 0.0), 1.0 - 1e-3)
    assert _seen(planes, (FAR + 1.0, 0.0, 0.0), 1.0 + 1e-3)


@pytest.mark.parametrize("side", [1.0, -1.0])
def test_a_side_plane_cuts_at_the_spheres_distance_from_it(planes: np.ndarray, side: float) -> None:
    """A sphere at x = 5 beside the view: its centre's distance to the plane y = ±HALF_WIDTH·x decides."""
    x, y = 5.0, side * (HALF_WIDTH * 5.0 + 0.5)
    distance = (abs(y) - HALF_WIDTH * x) / math.hypot(1.0, HALF_WIDTH)
    assert not _seen(planes, (x, y, 0.0), distance - MARGIN)
    assert _seen(planes, (x, y, 0.0), distance + MARGIN)


def test_the_top_plane_follows_the_vertical_field_of_view(planes: np.ndarray) -> None:
    slope = math.tan(math.radians(VFOV_DEG) / 2.0)
    x, z = 10.0, 10.0 * slope + 1.0
    distance = (z - slope * x) / math.hypot(1.0, slope)
    assert not _seen(planes, (x, 0.0, z), distance - MARGIN)
    assert _seen(planes, (x, 0.0, z), distance + MARGIN)


def test_a_bounding_sphere_holds_every_point_and_touches_the_farthest() -> None:
    points = np.random.default_rng(7).uniform(-3.0, 5.0, size=(200, 3))
    centre, radius = culling.sphere(points)
    np.testing.assert_allclose(centre, (points.min(axis=0) + points.max(axis=0)) / 2.0)
    reach = np.sqrt(((points - centre) ** 2).sum(axis=1))
    assert reach.max() == pytest.approx(radius, rel=1e-12)


def test_no_points_give_an_empty_sphere_and_no_spheres_none_seen(planes: np.ndarray) -> None:
    centre, radius = culling.sphere(np.zeros((0, 3)))
    assert radius == 0.0 and not centre.any()
    assert culling.visible(planes, np.zeros((0, 3)), np.zeros(0)).shape == (0,)


def test_a_visual_falls_in_the_cell_of_its_middle() -> None:
    edge = culling.CELL_M
    box = np.array([[edge - 1.0, -0.5, 0.0], [edge + 3.0, 0.5, 1.0]])  # middle at x = edge + 1
    assert culling.cell_of(box) == (1, 0)
    assert culling.cell_of(box - [0.0, 0.75, 0.0]) == (1, -1), "the middle just below y = 0"
