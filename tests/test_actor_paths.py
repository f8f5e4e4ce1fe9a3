"""Where an actor's script puts it (simbot.description.actor_paths), against gz-sim's arithmetic worked by hand.

Scripts are read from SDF text as a user writes them; each expected pose follows from gz-math's
formulas: a Hermite segment p0·h00 + m0·h10 + p1·h01 + m1·h11 of the time fraction s, its tangents
half the chord to the neighbours times (1 − tension), and squad between rotations.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from simbot.description import load_sdf
from simbot.description.actor_paths import ScriptPath
from simbot.description.actor_scripts import ActorModel
from simbot.transform import yaw_of


def _path(tmp_path: Path, script: str) -> ScriptPath:
    path = tmp_path / "actor.sdf"
    path.write_text(f'<?xml version="1.0"?><sdf version="1.9"><actor name="a"><script>{script}</script></actor></sdf>')
    actor = load_sdf(path)
    assert isinstance(actor, ActorModel)
    return ScriptPath.of(actor.script)


def _waypoint(time: float, x: float, y: float = 0.0, yaw: float = 0.0) -> str:
    return f"<waypoint><time>{time}</time><pose>{x} {y} 0 0 0 {yaw}</pose></waypoint>"


def _trajectory(ident: int, *waypoints: str, tension: float = 0.0) -> str:
    return f'<trajectory id="{ident}" type="walk" tension="{tension}">{"".join(waypoints)}</trajectory>'


def _hermite(s: float, p0: float, p1: float, m0: float, m1: float) -> float:
    return (
        (2 * s**3 - 3 * s**2 + 1) * p0 + (s**3 - 2 * s**2 + s) * m0 + (-2 * s**3 + 3 * s**2) * p1 + (s**3 - s**2) * m1
    )


def test_trajectories_play_in_sequence_and_the_script_stays_at_its_end_without_loop(tmp_path: Path) -> None:
    """Two trajectories of 2 s and 4 s: the second starts where the first's time ends, whatever its own
    waypoint times say (it is keyed from its first waypoint); without loop the last pose holds."""
    script = (
        "<loop>false</loop>"
        + _trajectory(0, _waypoint(0, 0), _waypoint(2, 2))
        + _trajectory(1, _waypoint(10, 2), _waypoint(14, 2, 4))
    )
    path = _path(tmp_path, script)
    assert path.pose_at(1.0).position[0] == pytest.approx(_hermite(0.5, 0, 2, 1, 1))
    assert path.pose_at(2.0).position == pytest.approx((2.0, 0.0, 0.0))
    assert path.pose_at(4.0).position == pytest.approx((2.0, _hermite(0.5, 0, 4, 2, 2), 0.0))
    assert path.pose_at(6.0).position == pytest.approx((2.0, 4.0, 0.0))
    assert path.pose_at(60.0).position == pytest.approx((2.0, 4.0, 0.0))


def test_loop_starts_over_after_the_delay(tmp_path: Path) -> None:
    path = _path(tmp_path, "<delay_start>3</delay_start>" + _trajectory(0, _waypoint(0, 0), _waypoint(2, 2)))
    assert path.pose_at(2.9).position[0] == 0.0
    assert path.pose_at(4.0).position[0] == pytest.approx(1.0)
    assert path.pose_at(3 + 2 + 1.0).position[0] == pytest.approx(1.0)  # one round later
    assert path.pose_at(3 + 2 * 7 + 0.5).position[0] == pytest.approx(_hermite(0.25, 0, 2, 1, 1))


def test_tension_one_stops_at_every_waypoint_and_zero_keeps_the_pace_through_the_middle_ones(tmp_path: Path) -> None:
    """Tension 1: zero tangents, the smoothstep 3s² − 2s³ on every segment. Tension 0 with evenly
    spaced waypoints in a line: the middle segments are linear (tangent = chord)."""
    waypoints = [_waypoint(t, t) for t in range(4)]
    stops = _path(tmp_path, _trajectory(0, *waypoints, tension=1.0))
    assert stops.pose_at(1.25).position[0] == pytest.approx(1 + 3 * 0.25**2 - 2 * 0.25**3)
    flows = _path(tmp_path, _trajectory(0, *waypoints, tension=0.0))
    assert flows.pose_at(1.25).position[0] == pytest.approx(1.25)
    assert flows.pose_at(0.25).position[0] == pytest.approx(_hermite(0.25, 0, 1, 0.5, 1.0))


def test_a_turn_in_place_is_squad_half_way_and_exact_at_the_waypoints(tmp_path: Path) -> None:
    path = _path(tmp_path, "<loop>false</loop>" + _trajectory(0, _waypoint(0, 1, 1, 0.0), _waypoint(2, 1, 1, 1.2)))
    assert yaw_of(path.pose_at(0.0).orientation) == 0.0
    assert yaw_of(path.pose_at(1.0).orientation) == pytest.approx(0.6, abs=1e-9)
    assert yaw_of(path.pose_at(2.0).orientation) == pytest.approx(1.2, abs=1e-12)
    assert path.pose_at(1.0).position == pytest.approx((1.0, 1.0, 0.0))


def test_a_closed_path_takes_its_end_tangents_from_across_the_seam(tmp_path: Path) -> None:
    """First waypoint = last: the first tangent is half of (p1 − p[n−2]), as gz-math's closed spline."""
    square = [_waypoint(0, 0, 0), _waypoint(1, 1, 0), _waypoint(2, 1, 1), _waypoint(3, 0, 1), _waypoint(4, 0, 0)]
    path = _path(tmp_path, _trajectory(0, *square))
    x = path.pose_at(0.5).position[0]
    assert x == pytest.approx(_hermite(0.5, 0, 1, 0.5 * (1 - 0), 0.5 * (1 - 0)))
    y = path.pose_at(0.5).position[1]
    assert y == pytest.approx(_hermite(0.5, 0, 0, 0.5 * (0 - 1), 0.5 * (1 - 0)))


def test_auto_start_false_holds_the_start_and_no_script_stands_still(tmp_path: Path) -> None:
    held = _path(tmp_path, "<auto_start>false</auto_start>" + _trajectory(0, _waypoint(0, 3), _waypoint(2, 5)))
    assert held.pose_at(1.0).position[0] == 3.0
    assert _path(tmp_path, "").pose_at(5.0).position == (0.0, 0.0, 0.0)


def test_the_same_time_gives_the_same_pose_bit_for_bit(tmp_path: Path) -> None:
    script = _trajectory(0, _waypoint(0, 0, 0, 0.3), _waypoint(1.7, 2, 1, 2.0), _waypoint(3.1, -1, 2, -2.5))
    first, second = _path(tmp_path, script), _path(tmp_path, script)
    times = [i * 0.001 for i in range(0, 7000, 37)]
    assert [first.pose_at(t) for t in times] == [second.pose_at(t) for t in times]
    assert all(math.isclose(sum(q * q for q in first.pose_at(t).orientation), 1.0) for t in times)
