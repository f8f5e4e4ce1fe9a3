"""World control for ROS 2 tools: reset, pause and step as services of standard types.

Beside world control's JSON queryables (`world_control.py`), each world serves, on rmw_zenoh's
keys and the ROS 2 graph (`ros2 service list`, `ros2 service call`):

- `world/<name>/reset`, `std_srvs/srv/Empty`: as JSON control's `{"reset": {"all": true}}`;
- `world/<name>/pause`, `std_srvs/srv/SetBool`: `data: true` pauses, `false` runs again (refused
  in lockstep, where the world advances only on steps: `success: false` and why);
- `world/<name>/step`, `std_srvs/srv/Trigger`: one step, answered once it is done, its message
  the sim time reached.

A request that is not the service's CDR, or lacks rmw_zenoh's attachment, is answered with an
error and counted with the dropped inputs. Polled by the simulation loop between steps.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Protocol

from simbot.bus import BadRequest, Node, RosRequest, RosService, message_type
from simbot.sim.loop.bus_view import Drops
from simbot.sim.loop.simulation import Mode, Simulation


class Resetting(Protocol):
    def reset(self) -> None: ...


class RosWorldControl:
    """The three ROS 2 services of one world."""

    def __init__(self, node: Node, base: str, sim: Simulation, models: Resetting, drops: Drops) -> None:
        """`base`: the world's key, `world/<name>` (under a zone's name in a zone server)."""
        self.node = node
        self.sim = sim
        self.models = models
        self.drops = drops
        handlers: tuple[tuple[str, str, Callable[[RosRequest, Any], None]], ...] = (
            ("reset", "std_srvs/srv/Empty", self._reset),
            ("pause", "std_srvs/srv/SetBool", self._pause),
            ("step", "std_srvs/srv/Trigger", self._step),
        )
        self._services = [
            (node.ros_service(f"{base}/{name}", typename), handler) for name, typename, handler in handlers
        ]

    def poll(self) -> None:
        """Handles every request that arrived since the last call."""
        for service, handler in self._services:
            for request in service.poll():
                self._handle(service, request, handler)

    def _handle(self, service: RosService, request: RosRequest, handler: Callable[[RosRequest, Any], None]) -> None:
        try:
            message = request.message()
        except BadRequest as exc:
            self.drops.drop(service.name, str(exc))
            request.reply_error(str(exc))
            return
        handler(request, message)

    def _reset(self, request: RosRequest, _message: Any) -> None:
        self.models.reset()
        request.reply(_response(request, structure_needs_at_least_one_member=0))

    def _pause(self, request: RosRequest, message: Any) -> None:
        pause = bool(message.data)
        if not pause and self.sim.mode is Mode.LOCKSTEP:
            request.reply(
                _response(request, success=False, message="in lockstep mode the world advances only on steps")
            )
            return
        self.sim.set_paused(pause)
        request.reply(_response(request, success=True, message="paused" if pause else "running"))

    def _step(self, request: RosRequest, _message: Any) -> None:
        def done() -> None:
            reached = f"sim time {self.sim.clock.now_ns / 1e9:.3f} s, iteration {self.sim.clock.iterations}"
            request.reply(_response(request, success=True, message=reached))

        self.node.refresh_subscribers()
        self.sim.request_steps(1, done)


def _response(request: RosRequest, **fields: Any) -> Any:
    """The service's response message with `fields`."""
    return message_type(request.service.response_type)(**fields)
