"""Benchmark of how the dynamic tug turns (issue 55's goals): in the warehouse, the DiffDrive's wheel
speeds for 0.5 m/s on a 3 m radius, held for 12 s after 3 s to settle, with simbot's tyre and with
the knife-edge it replaced (friction saturating at 1 cm/s of slip, stated as SDF's force-dependent
slip, `<slip1>`/`<slip2>`, for the tug's wheel loads), in one run. For each: where the turn is
centred ahead of the middle between the axles, the body's sideways slip over its travel, the wheel
odometry's sideways error per 0.1 m of travel, the yaw rate over the command and odometry's yaw
rate over the true one, beside the steady turn the SDF implies (`steady_turn`, docs/robot.md).

    python benchmarks/bench_turn.py
"""

from __future__ import annotations

import dataclasses
import math

from tables import publish

from simbot.description import load_model, load_world
from simbot.description.model import Model
from simbot.description.poses import Pose
from simbot.description.resources import asset
from simbot.sim.physics import Physics
from simbot.sim.physics.steady_turn import Chassis, Placed, SteadyTurn, steady_turn, turn_centre
from simbot.sim.systems.diff_drive import wheel_motion
from simbot.transform import yaw_of

SPEED, RADIUS = 0.5, 3.0
SEPARATION, WHEEL = 0.4, 0.075
LEFT, RIGHT = ("front_left_wheel_joint", "back_left_wheel_joint"), ("front_right_wheel_joint", "back_right_wheel_joint")
KNIFE_EDGE_SLIP = 0.01
"""m/s: the slip at which the old friction saturated."""


def knife_edge(model: Model, load: float) -> Model:
    """The tug with its wheels' friction saturating at KNIFE_EDGE_SLIP under `load` (N), as SDF slip."""
    return model.with_wheel_friction(
        lambda f: dataclasses.replace(f, slip1=KNIFE_EDGE_SLIP / (f.mu * load), slip2=KNIFE_EDGE_SLIP / (f.mu2 * load))
    )


def measure(model: Model) -> dict[str, float]:
    """The turn's figures in the warehouse (ground truth against wheel odometry)."""
    world = load_world(asset("worlds/warehouse.sdf"))
    sim = Physics(world)
    for other in world.models:
        if other.name != "trolley":
            sim.add_model(other)
    sim.add_model(model, "flexley_tug", Pose((-2.5, 0.0, 0.1)))
    half = SPEED / RADIUS * SEPARATION / 2
    for joints, speed in ((LEFT, SPEED - half), (RIGHT, SPEED + half)):
        for joint in joints:
            sim.set_joint_velocity("flexley_tug", joint, speed / WHEEL, 10000.0)
    for _ in range(3000):
        sim.step()
    truth, (left, right) = [sim.model_pose("flexley_tug")], _sides(sim)
    starts, laterals = [truth[0]], []
    for _ in range(12000):
        sim.step()
        now = sim.model_pose("flexley_tug")
        if math.dist(now[0][:2], starts[-1][0][:2]) >= 0.1:  # the odometry rolls on, straight ahead
            laterals.append(abs(_in_frame(starts[-1], now)[1]))
            starts.append(now)
        truth.append(now)
    end_left, end_right = _sides(sim)
    *_, odom_turn = wheel_motion(end_left - left, end_right - right, WHEEL, SEPARATION)
    first, last = truth[0], truth[-1]
    turned = sum(math.remainder(yaw_of(b[1]) - yaw_of(a[1]), math.tau) for a, b in zip(truth, truth[1:]))
    travel = sum(math.dist(a[0][:2], b[0][:2]) for a, b in zip(truth, truth[1:]))
    pivot, _ = turn_centre(first, last)
    sim.close()
    return {
        "pivot": pivot,
        "slip": abs(pivot) * abs(turned) / travel,
        "odom_side": max(laterals),
        "yaw": turned / 12.0 / (SPEED / RADIUS),
        "odom_yaw": odom_turn / turned,
    }


def _sides(sim: Physics) -> tuple[float, float]:
    states = sim.joint_states("flexley_tug", [*LEFT, *RIGHT])
    return (states[0][0] + states[1][0]) / 2, (states[2][0] + states[3][0]) / 2


def _in_frame(base: Placed, point: Placed) -> tuple[float, float]:
    yaw = yaw_of(base[1])
    dx, dy = point[0][0] - base[0][0], point[0][1] - base[0][1]
    return math.cos(yaw) * dx + math.sin(yaw) * dy, -math.sin(yaw) * dx + math.cos(yaw) * dy


def main() -> None:
    model = load_model(asset("urdf/flexley_tug.sdf"))
    chassis = Chassis.of(model)
    derived: SteadyTurn = steady_turn(chassis, SPEED, SPEED / RADIUS)
    load = float(chassis.loads().mean())
    tyre, edge = measure(model), measure(knife_edge(model, load))
    rows = [
        ("turn centre ahead of the middle, m", derived.pivot, "pivot", "{:.3f}"),
        ("body's sideways slip ÷ distance travelled", derived.side_slip, "slip", "{:.2%}"),
        ("odometry's sideways error per 0.1 m of travel (most), m", derived.side_slip * 0.1, "odom_side", "{:.4f}"),
        ("yaw rate ÷ commanded", derived.yaw_ratio, "yaw", "{:.3f}"),
        ("odometry's yaw rate ÷ true", derived.odom_yaw_ratio, "odom_yaw", "{:.3f}"),
    ]
    table = [
        f"| the tug in the warehouse, 0.5 m/s on a {RADIUS:g} m radius | derived (steady_turn) | simbot's tyre | "
        "the knife-edge (before) |",
        "| --- | --- | --- | --- |",
        *(
            f"| {label} | {fmt.format(d)} | {fmt.format(tyre[k])} | {fmt.format(edge[k])} |"
            for label, d, k, fmt in rows
        ),
    ]
    publish("turn", table)


if __name__ == "__main__":
    main()
