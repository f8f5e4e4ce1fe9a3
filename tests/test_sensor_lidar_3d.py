"""The lidar system's 3-D scans (rows of rays, PointCloud2 beside the middle plane's LaserScan) in
the probe world (probe_helpers.py), against geometry: PyBullet's ray test against a box is exact
to float precision, and a LaserScan or cloud holds float32: 1e-5 m on metres."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from probe_helpers import probe, sensor

from simbot.bus import messages

WALL_FACE_X = 1.9
LIDAR_HEIGHT = 0.5  # the sensor 0.5 m above the probe's frame, itself at z 0.5: 1 m above the floor
H_SAMPLES, H_MAX = 41, 0.5


def lidar(name: str, vertical: int, horizontal: int = H_SAMPLES) -> str:
    """A noiseless lidar `name` with `vertical` rows over ±0.2 rad (1: planar, in the horizontal plane)."""
    rows = (
        f"<vertical><samples>{vertical}</samples><min_angle>-0.2</min_angle><max_angle>0.2</max_angle></vertical>"
        if vertical > 1
        else ""
    )
    body = (
        f"<lidar><scan><horizontal><samples>{horizontal}</samples><min_angle>-{H_MAX}</min_angle>"
        f"<max_angle>{H_MAX}</max_angle></horizontal>{rows}</scan><range><min>0.1</min><max>10</max></range></lidar>"
    )
    return sensor(name, "gpu_lidar", body, f"0 0 {LIDAR_HEIGHT} 0 0 0")


def test_3d_lidar_sees_a_wall_point_by_point(tmp_path: Path) -> None:
    """5 rows × 41 columns of points, each on the wall's face x = 1.9 where its ray meets it, ring = row;
    the middle-plane scan is the middle row's ranges and equals a planar lidar's scan."""
    with probe(tmp_path, lidar("odd", 5) + lidar("flat", 1)) as sim:
        t = sim.step(10)
        cloud = messages.lidar_points_array(sim.at("odd/points", t))
        scan, flat = sim.at("odd", t), sim.at("flat", t)
    assert cloud.shape == (5, H_SAMPLES)
    azimuth = np.linspace(-H_MAX, H_MAX, H_SAMPLES)[None, :]
    elevation = np.linspace(-0.2, 0.2, 5)[:, None]
    distance = WALL_FACE_X / (np.cos(azimuth) * np.cos(elevation))  # along each ray to the plane x = 1.9
    assert np.abs(cloud["x"] - WALL_FACE_X).max() < 1e-5
    assert np.abs(cloud["y"] - distance * np.cos(elevation) * np.sin(azimuth)).max() < 1e-5
    assert np.abs(cloud["z"] - distance * np.sin(elevation)).max() < 1e-5
    assert (cloud["ring"] == np.arange(5)[:, None]).all() and (cloud["intensity"] == 0).all()
    middle = np.sqrt(cloud["x"][2] ** 2 + cloud["y"][2] ** 2 + cloud["z"][2] ** 2)
    assert np.asarray(scan.ranges) == pytest.approx(middle, abs=1e-5)
    assert np.asarray(scan.ranges) == pytest.approx(np.asarray(flat.ranges), abs=1e-6)
    assert (scan.angle_min, scan.angle_max, len(scan.ranges)) == (flat.angle_min, flat.angle_max, H_SAMPLES)


def test_even_rows_cast_the_middle_plane_apart(tmp_path: Path) -> None:
    """4 rows (none horizontal): the cloud has 4 rows, the scan is the horizontal plane all the same;
    rays above the wall's top read nothing: NaN in the cloud."""
    with probe(tmp_path, lidar("even", 4) + lidar("flat", 1), spawn=(0.0, 0.0, 0.75, 0.0)) as sim:
        t = sim.step(10)
        cloud = messages.lidar_points_array(sim.at("even/points", t))
        scan, flat = sim.at("even", t), sim.at("flat", t)
    assert cloud.shape == (4, H_SAMPLES)
    assert np.asarray(scan.ranges) == pytest.approx(np.asarray(flat.ranges), abs=1e-6)
    # the sensor is 1.25 m up: the top row (+0.2 rad) passes over the 2 m wall's top only if
    # 1.25 + 1.9·tan(0.2) > 2, which it is not: every ray hits, on the face
    assert np.isfinite(cloud["x"]).all() and np.abs(cloud["x"] - WALL_FACE_X).max() < 1e-5


def test_more_rays_than_one_pybullet_batch(tmp_path: Path) -> None:
    """9 × 2001 = 18009 rays, over PyBullet's 16384 a batch: cast in parts, every point still on the wall
    where its own ray meets it (a ray lost or shifted at a part's edge would misplace the rest)."""
    with probe(tmp_path, lidar("odd", 9, 2001)) as sim:
        cloud = messages.lidar_points_array(sim.sample("odd/points"))
    azimuth = np.linspace(-H_MAX, H_MAX, 2001)[None, :]
    assert cloud.shape == (9, 2001) and np.abs(cloud["x"] - WALL_FACE_X).max() < 1e-5
    assert np.abs(cloud["y"] - WALL_FACE_X * np.tan(azimuth)).max() < 1e-5


def test_rays_that_hit_nothing_are_nan_points(tmp_path: Path) -> None:
    """Turned away from the wall, the upper rows see nothing: NaN, and the cloud says it is not dense."""
    with probe(tmp_path, lidar("odd", 5), spawn=(0.0, 0.0, 0.5, math.pi)) as sim:
        t = sim.step(10)
        msg = sim.at("odd/points", t)
    cloud = messages.lidar_points_array(msg)
    # the lowest row (−0.2 rad) meets the floor 1 m below at 1/sin 0.2 = 5.0 m; the next (−0.1 rad)
    # only at 10.02 m, past range_max; level and up there is nothing
    assert np.isfinite(cloud["x"][0]).all() and np.isnan(cloud["x"][1:]).all()
    assert np.abs(cloud["z"][0] + 1.0).max() < 1e-5 and not msg.is_dense
