"""Plain typed data of a robot or world description, whatever file format it came from.

Every pose here is already resolved (SDF `relative_to` applied): a link's pose is in its
model's frame, a joint's pose is in its model's frame, and the poses of what a link holds
(inertial, collisions, visuals, sensors) are in that link's frame.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

from simbot.description.poses import IDENTITY, Pose, Vec3

RGBA = tuple[float, float, float, float]


@dataclass(frozen=True)
class Box:
    size: Vec3


@dataclass(frozen=True)
class Cylinder:
    """Axis along the geometry's z, as in SDF and URDF."""

    radius: float
    length: float


@dataclass(frozen=True)
class Sphere:
    radius: float


@dataclass(frozen=True)
class Capsule:
    """Axis along z; `length` is the cylinder between the two half spheres (SDF and PyBullet agree)."""

    radius: float
    length: float


@dataclass(frozen=True)
class Ellipsoid:
    radii: Vec3


@dataclass(frozen=True)
class Cone:
    """Axis along z: the base circle at z = -length/2, the apex at +length/2."""

    radius: float
    length: float


@dataclass(frozen=True)
class Polyline:
    """Closed outlines in the xy plane, each extruded from z = 0 up to its height (one per SDF <polyline>)."""

    outlines: tuple[tuple[tuple[float, float], ...], ...]
    heights: tuple[float, ...]


@dataclass(frozen=True)
class Heightmap:
    """A grey image as terrain: `size` metres along x and y, and from black to white along z; `pos`
    moves it (its centre in x and y, its zero height in z). `path` the image, None when not found."""

    uri: str
    size: Vec3 = (1.0, 1.0, 1.0)
    pos: Vec3 = (0.0, 0.0, 0.0)
    path: Path | None = None


@dataclass(frozen=True)
class Plane:
    normal: Vec3
    size: tuple[float, float]


@dataclass(frozen=True)
class Mesh:
    """`uri` as written; `path` the file it resolved to, None when it could not be found."""

    uri: str
    scale: Vec3 = (1.0, 1.0, 1.0)
    path: Path | None = None


Geometry = Box | Cylinder | Sphere | Plane | Mesh | Capsule | Ellipsoid | Cone | Polyline | Heightmap


@dataclass(frozen=True)
class Material:
    """SDF `<material>`: the colours as written (None where left out), `<lighting>`, `<shininess>`,
    and PBR's maps (`<pbr><metal>` or `<pbr><specular>`), each map the file it resolved to."""

    ambient: RGBA | None = None
    diffuse: RGBA | None = None
    specular: RGBA | None = None
    emissive: RGBA | None = None
    lighting: bool = True
    shininess: float | None = None
    albedo_map: Path | None = None
    normal_map: Path | None = None
    metalness: float | None = None
    roughness: float | None = None

    def color(self) -> RGBA | None:
        """The one colour a renderer without lighting terms should use."""
        return self.diffuse or self.ambient


@dataclass(frozen=True)
class Friction:
    """ODE-style friction: mu along fdir1 (or the first friction direction), mu2 across."""

    mu: float = 1.0
    mu2: float = 1.0
    fdir1: Vec3 | None = None
    slip1: float = 0.0
    """ODE's force-dependent slip along fdir1, m/s per N (0, SDF's default: none stated)."""
    slip2: float = 0.0
    """The same across."""


@dataclass(frozen=True)
class Inertial:
    mass: float
    pose: Pose = IDENTITY
    inertia: tuple[float, float, float, float, float, float] = (1.0, 0.0, 0.0, 1.0, 0.0, 1.0)
    """ixx, ixy, ixz, iyy, iyz, izz about the centre of mass, in the inertial frame."""


@dataclass(frozen=True)
class Collision:
    name: str
    geometry: Geometry
    pose: Pose = IDENTITY
    friction: Friction | None = None


@dataclass(frozen=True)
class Visual:
    name: str
    geometry: Geometry
    pose: Pose = IDENTITY
    material: Material | None = None
    transparency: float = 0.0
    cast_shadows: bool = True
    plugins: tuple[Plugin, ...] = ()
    """The visual's `<plugin>`s (Gazebo's Label, Thermal), after those of the nested model it came from."""


@dataclass(frozen=True)
class Param:
    """One child element of a `<plugin>`, kept whole because plugins define their own syntax."""

    tag: str
    text: str = ""
    attrs: tuple[tuple[str, str], ...] = ()
    children: tuple[Param, ...] = ()


@dataclass(frozen=True)
class Sensor:
    name: str
    type: str
    pose: Pose = IDENTITY
    update_rate: float = 0.0
    always_on: bool = False
    topic: str | None = None
    frame_name: str | None = None
    params: tuple[Param, ...] = ()
    """The `<sensor>`'s children kept whole: each sensor module reads its own (simbot/description/sensor_params.py)."""


@dataclass(frozen=True)
class Plugin:
    name: str
    filename: str
    params: tuple[Param, ...] = ()

    def get(self, tag: str, default: str | None = None) -> str | None:
        """Text of the first parameter named `tag`."""
        return next((p.text for p in self.params if p.tag == tag), default)

    def get_all(self, tag: str) -> list[str]:
        """Texts of every parameter named `tag`, in file order (e.g. several left_joint)."""
        return [p.text for p in self.params if p.tag == tag]


@dataclass(frozen=True)
class Link:
    name: str
    pose: Pose = IDENTITY
    inertial: Inertial | None = None
    collisions: tuple[Collision, ...] = ()
    visuals: tuple[Visual, ...] = ()
    sensors: tuple[Sensor, ...] = ()


@dataclass(frozen=True)
class Axis:
    """Direction in the joint frame; limits of None mean unlimited."""

    xyz: Vec3 = (0.0, 0.0, 1.0)
    lower: float | None = None
    upper: float | None = None
    effort: float | None = None
    velocity: float | None = None
    damping: float = 0.0
    friction: float = 0.0


@dataclass(frozen=True)
class Joint:
    name: str
    type: str
    parent: str
    child: str
    pose: Pose = IDENTITY
    axis: Axis | None = None
    sensors: tuple[Sensor, ...] = ()
    """A joint's `<sensor>`s (force_torque), posed in its child link's frame."""


@dataclass(frozen=True)
class Model:
    name: str
    pose: Pose = IDENTITY
    static: bool = False
    canonical_link: str = ""
    links: tuple[Link, ...] = ()
    joints: tuple[Joint, ...] = ()
    plugins: tuple[Plugin, ...] = ()
    source: Path | None = None
    uri: str | None = None
    """The include URI this model came from, if any."""

    def link(self, name: str) -> Link:
        """The link called `name`; KeyError names it when absent."""
        for link in self.links:
            if link.name == name:
                return link
        raise KeyError(f"model {self.name!r} has no link {name!r}")

    def joint(self, name: str) -> Joint:
        """The joint called `name`; KeyError names it when absent."""
        for joint in self.joints:
            if joint.name == name:
                return joint
        raise KeyError(f"model {self.name!r} has no joint {name!r}")

    def sensors(self) -> list[tuple[Link, Sensor]]:
        """Every sensor with the link that carries it; a joint's sensors with the joint's child link."""
        on_links = [(link, sensor) for link in self.links for sensor in link.sensors]
        return on_links + [(self.link(joint.child), sensor) for joint in self.joints for sensor in joint.sensors]

    def joint_of(self, sensor: Sensor) -> Joint | None:
        """The joint a sensor belongs to (a force_torque sensor), None for a link's sensor."""
        return next((joint for joint in self.joints if sensor in joint.sensors), None)

    def with_wheel_friction(self, change: Callable[[Friction], Friction]) -> Model:
        """This model with `change` applied to the friction of every collision whose μ and μ2
        differ (the wheels the physics gives a tyre): a tyre's slip restated, for a comparison."""

        def restated(collision: Collision) -> Collision:
            friction = collision.friction
            if friction is None or friction.mu == friction.mu2:
                return collision
            return replace(collision, friction=change(friction))

        links = tuple(replace(link, collisions=tuple(map(restated, link.collisions))) for link in self.links)
        return replace(self, links=links)


@dataclass(frozen=True)
class SdfPhysics:
    """SDF `<physics>`: the step size and pace a world asks for (simbot.sim.physics.Physics is the engine)."""

    max_step_size: float = 0.001
    real_time_factor: float = 1.0
    real_time_update_rate: float = 1000.0
    type: str = "ode"


@dataclass(frozen=True)
class SdfLight:
    """SDF `<light>` as the world declares it, with SDF's defaults (simbot.sim.render's Lighting is
    what the renderers shade with). `direction` is in the light's frame (its pose turns it)."""

    name: str
    type: str
    pose: Pose = IDENTITY
    diffuse: RGBA = (1.0, 1.0, 1.0, 1.0)
    specular: RGBA = (0.1, 0.1, 0.1, 1.0)
    direction: Vec3 = (0.0, 0.0, -1.0)
    cast_shadows: bool = False
    intensity: float = 1.0
    attenuation_range: float = 10.0
    """`<attenuation><range>`: no light beyond this distance (point and spot)."""
    constant: float = 1.0
    linear: float = 1.0
    quadratic: float = 0.0
    """Attenuation 1 / (constant + linear·d + quadratic·d²), as Gazebo."""
    inner_angle: float = 0.0
    outer_angle: float = 0.0
    """`<spot>` cone angles, radians, full angles (Ogre's: the edge is at half of each from the axis)."""
    falloff: float = 0.0
    """`<spot><falloff>`: exponent of the fade from the inner to the outer cone."""


@dataclass(frozen=True)
class Scene:
    """SDF `<scene>`: the ambient light, the sky's colour, and whether lights cast shadows."""

    ambient: RGBA = (0.4, 0.4, 0.4, 1.0)
    background: RGBA = (0.7, 0.7, 0.7, 1.0)
    shadows: bool = True


@dataclass(frozen=True)
class SphericalCoordinates:
    """Where the world's origin is on the Earth (SDF `<spherical_coordinates>`); the world's x axis
    points `heading_deg` counter-clockwise from east (gz-math's convention), z up."""

    surface_model: str = "EARTH_WGS84"
    world_frame_orientation: str = "ENU"
    latitude_deg: float = 0.0
    longitude_deg: float = 0.0
    elevation: float = 0.0
    heading_deg: float = 0.0


@dataclass(frozen=True)
class Atmosphere:
    """SDF `<atmosphere>` (adiabatic): sea-level temperature (K) and pressure (Pa), lapse (K/m)."""

    temperature: float = 288.15
    pressure: float = 101325.0
    temperature_gradient: float = -0.0065


EARTH_MAGNETIC_FIELD: Vec3 = (5.5645e-6, 22.8758e-6, -42.3884e-6)
"""SDF's default `<magnetic_field>`, tesla, in the world frame."""


@dataclass(frozen=True)
class World:
    name: str
    physics: SdfPhysics = field(default_factory=SdfPhysics)
    gravity: Vec3 = (0.0, 0.0, -9.8)
    scene: Scene = field(default_factory=Scene)
    lights: tuple[SdfLight, ...] = ()
    models: tuple[Model, ...] = ()
    plugins: tuple[Plugin, ...] = ()
    source: Path | None = None
    spherical_coordinates: SphericalCoordinates = field(default_factory=SphericalCoordinates)
    magnetic_field: Vec3 = EARTH_MAGNETIC_FIELD
    atmosphere: Atmosphere = field(default_factory=Atmosphere)

    def model(self, name: str) -> Model:
        """The model called `name`; KeyError names it when absent."""
        for model in self.models:
            if model.name == name:
                return model
        raise KeyError(f"world {self.name!r} has no model {name!r}")
