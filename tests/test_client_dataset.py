"""simbot dataset and a camera's `<save>`: frames on disk in one layout (simbot/dataset_format.py), read back
by outside readers (OpenCV for the PNGs, pycocotools for the COCO annotations), their pixels, depths,
intrinsics and poses where the geometry of the fixture room puts them.

The room (tests/fixtures/dataset_room.sdf): a wall's face at x 4.0, two labelled crates' faces at
x 3.0; the rig (tests/fixtures/dataset_rig.sdf), the robot, at the origin with a colour and a depth
camera 0.5 m up looking along +x.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from collections.abc import Iterator
from importlib.metadata import entry_points
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from client_helpers import bus_args, client_process, run_without_terminal
from gl_helpers import NO_EGL, box_body
from pycocotools import mask as coco_mask
from pycocotools.coco import COCO
from server_helpers import REPO, SimServer, left_out, running_server, wait_until

from simbot.bus.intrinsics import Intrinsics
from simbot.dataset_format import DatasetWriter, Shot
from simbot.sim.render import Annotation, CameraSpec, RenderPool
from simbot.sim.render.label_bits import instance_of, label_of, labelled
from simbot.transform import Transform

FIXTURES = REPO / "tests" / "fixtures"
ROOM = FIXTURES / "dataset_room.sdf"
RIG = FIXTURES / "dataset_rig.sdf"
W, H, HFOV = 160, 120, 1.2
FX = (W / 2) / math.tan(HFOV / 2)
CAMERA_IN_RIG = (0.1, 0.0, 0.4)
SPAWN_Z = 0.1
WALL_X, CRATE_X = 4.0, 3.0
CRATES = {5: (3.3, 0.6, 0.4), 9: (3.3, -0.6, 0.4)}
"""label → the centre of its crate, a 0.6 m cube."""
HALF = 0.3
CAMERA_PERIOD_NS = 100_000_000
FIRST_STEP_NS = 1_000_000
EDGE_PX = 2.0
"""The camera model's tolerance: a pixel at an edge may fall either way, and rounding adds one."""
DEPTH_MM = 5
POSE_M = 0.002
RUN_TIMEOUT_S = 180.0
STOP_TIMEOUT_S = 30.0
"""A camera server's SIGTERM to its exit: its render worker stops too, seconds on a loaded machine."""

SPAWN = ("--spawn", "0", "0", str(SPAWN_Z), "0")


@pytest.fixture(scope="module")
def sim() -> Iterator[SimServer]:
    """The room with the rig, for the module; its stop waits for the render worker (slow on a loaded machine)."""
    with running_server(str(ROOM), extra=("--robot", str(RIG), *SPAWN)) as server:
        yield server
        server.stop(timeout=STOP_TIMEOUT_S)


def projected(y: float, z: float, depth: float, cy: float = (H - 1) / 2) -> tuple[float, float]:
    """The pixel (column, row, pixel-centre coordinates) of a point `y` left of and `z` above the
    optical axis, `depth` ahead."""
    return (W - 1) / 2 - FX * y / depth, cy - FX * z / depth


def crate_outline(label: int, camera: tuple[float, float, float]) -> np.ndarray:
    """The image of a crate seen from `camera` (looking along +x): the convex hull of its corners'
    pixels (pixel-edge coordinates, as COCO measures), its silhouette for a box wholly ahead."""
    cx, cy, cz = CRATES[label]
    corners = [
        projected(cy + dy - camera[1], cz + dz - camera[2], cx + dx - camera[0])
        for dx in (-HALF, HALF)
        for dy in (-HALF, HALF)
        for dz in (-HALF, HALF)
    ]
    return cv2.convexHull(np.array(corners, dtype=np.float32) + 0.5)


def crate_box(label: int, camera: tuple[float, float, float]) -> list[float]:
    """COCO's box (x, y, width, height) of a crate's image."""
    points = crate_outline(label, camera).reshape(-1, 2)
    (x0, y0), (x1, y1) = points.min(axis=0), points.max(axis=0)
    return [float(x0), float(y0), float(x1 - x0), float(y1 - y0)]


def read_image(path: Path, flags: int = cv2.IMREAD_COLOR) -> np.ndarray:
    """The image OpenCV reads at `path` (cv2.imread's default: 8-bit BGR)."""
    image = cv2.imread(str(path), flags)
    assert image is not None, f"OpenCV reads no image at {path}"
    return image


def check_area(annotation: dict[str, Any], camera: tuple[float, float, float]) -> None:
    """The mask's area is the silhouette's, give or take the pixels along its outline."""
    outline = crate_outline(annotation["category_id"], camera)
    area, perimeter = cv2.contourArea(outline), cv2.arcLength(outline, closed=True)
    assert abs(annotation["area"] - area) <= EDGE_PX / 2 * perimeter, (annotation["area"], area)


# --- the writer, fed by a real renderer, read by pycocotools


@pytest.fixture(scope="module", params=["gl", "tiny"])
def rendered(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The room's crates and wall rendered (colour and labels) from a camera 0.5 m up at x 0, and
    written as a colour shot and a segmentation shot from the same place."""
    if request.param == "gl" and NO_EGL:
        pytest.skip(NO_EGL)
    grey, red, blue = (0.5, 0.5, 0.5, 1.0), (0.9, 0.1, 0.1, 1.0), (0.1, 0.1, 0.9, 1.0)
    bodies = [
        box_body(
            "wall", (0.1, 10.0, 4.0), grey, True, Transform((WALL_X + 0.05, 0.0, 1.0), (0.0, 0.0, 0.0, 1.0)), (), 1
        ),
        box_body(
            "red",
            (0.6, 0.6, 0.6),
            red,
            True,
            Transform((3.3, 0.6, 0.4), (0.0, 0.0, 0.0, 1.0)),
            (Annotation(label=5),),
            2,
        ),
        box_body(
            "blue",
            (0.6, 0.6, 0.6),
            blue,
            True,
            Transform((3.3, -0.6, 0.4), (0.0, 0.0, 0.0, 1.0)),
            (Annotation(label=9),),
            3,
        ),
    ]
    spec = CameraSpec("cam", W, H, HFOV, 0.1, 10.0, outputs=("color", "labels"))
    with RenderPool(bodies, [spec], workers=1, renderer=str(request.param)) as pool:
        pool.request(0, 1, Transform((0.0, 0.0, 0.5), (0.0, 0.0, 0.0, 1.0)), {})
        (frame,) = pool.collect(wait_for=0, timeout=120.0)
        color, packed = frame["color"].copy(), frame["labels"].copy()
    root = tmp_path_factory.mktemp(f"rendered-{request.param}")
    intrinsics = Intrinsics(W, H, FX, FX, (W - 1) / 2, (H - 1) / 2)
    pose = np.eye(4)
    colour = Shot("cam", 1, intrinsics, pose, color=color)
    seg = Shot("seg", 1, intrinsics, pose, instances=instance_of(packed) * labelled(packed), labels=label_of(packed))
    writer = DatasetWriter(root)
    writer.write([colour, seg])
    writer.close()
    return root


def test_pycocotools_reads_the_masks_where_the_crates_are(rendered: Path) -> None:
    coco = COCO(str(rendered / "annotations.json"))
    assert sorted(coco.getCatIds()) == [5, 9]
    (image,) = coco.loadImgs(coco.getImgIds())
    assert image["file_name"] == "cam/rgb/0000000000000000001.png", "the colour image from the same place"
    assert read_image(rendered / image["file_name"]).shape == (H, W, 3)
    annotations = coco.loadAnns(coco.getAnnIds(imgIds=[image["id"]]))
    assert sorted(a["category_id"] for a in annotations) == [5, 9]
    for annotation in annotations:
        mask = coco.annToMask(annotation)
        expected = crate_box(annotation["category_id"], (0.0, 0.0, 0.5))
        rle = coco.annToRLE(annotation)
        assert mask.sum() == annotation["area"] == coco_mask.area(rle)
        assert np.allclose(coco_mask.toBbox(rle), annotation["bbox"])
        assert np.allclose(annotation["bbox"], expected, atol=EDGE_PX), (annotation["bbox"], expected)
        check_area(annotation, (0.0, 0.0, 0.5))


def test_the_label_maps_hold_what_the_masks_say(rendered: Path) -> None:
    coco = COCO(str(rendered / "annotations.json"))
    labels = read_image(rendered / "seg/labels/0000000000000000001.png", cv2.IMREAD_UNCHANGED)
    instances = read_image(rendered / "seg/instances/0000000000000000001.png", cv2.IMREAD_UNCHANGED)
    assert labels.dtype == np.uint8 and instances.dtype == np.uint16
    for annotation in coco.loadAnns(coco.getAnnIds()):
        mask = coco.annToMask(annotation).astype(bool)
        assert np.array_equal(mask, instances == annotation["instance"])
        assert set(np.unique(labels[mask]).tolist()) == {annotation["category_id"]}
    assert not labels[instances == 0].any(), "the unlabelled wall is background"


# --- the client on a running server


def collect(server: SimServer, *args: str) -> tuple[dict[str, Any], Path]:
    """`simbot dataset` run to its `--count` while the lockstep world steps; its manifest and folder."""
    out = Path(tempfile.mkdtemp(prefix="simbot-dataset-"))
    with client_process(server, "dataset", "--out", str(out), *args) as client:
        wait_until(lambda: (server.step(50), not client.alive())[1], RUN_TIMEOUT_S, "the dataset client to finish")
        assert client.process.returncode == 0, client.stderr()
    return json.loads((out / "manifest.json").read_text()), out


def frame_number(stamp_ns: int) -> int:
    """Which frame of a 10 Hz camera a stamp is: the first step's (1 ms) is 0, then one each tenth of a second."""
    assert stamp_ns == FIRST_STEP_NS or stamp_ns % CAMERA_PERIOD_NS == 0, stamp_ns
    return stamp_ns // CAMERA_PERIOD_NS


def camera_place(server: SimServer) -> np.ndarray:
    """Where the rig's cameras are in the world, from its ground truth in the world state."""
    (x, y, z), quat = server.pose()
    assert abs(quat[3]) > 0.9999, "the rig stands upright, facing +x"
    return np.array([x + CAMERA_IN_RIG[0], y + CAMERA_IN_RIG[1], z + CAMERA_IN_RIG[2]])


def test_sets_of_colour_and_depth_with_intrinsics_and_poses(sim: SimServer) -> None:
    manifest, out = collect(sim, "--cameras", "rig_rgb", "rig_depth", "--every", "2", "--count", "3")
    sets = manifest["sets"]
    assert len(sets) == 3
    stamps = [s["stamp_ns"] for s in sets]
    assert np.diff([frame_number(stamp) for stamp in stamps]).tolist() == [2, 2], (
        f"--every 2 keeps every other set: {stamps}"
    )
    place = camera_place(sim)
    for group in sets:
        frames = {f["camera"]: f for f in group["frames"]}
        assert sorted(frames) == ["rig_depth", "rig_rgb"]
        for frame in frames.values():
            assert frame["stamp_ns"] == group["stamp_ns"]
            k = np.array(frame["intrinsics"]["K"])
            expected_k: list[list[float]] = [[FX, 0, (W - 1) / 2], [0, FX, (H - 1) / 2], [0, 0, 1]]
            assert np.allclose(k, expected_k, atol=1e-6)
            pose = np.array(frame["pose"])
            assert np.allclose(pose[:3, 3], place, atol=POSE_M), (pose[:3, 3], place)
            optical = [[0, 0, 1], [-1, 0, 0], [0, -1, 0]]  # x right, y down, z forward, in the world
            assert np.allclose(pose[:3, :3], optical, atol=1e-3), pose
        colour = read_image(out / frames["rig_rgb"]["files"]["rgb"])[..., ::-1]
        depth = read_image(out / frames["rig_depth"]["files"]["depth"], cv2.IMREAD_UNCHANGED)
        assert colour.shape == (H, W, 3) and depth.dtype == np.uint16
        column, row = (round(v) for v in projected(0.6, 0.4 - place[2], CRATE_X - place[0]))
        red = colour[row, column].astype(int)
        assert red[0] > 2 * max(red[1], red[2]), f"the red crate at ({column}, {row}): {red}"
        centre = int(depth[(H - 1) // 2, (W - 1) // 2])
        assert abs(centre - 1000 * (WALL_X - place[0])) <= DEPTH_MM, centre
        crate = int(depth[row, column])
        assert abs(crate - 1000 * (CRATE_X - place[0])) <= DEPTH_MM, crate


def test_without_cameras_named_every_camera_of_the_robot_is_taken(sim: SimServer) -> None:
    manifest, out = collect(sim, "--count", "1")
    (group,) = manifest["sets"]
    assert sorted(f["camera"] for f in group["frames"]) == ["rig_depth", "rig_rgb"]
    assert all((out / file).is_file() for f in group["frames"] for file in f["files"].values())


def test_an_unwritable_folder_is_one_line_and_exit_2(sim: SimServer, tmp_path: Path) -> None:
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    done = run_without_terminal("dataset", *bus_args(sim), "--out", str(blocker / "sub"), "--cameras", "rig_rgb")
    assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr
    (line,) = done.stderr.strip().splitlines()
    assert "--out" in line and str(blocker / "sub") in line, line


def test_an_unknown_camera_is_one_line_naming_it_and_exit_2(sim: SimServer, tmp_path: Path) -> None:
    args = ("--out", str(tmp_path / "d"), "--cameras", "rig_rgb", "no_such_camera", "--timeout", "2")
    done = run_without_terminal("dataset", *bus_args(sim), *args)
    assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr
    (line,) = done.stderr.strip().splitlines()
    assert "no_such_camera" in line and "rig_rgb" in line, line


# --- <save> in the server


SAVER = """<?xml version="1.0"?>
<sdf version="1.9">
  <model name="saver">
    <static>true</static>
    <pose>0 0 1.5 0 0.3 0</pose>
    <link name="link">{sensors}</link>
  </model>
</sdf>
"""
SAVING_CAMERA = """
      <sensor name="{name}" type="{type}">
        <update_rate>10</update_rate>
        <topic>{name}</topic>
        <camera>
          <horizontal_fov>1.2</horizontal_fov>
          <image><width>160</width><height>120</height></image>
          <segmentation_type>instance</segmentation_type>
          <save enabled="true"><path>{path}</path></save>
        </camera>
      </sensor>"""
PITCH = 0.3
"""The saving cameras look along +x pitched down this much (rad), from 1.5 m up at the origin."""


def saved_run(tmp_path: Path, cameras: dict[str, str]) -> dict[str, Any]:
    """A second of a server whose static cameras (name → SDF type) save to one folder, given
    relative to the server's working directory (the repository, where the test servers run); the
    manifest they wrote, and its folder under "root"."""
    target = tmp_path / "saved"
    path = os.path.relpath(target, REPO)
    sensors = "".join(SAVING_CAMERA.format(name=name, type=kind, path=path) for name, kind in cameras.items())
    addition = tmp_path / "saver.sdf"
    addition.write_text(SAVER.format(sensors=sensors))
    with running_server(str(ROOM), extra=("--robot", "none", "--add", str(addition))) as server:
        server.step(1000)
        server.stop(timeout=STOP_TIMEOUT_S)
    return json.loads((target / "manifest.json").read_text()) | {"root": target}


def test_save_writes_every_frame_in_the_layout(tmp_path: Path) -> None:
    manifest = saved_run(tmp_path, {"saver": "camera"})
    target = manifest["root"]
    frames = [f for s in manifest["sets"] for f in s["frames"]]
    assert [frame_number(f["stamp_ns"]) for f in frames] == list(range(11)), "the first step's, then ten over a second"
    for frame in frames:
        assert frame["camera"] == "saver"
        assert read_image(target / frame["files"]["rgb"]).shape == (H, W, 3)
        pose = np.array(frame["pose"])
        assert np.allclose(pose[:3, 3], [0, 0, 1.5], atol=1e-6)
        forward = [math.cos(PITCH), 0.0, -math.sin(PITCH)]
        assert np.allclose(pose[:3, 2], forward, atol=1e-6), "the optical z axis along the pitched-down view"
    assert json.loads((target / "annotations.json").read_text())["images"] == [], "a colour camera annotates nothing"


def test_save_to_a_folder_that_cannot_be_made_is_one_line_and_the_world_runs(tmp_path: Path) -> None:
    """As any sensor with bad parameters: that camera is left out, with one line naming it and the element."""
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    addition = tmp_path / "saver.sdf"
    camera = SAVING_CAMERA.format(name="saver", type="camera", path=blocker / "sub")
    addition.write_text(SAVER.format(sensors=camera))
    (line,) = left_out(str(ROOM), "dataset_room", "--robot", "none", "--add", str(addition))
    assert "sensor saver: <camera><save><path>" in line and str(blocker / "sub") in line, line


# --- segmentation and boxes (the cameras of branch seg)


def _registered(sensor: str) -> bool:
    return any(e.name == sensor for e in entry_points(group="simbot.sensors"))


@pytest.mark.skipif(
    not (_registered("segmentation") and _registered("boundingbox_camera")),
    reason="the segmentation and bounding-box cameras (branch seg) are not registered in simbot.sensors yet",
)
def test_masks_and_boxes_from_the_segmentation_and_box_cameras(tmp_path: Path) -> None:
    rig = tmp_path / "rig.sdf"
    extra = """
      <sensor name="seg" type="segmentation">
        <pose>0.1 0 0.4 0 0 0</pose><update_rate>10</update_rate><topic>rig_seg</topic>
        <camera><segmentation_type>instance</segmentation_type><horizontal_fov>1.2</horizontal_fov>
          <image><width>160</width><height>120</height></image><clip><near>0.1</near><far>10</far></clip></camera>
      </sensor>
      <sensor name="boxes" type="boundingbox_camera">
        <pose>0.1 0 0.4 0 0 0</pose><update_rate>10</update_rate><topic>rig_boxes</topic>
        <camera><box_type>2d</box_type><horizontal_fov>1.2</horizontal_fov>
          <image><width>160</width><height>120</height></image><clip><near>0.1</near><far>10</far></clip></camera>
      </sensor>
    </link>"""
    rig.write_text(RIG.read_text().replace("</link>", extra, 1))
    with running_server(str(ROOM), extra=("--robot", str(rig), *SPAWN)) as server:
        manifest, out = collect(server, "--cameras", "rig_rgb", "rig_seg", "rig_boxes", "--count", "2")
        place = camera_place(server)
        server.stop(timeout=STOP_TIMEOUT_S)
    coco = COCO(str(out / "annotations.json"))
    assert len(manifest["sets"]) == 2
    images = coco.loadImgs(coco.getImgIds())
    assert sorted(i["camera"] for i in images) == ["rig_boxes", "rig_boxes", "rig_seg", "rig_seg"]
    for image in images:
        assert image["file_name"].startswith("rig_rgb/rgb/"), "masks and boxes come with the colour image beside them"
        annotations = coco.loadAnns(coco.getAnnIds(imgIds=[image["id"]]))
        assert sorted(a["category_id"] for a in annotations) == [5, 9], annotations
        assert all(("segmentation" in a) == (image["camera"] == "rig_seg") for a in annotations)
        for annotation in annotations:
            expected = crate_box(annotation["category_id"], tuple(place))
            assert np.allclose(annotation["bbox"], expected, atol=EDGE_PX), (image["camera"], annotation, expected)
            if "segmentation" in annotation:
                assert coco.annToMask(annotation).sum() == annotation["area"]
                check_area(annotation, tuple(place))


@pytest.mark.skipif(not _registered("segmentation"), reason="the segmentation camera (branch seg) is not registered")
def test_save_of_a_segmentation_camera_beside_a_colour_one(tmp_path: Path) -> None:
    """Two cameras saving to one folder share its manifest, a set per stamp; the segmentation
    camera's frames give COCO masks of both crates, shown by the colour camera's images."""
    manifest = saved_run(tmp_path, {"saver": "camera", "saver_seg": "segmentation"})
    target = manifest["root"]
    assert len(manifest["sets"]) == 11
    for group in manifest["sets"]:
        assert sorted(f["camera"] for f in group["frames"]) == ["saver", "saver_seg"]
    coco = COCO(str(target / "annotations.json"))
    images = coco.loadImgs(coco.getImgIds())
    assert len(images) == 11 and all(i["file_name"].startswith("saver/rgb/") for i in images)
    for image in images:
        annotations = coco.loadAnns(coco.getAnnIds(imgIds=[image["id"]]))
        assert sorted(a["category_id"] for a in annotations) == [5, 9]
        labels = read_image(target / "saver_seg" / "labels" / Path(image["file_name"]).name, cv2.IMREAD_UNCHANGED)
        for annotation in annotations:
            mask = coco.annToMask(annotation).astype(bool)
            assert mask.sum() == annotation["area"] > 0
            assert set(np.unique(labels[mask]).tolist()) == {annotation["category_id"]}
