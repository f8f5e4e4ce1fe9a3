"""The OpenGL 3.3 renderer: moderngl on a headless EGL context (the GPU where there is one, Mesa's
llvmpipe on the CPU where there is not).

The scene comes from the worker's PyBullet copy (`BulletScene`) as `body_pieces` (`visuals.py`),
tessellated once. Bodies that never move are baked into one world-frame vertex
buffer, drawn in one call; each link of a moving body is one buffer in its link frame, drawn with
the link's transform of the request. A body added or removed at run time adds or drops its links'
buffers; a static one re-bakes the world buffer from the static bodies' vertices, which are kept
for that (tessellating them again would cost far more than concatenating). Lighting is TinyRenderer's model (ambient + diffuse of the
world's sun, no specular), per vertex, so a fragment costs one colour write.

The projection flips y, so the framebuffer's first row is the image's top row and the pixels are
read straight into the camera's shared memory, with no copy. A depth camera reads the depth
buffer too, which its depth output turns into metres (`outputs.py`); it draws with depth
clamping, so geometry nearer than the near plane is kept (and reads −inf) rather than cut away,
and it discards what lies beyond the far plane (+inf, the background).
"""

from __future__ import annotations

import logging
import os
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from simbot.sim.render.kinds import Array, Raw
from simbot.sim.render.scene import BulletScene, Matrix, projection_matrix, view_matrix
from simbot.sim.render.surfaces import Piece
from simbot.sim.render.visuals import body_pieces
from simbot.sim.render.specs import CameraSpec, Light, SceneBody
from simbot.transform import Transform

log = logging.getLogger(__name__)

GL_DEPTH_CLAMP = 0x864F
BACKGROUND = (1.0, 1.0, 1.0)
"""White, as TinyRenderer clears (so the two renderers give the same images, and mono of it is white too)."""
FLIP_Y = np.diag([1.0, -1.0, 1.0, 1.0])

_VERTEX = """
#version 330
uniform mat4 view_projection;
uniform mat4 model;
uniform vec3 to_light;
uniform float ambient;
uniform float diffuse;
uniform mat4 view;
in vec3 in_position;
in vec3 in_normal;
in vec3 in_color;
out vec3 color;
out float eye_depth;
void main() {
    vec4 world = model * vec4(in_position, 1.0);
    vec3 normal = normalize(mat3(model) * in_normal);
    color = in_color * (ambient + diffuse * max(dot(normal, to_light), 0.0));
    eye_depth = -(view * world).z;
    gl_Position = view_projection * world;
}
"""

_FRAGMENT = """
#version 330
uniform float far;
uniform bool mono;
in vec3 color;
in float eye_depth;
out vec4 out_color;
void main() {
    if (eye_depth > far) discard;
    float luma = dot(color, vec3(0.299, 0.587, 0.114));
    out_color = vec4(mono ? vec3(luma) : color, 1.0);
}
"""


@dataclass
class _Part:
    """A vertex array drawn with one transform: the static world, or one moving link."""

    vao: Any
    buffer: Any
    body: str | None
    """None for the static world (identity transform)."""
    link: int

    def release(self) -> None:
        self.vao.release()
        self.buffer.release()


@dataclass
class _Target:
    spec: CameraSpec
    fbo: Any
    projection: Matrix
    mono: bool
    """The colour buffer holds luminance (drawn so by the shader)."""
    depth: bool
    """Depth is read back: drawn with depth clamping (see the module docstring)."""


class GlRenderer:
    """Draws the worker's scene into per-camera framebuffers; see the module docstring."""

    name = "gl"

    def __init__(
        self, scene: BulletScene, light: Light, cameras: Mapping[int, CameraSpec], threads: int | None = None
    ) -> None:
        if threads is not None:
            os.environ["LP_NUM_THREADS"] = str(threads)  # read by Mesa's llvmpipe when the context opens
        import moderngl  # an import error is a reason to fall back, reported by the worker

        self.scene = scene
        self.ctx = moderngl.create_context(standalone=True, backend="egl", require=330)  # type: ignore[arg-type]  # the stub lags the signature
        self.device = str(self.ctx.info.get("GL_RENDERER", "unknown"))
        self.ctx.enable(moderngl.DEPTH_TEST)
        self.program = self.ctx.program(vertex_shader=_VERTEX, fragment_shader=_FRAGMENT)
        self.uniforms = {name: _uniform(self.program, name) for name in _UNIFORMS}
        to_light = -np.asarray(light.direction, dtype=np.float64)
        self.uniforms["to_light"].value = tuple(to_light / np.linalg.norm(to_light))
        self.uniforms["ambient"].value = light.ambient
        self.uniforms["diffuse"].value = light.diffuse
        self.parts: list[_Part] = []
        """The static world first (if any), then each moving link, in the order the bodies came."""
        self._static: dict[str, npt.NDArray[np.float32]] = {}
        """Each static body's vertices in the world frame: what the world buffer is baked from."""
        self._posed = -1
        self._model_matrices: list[bytes] = []
        for body in scene.bodies.values():
            self._tessellate(body)
        self._bake()
        self.targets: dict[int, _Target] = {}
        for index, spec in cameras.items():
            self.add_camera(index, spec)

    # --- the scene

    def add_body(self, name: str) -> None:
        """Draw a body the scene has just loaded."""
        body = self.scene.bodies[name]
        self._tessellate(body)
        if body.static:
            self._bake()
        self._posed = -1

    def remove_body(self, name: str) -> None:
        """Stop drawing a body, before the scene drops it."""
        for part in self.parts:
            if part.body == name:
                part.release()
        self.parts = [part for part in self.parts if part.body != name]
        if self._static.pop(name, None) is not None:
            self._bake()
        self._posed = -1

    def add_camera(self, index: int, spec: CameraSpec) -> None:
        self.targets[index] = self._target(spec)

    def _tessellate(self, body: SceneBody) -> None:
        """A static body's vertices in the world frame (for `_bake`); a moving body's links as parts."""
        pieces = body_pieces(self.scene, body.name)
        if body.static:
            frames = self.scene.link_matrices(body.name)
            self._static[body.name] = _stack([_vertices(piece, frames[piece.link]) for piece in pieces])
            return
        for link in sorted({piece.link for piece in pieces}):
            data = _stack([_vertices(p, np.eye(4)) for p in pieces if p.link == link])
            if len(data):
                self.parts.append(self._part(data, body.name, link))

    def _bake(self) -> None:
        """Every static body into one world buffer, drawn in one call, replacing the old one."""
        for part in self.parts:
            if part.body is None:
                part.release()
        self.parts = [part for part in self.parts if part.body is not None]
        world = _stack(list(self._static.values()))
        if len(world):
            self.parts.insert(0, self._part(world, None, -1))
        log.debug("GL scene: %d draws, %d vertices", len(self.parts), sum(p.vao.vertices for p in self.parts))

    def _part(self, data: npt.NDArray[np.float32], body: str | None, link: int) -> _Part:
        buffer = self.ctx.buffer(np.ascontiguousarray(data, dtype=np.float32).tobytes())
        vao = self.ctx.vertex_array(self.program, [(buffer, "3f 3f 3f", "in_position", "in_normal", "in_color")])
        return _Part(vao, buffer, body, link)

    def _target(self, spec: CameraSpec) -> _Target:
        size, drawn = (spec.width, spec.height), spec.drawn()
        mono = len(drawn.get("color", ())) == 2  # an H×W colour buffer: luminance
        read_depth = "depth" in drawn
        color = self.ctx.renderbuffer(size, components=1 if mono else 3)
        depth = self.ctx.depth_texture(size) if read_depth else self.ctx.depth_renderbuffer(size)
        projection = FLIP_Y @ projection_matrix(spec.render_vfov_deg, spec.width / spec.height, spec.near, spec.far)
        fbo = self.ctx.framebuffer(color_attachments=[color], depth_attachment=depth)
        return _Target(spec, fbo, projection, mono, read_depth)

    # --- a frame

    def render(self, camera: int, pose: Transform, drawn: Mapping[Raw, Array]) -> None:
        """Draw camera `camera` at `pose` (the scene already posed); read colour (uint8) and window
        depth (float32, 0..1) straight into the given buffers."""
        target = self.targets[camera]
        view = view_matrix(pose)
        uniforms = self.uniforms
        uniforms["view_projection"].write(_gl(target.projection @ view))
        uniforms["view"].write(_gl(view))
        uniforms["far"].value = target.spec.far
        uniforms["mono"].value = target.mono
        target.fbo.use()
        target.fbo.clear(*BACKGROUND, 1.0, depth=1.0)
        if target.depth:
            self.ctx.enable_direct(GL_DEPTH_CLAMP)
        try:
            self._draw()
        finally:
            if target.depth:
                self.ctx.disable_direct(GL_DEPTH_CLAMP)
        if (color := drawn.get("color")) is not None:
            target.fbo.read_into(color, components=1 if target.mono else 3, alignment=1)
        if (depth := drawn.get("depth")) is not None:
            target.fbo.read_into(depth, attachment=-1, dtype="f4", alignment=1)

    def _draw(self) -> None:
        model = self.uniforms["model"]
        for part, transform in zip(self.parts, self._transforms(), strict=True):
            model.write(transform)
            part.vao.render()

    def _transforms(self) -> list[bytes]:
        """Each part's model matrix for the scene's current pose, worked out once per pose (the
        six cameras of a set share it)."""
        if self._posed != self.scene.version:
            frames = {
                body: self.scene.link_matrices(body) for body in {p.body for p in self.parts if p.body is not None}
            }
            self._model_matrices = [_gl(np.eye(4) if p.body is None else frames[p.body][p.link]) for p in self.parts]
            self._posed = self.scene.version
        return self._model_matrices

    def close(self) -> None:
        self.ctx.release()


_UNIFORMS = ("view_projection", "view", "model", "to_light", "ambient", "diffuse", "far", "mono")


def _uniform(program: Any, name: str) -> Any:
    """A uniform of the program; a shader that lost one (the compiler drops what is unused) fails here, not mid-frame."""
    member = program.get(name, None)
    if member is None:
        raise RuntimeError(f"the GL program has no uniform {name!r}")
    return member


def _gl(m: Matrix) -> bytes:
    """A 4×4 matrix as GLSL's column-major float32 bytes."""
    return np.ascontiguousarray(m.T, dtype=np.float32).tobytes()


def _stack(arrays: list[npt.NDArray[np.float32]]) -> npt.NDArray[np.float32]:
    """Vertex rows one after the other; no rows for no arrays."""
    return np.concatenate(arrays) if arrays else np.empty((0, 9), dtype=np.float32)


def _vertices(piece: Piece, link_to_world: Matrix) -> npt.NDArray[np.float32]:
    """Interleaved position, normal, colour rows of the piece, transformed by `link_to_world`."""
    rotation = link_to_world[:3, :3]
    positions = piece.positions @ rotation.T + link_to_world[:3, 3]
    normals = piece.normals @ rotation.T
    colors = np.broadcast_to(np.asarray(piece.surface.diffuse, dtype=np.float32), positions.shape)
    return np.hstack([positions, normals, colors]).astype(np.float32)
