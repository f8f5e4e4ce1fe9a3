"""Write `layouts/simbot.json`, the Foxglove layout for `simbot foxglove`, with the SDK's `foxglove.layouts`.

Built in code so that every panel and setting is checked against the SDK's layout types, and the
topic and frame names come from the code that publishes them. The layout opens on the tug:

- a 3D panel whose fixed frame is `odom` (the world stays put while the robot drives) and whose
  view follows `base_link` from behind and above, turning with it: the world's visuals as markers
  (the scene publisher's `/scene`: floor, walls, racks, the trolley, the people and the tug
  itself; the server places `world` in `odom`), the merger's 360° scan over them, and the robot's
  frames as small axes without labels (labels of a dozen frames a few centimetres apart pile up);
- beside it, the front camera over the stitcher's panorama (two Image panels);
- under the 3D panel, the TransformTree panel: every frame by name.

The app subscribes only to what the panels show: of the cameras, the front one (the stitcher
subscribes to all six itself). The output is deterministic (a test compares it with the committed file).

    .venv/bin/python layouts/make_layout.py [--out FILE]     (`make layout`)
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Literal

import foxglove.layouts as fl

from simbot.clients.merger import MERGED_TOPIC, TARGET_FRAME
from simbot.clients.stitcher import CAMERAS, IMAGE_TOPIC
from simbot.sim.systems.scene_publisher import SCENE_TOPIC

FIXED_FRAME = "odom"
FRONT_CAMERA = "/" + CAMERAS[0]
PANORAMA = "/" + IMAGE_TOPIC
SCAN = "/" + MERGED_TOPIC
SCENE = "/" + SCENE_TOPIC
BEHIND_AND_ABOVE = fl.ThreeDeeCameraState(
    perspective=True, distance=12.0, phi=60.0, theta_offset=90.0, target_offset=(3.5, 0.0, 0.0), fovy=45.0
)
"""12 m from a point 3.5 m ahead of base_link, 60° from the vertical, on base_link's -x side
(theta_offset 90°): the tug low in the middle, the trolley and the aisle ahead, the pillars either side."""


def tug_panel() -> fl.ThreeDeePanel:
    """The scene, the merged scan and the robot's frames, seen from behind and above base_link."""
    scene = fl.BaseRendererSceneSettings(
        # the robot's STL meshes are z-up, as in ROS; the app's default for STL is y-up
        mesh_up_axis="z_up",
        transforms=fl.BaseRendererTransforms(visible=True, show_label=False, axis_size=0.15, line_width=0.0),
    )
    topics = {
        SCENE: fl.BaseRendererRosMarkerTopicSettings(visible=True, show_outlines=False),
        # a colour field named, though the colour is flat: without one, Studio 1.48 (the browser
        # test's) colours by intensity, which the merged scan leaves empty, and draws nothing
        SCAN: fl.BaseRendererLaserScanTopicSettings(
            visible=True, point_size=6.0, color_mode="flat", flat_color="#ff3b30", color_field="range"
        ),
    }
    config = fl.ThreeDeeConfig(
        fixed_frame=FIXED_FRAME,
        follow_tf=TARGET_FRAME,
        follow_mode="follow-pose",
        camera_state=BEHIND_AND_ABOVE,
        scene=scene,
        topics=topics,
    )
    return fl.ThreeDeePanel(title="Tug", config=config)


def image_panel(title: str, topic: str) -> fl.ImagePanel:
    """An Image panel on one image topic."""
    return fl.ImagePanel(title=title, config=fl.ImageConfig(image_mode=fl.ImageModeConfig(image_topic=topic)))


def split(direction: Literal["row", "column"], *items: tuple[float, fl.Content]) -> fl.SplitContainer:
    """Panels side by side (`row`) or one over another (`column`), each given as (proportion, panel)."""
    return fl.SplitContainer(
        direction=direction, items=[fl.SplitItem(proportion=share, content=content) for share, content in items]
    )


def layout() -> fl.Layout:
    """The 3D panel over the transform tree on the left; the front camera over the panorama on the right."""
    tug = split("column", (4, tug_panel()), (1, fl.TransformTreePanel()))
    images = split("column", (3, image_panel("Front camera", FRONT_CAMERA)), (1, image_panel("Panorama", PANORAMA)))
    return fl.Layout(content=split("row", (3, tug), (2, images)))


def render() -> str:
    """The layout as the committed file holds it: indented JSON, keys in the SDK's order, a final newline."""
    return json.dumps(json.loads(layout().to_json()), indent=2, ensure_ascii=False) + "\n"


def main() -> None:
    """Write the layout to --out (default: simbot.json beside this script)."""
    parser = argparse.ArgumentParser(description="Write simbot's Foxglove layout.")
    parser.add_argument("--out", type=Path, default=Path(__file__).resolve().with_name("simbot.json"))
    out: Path = parser.parse_args().out
    out.write_text(render(), encoding="utf-8")


if __name__ == "__main__":
    main()
