"""The OpenGL renderer's shaders and the uniforms that carry the world's lighting into them.

Per fragment, Gazebo's (Ogre's) fixed material model with Blinn-Phong highlights: scene ambient ×
material ambient, plus for each light its diffuse × material diffuse × N·L and its specular ×
material specular × (N·H)^shininess, scaled by the light's attenuation (point and spot:
1 / (c + l·d + q·d²) within `range`, none beyond; spot: Ogre's cone, full brightness inside half
the inner angle, none outside half the outer angle, ((cos θ − cos ½outer) / (cos ½inner − cos ½outer))^falloff
between) and, for the sun that casts shadows, its shadow map; plus emissive. An albedo map
multiplies the diffuse and ambient colours. An unlit surface (`<lighting>` false) shows its diffuse
colour (or texture) as is. Normals face the viewer (a mesh's winding is not trusted). A normal
map (tangent space, OpenGL's convention: green up the texture's v) bends the normal in a tangent
frame worked out per fragment from the derivatives of position and texture coordinates, so no
tangents are stored; only its surfaces pay for it.

The shaders are written for the world's lights (`shaders`): their values are
constants in it, so a fragment runs no loop over lights and reads no arrays (on llvmpipe a loop over
uniform arrays cost three times the whole frame). At most `MAX_LIGHTS` lights.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt

from simbot.sim.render.specs import MAX_LIGHTS, Light, LightSource
from simbot.sim.render.surfaces import Surface
from simbot.transform import norm

_VERTEX = """
#version 330
uniform mat4 view_projection;
uniform mat4 model;
uniform vec3 eye;
in vec3 in_position;
in vec3 in_normal;
in vec2 in_uv;
out vec3 world;
out vec3 normal;
out vec2 uv;
out vec3 direct;  // diffuse light of the directional lights but the sun that casts shadows
out vec3 sun;  // diffuse light of that sun, before its shadow
out vec3 in_shadow_map;  // where the fragment lies in the sun's shadow maps (texture coordinates, depth)
uniform mat4 shadow_matrix;  // world -> the shadow maps' texture coordinates and depth
void main() {
    vec4 placed = model * vec4(in_position, 1.0);
    world = placed.xyz;
    vec3 n = normalize(mat3(model) * in_normal);
    normal = dot(n, eye - world) < 0.0 ? -n : n;
    uv = in_uv;
    direct = vec3(0.0);
    sun = vec3(0.0);
    in_shadow_map = (shadow_matrix * placed).xyz;  // orthographic: no division
DIRECTIONAL
    gl_Position = view_projection * placed;
}
"""

_FRAGMENT = """
#version 330
uniform sampler2DShadow shadow_static;
uniform sampler2DShadow shadow_moving;
uniform bool shadow_has_moving;
uniform vec3 eye;
uniform vec3 m_ambient;
uniform vec3 m_diffuse;
uniform vec3 m_specular;
uniform vec3 m_emissive;
uniform float m_shininess;
uniform float m_opacity;
KIND
uniform sampler2D albedo;
uniform sampler2D normal_map;
uniform bool mono;
in vec3 world;
in vec3 normal;
in vec2 uv;
in vec3 direct;
in vec3 sun;
in vec3 in_shadow_map;
out vec4 out_color;

float lit_by_sun() {
    vec3 p = in_shadow_map;
    if (any(lessThan(p.xyz, vec3(0.0))) || any(greaterThan(p.xyz, vec3(1.0)))) return 1.0;
    float lit = texture(shadow_static, p.xyz);
    if (shadow_has_moving) lit = min(lit, texture(shadow_moving, p.xyz));
    return lit;
}

void add_specular(vec3 n, vec3 v, vec3 l, float k, vec3 light_specular, inout vec3 specular) {
    if (k > 0.0 && dot(n, l) > 0.0) specular += light_specular * (k * pow(max(dot(n, normalize(l + v)), 0.0), m_shininess));
}

void add_light(vec3 n, vec3 v, vec3 l, float k, vec3 light_diffuse, vec3 light_specular,
               inout vec3 diffuse, inout vec3 specular) {
    float nl = dot(n, l);
    if (k <= 0.0 || nl <= 0.0) return;
    diffuse += light_diffuse * (k * nl);
    if (m_shiny) add_specular(n, v, l, k, light_specular, specular);
}

vec3 bumped(vec3 n) {
    // the tangent frame from the screen-space derivatives of position and uv (no tangents stored);
    // negated, as the projection flips y (which flips both derivatives along y)
    vec3 dp1 = dFdx(world);
    vec3 dp2 = dFdy(world);
    vec2 duv1 = dFdx(uv);
    vec2 duv2 = dFdy(uv);
    vec3 dp2perp = cross(dp2, n);
    vec3 dp1perp = cross(n, dp1);
    vec3 t = dp2perp * duv1.x + dp1perp * duv2.x;
    vec3 b = dp2perp * duv1.y + dp1perp * duv2.y;
    if (dot(t, t) < 1e-20 || dot(b, b) < 1e-20) return n;  // no texture coordinates to bend along
    vec3 m = texture(normal_map, uv).rgb * 2.0 - 1.0;
    return normalize(-normalize(t) * m.x - normalize(b) * m.y + n * m.z);  // unit tangents, as stored ones
}

void main() {
    vec3 base = m_textured ? texture(albedo, uv).rgb : vec3(1.0);
    vec3 color;
    if (!m_lit) {
        color = base * m_diffuse;
    } else {
        vec3 diffuse = direct;
        vec3 specular = vec3(0.0);
        float sunlit = 1.0;
SUN
        if (PER_FRAGMENT) {
            vec3 n = normalize(normal);
            if (m_bumpy) n = bumped(n);
            vec3 v = normalize(eye - world);
            vec3 l;
            vec3 d;
            float dist;
            float k;
DIRECTIONAL
POSITIONAL
            if (m_shiny) {
SPECULAR
            }
        }
        color = SCENE_AMBIENT * m_ambient * base + diffuse * m_diffuse * base + specular * m_specular + m_emissive;
    }
    color = clamp(color, 0.0, 1.0);
    out_color = vec4(mono ? vec3(dot(color, vec3(0.299, 0.587, 0.114))) : color, m_opacity);
}
"""


class Kind(NamedTuple):
    """What a surface needs of the fragment shader: each kind is a program of its own, as llvmpipe
    runs both sides of every branch (a branch on a uniform saves nothing there)."""

    lit: bool
    textured: bool
    shiny: bool
    """Its specular colour is not black: highlights are worked out."""
    bumpy: bool
    """It has a normal map: the directional lights too are worked out per fragment."""

    @staticmethod
    def of(surface: Surface, textured: bool, bumpy: bool) -> Kind:
        return Kind(surface.lit, textured, any(surface.specular), bumpy)


def shaders(lighting: Light, kind: Kind) -> tuple[str, str]:
    """(vertex, fragment) shaders for a kind of surface in the world's lighting, its lights' values
    written in as constants (lighting never changes in a worker's life), so a fragment runs no loop
    and reads no light arrays. Directional lights' diffuse light is worked out per vertex (exact on
    flat faces: one normal, one direction; per fragment on a normal-mapped surface), the sun's
    shadow, point and spot lights and highlights per fragment. The first `MAX_LIGHTS` lights (the renderer warns of the rest)."""
    sources = lighting.sources[:MAX_LIGHTS]
    caster = lighting.shadow_caster
    directional = [(i, s) for i, s in enumerate(sources) if s.type == "directional"]
    per_vertex = "".join(
        f"    {'sun' if i == caster else 'direct'} += {_vec3(s.diffuse)} * max(dot(normal, {_vec3(_towards(s))}), 0.0);\n"
        for i, s in directional
    )
    sun = (
        "        if (sun != vec3(0.0)) { sunlit = lit_by_sun(); diffuse += sun * sunlit; }\n"
        if caster is not None
        else ""
    )
    per_fragment_directional = "".join(_bumpy_directional_code(s, i == caster) for i, s in directional)
    if kind.bumpy:  # the map's normal varies within a face: every light per fragment, highlights with them
        per_vertex, sun = "", ""
    positional = "".join(_positional_code(s) for s in sources if s.type != "directional")
    specular = "".join(
        f"                add_specular(n, v, {_vec3(_towards(s))}, {'sunlit' if i == caster else '1.0'}, {_vec3(s.specular)}, specular);\n"
        for i, s in directional
        if any(s.specular)
    )
    vertex = _VERTEX.replace("DIRECTIONAL\n", per_vertex)
    fragment = _FRAGMENT.replace("SUN\n", sun).replace("POSITIONAL\n", positional)
    fragment = fragment.replace("DIRECTIONAL\n", per_fragment_directional if kind.bumpy else "")
    fragment = fragment.replace("SPECULAR\n", "" if kind.bumpy else specular)
    per_fragment = (
        "true" if positional or kind.bumpy else "m_shiny"
    )  # else only a highlight needs the fragment's normal
    flags = "".join(f"#define m_{name} {str(value).lower()}\n" for name, value in kind._asdict().items())
    fragment = fragment.replace("SCENE_AMBIENT", _vec3(lighting.ambient)).replace("PER_FRAGMENT", per_fragment)
    return vertex, fragment.replace("KIND\n", flags)


def _towards(source: LightSource) -> npt.NDArray[np.float64]:
    """Unit vector towards a directional light (against the way it travels)."""
    direction = np.asarray(source.direction, dtype=np.float64)
    return -direction / (norm(direction) or 1.0)


def _bumpy_directional_code(source: LightSource, shadowed: bool) -> str:
    """GLSL adding a directional light per fragment (a normal-mapped surface), the sun's shadow with it."""
    code = f"l = {_vec3(_towards(source))}; k = 1.0;"
    if shadowed:
        code += " if (dot(n, l) > 0.0) { sunlit = lit_by_sun(); k = sunlit; }"
    diffuse, specular = _vec3(source.diffuse), _vec3(source.specular)
    return f"            {code}\n            add_light(n, v, l, k, {diffuse}, {specular}, diffuse, specular);\n"


def _positional_code(source: LightSource) -> str:
    """GLSL adding a point or spot light to `diffuse` and `specular` (the module docstring has the formulas)."""
    reach, (c, lin, q) = source.range, source.attenuation
    code = (
        f"d = {_vec3(source.position)} - world; dist = length(d); l = d / max(dist, 1e-6);"
        f" k = dist > {_float(reach)} ? 0.0 : 1.0 / max({_float(c)} + {_float(lin)} * dist + {_float(q)} * dist * dist, 1e-6);"
    )
    if source.type == "spot":
        code += _cone_code(-_towards(source), *source.spot)
    diffuse, specular = _vec3(source.diffuse), _vec3(source.specular)
    return f"            {code}\n            add_light(n, v, l, k, {diffuse}, {specular}, diffuse, specular);\n"


def _cone_code(axis: npt.NDArray[np.float64], inner: float, outer: float, falloff: float) -> str:
    """Ogre's spot cone: full light within half the inner angle, none beyond half the outer one,
    ((cos θ − cos ½outer) / (cos ½inner − cos ½outer))^falloff between."""
    cos_inner, cos_outer = math.cos(inner / 2.0), math.cos(outer / 2.0)
    code = f" float rho = dot(-l, {_vec3(axis)}); if (rho <= {_float(cos_outer)}) k = 0.0;"
    if cos_inner > cos_outer:
        fade = f"pow((rho - {_float(cos_outer)}) / {_float(cos_inner - cos_outer)}, {_float(falloff)})"
        code += f" else if (rho < {_float(cos_inner)}) k *= {fade};"
    return " {" + code + " }"


def _vec3(values: Any) -> str:
    return "vec3({}, {}, {})".format(*(_float(float(v)) for v in values))


def _float(value: float) -> str:
    return f"{value:.9g}" if "e" in f"{value:.9g}" or "." in f"{value:.9g}" else f"{value:.9g}.0"


DEPTH_VERTEX = """
#version 330
uniform mat4 view_projection;
uniform mat4 model;
in vec3 in_position;
void main() {
    vec4 placed = model * vec4(in_position, 1.0);
    gl_Position = view_projection * placed;
}
"""
"""Depth only: the sun's shadow maps."""

DEPTH_FRAGMENT = """
#version 330
void main() {}
"""

ANNOTATION_VERTEX = """
#version 330
uniform mat4 view_projection;
uniform mat4 model;
in vec3 in_position;
in uint in_label;
in float in_temperature;
flat out uint label;
flat out float temperature;
out float height;
void main() {
    vec4 placed = model * vec4(in_position, 1.0);
    gl_Position = view_projection * placed;
    label = in_label;
    temperature = in_temperature;
    height = placed.z;
}
"""
"""What annotated cameras see: each fragment's label (`label_bits.py`) and temperature."""

ANNOTATION_FRAGMENT = """
#version 330
uniform float ambient_temperature;
uniform float temperature_gradient;
flat in uint label;
flat in float temperature;
in float height;
layout(location = 0) out uint out_label;
layout(location = 1) out float out_temperature;
void main() {
    out_label = label;
    // below zero: no Thermal system says; the atmosphere's temperature at this height
    out_temperature = temperature >= 0.0 ? temperature : ambient_temperature + temperature_gradient * height;
}
"""


Material = tuple[tuple[Any, bytes], ...]
"""A surface's uniforms (member, packed value), as `Program.material` makes them."""


def gl_matrix(m: npt.NDArray[np.float64]) -> bytes:
    """A 4×4 matrix as GLSL's column-major float32 bytes."""
    return np.ascontiguousarray(m.T, dtype=np.float32).tobytes()


class Program:
    """The camera program for one kind of surface; uniforms the compiler dropped (what this
    lighting or kind does not read) are skipped when set."""

    def __init__(self, ctx: Any, lighting: Light, kind: Kind, samplers: dict[str, int]) -> None:
        vertex, fragment = shaders(lighting, kind)
        self.program = ctx.program(vertex_shader=vertex, fragment_shader=fragment)
        self.model: Any = self.program["model"]
        self.kind = kind
        for name, unit in samplers.items():
            self.set(name, unit)

    def set(self, name: str, value: Any) -> None:
        if (member := self.program.get(name, None)) is not None:
            member.value = value

    def write(self, name: str, data: bytes) -> None:
        if (member := self.program.get(name, None)) is not None:
            member.write(data)

    def material(self, surface: Surface) -> Material:
        """A piece's material as the uniform writes before its draw, packed once: a draw writes
        bytes (packing the values at every draw took a tenth of a frame)."""
        values = {
            "m_ambient": surface.ambient,
            "m_diffuse": surface.diffuse,
            "m_specular": surface.specular,
            "m_emissive": surface.emissive,
            "m_shininess": (max(surface.shininess, 1e-3),),
            "m_opacity": (surface.opacity,),
        }
        return tuple(
            (member, np.asarray(value, dtype=np.float32).tobytes())
            for name, value in values.items()
            if (member := self.program.get(name, None)) is not None
        )

    def draw(self, material: Material, model: bytes, vao: Any) -> None:
        """One draw: its model matrix and material, then its vertices."""
        self.model.write(model)
        for member, data in material:
            member.write(data)
        vao.render()

    def release(self) -> None:
        self.program.release()
