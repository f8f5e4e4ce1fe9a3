"""Systems without a running server: the registry, their parameters, rates, limits and odometry."""

from __future__ import annotations

import logging
import math

import pytest
from conftest import ROBOT_SDF

from simbot.description import load_model, load_world
from simbot.description.drive_params import DiffDriveParams, Limits
from simbot.description.model import Param, Plugin
from simbot.description.naming import canonical_name
from simbot.description.plugin_params import number_param
from simbot.description.resources import asset
from simbot.sim.kit.drive import PlanarPose, check_twist
from simbot.sim.kit.rates import Every
from simbot.sim.loop.registry import lookup, registered
from simbot.sim.loop.system import SystemConfigError
from simbot.sim.systems.diff_drive import wheel_motion
from simbot.sim.systems.recognised import Recognised


def _plugin(name: str, filename: str = "", **params: str) -> Plugin:
    return Plugin(name, filename, tuple(Param(tag, text) for tag, text in params.items()))


@pytest.mark.parametrize(
    ("name", "filename"),
    [
        ("gz::sim::systems::DiffDrive", "gz-sim-diff-drive-system"),
        ("ignition::gazebo::systems::DiffDrive", "libignition-gazebo-diff-drive-system.so"),
        ("diff_drive", "libignition-gazebo6-diff-drive-system.so"),
        ("dd", "gz-sim-diff-drive-system"),
    ],
)
def test_every_gazebo_spelling_maps_to_one_system(name: str, filename: str) -> None:
    assert canonical_name(_plugin(name, filename)) == "DiffDrive"


def test_the_robot_and_world_plugins_are_all_registered() -> None:
    """Through the entry-point group, as a third party's would be; nothing is unknown in our own files."""
    plugins = list(load_model(ROBOT_SDF).plugins) + list(load_world(asset("worlds/warehouse.sdf")).plugins)
    assert {canonical_name(p) for p in plugins} <= set(registered())
    assert registered()["Physics"] is Recognised


def test_an_unknown_plugin_is_a_warning_naming_it(caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level(logging.WARNING):
        assert (
            lookup(
                _plugin(
                    "ignition::gazebo::systems::TriggeredPublisher", "libignition-gazebo-triggered-publisher-system.so"
                )
            )
            is None
        )
    assert "TriggeredPublisher" in caplog.text


def test_diff_drive_reads_gazebo_and_reference_names() -> None:
    """`frame_id`/`child_frame_id` (gz-sim) and `odometry_frame`/`base_frame` (the original robot) both work."""
    model = load_model(ROBOT_SDF)
    ours = DiffDriveParams.parse(model.plugins[0], model, "flexley_tug")
    assert (ours.frame_id, ours.child_frame_id, ours.odom_rate, len(ours.left)) == ("odom", "base_footprint", 50.0, 2)
    joints = {"left_joint": "front_left_wheel_joint", "right_joint": "front_right_wheel_joint"}
    legacy = _plugin(
        "dd",
        odometry_frame="odom2",
        base_frame="base_link",
        update_rate="20",
        wheel_separation="0.4",
        wheel_radius="0.075",
        **joints,
    )
    params = DiffDriveParams.parse(legacy, model, "flexley_tug")
    assert (params.frame_id, params.child_frame_id, params.odom_rate) == ("odom2", "base_link", 20.0)


@pytest.mark.parametrize(
    ("params", "message"),
    [
        (
            {
                "left_joint": "nope",
                "right_joint": "front_right_wheel_joint",
                "wheel_separation": "0.4",
                "wheel_radius": "0.075",
            },
            "no joint 'nope'",
        ),
        (
            {
                "left_joint": "front_left_wheel_joint",
                "right_joint": "front_right_wheel_joint",
                "wheel_separation": "wide",
                "wheel_radius": "0.075",
            },
            "<wheel_separation> expected a number",
        ),
        (
            {
                "left_joint": "front_left_wheel_joint",
                "right_joint": "front_right_wheel_joint",
                "wheel_separation": "0.4",
                "wheel_radius": "-1",
            },
            "positive",
        ),
        ({"right_joint": "front_right_wheel_joint"}, "<left_joint>"),
    ],
)
def test_bad_diff_drive_parameters_name_the_parameter(params: dict[str, str], message: str) -> None:
    with pytest.raises(SystemConfigError, match=message):
        DiffDriveParams.parse(_plugin("gz::sim::systems::DiffDrive", **params), load_model(ROBOT_SDF), "flexley_tug")


def test_number_param_rejects_non_finite() -> None:
    with pytest.raises(SystemConfigError, match="update_rate"):
        number_param(_plugin("p", update_rate="nan"), "update_rate")


@pytest.mark.parametrize("rate", [30.0, 50.0, 100.0, 200.0, 7.0])
def test_every_fires_at_its_rate_on_1ms_steps(rate: float) -> None:
    """Over 10 s of 1 ms steps (the first at 1 ms), exactly rate × 10 firings (30 Hz must not become 29.4 Hz)."""
    every = Every.hz(rate)
    fired = sum(every.due(step * 1_000_000) for step in range(1, 10_000))
    assert fired == round(rate * 10)


@pytest.mark.parametrize(("rate", "step_ns"), [(30.0, 5_000_000), (7.0, 1_000_000), (500.0, 5_000_000)])
def test_a_rate_passed_over_and_caught_up_fires_where_asking_every_step_would(rate: float, step_ns: int) -> None:
    """A camera no one watches is not asked (the rendering system passes it over); watched again, it
    catches up (`Every.catch_up`) and fires at the steps where a rate asked at every step fires,
    whether it left off mid-period, periods ago, never asked since the start, or (500 Hz on 5 ms
    steps) at every step."""
    asked, skipped = Every.hz(rate), Every.hz(rate)
    steps = [step * step_ns for step in range(1, 2_000)]
    away = set(range(0, 3)) | set(range(100, 377)) | set(range(900, 901)) | set(range(1500, 1999))
    for index, now in enumerate(steps):
        expected = asked.due(now)
        if index in away:
            continue
        if index - 1 in away:
            skipped.catch_up(now, step_ns)
        assert skipped.due(now) == expected, f"step {index} at {now} ns"


@pytest.mark.parametrize(("came", "asked_from"), [(10, 11), (10, 40), (10, 10 + 200)])
def test_a_rate_that_came_at_run_time_fires_at_its_first_step_then_on_its_grid(came: int, asked_from: int) -> None:
    """A camera created at run time (after step `came`) and first asked at a later step fires where
    a rate asked from the step after it came fires: at that first step, then on its grid."""
    step_ns, rate = 1_000_000, 30.0
    asked, late = Every.hz(rate), Every.hz(rate)
    for step in range(came + 1, 1_000):
        now = step * step_ns
        expected = asked.due(now)
        if step < asked_from:
            continue
        if step == asked_from:
            late.catch_up(now, step_ns, came * step_ns)
        assert late.due(now) == expected, f"step {step}"


def test_limits_clamp_and_ramp() -> None:
    limits = Limits(min_value=-0.5, max_value=1.0, min_rate=-2.0, max_rate=1.0)
    assert (limits.clamp(3.0), limits.clamp(-3.0), limits.clamp(0.2)) == (1.0, -0.5, 0.2)
    assert limits.ramp(0.0, 1.0, 0.1) == pytest.approx(0.1)
    assert limits.ramp(1.0, 0.0, 0.1) == pytest.approx(0.8)
    assert Limits().ramp(0.0, 5.0, 0.001) == 5.0


def test_odometry_integrates_an_arc_exactly() -> None:
    """Wheels that trace a quarter circle of 1 m arc, in 100 updates: the exact end pose."""
    pose, radius, sep = PlanarPose(), 0.075, 0.4
    turn = math.pi / 2
    arc = 1.0  # metres travelled by the centre
    left, right = (arc - turn * sep / 2) / radius, (arc + turn * sep / 2) / radius
    for _ in range(100):
        pose.advance(*wheel_motion(left / 100, right / 100, radius, sep))
    r = arc / turn
    assert (pose.x, pose.y, pose.yaw) == pytest.approx((r, r, turn), abs=1e-9)


class _Twist:
    def __init__(self, vx: float, wz: float) -> None:
        self.linear = type("V", (), {"x": vx, "y": 0.0, "z": 0.0})()
        self.angular = type("V", (), {"x": 0.0, "y": 0.0, "z": wz})()


@pytest.mark.parametrize(
    ("vx", "wz", "ok"), [(0.5, 0.5, True), (math.nan, 0, False), (0, math.inf, False), (1e6, 0, False), (-99, 99, True)]
)
def test_check_twist(vx: float, wz: float, ok: bool) -> None:
    assert (check_twist(_Twist(vx, wz)) is None) == ok
