"""The Label system and the segmentation camera through the real server, in the labelled room
(tests/room_helpers.py): each label where the geometry puts it, by the pinhole model.

The room: two 1 m crates of label 10 (a Label on each model) at x 5, y ±1.2; a pillar at x 7 whose
visual carries label 30, its right half (y < 0) hidden behind an unlabelled screen at x 4; a bin of
label 40 included from a model file (the Label in the `<include>`); a shelf of label 50 up at
z 2.6 whose nested drawer has a face of its own label 60 and a rim the shelf's label covers. Pixels
are sampled at least 2 px inside each face, so the test holds with either renderer's rasterisation.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from gz_examples import gazebo_example
from room_helpers import CX, CY, FX, ROOM, H, W, pixel, room, runs_without
from server_helpers import running_server, stamp_ns

from simbot.bus import messages
from simbot.sim.render.segmentation import colour_of

IMAGE = "sensor_msgs/msg/Image"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
KEYS = {
    "semantic/labels_map": IMAGE,
    "semantic/colored_map": IMAGE,
    "semantic/camera_info": CAMERA_INFO,
    "panoptic/labels_map": IMAGE,
    "panoptic/colored_map": IMAGE,
}
SAMPLES = {
    "crate_left": (pixel(4.5, 1.2), 10),
    "crate_right": (pixel(4.5, -1.2), 10),
    "pillar's seen half": (pixel(6.8, 0.25), 30),
    "pillar behind the screen": (pixel(6.8, -0.25), 0),
    "bin (label in the include)": (pixel(5.7, -3.2), 40),
    "shelf": (pixel(8.7, 3.0, 2.6), 50),
    "drawer face (its visual's own label)": (pixel(8.7, 2.1, 2.6), 60),
    "drawer rim (the shelf's label covers the nested model)": (pixel(8.7, 1.2, 2.6), 50),
    "sky": ((CX, 3.0), 0),
    "floor": ((CX, H - 3.0), 0),
}
"""(u, v) in the image and the label the geometry puts there."""


@pytest.fixture(scope="module", params=["gl", "tiny"])
def maps(request: pytest.FixtureRequest) -> Iterator[dict[str, Any]]:
    """One frame of each map (and camera_info) of the room's segmentation cameras."""
    for sim in room(str(request.param)):
        frames = sim.latest(KEYS, chunk=34)
    yield frames


def _pixels(maps: dict[str, Any], key: str) -> np.ndarray:
    return messages.image_pixels(maps[key])


def _at(image: np.ndarray, uv: tuple[float, float]) -> np.ndarray:
    return image[round(uv[1]), round(uv[0])]


@pytest.mark.parametrize("what", SAMPLES)
def test_semantic_labels_lie_where_the_geometry_puts_them(maps: dict[str, Any], what: str) -> None:
    uv, label = SAMPLES[what]
    labels = _pixels(maps, "semantic/labels_map")
    assert labels.shape == (H, W, 3) and maps["semantic/labels_map"].encoding == "rgb8"
    assert list(_at(labels, uv)) == [label] * 3, f"{what} at {uv}: {_at(labels, uv)}, expected label {label}"


def test_each_crate_fills_its_projected_outline(maps: dict[str, Any]) -> None:
    """Label 10 covers each crate's near face (inset 1 px), and its columns end where the corners
    project: the outer edge of the near face, the inner edge of the far face (its side is seen)."""
    labels = _pixels(maps, "semantic/labels_map")[..., 0]
    for y, side in ((1.2, 1.0), (-1.2, -1.0)):
        (u0, v0), (u1, v1) = sorted([pixel(4.5, y + 0.5, 1.5), pixel(4.5, y - 0.5, 0.5)])
        face = labels[math.ceil(min(v0, v1)) + 1 : math.floor(max(v0, v1)), math.ceil(u0) + 1 : math.floor(u1)]
        assert face.size and (face == 10).all(), f"crate at y {y}: labels {np.unique(face)} on its face"
        half = labels[:, : round(CX)] if side > 0 else labels[:, round(CX) :]
        columns = np.flatnonzero((half == 10).any(axis=0)) + (0 if side > 0 else round(CX))
        outer, inner = pixel(4.5, y + side * 0.5)[0], pixel(5.5, y - side * 0.5)[0]
        seen = (columns.min(), columns.max()) if side > 0 else (columns.max(), columns.min())
        assert abs(seen[0] - outer) <= 1.5 and abs(seen[1] - inner) <= 1.5, (
            f"crate at y {y} spans columns {columns.min()}..{columns.max()}, the corners say {outer:.1f}, {inner:.1f}"
        )


def test_instances_two_crates_of_one_label_differ_in_count(maps: dict[str, Any]) -> None:
    """Panoptic: [count & 0xFF, count >> 8, label]; each crate one count, the two counts different."""
    labels = _pixels(maps, "panoptic/labels_map").astype(int)
    counts = []
    for name, (x, y) in {"crate_left": (4.5, 1.2), "crate_right": (4.5, -1.2)}.items():
        (u0, v0), (u1, v1) = pixel(x, y + 0.4, 1.4), pixel(x, y - 0.4, 0.6)
        face = labels[math.ceil(v0) : math.floor(v1), math.ceil(u0) : math.floor(u1)]
        assert (face[..., 2] == 10).all(), f"{name}: label bytes {np.unique(face[..., 2])}"
        count = face[..., 0] | face[..., 1] << 8
        assert len(np.unique(count)) == 1 and count.flat[0] > 0, f"{name}: counts {np.unique(count)}"
        counts.append(int(count.flat[0]))
    assert counts[0] != counts[1], f"both crates have instance count {counts[0]}"
    semantic = _pixels(maps, "semantic/labels_map")[..., 0]
    assert ((labels[..., 2] == 0) == (semantic == 0)).all(), "the panoptic and semantic maps disagree on background"


def test_colored_maps_one_colour_per_label_or_per_instance_background_black(maps: dict[str, Any]) -> None:
    semantic, panoptic = _pixels(maps, "semantic/colored_map"), _pixels(maps, "panoptic/colored_map")
    left, right = pixel(4.5, 1.2), pixel(4.5, -1.2)
    expected = colour_of(np.array([[10 << 16]], dtype=np.uint32))[0, 0]
    assert list(_at(semantic, left)) == list(_at(semantic, right)) == list(expected), "semantic: one colour per label"
    assert list(_at(panoptic, left)) != list(_at(panoptic, right)), "panoptic: the two crates share a colour"
    labels = _pixels(maps, "semantic/labels_map")[..., 0]
    for name, image in (("semantic", semantic), ("panoptic", panoptic)):
        assert not image[labels == 0].any(), f"{name}: background is not black"
        assert image[labels != 0].max(axis=-1).min() >= 32, f"{name}: an object is drawn (nearly) black"


def test_camera_info_beside_the_maps_under_their_stamp(maps: dict[str, Any]) -> None:
    info, labels = maps["semantic/camera_info"], maps["semantic/labels_map"]
    assert (info.width, info.height) == (W, H)
    assert np.allclose(info.k, [FX, 0, CX, 0, FX, CY, 0, 0, 1], atol=1e-6)
    assert stamp_ns(info) == stamp_ns(labels) > 0
    assert info.header.frame_id == labels.header.frame_id == "semantic_eye_optical_frame"


def test_bad_segmentation_type_leaves_that_camera_out_and_the_rest_runs(tmp_path: Path) -> None:
    world = tmp_path / "bad.sdf"
    world.write_text(Path(ROOM).read_text().replace("<segmentation_type>semantic<", "<segmentation_type>stereo<"))
    errors, got = runs_without(world, {"panoptic/labels_map": IMAGE})
    expected = "sensor semantic_eye: <camera><segmentation_type> must be semantic, instance or panoptic, got 'stereo'"
    assert len(errors) == 1 and expected in errors[0], errors
    assert _at(messages.image_pixels(got["panoptic/labels_map"]), pixel(4.5, 1.2))[2] == 10


@pytest.mark.parametrize(
    ("label", "message"),
    [("300", "<label> must be 0..255, got 300"), ("ten", "<label> must be an integer 0..255, got 'ten'")],
)
def test_bad_label_is_one_line_naming_plugin_and_element_and_the_rest_runs(
    tmp_path: Path, label: str, message: str
) -> None:
    """The pillar's Label is left out (the pillar is unlabelled: background); the crates keep theirs."""
    world = tmp_path / "bad.sdf"
    world.write_text(Path(ROOM).read_text().replace("<label>30</label>", f"<label>{label}</label>"))
    errors, got = runs_without(world, {"semantic/labels_map": IMAGE})
    assert len(errors) == 1 and f"Label on pillar visual visual: {message}" in errors[0], errors
    labels = messages.image_pixels(got["semantic/labels_map"])
    assert _at(labels, pixel(6.8, 0.25))[0] == 0 and _at(labels, pixel(4.5, 1.2))[0] == 10


def test_gazebo_segmentation_example_publishes_on_its_keys(tmp_path: Path) -> None:
    """gz-sim's segmentation_camera.sdf (its Fuel models removed: nothing labelled is left) publishes
    both maps of both cameras on the keys its GUI subscribes to, all background."""
    world = gazebo_example("segmentation_camera.sdf", tmp_path)
    keys = {f"{kind}/{name}": IMAGE for kind in ("semantic", "panoptic") for name in ("labels_map", "colored_map")}
    with running_server(str(world), "lockstep", cwd=tmp_path, world_name="shapes", extra=["--robot", "none"]) as sim:
        got = sim.latest(keys, chunk=34)
    for key, image in got.items():
        assert (image.width, image.height, image.encoding) == (800, 600, "rgb8"), key
        assert not messages.image_pixels(image).any(), f"{key}: something labelled in a world with no labels left"
