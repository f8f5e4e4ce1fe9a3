"""The OpenGL 3.3 renderer: moderngl on a headless EGL context (the GPU where there is one, Mesa's
llvmpipe on the CPU where there is not).

The scene comes from the worker's PyBullet copy (`BulletScene`) as each body's pieces
(`visuals.py::body_pieces`: triangles with one `Surface` each), read once when the body loads.
Bodies that never move are baked into world-frame vertex buffers, one per surface and cell of the
floor plan (`culling.py`); each (link, surface) of a moving body is one buffer in its link frame,
drawn with the link's transform of the request. Each view draws only the parts whose bounding
sphere reaches into its frustum, the opaque ones nearest first; the label and temperature pass
draws the same ones. A body added or removed at run time adds or drops its parts; a
static one re-bakes the world's buffers from the static bodies' vertices, which are kept for that.
Textures (albedo and normal maps) are read and uploaded (mipmapped, sampled from the nearest texel of the nearest level) once per
worker, the first time a piece names them; an image that cannot be read is one warning and the
piece shows its colour.

Shading is in `gl_shaders.py` (Gazebo's material model, the world's lights, `Light`), the sun's
shadows in `gl_shadow.py`. The sky is `<scene><background>`. Opaque parts are drawn first, then
those with opacity < 1 blended over them (not sorted, and writing no depth: a depth camera sees
through them). No face is culled (a mesh's winding is not trusted), so a translucent box blends
its back face and then its front one over what lies behind it.

Clipping is Gazebo's: geometry nearer than the camera's `near` or beyond its `far` is cut away, so
a camera inside its housing sees out. The projection flips y, so the framebuffer's first row is the
image's top row and the pixels are read straight into the camera's shared memory, with no copy. A
depth camera reads the depth buffer too, which its depth output turns into metres (`outputs.py`).
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable, Collection, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt

from simbot.sim.render import culling, textures
from simbot.sim.render import gl_shaders as shaders
from simbot.sim.render.gl_parts import Part, Rows, stacked, vertex_rows
from simbot.sim.render.gl_shadow import ShadowMap
from simbot.sim.render.kinds import Array, Raw
from simbot.sim.render.outputs import LUMA
from simbot.sim.render.scene import BulletScene, Matrix, projection_matrix, view_matrix
from simbot.sim.render.skinning import Skinned
from simbot.sim.render.specs import MAX_LIGHTS, CameraSpec, Light, SceneBody
from simbot.sim.render.surfaces import Piece, Surface
from simbot.sim.render.visuals import body_pieces
from simbot.transform import Transform, matmul

log = logging.getLogger(__name__)

FLIP_Y = np.diag([1.0, -1.0, 1.0, 1.0])
SHADED_ROW, DEPTH_ROW, ANNOTATION_ROW = "3f 3f 2f 8x", "3f 28x", "3f 20x 1u 1f"
"""What each program reads of a vertex."""
ALBEDO_UNIT, SHADOW_STATIC_UNIT, SHADOW_MOVING_UNIT, NORMAL_UNIT = 0, 1, 2, 3

_Drawn = tuple[Part, bytes]
"""A part with its model matrix (GLSL bytes)."""


class _Seen(NamedTuple):
    """What one view draws: its opaque parts nearest first, then its translucent ones."""

    opaque: list[_Drawn]
    translucent: list[_Drawn]


@dataclass
class _Target:
    spec: CameraSpec
    fbo: Any | None
    """Colour and depth; None for a camera that draws neither."""
    projection: Matrix
    mono: bool
    """The colour buffer holds luminance (drawn so by the shader)."""
    annotations: Any | None
    """Labels and temperatures; None for a camera that draws neither."""


class GlRenderer:
    """Draws the worker's scene into per-camera framebuffers; see the module docstring."""

    name = "gl"

    def __init__(
        self,
        scene: BulletScene,
        light: Light,
        cameras: Mapping[int, CameraSpec],
        threads: int | None = None,
        pieces: Callable[[BulletScene, str], list[Piece]] = body_pieces,
    ) -> None:
        """`pieces` gives a body's pieces (`visuals.py::body_pieces`; a test may dress them in surfaces of its own)."""
        if threads is not None:
            os.environ["LP_NUM_THREADS"] = str(threads)  # read by Mesa's llvmpipe when the context opens
        import moderngl  # an import error is a reason to fall back, reported by the worker

        self.scene = scene
        self.light = light
        self.pieces = pieces
        self.ctx = moderngl.create_context(standalone=True, backend="egl", require=330)  # type: ignore[arg-type]  # the stub lags the signature
        self.device = str(self.ctx.info.get("GL_RENDERER", "unknown"))
        self.ctx.enable(moderngl.DEPTH_TEST)
        if len(light.sources) > MAX_LIGHTS:
            log.warning("the world has %d lights; the renderer shades the first %d", len(light.sources), MAX_LIGHTS)
        self.programs: dict[shaders.Kind, shaders.Program] = {}
        """The camera programs, one a kind of surface, compiled when a piece of the kind first comes."""
        self.depth_program: Any = self.ctx.program(
            vertex_shader=shaders.DEPTH_VERTEX, fragment_shader=shaders.DEPTH_FRAGMENT
        )
        self.annotation_program: Any = self.ctx.program(
            vertex_shader=shaders.ANNOTATION_VERTEX, fragment_shader=shaders.ANNOTATION_FRAGMENT
        )
        self.shadow: ShadowMap | None = None
        self._light_up(light)
        self.parts: list[Part] = []
        """The static world first, then each moving link's surfaces, in the order the bodies came."""
        self._static: dict[str, list[tuple[Surface, Rows]]] = {}
        """Each static body's pieces in the world frame: what the world's buffers are baked from."""
        self._textures: dict[str, Any | None] = {}
        self._posed = -1
        self._model_matrices: list[bytes] = []
        self._centres: npt.NDArray[np.float64] = np.zeros((0, 3))
        self._radii: npt.NDArray[np.float64] = np.zeros(0)
        for body in scene.bodies.values():
            self._load(body)
        self._bake()
        self.targets: dict[int, _Target] = {}
        for index, spec in cameras.items():
            self.add_camera(index, spec)

    def _light_up(self, light: Light) -> None:
        """The world's lighting: the sun's shadow map along its direction, the atmosphere's temperatures."""
        self.light = light
        caster = light.shadow_caster
        if self.shadow is not None:
            self.shadow.release()
        self.shadow = (
            None if caster is None else ShadowMap(self.ctx, self.depth_program, light.sources[caster].direction)
        )
        self.annotation_program["ambient_temperature"].value = light.ambient_temperature
        self.annotation_program["temperature_gradient"].value = light.temperature_gradient

    def _program(self, kind: shaders.Kind) -> shaders.Program:
        if kind not in self.programs:
            self.programs[kind] = shaders.Program(self.ctx, self.light, kind, _SAMPLERS)
            self._posed = -1  # its shadow uniforms are set with the next pose
        return self.programs[kind]

    # --- the scene

    def edit(self, removed: Collection[str], added: Collection[str], light: Light | None, order: Sequence[str]) -> None:
        """The scene has dropped `removed` and loaded `added` (`pipe.EditScene`): their parts go and
        come, the lighting changes, and the static world is baked again once, where it changed,
        every body in `order` (so that an edited world batches as a fresh one does)."""
        rebake = [name for name in removed if self._static.pop(name, None) is not None] != []
        for part in self.parts:
            if part.body in removed:
                part.release()
        self.parts = [part for part in self.parts if part.body not in removed]
        if light is not None and light != self.light:
            self._relight(light)
            rebake = True
        for name in added:
            self._load(self.scene.bodies[name])
            rebake = rebake or self.scene.bodies[name].static
        rank = {name: i for i, name in enumerate(order)}
        self._static = dict(sorted(self._static.items(), key=lambda item: rank.get(item[0], len(rank))))
        self.parts.sort(key=lambda part: -1 if part.body is None else rank.get(part.body, len(rank)))
        self._posed = -1
        if rebake:
            self._bake()
        elif self.shadow is not None:
            self._fit_shadow()  # the sun's view takes in the moving bodies where they are

    def _relight(self, light: Light) -> None:
        """Other lights: the programs are written for the lights (their values are constants in
        them), so each part is bound to its kind's program anew."""
        for program in self.programs.values():
            program.release()
        self.programs = {}
        self._light_up(light)
        for part in self.parts:
            part.vao.release()
            part.program = self._program(part.program.kind)
            part.vao = self._shaded(part.program, part.buffer)
            part.material = part.program.material(part.surface)

    def add_camera(self, index: int, spec: CameraSpec) -> None:
        self.targets[index] = self._target(spec)

    def _load(self, body: SceneBody) -> None:
        """A static body's pieces in the world frame (for `_bake`); a moving body's link surfaces as parts."""
        pieces = self.pieces(self.scene, body.name)
        for piece in pieces:
            self._texture(piece.surface.albedo_map)
            self._texture(piece.surface.normal_map)
        if body.static:
            frames = self.scene.link_matrices(body.name)
            self._static[body.name] = [(p.surface, vertex_rows(p, frames[p.link])) for p in pieces]
            return
        identity = np.eye(4)
        for piece in pieces:
            if piece.skin is not None and len(piece.positions):
                self.parts.append(
                    self._part(vertex_rows(piece, identity), body.name, piece.link, piece.surface, piece.skin)
                )
        pieces = [piece for piece in pieces if piece.skin is None]
        for link, surface in dict.fromkeys((p.link, p.surface) for p in pieces):
            data = stacked([vertex_rows(p, identity) for p in pieces if p.link == link and p.surface == surface])
            if len(data):
                self.parts.append(self._part(data, body.name, link, surface))

    def _bake(self) -> None:
        """Every static body into one world buffer per surface, replacing the old ones; the sun's
        view refitted and its static map redrawn."""
        for part in self.parts:
            if part.body is None:
                part.release()
        moving = [part for part in self.parts if part.body is not None]
        batches: dict[tuple[Surface, culling.Cell], list[Rows]] = {}
        for pieces in self._static.values():
            for surface, rows in pieces:
                if len(rows):
                    batches.setdefault((surface, culling.cell_of(rows[:, :3])), []).append(rows)
        static = [self._part(stacked(rows), None, -1, surface) for (surface, _), rows in batches.items()]
        self.parts = [part for part in static if part.vao.vertices] + moving
        self._posed = -1
        if self.shadow is not None:
            self._fit_shadow()
        log.debug("GL scene: %d draws, %d vertices", len(self.parts), sum(p.vao.vertices for p in self.parts))

    def _fit_shadow(self) -> None:
        """The sun's view over the static casters and the moving bodies as they are now; the static map drawn."""
        assert self.shadow is not None
        static = [rows[:, :3] for pieces in self._static.values() for surface, rows in pieces if surface.cast_shadows]
        moving = [frame[:3, 3].reshape(1, 3).astype(np.float32) for frame in self._link_origins()]
        self.shadow.fit(static + moving)
        identity = shaders.gl_matrix(np.eye(4))
        self.shadow.draw(0, ((p.depth_vao, identity) for p in self.parts if p.body is None and p.surface.cast_shadows))

    def _link_origins(self) -> Iterator[Matrix]:
        for body in {p.body for p in self.parts if p.body is not None}:
            yield from self.scene.link_matrices(body).values()

    def _part(self, data: Rows, body: str | None, link: int, surface: Surface, skin: Skinned | None = None) -> Part:
        buffer = self.ctx.buffer(np.ascontiguousarray(data, dtype=np.float32).tobytes())
        texture = self._textures.get(surface.albedo_map) if surface.albedo_map else None
        normal_map = self._textures.get(surface.normal_map) if surface.normal_map else None
        program = self._program(shaders.Kind.of(surface, texture is not None, normal_map is not None))
        vao = self._shaded(program, buffer)
        depth_vao = self.ctx.vertex_array(self.depth_program, [(buffer, DEPTH_ROW, "in_position")])
        annotated = [(buffer, ANNOTATION_ROW, "in_position", "in_label", "in_temperature")]
        annotation_vao = self.ctx.vertex_array(self.annotation_program, annotated)
        centre, radius = culling.sphere(data[:, :3])
        material = program.material(surface)
        return Part(
            buffer,
            vao,
            depth_vao,
            annotation_vao,
            body,
            link,
            surface,
            texture,
            normal_map,
            program,
            material,
            centre,
            radius,
            skin,
            data if skin is not None else None,
        )

    def _shaded(self, program: shaders.Program, buffer: Any) -> Any:
        """The camera program's view of a part's vertices; attributes its kind does not read (a
        world with no light reads no normal) are skipped."""
        attributes = [(buffer, SHADED_ROW, "in_position", "in_normal", "in_uv")]
        return self.ctx.vertex_array(program.program, attributes, skip_errors=True)

    def _texture(self, path: str | None) -> None:
        """Reads and uploads an image the first time it is named; None (the colour is used) where it cannot be read."""
        if path is None or path in self._textures:
            return
        import moderngl

        texture = textures.upload(self.ctx, path, self.device)  # mipmapped once, kept on disk
        if texture is None:
            log.warning("texture %s cannot be read; its surfaces show their colour", path)
            self._textures[path] = None
            return
        # the nearest texel of the nearest level: bilinear cost a tenth more a frame on llvmpipe,
        # trilinear half as much again; a 4 mm texel is about a pixel at 1 m, so little shows
        texture.filter = (moderngl.NEAREST_MIPMAP_NEAREST, moderngl.NEAREST)
        self._textures[path] = texture

    def _target(self, spec: CameraSpec) -> _Target:
        size, drawn = (spec.width, spec.height), spec.drawn()
        mono = len(drawn.get("color", ())) == 2  # an H×W colour buffer: luminance
        aspect = spec.width / spec.height
        projection = matmul(FLIP_Y, projection_matrix(spec.render_vfov_deg, aspect, spec.near, spec.far))
        fbo = annotations = None
        if "color" in drawn or "depth" in drawn:
            color = self.ctx.renderbuffer(size, components=1 if mono else 3)
            depth = self.ctx.depth_texture(size) if "depth" in drawn else self.ctx.depth_renderbuffer(size)
            fbo = self.ctx.framebuffer(color_attachments=[color], depth_attachment=depth)
        if "labels" in drawn or "temperature" in drawn:
            # both: the annotation program writes both (the temperature at location 1)
            buffers = [self.ctx.renderbuffer(size, components=1, dtype=dtype) for dtype in ("u4", "f4")]
            annotations = self.ctx.framebuffer(
                color_attachments=buffers, depth_attachment=self.ctx.depth_renderbuffer(size)
            )
        return _Target(spec, fbo, projection, mono, annotations)

    # --- a frame

    def render(self, camera: int, pose: Transform, drawn: Mapping[Raw, Array]) -> None:
        """Draw camera `camera` at `pose` (the scene already posed); read colour (uint8) and window
        depth (float32, 0..1) straight into the given buffers."""
        target = self.targets[camera]
        transforms = self._transforms()
        view_projection = matmul(target.projection, view_matrix(pose))
        seen = self._seen(view_projection, np.asarray(pose[0], dtype=np.float64), transforms)
        if target.fbo is not None:
            self._shade(target, target.fbo, pose, shaders.gl_matrix(view_projection), seen, drawn)
        if target.annotations is not None:
            self._annotate(target.annotations, shaders.gl_matrix(view_projection), seen, drawn)

    def _seen(self, view_projection: Matrix, eye: npt.NDArray[np.float64], transforms: list[bytes]) -> _Seen:
        """The parts the view can show with their transforms: the opaque ones nearest first, and
        the translucent ones in the scene's order (`culling.py`)."""
        inside = np.flatnonzero(culling.visible(culling.frustum_planes(view_projection), self._centres, self._radii))
        offsets = self._centres - eye
        distance = (offsets * offsets).sum(axis=1)
        opaque = sorted((i for i in inside if self.parts[i].surface.opacity >= 1.0), key=lambda i: (distance[i], i))
        translucent = [i for i in inside if self.parts[i].surface.opacity < 1.0]
        return _Seen(*([(self.parts[i], transforms[i]) for i in kind] for kind in (opaque, translucent)))

    def _shade(
        self,
        target: _Target,
        fbo: Any,
        pose: Transform,
        view_projection: bytes,
        seen: _Seen,
        drawn: Mapping[Raw, Array],
    ) -> None:
        """What the camera sees in the world's light: colour, and window depth."""
        for program in self.programs.values():
            program.write("view_projection", view_projection)
            program.set("eye", tuple(float(v) for v in pose[0]))
            program.set("mono", target.mono)
        fbo.use()
        sky = self.light.background
        fbo.clear(*((float(matmul(sky, LUMA)),) * 3 if target.mono else sky), 1.0, depth=1.0)
        self._draw(seen, fbo)
        if (color := drawn.get("color")) is not None:
            fbo.read_into(color, components=1 if target.mono else 3, alignment=1)
        if (depth := drawn.get("depth")) is not None:
            fbo.read_into(depth, attachment=-1, dtype="f4", alignment=1)

    def _annotate(self, fbo: Any, view_projection: bytes, seen: _Seen, drawn: Mapping[Raw, Array]) -> None:
        """Each pixel's label and temperature, every surface drawn opaque and unshaded; 0 where
        nothing is (the sky)."""
        program = self.annotation_program
        program["view_projection"].write(view_projection)
        fbo.use()
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        for part, transform in (*seen.opaque, *seen.translucent):
            program["model"].write(transform)
            part.annotation_vao.render()
        if (labels := drawn.get("labels")) is not None:
            fbo.read_into(labels, components=1, attachment=0, dtype="u4", alignment=1)
        if (temperature := drawn.get("temperature")) is not None:
            fbo.read_into(temperature, components=1, attachment=1, dtype="f4", alignment=1)

    def _draw(self, seen: _Seen, fbo: Any) -> None:
        """The opaque parts, then the translucent ones blended over them without writing depth.
        (A depth pre-pass, to shade each pixel once, cost more on llvmpipe than it saved: the
        vertices, drawn twice, are the larger part of a frame.)"""
        import moderngl

        for part, transform in seen.opaque:
            self._draw_part(part, transform)
        if not seen.translucent:
            return
        self.ctx.enable(moderngl.BLEND)
        fbo.depth_mask = False
        try:
            for part, transform in seen.translucent:
                self._draw_part(part, transform)
        finally:
            fbo.depth_mask = True
            self.ctx.disable(moderngl.BLEND)

    def _draw_part(self, part: Part, transform: bytes) -> None:
        if part.texture is not None:
            part.texture.use(ALBEDO_UNIT)
        if part.normal_map is not None:
            part.normal_map.use(NORMAL_UNIT)
        part.program.draw(part.material, transform, part.vao)

    def _transforms(self) -> list[bytes]:
        """Each part's model matrix for the scene's current pose, its bounding sphere's centre in
        the world, and the sun's moving map, worked out once per pose (the cameras of a set share them)."""
        if self._posed != self.scene.version:
            self._skin()
            frames = {
                body: self.scene.link_matrices(body) for body in {p.body for p in self.parts if p.body is not None}
            }
            identity = np.eye(4)
            matrices = [identity if p.body is None else frames[p.body][p.link] for p in self.parts]
            self._model_matrices = [shaders.gl_matrix(m) for m in matrices]
            self._centres = np.array(
                [matmul(m[:3, :3], p.centre) + m[:3, 3] for p, m in zip(self.parts, matrices, strict=True)]
            ).reshape(-1, 3)
            self._radii = np.array([p.radius for p in self.parts], dtype=np.float64)
            self._posed = self.scene.version
            self._shadow_moving()
        return self._model_matrices

    def _skin(self) -> None:
        """Each skinned part's vertices at the pose the scene's joint positions give, into its buffer."""
        posed = self.scene.posed or {}
        for part in self.parts:
            if part.skin is None or part.rows is None or part.body is None:
                continue
            state = posed.get(part.body)
            positions, normals = part.skin.posed(state.joints if state is not None else {})
            part.rows[:, 0:3], part.rows[:, 3:6] = positions, normals
            part.buffer.write(part.rows.tobytes())
            part.centre, part.radius = culling.sphere(part.rows[:, :3])

    def _shadow_moving(self) -> None:
        """The moving casters into the sun's second map, as posed now."""
        if self.shadow is None:
            return
        casters = [
            (p.depth_vao, m)
            for p, m in zip(self.parts, self._model_matrices, strict=True)
            if p.body and p.surface.cast_shadows
        ]
        self.shadow.has_moving = bool(casters)
        if casters:
            self.shadow.draw(1, casters)
        self.shadow.bind(SHADOW_STATIC_UNIT, SHADOW_MOVING_UNIT)
        matrix = shaders.gl_matrix(self.shadow.matrix)
        for program in self.programs.values():
            program.write("shadow_matrix", matrix)
            program.set("shadow_has_moving", self.shadow.has_moving)

    def close(self) -> None:
        self.ctx.release()  # with it everything it made


_SAMPLERS = {
    "albedo": ALBEDO_UNIT,
    "shadow_static": SHADOW_STATIC_UNIT,
    "shadow_moving": SHADOW_MOVING_UNIT,
    "normal_map": NORMAL_UNIT,
}
"""Texture units of the programs' samplers, fixed for their life."""
