"""Wide-angle camera (SDF `wideanglecamera`, also `wide_angle_camera`): a colour camera behind one
of Gazebo's fisheye lenses, rendered as a remap of cube faces (simbot/sim/render/wide_angle.py
gives the mapping and how it is drawn).

It is the colour camera of `camera.py` (its image on `<topic>`, else Gazebo's
`world/<w>/model/<m>/link/<l>/sensor/<s>/image`, camera_info beside it under the same stamp, the
`<image>`, `<clip>`, `<noise>` and `<update_rate>` elements; `<distortion>` is ignored, the lens
bends the image), with `<horizontal_fov>` up to 2π and a `<lens>`:

| element | default | meaning |
| --- | --- | --- |
| `<type>` | stereographic | gnomonical, stereographic, equidistant, equisolid_angle, orthographic or custom |
| `<custom_function>` `<c1>` `<c2>` `<c3>` `<f>` `<fun>` | 1 1 0 1 tan | r = c1·f·fun(θ/c2 + c3), fun sin, tan or id (type custom) |
| `<scale_to_hfov>` | true | f fits `<horizontal_fov>` to the image width |
| `<cutoff_angle>` | π/2 | radians off the axis beyond which the image is black |
| `<env_texture_size>` | 256 | pixels on a side of each cube face drawn |

An unknown lens type or function is a one-line error naming the sensor and the element; the
sensor is then off and the rest of the world runs.

camera_info says what ROS's distortion models can: K has the lens's f in pixels at the image
centre. A lens linear in θ (equidistant, or a custom id function with c3 = 0) is OpenCV's fisheye
model exactly: distortion_model `equidistant`, D = [0, 0, 0, 0], fx = c1·f/c2. A tan function with
c2 = 1 and c3 = 0 (gnomonical) is a pinhole: `plumb_bob`, D all zero, fx = c1·f. Any other lens
is given as `equidistant` with k1..k4 fitted (least squares) to its θ_d = r(θ)/fx over the angles
the image shows up to 89°: close, not exact, and no ROS model holds rays beyond 90°.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from typing import Any

import numpy as np
import numpy.typing as npt

from simbot.bus import messages
from simbot.description.model import Sensor
from simbot.description.sensor_params import SdfElement
from simbot.sim.render.wide_lens import FUNCTIONS, LENS_TYPES, WideLens
from simbot.sim.systems.camera import Camera
from simbot.transform import norm

log = logging.getLogger(__name__)

WIDE_OUTPUTS = {"R8G8B8": "wide_color", "RGB_INT8": "wide_color", "L8": "wide_mono", "L_INT8": "wide_mono"}
"""The camera's SDF image formats, by the wide-angle output that renders each."""
MAX_FACE = 4096
FISHEYE_LIMIT = math.radians(89.0)
"""The widest ray OpenCV's fisheye model (θ = atan of the undistorted point) can hold, with a margin."""


def read_lens(sensor: Sensor) -> WideLens:
    """SDF `<camera><lens>`, checked (the table in the module docstring)."""
    camera = SdfElement.of(sensor).child_or_empty("camera")
    lens = camera.child_or_empty("lens")
    kind = lens.text("type", "stereographic") or "stereographic"
    if kind == "custom":
        custom = lens.child_or_empty("custom_function")
        fun = custom.text("fun", "tan") or "tan"
        if fun not in FUNCTIONS:
            raise custom.error("fun", f"{fun!r} is not one of Gazebo's functions; use one of {', '.join(FUNCTIONS)}")
        c1, c2, c3, f = (custom.number(tag, d) for tag, d in (("c1", 1.0), ("c2", 1.0), ("c3", 0.0), ("f", 1.0)))
    elif kind in LENS_TYPES:
        c1, c2, c3, f, fun = LENS_TYPES[kind]
    else:
        known = ", ".join((*LENS_TYPES, "custom"))
        raise lens.error("type", f"{kind!r} is not a Gazebo lens type; use one of {known}")
    scale = (lens.text("scale_to_hfov", "true") or "true").strip().lower()
    if scale not in ("true", "1", "false", "0"):
        raise lens.error("scale_to_hfov", f"expected true or false, got {scale!r}")
    face = lens.integer("env_texture_size", 256)
    if not 1 <= face <= MAX_FACE:
        raise lens.error("env_texture_size", f"must be 1..{MAX_FACE} pixels, got {face}")
    if c1 == 0.0 or c2 == 0.0:
        raise lens.error("custom_function", f"c1 and c2 must be non-zero, got c1 {c1} c2 {c2}")
    cutoff = lens.number("cutoff_angle", math.pi / 2.0)
    if not cutoff > 0.0:
        raise lens.error("cutoff_angle", f"must be > 0 radians, got {cutoff}")
    wide = WideLens(kind, c1, c2, c3, f, fun, scale in ("true", "1"), cutoff, face)
    hfov = camera.number("horizontal_fov", 1.047)
    focal = wide.focal(hfov)
    if not (math.isfinite(focal) and focal > 0.0):
        tag = "scale_to_hfov" if wide.scale_to_hfov else "custom_function"
        raise lens.error(tag, f"gives no positive f for a {kind} lens of horizontal_fov {hfov} (f = {focal})")
    return wide


class WideAngleCamera(Camera):
    """sensor_msgs/Image through a wide-angle lens on `<topic>`, and CameraInfo beside it."""

    formats = WIDE_OUTPUTS
    widest = 2.0 * math.pi + 1e-6

    def wide_lens(self, sensor: Sensor) -> WideLens:
        return read_lens(sensor)

    def camera_info(self, stamp_ns: int) -> Any:
        """camera_info as the module docstring says: exact where a ROS model is, else a fit."""
        spec = self.spec
        assert spec.wide is not None
        model, fx, d = info_model(spec.wide, spec.width, spec.height, spec.hfov)
        cx, cy = spec.principal_point
        info = messages.camera_info(stamp_ns, self.frame_id, spec.width, spec.height, fx, fx, cx, cy)
        if model == "plumb_bob":
            return info
        return dataclasses.replace(info, distortion_model=model, d=np.asarray(d, dtype=np.float64))


def info_model(lens: WideLens, width: int, height: int, hfov: float) -> tuple[str, float, tuple[float, ...]]:
    """(distortion_model, fx, D) of camera_info for the lens (the module docstring)."""
    focal = lens.focal_px(width, hfov)
    if lens.c3 == 0.0 and lens.fun == "tan" and lens.c2 == 1.0:
        return "plumb_bob", lens.c1 * focal, (0.0,) * 5
    fx = lens.c1 * focal / lens.c2
    if lens.c3 == 0.0 and lens.fun == "id":
        return "equidistant", fx, (0.0,) * 4
    corner = lens.angle(np.float64(math.hypot((width - 1) / 2.0, (height - 1) / 2.0)), focal)
    reach = min(lens.cutoff, FISHEYE_LIMIT, float(corner) if np.isfinite(corner) else math.pi)
    theta = np.linspace(reach / 200.0, reach, 200)
    powers = np.stack([theta ** (2 * i + 3) for i in range(4)], axis=-1)
    return "equidistant", fx, _least_squares(powers, lens.radius(theta, focal) / fx - theta)


def _least_squares(a: npt.NDArray[np.float64], b: npt.NDArray[np.float64]) -> tuple[float, ...]:
    """The x minimising |a·x − b|: modified Gram–Schmidt on the columns of [a | b] (as stable as a
    QR factorisation, Björck 1967), then back-substitution. Every dot product is a `math.fsum` of
    exactly rounded products, so D has the same bits on every CPU, where numpy's least squares asks
    LAPACK, whose kernels sum in an order of the CPU's."""
    columns = [np.array(column, dtype=float) for column in np.asarray(a).T] + [np.array(b, dtype=float)]
    n = len(columns) - 1
    r = [[0.0] * (n + 1) for _ in range(n)]
    for j in range(n):
        r[j][j] = norm(columns[j])
        columns[j] = columns[j] / r[j][j]
        for later in range(j + 1, n + 1):
            r[j][later] = math.fsum((columns[j] * columns[later]).tolist())
            columns[later] = columns[later] - r[j][later] * columns[j]
    x = [0.0] * n
    for j in reversed(range(n)):
        x[j] = (r[j][n] - math.fsum(r[j][i] * x[i] for i in range(j + 1, n))) / r[j][j]
    return tuple(x)
