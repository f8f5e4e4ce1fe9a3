"""What the server and the render workers agree on: the scene's bodies, a camera's intrinsics and
outputs, the light, and a finished frame. Plain frozen data: it crosses the process boundary."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]
Transform = tuple[Vec3, Quat]
"""(xyz, quaternion xyzw): PyBullet's form."""

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

    Outputs: `channels` uint8 colour channels (3 rgb8, 1 mono8, 0 none), `depth` (float32 metres
    along the optical axis, REP 118) and `points` (x y z rgb float32 per pixel in the optical frame,
    the layout of an organised PointCloud2). They lie one after the other in the camera's shared
    memory block (see `layout`)."""

    name: str
    width: int
    height: int
    hfov: float
    """Horizontal field of view, radians; pixels are square, so fx = fy = (width/2)/tan(hfov/2)."""
    near: float
    far: float
    channels: int = 3
    depth: bool = False
    points: bool = False
    noise_stddev: float = 0.0
    """Gaussian pixel noise in units of full scale, as SDF camera noise (0..1)."""
    seed: int = 0

    def __post_init__(self) -> None:
        """Fail at configuration, not in a worker."""
        if self.width <= 0 or self.height <= 0:
            raise ValueError(f"camera {self.name!r}: image size {self.width}x{self.height} must be positive")
        if not 0.0 < self.hfov < math.pi:
            raise ValueError(f"camera {self.name!r}: horizontal fov {self.hfov} must be in (0, pi)")
        if not 0.0 < self.near < self.far:
            raise ValueError(f"camera {self.name!r}: clip near {self.near} / far {self.far} must be 0 < near < far")
        if self.channels not in (0, 1, 3):
            raise ValueError(f"camera {self.name!r}: channels {self.channels} must be 0, 1 (mono8) or 3 (rgb8)")
        if self.points and not (self.depth and self.channels == 3):
            raise ValueError(f"camera {self.name!r}: points need depth and rgb")
        if not self.noise_stddev >= 0.0:
            raise ValueError(f"camera {self.name!r}: noise stddev {self.noise_stddev} must be >= 0")

    @property
    def shape(self) -> tuple[int, ...]:
        """The colour image's shape: H×W×3, or H×W for mono."""
        return (self.height, self.width, 3) if self.channels == 3 else (self.height, self.width)

    def layout(self) -> dict[str, tuple[np.dtype[np.generic], tuple[int, ...], int]]:
        """Each output's dtype, shape and byte offset in the camera's shared memory."""
        outputs: list[tuple[str, np.dtype[np.generic], tuple[int, ...]]] = []
        if self.channels:
            outputs.append(("color", np.dtype(np.uint8), self.shape))
        if self.depth:
            outputs.append(("depth", np.dtype(np.float32), (self.height, self.width)))
        if self.points:
            outputs.append(("points", np.dtype(np.float32), (self.height, self.width, 4)))
        placed, offset = {}, 0
        for name, dtype, shape in outputs:
            placed[name] = (dtype, shape, offset)
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
    def fx(self) -> float:
        """Focal length in pixels (fx = fy)."""
        return (self.width / 2.0) / math.tan(self.hfov / 2.0)

    @property
    def principal_point(self) -> tuple[float, float]:
        """(cx, cy) in ROS's pixel-centre coordinates: the image centre, where a symmetric frustum puts it."""
        return (self.width - 1) / 2.0, (self.height - 1) / 2.0


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


class Frame(NamedTuple):
    """A rendered frame. Its arrays are views of the camera's shared memory, valid until the next
    request for that camera; None for an output the camera does not produce."""

    camera: int
    stamp_ns: int
    color: Pixels | None
    depth: Depths | None
    points: Points | None
    render_s: float
    """Seconds the worker spent on it (scene update, render, conversion, copy)."""

    def rgb(self) -> Pixels:
        """The colour image; ValueError for a camera that renders none."""
        if self.color is None:
            raise ValueError(f"camera {self.camera} renders no colour")
        return self.color

    def metres(self) -> Depths:
        """The depth image; ValueError for a camera that renders none."""
        if self.depth is None:
            raise ValueError(f"camera {self.camera} renders no depth")
        return self.depth

    def cloud(self) -> Points:
        """The point cloud; ValueError for a camera that renders none."""
        if self.points is None:
            raise ValueError(f"camera {self.camera} renders no points")
        return self.points
