"""Actors and the running world: created and removed through world control, and walking into the tug.

The empty world with the Flexley Tug at its default spawn (−2.5, 0, 0.1), in lockstep. An actor
created with an SDF whose root is an `<actor>` enters between two steps and follows its script on
the world's clock; removed, it leaves the world state. Walking through the tug's place, the actor
(kinematic: infinite mass, its script goes on whatever it meets, as Gazebo's actors do) pushes the
tug out of its way: the tug ends beside the actor, its proxy's radius plus the tug's half width
from the actor's axis, upright, and the server steps on.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import pytest
from server_helpers import REPO, SimServer, running_server

from simbot.bus import messages
from simbot.transform import quaternion_to_matrix

TUG_X = -2.5
PROXY_RADIUS, TUG_HALF_WIDTH = 0.25, 0.25
CROSSER = """<?xml version="1.0"?>
<sdf version="1.9">
  <actor name="crosser">
    <pose>-2.5 0 1 0 0 0</pose>
    <skin><filename>not_shipped_person.dae</filename></skin>
    <script>
      <loop>false</loop>
      <trajectory id="0" type="walk">
        <waypoint><time>0</time><pose>0 -3 0 0 0 1.5708</pose></waypoint>
        <waypoint><time>6</time><pose>0 3 0 0 0 1.5708</pose></waypoint>
      </trajectory>
    </script>
  </actor>
</sdf>
"""


@pytest.fixture(scope="module")
def sim() -> Iterator[SimServer]:
    with running_server("empty", "lockstep") as server:
        yield server


def _create(sim: SimServer, name: str) -> None:
    reply = sim.call("create", {"sdf": CROSSER, "name": name})
    assert reply == {"ok": True, "name": name}, reply


def test_a_created_actor_walks_on_the_worlds_clock_and_a_removed_one_is_gone(sim: SimServer) -> None:
    start = sim.state()["sim_time"]
    _create(sim, "visitor")
    sim.step(100)
    (x, y, z), _ = sim.pose("visitor")
    s = (start + 0.1) / 6
    assert (x, z) == pytest.approx((TUG_X, 1.0), abs=0.01)
    assert y == pytest.approx(-3 + 6 * (1.5 * s * s - s**3 + 0.5 * s), abs=0.01)
    assert sim.call("remove", {"name": "visitor"}) == {"ok": True, "name": "visitor"}
    assert "visitor" not in sim.state()["models"]
    sim.step(10)


def test_an_actor_walking_through_the_tug_pushes_it_aside(sim: SimServer) -> None:
    assert sim.control({"reset": {"all": True}})["ok"]
    (_, y0, z0), _ = sim.pose()
    _create(sim, "crosser")
    sim.step(7000)  # the script ends at 6 s: the crosser stands at y 3
    (ax, ay, _), _ = sim.pose("crosser")
    (tx, ty, tz), quat = sim.pose()
    assert (ax, ay) == pytest.approx((TUG_X, 3.0), abs=0.01)
    assert ty - ay == pytest.approx(PROXY_RADIUS + TUG_HALF_WIDTH, abs=0.05), f"the tug is at y {ty}"
    assert abs(tx - TUG_X) < 0.1 and abs(tz - z0) < 0.01, f"the tug left its lane or the floor: {tx, ty, tz}"
    up = quaternion_to_matrix(quat)[2, 2]
    assert math.degrees(math.acos(min(1.0, up))) < 2.0, "the tug tipped"
    assert y0 == pytest.approx(0.0, abs=0.01)
    sim.step(100)


def test_the_worker_spawned_with_a_pose_walks_its_beat_from_there(sim: SimServer) -> None:
    """worlds/models/worker, created from its file at (0, 4, 1) turned to +y: its 4 m beat runs along +y
    (half way out at 2 s of its 10 s round: the beat's middle waypoint is at 2 s on a straight stretch)."""
    assert sim.control({"reset": {"all": True}})["ok"]
    path = str(REPO / "worlds" / "models" / "worker" / "model.sdf")
    pose = {
        "position": {"x": 0.0, "y": 4.0, "z": 1.0},
        "orientation": {"z": math.sin(math.pi / 4), "w": math.cos(math.pi / 4)},
    }
    assert sim.call("create", {"sdf_filename": path, "name": "alice", "pose": pose}) == {"ok": True, "name": "alice"}
    sim.step(2000)
    (x, y, z), _ = sim.pose("alice")
    assert (x, y, z) == pytest.approx((0.0, 6.0, 1.0), abs=0.01)


STANDING_WORKER = """<?xml version="1.0"?>
<sdf version="1.9">
  <actor name="bob">
    <pose>1.5 0 1 0 0 0</pose>
    <skin><filename>model://worker/meshes/worker.dae</filename></skin>
  </actor>
</sdf>
"""
CAMERA_X, FX = TUG_X + 1.0, 320 / math.tan(2.0944 / 2)
"""The tug's front camera (1.0 m ahead of its frame, 120° wide at 640 px)."""
VEST_BACK_X, VEST_WIDTH = 1.5 - 0.12, 0.40


def _yellow(image: np.ndarray) -> np.ndarray:
    """The worker's high-visibility vest, lit or in shade: red and green alike, blue far below them."""
    r, g, b = (image[..., i].astype(int) for i in range(3))
    return (r > 50) & (g > 50) & (abs(r - g) < 0.25 * np.maximum(r, g)) & (b < 0.35 * np.minimum(r, g))


def test_the_front_camera_sees_the_workers_skin_where_the_projection_puts_it(sim: SimServer) -> None:
    """A worker standing 2.9 m ahead of the tug's front camera, its back to it: the vest's yellow (its
    COLLADA material) stands in the middle of the image, fx · 0.40 / 2.88 = 25.7 px wide, above the
    camera's horizon (the vest is 1.0 to 1.56 m up)."""
    assert sim.control({"reset": {"all": True}})["ok"]
    assert sim.call("create", {"sdf": STANDING_WORKER}) == {"ok": True, "name": "bob"}
    frame = sim.latest({"camera_front": "sensor_msgs/msg/Image"}, chunk=34)["camera_front"]
    vest = _yellow(messages.image_pixels(frame))
    rows = vest.sum(axis=1)
    assert rows.max() > 0, "the front camera shows no yellow"
    row = int(np.argmax(rows))
    columns = np.flatnonzero(vest[row])
    expected = FX * VEST_WIDTH / (VEST_BACK_X - CAMERA_X)
    assert abs(len(columns) - expected) <= 3, f"the vest is {len(columns)} px wide, the projection says {expected:.1f}"
    assert abs((columns[0] + columns[-1]) / 2 - 319.5) <= 2, "the vest is not straight ahead"
    assert row < 240, "the vest shows below the camera's horizon"
    sim.unsubscribe_all()
    assert sim.call("remove", {"name": "bob"})["ok"]
