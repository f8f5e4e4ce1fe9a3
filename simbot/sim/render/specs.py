"""What the server and the render workers agree on: the scene's bodies, a camera's intrinsics and
outputs, the world's lighting, and a finished frame. Plain frozen data: it crosses the process boundary."""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from simbot.description.urdf_visuals import UrdfVisual
from simbot.sim.render.kinds import Array, OutputKind, Raw, resolve
from simbot.sim.render.lens import Distortion, principal_point, render_focal
from simbot.sim.render.wide_lens import WideLens
from simbot.transform import Transform, Vec3

Pixels = npt.NDArray[np.uint8]
Depths = npt.NDArray[np.float32]
Points = npt.NDArray[np.float32]


@dataclass(frozen=True)
class Annotation:
    """What Gazebo's Label and Thermal systems say of a body's visuals: a label (0..255) for
    segmentation and bounding-box cameras, a temperature (K) for thermal ones."""

    link: str | None = None
    """The URDF link of the one visual it covers; None: every visual of the body."""
    visual: str | None = None
    label: int | None = None
    temperature: float | None = None


@dataclass(frozen=True)
class SceneBody:
    """A body as the server loaded it, for the workers to load the same way (`bodies.scene_body`)
    and to draw."""

    name: str
    urdf: str
    """URDF text as PyBullet loaded it in the server (mesh paths absolute): what a worker's PyBullet
    copy loads, for the link poses (and TinyRenderer's drawing)."""
    static: bool
    """loadURDF(useFixedBase=static): a static body never moves, so GL bakes it into the world's buffer."""
    base: Transform
    """The root link's URDF frame in the world at start."""
    annotations: tuple[Annotation, ...] = ()
    """In the order they apply: a later one overrides an earlier one where both say something."""
    instance: int = 0
    """The body's instance number for segmentation (1..65535; the same in every worker)."""
    visuals: tuple[UrdfVisual, ...] = ()
    """Its visuals as typed data from the description, each on its URDF link (`urdf_visuals`):
    what the OpenGL renderer draws (`visuals.py`) and bounding boxes are fitted to (`boxes.py`)."""

    def annotated(self, link: str, visual: str) -> tuple[int | None, float | None]:
        """(label, temperature) of one visual: the body's annotations, then the visual's own."""
        label, temperature = None, None
        ordered = sorted(self.annotations, key=lambda a: a.visual is not None)  # stable: whole-body first
        for annotation in ordered:
            if annotation.visual is None or (annotation.link, annotation.visual) == (link, visual):
                label = annotation.label if annotation.label is not None else label
                temperature = annotation.temperature if annotation.temperature is not None else temperature
        return label, temperature


@dataclass(frozen=True)
class BodyState:
    """Where a moving body is at the instant a frame is taken."""

    base: Transform
    """The root link's URDF frame in the world."""
    joints: Mapping[str, float]
    """The position of every joint of the URDF that moves, by name."""


@dataclass(frozen=True)
class CameraSpec:
    """A camera's intrinsics and what it produces; the pose comes with each request.

    `outputs` names the outputs it publishes (`kinds.py`; the built-in `color`, `mono`, `depth`
    and `points` are in `outputs.py`). Resolved once here, they and the outputs they need are
    `kinds`, which travel to the workers with the spec; their arrays lie one after the other in
    the camera's shared memory block (see `layout`)."""

    name: str
    width: int
    height: int
    hfov: float
    """Horizontal field of view, radians; pixels are square, so fx = fy = (width/2)/tan(hfov/2)."""
    near: float
    far: float
    outputs: tuple[str, ...] = ("color",)
    noise_stddev: float = 0.0
    """Gaussian pixel noise in units of full scale, as SDF camera noise (0..1)."""
    seed: int = 0
    distortion: Distortion = Distortion()
    """The lens (SDF `<distortion>`; `lens.py`); the default bends nothing."""
    wide: WideLens | None = None
    """A wide-angle lens (`wide_lens.py`): the camera is drawn as cube faces (`rendered`) and remapped."""
    kinds: tuple[OutputKind, ...] = field(init=False, repr=False, compare=False)
    """The outputs' kinds, each after those it needs."""

    def __post_init__(self) -> None:
        """Fail at configuration, not in a worker."""
        if self.width <= 0 or self.height <= 0:
            raise ValueError(f"camera {self.name!r}: image size {self.width}x{self.height} must be positive")
        widest = math.pi if self.wide is None else 2.0 * math.pi + 1e-6
        if not 0.0 < self.hfov < widest:
            raise ValueError(f"camera {self.name!r}: horizontal fov {self.hfov} must be in (0, {widest:.4f})")
        if not 0.0 < self.near < self.far:
            raise ValueError(f"camera {self.name!r}: clip near {self.near} / far {self.far} must be 0 < near < far")
        if not all(math.isfinite(c) for c in (*self.distortion.d, *self.distortion.center)):
            raise ValueError(f"camera {self.name!r}: distortion {self.distortion} must be finite")
        if not self.noise_stddev >= 0.0:
            raise ValueError(f"camera {self.name!r}: noise stddev {self.noise_stddev} must be >= 0")
        try:
            kinds = resolve(self.outputs)
        except ValueError as exc:
            raise ValueError(f"camera {self.name!r}: {exc}") from None
        drawn = [kind.draws for kind in kinds if kind.draws is not None]
        if len(set(drawn)) != len(drawn):
            names = [kind.name for kind in kinds if kind.draws is not None]
            raise ValueError(f"camera {self.name!r}: outputs {names} draw the same buffer twice ({drawn})")
        object.__setattr__(self, "kinds", kinds)

    def drawn(self) -> dict[Raw, tuple[int, ...]]:
        """The raw buffers a renderer draws for this camera, with their shapes."""
        return {kind.draws: kind.shape(self) for kind in self.kinds if kind.draws is not None}

    def layout(self) -> dict[str, tuple[np.dtype[np.generic], tuple[int, ...], int]]:
        """Each output's dtype, shape and byte offset in the camera's shared memory."""
        placed, offset = {}, 0
        for kind in self.kinds:
            dtype, shape = np.dtype(kind.dtype), kind.shape(self)
            placed[kind.name] = (dtype, shape, offset)
            offset += dtype.itemsize * math.prod(shape)
            offset += -offset % 16  # float blocks start aligned
        return placed

    @property
    def nbytes(self) -> int:
        placed = self.layout()
        return max((dtype.itemsize * math.prod(shape) + offset for dtype, shape, offset in placed.values()), default=1)

    @property
    def vfov_deg(self) -> float:
        """Vertical field of view in degrees, as computeProjectionMatrixFOV wants it."""
        return math.degrees(2.0 * math.atan(math.tan(self.hfov / 2.0) * self.height / self.width))

    @property
    def render_vfov_deg(self) -> float:
        """The vertical field of view the renderer draws with, degrees: the camera's own, or the one
        a lens that bends the image samples its rays from (`lens.render_focal`)."""
        if not self.distortion.bends:
            return self.vfov_deg
        focal = render_focal(self.distortion, self.width, self.height, self.fx)
        return math.degrees(2.0 * math.atan((self.height / 2.0) / focal))

    @property
    def fx(self) -> float:
        """Focal length in pixels (fx = fy); a wide-angle lens's f."""
        if self.wide is not None:
            return self.wide.focal_px(self.width, self.hfov)
        return (self.width / 2.0) / math.tan(self.hfov / 2.0)

    @property
    def rendered(self) -> CameraSpec:
        """The camera a renderer draws: this one, or for a wide-angle lens a 90° cube face
        (`wide_angle.views` poses it and gives it its buffer)."""
        if self.wide is None:
            return self
        size = self.wide.face
        return CameraSpec(self.name, size, size, math.pi / 2.0, self.near, self.far)

    @property
    def principal_point(self) -> tuple[float, float]:
        """(cx, cy) in ROS's pixel-centre coordinates: the image centre, where a symmetric frustum puts
        it, or the distortion centre of a lens that bends (`lens.principal_point`)."""
        return principal_point(self.distortion, self.width, self.height)


RGB = tuple[float, float, float]

MAX_LIGHTS = 8
"""Lights the OpenGL renderer shades at once (a fixed loop in its shader); a world with more keeps
the first eight, with a warning."""


@dataclass(frozen=True)
class LightSource:
    """One light of the world, in the world frame, as Gazebo shades it (SDF `<light>`)."""

    type: str = "directional"
    """directional, point or spot."""
    diffuse: RGB = (1.0, 1.0, 1.0)
    """Colour times `<intensity>`."""
    specular: RGB = (0.0, 0.0, 0.0)
    position: Vec3 = (0.0, 0.0, 0.0)
    """Point and spot lights."""
    direction: Vec3 = (-0.5, 0.1, -0.9)
    """Direction the light travels (directional and spot); PyBullet wants the opposite."""
    range: float = 10.0
    """No light beyond this distance (point and spot)."""
    attenuation: Vec3 = (1.0, 1.0, 0.0)
    """(constant, linear, quadratic): the light falls as 1 / (c + l·d + q·d²) with distance d."""
    spot: Vec3 = (0.0, 0.0, 0.0)
    """(inner angle, outer angle, falloff): full cone angles in radians (the edge lies at half the
    outer angle from the axis); between the cones the light fades as s^falloff, s going 1 → 0."""
    cast_shadows: bool = False


@dataclass(frozen=True)
class Light:
    """The world's lighting: its lights, the scene's ambient light and sky colour, and whether the
    sun casts shadows. A fragment shows scene ambient × material ambient + Σ (light diffuse ×
    material diffuse × N·L + light specular × material specular × Blinn-Phong) + emissive.

    The default (no world given) is one white sun with ambient 0.6 and diffuse 0.4: a face that
    looks at the sun shows its material colour exactly, faces away from it 60 % of it; a white sky."""

    sources: tuple[LightSource, ...] = (LightSource(diffuse=(0.4, 0.4, 0.4)),)
    ambient: RGB = (0.6, 0.6, 0.6)
    background: RGB = (1.0, 1.0, 1.0)
    shadows: bool = True
    """SDF `<scene><shadows>`: the first directional light that casts shadows casts them."""
    ambient_temperature: float = 288.15
    """What a thermal camera sees where no Thermal system says (the light it sees is the heat):
    the world's `<atmosphere>` temperature at z = 0, K ..."""
    temperature_gradient: float = -0.0065
    """... changing by this much a metre up (K/m)."""

    @property
    def sun(self) -> LightSource | None:
        """The first directional light: TinyRenderer's one light."""
        return next((s for s in self.sources if s.type == "directional"), None)

    @property
    def shadow_caster(self) -> int | None:
        """Index of the light whose shadows are drawn: the first directional light with
        `<cast_shadows>` among those shaded, where the scene has shadows on."""
        if not self.shadows:
            return None
        shaded = self.sources[:MAX_LIGHTS]
        return next((i for i, s in enumerate(shaded) if s.type == "directional" and s.cast_shadows), None)


@dataclass(frozen=True, eq=False)
class Frame(Mapping[str, Array]):
    """A rendered frame: the camera's outputs by name. Its arrays are views of the camera's shared
    memory, valid until the next request for that camera."""

    camera: int
    stamp_ns: int
    arrays: Mapping[str, Array]
    render_s: float
    """Seconds the worker spent on it (scene update, render, conversion, copy)."""
    camera_pose: Transform | None = None
    """The camera's world pose it was rendered from (looking along its +x, z up)."""
    states: Mapping[str, BodyState] = field(default_factory=dict)
    """Where the moving bodies were in it."""
    bodies: Mapping[str, SceneBody] = field(default_factory=dict)
    """The bodies of the scene it shows, by name (with their labels and instance numbers): what a
    camera that reads geometry (bounding boxes) needs besides the pixels."""

    def __getitem__(self, name: str) -> Array:
        """KeyError naming the camera for an output it does not render."""
        try:
            return self.arrays[name]
        except KeyError:
            raise KeyError(f"camera {self.camera} renders no {name!r}") from None

    def __iter__(self) -> Iterator[str]:
        return iter(self.arrays)

    def __len__(self) -> int:
        return len(self.arrays)
