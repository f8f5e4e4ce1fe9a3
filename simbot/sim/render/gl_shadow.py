"""The sun's shadows for the OpenGL renderer: two depth maps seen from the sun, one square
orthographic view fitted to the scene.

The static casters are drawn into the first map once, when the scene's bodies change; the moving
ones into the second once per posed scene, so the cameras of a set share both and a frame costs
one or two lookups per fragment (hard edges: no filtering). The view covers the static casters (planes excepted: a ground
plane reaches 100 m each way and casts onto nothing) and where the moving bodies were when they
came, `MARGIN` metres wider; a moving body that leaves it casts no shadow there.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np
import numpy.typing as npt

from simbot.sim.render.gl_shaders import gl_matrix
from simbot.sim.render.shapes import PLANE_HALF_SIZE
from simbot.transform import Matrix, matmul, norm

SIZE = 1024
"""Texels each side of each map: about 3 cm a texel over the warehouse (20 m and the margins).
Twice as many cost a third more a frame on llvmpipe (texture cache misses)."""
MARGIN = 5.0
"""Metres the view reaches beyond what it was fitted to (a robot's mast above the racks)."""
SLOPE_BIAS = (2.0, 4.0)
"""glPolygonOffset(factor, units) while drawing the maps: keeps a lit face from shadowing itself."""
TO_TEXTURE = np.array([[0.5, 0, 0, 0.5], [0, 0.5, 0, 0.5], [0, 0, 0.5, 0.5], [0, 0, 0, 1.0]])
"""Clip coordinates (−1..1) to texture coordinates and depth (0..1)."""

Draw = tuple[Any, bytes]
"""A caster: its vertex array for the depth program, and its model matrix (GLSL bytes)."""


class ShadowMap:
    """The sun's two depth maps and the matrix that looks them up; see the module docstring."""

    def __init__(self, ctx: Any, program: Any, direction: tuple[float, float, float]) -> None:
        """`program` draws depth only (`gl_shaders.DEPTH_VERTEX`), with the renderer's vertex arrays for it."""
        import moderngl

        self.ctx = ctx
        self.program = program
        self.maps = [ctx.depth_texture((SIZE, SIZE)) for _ in range(2)]
        for texture in self.maps:
            texture.compare_func = "<="  # a shadow sampler: 1 where the fragment is not behind the map
            texture.filter = (moderngl.NEAREST, moderngl.NEAREST)  # one tap: 2×2 filtering cost 40 % more a frame
            texture.repeat_x = texture.repeat_y = False
        self.framebuffers = [ctx.framebuffer(depth_attachment=texture) for texture in self.maps]
        self.light_view = _look_along(np.asarray(direction, dtype=np.float64))
        self.projection: Matrix = np.eye(4)
        self.has_moving = False

    @property
    def matrix(self) -> Matrix:
        """World → the maps' texture coordinates and depth, for the camera's shader."""
        result: Matrix = matmul(matmul(TO_TEXTURE, self.projection), self.light_view)
        return result

    def fit(self, points: Iterable[npt.NDArray[np.float32]]) -> None:
        """Fits the view to the given world-frame points (`MARGIN` wider)."""
        chosen = [p for p in points if len(p) and np.ptp(p, axis=0).max() < 2.0 * PLANE_HALF_SIZE]
        if not chosen:
            chosen = [np.zeros((1, 3), dtype=np.float32)]
        seen = matmul(np.concatenate(chosen).astype(np.float64), self.light_view[:3, :3].T) + self.light_view[:3, 3]
        low, high = seen.min(axis=0) - MARGIN, seen.max(axis=0) + MARGIN
        centre, half = (low[:2] + high[:2]) / 2.0, (high[:2] - low[:2]).max() / 2.0
        self.projection = _orthographic(centre, half, near=-high[2], far=-low[2])

    def draw(self, which: int, casters: Iterable[Draw]) -> None:
        """Draws the casters into map `which` (0 static, 1 moving), replacing what it held."""
        framebuffer = self.framebuffers[which]
        framebuffer.use()
        framebuffer.clear(depth=1.0)
        self.program["view_projection"].write(gl_matrix(matmul(self.projection, self.light_view)))
        model = self.program["model"]
        self.ctx.polygon_offset = SLOPE_BIAS
        try:
            for vao, transform in casters:
                model.write(transform)
                vao.render()
        finally:
            self.ctx.polygon_offset = (0.0, 0.0)

    def bind(self, static_unit: int, moving_unit: int) -> None:
        self.maps[0].use(static_unit)
        self.maps[1].use(moving_unit)

    def release(self) -> None:
        for item in (*self.framebuffers, *self.maps):
            item.release()


def _look_along(direction: npt.NDArray[np.float64]) -> Matrix:
    """World → the sun's eye frame (it looks along `direction`, OpenGL's −z), centred on the origin."""
    forward = direction / norm(direction)
    up = np.array([0.0, 0.0, 1.0]) if abs(forward[2]) < 0.99 else np.array([1.0, 0.0, 0.0])
    right = np.cross(forward, up)
    right /= norm(right)
    true_up = np.cross(right, forward)
    view = np.eye(4)
    view[0, :3], view[1, :3], view[2, :3] = right, true_up, -forward
    return view


def _orthographic(centre: npt.NDArray[np.float64], half: float, near: float, far: float) -> Matrix:
    """glOrtho of the square `half` each side of `centre`, depths near..far along −z."""
    result = np.eye(4)
    result[0, 0] = result[1, 1] = 1.0 / half
    result[0, 3], result[1, 3] = -centre[0] / half, -centre[1] / half
    result[2, 2] = -2.0 / (far - near)
    result[2, 3] = -(far + near) / (far - near)
    return result
