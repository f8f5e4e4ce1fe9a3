"""DetachableJoint: `attach` fixes a child model's link to ours at their current relative pose; `detach` frees it.

| parameter | default |
|---|---|
| `parent_link` | required |
| `child_model`, `child_link` | required |
| `attach_topic` | `model/<model>/detachable_joint/attach` |
| `detach_topic` (or `topic`) | `model/<model>/detachable_joint/detach` |
| `output_topic` | `model/<child_model>/detachable_joint/state` (`attached` / `detached`, on change and to late joiners) |

The default keys are Gazebo Sim's. Unlike Gazebo's, it starts detached: the tug must drive under
the trolley first. In a fleet every tug's joint names the one `trolley`: a trolley that one robot
holds is refused to the others (a warning; the state stays `detached`) until it is detached.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

from simbot.bus import messages
from simbot.description.naming import model_topic
from simbot.description.plugin_params import param
from simbot.sim.loop.system import Batch, SystemConfigError, SystemContext, UpdateInfo

log = logging.getLogger(__name__)

EMPTY = "std_msgs/msg/Empty"


class DetachableJoint:
    """Requests are queued by the bus and acted on before the next physics step."""

    name = "DetachableJoint"

    def __init__(self, ctx: SystemContext) -> None:
        plugin = ctx.plugin
        assert plugin is not None
        model, self._name = ctx.require_model("DetachableJoint")
        parent_link, child_model, child_link = (
            param(plugin, tag) for tag in ("parent_link", "child_model", "child_link")
        )
        if parent_link is None or child_model is None or child_link is None:
            raise SystemConfigError(f"{plugin.name}: <parent_link>, <child_model> and <child_link> are required")
        if parent_link not in {link.name for link in model.links}:
            raise SystemConfigError(f"{plugin.name}: model {model.name!r} has no link {parent_link!r}")
        self._parent = (self._name, parent_link)
        self._child = (child_model, child_link)
        self._physics = ctx.physics
        attach = param(plugin, "attach_topic") or ctx.model_topic("detachable_joint/attach")
        detach = param(plugin, "detach_topic", "topic") or ctx.model_topic("detachable_joint/detach")
        state = param(plugin, "output_topic") or model_topic(child_model, "detachable_joint/state")
        self._attach = ctx.bus.input(attach, EMPTY)
        self._detach = ctx.bus.input(detach, EMPTY)
        self._state = ctx.bus.publisher(state, messages.String, latched=True)
        self._bell = ctx.bus.doorbell(type(self).__name__)
        self._attach.rings(self._bell, self)
        self._detach.rings(self._bell, self)
        self._joint: int | None = None
        self._publish()

    @property
    def attached(self) -> bool:
        return self._joint is not None

    @classmethod
    def pre_update_all(cls, batches: Sequence[Batch]) -> None:
        """Each joint of each world asked to attach or detach (its requests rang the world's
        doorbell of joints); the others (a fleet's, most steps) cost nothing."""
        for joints, info in batches:
            for joint in joints[0]._bell.answer():
                joint.pre_update(info)

    def pre_update(self, info: UpdateInfo) -> None:
        # Both within one step: attach, then detach (the bus keeps no order between two keys).
        wants_attach, wants_detach = bool(self._attach.drain()), bool(self._detach.drain())
        if wants_attach and not self.attached:
            self._do_attach()
        if wants_detach and self.attached:
            self._do_detach()

    def _do_attach(self) -> None:
        holder = self._physics.holder(self._child[0])
        if holder is not None:  # another robot of the fleet pulls it: one joint at a time
            log.warning("cannot attach: %s is attached to %s", self._child[0], holder)
            return
        try:
            self._joint = self._physics.attach(self._parent, self._child)
        except KeyError as exc:
            log.warning("cannot attach: %s", exc.args[0])
            return
        log.info("attached %s::%s to %s::%s", *self._child, *self._parent)
        self._publish()

    def _do_detach(self) -> None:
        assert self._joint is not None
        self._physics.detach(self._joint)
        self._joint = None
        log.info("detached %s::%s", *self._child)
        self._publish()

    def _publish(self) -> None:
        self._state.put(messages.string("attached" if self.attached else "detached"))

    def reset(self, info: UpdateInfo) -> None:
        if self.attached:
            self._do_detach()

    def close(self) -> None:
        """The model leaves the world (or the server stops): the child goes free."""
        if self.attached:
            self._do_detach()
