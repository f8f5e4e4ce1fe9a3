"""What the server and the render workers agree on: the scene's bodies, a camera's intrinsics and
outputs, the light, and a finished frame. Plain frozen data: it crosses the process boundary."""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from simbot.sim.render.kinds import Array, OutputKind, Raw, resolve
from simbot.sim.render.lens import Distortion, principal_point, render_focal
from simbot.transform import Transform, Vec3

Pixels = npt.NDArray[np.uint8]
Depths = npt.NDArray[np.float32]
Points = npt.NDArray[np.float32]


@dataclass(frozen=True)
class SceneBody:
    """A body as the server loaded it, for the workers to load the same way."""

    name: str
    urdf: str
    """URDF text as PyBullet loaded it in the server (mesh paths absolute)."""
    static: bool
    """loadURDF(useFixedBase=static): a static body never moves, so GL bakes it into the world's buffer."""
    base: Transform
    """The root link's URDF frame in the world at start."""


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
    kinds: tuple[OutputKind, ...] = field(init=False, repr=False, compare=False)
    """The outputs' kinds, each after those it needs."""

    def __post_init__(self) -> None:
        """Fail at configuration, not in a worker."""
        if self.width <= 0 or self.height <= 0:
            raise ValueError(f"camera {self.name!r}: image size {self.width}x{self.height} must be positive")
        if not 0.0 < self.hfov < math.pi:
            raise ValueError(f"camera {self.name!r}: horizontal fov {self.hfov} must be in (0, pi)")
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
        """Focal length in pixels (fx = fy)."""
        return (self.width / 2.0) / math.tan(self.hfov / 2.0)

    @property
    def principal_point(self) -> tuple[float, float]:
        """(cx, cy) in ROS's pixel-centre coordinates: the image centre, where a symmetric frustum puts
        it, or the distortion centre of a lens that bends (`lens.principal_point`)."""
        return principal_point(self.distortion, self.width, self.height)


@dataclass(frozen=True)
class Light:
    """The world's directional light. ambient + diffuse = 1, so a face that looks at the light
    shows its material colour exactly (no clipping, hue kept) and faces away from it keep 60 % of
    it. No specular term: its highlight depends on the view and adds nothing for perception."""

    direction: Vec3 = (-0.5, 0.1, -0.9)
    """Direction the light travels, world frame (SDF <direction>); PyBullet wants the opposite."""
    ambient: float = 0.6
    diffuse: float = 0.4
    specular: float = 0.0
    color: Vec3 = (1.0, 1.0, 1.0)


@dataclass(frozen=True, eq=False)
class Frame(Mapping[str, Array]):
    """A rendered frame: the camera's outputs by name. Its arrays are views of the camera's shared
    memory, valid until the next request for that camera."""

    camera: int
    stamp_ns: int
    arrays: Mapping[str, Array]
    render_s: float
    """Seconds the worker spent on it (scene update, render, conversion, copy)."""

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
