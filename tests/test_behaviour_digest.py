"""The simulator's behaviour, pinned: a digest of every message of two seeded lockstep runs.

Recorded before the core's redesign (issue 22) and kept after it, so that a refactoring that
changes any published byte (a pose, a scan, an image, a frame id, a stamp) fails here, naming the
keys whose messages differ. Two runs:

- the tug in the warehouse, its six cameras at 64×48 (small, so that no image is dropped on a
  loaded machine; the pipeline is the one a 640×480 frame takes), driven on a curve;
- tests/fixtures/gazebo/two_vehicles.sdf: simbot's own world in the shape of gz-sim's
  diff_drive.sdf (two DiffDrive vehicles with Gazebo's default keys; gz-sim's file is not ours
  to copy), one vehicle driven.

Every sample on the server's namespace is kept per key, in arrival order (one publisher per key,
and Zenoh keeps a publisher's order). The run ends with the clock stamped at its last step: the
clock publishes last in a step and every key shares its priority, so everything before it has
arrived. A key's digest is SHA-256 over its payloads.

Images drawn by GL are compared only where the rasteriser is the one they were recorded on
(`device` in the digest file: llvmpipe's vector width changes its rounding); everything else is
compared everywhere. The checkout's path is taken out of each payload before hashing (the
description names its meshes by absolute URIs). `SIMBOT_RECORD_DIGESTS=1 pytest tests/test_behaviour_digest.py` records them
anew; do that only for a change meant to alter behaviour, and say so in its commit.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import pytest
import zenoh
from conftest import REPO
from gl_helpers import NO_EGL
from server_helpers import CLOCK, STRING, keyed_payload, raw_samples, running_server

from simbot.bus import DecodeError, decode, encode, messages

DIGESTS = Path(__file__).parent / "fixtures" / "digests.json"
RECORD = os.environ.get("SIMBOT_RECORD_DIGESTS") == "1"
TWO_VEHICLES = Path(__file__).parent / "fixtures" / "gazebo" / "two_vehicles.sdf"
SEED = 7
STEPS_BEFORE = 50
STEPS_DRIVEN = 600
IMAGE = "sensor_msgs/msg/Image"
MARKER_ARRAY = "visualization_msgs/msg/MarkerArray"
LATCHED = ("robot_description", "tf_static", "scene")
IMAGE_ENCODINGS = {"rgb8", "mono8", "32FC1"}


@dataclass(frozen=True)
class Run:
    """One seeded lockstep run: its world, its server options, and the command it drives with."""

    world: str
    extra: tuple[str, ...]
    cmd_vel: str
    latched: tuple[str, ...] = ()
    """Keys published once before the run (a plain subscriber misses them): fetched with a get."""
    cameras: int = 0


RUNS = {
    "warehouse": Run("warehouse", ("--camera-size", "64x48", "--renderer", "gl"), "cmd_vel", LATCHED, cameras=6),
    "diff_drive": Run(str(TWO_VEHICLES), ("--robot", "none"), "model/vehicle_blue/cmd_vel", ("scene",)),
}


def _record(run: Run) -> tuple[dict[str, str], set[str]]:
    """Each key's digest (its key relative to the namespace), and the keys GL draws, from one run."""
    with running_server(run.world, "lockstep", SEED, run.extra) as sim:
        session, prefix = sim.node.session, f"{sim.namespace}/"
        with raw_samples(session, f"{prefix}**", keyed_payload) as samples:
            sim.step(STEPS_BEFORE)
            sim.send(run.cmd_vel, messages.twist((0.6, 0.0, 0.0), (0.0, 0.0, 0.4)))
            end_ns = round(sim.step(STEPS_DRIVEN)["sim_time"] * 1e9)
            samples.wait_for(
                lambda items: any(key == f"{prefix}clock" and _clock_ns(data) == end_ns for key, data in items),
                timeout=120.0,
                what=f"the clock stamped {end_ns / 1e9:.3f} s",
            )
            received = samples.messages() + _latched(session, prefix, run.latched)
    hashes: dict[str, Any] = {}
    first: dict[str, bytes] = {}
    for key, payload in received:
        name = key.removeprefix(prefix)
        hashes.setdefault(name, hashlib.sha256()).update(_placeless(name, payload))
        first.setdefault(key.removeprefix(prefix), payload)
    return {key: digest.hexdigest() for key, digest in sorted(hashes.items())}, _drawn(first)


def _latched(session: zenoh.Session, prefix: str, keys: tuple[str, ...]) -> list[tuple[str, bytes]]:
    """The latest sample of each latched key, from its publisher's queryable."""
    found = []
    for key in keys:
        replies = [reply.ok for reply in session.get(prefix + key, timeout=10.0) if reply.ok is not None]
        assert len(replies) == 1, f"{key}: {len(replies)} replies to a get of a latched key"
        found.append((prefix + key, replies[0].payload.to_bytes()))
    return found


def _placeless(key: str, payload: bytes) -> bytes:
    """The payload with the checkout's path taken out, decoded and encoded again (a string's length
    is in its bytes): `robot_description` (a std_msgs/String) names its meshes by absolute
    `file://` URIs, which differ from one clone to the next, and so do the mesh markers of `scene`."""
    repo = str(REPO)
    if repo.encode() not in payload:
        return payload
    if key == "robot_description":
        return encode(messages.string(decode(payload, STRING).data.replace(repo, "<repo>")))
    assert key == "scene", f"{key} names the checkout's path"
    scene = decode(payload, MARKER_ARRAY)
    markers = [replace(m, mesh_resource=m.mesh_resource.replace(repo, "<repo>")) for m in scene.markers]
    return encode(replace(scene, markers=markers))


def _drawn(payloads: dict[str, bytes]) -> set[str]:
    """The keys whose messages GL draws: sensor_msgs/Image in a camera's encodings (by a key's first payload)."""
    drawn = set()
    for key, payload in payloads.items():
        try:
            image = decode(payload, IMAGE)
        except DecodeError:
            continue
        if image.encoding in IMAGE_ENCODINGS and len(image.data) == image.height * image.step > 0:
            drawn.add(key)
    return drawn


def _clock_ns(payload: bytes) -> int:
    return messages.stamp_ns(decode(payload, CLOCK).clock)


def _gl_device() -> str:
    """What rasterises GL here (llvmpipe names its LLVM and vector width)."""
    import moderngl

    context = moderngl.create_context(standalone=True, backend="egl", require=330)
    try:
        return str(context.info["GL_RENDERER"])
    finally:
        context.release()


@pytest.mark.parametrize("name", sorted(RUNS))
def test_every_message_of_a_seeded_lockstep_run_is_as_recorded(name: str) -> None:
    if name == "warehouse" and NO_EGL:
        pytest.skip(NO_EGL)
    digests, drawn = _record(RUNS[name])
    device = _gl_device() if name == "warehouse" else None
    assert len(digests) > 5, f"too few keys published: {sorted(digests)}"
    assert len(drawn) == RUNS[name].cameras, f"camera images: {sorted(drawn)}"
    recorded = json.loads(DIGESTS.read_text()) if DIGESTS.exists() else {}
    if RECORD:
        recorded[name] = {"device": device, "keys": digests}
        DIGESTS.write_text(json.dumps(recorded, indent=1, sort_keys=True) + "\n")
    expected = recorded[name]
    assert sorted(digests) == sorted(expected["keys"]), "the set of published keys changed"
    compared = [key for key in digests if device == expected["device"] or key not in drawn]
    differ = [key for key in compared if digests[key] != expected["keys"][key]]
    print(f"{name}: {len(compared)} of {len(digests)} keys compared (GL device {device})")
    assert not differ, f"{len(differ)} of {len(digests)} keys publish other bytes than recorded: {differ}"
