"""Randomised worlds (simbot/variation/): the warehouse's profile drawn from seeds, checked against what
the profile allows; the same seed the same world, byte for byte; a server's seeded reset; `simbot
dataset --randomise` over 20 seeds read back by pycocotools with the clutter's boxes; bad profiles,
seeds and options one line each.
"""

from __future__ import annotations

import hashlib
import json
import math
import subprocess
import tempfile
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from client_helpers import client_process
from pycocotools.coco import COCO
from server_helpers import REPO, SimServer, running_server, server_command, wait_until

from simbot.description import load_world
from simbot.description.actor_paths import ScriptPath
from simbot.description.actor_scripts import ActorModel
from simbot.description.additions import with_additions
from simbot.description.footprints import overlap
from simbot.description.model import World
from simbot.sim.loop.world import load_robot
from simbot.variation import Profile, ProfileError, read_profile, vary
from simbot.variation.clutter import PREFIX
from simbot.variation.vary import NOISY_CAMERAS

WAREHOUSE = REPO / "worlds" / "warehouse.sdf"
PROFILE = REPO / "worlds" / "warehouse.variation.toml"
PEOPLE = REPO / "worlds" / "additions" / "warehouse_people.sdf"
TUG = REPO / "urdf" / "flexley_tug.sdf"
SEEDS = 20
CLUTTER_LABELS = {20, 21, 22}
RUN_TIMEOUT_S = 600.0

RIG = """<?xml version="1.0"?>
<sdf version="1.9">
  <model name="rig">
    <link name="base">
      <inertial><pose>0 0 -4.5 0 0 0</pose><mass>1000</mass>
        <inertia><ixx>6870</ixx><iyy>6870</iyy><izz>240</izz></inertia></inertial>
      <collision name="tower"><pose>0 0 -4.5 0 0 0</pose><geometry><box><size>1.2 1.2 9</size></box></geometry></collision>
      <sensor name="rgb" type="camera">
        <pose>0 0 0 0 1.5707963 0</pose><update_rate>10</update_rate><topic>rig_rgb</topic>
        <camera><horizontal_fov>1.7</horizontal_fov><image><width>160</width><height>120</height></image>
          <clip><near>0.5</near><far>20</far></clip></camera>
      </sensor>
      <sensor name="boxes" type="boundingbox_camera">
        <pose>0 0 0 0 1.5707963 0</pose><update_rate>10</update_rate><topic>rig_boxes</topic>
        <camera><box_type>2d</box_type><horizontal_fov>1.7</horizontal_fov>
          <image><width>160</width><height>120</height></image><clip><near>0.5</near><far>20</far></clip></camera>
      </sensor>
    </link>
  </model>
</sdf>
"""
"""A camera rig on a heavy tower standing in the tug's lane, 9 m above the floor, looking straight down
with the image's width along x: the hall from x −6.5 to 13.5 and y −7.2 to 7.2 in view (the clutter
goes east of the people's routes). A tower, not a static model, so that its pose is published
and the dataset's boxes name the colour image beside them."""


@pytest.fixture(scope="module")
def profile() -> Profile:
    return read_profile(PROFILE)


@pytest.fixture(scope="module")
def warehouse() -> World:
    return with_additions(load_world(WAREHOUSE), [PEOPLE])


# --- the draws, against the profile


def test_the_same_seed_draws_the_same_world_and_others_differ(warehouse: World, profile: Profile) -> None:
    robot = load_robot(TUG)
    first, again, other = (
        vary(warehouse, robot, profile, 7),
        vary(warehouse, robot, profile, 7),
        vary(warehouse, robot, profile, 8),
    )
    assert first == again
    assert first.world != other.world and first.clutter != () and other.clutter != ()


def test_every_draw_stays_within_the_profile(warehouse: World, profile: Profile) -> None:
    original = {model.name: model for model in warehouse.models}
    assert profile.clutter is not None and profile.sun is not None and profile.people is not None
    for seed in range(5):
        variant = vary(warehouse, load_robot(TUG), profile, seed)
        world = variant.world
        low, high = profile.clutter.count
        placed = [m for m in world.models if m.name.startswith(PREFIX)]
        assert low <= len(placed) <= high
        for model in placed:
            x, y, z = model.pose.xyz
            xmin, ymin, xmax, ymax = profile.clutter.area
            assert xmin <= x <= xmax and ymin <= y <= ymax and z == 0.0 and model.static
            for rect in profile.clutter.keep_clear:
                assert not _inside(x, y, rect), (seed, model.name, rect)
        sun = next(light for light in world.lights if light.name == profile.sun.light)
        elevation = math.degrees(math.asin(-sun.direction[2] / np.linalg.norm(sun.direction)))
        assert profile.sun.elevation_deg[0] - 1e-9 <= elevation <= profile.sun.elevation_deg[1] + 1e-9
        trolley, before = world.model("trolley"), original["trolley"]
        moved = profile.moved["trolley"]
        assert moved.x[0] <= trolley.pose.xyz[0] - before.pose.xyz[0] <= moved.x[1]
        assert moved.y[0] <= trolley.pose.xyz[1] - before.pose.xyz[1] <= moved.y[1]
        for actor in (m for m in world.models if isinstance(m, ActorModel)):
            period = actor.script.trajectories[0].waypoints[-1].time
            base = original[actor.name]
            assert isinstance(base, ActorModel)
            pace = base.script.trajectories[0].waypoints[-1].time / period
            assert profile.people.speed[0] - 1e-9 <= pace <= profile.people.speed[1] + 1e-9
            assert (
                profile.people.phase[0] * period - 1e-9
                <= actor.script.played
                <= profile.people.phase[1] * period + 1e-9
            )
            unplayed = ScriptPath.of(replace(actor.script, played=0.0))
            start = ScriptPath.of(actor.script).pose_at(0.0)
            assert np.allclose(start.position, unplayed.pose_at(actor.script.played).position, atol=1e-12)
        for link in variant.robot.links if variant.robot else ():
            for sensor in (s for s in link.sensors if s.type in NOISY_CAMERAS):
                camera = next(p for p in sensor.params if p.tag == "camera")
                noise = next(p for p in camera.children if p.tag == "noise")
                stddev = float(next(p.text for p in noise.children if p.tag == "stddev"))
                assert profile.camera_noise is not None
                assert profile.camera_noise[0] <= stddev <= profile.camera_noise[1]


def _inside(x: float, y: float, rect: tuple[float, float, float, float]) -> bool:
    return rect[0] <= x <= rect[2] and rect[1] <= y <= rect[3]


def test_clutter_keeps_off_every_route_and_every_model(warehouse: World, profile: Profile) -> None:
    """No piece's shadow overlaps another model's (the boxes holding their collisions) or a person's path."""
    from simbot.description.footprints import Rectangle
    from simbot.description.free_poses import Places

    variant = vary(warehouse, None, profile, 11)
    pieces = [m for m in variant.world.models if m.name.startswith(PREFIX)]
    others = Places.of_world(
        variant.world.__class__(
            name="w", models=tuple(m for m in variant.world.models if not m.name.startswith(PREFIX) or True)
        ),
        Rectangle(0, 0, 0, 0),
        3.0,
        0.0,
        profile.clutter.area if profile.clutter else None,
    ).obstacles
    for piece in pieces:
        mine = [o for o in others if o.name.startswith(f"{piece.name}::")]
        assert mine, piece.name
        for obstacle in others:
            if obstacle.name.split("::")[0] == piece.name:
                continue
            for own in mine:
                assert not overlap(own.polygon, obstacle.polygon), (piece.name, obstacle.name)


# --- bad profiles: one line naming the file and the key


@pytest.mark.parametrize(
    ("text", "says"),
    [
        (
            "[sun]\nlight = 'sun'\nelevation_deg = [80, 30]\nazimuth_deg = [0, 1]\nintensity = [1, 1]\n",
            "sun.elevation_deg: min 80 > max 30",
        ),
        ("[weather]\nrain = 1\n", "unknown key weather"),
        ("[people]\nwalk = 1\n", "unknown key people.walk"),
        ("[models.forklift]\nx = [0, 1]\n", "models.forklift: world 'warehouse' has no model 'forklift'"),
        (
            "[clutter]\ncount = [1, 2]\narea = [0, 0, 1, 1]\nmodels = [{ uri = 'model://nothing_here' }]\n",
            "clutter.models[0].uri: 'model://nothing_here' not found",
        ),
        ("[cameras]\nnoise_stddev = [-1, 0]\n", "cameras.noise_stddev: must be at least 0"),
    ],
)
def test_a_bad_profile_is_one_line_naming_file_and_key(tmp_path: Path, warehouse: World, text: str, says: str) -> None:
    path = tmp_path / "bad.variation.toml"
    path.write_text(text)
    with pytest.raises(ProfileError) as caught:
        vary(warehouse, None, read_profile(path), 0)
    message = str(caught.value)
    assert "\n" not in message and str(path) in message and says in message, message


@pytest.mark.parametrize(
    ("option", "says"),
    [
        ("seven", "--randomise: expected SEED[:PROFILE]"),
        ("1:/nonexistent/p.toml", "/nonexistent/p.toml: no such variation profile"),
    ],
)
def test_a_bad_randomise_option_is_one_line_and_exit_2(option: str, says: str) -> None:
    done = subprocess.run(
        server_command("--world", "warehouse", "--randomise", option, "--mode", "lockstep"),
        capture_output=True, text=True, timeout=120, cwd=REPO, check=False,
    )  # fmt: skip
    assert done.returncode == 2, done.stderr
    assert says in done.stderr and "Traceback" not in done.stderr, done.stderr


# --- a server: seeded resets, and a dataset over 20 seeds


@pytest.fixture(scope="module")
def sim(tmp_path_factory: pytest.TempPathFactory) -> Iterator[SimServer]:
    rig = tmp_path_factory.mktemp("rig") / "rig.sdf"
    rig.write_text(RIG)
    with running_server(
        "warehouse", extra=("--robot", str(rig), "--spawn", "3.5", "0", "9.001", "1.5707963", "--render-workers", "1")
    ) as server:
        yield server
        server.stop(timeout=60.0)


def collect(server: SimServer, *args: str) -> tuple[dict, Path]:
    out = Path(tempfile.mkdtemp(prefix="simbot-variation-"))
    with client_process(server, "dataset", "--out", str(out), "--cameras", "rig_rgb", "rig_boxes", *args) as client:

        def stepped_and_finished() -> bool:
            _steps(server, 10)
            return not client.alive()

        # a seed's first set comes at its first step, so a chunk of steps may span several seeded resets
        wait_until(stepped_and_finished, RUN_TIMEOUT_S, "the dataset client to finish")
        assert client.process.returncode == 0, client.stderr()
    return json.loads((out / "manifest.json").read_text()), out


def test_a_dataset_over_20_seeds_holds_20_worlds_and_their_clutter(sim: SimServer) -> None:
    manifest, out = collect(sim, "--randomise", str(SEEDS), "--count", "1")
    sets = manifest["sets"]
    assert sorted(s["world_seed"] for s in sets) == list(range(SEEDS))
    pictures = {s["world_seed"]: _rgb(out, s) for s in sets}
    assert len({hashlib.sha256(p).hexdigest() for p in pictures.values()}) == SEEDS, (
        "every seed's world looks different"
    )
    coco = COCO(str(out / "annotations.json"))
    images = coco.loadImgs(coco.getImgIds())
    assert len(images) == SEEDS
    for image in images:
        labels = [a["category_id"] for a in coco.loadAnns(coco.getAnnIds(imgIds=[image["id"]]))]
        assert set(labels) & CLUTTER_LABELS, f"{image['file_name']}: no clutter box among {labels}"
        assert (out / image["file_name"]).is_file()
    again, out_again = collect(sim, "--randomise", "3:4", "--count", "1")
    (only,) = again["sets"]
    first = next(s for s in sets if s["world_seed"] == 3)
    assert only["stamp_ns"] == first["stamp_ns"]
    assert _rgb(out_again, only) == pictures[3], "seed 3 twice: the same pixels"


def _steps(server: SimServer, count: int) -> None:
    server.control({"multi_step": count}, timeout=RUN_TIMEOUT_S)


def _rgb(root: Path, entry: dict) -> bytes:
    frame = next(f for f in entry["frames"] if f["camera"] == "rig_rgb")
    return (root / frame["files"]["rgb"]).read_bytes()


def test_a_bad_seed_is_answered_with_an_error_and_the_world_runs_on(sim: SimServer) -> None:
    before = sim.state()
    for seed in ("x", -1, 1.5, True):
        reply = sim.control({"reset": {"seed": seed}})
        assert reply["ok"] is False and "reset.seed" in reply["error"], reply
    after = sim.step(10)
    assert after["iterations"] == before["iterations"] + 10
    assert sim.state()["variation"] == before["variation"]


def test_a_seed_for_a_world_without_a_profile_is_an_error() -> None:
    with running_server("empty") as server:
        reply = server.control({"reset": {"seed": 3}})
        assert reply["ok"] is False and "has no variation profile" in reply["error"], reply
        assert server.step(5)["iterations"] == 5
