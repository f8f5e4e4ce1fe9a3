"""The render pool with real PyBullet in real worker processes, with both renderers (OpenGL on EGL
and TinyRenderer): geometry of the images (pinhole facts), the light convention, moving bodies and
joints, pixel formats and noise, depth and points, an output kind simbot does not ship, the two
renderers agreeing, the one outstanding request per camera, bodies and cameras added to a running
pool (and bodies removed), the fallback where no EGL context opens, and a dead or busy worker
never hanging the caller."""

from __future__ import annotations

import math
import os
import pickle
import signal
import subprocess
import sys
import time
from collections.abc import Iterator, Mapping
from dataclasses import replace
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pytest
from gl_helpers import INERTIA, NO_EGL, body_of, box_body, box_model
from server_helpers import wait_until

from simbot.description.model import (
    Axis,
    Box,
    Capsule,
    Cylinder,
    Geometry,
    Inertial,
    Joint,
    Link,
    Material,
    Mesh,
    Model,
    Sphere,
    Visual,
)
from simbot.description.poses import Pose
from simbot.sim.render import (
    BodyState,
    CameraSpec,
    Frame,
    Light,
    LightSource,
    OutputKind,
    PoolPlan,
    RenderPool,
    SceneBody,
    output_kinds,
    plan_pool,
)
from simbot.sim.render.kinds import Array, Finish, Optics
from simbot.sim.render.specs import Transform

W, H = 160, 120
FX = 100.0
HFOV = 2.0 * math.atan((W / 2) / FX)  # so that fx = fy = 100 px
WAIT = 10.0  # seconds a test waits for a frame before failing (a bug fails, never hangs)

RED = (1.0, 0.0, 0.0, 1.0)
GREEN = (0.0, 1.0, 0.0, 1.0)
ORANGE = (0.8, 0.5, 0.2, 1.0)
FRONT_LIT = Light(sources=(LightSource(diffuse=(0.4, 0.4, 0.4), direction=(1.0, 0.0, 0.0)),))
"""The default lighting but its sun travels along +x: it lights the faces that look back at -x."""

# The scene: each test's objects sit in their own region, 100 m apart (beyond the far clip).
RED_FACE = 2.0  # the red box's front face, metres ahead of a camera at the origin
RED_SIZE = 1.0
MOVER_AT = (100.0, 0.0, 0.0)  # the camera looking at the green mover sits here
MOVER_FACE = 2.0
ARM_AT = (200.0, 0.0, 0.0)  # the swinging arm's joint, and the camera looking along it
ARM_REACH = 2.5
OFFSET_AT = (300.0, 0.0, 0.0)  # a body whose centre of mass is beside its visual
ORANGE_AT = (400.0, 0.0, 0.0)
GREY_AT = (500.0, 0.0, 0.0)  # a grey wall filling the view: a flat region for the noise
LATE_AT = (600.0, 0.0, 0.0)  # empty until a test adds bodies to the running pool
LATE_FACE, LATE_SIZE, LATE_SIDE = 2.0, 0.4, 0.5  # their front faces 2 m ahead, 0.4 m wide, 0.5 m either side

AHEAD: Transform = Transform((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))


ARM = Model(
    "arm",
    links=(
        Link("hub", inertial=Inertial(1.0, inertia=INERTIA)),
        Link(
            "arm",
            inertial=Inertial(1.0, inertia=INERTIA),
            visuals=(Visual("arm", Box((0.2, 0.2, 0.2)), Pose((ARM_REACH, 0.0, 0.0)), Material(diffuse=GREEN)),),
        ),
    ),
    joints=(Joint("swing", "revolute", "hub", "arm", axis=Axis((0.0, 0.0, 1.0), -3.0, 3.0, 10.0, 10.0)),),
)


def at(xyz: tuple[float, float, float]) -> Transform:
    return Transform(xyz, (0.0, 0.0, 0.0, 1.0))


def yawed(xyz: tuple[float, float, float], yaw: float) -> Transform:
    return Transform(xyz, (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)))


def scene() -> list[SceneBody]:
    offset = box_model((0.1, 0.4, 0.4), RED, com=(0.0, 0.4, 0.0))
    return [
        box_body("red", (0.1, RED_SIZE, RED_SIZE), RED, True, at((RED_FACE + 0.05, 0.0, 0.0))),
        box_body("mover", (0.1, 0.4, 0.4), GREEN, False, at((MOVER_AT[0] + MOVER_FACE + 0.05, 0.0, 0.0))),
        body_of("arm", ARM, False, at(ARM_AT)),
        body_of("offset", offset, True, at((OFFSET_AT[0] + 2.05, 0.0, 0.0))),
        box_body("orange", (0.1, 1.0, 1.0), ORANGE, True, at((ORANGE_AT[0] + 2.05, 0.0, 0.0))),
        box_body("grey", (0.1, 20.0, 20.0), (0.5, 0.5, 0.5, 1.0), True, at((GREY_AT[0] + 2.05, 0.0, 0.0))),
    ]


CAMERAS = [
    CameraSpec("rgb", W, H, HFOV, 0.05, 50.0),
    CameraSpec("rgbd", W, H, HFOV, 0.05, 50.0, outputs=("color", "depth", "points")),
    CameraSpec("mono", W, H, HFOV, 0.05, 50.0, outputs=("mono",)),
    CameraSpec("full", 640, 480, HFOV, 0.05, 50.0),
    CameraSpec("noisy_a", W, H, HFOV, 0.05, 50.0, noise_stddev=0.02, seed=7),
    CameraSpec("noisy_b", W, H, HFOV, 0.05, 50.0, noise_stddev=0.02, seed=7),
    CameraSpec("noisy_c", W, H, HFOV, 0.05, 50.0, noise_stddev=0.02, seed=8),
]
RGB, RGBD, MONO, FULL, NOISY_A, NOISY_B, NOISY_C = range(len(CAMERAS))


@pytest.fixture(scope="module", params=["gl", "tiny"])
def renderer(request: pytest.FixtureRequest) -> str:
    if request.param == "gl" and NO_EGL:
        pytest.skip(NO_EGL)
    return str(request.param)


@pytest.fixture(scope="module")
def shared_pool(renderer: str) -> Iterator[RenderPool]:
    """Six cameras on two workers, the front faces lit."""
    with RenderPool(scene(), CAMERAS, workers=2, renderer=renderer, light=FRONT_LIT) as render_pool:
        assert render_pool.renderer_used == renderer
        yield render_pool


@pytest.fixture
def pool(shared_pool: RenderPool) -> Iterator[RenderPool]:
    """The shared pool, left with no outstanding request whatever the test did."""
    yield shared_pool
    for camera in range(len(CAMERAS)):
        if shared_pool.busy(camera):
            shared_pool.collect(wait_for=camera, timeout=WAIT)


def render(pool: RenderPool, camera: int, pose: Transform, states: dict[str, BodyState] | None = None) -> Frame:
    """One frame, in lockstep; a copy of its pixels, which are the pool's until the next request."""
    pool.request(camera, 42, pose, states or {})
    frames = [f for f in pool.collect(wait_for=camera, timeout=WAIT) if f.camera == camera]
    assert len(frames) == 1
    frame = frames[0]
    return replace(frame, arrays={name: array.copy() for name, array in frame.items()})


def mask(pixels: npt.NDArray[np.uint8], channel: int) -> npt.NDArray[np.bool_]:
    """Pixels of a saturated primary colour (channel 0 red, 1 green)."""
    others = [c for c in range(3) if c != channel]
    return (pixels[..., channel] > 150) & (pixels[..., others[0]] < 60) & (pixels[..., others[1]] < 60)


def centroid_column(m: npt.NDArray[np.bool_]) -> float:
    assert m.any(), "the object is not in the image"
    return float(np.nonzero(m)[1].mean())


def test_box_ahead_fills_the_centre_with_its_pinhole_width(pool: RenderPool) -> None:
    """A 1 m red face 2 m ahead: red at the centre, fx·size/d pixels wide; looking back, nothing."""
    pixels = render(pool, RGB, AHEAD)["color"]
    assert pixels.shape == (H, W, 3) and pixels.dtype == np.uint8
    red = mask(pixels, 0)
    assert red[H // 2, W // 2]
    assert red[H // 2].sum() == pytest.approx(FX * RED_SIZE / RED_FACE, abs=2)
    assert red[:, W // 2].sum() == pytest.approx(FX * RED_SIZE / RED_FACE, abs=2)  # square pixels: fy = fx
    behind = render(pool, RGB, yawed((0.0, 0.0, 0.0), math.pi))["color"]
    assert not mask(behind, 0).any()


def test_camera_pose_moves_the_image(pool: RenderPool) -> None:
    """A camera 0.2 m to the left sees the box 10 px further right; tilted up, the box moves down."""
    left = render(pool, RGB, at((0.0, 0.2, 0.0)))["color"]
    assert centroid_column(mask(left, 0)) == pytest.approx(W / 2 + FX * 0.2 / RED_FACE - 0.5, abs=2)
    pitch = -0.1  # a negative pitch about y raises the optical axis (z up)
    up = render(pool, RGB, Transform((0.0, 0.0, 0.0), (0.0, math.sin(pitch / 2), 0.0, math.cos(pitch / 2))))["color"]
    rows = np.nonzero(mask(up, 0))[0]
    assert rows.mean() == pytest.approx(H / 2 + FX * math.tan(0.1) - 0.5, abs=2)  # row 0 is the top


def test_full_size_image(pool: RenderPool) -> None:
    """640×480 RGB, the box in the middle, four times as wide as at 160×120 with the same fov."""
    pixels = render(pool, FULL, AHEAD)["color"]
    assert pixels.shape == (480, 640, 3) and pixels.dtype == np.uint8
    assert mask(pixels, 0)[240].sum() == pytest.approx(4 * FX * RED_SIZE / RED_FACE, abs=2)


def test_moving_a_body_moves_it_in_the_image(pool: RenderPool) -> None:
    """The green box moved 0.3 m to the left (+y) shifts left by fx·dy/d pixels."""
    camera = at(MOVER_AT)
    centre = (MOVER_AT[0] + MOVER_FACE + 0.05, 0.0, 0.0)
    before = centroid_column(mask(render(pool, RGB, camera, {"mover": BodyState(at(centre), {})})["color"], 1))
    moved = BodyState(at((centre[0], 0.3, 0.0)), {})
    after = centroid_column(mask(render(pool, RGB, camera, {"mover": moved})["color"], 1))
    assert before == pytest.approx(W / 2 - 0.5, abs=1)
    assert after - before == pytest.approx(-FX * 0.3 / MOVER_FACE, abs=2)


def test_joint_positions_move_links(pool: RenderPool) -> None:
    """The arm swung by 0.1 rad about z puts its box fx·tan(0.1) pixels to the left."""
    camera = at(ARM_AT)
    straight = centroid_column(
        mask(render(pool, RGB, camera, {"arm": BodyState(at(ARM_AT), {"swing": 0.0})})["color"], 1)
    )
    swung = centroid_column(mask(render(pool, RGB, camera, {"arm": BodyState(at(ARM_AT), {"swing": 0.1})})["color"], 1))
    assert straight == pytest.approx(W / 2 - 0.5, abs=1)
    assert swung - straight == pytest.approx(-FX * math.tan(0.1), abs=2)


def test_base_poses_are_centre_of_mass_frames(pool: RenderPool) -> None:
    """A body whose centre of mass is 0.4 m beside its visual, placed by PyBullet's base pose, shows its visual
    where the server has it (centred), not 0.4 m (20 px) off."""
    pixels = render(pool, RGB, at(OFFSET_AT))["color"]
    assert centroid_column(mask(pixels, 0)) == pytest.approx(W / 2 - 0.5, abs=1)


def test_light_travels_along_its_direction_and_keeps_the_hue(pool: RenderPool, renderer: str) -> None:
    """Lit from behind the camera, an orange face shows scene ambient (0.6) × its colour + sun diffuse
    (0.4) × its colour × N·L (1): its colour exactly; the default sun (travelling towards -x) leaves
    that face in the ambient light only: 60 % of it, same hue. Both renderers shade so."""
    lit = render(pool, RGB, at(ORANGE_AT))["color"][H // 2, W // 2].astype(float)
    np.testing.assert_allclose(lit, np.array(ORANGE[:3]) * 255, atol=2)
    with RenderPool(
        [b for b in scene() if b.name == "orange"], CAMERAS[:1], workers=1, renderer=renderer
    ) as default_light:
        shaded = render(default_light, RGB, at(ORANGE_AT))["color"][H // 2, W // 2].astype(float)
    np.testing.assert_allclose(shaded, np.array(ORANGE[:3]) * 255 * Light().ambient, atol=2)


def test_a_coloured_sun_and_the_scene_ambient_shade_alike_in_both_renderers(renderer: str) -> None:
    """Scene ambient 0.3 (grey) and a sun of diffuse (0.5, 0.3, 0.2) face on: the orange face shows
    colour × (0.3 + sun), channel by channel, in GL and in TinyRenderer (its one light's colour
    and ambient coefficient)."""
    sun = LightSource(diffuse=(0.5, 0.3, 0.2), direction=(1.0, 0.0, 0.0))
    lighting = Light(sources=(sun,), ambient=(0.3, 0.3, 0.3))
    orange = [b for b in scene() if b.name == "orange"]
    with RenderPool(orange, CAMERAS[:1], workers=1, renderer=renderer, light=lighting) as one:
        pixel = render(one, RGB, at(ORANGE_AT))["color"][H // 2, W // 2].astype(float)
    np.testing.assert_allclose(pixel, 255 * np.array(ORANGE[:3]) * (0.3 + np.array(sun.diffuse)), atol=2)


def test_mono_is_luminance(pool: RenderPool) -> None:
    """The mono output: H×W uint8, the BT.601 luminance of the RGB image."""
    rgb = render(pool, RGB, AHEAD)["color"].astype(float)
    mono = render(pool, MONO, AHEAD)["mono"]
    assert mono.shape == (H, W) and mono.dtype == np.uint8
    np.testing.assert_allclose(mono, rgb @ [0.299, 0.587, 0.114], atol=1)


def test_noise_has_the_configured_spread_and_follows_the_seed(pool: RenderPool) -> None:
    """σ 0.02 of full scale is ≈ 5.1 levels on a flat region; same seed, same image; another seed, another."""
    wall = at(GREY_AT)
    clean = render(pool, RGB, wall)["color"].astype(float)
    assert clean.std() == 0 and clean[0, 0, 0] == pytest.approx(128, abs=2)  # mid-grey: no clipping
    a, b, c = (render(pool, cam, wall)["color"] for cam in (NOISY_A, NOISY_B, NOISY_C))
    assert (a - clean).std() == pytest.approx(0.02 * 255, rel=0.2)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)


def test_depth_is_z_along_the_optical_axis_and_points_lie_on_the_surface(pool: RenderPool) -> None:
    """A wall square to the axis 2 m ahead reads 2.00 m at every pixel (z-depth, not range), its points lie on
    the plane z = 2 in the optical frame within 1 cm and carry the wall's colour; nothing in view reads +inf."""
    frame = render(pool, RGBD, at(GREY_AT))
    depth, points, color = frame["depth"], frame["points"], frame["color"]
    assert depth.shape == (H, W) and depth.dtype == np.float32
    np.testing.assert_allclose(depth, 2.0, atol=0.01)
    np.testing.assert_allclose(points[..., 2], 2.0, atol=0.01)
    u, v = np.meshgrid(np.arange(W) - (W - 1) / 2, np.arange(H) - (H - 1) / 2)
    np.testing.assert_allclose(points[..., 0], u * 2.0 / FX, atol=0.01)  # x right
    np.testing.assert_allclose(points[..., 1], v * 2.0 / FX, atol=0.01)  # y down
    packed = np.ascontiguousarray(points[..., 3]).view(np.uint32)
    assert int(packed[0, 0]) == (int(color[0, 0, 0]) << 16) | (int(color[0, 0, 1]) << 8) | int(color[0, 0, 2])
    sky = render(pool, RGBD, at((GREY_AT[0] + 100.0, 0.0, 0.0)))  # past the last region: nothing within the far clip
    assert np.isposinf(sky["depth"]).all() and np.isnan(sky["points"][..., :3]).all()


def test_every_camera_gets_its_own_frame_and_busy_means_outstanding(pool: RenderPool) -> None:
    """Three cameras of one worker (round-robin over two: cameras 0, 2, 4 and 6 are worker 0's): each frame
    comes back with its own stamp; a camera stays busy until its frame is collected, rendered or not, and a
    second request meanwhile raises. A failing request for a fourth camera of that worker, sent last, marks
    the three as rendered: the worker takes its requests in order, and the failure is collected alone."""
    cameras = (RGB, MONO, NOISY_C)
    for n, camera in enumerate(cameras):
        pool.request(camera, 1000 + n, AHEAD, {})
    assert all(pool.busy(camera) for camera in cameras)
    assert not pool.busy(FULL)
    with pytest.raises(RuntimeError, match="busy"):
        pool.request(RGB, 2000, AHEAD, {})
    pool.request(NOISY_A, 3000, at(ARM_AT), {"arm": BodyState(at(ARM_AT), {})})  # no joint position: fails
    with pytest.raises(RuntimeError, match="arm"):
        pool.collect(wait_for=NOISY_A, timeout=WAIT)
    assert all(pool.busy(camera) for camera in cameras)  # rendered, but not collected: their pixels are not ours yet
    assert {f.camera: f.stamp_ns for f in pool.collect()} == {RGB: 1000, MONO: 1001, NOISY_C: 1002}
    assert not any(pool.busy(camera) for camera in cameras)
    assert pool.collect() == []


def test_bad_requests_are_refused(pool: RenderPool) -> None:
    """Unknown bodies and cameras fail at the request, in the caller."""
    with pytest.raises(ValueError, match="nosuch"):
        pool.request(RGB, 0, AHEAD, {"nosuch": BodyState(AHEAD, {})})
    with pytest.raises(IndexError):
        pool.request(len(CAMERAS), 0, AHEAD, {})
    assert not pool.busy(RGB)


def shapes_model(mesh: Path) -> Model:
    """A red box, a green cylinder, a blue sphere, a magenta capsule and a cyan mesh, one a link, fixed together."""
    shapes: dict[str, tuple[Geometry, Pose, tuple[float, float, float, float]]] = {
        "box": (Box((0.4, 0.6, 0.8)), Pose((1.8, -0.9, 0.0)), (1.0, 0.0, 0.0, 1.0)),
        "cylinder": (Cylinder(0.25, 0.8), Pose((1.8, -0.3, 0.0), (0.3, 0.0, 0.0)), (0.0, 1.0, 0.0, 1.0)),
        "sphere": (Sphere(0.3), Pose((1.8, 0.3, 0.0)), (0.0, 0.0, 1.0, 1.0)),
        "capsule": (Capsule(0.2, 0.5), Pose((1.8, 0.9, 0.0), (0.0, 0.4, 0.0)), (1.0, 0.0, 1.0, 1.0)),
        "mesh": (
            Mesh(str(mesh), (0.004,) * 3, mesh),
            Pose((1.5, 0.0, -0.55), (1.5708, 0.0, 0.0)),
            (0.0, 1.0, 1.0, 1.0),
        ),
    }
    links = tuple(
        Link(name, visuals=(Visual(name, geometry, pose, Material(diffuse=rgba)),))
        for name, (geometry, pose, rgba) in shapes.items()
    )
    joints = tuple(Joint(f"j{k}", "fixed", "box", name) for k, name in enumerate(list(shapes)[1:], 1))
    return Model("shapes", links=links, joints=joints)


PRIMARIES = {"box": (0, (1, 2)), "cylinder": (1, (0, 2)), "sphere": (2, (0, 1))}


def _silhouettes(pixels: npt.NDArray[np.uint8]) -> dict[str, npt.NDArray[np.bool_]]:
    """Each object by its colour: red box, green cylinder, blue sphere, magenta capsule, cyan mesh."""
    hi, lo = pixels > 100, pixels < 40
    return {
        "box": hi[..., 0] & lo[..., 1] & lo[..., 2],
        "cylinder": lo[..., 0] & hi[..., 1] & lo[..., 2],
        "sphere": lo[..., 0] & lo[..., 1] & hi[..., 2],
        "capsule": hi[..., 0] & lo[..., 1] & hi[..., 2],
        "mesh": lo[..., 0] & hi[..., 1] & hi[..., 2],
    }


def test_gl_and_tiny_draw_every_shape_with_the_same_silhouette() -> None:
    """Box, cylinder, sphere, capsule and mesh (the robot's wheel) from the same pose. Box, cylinder
    and mesh: per-object silhouettes of the two renderers overlap with IoU ≥ 0.97 (they differ by
    edge pixels: TinyRenderer samples half a pixel off the pixel centres). TinyRenderer draws
    spheres and capsules as coarse polyhedra (its sphere covers 7 % less than the true disc), so
    there its silhouette must lie inside GL's (≥ 97 % of it), and GL's sphere must match the true
    silhouette (each pixel's centre ray against the sphere) with IoU ≥ 0.97."""
    if NO_EGL:
        pytest.skip(NO_EGL)
    shapes = shapes_model(Path(__file__).resolve().parents[1] / "meshes" / "wheel.stl")
    bodies = [body_of("shapes", shapes, True, at((0.0, 0.0, 0.0)))]
    camera = CameraSpec("c", 640, 480, 1.6, 0.05, 50.0)
    images = {}
    for name in ("gl", "tiny"):
        with RenderPool(bodies, [camera], workers=1, renderer=name) as one:
            images[name] = render(one, 0, AHEAD)["color"]
    gl, tiny = _silhouettes(images["gl"]), _silhouettes(images["tiny"])
    for shape in ("box", "cylinder", "mesh"):
        iou = (gl[shape] & tiny[shape]).sum() / (gl[shape] | tiny[shape]).sum()
        assert iou >= 0.97, f"{shape}: IoU {iou:.3f} between the gl and tiny silhouettes"
    for shape in ("sphere", "capsule"):
        inside = (gl[shape] & tiny[shape]).sum() / tiny[shape].sum()
        assert inside >= 0.97, f"{shape}: only {inside:.3f} of TinyRenderer's silhouette lies inside GL's"
    true = _sphere_silhouette(camera, centre=(1.8, 0.3, 0.0), radius=0.3)
    iou = (gl["sphere"] & true).sum() / (gl["sphere"] | true).sum()
    assert iou >= 0.97, f"sphere: IoU {iou:.3f} between GL's silhouette and the true one"


def _sphere_silhouette(camera: CameraSpec, centre: tuple[float, float, float], radius: float) -> npt.NDArray[np.bool_]:
    """The pixels whose centre ray (camera at the origin looking along +x, z up) meets the sphere."""
    cx, cy = camera.principal_point
    u, v = np.meshgrid(np.arange(camera.width) - cx, np.arange(camera.height) - cy)
    rays = np.stack([np.full(u.shape, camera.fx), -u, -v], axis=-1)
    rays /= np.linalg.norm(rays, axis=-1, keepdims=True)
    to_centre = np.asarray(centre) / np.linalg.norm(centre)
    return rays @ to_centre > math.cos(math.asin(radius / np.linalg.norm(centre)))


def test_a_failed_render_raises_and_frees_the_camera(pool: RenderPool) -> None:
    """A state the worker cannot apply (the arm without its joint position) fails that frame only."""
    pool.request(RGB, 7, at(ARM_AT), {"arm": BodyState(at(ARM_AT), {})})
    with pytest.raises(RuntimeError, match="arm"):
        pool.collect(wait_for=RGB, timeout=WAIT)
    assert not pool.busy(RGB)
    assert mask(render(pool, RGB, AHEAD)["color"], 0)[H // 2, W // 2]


def late_box(name: str, rgba: tuple[float, float, float, float], side: float, static: bool) -> SceneBody:
    """A box for the empty region, its front face LATE_FACE ahead of the camera there, `side` m to its left."""
    size = (0.1, LATE_SIZE, LATE_SIZE)
    return box_body(name, size, rgba, static, at((LATE_AT[0] + LATE_FACE + 0.05, side, 0.0)))


def test_bodies_added_to_a_running_pool_are_drawn_where_placed_and_removed_ones_vanish(pool: RenderPool) -> None:
    """A moving green box 0.5 m to the left and a static red one 0.5 m to the right, added while the pool runs:
    each fx·0.4/2 = 20 px wide, centred fx·0.5/2 = 25 px off the centre column; the static bodies loaded at the
    start are still drawn as before (GL re-bakes its static world). Removed, they are gone from the image."""
    camera = at(LATE_AT)
    assert not mask(render(pool, RGB, camera)["color"], 1).any()
    green, red = late_box("late_green", GREEN, LATE_SIDE, False), late_box("late_red", RED, -LATE_SIDE, True)
    pool.add_body(green)
    pool.add_body(red)
    assert {"late_green", "late_red"} <= pool.body_names
    pixels = render(pool, RGB, camera, {"late_green": BodyState(green.base, {})})["color"]
    offset = FX * LATE_SIDE / LATE_FACE
    for m, side in ((mask(pixels, 1), -1), (mask(pixels, 0), 1)):
        assert centroid_column(m) == pytest.approx(W / 2 - 0.5 + side * offset, abs=1)
        assert m[H // 2].sum() == pytest.approx(FX * LATE_SIZE / LATE_FACE, abs=2)
    assert mask(render(pool, RGB, AHEAD)["color"], 0)[H // 2].sum() == pytest.approx(FX * RED_SIZE / RED_FACE, abs=2)
    pool.remove_body("late_green")
    pool.remove_body("late_red")
    assert not {"late_green", "late_red"} & pool.body_names
    emptied = render(pool, RGB, camera)["color"]
    assert not mask(emptied, 0).any() and not mask(emptied, 1).any()
    with pytest.raises(ValueError, match="late_green"):
        pool.request(RGB, 0, camera, {"late_green": BodyState(green.base, {})})


def nearer_than_3m(spec: Optics) -> Finish:
    """The test kind's finishing step: 255 where the depth (finished into metres before it) is under 3 m."""

    def fill(out: Array, arrays: Mapping[str, Array]) -> None:
        out[...] = np.where(arrays["depth"] < 3.0, 255, 0)

    return fill


NEAR = OutputKind("near", np.uint8, 1, encoding="mono8", needs=("depth",), finisher=nearer_than_3m)
"""A kind simbot does not ship, computed from depth: it reaches the worker inside the camera's spec."""


def test_a_new_output_kind_flows_through_a_real_pool(renderer: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """A camera asking only for `near` gets it, and the depth it needs, finished in that order: the red
    box's face, 2 m ahead and fx·1/2 = 50 px wide, is the only thing nearer than 3 m."""
    monkeypatch.setitem(output_kinds(), "near", NEAR)
    camera = CameraSpec("near", W, H, HFOV, 0.05, 50.0, outputs=("near",))
    assert [kind.name for kind in camera.kinds] == ["depth", "near"]
    with RenderPool(scene()[:1], [camera], workers=1, renderer=renderer) as one:
        frame = render(one, 0, AHEAD)
    assert set(frame) == {"depth", "near"} and frame["near"].dtype == np.uint8
    near = frame["near"] == 255
    assert near[H // 2, W // 2] and near[H // 2].sum() == pytest.approx(FX * RED_SIZE / RED_FACE, abs=2)
    np.testing.assert_array_equal(near, frame["depth"] < 3.0)


def test_camera_outputs_are_checked_at_configuration() -> None:
    """An unknown output, or two outputs drawing the same buffer (points need rgb colour, not mono), fail in the
    server; a camera's memory holds the outputs it asks for and those they need."""
    with pytest.raises(ValueError, match="'c'.*no camera output 'heat'"):
        CameraSpec("c", W, H, HFOV, 0.05, 50.0, outputs=("heat",))
    with pytest.raises(ValueError, match="'c'.*draw the same buffer"):
        CameraSpec("c", W, H, HFOV, 0.05, 50.0, outputs=("mono", "points"))
    assert list(CameraSpec("c", W, H, HFOV, 0.05, 50.0, outputs=("points",)).layout()) == ["color", "depth", "points"]


def test_a_camera_added_to_a_running_pool_renders_its_own_view(renderer: str) -> None:
    """Two cameras on two workers, then a third of another size and focal length: it takes index 2 (the others
    keep theirs) and sees the red box with its own pinhole (fx 50: 25 px wide) and from its own pose."""
    late = CameraSpec("late", 80, 60, 2.0 * math.atan(40 / 50), 0.05, 50.0)
    with RenderPool(scene()[:1], CAMERAS[:2], workers=2, renderer=renderer, light=FRONT_LIT) as growing:
        assert growing.add_camera(late) == 2
        pixels = render(growing, 2, at((0.0, 0.2, 0.0)))["color"]
        assert pixels.shape == (60, 80, 3)
        red = mask(pixels, 0)
        assert red[30].sum() == pytest.approx(late.fx * RED_SIZE / RED_FACE, abs=2)
        assert centroid_column(red) == pytest.approx(40 - 0.5 + late.fx * 0.2 / RED_FACE, abs=2)
        assert mask(render(growing, RGB, AHEAD)["color"], 0)[H // 2].sum() == pytest.approx(
            FX * RED_SIZE / RED_FACE, abs=2
        )


def kill_worker(render_pool: RenderPool, index: int) -> None:
    """SIGKILL to a worker, returning once it has exited: the pool sees the death at its next look,
    whatever the worker had done with its requests by then."""
    pid = render_pool.pids[index]
    assert pid is not None
    os.kill(pid, signal.SIGKILL)
    wait_until(lambda: render_pool.exited(index), WAIT, f"render worker {index} (pid {pid}) to exit")


def test_an_added_camera_goes_to_the_worker_with_the_fewest_cameras() -> None:
    """Three cameras on two workers (rgb and mono on worker 0, rgbd on worker 1): a fourth goes to worker 1,
    as the death of worker 1 shows, naming its cameras."""
    with RenderPool(scene()[:1], CAMERAS[:3], workers=2, renderer="tiny") as render_pool:
        added = render_pool.add_camera(CameraSpec("late", W, H, HFOV, 0.05, 50.0))
        kill_worker(render_pool, 1)
        with pytest.raises(RuntimeError, match=r"worker 1 .*died.*its cameras: rgbd, late$"):
            render_pool.request(added, 1, AHEAD, {})


def test_a_body_that_does_not_load_fails_the_next_collect_and_the_worker_goes_on() -> None:
    """A broken URDF added to a running pool: the next collect raises naming it; the worker still renders."""
    with RenderPool(scene()[:1], CAMERAS[:1], workers=1, renderer="tiny") as render_pool:
        render_pool.add_body(SceneBody("broken", "<robot name='x'><link", True, AHEAD))
        render_pool.request(RGB, 1, AHEAD, {})
        with pytest.raises(RuntimeError, match="add_body 'broken'"):
            render_pool.collect(wait_for=RGB, timeout=WAIT)
        (frame,) = render_pool.collect()
        assert mask(frame["color"], 0)[H // 2, W // 2]


QUIET_SCRIPT = """
import pickle
from simbot.sim.render import CameraSpec, RenderPool
if __name__ == "__main__":
    body = pickle.loads({body!r})
    with RenderPool([body], [CameraSpec("c", 32, 24, 1.5, 0.05, 50.0)], workers=1, renderer="auto") as pool:
        pool.request(0, 1, ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0)), {{}})
        pool.collect(wait_for=0, timeout=10)
"""


def test_workers_keep_pybullet_chatter_off_stdout_and_stderr(tmp_path: Path) -> None:
    """PyBullet and Mesa print from C; none of it reaches the server's stdout or stderr."""
    script = tmp_path / "quiet.py"
    body = box_body("red", (0.1, 1.0, 1.0), RED, True, at((2.05, 0.0, 0.0)))
    script.write_text(QUIET_SCRIPT.format(body=pickle.dumps(body)))
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert (done.stdout, done.stderr) == ("", "")


def test_auto_falls_back_to_tiny_with_the_reason_where_no_egl_context_opens(monkeypatch: pytest.MonkeyPatch) -> None:
    """No EGL vendor library (glvnd finds no ICD): `auto` renders with TinyRenderer and says why; `gl` refuses to start."""
    monkeypatch.setenv("__EGL_VENDOR_LIBRARY_FILENAMES", "/nonexistent/egl_vendor.json")
    with RenderPool(scene()[:1], CAMERAS[:1], workers=1, renderer="auto") as fallback:
        assert fallback.renderer_used == "tiny"
        assert fallback.fallback_reason and "EGL" in fallback.fallback_reason
        assert mask(render(fallback, RGB, AHEAD)["color"], 0)[H // 2, W // 2]
    with pytest.raises(RuntimeError, match="--renderer gl: no OpenGL 3.3 EGL context"):
        RenderPool(scene()[:1], CAMERAS[:1], workers=1, renderer="gl", start_timeout=WAIT)


def test_gl_is_the_default_where_egl_opens() -> None:
    if NO_EGL:
        pytest.skip(NO_EGL)
    with RenderPool(scene()[:1], CAMERAS[:1], workers=1) as default:
        assert default.renderer_used == "gl" and default.fallback_reason is None and default.device


def overdrawn(panels: int) -> list[SceneBody]:
    """`panels` walls one behind the other, each filling the view, listed from the farthest: TinyRenderer
    draws every pixel once a panel (each nearer one passes the depth test), so a frame of modest size
    (and memory) takes seconds."""
    return [
        box_body(f"panel{i}", (0.01, 20.0, 20.0), RED, True, at((1.0 + 0.2 * (panels - i), 0.0, 0.0)))
        for i in range(panels)
    ]


def test_close_during_a_render_is_prompt() -> None:
    """close() while a frame renders returns well before that frame would have finished, and ends the
    worker. The measure is the same frame rendered whole first, in this test (3.3 s on a 2-core Intel
    Xeon, KVM; close takes the stop's grace, 0.5 s, then terminates): a loaded machine slows the frame
    at least as much as close (its worker runs at nice 10)."""
    slow = CameraSpec("slow", 900, 900, HFOV, 0.05, 50.0)
    render_pool = RenderPool(overdrawn(30), [slow], workers=1, renderer="tiny")
    (pid,) = render_pool.pids
    asked = time.monotonic()
    render_pool.request(0, 1, AHEAD, {})
    render_pool.collect(wait_for=0, timeout=120.0)
    frame_s = time.monotonic() - asked
    asked = time.monotonic()
    render_pool.request(0, 2, AHEAD, {})  # the worker takes it before the stop that close() sends after it
    render_pool.close()
    closed_s = time.monotonic() - asked
    print(f"\nmeasured: close() {closed_s:.2f} s into a {frame_s:.2f} s frame")
    assert closed_s < frame_s / 2, f"close() took {closed_s:.2f} s of a {frame_s:.2f} s frame"
    with pytest.raises(ProcessLookupError):
        os.kill(pid, 0)  # type: ignore[arg-type]
    render_pool.close()  # idempotent
    with pytest.raises(RuntimeError, match="closed"):
        render_pool.request(0, 2, AHEAD, {})


def test_a_killed_worker_raises_instead_of_hanging() -> None:
    """A worker killed mid-request: collect(wait_for=) raises RuntimeError naming it; the camera is no longer
    busy and a new request for it raises too."""
    big = CameraSpec("big", 2000, 2000, HFOV, 0.05, 50.0)  # slow enough to be killed mid-render
    with RenderPool(scene()[:1], [CAMERAS[RGB], big], workers=2, renderer="tiny") as render_pool:
        render_pool.request(1, 1, AHEAD, {})
        kill_worker(render_pool, 1)
        with pytest.raises(RuntimeError, match=r"worker 1 .*died.*big"):
            render_pool.collect(wait_for=1, timeout=WAIT)
        assert not render_pool.busy(1)
        with pytest.raises(RuntimeError, match="died"):
            render_pool.request(1, 2, AHEAD, {})


def test_a_scene_that_does_not_load_fails_the_start() -> None:
    """A broken URDF fails the constructor with the worker's reason, not a timeout."""
    broken = SceneBody("broken", "<robot name='x'><link", True, AHEAD)
    with pytest.raises(RuntimeError, match="failed to start.*broken"):
        RenderPool([broken], CAMERAS[:1], workers=1, start_timeout=WAIT)


@pytest.mark.parametrize(
    ("cores", "asked", "threads", "plan"),
    [
        (2, None, None, PoolPlan(2, 1)),  # this machine: two one-thread workers, measured best (docs/speed.md)
        (1, None, None, PoolPlan(1, 1)),  # one core: one worker (at nice 10, the physics wins)
        (16, None, None, PoolPlan(6, 2)),  # a worker per camera, the 15 cores the physics leaves shared out: 6 × 2
        (8, None, None, PoolPlan(6, 1)),
        (16, 2, None, PoolPlan(2, 7)),  # --render-workers 2: each worker rasterizes on 7 threads
        (4, 10, None, PoolPlan(6, 1)),  # never more workers than cameras
        (2, 1, 2, PoolPlan(1, 2)),  # --render-workers 1 --render-threads 2
    ],
)
def test_workers_fill_the_cores_and_their_threads_those_the_physics_leaves(
    cores: int, asked: int | None, threads: int | None, plan: PoolPlan
) -> None:
    assert plan_pool(6, asked, cores, threads) == plan
