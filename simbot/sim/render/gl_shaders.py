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

At most `MAX_LIGHTS` lights: the loop is fixed-size in the shader, its trip count a uniform.
"""

from __future__ import annotations

import logging
import math
from typing import Any

import numpy as np
import numpy.typing as npt

from simbot.sim.render.specs import MAX_LIGHTS, Light
from simbot.sim.render.surfaces import Surface

log = logging.getLogger(__name__)

LIGHT_TYPES = {"directional": 0, "point": 1, "spot": 2}

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
void main() {
    vec4 placed = model * vec4(in_position, 1.0);
    world = placed.xyz;
    normal = mat3(model) * in_normal;
    uv = in_uv;
    gl_Position = view_projection * placed;
}
"""

FRAGMENT = (
    f"""
#version 330
#define MAX_LIGHTS {MAX_LIGHTS}
"""
    + """
uniform int light_count;
uniform int light_type[MAX_LIGHTS];
uniform vec3 light_position[MAX_LIGHTS];
uniform vec3 light_direction[MAX_LIGHTS];
uniform vec3 light_diffuse[MAX_LIGHTS];
uniform vec3 light_specular[MAX_LIGHTS];
uniform vec4 light_attenuation[MAX_LIGHTS];  // range, constant, linear, quadratic
uniform vec3 light_spot[MAX_LIGHTS];  // cos(inner / 2), cos(outer / 2), falloff
uniform vec3 scene_ambient;
uniform int shadow_light;  // -1: no shadows
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
uniform bool m_textured;
uniform sampler2D albedo;
uniform bool mono;
in vec3 world;
in vec3 normal;
in vec2 uv;
out vec4 out_color;

float attenuation(int i, out vec3 to_light) {
    if (light_type[i] == 0) {
        to_light = -light_direction[i];
        return 1.0;
    }
    vec3 d = light_position[i] - world;
    float dist = length(d);
    to_light = d / max(dist, 1e-6);
    vec4 a = light_attenuation[i];
    if (dist > a.x) return 0.0;
    float fade = 1.0 / max(a.y + a.z * dist + a.w * dist * dist, 1e-6);
    if (light_type[i] == 2) {
        vec3 s = light_spot[i];
        float rho = dot(-to_light, light_direction[i]);
        if (rho <= s.y) return 0.0;
        if (s.x > s.y && rho < s.x) fade *= pow((rho - s.y) / (s.x - s.y), s.z);
    }
    return fade;
}

float lit_by_sun() {
    vec4 p = shadow_matrix * vec4(world, 1.0);
    if (any(lessThan(p.xyz, vec3(0.0))) || any(greaterThan(p.xyz, vec3(1.0)))) return 1.0;
    float lit = texture(shadow_static, p.xyz);
    if (shadow_has_moving) lit = min(lit, texture(shadow_moving, p.xyz));
    return lit;
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
        for (int i = 0; i < light_count; ++i) {
            vec3 l;
            float k = attenuation(i, l);
            float nl = dot(n, l);
            if (k <= 0.0 || nl <= 0.0) continue;
            if (i == shadow_light) k *= lit_by_sun();
            diffuse += light_diffuse[i] * (k * nl);
            specular += light_specular[i] * (k * pow(max(dot(n, normalize(l + v)), 0.0), m_shininess));
        }
        color = scene_ambient * m_ambient * base + diffuse * m_diffuse * base + specular * m_specular + m_emissive;
    }
    color = clamp(color, 0.0, 1.0);
    out_color = vec4(mono ? vec3(dot(color, vec3(0.299, 0.587, 0.114))) : color, m_opacity);
}
"""
)

SHADOW_VERTEX = """
#version 330
uniform mat4 view_projection;
uniform mat4 model;
in vec3 in_position;
void main() {
    gl_Position = view_projection * model * vec4(in_position, 1.0);
}
"""

SHADOW_FRAGMENT = """
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


def write_lighting(program: Any, lighting: Light) -> None:
    """The world's lights and ambient into the program's uniforms, once: they never change."""
    sources = lighting.sources
    if len(sources) > MAX_LIGHTS:
        log.warning("the world has %d lights; the renderer shades the first %d", len(sources), MAX_LIGHTS)
        sources = sources[:MAX_LIGHTS]
    program["light_count"].value = len(sources)
    program["scene_ambient"].value = tuple(lighting.ambient)
    if not sources:
        return
    columns: dict[str, list[Any]] = {name: [] for name in _LIGHT_ARRAYS}
    for source in sources:
        inner, outer, falloff = source.spot
        direction = np.asarray(source.direction, dtype=np.float64)
        columns["light_type"].append(LIGHT_TYPES[source.type])
        columns["light_position"].append(tuple(source.position))
        columns["light_direction"].append(tuple(direction / (np.linalg.norm(direction) or 1.0)))
        columns["light_diffuse"].append(tuple(source.diffuse))
        columns["light_specular"].append(tuple(source.specular))
        columns["light_attenuation"].append((source.range, *source.attenuation))
        columns["light_spot"].append((math.cos(inner / 2.0), math.cos(outer / 2.0), falloff))
    for name, values in columns.items():
        member = program.get(name, None)
        if member is not None:  # the compiler drops an array no light type reads
            padded = values + values[-1:] * (member.array_length - len(values))
            member.value = padded if member.array_length > 1 else padded[0]


_LIGHT_ARRAYS = (
    "light_type",
    "light_position",
    "light_direction",
    "light_diffuse",
    "light_specular",
    "light_attenuation",
    "light_spot",
)


def write_surface(uniforms: dict[str, Any], surface: Surface, textured: bool) -> None:
    """A piece's material into the program's uniforms, before its draw."""
    uniforms["m_ambient"].value = surface.ambient
    uniforms["m_diffuse"].value = surface.diffuse
    uniforms["m_specular"].value = surface.specular
    uniforms["m_emissive"].value = surface.emissive
    uniforms["m_shininess"].value = max(surface.shininess, 1e-3)
    uniforms["m_opacity"].value = surface.opacity
    uniforms["m_lit"].value = surface.lit
    uniforms["m_textured"].value = textured


SURFACE_UNIFORMS = (
    "m_ambient",
    "m_diffuse",
    "m_specular",
    "m_emissive",
    "m_shininess",
    "m_opacity",
    "m_lit",
    "m_textured",
)
