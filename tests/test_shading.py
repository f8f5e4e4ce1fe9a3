"""What the OpenGL renderer shades, with real GL (those tests skipped where no EGL context opens)
and real PyBullet scenes: a point light's falloff and a spot light's cone against Gazebo's formulas, the
sun's shadow on the side away from it (from a static and from a moving body, and none with the
scene's shadows off), the sky colour, emissive and unlit surfaces, translucency, textures, normal
maps, and
Gazebo's near clip (a depth camera inside its housing box reads the scene), a world's SDF lights
and scene turned into the renderers' lighting, and the limit on lights.

Most tests draw in this process (`GlRenderer` on a `BulletScene`, as a worker does), where a test
can dress a body's pieces in surfaces of its own (`dressed`): the materials that SDF gives them
arrive through `body_pieces`. Pixels compare with the formula to 2 levels of 255 (8-bit rounding of
per-fragment arithmetic)."""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pybullet
import pytest
from gl_helpers import NO_EGL, body_of, box_body, box_model

from simbot.sim.render import BodyState, CameraSpec, Light, LightSource, RenderPool, SceneBody
from simbot.sim.render.outputs import LUMA, linear_depth
from simbot.sim.render.scene import BulletScene
from simbot.sim.render.surfaces import Piece, Surface
from simbot.sim.render.visuals import body_pieces
from simbot.transform import Transform

needs_gl = pytest.mark.skipif(NO_EGL is not None, reason=NO_EGL or "")

SIZE = 201  # odd: the centre pixel looks along the optical axis
HFOV = 2.0 * math.atan((SIZE / 2.0) / 100.0)  # fx = fy = 100 px
DOWN = (0.0, math.sin(math.pi / 4), 0.0, math.cos(math.pi / 4))  # the camera's +x turned to −z: image up is world +x
AHEAD = (0.0, 0.0, 0.0, 1.0)
WHITE = (1.0, 1.0, 1.0, 1.0)
DARK = Light(sources=(), ambient=(0.0, 0.0, 0.0), background=(0.0, 0.0, 0.0))
"""No light at all: what a test adds is all there is."""
TOLERANCE = 2.0

Pieces = Callable[[BulletScene, str], list[Piece]]


def floor() -> SceneBody:
    """A white slab, its top face at z 0."""
    return box_body("floor", (20.0, 20.0, 0.1), WHITE, True, Transform((0.0, 0.0, -0.05), AHEAD))


def camera(outputs: tuple[str, ...] = ("color",), near: float = 0.05) -> CameraSpec:
    return CameraSpec("c", SIZE, SIZE, HFOV, near, 50.0, outputs=outputs)


def dressed(surfaces: dict[str, Surface]) -> Pieces:
    """body_pieces, each named body's pieces in the given surface."""

    def pieces(scene: BulletScene, name: str) -> list[Piece]:
        found = body_pieces(scene, name)
        return [replace(p, surface=surfaces[name]) for p in found] if name in surfaces else found

    return pieces


@contextmanager
def drawing(
    bodies: list[SceneBody], light: Light, spec: CameraSpec, pieces: Pieces = body_pieces
) -> Iterator[Callable[..., dict[str, npt.NDArray[np.generic]]]]:
    """A function drawing `spec` at a pose (moving bodies placed by `states`): its colour (and depth, metres)."""
    from simbot.sim.render.gl import GlRenderer

    scene = BulletScene(pybullet, bodies)
    renderer = GlRenderer(scene, light, {0: spec}, pieces=pieces)

    def draw(pose: Transform, states: dict[str, BodyState] | None = None) -> dict[str, npt.NDArray[np.generic]]:
        scene.apply(states or {})
        shapes = spec.drawn()
        drawn = {
            raw: np.zeros(shape, dtype=np.float32 if raw == "depth" else np.uint8) for raw, shape in shapes.items()
        }
        renderer.render(0, pose, drawn)
        if "depth" in drawn:
            linear_depth(drawn["depth"], spec.near, spec.far)
        return drawn  # type: ignore[return-value]

    try:
        yield draw
    finally:
        renderer.close()
        scene.close()


def floor_point(spec: CameraSpec, height: float, u: float, v: float) -> tuple[float, float]:
    """Where pixel (u, v) of a camera `height` above the floor at the origin, looking down (`DOWN`), meets it."""
    cx, cy = spec.principal_point
    return (cy - v) / spec.fx * height, -(u - cx) / spec.fx * height


@needs_gl
def test_point_light_falls_off_as_gazebo_attenuates_it_and_stops_at_its_range() -> None:
    """A point light 1 m above a white floor: each pixel of the centre row shows
    N·L / (c + l·d + q·d²) with N·L = 1/d, and nothing beyond `range` (2 m)."""
    c, lin, q, reach = 1.0, 0.5, 0.5, 2.0
    bulb = LightSource("point", position=(0.0, 0.0, 1.0), range=reach, attenuation=(c, lin, q))
    spec = camera()
    with drawing([floor()], replace(DARK, sources=(bulb,)), spec) as draw:
        row = draw(((0.0, 0.0, 3.0), DOWN))["color"][SIZE // 2, :, 0].astype(float)
    checked = 0
    for u in range(SIZE):
        _, y = floor_point(spec, 3.0, u, SIZE // 2)
        d = math.hypot(y, 1.0)
        if abs(d - reach) < 0.05:
            continue  # the cut-off falls inside this pixel
        expected = 255.0 * (1.0 / d) / (c + lin * d + q * d * d) if d < reach else 0.0
        assert abs(row[u] - expected) <= TOLERANCE, f"pixel {u} (d = {d:.2f} m): {row[u]} ≠ {expected:.1f}"
        checked += 1
    assert checked > SIZE * 0.9


@needs_gl
def test_spot_light_cone_ends_at_half_its_outer_angle_and_fades_from_the_inner_one() -> None:
    """A spot 2 m above the floor pointing down, cones 40° and 60° (full angles), falloff 1: full
    light within 20° of the axis, none beyond 30°, and Ogre's linear fade between."""
    inner, outer, height = math.radians(40.0), math.radians(60.0), 2.0
    spot = LightSource("spot", position=(0.0, 0.0, height), direction=(0, 0, -1), attenuation=(1.0, 0.0, 0.0))
    spot = replace(spot, spot=(inner, outer, 1.0))
    spec = camera()
    with drawing([floor()], replace(DARK, sources=(spot,)), spec) as draw:
        row = draw(((0.0, 0.0, 4.0), DOWN))["color"][SIZE // 2, :, 0].astype(float)
    lit_radii = []
    for u in range(SIZE):
        _, y = floor_point(spec, 4.0, u, SIZE // 2)
        d = math.hypot(y, height)
        angle = math.atan2(abs(y), height)
        fade = (math.cos(angle) - math.cos(outer / 2)) / (math.cos(inner / 2) - math.cos(outer / 2))
        expected = 255.0 * (height / d) * min(max(fade, 0.0), 1.0)
        assert abs(row[u] - expected) <= TOLERANCE, f"pixel {u} ({math.degrees(angle):.1f}°): {row[u]} ≠ {expected:.1f}"
        if row[u] > 0:
            lit_radii.append(abs(y))
    pixel = 4.0 / spec.fx  # metres of floor a pixel spans
    assert max(lit_radii) == pytest.approx(height * math.tan(outer / 2), abs=2 * pixel)


@needs_gl
@pytest.mark.parametrize("static", [True, False], ids=["static", "moving"])
def test_a_box_casts_the_suns_shadow_on_the_floor_away_from_the_sun(static: bool) -> None:
    """The sun travels along +x and down at 45°: a 1 m cube's shadow lies on the floor from its +x
    face to 1 m beyond, where only the ambient light reaches (0.3); the floor on its −x side is lit
    (0.3 + 0.5 cos 45°). A moving cube, placed by the request, casts it where it is placed."""
    sun = LightSource(diffuse=(0.5, 0.5, 0.5), direction=(1.0, 0.0, -1.0), cast_shadows=True)
    light = Light(sources=(sun,), ambient=(0.3, 0.3, 0.3), background=(0.0, 0.0, 0.0))
    cube_at = (2.0, 0.0, 0.5)
    cube = box_body("cube", (1.0, 1.0, 1.0), (0.5, 0.5, 0.5, 1.0), static, Transform((0.0, 0.0, 0.5), AHEAD))
    states = {} if static else {"cube": BodyState(Transform(cube_at, AHEAD), {})}
    x0 = 0.0 if static else cube_at[0]
    lit, shaded = 255.0 * (0.3 + 0.5 * math.cos(math.pi / 4)), 255.0 * 0.3
    spec = camera()
    for shadows, behind in ((True, shaded), (False, lit)):
        with drawing([floor(), cube], replace(light, shadows=shadows), spec) as draw:
            image = draw(((x0, 0.0, 8.0), DOWN), states)["color"][..., 0].astype(float)
        for x, expected in ((1.0, behind), (-1.0, lit), (2.0, lit)):
            v = SIZE // 2 - x / 8.0 * spec.fx  # image up is +x
            value = image[round(v), SIZE // 2]
            assert abs(value - expected) <= TOLERANCE, f"shadows {shadows}, floor {x} m from the cube: {value}"


@needs_gl
def test_the_sky_is_the_scene_background_in_colour_and_in_mono() -> None:
    sky = (0.2, 0.4, 0.6)
    light = replace(Light(), background=sky)
    with drawing([floor()], light, camera()) as draw:
        color = draw(((0.0, 0.0, 1.0), AHEAD))["color"]
    with drawing([floor()], light, camera(("mono",))) as draw:
        mono = draw(((0.0, 0.0, 1.0), AHEAD))["color"]
    np.testing.assert_allclose(color[0, 0], np.array(sky) * 255, atol=1)
    assert abs(float(mono[0, 0]) - 255 * float(np.dot(sky, LUMA))) <= 1


@needs_gl
def test_emissive_adds_to_the_lit_colour_and_unlit_shows_its_colour_as_is() -> None:
    """Lit face on: ambient 0.2 × 0.4 + sun 0.5 × 0.4 + emissive (0.3, 0, 0); an unlit surface shows
    its diffuse colour whatever the light."""
    sun = LightSource(diffuse=(0.5, 0.5, 0.5), direction=(1.0, 0.0, 0.0))
    light = Light(sources=(sun,), ambient=(0.2, 0.2, 0.2), background=(0.0, 0.0, 0.0))
    grey = (0.4, 0.4, 0.4)
    surfaces = {
        "glow": Surface(diffuse=grey, ambient=grey, emissive=(0.3, 0.0, 0.0)),
        "flat": Surface(diffuse=(0.1, 0.8, 0.3), lit=False),
    }
    bodies = [
        box_body("glow", (0.1, 1.0, 1.0), WHITE, True, Transform((2.0, 0.6, 0.0), AHEAD)),
        box_body("flat", (0.1, 1.0, 1.0), WHITE, True, Transform((2.0, -0.6, 0.0), AHEAD)),
    ]
    with drawing(bodies, light, camera(), dressed(surfaces)) as draw:
        image = draw(((0.0, 0.0, 0.0), AHEAD))["color"].astype(float)
    left, right = image[SIZE // 2, SIZE // 2 - 30], image[SIZE // 2, SIZE // 2 + 30]  # image left is +y
    np.testing.assert_allclose(left, 255 * np.array([0.08 + 0.2 + 0.3, 0.28, 0.28]), atol=TOLERANCE)
    np.testing.assert_allclose(right, 255 * np.array([0.1, 0.8, 0.3]), atol=TOLERANCE)


@needs_gl
def test_a_translucent_box_blends_over_what_lies_behind_and_leaves_its_depth() -> None:
    """A green box of opacity 0.5 before a red wall: its back face, then its front face, each blend
    half over what lies behind (0.75 green + 0.25 red); the depth is the wall's."""
    surfaces = {
        "wall": Surface(diffuse=(1.0, 0.0, 0.0), lit=False),
        "glass": Surface(diffuse=(0.0, 1.0, 0.0), lit=False, opacity=0.5),
    }
    bodies = [
        box_body("wall", (0.1, 10.0, 10.0), WHITE, True, Transform((3.05, 0.0, 0.0), AHEAD)),
        box_body("glass", (0.1, 1.0, 1.0), WHITE, True, Transform((1.5, 0.0, 0.0), AHEAD)),
    ]
    with drawing(bodies, DARK, camera(("color", "depth")), dressed(surfaces)) as draw:
        frame = draw(((0.0, 0.0, 0.0), AHEAD))
    np.testing.assert_allclose(
        frame["color"][SIZE // 2, SIZE // 2].astype(float), [0.25 * 255, 0.75 * 255, 0.0], atol=1
    )
    np.testing.assert_allclose(frame["color"][5, 5].astype(float), [255.0, 0.0, 0.0], atol=1)
    assert float(frame["depth"][SIZE // 2, SIZE // 2]) == pytest.approx(3.0, abs=0.005)


PANEL = box_body("panel", (0.01, 0.01, 0.01), WHITE, True, Transform((0.0, 0.0, 0.0), AHEAD))
"""A body whose pieces `panel_pieces` gives."""


def panel_pieces(surface: Surface) -> Pieces:
    """A quad 2 m ahead of a camera at the origin, 2 m wide, facing it: y +1 (the image's left) is
    u 0, z −0.5 (its bottom) is v 0."""
    corners = np.array([[2.0, 1.0, -0.5], [2.0, -1.0, -0.5], [2.0, -1.0, 0.5], [2.0, 1.0, 0.5]], dtype=np.float32)
    uvs = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]], dtype=np.float32)
    order = [0, 1, 2, 0, 2, 3]
    normals = np.tile(np.array([[-1.0, 0.0, 0.0]], dtype=np.float32), (6, 1))
    return lambda scene, name: [Piece(-1, corners[order], normals, uvs[order], surface)]


@needs_gl
def test_a_textured_panel_shows_its_image_where_its_texture_coordinates_put_it(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """A panel 2 m ahead whose texture is red on its left half and blue on its right; an image that
    cannot be read is one warning and the panel shows its colour."""
    import cv2

    image = np.zeros((32, 64, 3), dtype=np.uint8)
    image[:, :32] = (0, 0, 255)  # BGR: red on the left
    image[:, 32:] = (255, 0, 0)  # blue on the right
    cv2.imwrite(str(tmp_path / "halves.png"), image)
    (tmp_path / "broken.png").write_bytes(b"not an image")

    def panel(texture: str) -> Pieces:
        return panel_pieces(Surface(diffuse=(1.0, 1.0, 1.0), lit=False, albedo_map=str(tmp_path / texture)))

    body = [PANEL]
    with drawing(body, DARK, camera(), panel("halves.png")) as draw:
        row = draw(((0.0, 0.0, 0.0), AHEAD))["color"][SIZE // 2]
    np.testing.assert_array_equal(row[SIZE // 2 - 20], [255, 0, 0])
    np.testing.assert_array_equal(row[SIZE // 2 + 20], [0, 0, 255])
    with caplog.at_level(logging.WARNING), drawing(body, DARK, camera(), panel("broken.png")) as draw:
        row = draw(((0.0, 0.0, 0.0), AHEAD))["color"][SIZE // 2]
    np.testing.assert_array_equal(row[SIZE // 2 + 20], [255, 255, 255])
    assert [r.message for r in caplog.records].count(
        f"texture {tmp_path / 'broken.png'} cannot be read; its surfaces show their colour"
    ) == 1


@needs_gl
@pytest.mark.parametrize("face", ["-x", "+x"])
def test_a_textured_box_shows_its_image_upright_on_each_face_it_turns_to_a_camera(tmp_path: Path, face: str) -> None:
    """A 1 m box whose material has an albedo map (SDF's, which the URDF writes as its texture): red
    left half, blue right half, a green top band. Seen from outside, face on, from either side,
    red lies left, blue right, green on top (not mirrored, not upside down). Lit by the scene's
    ambient alone (1): the texture's colours exactly."""
    import cv2

    image = np.zeros((32, 64, 3), dtype=np.uint8)
    image[:, :32], image[:, 32:], image[:4] = (0, 0, 255), (255, 0, 0), (0, 255, 0)  # BGR
    cv2.imwrite(str(tmp_path / "halves.png"), image)
    textured = box_model((1.0, 1.0, 1.0), WHITE, texture=tmp_path / "halves.png")
    box = body_of("box", textured, True, Transform((2.0, 0.0, 0.0), AHEAD))
    pose = ((0.0, 0.0, 0.0), AHEAD) if face == "-x" else ((4.0, 0.0, 0.0), (0.0, 0.0, 1.0, 0.0))
    with drawing([box], Light(sources=(), ambient=(1.0, 1.0, 1.0)), camera()) as draw:
        seen = draw(pose)["color"]
    c = SIZE // 2  # the face spans 33 px either side of the centre (0.5 m at 1.5 m, fx 100)
    np.testing.assert_array_equal(seen[c, c - 20], [255, 0, 0])
    np.testing.assert_array_equal(seen[c, c + 20], [0, 0, 255])
    np.testing.assert_array_equal(seen[c - 31, c - 20], [0, 255, 0])
    np.testing.assert_array_equal(seen[c + 31, c - 20], [255, 0, 0])


@needs_gl
@pytest.mark.parametrize("axis", ["u", "v"])
def test_a_normal_map_tilts_the_surface_towards_its_texture_axes(tmp_path: Path, axis: str) -> None:
    """A panel facing the camera, its normal map tilting every normal 30° towards +u (the image's
    right: world −y) or +v (up: world +z): a light grazing the panel from that side lights it by
    sin 30°, one from the other side not at all (the flat panel: by neither)."""
    import cv2

    tilt = math.radians(30.0)
    tangent = (math.sin(tilt), 0.0, math.cos(tilt)) if axis == "u" else (0.0, math.sin(tilt), math.cos(tilt))
    rgb = np.rint((np.array(tangent) * 0.5 + 0.5) * 255).astype(np.uint8)
    cv2.imwrite(str(tmp_path / "bumps.png"), np.tile(rgb[::-1], (16, 16, 1)))
    towards = (0.0, -1.0, 0.0) if axis == "u" else (0.0, 0.0, 1.0)  # where +u / +v points in the world
    surface = Surface(diffuse=(1.0, 1.0, 1.0), ambient=(0.0, 0.0, 0.0), normal_map=str(tmp_path / "bumps.png"))
    centre = []
    for sign in (1.0, -1.0):
        grazing = LightSource(diffuse=(1.0, 1.0, 1.0), direction=tuple(-sign * c for c in towards))  # type: ignore[arg-type]
        with drawing([PANEL], replace(DARK, sources=(grazing,)), camera(), panel_pieces(surface)) as draw:
            centre.append(float(draw(((0.0, 0.0, 0.0), AHEAD))["color"][SIZE // 2, SIZE // 2, 0]))
    assert centre[0] == pytest.approx(255 * math.sin(tilt), abs=3)  # 8-bit normals
    assert centre[1] == 0.0


@needs_gl
def test_a_depth_camera_inside_its_housing_box_reads_the_scene() -> None:
    """gz-sim's depth_camera_sensor world in shape: the camera at the centre of its 0.1 m housing box
    (near 0.1 m), 4 m from a 1 m box it faces, over a floor. The housing is cut away at the near
    plane: the box's face reads its distance along the optical axis, the floor below is finite, the
    empty sky +inf, and nothing −inf (before the near clip, every pixel read −inf)."""
    size, hfov = 256, 1.05
    eye = (4.05, 0.05, 0.55)
    facing = (0.0, 0.0, 1.0, 0.0)  # yawed π: looking along −x
    bodies = [
        floor(),
        box_body("box", (1.0, 1.0, 1.0), (0.5, 0.5, 0.5, 1.0), True, Transform((0.0, -1.0, 0.5), AHEAD)),
        box_body("housing", (0.1, 0.1, 0.1), (0.2, 0.2, 0.2, 1.0), True, Transform(eye, facing)),
    ]
    spec = CameraSpec("depth_camera1", size, size, hfov, 0.1, 10.0, outputs=("depth",))
    with RenderPool(bodies, [spec], workers=1, renderer="gl") as pool:
        pool.request(0, 1, Transform(eye, facing), {})
        frame = next(f for f in pool.collect(wait_for=0, timeout=30.0) if f.camera == 0)
        depth = np.array(frame["depth"])
    cx, cy = spec.principal_point
    face_x = 4.05 - 0.5  # the box's +x face, along the optical axis
    u = round(cx - spec.fx * (1.0 + 0.05) / face_x)  # the face's centre, 1.05 m to the camera's left
    assert float(depth[round(cy), u]) == pytest.approx(face_x, abs=0.01)
    assert not np.isneginf(depth).any()
    assert np.isfinite(depth[size - 10]).all()  # the floor at the bottom of the image
    assert np.isposinf(depth[round(cy) - 10, size - 10])


WORLD_SDF = """<?xml version="1.0"?>
<sdf version="1.9"><world name="lit">
  <scene><ambient>0.1 0.2 0.3 1</ambient><background>0.4 0.5 0.6 1</background><shadows>false</shadows></scene>
  <light type="directional" name="sun"><cast_shadows>true</cast_shadows><diffuse>0.8 0.8 0.8 1</diffuse>
    <direction>0 0 -1</direction><intensity>0.5</intensity></light>
  <light type="spot" name="lamp"><pose>1 2 3 0 1.5707963 0</pose><diffuse>1 0.5 0 1</diffuse>
    <direction>0 0 -1</direction>
    <attenuation><range>7</range><constant>0.2</constant><linear>0.3</linear><quadratic>0.4</quadratic></attenuation>
    <spot><inner_angle>0.5</inner_angle><outer_angle>1.0</outer_angle><falloff>2</falloff></spot></light>
  <light type="point" name="bulb"><range>3</range></light>
</world></sdf>"""


def test_the_worlds_sdf_lights_and_scene_become_the_renderers_lighting(tmp_path: Path) -> None:
    """Intensity scales the colours, the pose places the light and turns its direction (here
    pitched 90°: −z becomes −x), attenuation and spot as written, SDF's defaults elsewhere (a
    point light's `<attenuation>` block absent: range 10, constant 1, linear 1, quadratic 0);
    `<scene><shadows>` false leaves no shadow caster."""
    from simbot.description import load_world
    from simbot.sim.systems.camera_rendering import world_light

    path = tmp_path / "lit.sdf"
    path.write_text(WORLD_SDF)
    lighting = world_light(load_world(path))
    sun, lamp, bulb = lighting.sources
    assert (lighting.ambient, lighting.background, lighting.shadows) == ((0.1, 0.2, 0.3), (0.4, 0.5, 0.6), False)
    assert sun.diffuse == pytest.approx((0.4, 0.4, 0.4)) and sun.cast_shadows
    assert lighting.shadow_caster is None and replace(lighting, shadows=True).shadow_caster == 0
    assert lamp.type == "spot" and lamp.position == pytest.approx((1.0, 2.0, 3.0))
    assert lamp.direction == pytest.approx((-1.0, 0.0, 0.0), abs=1e-6)
    assert (lamp.range, lamp.attenuation, lamp.spot) == (7.0, (0.2, 0.3, 0.4), (0.5, 1.0, 2.0))
    assert (bulb.range, bulb.attenuation) == (10.0, (1.0, 1.0, 0.0))  # <range> outside <attenuation> is not SDF


@needs_gl
def test_more_lights_than_the_shader_holds_are_one_warning(caplog: pytest.LogCaptureFixture) -> None:
    """Nine lights: the first eight shade (the ninth, a bright sun, changes nothing), one warning."""
    dim = LightSource(diffuse=(0.05, 0.05, 0.05), direction=(1.0, 0.0, 0.0))
    bright = LightSource(diffuse=(1.0, 1.0, 1.0), direction=(1.0, 0.0, 0.0))
    wall = [box_body("wall", (0.1, 10.0, 10.0), WHITE, True, Transform((3.05, 0.0, 0.0), AHEAD))]
    with (
        caplog.at_level(logging.WARNING),
        drawing(wall, replace(DARK, sources=(dim,) * 8 + (bright,)), camera()) as draw,
    ):
        pixel = draw(((0.0, 0.0, 0.0), AHEAD))["color"][SIZE // 2, SIZE // 2].astype(float)
    assert abs(pixel[0] - 255 * 0.4) <= TOLERANCE
    assert sum("the renderer shades the first 8" in r.message for r in caplog.records) == 1
