"""The OpenGL renderer's shaders and the uniforms that carry the world's lighting into them.

Per fragment, Gazebo's (Ogre's) fixed material model with Blinn-Phong highlights: scene ambient ×
material ambient, plus for each light its diffuse × material diffuse × N·L and its specular ×
material specular × (N·H)^shininess, scaled by the light's attenuation (point and spot:
1 / (c + l·d + q·d²) within `range`, none beyond; spot: Ogre's cone, full brightness inside half
the inner angle, none outside half the outer angle, ((cos θ − cos ½outer) / (cos ½inner − cos ½outer))^falloff
between) and, for the sun that casts shadows, its shadow map; plus emissive. An albedo map
multiplies the diffuse and ambient colours. An unlit surface (`<lighting>` false) shows its diffuse
colour (or texture) as is. Normals face the viewer (a mesh's winding is not trusted), and normal
maps are not applied (their cost is a tangent frame per vertex; not reached).

The fragment shader is written for the world's lights (`fragment_shader`): their values are
constants in it, so a fragment runs no loop over lights and reads no arrays (on llvmpipe a loop over
uniform arrays cost three times the whole frame). At most `MAX_LIGHTS` lights.
"""

from __future__ import annotations

import logging
import math
from typing import Any

import numpy as np
import numpy.typing as npt

from simbot.sim.render.specs import MAX_LIGHTS, Light, LightSource
from simbot.sim.render.surfaces import Surface

log = logging.getLogger(__name__)

VERTEX = """
#version 330
uniform mat4 view_projection;
uniform mat4 model;
in vec3 in_position;
in vec3 in_normal;
in vec2 in_uv;
out vec3 world;
out vec3 normal;
out vec2 uv;
invariant gl_Position;  // the depth pre-pass computes it alike: the shaded pass draws where depth is equal
void main() {
    vec4 placed = model * vec4(in_position, 1.0);
    world = placed.xyz;
    normal = mat3(model) * in_normal;
    uv = in_uv;
    gl_Position = view_projection * placed;
}
"""

_FRAGMENT_HEAD = """
#version 330
uniform mat4 shadow_matrix;  // world -> the shadow maps' texture coordinates and depth
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
uniform bool m_lit;
uniform bool m_shiny;  // m_specular is not black
uniform bool m_textured;
uniform sampler2D albedo;
uniform bool mono;
in vec3 world;
in vec3 normal;
in vec2 uv;
out vec4 out_color;

float lit_by_sun() {
    vec4 p = shadow_matrix * vec4(world, 1.0);
    if (any(lessThan(p.xyz, vec3(0.0))) || any(greaterThan(p.xyz, vec3(1.0)))) return 1.0;
    float lit = texture(shadow_static, p.xyz);
    if (shadow_has_moving) lit = min(lit, texture(shadow_moving, p.xyz));
    return lit;
}

void add_light(vec3 n, vec3 v, vec3 l, float k, vec3 light_diffuse, vec3 light_specular,
               inout vec3 diffuse, inout vec3 specular) {
    float nl = dot(n, l);
    if (k <= 0.0 || nl <= 0.0) return;
    diffuse += light_diffuse * (k * nl);
    if (m_shiny) specular += light_specular * (k * pow(max(dot(n, normalize(l + v)), 0.0), m_shininess));
}

void main() {
    vec3 base = m_textured ? texture(albedo, uv).rgb : vec3(1.0);
    vec3 color;
    if (!m_lit) {
        color = base * m_diffuse;
    } else {
        vec3 n = normalize(normal);
        vec3 v = normalize(eye - world);
        if (dot(n, v) < 0.0) n = -n;
        vec3 diffuse = vec3(0.0);
        vec3 specular = vec3(0.0);
        vec3 l;
        vec3 d;
        float dist;
        float k;
"""

_FRAGMENT_TAIL = """
        color = SCENE_AMBIENT * m_ambient * base + diffuse * m_diffuse * base + specular * m_specular + m_emissive;
    }
    color = clamp(color, 0.0, 1.0);
    out_color = vec4(mono ? vec3(dot(color, vec3(0.299, 0.587, 0.114))) : color, m_opacity);
}
"""


def fragment_shader(lighting: Light) -> str:
    """The fragment shader for the world's lighting: each light's code written out with its values
    as constants (lighting never changes in a worker's life), so a fragment runs no loop and reads
    no light arrays; at most `MAX_LIGHTS` lights, with a warning for the rest."""
    sources = lighting.sources
    if len(sources) > MAX_LIGHTS:
        log.warning("the world has %d lights; the renderer shades the first %d", len(sources), MAX_LIGHTS)
        sources = sources[:MAX_LIGHTS]
    body = "".join(_light_code(source, index == lighting.shadow_caster) for index, source in enumerate(sources))
    return _FRAGMENT_HEAD + body + _FRAGMENT_TAIL.replace("SCENE_AMBIENT", _vec3(lighting.ambient))


def _light_code(source: LightSource, shadowed: bool) -> str:
    """GLSL adding one light to `diffuse` and `specular` (see the module docstring for the formulas)."""
    direction = np.asarray(source.direction, dtype=np.float64)
    direction = direction / (np.linalg.norm(direction) or 1.0)
    if source.type == "directional":
        code = f"l = {_vec3(-direction)}; k = 1.0;"
    else:
        reach, (c, lin, q) = source.range, source.attenuation
        code = (
            f"d = {_vec3(source.position)} - world; dist = length(d); l = d / max(dist, 1e-6);"
            f" k = dist > {_float(reach)} ? 0.0 : 1.0 / max({_float(c)} + {_float(lin)} * dist + {_float(q)} * dist * dist, 1e-6);"
        )
        if source.type == "spot":
            code += _cone_code(direction, *source.spot)
    if shadowed:
        code += " if (k > 0.0 && dot(n, l) > 0.0) k *= lit_by_sun();"
    diffuse, specular = _vec3(source.diffuse), _vec3(source.specular)
    return f"        {code}\n        add_light(n, v, l, k, {diffuse}, {specular}, diffuse, specular);\n"


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
invariant gl_Position;
void main() {
    vec4 placed = model * vec4(in_position, 1.0);
    gl_Position = view_projection * placed;
}
"""
"""Depth only: the sun's shadow maps, and each camera's pre-pass (so that each pixel is shaded once)."""

DEPTH_FRAGMENT = """
#version 330
void main() {}
"""


def gl_matrix(m: npt.NDArray[np.float64]) -> bytes:
    """A 4×4 matrix as GLSL's column-major float32 bytes."""
    return np.ascontiguousarray(m.T, dtype=np.float32).tobytes()


def uniform(program: Any, name: str) -> Any:
    """A uniform of the program; a shader that lost one (the compiler drops what is unused) fails here, not mid-frame."""
    member = program.get(name, None)
    if member is None:
        raise RuntimeError(f"the GL program has no uniform {name!r}")
    return member


def write_surface(uniforms: dict[str, Any], surface: Surface, textured: bool) -> None:
    """A piece's material into the program's uniforms, before its draw; those the compiler dropped
    for this world's lighting (no ambient, no specular light) are not in `uniforms`."""
    values = {
        "m_ambient": surface.ambient,
        "m_diffuse": surface.diffuse,
        "m_specular": surface.specular,
        "m_emissive": surface.emissive,
        "m_shininess": max(surface.shininess, 1e-3),
        "m_opacity": surface.opacity,
        "m_lit": surface.lit,
        "m_shiny": any(surface.specular),
        "m_textured": textured,
    }
    for name, value in values.items():
        if (member := uniforms.get(name)) is not None:
            member.value = value


SURFACE_UNIFORMS = (
    "m_ambient",
    "m_diffuse",
    "m_specular",
    "m_emissive",
    "m_shininess",
    "m_opacity",
    "m_lit",
    "m_shiny",
    "m_textured",
)
"""Uniforms of a surface; the lighting decides which of them the compiler keeps."""
