"""The built-in camera outputs (`kinds.py`): colour (rgb8) or mono (mono8) with pixel noise,
depth in metres, and the organised point cloud of an RGBD camera; and the finishing steps that
turn what a renderer drew into them, in place in the camera's shared memory. Both renderers hand
over the same raw form (uint8 colour, window depth 0..1), so this is shared by both.

A camera whose lens bends (`lens.py`) has its colour and depth remapped from the pinhole render
first (noise comes after the lens, as on a real sensor), and its points are cast along each
pixel's undistorted ray; a camera without one takes none of these steps."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from simbot.sim.render import lens
from simbot.sim.render.kinds import Array, Finish, Optics, OutputKind
from simbot.sim.render.specs import Depths, Pixels, Points
from simbot.transform import matmul

LUMA = (0.299, 0.587, 0.114)
"""ITU-R BT.601 luminance weights, as OpenCV's RGB2GRAY and Gazebo's L8 conversion."""


def linear_depth(window: Depths, near: float, far: float) -> None:
    """Window depth (0..1, OpenGL's perspective) → metres along the optical axis, in place.
    REP 118: +inf where nothing was drawn (nothing within far). −inf never occurs: as in Gazebo,
    geometry nearer than `near` is cut away (a camera inside its housing sees what lies beyond
    it), so every finite reading lies in near..far."""
    nothing = window >= 1.0
    np.multiply(window, far - near, out=window)
    np.subtract(far, window, out=window)
    np.divide(near * far, window, out=window)
    window[nothing] = np.inf


def luminance(rgb: Pixels) -> Pixels:
    weights = np.asarray(LUMA, dtype=np.float32)
    out: Pixels = np.rint(matmul(rgb.astype(np.float32), weights)).astype(np.uint8)
    return out


def add_noise(pixels: Pixels, stddev: float, rng: np.random.Generator) -> None:
    """Gaussian noise of `stddev` (fraction of full scale), in place, clipped to 0..255."""
    noise = rng.standard_normal(pixels.shape, dtype=np.float32) * np.float32(stddev * 255.0)
    pixels[...] = np.clip(np.rint(pixels + noise), 0, 255).astype(np.uint8)


class PointGrid:
    """Per-pixel ray slopes of a camera, worked out once: (u − cx)/fx and (v − cy)/fy of a pinhole
    camera, the undistorted ray of each pixel (`lens.rays`, NaN where none) through a lens that bends."""

    def __init__(self, spec: Optics) -> None:
        cx, cy = spec.principal_point
        self.x: Depths = ((np.arange(spec.width, dtype=np.float32) - cx) / spec.fx)[np.newaxis, :]
        self.y: Depths = ((np.arange(spec.height, dtype=np.float32) - cy) / spec.fx)[:, np.newaxis]
        if spec.distortion.bends:
            self.x, self.y = lens.rays(spec.distortion, spec.width, spec.height, spec.fx)

    def fill(self, depth: Depths, rgb: Pixels, out: Points) -> None:
        """x y z rgb per pixel in the optical frame (x right, y down, z forward); NaN where the
        depth is not finite (PCL's convention for an organised cloud)."""
        z = np.where(np.isfinite(depth), depth, np.float32(np.nan))
        out[..., 0] = self.x * z
        out[..., 1] = self.y * z
        out[..., 2] = z
        packed = (rgb[..., 0].astype(np.uint32) << 16) | (rgb[..., 1].astype(np.uint32) << 8) | rgb[..., 2]
        out[..., 3] = packed.view(np.float32)


def _remap(spec: Optics) -> lens.Remap | None:
    """The camera's lens as remap tables (shared by its outputs); None for a pinhole camera."""
    if not spec.distortion.bends:
        return None
    return lens.remap(spec.distortion, spec.width, spec.height, spec.fx)


def noise(spec: Optics) -> Finish | None:
    """The lens, then the camera's seeded pixel noise; none for a pinhole camera at stddev 0."""
    bend = _remap(spec)
    rng = np.random.default_rng(spec.seed) if spec.noise_stddev > 0.0 else None
    if bend is None and rng is None:
        return None

    def finish(pixels: Array, _: Mapping[str, Array]) -> None:
        if bend is not None:
            bend.pixels(pixels)
        if rng is not None:
            add_noise(pixels, spec.noise_stddev, rng)

    return finish


def metres(spec: Optics) -> Finish:
    """Window depth to metres, then the lens (nearest: no depth between two surfaces)."""
    bend = _remap(spec)

    def finish(depth: Array, _: Mapping[str, Array]) -> None:
        linear_depth(depth, spec.near, spec.far)
        if bend is not None:
            bend.depth(depth)

    return finish


def points(spec: Optics) -> Finish:
    grid = PointGrid(spec)

    def fill(out: Array, arrays: Mapping[str, Array]) -> None:
        grid.fill(arrays["depth"], arrays["color"], out)

    return fill


COLOR = OutputKind("color", np.uint8, 3, encoding="rgb8", draws="color", finisher=noise)
MONO = OutputKind("mono", np.uint8, 1, encoding="mono8", draws="color", finisher=noise)
"""The colour buffer as luminance (the renderer draws it so: GL in its shader, TinyRenderer by `luminance`)."""
DEPTH = OutputKind("depth", np.float32, 1, encoding="32FC1", draws="depth", finisher=metres)
"""float32 metres along the optical axis (REP 118); pixel noise is not applied to depth."""
POINTS = OutputKind("points", np.float32, 4, needs=("color", "depth"), finisher=points)
"""x y z rgb float32 per pixel in the optical frame: the layout of an organised PointCloud2."""
LABELS = OutputKind("labels", np.uint32, 1, draws="labels")
"""Each pixel's label and instance, packed (`label_bits.py`): what segmentation and bounding boxes are read from."""
TEMPERATURE = OutputKind("temperature", np.float32, 1, draws="temperature")
"""Each pixel's temperature in kelvin (the Thermal system's, else the atmosphere's at that height)."""
