"""`<actor>` read as Gazebo reads it (simbot.description.actor_scripts), and a bad script as one line.

Each bad script is run through `simbot describe` as a user would: exit 2, one line on standard
error naming the file, the line, the element and the actor, no traceback. A skin that cannot be
found is one warning naming its file, and the actor is drawn as its proxy.
"""

from __future__ import annotations

import logging
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import REPO, run_cli
from golden_helpers import Tolerance, text_differences

from simbot.description import load_sdf
from simbot.description.actor_legs import ActorRig
from simbot.description.actor_scripts import PROXY_HEIGHT, PROXY_RADIUS, ActorModel, SkinnedMesh
from simbot.description.model import Box, Capsule, Mesh
from simbot.description.skeleton_poses import load_rig

SCRIPT_OK = """<waypoint><time>0</time><pose>0 0 0 0 0 0</pose></waypoint>
          <waypoint><time>2</time><pose>1 0 0 0 0 0</pose></waypoint>"""


def _world(script: str, extra: str = "") -> str:
    return f"""<?xml version="1.0"?>
<sdf version="1.9">
  <world name="w">
    <actor name="walker">
      <pose>1 2 1 0 0 0</pose>
      {extra}
      <script>
        <delay_start>0.5</delay_start>
        <trajectory id="3" type="walk" tension="0.4">
          {script}
        </trajectory>
      </script>
    </actor>
  </world>
</sdf>
"""


def test_an_actor_is_read_with_its_skin_animation_script_and_links(tmp_path: Path) -> None:
    """A skin found beside the world (an OBJ here: bounds from trimesh put the proxy's soles on its lowest point)."""
    (tmp_path / "person.obj").write_text("v -0.2 -0.2 -0.9\nv 0.2 -0.2 -0.9\nv 0 0.2 0.8\nf 1 2 3\n")
    extra = """<skin><filename>person.obj</filename><scale>1.0</scale></skin>
      <animation name="walk"><filename>person.obj</filename><interpolate_x>true</interpolate_x></animation>
      <link name="hat"><pose>0 0 0.9 0 0 0</pose>
        <visual name="v"><geometry><box><size>0.3 0.3 0.1</size></box></geometry></visual></link>"""
    path = tmp_path / "world.sdf"
    path.write_text(_world(SCRIPT_OK, extra))
    actor = load_sdf(path).model("walker")  # type: ignore[union-attr]
    assert isinstance(actor, ActorModel) and not actor.static
    assert actor.pose.xyz == (1.0, 2.0, 1.0) and actor.canonical_link == "body"
    assert actor.skin is not None and actor.skin.path == tmp_path / "person.obj"
    assert [(a.name, a.interpolate_x) for a in actor.animations] == [("walk", True)]
    script = actor.script
    assert (script.loop, script.delay_start, script.auto_start) == (True, 0.5, True)
    trajectory = script.trajectories[0]
    assert (trajectory.id, trajectory.type, trajectory.tension) == (3, "walk", 0.4)
    assert [(w.time, w.pose.xyz) for w in trajectory.waypoints] == [(0.0, (0, 0, 0)), (2.0, (1, 0, 0))]
    body, hat = actor.links
    assert isinstance(body.visuals[0].geometry, Mesh)
    proxy = body.collisions[0]
    assert proxy.geometry == Capsule(PROXY_RADIUS, PROXY_HEIGHT - 2 * PROXY_RADIUS)
    assert proxy.pose.xyz[2] == pytest.approx(-0.9 + PROXY_HEIGHT / 2)
    assert hat.name == "hat" and isinstance(hat.visuals[0].geometry, Box) and hat.pose.xyz == (0, 0, 0.9)
    assert [(j.parent, j.child, j.type) for j in actor.joints] == [("body", "hat", "fixed")]


def test_a_skin_not_found_is_one_warning_naming_it_and_the_proxy_is_drawn(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    path = tmp_path / "world.sdf"
    path.write_text(
        _world(SCRIPT_OK, "<skin><filename>https://fuel.gazebosim.org/1.0/x/models/y/walk.dae</filename></skin>")
    )
    with caplog.at_level(logging.WARNING):
        actor = load_sdf(path).model("walker")  # type: ignore[union-attr]
    warnings = [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]
    assert len(warnings) == 1 and "walk.dae" in warnings[0] and "not found" in warnings[0], warnings
    body = actor.links[0]
    assert isinstance(body.visuals[0].geometry, Capsule) and body.visuals[0].geometry == body.collisions[0].geometry


BAD_SCRIPTS = {
    "out_of_order": (
        """<waypoint><time>0</time><pose>0 0 0 0 0 0</pose></waypoint>
          <waypoint><time>3</time><pose>1 0 0 0 0 0</pose></waypoint>
          <waypoint><time>2</time><pose>2 0 0 0 0 0</pose></waypoint>""",
        "<waypoint> actor 'walker': trajectory 3: waypoint at time 2 s is not after the one before it (3 s)",
    ),
    "missing_pose": (
        "<waypoint><time>0</time></waypoint>",
        "<waypoint> actor 'walker': waypoint without its <pose>",
    ),
    "missing_time": (
        "<waypoint><pose>0 0 0 0 0 0</pose></waypoint>",
        "<waypoint> actor 'walker': waypoint without its <time>",
    ),
    "no_waypoint": ("", "<trajectory> actor 'walker': trajectory 3 has no <waypoint>"),
    "bad_pose": (
        "<waypoint><time>0</time><pose>0 0 zero 0 0 0</pose></waypoint>",
        "<pose> expected numbers, got '0 0 zero 0 0 0'",
    ),
}


@pytest.mark.parametrize("case", sorted(BAD_SCRIPTS))
def test_a_bad_script_is_one_line_naming_the_actor_and_the_element(case: str, tmp_path: Path) -> None:
    script, message = BAD_SCRIPTS[case]
    bad = tmp_path / f"{case}.sdf"
    bad.write_text(_world(script))
    result = run_cli("describe", str(bad))
    lines = result.stderr.strip().splitlines()
    assert result.returncode == 2 and len(lines) == 1 and "Traceback" not in result.stderr, result.stderr
    assert lines[0].startswith(f"simbot describe: error: {bad}:") and message in lines[0], lines[0]


FIVE_DIGITS = Tolerance(
    1e-4,
    1e-9,
    "make_worker.py prints five significant digits: a CPU's last bit can flip the last one, 1e-4 relative",
)


def test_the_workers_skin_is_made_by_its_script_and_stands_on_its_soles(tmp_path: Path) -> None:
    """worlds/models/worker: the committed COLLADA is what meshes/make_worker.py writes (its numbers
    to the five digits printed);
    read as an actor, its skin is found and the proxy's soles are on the skin's lowest point, 1.0 m
    below the actor's frame (the figure's pelvis)."""
    out = tmp_path / "worker.dae"
    subprocess.run(
        [sys.executable, str(REPO / "meshes" / "make_worker.py"), "--out", str(out)], check=True, timeout=120
    )
    committed = REPO / "worlds" / "models" / "worker" / "meshes" / "worker.dae"
    found = text_differences(out.read_text(), committed.read_text(), FIVE_DIGITS)
    assert not found, "the committed skin is stale: run meshes/make_worker.py: " + "; ".join(found)
    actor = load_sdf(REPO / "worlds" / "models" / "worker" / "model.sdf")
    assert isinstance(actor, ActorModel) and actor.skin is not None and actor.skin.path == committed
    skin = actor.links[0].visuals[0].geometry
    assert isinstance(skin, SkinnedMesh)  # animated: a capsule per thigh and shin, and the torso's
    shapes = {c.name for link in actor.links for c in link.collisions}
    assert shapes == {"torso", "thigh_left", "shin_left", "thigh_right", "shin_right"}
    rig = ActorRig.of(load_rig(committed, skin.animations), 1.0)
    assert rig.lowest() == pytest.approx(-1.0, abs=1e-6)
