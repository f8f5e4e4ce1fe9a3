"""The simulator's behaviour, pinned: every message of two seeded lockstep runs, field by field.

Two golden runs:

- the tug in the warehouse, its six cameras at 64×48 (small, so that no image is dropped on a
  loaded machine; the pipeline is the one a 640×480 frame takes), driven on a curve;
- tests/fixtures/gazebo/two_vehicles.sdf: simbot's own world in the shape of gz-sim's
  diff_drive.sdf (two DiffDrive vehicles with Gazebo's default keys; gz-sim's file is not ours
  to copy), one vehicle driven.

Every sample on the server's namespace is kept per key, in arrival order (one publisher per key,
and Zenoh keeps a publisher's order). A run ends with the clock stamped at its last step: the
clock publishes last in a step and every key shares its priority, so everything before it has
arrived. Three promises, three tests:

1. **As recorded, on any machine.** Each message is decoded and compared field by field with
   tests/fixtures/behaviour/ (golden_helpers.py): integers, strings, frame ids, stamps and counts
   exactly, floats within the tolerance stated for their field, so a refactoring that changes a
   pose, a scan, a noise draw or an image fails here and a CPU's last bit does not. Machine-bound,
   and so compared only where it matches the recording: the pixels GL draws (llvmpipe's vector
   width changes its rounding; `device` in recorded.json). Everything else is compared everywhere;
   what may still move its last bits from one machine to another (libm's and numpy's
   transcendental functions, another build of PyBullet) is what the tolerances absorb
   (docs/reproducibility.md).
2. **Byte for byte, on one machine.** Two runs with one seed give identical bytes on every key,
   the cameras included: the promise docs/reproducibility.md makes.
3. **No CPU-chosen kernel decides a bit.** The run again under every other OpenBLAS kernel this
   CPU can run (`OPENBLAS_CORETYPE`), numpy's dispatched SIMD paths masked
   (`NPY_DISABLE_CPU_FEATURES`): identical bytes on every key. A published value that reaches
   BLAS (`@`, `np.dot`, `np.linalg` on numpy arrays) fails here on whatever machine runs it, not
   only on the next kind of CPU.

`SIMBOT_RECORD_BEHAVIOUR=1 pytest tests/test_behaviour.py` records the golden runs anew, with the
machine they were made on; do that only for a change meant to alter behaviour, and say so in its
commit.
"""

from __future__ import annotations

import json
import math
import os
from collections import defaultdict
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass

import pytest
import zenoh
from conftest import REPO
from gl_helpers import NO_EGL
from golden_helpers import DIGEST, IMAGE, Recording, columns, differences, kernel_environments, machine
from server_helpers import CLOCK, keyed_payload, raw_samples, running_server

from simbot.bus import decode, encode, messages
from simbot.bus.graph import discover

FIXTURES = REPO / "tests" / "fixtures" / "behaviour"
RECORDED = FIXTURES / "recorded.json"
RECORD = os.environ.get("SIMBOT_RECORD_BEHAVIOUR") == "1"
TWO_VEHICLES = REPO / "tests" / "fixtures" / "gazebo" / "two_vehicles.sdf"
SEED = 7
STEPS_BEFORE = 50
STEPS_DRIVEN = 600
LATCHED = ("robot_description", "tf_static", "scene")
IMAGE_ENCODINGS = {"rgb8", "mono8", "32FC1"}

Payloads = list[tuple[str, bytes]]
"""(key relative to the namespace, payload), in arrival order."""


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


@dataclass(frozen=True)
class Played:
    """What one run published: the payloads, and the type of each key from the bus's graph."""

    payloads: Payloads
    types: dict[str, str]

    def by_key(self) -> dict[str, list[bytes]]:
        grouped: defaultdict[str, list[bytes]] = defaultdict(list)
        for key, payload in self.payloads:
            grouped[key].append(payload)
        return dict(grouped)

    def recording(self) -> Recording:
        grouped = self.by_key()
        return Recording(
            {key: self.types[key] for key in grouped},
            {key: columns(self.types[key], payloads, str(REPO)) for key, payloads in grouped.items()},
        )

    def drawn(self) -> set[str]:
        """The keys whose pixels GL draws: sensor_msgs/Image in a camera's encodings."""
        return {
            key
            for key, payloads in self.by_key().items()
            if self.types[key] == IMAGE and decode(payloads[0], IMAGE).encoding in IMAGE_ENCODINGS
        }


def _play(run: Run, env: Mapping[str, str]) -> Played:
    """The run, on a server started with `env` added to its environment."""
    with running_server(run.world, "lockstep", SEED, run.extra, env=env) as sim:
        session, prefix = sim.node.session, f"{sim.namespace}/"
        with raw_samples(session, f"0/{prefix}**", keyed_payload) as samples:
            sim.step(STEPS_BEFORE)
            sim.send(run.cmd_vel, messages.twist((0.6, 0.0, 0.0), (0.0, 0.0, 0.4)))
            end_ns = round(sim.step(STEPS_DRIVEN)["sim_time"] * 1e9)
            samples.wait_for(
                lambda items: any(key == f"{prefix}clock" and _clock_ns(data) == end_ns for key, data in items),
                timeout=120.0,
                what=f"the clock stamped {end_ns / 1e9:.3f} s",
            )
            received = samples.messages() + _latched(session, prefix, run.latched)
        types = {e.key.removeprefix(prefix): e.typename for e in discover(session, sim.namespace) if e.kind != "srv"}
    return Played([(key.removeprefix(prefix), payload) for key, payload in received], types)


def _latched(session: zenoh.Session, prefix: str, keys: tuple[str, ...]) -> Payloads:
    """The latest sample of each latched key, from its publisher's queryable."""
    found = []
    for key in keys:
        replies = [reply.ok for reply in session.get(f"0/{prefix}{key}/*/*", timeout=10.0) if reply.ok is not None]
        assert len(replies) == 1, f"{key}: {len(replies)} replies to a get of a latched key"
        found.append((prefix + key, replies[0].payload.to_bytes()))
    return found


def _clock_ns(payload: bytes) -> int:
    return messages.stamp_ns(decode(payload, CLOCK).clock)


def _gl_device() -> str:
    """What rasterises GL here (llvmpipe names its LLVM and vector width)."""
    import moderngl

    context = moderngl.create_context(standalone=True, backend="egl", require=330)  # type: ignore[arg-type]  # the stub types **settings as dicts
    try:
        return str(context.info["GL_RENDERER"])
    finally:
        context.release()


Player = Callable[[str, Mapping[str, str], int], Played]
"""Plays run `name` in an environment; the take tells a repeat from the first."""


@pytest.fixture(scope="module")
def played() -> Iterator[Player]:
    """Plays each (run, environment, take) once per module: a world's first run serves all three tests."""
    done: dict[tuple[str, tuple[tuple[str, str], ...], int], Played] = {}

    def play(name: str, env: Mapping[str, str], take: int) -> Played:
        if name == "warehouse" and NO_EGL:
            pytest.skip(NO_EGL)
        key = (name, tuple(sorted(env.items())), take)
        if key not in done:
            done[key] = _play(RUNS[name], env)
        return done[key]

    yield play


def _unequal(a: Played, b: Played) -> list[str]:
    """Keys whose payloads differ between two runs, byte for byte (a key missing in one counts)."""
    ours, theirs = a.by_key(), b.by_key()
    return sorted(key for key in set(ours) | set(theirs) if ours.get(key) != theirs.get(key))


@pytest.mark.parametrize("name", sorted(RUNS))
def test_every_message_of_a_seeded_lockstep_run_is_as_recorded(name: str, played: Player) -> None:
    run = played(name, {}, 1)
    device = _gl_device() if RUNS[name].cameras else None
    assert len(run.types) > 5, f"too few keys published: {sorted(run.types)}"
    assert len(run.drawn()) == RUNS[name].cameras, f"camera images: {sorted(run.drawn())}"
    now = run.recording()
    recorded = json.loads(RECORDED.read_text()) if RECORDED.exists() else {"runs": {}}
    if RECORD:
        FIXTURES.mkdir(exist_ok=True)
        now.save(FIXTURES / f"{name}.npz")
        recorded["machine"] = machine()
        recorded["runs"][name] = {"device": device, "messages": len(run.payloads)}
        RECORDED.write_text(json.dumps(recorded, indent=1, sort_keys=True) + "\n")
    expected = recorded["runs"][name]
    unpinned = {} if device == expected["device"] else {DIGEST: f"GL drew these on {expected['device']}"}
    found = differences(now, Recording.load(FIXTURES / f"{name}.npz"), unpinned)
    print(
        f"{name}: {len(now.keys)} keys, {len(run.payloads)} messages; GL device {device}, pixels {unpinned or 'compared'}"
    )
    assert not found, (
        f"{len(found)} fields differ from the recording (made on {recorded['machine']['cpu']}):\n"
        + "\n".join(found[:30])
    )


@pytest.mark.parametrize("name", sorted(RUNS))
def test_a_seeded_lockstep_run_repeats_byte_for_byte(name: str, played: Player) -> None:
    first, again = played(name, {}, 1), played(name, {}, 2)
    assert len(first.drawn()) == RUNS[name].cameras, "the cameras are in the comparison"
    differ = _unequal(first, again)
    assert not differ, f"{len(differ)} of {len(first.types)} keys differ between two runs with seed {SEED}: {differ}"


@pytest.mark.parametrize("name", sorted(RUNS))
def test_no_cpu_chosen_kernel_decides_a_published_bit(name: str, played: Player) -> None:
    environments = kernel_environments()
    if not environments:
        pytest.skip("numpy here bundles no OpenBLAS with another kernel this CPU can run")
    first = played(name, {}, 1)
    for env in environments:
        differ = _unequal(first, played(name, env, 1))
        assert not differ, f"under {env}, {len(differ)} keys publish other bytes: {differ}"


def _recording(typename: str, *msgs: object) -> Recording:
    return Recording({"key": typename}, {"key": columns(typename, [encode(m) for m in msgs], str(REPO))})


def test_a_last_bit_passes_where_a_micrometre_a_nanosecond_or_a_frame_fails() -> None:
    """The comparison itself: a float one ulp off is within STATE; 1 µm, a stamp 1 ns later or
    another frame id is a difference, named with its key and field."""
    x, typename = 1.2345678, "geometry_msgs/msg/PoseStamped"

    def pose(ns: int = 1_000, frame: str = "world", at: float = x) -> object:
        return messages.pose_stamped(ns, frame, (at, 0.0, 0.1), (0.0, 0.0, 0.0, 1.0))

    recorded = _recording(typename, pose(), pose())
    assert differences(_recording(typename, pose(), pose(at=math.nextafter(x, 2.0))), recorded, {}) == []
    for changed, field in ((pose(at=x + 1e-6), "pose.position.x"), (pose(ns=1_001), "header.stamp.nanosec")):
        found = differences(_recording(typename, pose(), changed), recorded, {})
        assert len(found) == 1 and found[0].startswith(f"key {field}: 1 of 2"), found
    found = differences(_recording(typename, pose(), pose(frame="odom")), recorded, {})
    assert len(found) == 1 and "'odom', recorded 'world'" in found[0], found


def test_a_float_field_without_a_stated_tolerance_is_an_error() -> None:
    """A key of a type whose floats TOLERANCES does not pin cannot be compared until one is stated."""
    field = messages.magnetic_field(0, "imu", (1e-5, 2e-5, 3e-5))
    same = _recording("sensor_msgs/msg/MagneticField", field)
    with pytest.raises(AssertionError, match="no tolerance stated for the float field 'magnetic_field.x'"):
        differences(same, same, {})
