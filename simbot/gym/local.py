"""An environment's world in its own process, off the bus: what a training run no one watches uses.

`LocalSession` has `Session`'s requests (send, step, reset, set_pose, state, check, close) and
runs the very world a started server would run for the same `ServerSpec` (`simbot.sim.server`'s
`parse_config` and `build_world`, lockstep), with its systems on a `LocalNode`: each message a
system publishes reaches the environment's observer as the object it is, with no Zenoh, no CDR,
no other process and no round trip. A step is `steps` calls of the simulation's step; a request
world control would answer is a call on the world. The observations therefore equal the bus
path's for the same seed (tests/test_gym_vector.py compares them).

Cameras render in worker processes that hand their frames back to the world (no process can join
a `LocalNode`); this process starts them, so an env that observes one runs here only with
`cameras_in_process` (docs/learning.md says why), else on a server.
"""

from __future__ import annotations

import logging
import shutil
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from simbot.bus.local import LocalNode, LocalPublisher
from simbot.gym.session import ServerSpec
from simbot.sim.loop import simulation
from simbot.sim.loop.bus_view import SimBus
from simbot.sim.loop.world_control import model_states, unit_quaternion
from simbot.sim.server import build_world, parse_config
from simbot.transform import Transform, yaw_quaternion

log = logging.getLogger(__name__)


class LocalSession:
    """A lockstep world in this process; see the module docstring."""

    process = None
    """No process of its own (Session's started server)."""
    server_pid = None

    def __init__(self, spec: ServerSpec, world: str, folder: Path) -> None:
        self.node = LocalNode()
        self.world = world
        self.name = f"simbot world {world!r} in process"
        self.folder = folder
        self.closed = False
        self.sim_world = build_world(parse_config(spec.args()), SimBus(self.node))
        """The running world (a benchmark reads its physics)."""
        self._publishers: dict[str, LocalPublisher] = {}

    def check(self, what: str) -> None:
        """Nothing outside this process can have died."""

    def state(self) -> dict[str, Any]:
        """The part of world control's `state` an environment reads: every model's pose."""
        return {"sim_time": self.sim_world.sim.clock.now_ns / 1e9, "models": model_states(self.sim_world.physics)}

    def step(self, steps: int) -> int:
        """`steps` physics steps; the sim time reached, in nanoseconds."""
        return step_together([self], steps)[0]

    def reset(self, seed: int | None = None) -> None:
        self.sim_world.reset(seed)

    def set_pose(self, model: str, x: float, y: float, z: float, yaw: float) -> None:
        quat = unit_quaternion(list(yaw_quaternion(yaw)))
        self.sim_world.physics.set_model_pose(model, Transform((x, y, z), quat))

    def send(self, items: Sequence[tuple[str, Any]]) -> None:
        """Hands each (topic, message) to the system that takes it; the next step acts on it."""
        for topic, msg in items:
            if topic not in self._publishers:
                self._publishers[topic] = self.node.publisher(topic, msg.__msgtype__)
            self._publishers[topic].put(msg)

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        self.sim_world.close()
        self.node.close()
        shutil.rmtree(self.folder, ignore_errors=True)


def step_together(sessions: Sequence[LocalSession], steps: int) -> list[int]:
    """`steps` physics steps of each session's world, the worlds stepped phase by phase together (a
    vector env's sub-envs: each batched system called once for all); each one's sim time reached, ns."""
    sims = [session.sim_world.sim for session in sessions]
    for _ in range(steps):
        simulation.step_together(sims)
    return [sim.clock.now_ns for sim in sims]
