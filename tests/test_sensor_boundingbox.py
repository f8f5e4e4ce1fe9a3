"""The bounding-box camera through the real server, in the labelled room (tests/room_helpers.py):
box centres and sizes in pixels from the pinhole model (±2 px: a visible box is the extent of pixel
centres, a full one the projection of the corners), occlusion shrinking visible boxes and not full
ones, 3D boxes in the optical frame, and Gazebo's example world on its keys.

Seen from the camera: the crates (label 10) in full; the pillar (label 30) half hidden behind the
unlabelled screen (its left half, y > 0, is seen); the bin (label 40); the shelf and the drawer's
rim (label 50, two bodies) and the drawer's face (label 60).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from gz_examples import gazebo_example
from room_helpers import CX, CY, FX, ROOM, H, W, box_corners, room, runs_without
from server_helpers import running_server, stamp_ns

from simbot.bus import messages
from simbot.transform import quaternion_to_matrix

IMAGE = "sensor_msgs/msg/Image"
BOXES_2D = "vision_msgs/msg/Detection2DArray"
BOXES_3D = "vision_msgs/msg/Detection3DArray"
KEYS = {
    "boxes_visible": BOXES_2D,
    "boxes_full": BOXES_2D,
    "boxes_3d": BOXES_3D,
    "boxes_visible_image": IMAGE,
    "boxes_visible/camera_info": "sensor_msgs/msg/CameraInfo",
}
CRATES = {"crate_left": (5.0, 1.2, 1.0), "crate_right": (5.0, -1.2, 1.0)}
TOLERANCE_PX = 2.0
OPTICAL_FROM_WORLD = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
"""The room's camera looks along +x with z up: world axes in its optical frame (x right, y down, z forward)."""


@pytest.fixture(scope="module", params=["gl", "tiny"])
def boxes(request: pytest.FixtureRequest) -> Iterator[dict[str, Any]]:
    """One message of each of the room's bounding-box cameras' keys."""
    for sim in room(str(request.param)):
        frames = sim.latest(KEYS, chunk=34)
    yield frames


def _extent(corners: list[tuple[float, float]]) -> tuple[float, float, float, float]:
    us, vs = [c[0] for c in corners], [c[1] for c in corners]
    return min(us), min(vs), max(us), max(vs)


def _by_label(message: Any, label: int) -> list[Any]:
    return sorted(
        (d for d in message.detections if d.results[0].hypothesis.class_id == str(label)),
        key=lambda d: d.bbox.center.position.x,
    )


def _box(detection: Any) -> tuple[float, float, float, float]:
    """(u min, v min, u max, v max) of a Detection2D."""
    centre, w, h = detection.bbox.center.position, detection.bbox.size_x, detection.bbox.size_y
    return centre.x - w / 2, centre.y - h / 2, centre.x + w / 2, centre.y + h / 2


def _close(seen: tuple[float, ...], expected: tuple[float, ...], what: str) -> None:
    assert np.allclose(seen, expected, atol=TOLERANCE_PX), (
        f"{what}: box {np.round(seen, 1)}, the camera model says {np.round(expected, 1)}"
    )


@pytest.mark.parametrize("kind", ["boxes_visible", "boxes_full"])
def test_crates_boxes_are_their_projected_corners(boxes: dict[str, Any], kind: str) -> None:
    """Unhidden, visible and full boxes agree: the extent of the eight projected corners; two of label 10."""
    message = boxes[kind]
    assert message.header.frame_id == "visible_eye_optical_frame".replace("visible", kind.split("_")[1])
    crates = _by_label(message, 10)
    assert len(crates) == 2, f"{kind}: {len(crates)} boxes of label 10"
    for detection, name in zip(crates, ("crate_left", "crate_right"), strict=True):
        assert detection.results[0].hypothesis.score == 1.0
        _close(_box(detection), _extent(box_corners(CRATES[name], (1.0, 1.0, 1.0))), f"{kind} {name}")


def test_visible_box_is_what_the_screen_leaves_of_the_pillar_full_box_is_all_of_it(boxes: dict[str, Any]) -> None:
    """The screen hides the pillar's right half (y < 0, u > cx): its visible box ends at the image
    centre, its full box is the whole projected pillar."""
    (visible,), (full,) = _by_label(boxes["boxes_visible"], 30), _by_label(boxes["boxes_full"], 30)
    whole = _extent(box_corners((7.0, 0.0, 1.0), (0.4, 1.0, 1.0)))
    _close(_box(full), whole, "full pillar")
    _close(_box(visible), (whole[0], whole[1], CX, whole[3]), "visible pillar")
    assert _box(full)[2] - _box(visible)[2] > 6.0, "the hidden half is not cut from the visible box"


def test_every_labelled_object_seen_has_one_box(boxes: dict[str, Any]) -> None:
    """The bin (label in its include), the shelf and the drawer's rim (50), the face (60); nothing unlabelled."""
    for kind in ("boxes_visible", "boxes_full", "boxes_3d"):
        labels = sorted(int(d.results[0].hypothesis.class_id) for d in boxes[kind].detections)
        assert labels == [10, 10, 30, 40, 50, 50, 60], f"{kind}: labels {labels}"
    (bin_box,) = _by_label(boxes["boxes_full"], 40)
    _close(_box(bin_box), _extent(box_corners((6.0, -3.2, 1.0), (0.6, 0.6, 0.6))), "full bin")


def test_3d_boxes_lie_in_the_optical_frame(boxes: dict[str, Any]) -> None:
    """Centre, size and orientation of each crate's box, x right, y down, z forward, metres."""
    crates = sorted(_by_label(boxes["boxes_3d"], 10), key=lambda d: d.bbox.center.position.x)
    for detection, name in zip(crates, ("crate_left", "crate_right"), strict=True):
        x, y, z = CRATES[name]
        centre, size, q = detection.bbox.center.position, detection.bbox.size, detection.bbox.center.orientation
        assert np.allclose([centre.x, centre.y, centre.z], OPTICAL_FROM_WORLD @ [x, y, z - 1.0], atol=1e-4), name
        assert np.allclose([size.x, size.y, size.z], [1.0, 1.0, 1.0], atol=1e-4), name
        assert np.allclose(quaternion_to_matrix([q.x, q.y, q.z, q.w]), OPTICAL_FROM_WORLD, atol=1e-4), name
    (pillar,) = _by_label(boxes["boxes_3d"], 30)
    size = pillar.bbox.size
    assert np.allclose([size.x, size.y, size.z], [0.4, 1.0, 1.0], atol=1e-4), "the 3D box is not the whole pillar"


def test_image_shows_the_boxes_in_green_under_the_boxes_stamp(boxes: dict[str, Any]) -> None:
    image, info = boxes["boxes_visible_image"], boxes["boxes_visible/camera_info"]
    assert (image.width, image.height, image.encoding) == (W, H, "rgb8")
    pixels = messages.image_pixels(image)
    u0, v0, u1, v1 = (round(c) for c in _box(_by_label(boxes["boxes_visible"], 10)[0]))
    edge = pixels[v0 : v1 + 1, u0]
    assert (edge == [0, 255, 0]).all(), f"the left edge of crate_left's box is not green: {np.unique(edge, axis=0)}"
    assert np.allclose(info.k, [FX, 0, CX, 0, FX, CY, 0, 0, 1], atol=1e-6)
    assert stamp_ns(image) == stamp_ns(info) == stamp_ns(boxes["boxes_visible"]) > 0


def test_bad_box_type_leaves_that_camera_out_and_the_rest_runs(tmp_path: Path) -> None:
    world = tmp_path / "bad.sdf"
    world.write_text(Path(ROOM).read_text().replace("<box_type>full_2d<", "<box_type>full<"))
    errors, got = runs_without(world, {"boxes_visible": BOXES_2D})
    assert len(errors) == 1, errors
    assert "sensor full_eye: <camera><box_type> must be one of" in errors[0] and "got 'full'" in errors[0]
    assert len(_by_label(got["boxes_visible"], 10)) == 2


def test_gazebo_boundingbox_example_publishes_on_its_keys(tmp_path: Path) -> None:
    """gz-sim's boundingbox_camera.sdf: its three cameras (full, visible, 3d) see its two boxes of
    label 10 and its sphere of label 20 (the Fuel model of label 30 is removed), images beside."""
    world = gazebo_example("boundingbox_camera.sdf", tmp_path)
    keys = {"boxes_full_2d": BOXES_2D, "boxes_visible_2d": BOXES_2D, "boxes_3d": BOXES_3D, "boxes_full_2d_image": IMAGE}
    with running_server(
        str(world), "lockstep", cwd=tmp_path, world_name="boundingbox_sensor", extra=["--robot", "none"]
    ) as sim:
        got = sim.latest(keys, chunk=34)
    for key in ("boxes_full_2d", "boxes_visible_2d", "boxes_3d"):
        labels = sorted(d.results[0].hypothesis.class_id for d in got[key].detections)
        assert labels == ["10", "10", "20"], f"{key}: {labels}"
    assert (got["boxes_full_2d_image"].width, got["boxes_full_2d_image"].height) == (800, 600)
