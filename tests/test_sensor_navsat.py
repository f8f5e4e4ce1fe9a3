"""The navsat in the probe world (probe_helpers.py): the expected latitude and longitude come from
the meridian and prime-vertical radii of curvature at the origin (M + h, (N + h)·cos φ): exact to
first order; over 50 m the second order is d²/2R ≈ 2e-4 m ≈ 2e-9°, far inside the 1e-7° asked."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from probe_helpers import probe, sensor

LAT, LON, ELEVATION = 47.3, 8.5, 400.0
WGS84_A, WGS84_E2 = 6378137.0, 0.00669437999014


@pytest.mark.parametrize("heading_deg", [0.0, 90.0, -30.0])
def test_navsat_converts_a_displacement_to_latitude_and_longitude(tmp_path: Path, heading_deg: float) -> None:
    """At (30, 40) in the world: east and north by the heading (gz-math: ENU = Rz(heading)·world), then
    Δφ = north/(M + h), Δλ = east/((N + h)·cos φ), within 1e-7°; the altitude is elevation + z."""
    world = (
        f"<spherical_coordinates><surface_model>EARTH_WGS84</surface_model><latitude_deg>{LAT}</latitude_deg>"
        f"<longitude_deg>{LON}</longitude_deg><elevation>{ELEVATION}</elevation>"
        f"<heading_deg>{heading_deg}</heading_deg></spherical_coordinates>"
    )
    with probe(tmp_path, sensor("fix", "navsat"), world=world) as sim:
        sim.teleport((0.0, 0.0, 0.0))
        origin = sim.sample("fix")
        sim.teleport((30.0, 40.0, 0.0))
        moved = sim.sample("fix")
    h = math.radians(heading_deg)
    east, north = 30.0 * math.cos(h) - 40.0 * math.sin(h), 30.0 * math.sin(h) + 40.0 * math.cos(h)
    phi = math.radians(LAT)
    w = math.sqrt(1 - WGS84_E2 * math.sin(phi) ** 2)
    meridian, normal = WGS84_A * (1 - WGS84_E2) / w**3, WGS84_A / w
    assert (origin.latitude, origin.longitude) == (pytest.approx(LAT, abs=1e-9), pytest.approx(LON, abs=1e-9))
    assert origin.altitude == pytest.approx(ELEVATION, abs=1e-6)
    assert moved.latitude == pytest.approx(LAT + math.degrees(north / (meridian + ELEVATION)), abs=1e-7)
    assert moved.longitude == pytest.approx(LON + math.degrees(east / ((normal + ELEVATION) * math.cos(phi))), abs=1e-7)
    assert moved.altitude == pytest.approx(ELEVATION, abs=1e-3)  # the Earth's curvature: 50²/2R = 0.2 mm
    assert moved.status.status == 0 and moved.position_covariance_type == 0  # FIX; no noise: UNKNOWN


def test_navsat_noise_in_metres(tmp_path: Path) -> None:
    """σ 2 m horizontally and 3 m vertically: the spread of 300 fixes of a probe at rest, in metres
    (±20 %: an estimate from N samples is within ~1/√(2N) = 4 %), and σ² on the covariance's diagonal."""
    body = (
        '<navsat><position_sensing><horizontal><noise type="gaussian"><stddev>2</stddev></noise></horizontal>'
        '<vertical><noise type="gaussian"><stddev>3</stddev></noise></vertical></position_sensing></navsat>'
    )
    with probe(tmp_path, sensor("fix", "navsat", body)) as sim:
        fixes = [sim.sample("fix") for _ in range(300)]
    # at the world's default origin, 0° 0°: the meridian radius is a(1 − e²), the prime vertical's a
    north = np.radians([f.latitude for f in fixes]) * WGS84_A * (1 - WGS84_E2)
    east = np.radians([f.longitude for f in fixes]) * WGS84_A
    up = np.array([f.altitude for f in fixes])
    assert np.std(north) == pytest.approx(2.0, rel=0.2) and np.std(east) == pytest.approx(2.0, rel=0.2)
    assert np.std(up) == pytest.approx(3.0, rel=0.2)
    assert list(fixes[0].position_covariance) == [4.0, 0, 0, 0, 4.0, 0, 0, 0, 9.0]
    assert fixes[0].position_covariance_type == 2
