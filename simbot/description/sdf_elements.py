"""The SDF elements that hold no frame of their own: shapes, surfaces and materials of collisions and
visuals, and the settings of a world (its physics, scene, atmosphere and place on the Earth).

Each reader takes the `Reader` of its file (for errors that name the file and line) and an
element, and gives the plain data of simbot.description.model with SDF's defaults (as Gazebo
reads them). `sdf_reader` places what these return in the frame graph. And which file of a model
folder an `<include>` means.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from functools import cache
from pathlib import Path

from simbot.description.model import (
    Atmosphere,
    Box,
    Capsule,
    Cone,
    Cylinder,
    Ellipsoid,
    Friction,
    Geometry,
    Heightmap,
    Material,
    Mesh,
    Plane,
    Polyline,
    Scene,
    SdfLight,
    SdfPhysics,
    Sphere,
    SphericalCoordinates,
)
from simbot.description.resources import resolve
from simbot.description.xml import Element, Reader, parse_file, sdf_tag

logger = logging.getLogger(__name__)


def read_geometry(reader: Reader, owner: Element) -> Geometry:
    """The shape, with SDF's defaults for the sizes a file leaves out (as Gazebo reads them)."""
    geometry = reader.child(owner, "geometry")
    shape = next(iter(geometry), None)
    if shape is None:
        raise reader.error(geometry, f"empty <geometry>: expected one of {', '.join(_SHAPES)}")
    read = _SHAPES.get(str(shape.tag))
    if read is None:
        raise reader.error(shape, f"unsupported geometry <{sdf_tag(shape)}>")
    return read(reader, shape)


def _read_mesh(reader: Reader, shape: Element) -> Mesh:
    uri = reader.text(shape, "uri")
    if not uri:
        raise reader.error(shape, "missing required element <uri>")
    scale = reader.vector(shape, "scale", 3, (1.0, 1.0, 1.0))
    return Mesh(uri, scale, resolve(uri, reader.file.parent).path)  # type: ignore[arg-type]


def _read_polyline(reader: Reader, shape: Element) -> Polyline:
    """Every <polyline> of the geometry: each its outline of <point>s and its <height>."""
    outlines, heights = [], []
    for polyline in shape.getparent().findall("polyline"):
        points = tuple(reader.floats(p, 2) for p in polyline.findall("point"))
        if len(points) < 3:
            raise reader.error(polyline, f"a polyline needs at least 3 <point>s, got {len(points)}")
        outlines.append(points)
        heights.append(reader.number(polyline, "height", 1.0))
    return Polyline(tuple(outlines), tuple(heights))  # type: ignore[arg-type]


def _read_heightmap(reader: Reader, shape: Element) -> Heightmap:
    uri = reader.text(shape, "uri")
    if not uri:
        raise reader.error(shape, "missing required element <uri>")
    resolution = resolve(uri, reader.file.parent)
    path = resolution.path
    if path is None:
        raise reader.error(shape, f"cannot find heightmap image {uri!r} (tried {resolution.describe_tried()})")
    size = reader.vector(shape, "size", 3, (1.0, 1.0, 1.0))
    pos = reader.vector(shape, "pos", 3, (0.0, 0.0, 0.0))
    return Heightmap(uri, size, pos, path)  # type: ignore[arg-type]


_SHAPES: dict[str, Callable[[Reader, Element], Geometry]] = {
    "box": lambda r, e: Box(r.vector(e, "size", 3, (1.0, 1.0, 1.0))),  # type: ignore[arg-type]
    "cylinder": lambda r, e: Cylinder(r.number(e, "radius", 1.0), r.number(e, "length", 1.0)),
    "sphere": lambda r, e: Sphere(r.number(e, "radius", 1.0)),
    "capsule": lambda r, e: Capsule(r.number(e, "radius", 0.5), r.number(e, "length", 1.0)),
    "ellipsoid": lambda r, e: Ellipsoid(r.vector(e, "radii", 3, (1.0, 1.0, 1.0))),  # type: ignore[arg-type]
    "cone": lambda r, e: Cone(r.number(e, "radius", 0.5), r.number(e, "length", 1.0)),
    "plane": lambda r, e: Plane(r.vector(e, "normal", 3, (0.0, 0.0, 1.0)), r.vector(e, "size", 2, (100.0, 100.0))),  # type: ignore[arg-type]
    "mesh": _read_mesh,
    "polyline": _read_polyline,
    "heightmap": _read_heightmap,
}
"""Each SDF shape and how to read it; sizes default as in SDF's own specification."""


def read_friction(reader: Reader, collision: Element) -> Friction | None:
    ode = collision.find("surface/friction/ode")
    if ode is None:
        return None
    fdir1 = reader.vector(ode, "fdir1", 3)
    slip1, slip2 = (_read_slip(reader, collision, ode, tag) for tag in ("slip1", "slip2"))
    return Friction(reader.number(ode, "mu", 1.0), reader.number(ode, "mu2", 1.0), fdir1, slip1, slip2)  # type: ignore[arg-type]


def _read_slip(reader: Reader, collision: Element, ode: Element, tag: str) -> float:
    """ODE's force-dependent slip (m/s per N). A negative or unreadable one is a user's slip of
    the pen, not a reason to refuse the world: one line naming where, and SDF's default (0)."""
    text = reader.text(ode, tag)
    if text is None:
        return 0.0
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if value >= 0.0 and math.isfinite(value):
        return value
    link = collision.getparent()
    model = next((e for e in collision.iterancestors() if sdf_tag(e) == "model"), None)
    logger.warning(
        "%s: model %r, link %r, collision %r: <%s> must be a non-negative number of m/s per N, got %r; "
        "using the default tyre",
        reader.file,
        model.get("name") if model is not None else None,
        link.get("name") if link is not None else None,
        collision.get("name"),
        tag,
        text,
    )
    return 0.0


def rgba(reader: Reader, element: Element, tag: str) -> tuple[float, float, float, float] | None:
    found = element.find(tag)
    if found is None:
        return None
    values = reader.floats(found)
    if len(values) == 3:
        values = values + (1.0,)
    if len(values) != 4:
        raise reader.error(found, f"expected 4 numbers 'r g b a', got {len(values)}")
    return values


def read_material(reader: Reader, element: Element) -> Material:
    """Colours, `<lighting>`, `<shininess>` and PBR (`<pbr><metal>` or `<pbr><specular>`; the first
    one written). A map that does not resolve is a warning, and the visual keeps its colour."""
    colours = {tag: rgba(reader, element, tag) for tag in ("ambient", "diffuse", "specular", "emissive")}
    shininess = element.find("shininess")
    workflow = next(iter(element.findall("pbr/metal") + element.findall("pbr/specular")), None)
    pbr: dict[str, object] = {}
    if workflow is not None:
        glossiness = workflow.find("glossiness")
        roughness = (
            reader.number(workflow, "roughness", 0.5) if glossiness is None else 1.0 - reader.floats(glossiness, 1)[0]
        )
        pbr = {
            "albedo_map": _texture(reader, workflow, "albedo_map"),
            "normal_map": _texture(reader, workflow, "normal_map"),
            "metalness": reader.number(workflow, "metalness", 0.0 if workflow.tag == "specular" else 0.5),
            "roughness": roughness,
        }
    return Material(
        **colours,  # type: ignore[arg-type]
        lighting=reader.flag(element, "lighting", True),
        shininess=None if shininess is None else reader.floats(shininess, 1)[0],
        **pbr,  # type: ignore[arg-type]
    )


def _texture(reader: Reader, workflow: Element, tag: str) -> Path | None:
    """The image a PBR map names, resolved as a mesh is (relative to the file, `model://`, the resource path)."""
    uri = reader.text(workflow, tag)
    if not uri:
        return None
    resolution = resolve(uri, reader.file.parent)
    if resolution.path is not None and resolution.path.is_file():
        return resolution.path if _decodable(resolution.path) else None
    line = workflow.find(tag).sourceline
    tried = resolution.describe_tried()
    logger.warning(
        "%s:%s: <%s> %r not found (tried %s); the visual keeps its colour", reader.file, line, tag, uri, tried
    )
    return None


@cache
def _decodable(path: Path) -> bool:
    """Whether OpenCV (what the renderers read textures with) knows the image's format; a warning
    naming it, once, where not."""
    import cv2

    if cv2.haveImageReader(str(path)):
        return True
    logger.warning("texture %s is not an image OpenCV can decode; the visual keeps its colour", path)
    return False


def read_spherical_coordinates(reader: Reader, element: Element | None) -> SphericalCoordinates:
    """The world origin on the Earth; only Gazebo's ENU world frame has a meaning here."""
    if element is None:
        return SphericalCoordinates()
    defaults = SphericalCoordinates()
    orientation = reader.text(element, "world_frame_orientation") or defaults.world_frame_orientation
    if orientation != "ENU":
        raise reader.error(element, f"world_frame_orientation {orientation!r} is not supported (ENU only, as Gazebo)")
    return SphericalCoordinates(
        surface_model=reader.text(element, "surface_model") or defaults.surface_model,
        world_frame_orientation=orientation,
        latitude_deg=reader.number(element, "latitude_deg", defaults.latitude_deg),
        longitude_deg=reader.number(element, "longitude_deg", defaults.longitude_deg),
        elevation=reader.number(element, "elevation", defaults.elevation),
        heading_deg=reader.number(element, "heading_deg", defaults.heading_deg),
    )


def read_atmosphere(reader: Reader, element: Element | None) -> Atmosphere:
    if element is None:
        return Atmosphere()
    defaults = Atmosphere()
    return Atmosphere(
        temperature=reader.number(element, "temperature", defaults.temperature),
        pressure=reader.number(element, "pressure", defaults.pressure),
        temperature_gradient=reader.number(element, "temperature_gradient", defaults.temperature_gradient),
    )


def read_physics(reader: Reader, world: Element) -> SdfPhysics:
    """The physics marked default, else the first, as Gazebo picks it."""
    candidates = world.findall("physics")
    if not candidates:
        return SdfPhysics()
    chosen = next((p for p in candidates if p.get("default", "").lower() in ("1", "true")), candidates[0])
    step = reader.number(chosen, "max_step_size", 0.001)
    if not step > 0:
        raise reader.error(chosen, f"max_step_size must be positive, got {step}")
    return SdfPhysics(
        max_step_size=step,
        real_time_factor=reader.number(chosen, "real_time_factor", 1.0),
        real_time_update_rate=reader.number(chosen, "real_time_update_rate", 1000.0),
        type=chosen.get("type", "ode"),
    )


def read_scene(reader: Reader, element: Element | None) -> Scene:
    if element is None:
        return Scene()
    defaults = Scene()
    return Scene(
        ambient=rgba(reader, element, "ambient") or defaults.ambient,
        background=rgba(reader, element, "background") or defaults.background,
        shadows=reader.flag(element, "shadows", defaults.shadows),
    )


def read_light(reader: Reader, element: Element) -> SdfLight:
    """A `<light>` but its pose (which `sdf_reader` places in the frame graph)."""
    defaults = SdfLight("", "")
    attenuation = element.find("attenuation")
    spot = element.find("spot")
    return SdfLight(
        name=element.get("name", ""),
        type=element.get("type", "point"),
        diffuse=rgba(reader, element, "diffuse") or defaults.diffuse,
        specular=rgba(reader, element, "specular") or defaults.specular,
        direction=reader.vector(element, "direction", 3, defaults.direction),  # type: ignore[arg-type]
        cast_shadows=reader.flag(element, "cast_shadows", defaults.cast_shadows),
        intensity=reader.number(element, "intensity", defaults.intensity),
        attenuation_range=_number(reader, attenuation, "range", defaults.attenuation_range),
        constant=_number(reader, attenuation, "constant", defaults.constant),
        linear=_number(reader, attenuation, "linear", defaults.linear),
        quadratic=_number(reader, attenuation, "quadratic", defaults.quadratic),
        inner_angle=_number(reader, spot, "inner_angle", defaults.inner_angle),
        outer_angle=_number(reader, spot, "outer_angle", defaults.outer_angle),
        falloff=_number(reader, spot, "falloff", defaults.falloff),
    )


def _number(reader: Reader, element: Element | None, tag: str, default: float) -> float:
    """A number of an optional block (`<attenuation>`, `<spot>`): the default where the block is absent."""
    return default if element is None else reader.number(element, tag, default)


def model_file(reader: Reader, include: Element, found: Path) -> Path:
    """The SDF file of an included model: the file itself, or the one its model.config names."""
    if found.is_file():
        return found
    config = found / "model.config"
    if config.is_file():
        root = parse_file(config)
        entries = [e for e in root.findall("sdf") if (e.text or "").strip()]
        if not entries:
            raise Reader(config).error(root, "model.config names no <sdf> file")
        best = max(entries, key=lambda e: version_key(e.get("version")))
        return found / (best.text or "").strip()
    if (found / "model.sdf").is_file():
        return found / "model.sdf"
    raise reader.error(include, f"{found} holds neither model.config nor model.sdf")


def version_key(text: str | None) -> tuple[int, ...]:
    """(major, minor) of an SDF version; () when unreadable, which sorts first."""
    try:
        return tuple(int(part) for part in (text or "").split("."))
    except ValueError:
        return ()
