"""PyBullet's TinyRenderer: a software rasterizer in PyBullet itself, the fallback where no EGL
context opens. About 11 frames per CPU-second at 640×480 in the warehouse (`make bench`).

It lights the scene as far as getCameraImage allows: one light, the world's first directional one
(its diffuse colour; none: ambient only), the scene's ambient as its ambient coefficient (the grey
of `<scene><ambient>`), no specular (TinyRenderer's highlight ignores the material's specular colour,
so simbot leaves it off). It has no sky colour (it clears to white whatever `<scene><background>`
says), no point or spot lights, no emissive, unlit or translucent surfaces, no textures but those
PyBullet reads itself, no shadows (PyBullet's own are not the sun's). Like OpenGL it cuts away
geometry nearer than the near plane (a camera inside its housing sees out).

PyBullet draws a link without a visual as its collision shapes; an actor's leg capsules
(simbot.description.actor_legs) are made transparent, so it draws the skin, in its bind pose (the
stand-in simbot.description.stand_in_meshes gives it), as the GL renderer draws an unposed skin.

Labels and temperatures come from PyBullet's segmentation mask, which tells bodies and links
apart but not the visuals of one link: a link shows its first visual's label and temperature,
and geometry without a temperature shows the atmosphere's at z = 0 (OpenGL: at its height)."""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from simbot.description.actor_legs import is_leg_link
from simbot.sim.render.kinds import Array, Raw
from simbot.sim.render.outputs import luminance
from simbot.sim.render.scene import BulletScene, projection_matrix, view_matrix
from simbot.sim.render.specs import CameraSpec, Light
from simbot.sim.render.visuals import body_pieces, link_indices
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
        self.lighting = tiny_lighting(light)
        self._annotations: tuple[int, dict[int, tuple[int, float]]] = (-1, {})
        """(the scene's version, each (body, link)'s packed label and temperature by mask value)"""
        self.cameras: dict[int, CameraSpec] = {}
        self.projections: dict[int, Sequence[float]] = {}
        for index, spec in cameras.items():
            self.add_camera(index, spec)
        for name in scene.ids:
            self._hide_legs(name)

    def add_camera(self, index: int, spec: CameraSpec) -> None:
        self.cameras[index] = spec
        self.projections[index] = _flat(
            projection_matrix(spec.render_vfov_deg, spec.width / spec.height, spec.near, spec.far)
        )

    def edit(self, removed: Collection[str], added: Collection[str], light: Light | None, order: Sequence[str]) -> None:
        """PyBullet draws the scene's bodies as they are (in the order it holds them), the new ones
        but for their leg capsules; the new lighting where there is one."""
        for name in added:
            self._hide_legs(name)
        if light is not None:
            self.light = light
            self.lighting = tiny_lighting(light)

    def _hide_legs(self, name: str) -> None:
        """PyBullet draws the body as it is, but for its leg capsules (see the module docstring)."""
        pb, body = self.scene.pb, self.scene.ids[name]
        for link, index in link_indices(self.scene, name).items():
            if is_leg_link(link):
                pb.changeVisualShape(body, index, rgbaColor=[1.0, 1.0, 1.0, 0.0], physicsClientId=self.scene.client)

    def render(self, camera: int, pose: Transform, drawn: Mapping[Raw, Array]) -> None:
        spec = self.cameras[camera]
        pb = self.scene.pb
        annotated = "labels" in drawn or "temperature" in drawn
        flags = pb.ER_SEGMENTATION_MASK_OBJECT_AND_LINKINDEX if annotated else pb.ER_NO_SEGMENTATION_MASK
        image = pb.getCameraImage(
            spec.width,
            spec.height,
            _flat(view_matrix(pose)),
            self.projections[camera],
            renderer=pb.ER_TINY_RENDERER,
            flags=flags,
            shadow=0,
            physicsClientId=self.scene.client,
            **self.lighting,
        )
        if (color := drawn.get("color")) is not None:
            rgb = np.asarray(image[2], dtype=np.uint8).reshape(spec.height, spec.width, 4)[:, :, :3]
            color[...] = luminance(rgb) if color.ndim == 2 else rgb
        if (depth := drawn.get("depth")) is not None:
            depth[...] = np.asarray(image[3], dtype=np.float32).reshape(spec.height, spec.width)
            depth[depth >= CLEARED_DEPTH] = 1.0
        if annotated:
            self._annotate(np.asarray(image[4], dtype=np.int64).reshape(spec.height, spec.width), drawn)

    def _annotate(self, mask: npt.NDArray[np.int64], drawn: Mapping[Raw, Array]) -> None:
        """Labels and temperatures by the body and link PyBullet drew in each pixel (0: the sky)."""
        table = self._table()
        values, inverse = np.unique(mask, return_inverse=True)
        found = [table.get(int(v), (0, 0.0)) for v in values]
        if (labels := drawn.get("labels")) is not None:
            labels[...] = np.array([f[0] for f in found], dtype=np.uint32)[inverse].reshape(mask.shape)
        if (temperature := drawn.get("temperature")) is not None:
            temperature[...] = np.array([f[1] for f in found], dtype=np.float32)[inverse].reshape(mask.shape)

    def _table(self) -> dict[int, tuple[int, float]]:
        """Mask value (body id + (link + 1) << 24) → (packed label, temperature), rebuilt when bodies change."""
        version, table = self._annotations
        if version == self.scene.body_version:
            return table
        table = {}
        ambient = self.light.ambient_temperature
        for name, body_id in self.scene.ids.items():
            for piece in body_pieces(self.scene, name):
                temperature = ambient if np.isnan(piece.temperature) else piece.temperature
                table.setdefault(body_id + ((piece.link + 1) << 24), (piece.label, temperature))
        self._annotations = (self.scene.body_version, table)
        return table

    def close(self) -> None:
        """Nothing of its own: the scene's client is the worker's to disconnect."""


def tiny_lighting(light: Light) -> dict[str, Any]:
    """getCameraImage's light arguments for the world's lighting (see the module docstring)."""
    sun = light.sun
    colour = sun.diffuse if sun is not None else (0.0, 0.0, 0.0)
    direction = sun.direction if sun is not None else (0.0, 0.0, -1.0)
    return {
        "lightDirection": [-v for v in direction],
        "lightColor": list(colour),
        "lightAmbientCoeff": float(np.mean(light.ambient)),
        "lightDiffuseCoeff": 1.0 if sun is not None else 0.0,
        "lightSpecularCoeff": 0.0,
    }


def _flat(m: np.ndarray) -> Sequence[float]:
    """A 4×4 matrix as PyBullet wants it: 16 floats, column-major."""
    return [float(v) for v in m.T.reshape(-1)]
