"""Write `layouts/simbot.json`, the Foxglove layout for `simbot foxglove`, with the SDK's `foxglove.layouts`.

Built in code so that every panel and setting is checked against the SDK's layout types, and the
topic and frame names come from the clients that publish them. The layout shows:

- the stitcher's panorama (an Image panel);
- the merger's 360° scan from above over the world's scene (`/scene`, the walls, racks and
  trolley as markers; the server places `world` in `odom`), in a 3D panel whose fixed frame is
  `odom` (the scan stays where the world is while the robot drives) and whose view follows
  `base_link`, with the robot's collision shapes from `robot_description`;
- the robot's frames: a 3D panel with every tf frame, labelled, and the TransformTree panel.

The app subscribes only to what the panels show, so the cameras render only for the stitcher.
The output is deterministic (a test compares it with the committed file).

    .venv/bin/python layouts/make_layout.py [--out FILE]     (`make layout`)
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import foxglove.layouts as fl

from simbot.clients.merger import MERGED_TOPIC, TARGET_FRAME
from simbot.clients.stitcher import IMAGE_TOPIC

FIXED_FRAME = "odom"
PANORAMA = "/" + IMAGE_TOPIC
SCAN = "/" + MERGED_TOPIC
ROBOT_DESCRIPTION = "/robot_description"
SCENE = "/scene"
SCAN_VIEW_M = 14.0
"""How far the scan panel's camera is from base_link: the ±6 m a warehouse aisle shows, with a margin."""


def robot_model(opacity: float) -> fl.BaseRendererUrdfTopicSettings:
    """The robot from `robot_description`, drawn by its collision shapes."""
    return fl.BaseRendererUrdfTopicSettings(
        visible=True, display_mode="collision", fallback_color="#e8a33d", opacity=opacity
    )


def panorama_panel() -> fl.ImagePanel:
    return fl.ImagePanel(title="Panorama", config=fl.ImageConfig(image_mode=fl.ImageModeConfig(image_topic=PANORAMA)))


def following_panel(
    title: str, camera: fl.ThreeDeeCameraState, scene: fl.BaseRendererSceneSettings, **settings: Any
) -> fl.ThreeDeePanel:
    """A 3D panel whose fixed frame is odom and whose view follows base_link's position and heading."""
    config = fl.ThreeDeeConfig(
        fixed_frame=FIXED_FRAME,
        follow_tf=TARGET_FRAME,
        follow_mode="follow-pose",
        camera_state=camera,
        scene=scene,
        **settings,
    )
    return fl.ThreeDeePanel(title=title, config=config)


def scan_panel() -> fl.ThreeDeePanel:
    """The merged scan from above over the scene, in odom, the view following base_link's heading."""
    return following_panel(
        "Merged scan",
        fl.ThreeDeeCameraState(perspective=False, distance=SCAN_VIEW_M, phi=0.0, theta_offset=0.0),
        fl.BaseRendererSceneSettings(transforms=fl.BaseRendererTransforms(visible=False)),
        layers={"grid": fl.BaseRendererGridLayerSettings(frame_id=FIXED_FRAME, size=20.0, divisions=20.0)},
        topics={
            # a colour field named, though the colour is flat: without one, Studio 1.48 (the browser
            # test's) colours by intensity, which the merged scan leaves empty, and draws nothing
            SCAN: fl.BaseRendererLaserScanTopicSettings(
                visible=True, point_size=3.0, color_mode="flat", flat_color="#ff3b30", color_field="range"
            ),
            ROBOT_DESCRIPTION: robot_model(opacity=0.8),
            SCENE: fl.BaseRendererRosMarkerTopicSettings(visible=True, show_outlines=False),
        },
    )


def frames_panel() -> fl.ThreeDeePanel:
    """Every tf frame of the robot, labelled, around base_link."""
    return following_panel(
        "Frames",
        fl.ThreeDeeCameraState(perspective=True, distance=4.0, phi=55.0, theta_offset=45.0),
        fl.BaseRendererSceneSettings(
            transforms=fl.BaseRendererTransforms(visible=True, show_label=True, label_size=0.08, axis_size=0.15)
        ),
        topics={ROBOT_DESCRIPTION: robot_model(opacity=0.3)},
    )


def layout() -> fl.Layout:
    """Panorama over the scan on the left; the frames in 3D over the transform tree on the right."""
    left = fl.SplitContainer(
        direction="column",
        items=[fl.SplitItem(proportion=1, content=panorama_panel()), fl.SplitItem(proportion=2, content=scan_panel())],
    )
    right = fl.SplitContainer(
        direction="column",
        items=[
            fl.SplitItem(proportion=2, content=frames_panel()),
            fl.SplitItem(proportion=1, content=fl.TransformTreePanel()),
        ],
    )
    return fl.Layout(
        content=fl.SplitContainer(
            direction="row", items=[fl.SplitItem(proportion=3, content=left), fl.SplitItem(proportion=2, content=right)]
        )
    )


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
