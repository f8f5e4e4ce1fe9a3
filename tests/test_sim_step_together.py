"""Worlds stepped together (`simbot.sim.loop.simulation.step_together`, a vector env's sub-envs):
each world sends what it sends stepped alone, bit for bit.

Three lockstep worlds of the warehouse with its people and the kinematic tug, on `LocalNode`s in
this process (as `simbot-server` builds them), each tug driven its own way: the people of all three
think in one pass of the crowd's arrays and the IMUs sample in one pass, each world with its own
clock (the second is reset part of the way, so that its sim time differs from the others', as a
sub-env's does after its autoreset). The people's poses, the IMU and the odometry must equal those
of the same three worlds stepped one after the other.
"""

from __future__ import annotations

from collections import defaultdict
from typing import Any

import pytest

from simbot.bus import encode, messages
from simbot.bus.local import LocalNode
from simbot.sim.loop.bus_view import SimBus
from simbot.sim.loop.simulation import step_together
from simbot.sim.server import build_world, parse_config
from simbot.sim.systems.crowd import SocialForce

ARGS = ["--world", "warehouse", "--add", "warehouse_people", "--physics", "kinematic", "--mode", "lockstep"]
STEPS = 160
"""0.8 s of 5 ms steps: 40 thinks of each person at 50 Hz, 160 IMU samples."""
RESET_AT = 61
"""The step before which the second world is reset: its clock restarts, the others' go on."""
KEYS = ("imu_scan", "odom", "lidar_front", *(f"model/worker_{w}/pose" for w in ("north", "crossing", "west")))
DRIVES = ((0.6, 0.3), (0.4, -0.5), (0.8, 0.0))
"""Each world's tug's (v, ω)."""

Recording = dict[str, list[bytes]]


def build(seed: int) -> tuple[Any, LocalNode]:
    node = LocalNode()
    return build_world(parse_config([*ARGS, "--seed", str(seed)]), SimBus(node)), node


def run(together: bool) -> list[Recording]:
    """Every message on KEYS of each world, CDR-encoded, the worlds stepped together or alone."""
    worlds = [build(seed) for seed in (3, 4, 5)]
    got: list[Recording] = [defaultdict(list) for _ in worlds]
    try:
        for (_, node), drive, record in zip(worlds, DRIVES, got, strict=True):
            for key in KEYS:

                def deliver(msg: Any, key: str = key, record: Recording = record) -> None:
                    record[key].append(encode(msg))

                node.hub.listen(key, deliver)
            command = node.publisher("cmd_vel", messages.Twist)
            command.put(messages.twist((drive[0], 0.0, 0.0), (0.0, 0.0, drive[1])))
        sims = [world.sim for world, _ in worlds]
        for step in range(STEPS):
            if step == RESET_AT:
                worlds[1][0].reset(None)
            if together:
                step_together(sims)
            else:
                for sim in sims:
                    sim.step()
        assert sims[1].clock.now_ns == (STEPS - RESET_AT) * 5_000_000 != sims[0].clock.now_ns
    finally:
        for world, _ in worlds:
            world.close()
    return got


@pytest.fixture(scope="module")
def alone() -> list[Recording]:
    return run(together=False)


def test_worlds_stepped_together_send_what_each_sends_alone(alone: list[Recording]) -> None:
    spent: list[int] = []
    original = SocialForce.pre_update_all.__func__  # type: ignore[attr-defined]

    def counted(cls: type[SocialForce], batches: Any) -> None:
        spent.append(len(batches))
        original(cls, batches)

    SocialForce.pre_update_all = classmethod(counted)  # type: ignore[method-assign, assignment]
    try:
        together = run(together=True)
    finally:
        SocialForce.pre_update_all = classmethod(original)  # type: ignore[method-assign, assignment]
    assert spent and set(spent) == {3}, "the three worlds' people should step in one call"
    for index, (a, b) in enumerate(zip(together, alone, strict=True)):
        for key in KEYS:
            assert len(b[key]) >= 4, f"world {index} {key}: {len(b[key])} messages"
            assert a[key] == b[key], f"world {index} {key}: stepped together differs from alone"
