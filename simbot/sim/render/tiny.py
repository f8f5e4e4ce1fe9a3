"""PyBullet's TinyRenderer: a software rasterizer in PyBullet itself, the fallback where no EGL
context opens. About 11 frames per CPU-second at 640×480 in the warehouse (`make bench`)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from simbot.sim.render.kinds import Array, Raw
from simbot.sim.render.outputs import luminance
from simbot.sim.render.scene import BulletScene, projection_matrix, view_matrix
from simbot.sim.render.specs import CameraSpec, Light
from simbot.transform import Transform

CLEARED_DEPTH = 1.0 - 1e-6
"""TinyRenderer clears its depth buffer to just under 1; at or above this, nothing was drawn (a
surface within about 1 cm of a 50 m far clip reads +inf too)."""


class TinyRenderer:
    """Draws with getCameraImage(ER_TINY_RENDERER) into the camera's buffers."""

    name = "tiny"
    device = "PyBullet TinyRenderer (CPU)"

    def __init__(self, scene: BulletScene, light: Light, cameras: Mapping[int, CameraSpec]) -> None:
        self.scene = scene
        self.light = light
        self.cameras: dict[int, CameraSpec] = {}
        self.projections: dict[int, Sequence[float]] = {}
        for index, spec in cameras.items():
            self.add_camera(index, spec)

    def add_camera(self, index: int, spec: CameraSpec) -> None:
        self.cameras[index] = spec
        self.projections[index] = _flat(
            projection_matrix(spec.render_vfov_deg, spec.width / spec.height, spec.near, spec.far)
        )

    def add_body(self, name: str) -> None:
        """Nothing to do: PyBullet draws the scene's bodies as they are."""

    def remove_body(self, name: str) -> None:
        """Nothing to do: PyBullet draws the scene's bodies as they are."""

    def render(self, camera: int, pose: Transform, drawn: Mapping[Raw, Array]) -> None:
        spec = self.cameras[camera]
        pb = self.scene.pb
        image = pb.getCameraImage(
            spec.width,
            spec.height,
            _flat(view_matrix(pose)),
            self.projections[camera],
            renderer=pb.ER_TINY_RENDERER,
            flags=pb.ER_NO_SEGMENTATION_MASK,
            shadow=0,
            lightDirection=[-v for v in self.light.direction],
            lightColor=list(self.light.color),
            lightAmbientCoeff=self.light.ambient,
            lightDiffuseCoeff=self.light.diffuse,
            lightSpecularCoeff=self.light.specular,
            physicsClientId=self.scene.client,
        )
        if (color := drawn.get("color")) is not None:
            rgb = np.asarray(image[2], dtype=np.uint8).reshape(spec.height, spec.width, 4)[:, :, :3]
            color[...] = luminance(rgb) if color.ndim == 2 else rgb
        if (depth := drawn.get("depth")) is not None:
            depth[...] = np.asarray(image[3], dtype=np.float32).reshape(spec.height, spec.width)
            depth[depth >= CLEARED_DEPTH] = 1.0

    def close(self) -> None:
        """Nothing of its own: the scene's client is the worker's to disconnect."""


def _flat(m: np.ndarray) -> Sequence[float]:
    """A 4×4 matrix as PyBullet wants it: 16 floats, column-major."""
    return [float(v) for v in m.T.reshape(-1)]
