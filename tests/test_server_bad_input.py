"""Bad input to a real server: garbage on every input key and every world-control key, and bad worlds.

What must hold (SPEC §4): a malformed command (bad CDR, the wrong type, NaN, infinities, absurd
values) is dropped and counted per key in the world state's `dropped`, with the reason in
`last_errors`; a malformed world-control request gets `{"ok": false, "error": ...}` and is
counted the same way; the server keeps running, its sim time keeps advancing, and the robot does
not move. On the command line, a world or robot that cannot be loaded is exit code 2 and one
line on stderr naming the file.

Everything runs in lockstep, so "the robot did not move" is exact: with a zero command in force
and no valid command since, the pose after N more steps equals the pose before to far below a
millimetre (the settled tug creeps less than 1e-6 m per 100 steps).
"""

from __future__ import annotations

import contextlib
import math
import random
import subprocess
from pathlib import Path
from typing import Any

import pytest
from bus_helpers import endpoint, free_port
from server_helpers import (
    STRING,
    SimServer,
    module_server,
    planar_distance,
    reset_before_each,
    running_server,
    server_command,
    wrap,
)

from simbot.bus import encode, messages
from simbot.transform import yaw_of

SEED = 20240611
SETTLE_STEPS = 300
STILL_M = 1e-4
STILL_RAD = 1e-4
INPUT_TYPES = {"cmd_vel": "geometry_msgs/msg/Twist", "attach": "std_msgs/msg/Empty", "detach": "std_msgs/msg/Empty"}
"""The type each input takes: its garbage goes on that type's key, where the server listens for it."""


sim = module_server("warehouse")
fresh_world = reset_before_each(SETTLE_STEPS)


def _twist_bytes(linear: tuple[float, float, float], angular: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> bytes:
    return encode(messages.twist(linear, angular))


def _random(rng: random.Random, size: int) -> bytes:
    return bytes(rng.getrandbits(8) for _ in range(size))


def _bad_twists() -> list[tuple[str, bytes, str]]:
    rng = random.Random(SEED)
    valid = _twist_bytes((0.5, 0.0, 0.0), (0.0, 0.0, 0.5))
    odometry = messages.odometry(0, "odom", "base_footprint", (0, 0, 0), (0, 0, 0, 1), (0.5, 0, 0), (0, 0, 0))
    return [
        ("NaN linear.x", _twist_bytes((math.nan, 0.0, 0.0)), "non-finite"),
        ("NaN angular.z", _twist_bytes((0.0, 0.0, 0.0), (0.0, 0.0, math.nan)), "non-finite"),
        ("+inf linear.x", _twist_bytes((math.inf, 0.0, 0.0)), "non-finite"),
        ("-inf angular.z", _twist_bytes((0.0, 0.0, 0.0), (0.0, 0.0, -math.inf)), "non-finite"),
        ("inf linear.y", _twist_bytes((0.0, math.inf, 0.0)), "non-finite"),
        ("absurd 1e6 m/s", _twist_bytes((1e6, 0.0, 0.0)), "absurd"),
        ("absurd -1e9 rad/s", _twist_bytes((0.0, 0.0, 0.0), (0.0, 0.0, -1e9)), "absurd"),
        ("truncated to 30 bytes", valid[:30], "Twist"),
        ("truncated to the header", valid[:4], "Twist"),
        ("empty payload", b"", "shorter"),
        ("big-endian encapsulation", b"\x00\x00" + valid[2:], "encapsulation"),
        ("random 3 bytes", _random(rng, 3), "Twist"),
        ("random 52 bytes", _random(rng, 52), "Twist"),
        ("random 1000 bytes", _random(rng, 1000), "Twist"),
        ("CDR header + random 37 bytes", b"\x00\x01\x00\x00" + _random(rng, 37), "Twist"),
        ("a String", encode(messages.string("forward 0.5")), "Twist"),
        ("an Odometry", encode(odometry), "Twist"),
    ]


def _bad_empties() -> list[tuple[str, bytes, str]]:
    rng = random.Random(SEED + 1)
    return [
        ("a Twist", _twist_bytes((0.5, 0.0, 0.0)), "Empty"),
        ("a String", encode(messages.string("attach, please")), "Empty"),
        ("truncated to the header", encode(messages.empty())[:4], "Empty"),
        ("empty payload", b"", "shorter"),
        ("random 3 bytes", _random(rng, 3), "Empty"),
        ("random 5 bytes", _random(rng, 5), "Empty"),
        ("random 64 bytes", _random(rng, 64), "Empty"),
        ("CDR header + random 20 bytes", b"\x00\x01\x00\x00" + _random(rng, 20), "Empty"),
    ]


def _expect_drop(sim: SimServer, topic: str, label: str, payload: bytes, reason: str) -> str:
    """Sends `payload` on `topic` (on the key of the type the topic takes), steps until the server
    has taken it, checks it was dropped and why."""
    key = sim.key(topic)
    before = sim.state()["dropped"].get(key, 0)
    sim.send_raw(topic, INPUT_TYPES[topic], payload)
    for _ in range(50):
        sim.step(1)
        state = sim.state()
        if state["dropped"].get(key, 0) != before:
            break
    count = state["dropped"].get(key, 0)
    assert count == before + 1, f"{topic} <- {label}: dropped count {before} -> {count}, expected one drop"
    error = state["last_errors"].get(key, "")
    assert reason.lower() in error.lower(), f"{topic} <- {label}: last error {error!r} does not say {reason!r}"
    return error


def _assert_still(sim: SimServer, before: dict[str, Any], what: str) -> None:
    after = sim.state()
    for model in ("flexley_tug", "trolley"):
        (p0, q0), (p1, q1) = sim.pose(model, before), sim.pose(model, after)
        moved = math.dist(p0, p1)
        turned = abs(wrap(yaw_of(q1) - yaw_of(q0)))
        assert moved < STILL_M and turned < STILL_RAD, f"{model} moved {moved:.6f} m / {turned:.6f} rad after {what}"


def test_bad_cmd_vel_is_dropped_counted_and_ignored(sim: SimServer) -> None:
    before = sim.state()
    cases = _bad_twists()
    errors = {label: _expect_drop(sim, "cmd_vel", label, payload, reason) for label, payload, reason in cases}
    after = sim.step(200)
    assert sim.alive()
    assert after["iterations"] >= before["iterations"] + len(cases) + 200, "sim time did not keep advancing"
    _assert_still(sim, before, "garbage on cmd_vel")
    state = sim.state()
    key = sim.key("cmd_vel")
    assert state["dropped"][key] == len(cases)
    assert state["received"][key] == before["received"][key] + len(cases), "received counts every payload, bad ones too"
    # the input still works: a valid command moves the robot
    sim.drive(0.5)
    sim.step(400)
    moved = planar_distance(sim.pose(state=state)[0], sim.pose()[0])
    assert moved > 0.1, f"a valid cmd_vel after the garbage moved the robot only {moved:.4f} m"
    print(f"\nmeasured: {len(cases)} bad cmd_vel payloads dropped; e.g. {errors['NaN linear.x']!r}")


@pytest.mark.parametrize("topic", ["attach", "detach"])
def test_bad_attach_and_detach_are_dropped_counted_and_ignored(sim: SimServer, topic: str) -> None:
    joint = sim.subscribe("detachable_joint/state", STRING, latched=True)
    joint.wait_count(1, what="the latched detachable_joint/state")
    before = sim.state()
    if topic == "detach":
        sim.send("attach", messages.empty())
        sim.step(1)
        joint.wait_for(lambda ms: [m.data for m in ms][-1:] == ["attached"], what="'attached'")
    cases = _bad_empties()
    for label, payload, reason in cases:
        _expect_drop(sim, topic, label, payload, reason)
    sim.step(200)
    assert sim.alive()
    expected = ["detached"] if topic == "attach" else ["detached", "attached"]
    assert [m.data for m in joint.messages()] == expected, f"garbage on {topic} changed the joint"
    assert sim.state()["dropped"][sim.key(topic)] == len(cases)
    if topic == "attach":
        _assert_still(sim, before, "garbage on attach")
    else:
        sim.send("detach", messages.empty())
        sim.step(1)
        joint.wait_for(lambda ms: [m.data for m in ms][-1:] == ["detached"], what="'detached' after a valid detach")


BAD_CONTROL: list[tuple[str, bytes, str]] = [
    ("malformed JSON", b"{not json", "malformed JSON"),
    ("not UTF-8", b"\xff\xfe\x00", "malformed JSON"),
    ("a JSON array", b"[1, 2]", "JSON object"),
    ("a JSON string", b'"step"', "JSON object"),
    ("unknown field", b'{"bogus": 1}', "bogus"),
    ("negative multi_step", b'{"multi_step": -1}', "multi_step"),
    ("string multi_step", b'{"multi_step": "ten"}', "multi_step"),
    ("fractional multi_step", b'{"multi_step": 1.5}', "multi_step"),
    ("boolean multi_step", b'{"multi_step": true}', "multi_step"),
    ("NaN multi_step", b'{"multi_step": NaN}', "multi_step"),
    ("huge multi_step", b'{"multi_step": 1000000000000}', "multi_step"),
    ("numeric step", b'{"step": 3}', "step"),
    ("string pause", b'{"pause": "yes"}', "pause"),
    ("resume in lockstep", b'{"pause": false}', "lockstep"),
    ("numeric reset", b'{"reset": 5}', "reset"),
    ("reset nothing", b'{"reset": {"all": false}}', "reset"),
]

BAD_SET_POSE: list[tuple[str, bytes, str]] = [
    ("malformed JSON", b'{"name": "trolley", ', "malformed JSON"),
    ("a JSON array", b'["trolley"]', "JSON object"),
    ("no name", b"{}", "name"),
    ("numeric name", b'{"name": 5}', "name"),
    ("unknown model", b'{"name": "nosuch_model"}', "nosuch_model"),
    ("position a list", b'{"name": "trolley", "position": [1, 2, 3]}', "position"),
    ("position.x a string", b'{"name": "trolley", "position": {"x": "a"}}', "position.x"),
    ("position.x NaN", b'{"name": "trolley", "position": {"x": NaN}}', "position.x"),
    ("position.y Infinity", b'{"name": "trolley", "position": {"y": Infinity}}', "position.y"),
    ("orientation zero", b'{"name": "trolley", "orientation": {"x": 0, "y": 0, "z": 0, "w": 0}}', "quaternion"),
    ("orientation.w -Infinity", b'{"name": "flexley_tug", "orientation": {"w": -Infinity}}', "orientation.w"),
]


def test_bad_world_control_requests_are_refused_and_counted(sim: SimServer) -> None:
    before = sim.state()
    for name, cases in (("control", BAD_CONTROL), ("set_pose", BAD_SET_POSE)):
        key = sim.key(f"world/{sim.world}/{name}")
        for i, (label, payload, reason) in enumerate(cases, start=1):
            reply = sim.call(name, payload)
            assert reply.get("ok") is False, f"{name} <- {label}: accepted: {reply}"
            assert reason.lower() in reply.get("error", "").lower(), (
                f"{name} <- {label}: error {reply.get('error')!r} does not say {reason!r}"
            )
            state = sim.state()
            assert state["dropped"].get(key) == i, (
                f"{name} <- {label}: dropped count {state['dropped'].get(key)}, expected {i}"
            )
            assert state["last_errors"].get(key) == reply["error"]
    state = sim.state()
    assert state["iterations"] == before["iterations"], "a refused control request stepped or reset the world"
    assert state["paused"] is False
    _assert_still(sim, before, "bad world-control requests")
    # the state key takes any payload (documented): garbage still gets the state
    for payload in (b"{not json", b"\xff\xfe", b"[1]", b'{"bogus": 1}'):
        reply = sim.call("state", payload)
        assert reply["ok"] is True and "models" in reply, reply
    # the world still runs
    assert sim.step(10)["iterations"] == before["iterations"] + 10
    assert sim.alive()


def test_a_refused_control_request_changes_nothing(sim: SimServer) -> None:
    """A request answered {"ok": false} must not have been half carried out."""
    sim.drive(0.5)
    sim.step(500)
    before = sim.state()
    problems = []
    reply = sim.control({"reset": {"all": True}, "multi_step": -1})
    state = sim.state()
    assert reply["ok"] is False
    if state["iterations"] != before["iterations"]:
        problems.append(f'{{"reset": {{"all": true}}, "multi_step": -1}} was refused ({reply["error"]!r}) '
                        f'but reset the world: iterations {before["iterations"]} -> {state["iterations"]}')  # fmt: skip
    reply = sim.control({"pause": True, "multi_step": "x"})
    state = sim.state()
    assert reply["ok"] is False
    if state["paused"]:
        problems.append(f'{{"pause": true, "multi_step": "x"}} was refused ({reply["error"]!r}) but paused the world')
    assert not problems, "SERVER BUG: " + "; ".join(problems)


def test_absurd_set_pose_is_refused_and_the_world_stays_readable() -> None:
    """A finite but absurd position (1e300 m) is refused like NaN; world state must keep answering."""
    with running_server("warehouse", "lockstep") as sim:
        sim.step(100)
        reply = sim.call("set_pose", {"name": "trolley", "position": {"x": 1e300, "y": 0.2, "z": 0.0}})
        sim.step(10)
        state = sim.call("state", {})
        problems = []
        if reply.get("ok") is not False:
            problems.append(f"set_pose with x = 1e300 was accepted: {reply}")
        if state.get("ok") is not True:
            problems.append(f"afterwards world state no longer answers: {state}")
        sim.call("set_pose", {"name": "trolley", "position": {"x": 1.0, "y": 0.2, "z": 0.0}})
        sim.control({"reset": {"all": True}})
        sim.step(1000)
        (_, _, z), _ = sim.pose("trolley")
        if abs(z) > 0.01:
            problems.append(
                f"after set_pose back and a reset the trolley falls through the floor: z {z:.3f} m after 1 s"
            )
        assert not problems, "SERVER BUG: " + "; ".join(problems)


@pytest.mark.parametrize("name", ["control", "set_pose"])
def test_deeply_nested_json_is_refused_not_fatal(name: str) -> None:
    """100 000 nested brackets: a JSON error reply, not a RecursionError that ends the server."""
    with running_server("empty", "lockstep") as sim:
        try:
            reply: dict[str, Any] | None = sim.call(name, b"[" * 100_000, timeout=3.0)
        except TimeoutError:
            reply = None
        with contextlib.suppress(subprocess.TimeoutExpired):
            sim.process.wait(timeout=0.5 if reply is not None else 3.0)
        if not sim.alive():
            sim.stopped = True  # nothing left to stop; the assertion below says why
            tail = sim.stderr().strip().splitlines()[-1:]
            raise AssertionError(
                f"SERVER BUG: the server died (code {sim.process.returncode}) on 100 000 nested brackets to {name}: {tail}"
            )
        assert reply is not None, f"no reply to deeply nested JSON on {name}, though the server is alive"
        assert reply["ok"] is False and "json" in reply["error"].lower(), reply
        assert sim.step(10)["iterations"] == 10


# --- the command line ---------------------------------------------------------------------------


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def bad_files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("bad_worlds")
    return {
        "broken_xml": _write(folder / "broken.sdf", '<?xml version="1.0"?>\n<sdf version="1.9"><world name="w"><model name="m"><link name="l"></model></world></sdf>\n'),
        "missing_include": _write(folder / "include.sdf", '<?xml version="1.0"?>\n<sdf version="1.9">\n<world name="w">\n<include><uri>model://no_such_model_here</uri></include>\n</world>\n</sdf>\n'),
        "a_model_not_a_world": _write(folder / "model.sdf", '<?xml version="1.0"?>\n<sdf version="1.9"><model name="m"><link name="l"/></model></sdf>\n'),
        "add_no_models": _write(folder / "nobody.sdf", '<?xml version="1.0"?>\n<sdf version="1.9"><world name="nobody"/></sdf>\n'),
    }  # fmt: skip


@pytest.mark.parametrize(
    "case",
    [
        "nosuch",
        "missing_file",
        "broken_xml",
        "missing_include",
        "a_model_not_a_world",
        "broken_robot",
        "add_missing_file",
        "add_no_models",
    ],
)
def test_a_bad_world_or_robot_is_exit_2_and_one_line(case: str, bad_files: dict[str, Path], tmp_path: Path) -> None:
    if case == "nosuch":
        args, named = ["--world", "nosuch"], "nosuch"
    elif case == "missing_file":
        named = str(tmp_path / "missing.sdf")
        args = ["--world", named]
    elif case == "broken_robot":
        named = str(bad_files["broken_xml"])
        args = ["--world", "empty", "--robot", named]
    elif case == "add_missing_file":
        named = str(tmp_path / "missing_people.sdf")
        args = ["--world", "empty", "--add", named]
    elif case == "add_no_models":
        named = str(bad_files[case])
        args = ["--world", "empty", "--add", named]
    else:
        named = str(bad_files[case])
        args = ["--world", named]
    result = subprocess.run(
        server_command(*args, "--listen", endpoint(free_port()), "--quiet"), capture_output=True, text=True, timeout=60
    )
    assert result.returncode == 2, f"exit code {result.returncode}: {result.stderr}"
    lines = result.stderr.splitlines()
    assert any(named in line for line in lines), f"stderr does not name {named}: {result.stderr!r}"
    assert len(lines) == 1, f"SERVER BUG: stderr has {len(lines)} lines, expected one: {lines}"
    assert result.stdout == ""
