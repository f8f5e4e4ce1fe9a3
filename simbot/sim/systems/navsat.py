"""NavSat (SDF `navsat`, and `gps`, its old name): the sensor's latitude, longitude and altitude.

The world's `<spherical_coordinates>` put its origin on the WGS 84 ellipsoid (latitude, longitude,
elevation) and turn its x axis `heading_deg` counter-clockwise from east, as gz-math reckons it;
the sensor's world position, turned by the heading into east-north-up, is carried through
Earth-centred coordinates (ECEF) to geodetic latitude, longitude and height above the ellipsoid.
That is exact at any distance, not a flat-Earth approximation.

Noise as the SDF describes it, in metres: the horizontal noise is drawn on east and on north, the
vertical on up, before the conversion (Gazebo's sensor adds the horizontal σ to the degrees
themselves). Published as sensor_msgs/NavSatFix (status FIX, service GPS; the σ² of east, north
and up on the covariance's diagonal, type DIAGONAL_KNOWN, when there is noise, else type UNKNOWN,
as ros_gz_bridge writes it) on `<topic>` or Gazebo's
`world/<w>/model/<m>/link/<l>/sensor/<s>/navsat`. NavSatFix has no velocity, so the SDF's
`<velocity_sensing>` has nothing to act on and is not read.

SDF parameters (under `<navsat>`, or `<gps>` for the old type; `NavSatParams`):

| element | default | meaning |
| --- | --- | --- |
| `<position_sensing><horizontal><noise>` | none | gaussian noise east and north (m) |
| `<position_sensing><vertical><noise>` | none | gaussian noise up (m) |
| `<update_rate>` (of the `<sensor>`) | the physics rate | fixes per second |
| world `<spherical_coordinates>` | 0°, 0°, 0 m, heading 0 | `surface_model` EARTH_WGS84 only |
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from simbot.bus import messages
from simbot.description.model import Sensor, SphericalCoordinates
from simbot.description.sensor_params import Noise, SdfElement
from simbot.sim.kit.sensors import FramedSensor
from simbot.sim.loop.system import SystemConfigError, SystemContext, UpdateInfo
from simbot.transform import matmul

WGS84_A = 6378137.0
"""m, the ellipsoid's equatorial radius."""
WGS84_F = 1 / 298.257223563
WGS84_E2 = WGS84_F * (2 - WGS84_F)
"""Its first eccentricity, squared."""

Floats = npt.NDArray[np.float64]


def _to_ecef(lat: float, lon: float, height: float) -> Floats:
    """Earth-centred coordinates of a geodetic point (radians, metres above the ellipsoid)."""
    normal = WGS84_A / math.sqrt(1 - WGS84_E2 * math.sin(lat) ** 2)
    return np.array(
        [
            (normal + height) * math.cos(lat) * math.cos(lon),
            (normal + height) * math.cos(lat) * math.sin(lon),
            (normal * (1 - WGS84_E2) + height) * math.sin(lat),
        ]
    )


def _to_geodetic(ecef: Floats) -> tuple[float, float, float]:
    """(latitude, longitude in radians, height in metres) of an Earth-centred point; the latitude by
    fixed-point iteration, converged to far below a micrometre in five rounds anywhere off the poles."""
    x, y, z = (float(v) for v in ecef)
    p = math.hypot(x, y)
    lat = math.atan2(z, p * (1 - WGS84_E2))
    for _ in range(5):
        normal = WGS84_A / math.sqrt(1 - WGS84_E2 * math.sin(lat) ** 2)
        lat = math.atan2(z + WGS84_E2 * normal * math.sin(lat), p)
    normal = WGS84_A / math.sqrt(1 - WGS84_E2 * math.sin(lat) ** 2)
    height = p / math.cos(lat) - normal if abs(lat) < math.pi / 4 else z / math.sin(lat) - normal * (1 - WGS84_E2)
    return lat, math.atan2(y, x), height


class Geodesy:
    """World positions to latitude, longitude, altitude, for one world's `<spherical_coordinates>`."""

    def __init__(self, origin: SphericalCoordinates) -> None:
        lat, lon = math.radians(origin.latitude_deg), math.radians(origin.longitude_deg)
        self._origin = _to_ecef(lat, lon, origin.elevation)
        east = [-math.sin(lon), math.cos(lon), 0.0]
        north = [-math.sin(lat) * math.cos(lon), -math.sin(lat) * math.sin(lon), math.cos(lat)]
        up = [math.cos(lat) * math.cos(lon), math.cos(lat) * math.sin(lon), math.sin(lat)]
        self._enu_to_ecef = np.array([east, north, up]).T
        heading = math.radians(origin.heading_deg)
        c, s = math.cos(heading), math.sin(heading)
        self.world_to_enu = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        """East, north, up of the world's x, y, z: the world turned by the heading."""

    def enu_to_geodetic(self, enu: Floats) -> tuple[float, float, float]:
        """(latitude°, longitude°, altitude m) of a point given east, north, up of the world origin."""
        lat, lon, height = _to_geodetic(self._origin + matmul(self._enu_to_ecef, enu))
        return math.degrees(lat), math.degrees(lon), height


@dataclass(frozen=True)
class NavSatParams:
    """A navsat's SDF parameters (the table in the module docstring)."""

    horizontal_noise: Noise = Noise()
    vertical_noise: Noise = Noise()

    @staticmethod
    def from_sdf(sensor: Sensor) -> NavSatParams:
        root = SdfElement.of(sensor)
        element = (root.child("navsat") or root.child_or_empty("gps")).child_or_empty("position_sensing")
        return NavSatParams(element.noise_of("horizontal"), element.noise_of("vertical"))


class NavSat(FramedSensor):
    """sensor_msgs/NavSatFix at the sensor's rate, stamped with the sim time of the fix."""

    def __init__(self, ctx: SystemContext) -> None:
        sensor = ctx.require_sensor()[2]
        self.params = spec = NavSatParams.from_sdf(sensor)
        origin = ctx.world.spherical_coordinates
        if origin.surface_model != "EARTH_WGS84":
            raise SystemConfigError(
                f"sensor {sensor.name}: the world's <spherical_coordinates><surface_model> "
                f"{origin.surface_model!r} is not supported (EARTH_WGS84 only)"
            )
        channels = (spec.horizontal_noise, spec.horizontal_noise, spec.vertical_noise)
        super().__init__(ctx, channels, "navsat", messages.NavSatFix)
        self._geodesy = Geodesy(origin)
        variances = self.noise.variances()
        self._variances = variances if variances.any() else None

    def post_update(self, info: UpdateInfo) -> None:
        if not self.due(info):
            return
        position, _ = self.physics.frame_pose(*self.where)
        fix = self._geodesy.enu_to_geodetic(self.noise(matmul(self._geodesy.world_to_enu, position)))
        self.publish(info, messages.nav_sat_fix(info.sim_time_ns, self.frame, fix, self._variances))
