"""The scene for viewers (simbot/sim/systems/scene_publisher.py) from a real lockstep server of a
fixture room (tests/fixtures/scene_room.sdf): every visual with its pose, size and colour; models
created and removed; a moved model's frame on tf."""

from __future__ import annotations

import math
from typing import Any

from conftest import REPO
from server_helpers import Collector, SimServer, module_server, reset_before_each

from simbot.sim.systems.scene_publisher import SCENE_TF_RATE

WORLD = REPO / "tests" / "fixtures" / "scene_room.sdf"
SCENE_TYPE = "visualization_msgs/msg/MarkerArray"
MM = 1e-3
CUBE, SPHERE, CYLINDER, MESH = 1, 2, 3, 10
STEP_S = 0.001
PERIOD_STEPS = round(1.0 / SCENE_TF_RATE / STEP_S)
YAW_90 = (0.0, 0.0, math.sqrt(0.5), math.sqrt(0.5))

sim = module_server(str(WORLD), extra=("--robot", "none"))
fresh_world = reset_before_each()

# (model, id): frame, marker type, position, orientation (x, y, z, w), scale, colour; worked out from the SDF
EXPECTED: dict[tuple[str, int], tuple[str, int, tuple[float, ...], tuple[float, ...], tuple[float, ...], Any]] = {
    ("ground_plane", 0): ("world", CUBE, (0, 0, 0), (0, 0, 0, 1), (40, 40, 0.001), (0.5, 0.5, 0.5, 1)),
    ("north_wall", 0): ("world", CUBE, (0, 5, 1), (0, 0, 0, 1), (10, 0.2, 2), (0.9, 0.8, 0.1, 1)),
    # the link 0.5 m along the model's x, which the model's yaw of 90 deg turns onto world y
    ("east_wall", 0): ("world", CUBE, (5, 0.5, 0.5), YAW_90, (8, 0.2, 1), (0.1, 0.7, 0.2, 1)),
    # 1 m along the link's x (world y) and 0.5 up; ambient alone gives the colour, transparency 0.5 the alpha
    ("east_wall", 1): ("world", CUBE, (5, 1.5, 1.5), YAW_90, (6, 0.2, 1), (0.1, 0.2, 0.9, 0.5)),
    ("post", 0): ("world", CYLINDER, (-3, -3, 0.75), (0, 0, 0, 1), (0.3, 0.3, 1.5), (1, 1, 1, 1)),
    ("ball", 0): ("world", SPHERE, (-3, 3, 0.4), (0, 0, 0, 1), (0.8, 0.8, 0.8), (1, 1, 1, 1)),
    # roll 90 deg then yaw 0.5 rad
    ("wheel", 0): (
        "world",
        MESH,
        (3, -3, 0.2),
        (
            math.sin(math.pi / 4) * math.cos(0.25),
            math.sin(math.pi / 4) * math.sin(0.25),
            math.cos(math.pi / 4) * math.sin(0.25),
            math.cos(math.pi / 4) * math.cos(0.25),
        ),
        (0.5, 0.5, 0.5),
        (0, 0, 0, 0),
    ),
    # a dynamic model: in its link's frame, which tf places
    ("crate", 0): (
        "scene/crate",
        CUBE,
        (0, 0, 0.1),
        (0, 0, math.sin(0.15), math.cos(0.15)),
        (0.5, 0.5, 0.3),
        (0.9, 0.6, 0.1, 1),
    ),
}

BLOCK = """<?xml version="1.0"?>
<sdf version="1.9">
  <model name="block">
    <static>true</static>
    <link name="link">
      <visual name="visual"><geometry><box><size>0.3 0.4 0.5</size></box></geometry></visual>
    </link>
  </model>
</sdf>"""


def _scene(sim: SimServer, condition: Any = lambda markers: True) -> dict[tuple[str, int], Any]:
    """The markers of the first scene message (from now, latched) that meets `condition`, by (model, id)."""
    scenes: Collector[Any] = sim.subscribe("scene", SCENE_TYPE, latched=True)
    sim.step(1)  # a change is published after the step that follows it

    def by_key(msg: Any) -> dict[tuple[str, int], Any]:
        return {(m.ns, m.id): m for m in msg.markers if m.action == 0}

    found = scenes.wait_for(lambda msgs: any(condition(by_key(m)) for m in msgs), timeout=30.0, what="the scene")
    return next(by_key(msg) for msg in reversed(found) if condition(by_key(msg)))


def _close(actual: Any, expected: tuple[float, ...], tolerance: float) -> bool:
    return all(abs(a - e) <= tolerance for a, e in zip(actual, expected))


def _same_turn(q: tuple[float, ...], expected: tuple[float, ...]) -> bool:
    """Equal rotations (q and -q are one), within a 1 mm chord at 1 m."""
    dot = abs(sum(a * b for a, b in zip(q, expected)))
    return 2 * math.acos(min(1.0, dot)) <= MM


def test_the_scene_holds_every_visual_with_its_pose_size_and_colour(sim: SimServer) -> None:
    markers = _scene(sim)
    assert markers.keys() == EXPECTED.keys()
    for key, (frame, kind, xyz, quat, scale, rgba) in EXPECTED.items():
        m = markers[key]
        p, q, s, c = m.pose.position, m.pose.orientation, m.scale, m.color
        assert (m.header.frame_id, m.type) == (frame, kind), key
        assert _close((p.x, p.y, p.z), xyz, MM), (key, p)
        assert _same_turn((q.x, q.y, q.z, q.w), quat), (key, q)
        assert _close((s.x, s.y, s.z), scale, MM), (key, s)
        assert _close((c.r, c.g, c.b, c.a), rgba, 1e-6), (key, c)


def test_a_mesh_is_named_by_a_uri_the_viewer_can_load(sim: SimServer) -> None:
    wheel = _scene(sim)[("wheel", 0)]
    assert wheel.mesh_resource == (REPO / "meshes" / "wheel.stl").resolve().as_uri()
    assert wheel.mesh_use_embedded_materials  # no material of its own: the file's


def test_a_created_model_appears_and_a_removed_one_leaves(sim: SimServer) -> None:
    pose = {"position": {"x": -1.0, "y": -2.0, "z": 0.25}, "orientation": {"w": 1.0}}
    assert sim.call("create", {"sdf": BLOCK, "name": "block", "pose": pose})["ok"]
    block = _scene(sim, lambda markers: ("block", 0) in markers)[("block", 0)]
    p, s = block.pose.position, block.scale
    assert _close((p.x, p.y, p.z), (-1.0, -2.0, 0.25), MM) and _close((s.x, s.y, s.z), (0.3, 0.4, 0.5), MM)
    assert sim.call("remove", {"name": "block"})["ok"]
    left = _scene(sim, lambda markers: ("block", 0) not in markers)
    assert left.keys() == EXPECTED.keys()


def _crate_places(msgs: list[Any]) -> list[Any]:
    return [
        t.transform.translation
        for msg in msgs
        for t in msg.transforms
        if t.child_frame_id == "scene/crate" and t.header.frame_id == "world"
    ]


def test_a_moved_model_s_frame_follows_within_one_period(sim: SimServer) -> None:
    frames: Collector[Any] = sim.subscribe("tf", "tf2_msgs/msg/TFMessage")
    target = (-2.0, 1.0, 0.25)
    assert sim.call("set_pose", {"name": "crate", "position": dict(zip("xyz", target))})["ok"]
    sim.step(PERIOD_STEPS)  # the world stands still after these: only they can have sent the crate's new place

    def there(msgs: list[Any]) -> bool:
        return any(_close((p.x, p.y), target[:2], MM) and abs(p.z - target[2]) < 5 * MM for p in _crate_places(msgs))

    frames.wait_for(there, timeout=10.0, what="the crate's frame at its new place")


def test_the_scene_is_latched(sim: SimServer) -> None:
    """A plain `get` (z_get) is answered with the whole scene, as the other latched keys are."""
    _scene(sim)  # published once (whichever test of the module runs first)
    replies = sim.node.session.get(sim.any_type_key("scene"), timeout=10.0)
    payloads = [r.ok.payload.to_bytes() for r in replies if r.ok is not None]
    assert payloads and len(payloads[0]) > 1000
