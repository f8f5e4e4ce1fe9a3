"""simbot.gym: Navigate-v0 and Dock-v0 on real worlds, no mocks.

Each environment steps its own world (the empty world, or a test world with one wall: in its
process, off the bus, unless it observes a camera or is told to `watch`, when it starts its own
lockstep server) and every assertion is physical: a step at 0.5 m/s moves the robot 0.05 m by the world's ground truth; a
goal 1 m ahead is reached by a scripted drive; a wall is hit, seen by the scan where it stands, and
ends the episode; the tug docks under the trolley by the docking client's rule. The same seed
gives the same first observation byte for byte (cameras included), on one server and on another;
Gymnasium's own checker passes on both environments; a server that hangs or dies is an error
naming it, and `close()` leaves none of its processes behind.
"""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
import pytest
from bus_helpers import free_port, unique_namespace
from conftest import ROBOT_SDF
from gymnasium.utils.env_checker import check_env
from server_helpers import killed_script, running_server, wait_until

import simbot.gym
from simbot.gym import EnvConfigError, SimServerError
from simbot.gym.base import SimbotEnv
from simbot.gym.options import EnvOptions, check_limits
from simbot.gym.robot import RobotFacts

FAST = {"world": "empty", "max_linear": 1.0, "max_angular": 1.0, "camera_size": (32, 24)}
"""The empty world, actions within ±1 (the SDF allows 7.5 m/s), cameras small when asked for."""
WALL_X = 2.5
"""The test world's wall: its centre 2.5 m ahead of the origin, 0.2 m thick, so its face is at 2.4."""
WALL_WORLD = f"""<?xml version="1.0"?>
<sdf version="1.9">
  <world name="walled">
    <physics name="1ms" type="ignore"><max_step_size>0.001</max_step_size></physics>
    <model name="ground_plane">
      <static>true</static>
      <link name="link">
        <collision name="collision"><geometry><plane><normal>0 0 1</normal><size>20 20</size></plane></geometry></collision>
      </link>
    </model>
    <model name="wall">
      <static>true</static>
      <pose>{WALL_X} 0 0.5 0 0 0</pose>
      <link name="link">
        <collision name="slab"><geometry><box><size>0.2 4 1</size></box></geometry></collision>
        <visual name="slab"><geometry><box><size>0.2 4 1</size></box></geometry></visual>
      </link>
    </model>
  </world>
</sdf>
"""


def make(env_id: str, **kwargs: Any) -> Any:
    """`gymnasium.make` as a user calls it (the registered id, Gymnasium's wrappers)."""
    return gymnasium.make(env_id, **kwargs)


def unwrapped(env: Any) -> SimbotEnv:
    inner = env.unwrapped
    assert isinstance(inner, SimbotEnv)
    return inner


def ground_truth(env: Any, model: str = "flexley_tug") -> tuple[float, float, float]:
    """A model's (x, y, yaw) from the world state."""
    state = unwrapped(env).session.state()["models"][model]
    x, y, _ = state["position"]
    qx, qy, qz, qw = state["orientation"]
    return x, y, math.atan2(2 * (qw * qz + qx * qy), 1 - 2 * (qy * qy + qz * qz))


def group_members(pgid: int) -> list[int]:
    """Live (not zombie) processes of process group `pgid`, from /proc."""
    members = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            fields = (entry / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[2]) == pgid and fields[0] != "Z":
            members.append(int(entry.name))
    return members


def drive(env: Any, v: float, w: float = 0.0, *extra: float) -> tuple[Any, float, bool, bool, dict[str, Any]]:
    obs, reward, terminated, truncated, info = env.step(np.array([v, w, *extra], np.float32))
    return obs, float(reward), bool(terminated), bool(truncated), info


@pytest.fixture(scope="module")
def nav() -> Iterator[Any]:
    env = make(simbot.gym.NAVIGATE, **FAST)
    yield env
    env.close()


@pytest.fixture(scope="module")
def walled(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Any]:
    world = tmp_path_factory.mktemp("gym") / "walled.sdf"
    world.write_text(WALL_WORLD)
    env = make(simbot.gym.NAVIGATE, **{**FAST, "world": str(world)})
    yield env
    env.close()


@pytest.fixture(scope="module")
def dock() -> Iterator[Any]:
    env = make(simbot.gym.DOCK, **FAST)
    yield env
    env.close()


# --- without a server ---------------------------------------------------------------------------


def test_import_registers_both_environments() -> None:
    for env_id, entry in (("simbot/Navigate-v0", "navigate:NavigateEnv"), ("simbot/Dock-v0", "dock:DockEnv")):
        assert gymnasium.registry[env_id].entry_point == f"simbot.gym.{entry}"


def test_the_action_space_is_the_drives_limit_from_the_robots_sdf() -> None:
    """The tug's DiffDrive states no velocity limit, so its wheels' do: |v| ≤ 100 rad/s × 0.075 m,
    |ω| ≤ that speed on both sides over the 0.4 m separation. Read here from the SDF independently."""
    model = ET.parse(ROBOT_SDF).getroot().find("model")
    assert model is not None
    drive = next(p for p in model.iter("plugin") if p.get("name", "").endswith("DiffDrive"))
    assert drive.find("max_linear_velocity") is None
    wheel = min(
        float(j.findtext("axis/limit/velocity") or "nan") for j in model.iter("joint") if "wheel" in j.get("name", "")
    )
    radius, separation = float(drive.findtext("wheel_radius") or ""), float(drive.findtext("wheel_separation") or "")
    linear, angular = check_limits(EnvOptions(), RobotFacts.read(ROBOT_SDF, "empty"))
    assert (linear, angular) == pytest.approx((wheel * radius, 2 * wheel * radius / separation))
    with pytest.raises(EnvConfigError, match=r"max_linear 9\.0: must be in \(0, 7\.5\]"):
        check_limits(EnvOptions(max_linear=9.0), RobotFacts.read(ROBOT_SDF, "empty"))


def test_a_lidar_without_a_topic_is_observed_on_gazebos_default_key(tmp_path: Path) -> None:
    """The server publishes a sensor that states no `<topic>` on Gazebo's default key; the env names
    its sources by the same rule, so it observes that scan: the same as the tug's own, whose front
    lidar states one (before, the env listened on the sensor's name, where nothing came)."""
    text = ROBOT_SDF.read_text(encoding="utf-8").replace("../meshes/", f"{ROBOT_SDF.parent.parent / 'meshes'}/")
    assert text.count("<topic>lidar_front</topic>") == 1
    robot = tmp_path / "tug_without_a_front_topic.sdf"
    robot.write_text(text.replace("<topic>lidar_front</topic>", ""), encoding="utf-8")
    key = RobotFacts.read(robot, "empty").lidars["lidar_front"]
    assert key == "world/empty/model/flexley_tug/link/base_scan_front/sensor/lidar_front/scan"
    scans = []
    for sdf in (ROBOT_SDF, robot):
        env = gymnasium.make(simbot.gym.NAVIGATE, world="empty", physics="kinematic", robot=sdf, timeout=20.0)
        try:
            obs, _ = env.reset(seed=3)
            obs, *_ = env.step(np.array([0.5, 0.2], np.float32))
            scans.append(obs["scan"])
        finally:
            env.close()
    assert np.array_equal(scans[0], scans[1]), "the scan differs from the tug's own"


@pytest.mark.parametrize(
    ("kwargs", "named"),
    [
        ({"world": "moon"}, "unknown world 'moon'"),
        ({"cameras": ("camera_top",)}, "camera 'camera_top': the robot has no such camera"),
        ({"control_period": 0.05}, "control_period 0.05 s: must be a multiple of 0.02 s"),
        ({"control_period": 0.0105}, "not a whole number of 0.001 s steps"),
        ({"colour": "red"}, "unknown option(s) colour"),
        ({"render_mode": "ansi"}, "render_mode 'ansi'"),
        ({"physics": "ragdoll"}, "physics 'ragdoll': one of dynamic, kinematic"),
        ({"physics": "kinematic", "control_period": 0.0105}, "not a whole number of 0.005 s steps"),
    ],
)
def test_bad_options_are_one_clear_error_naming_them_before_a_server_starts(kwargs: dict[str, Any], named: str) -> None:
    before = server_children()
    with pytest.raises(EnvConfigError) as raised:
        make(simbot.gym.NAVIGATE, **kwargs)
    assert named in str(raised.value) and "\n" not in str(raised.value)
    assert server_children() - before == set()


def server_children() -> set[int]:
    """This process's children that run a simbot server (the environments' own)."""
    found = set()
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            parent = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
            if parent == os.getpid() and b"simbot.sim.server" in (entry / "cmdline").read_bytes():
                found.add(int(entry.name))
        except OSError:
            continue
    return found


# --- Navigate in the empty world ----------------------------------------------------------------


def test_a_step_of_0_1_s_at_0_5_m_s_moves_the_robot_0_05_m(nav: Any) -> None:
    """After a second at 0.5 m/s (the drive up to speed), one more step moves the ground truth
    0.05 m straight ahead; the observation's twist says 0.5 m/s and its goal comes as much nearer."""
    obs, info = nav.reset(options={"start": (0.0, 0.0, 0.0), "goal": (6.0, 0.0, 0.0)})
    assert info["sim_time"] == pytest.approx(0.1) and obs["goal"][0] == pytest.approx(6.0, abs=0.01)
    for _ in range(10):
        obs, *_ = drive(nav, 0.5)
    before = ground_truth(nav)
    goal_before = float(obs["goal"][0])
    obs, _, terminated, truncated, info = drive(nav, 0.5)
    after = ground_truth(nav)
    assert info["sim_time"] == pytest.approx(1.2, abs=1e-9)
    assert after[0] - before[0] == pytest.approx(0.05, abs=0.003)
    assert abs(after[1] - before[1]) < 0.002 and abs(after[2]) < 0.01
    assert obs["twist"][0] == pytest.approx(0.5, abs=0.01) and abs(obs["twist"][1]) < 0.01
    assert goal_before - float(obs["goal"][0]) == pytest.approx(after[0] - before[0], abs=1e-4)
    assert obs["goal"][0] == pytest.approx(6.0 - after[0], abs=1e-3)  # of this step's end, not the last's
    assert not terminated and not truncated and info["collisions"] == 0


def test_a_goal_one_metre_ahead_is_reached_by_a_scripted_drive(nav: Any) -> None:
    nav.reset(options={"start": (0.0, 0.0, 0.0), "goal": (1.0, 0.0, 0.0)})
    steps = 0
    while steps < 40:
        _, reward, terminated, truncated, info = drive(nav, 0.5)
        steps += 1
        if terminated or truncated:
            break
    assert terminated and not truncated and info["success"] is True, info
    x, y, yaw = ground_truth(nav)
    assert math.hypot(1.0 - x, y) <= 0.3 and abs(yaw) <= 0.3
    assert reward > 9.0  # the success bonus (10) on the last step
    assert 10 <= steps <= 20  # 0.7 m at up to 0.5 m/s


def test_an_action_outside_the_space_is_clipped_and_counted(nav: Any) -> None:
    nav.reset(options={"start": (0.0, 0.0, 0.0), "goal": (8.0, 0.0, 0.0)})
    for _ in range(10):
        obs, *_, info = drive(nav, 5.0)  # the space allows 1.0
    assert info["clipped_actions"] == 10
    assert obs["twist"][0] == pytest.approx(1.0, abs=0.02)
    obs, *_, info = drive(nav, 0.5)
    assert info["clipped_actions"] == 10
    with pytest.raises(ValueError, match="not finite"):
        unwrapped(nav).step(np.array([math.nan, 0.0], np.float32))


def test_the_same_seed_draws_the_same_episode_and_another_seed_another(nav: Any) -> None:
    first, info = nav.reset(seed=11)
    drive(nav, 0.8, 0.5)
    again, info_again = nav.reset(seed=11)
    other, _ = nav.reset(seed=12)
    assert info["seed"] == info_again["seed"] == 11
    assert all(first[key].tobytes() == again[key].tobytes() for key in first)
    assert first["goal"].tobytes() != other["goal"].tobytes()
    start = ground_truth(nav)
    assert unwrapped(nav).places.blocker((start[0], start[1], start[2])) is None


# --- a wall ---------------------------------------------------------------------------------------


def test_the_scan_sees_the_wall_where_it_stands(walled: Any) -> None:
    obs, _ = walled.reset(options={"start": (0.0, 0.0, 0.0), "goal": (-3.0, 0.0, 0.0)})
    scan = obs["scan"]
    ahead = scan[len(scan) // 2]  # bin i is centred on −π + i·2π/bins: the middle one looks along +x
    assert ahead == pytest.approx(WALL_X - 0.1, abs=0.02)
    assert scan[0] == pytest.approx(unwrapped(walled).robot.lidar_reach)  # nothing behind: no return


def test_driving_into_the_wall_ends_the_episode_with_a_collision(walled: Any) -> None:
    """At 1 m/s the scan ahead shortens with the ground truth at every step (it is of the step just
    taken: a scan 0.1 s old would be 0.1 m long), until the chassis meets the wall."""
    walled.reset(options={"start": (0.0, 0.0, 0.0), "goal": (-3.0, 0.0, 0.0)})
    checked = 0
    for _ in range(40):
        obs, reward, terminated, truncated, info = drive(walled, 1.0)
        if terminated or truncated:
            break
        ahead, x = float(obs["scan"][len(obs["scan"]) // 2]), ground_truth(walled)[0]
        if WALL_X - 0.1 - x > 1.2:  # the lidar (0.99 m ahead of base_link) sees nothing nearer than 0.08 m
            assert ahead == pytest.approx(WALL_X - 0.1 - x, abs=0.02)
            checked += 1
    assert terminated and info["success"] is False and info["collisions"] == 1, info
    assert checked >= 5
    assert any(name.startswith("wall::") for name in info["touched"]), info["touched"]
    assert reward < -9.0  # the collision penalty (10)
    x, _, _ = ground_truth(walled)
    front = x + unwrapped(walled).robot.footprint.xmax
    assert front == pytest.approx(WALL_X - 0.1, abs=0.1)


def test_a_goal_inside_the_wall_is_an_error_naming_it(walled: Any) -> None:
    with pytest.raises(
        EnvConfigError, match=r"goal \(2\.5, 0, 0\) is not free for the robot: within 0\.3 m of wall::link::slab"
    ):
        walled.reset(options={"goal": (WALL_X, 0.0, 0.0)})


# --- cameras, determinism, Gymnasium's checker ---------------------------------------------------


def test_the_same_seed_gives_the_same_first_observation_byte_for_byte_on_two_servers() -> None:
    kwargs = {**FAST, "cameras": ("camera_front",), "render_mode": "rgb_array"}
    first = make(simbot.gym.NAVIGATE, **kwargs)
    try:
        a, _ = first.reset(seed=5)
        for _ in range(3):
            drive(first, 0.7, -0.4)
        b, _ = first.reset(seed=5)
        frame = first.render()
    finally:
        first.close()
    second = make(simbot.gym.NAVIGATE, **kwargs)
    try:
        c, _ = second.reset(seed=5)
    finally:
        second.close()
    assert set(a) == {"scan", "goal", "twist", "camera_front"}
    assert a["camera_front"].shape == (24, 32, 3) and a["camera_front"].dtype == np.uint8
    for key in a:
        assert a[key].tobytes() == b[key].tobytes() == c[key].tobytes(), key
    assert frame is not None and frame.tobytes() == b["camera_front"].tobytes()
    assert len(np.unique(frame.reshape(-1, 3), axis=0)) > 1  # a picture, not a blank


@pytest.mark.parametrize("env_id", [simbot.gym.NAVIGATE, simbot.gym.DOCK])
def test_gymnasiums_checker_passes(env_id: str, nav: Any, dock: Any) -> None:
    env = nav if env_id == simbot.gym.NAVIGATE else dock
    check_env(env.unwrapped)


# --- Dock -----------------------------------------------------------------------------------------


def test_the_tug_docks_under_the_trolley_by_the_docking_rule(dock: Any) -> None:
    """The trolley stands at the origin of the empty world (the environment adds it); from 2.5 m
    behind it the tug drives under it, stops, and attaches once it has been near for 0.4 s. An
    attach asked for from afar is refused and counted."""
    obs, info = dock.reset(options={"start": (-2.5, 0.0, 0.0)})
    assert info["distance"] == pytest.approx(2.5, abs=0.01)
    _, reward, terminated, _, info = drive(dock, 0.0, 0.0, 1.0)
    assert not terminated and info["refused_attach"] == 1 and info["attached"] is False
    assert reward < -0.1
    for _ in range(80):
        obs, _, terminated, _, info = drive(dock, 0.5, 0.0, 0.0)
        if info["distance"] < 0.15:
            break
    assert not terminated and info["distance"] < 0.15
    for _ in range(5):  # near at the end of each step over 0.4 s
        drive(dock, 0.0, 0.0, 0.0)
    _, reward, terminated, _, info = drive(dock, 0.0, 0.0, 1.0)
    assert terminated and info["success"] is True and info["attached"] is True, info
    assert reward > 9.0
    robot, trolley = ground_truth(dock), ground_truth(dock, "trolley")
    assert math.hypot(robot[0] - trolley[0], robot[1] - trolley[1]) <= 0.55


# --- a server given -------------------------------------------------------------------------------


def test_an_environment_uses_a_server_it_is_given_and_leaves_it_running(tmp_path: Path) -> None:
    """`python -m simbot.gym.serve` starts the server an environment would; one given by `endpoint=`
    is driven as the environment's own and is still running after `close()`. A plain server (no
    contact sensors on its robot) is refused, at the first reset, with a line that says how to start one."""
    port, namespace = free_port(), unique_namespace()
    endpoint = f"tcp/127.0.0.1:{port}"
    log = (tmp_path / "serve.log").open("wb")
    command = ["-m", "simbot.gym.serve", "navigate", "--world", "empty", "--listen", endpoint, "--namespace", namespace]
    serve = subprocess.Popen([sys.executable, *command], stdout=log, stderr=log)
    try:
        env = make(simbot.gym.NAVIGATE, **FAST, endpoint=endpoint, namespace=namespace)
        try:
            env.reset(options={"start": (0.0, 0.0, 0.0), "goal": (5.0, 0.0, 0.0)})
            for _ in range(10):
                *_, info = drive(env, 0.5)
            assert ground_truth(env)[0] == pytest.approx(0.45, abs=0.05)  # 1 s at up to 0.5 m/s
            assert info["distance"] == pytest.approx(5.0 - ground_truth(env)[0], abs=0.01)
        finally:
            env.close()
        assert serve.poll() is None, "the environment stopped a server it did not start"
        with running_server("empty") as plain:
            refused = make(simbot.gym.NAVIGATE, **FAST, endpoint=plain.endpoint, namespace=plain.namespace)
            with pytest.raises(EnvConfigError, match=r"runs no contact sensor .*simbot\.gym\.serve"):
                refused.reset()  # an env joins its server at its first reset
            refused.close()
    finally:
        serve.send_signal(signal.SIGTERM)
        assert serve.wait(timeout=30) == 0, (tmp_path / "serve.log").read_text()[-2000:]
        log.close()


# --- a server that hangs or dies ----------------------------------------------------------------------


def wait_gone(group: int, timeout: float = 15.0) -> None:
    """Waits until the process group has no live member (a SIGKILLed process takes a moment to be gone)."""
    wait_until(lambda: not group_members(group), timeout, f"process group {group} to end")


def test_a_hung_or_dead_server_is_an_error_naming_it_and_close_leaves_no_process() -> None:
    env = make(simbot.gym.NAVIGATE, **{**FAST, "cameras": ("camera_front",)})
    session = unwrapped(env).session
    assert session.process is not None and session.server_pid is not None
    group, server = session.process.pid, session.server_pid
    try:
        env.reset(seed=1)  # the first image may take long on a loaded machine: the default timeout
        session.timeout = 3.0
        members = group_members(group)
        assert server in members and len(members) > 2, members  # its keeper, the server, its render workers
        os.kill(server, signal.SIGSTOP)
        with pytest.raises(
            SimServerError, match=r"simbot server `.*simbot\.sim\.server.*` .*did not answer .* within 3 s"
        ):
            drive(env, 0.5)
        os.kill(server, signal.SIGKILL)
        with pytest.raises(SimServerError, match=r"simbot server `.*simbot\.sim\.server.*` .*exited with code -9"):
            drive(env, 0.5)
    finally:
        env.close()
    wait_gone(group)
    env.close()  # twice is harmless


def test_a_process_that_dies_without_closing_its_environment_leaves_no_server() -> None:
    """SIGKILL runs no finaliser: the server's keeper sees its pipe from the environment close."""
    code = (
        "import os, signal, gymnasium, simbot.gym\n"
        "env = gymnasium.make('simbot/Navigate-v0', world='empty', watch=True)\n"
        "env.reset(seed=0)\n"
        "s = env.unwrapped.session\n"
        "print(s.process.pid, s.server_pid, flush=True)\n"
        "os.kill(os.getpid(), signal.SIGKILL)\n"
    )
    group, server = (int(v) for v in killed_script(code).split())
    wait_gone(group)
    assert (
        not Path(f"/proc/{server}").exists() or "Z" in (Path(f"/proc/{server}") / "stat").read_text().split(")")[-1][:3]
    )
