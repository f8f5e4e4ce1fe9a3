"""The messages an observation is made of, waited for at the sim time of the step just taken.

Every observed topic (the lidars, odometry, the robot's and the trolley's ground-truth poses, the
cameras) is subscribed for the environment's life; Zenoh's threads only file each message under
its header stamp. After a step to sim time T, `Observer.wait(T)` returns, for each topic, the
message stamped exactly T, waiting for any not yet in: never an older one. The environment sets
the rates so that each is due at T (docs/learning.md, "Observations are of the step just taken").

Contacts are published only while something touches, so no message says "none": the server
publishes the clock last in a step (simbot.sim.systems.clock_publisher), after everything
stamped T, on the same link, so once the clock stamped T is in, every contact up to T is too.
`contacts(after, upto)` then lists what the robot's bumpers touched in between.
"""

from __future__ import annotations

import functools
import logging
import threading
import time
from collections import OrderedDict
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from simbot.bus import Node, Subscription, messages
from simbot.bus.tf_tree import Matrix, TransformTree
from simbot.description.footprints import Planar
from simbot.gym.errors import SimServerError
from simbot.scan_merge import Binning, ScanMerger
from simbot.transform import yaw_of

log = logging.getLogger(__name__)

KEEP = 4
"""Stamps kept per topic: the step just taken and a few before (a late duplicate does no harm)."""
CLOCK = "clock"
POLL_S = 0.05
"""How often a wait looks at the server's process while no message comes."""

Source = tuple[str, str]
"""(topic, ROS type name)."""


class Observer:
    """The subscriptions of one environment and what they have brought; see the module docstring."""

    def __init__(
        self, node: Node, sources: Mapping[str, Source], contact_topic: str, robot: str, state_topic: str | None
    ) -> None:
        self._cond = threading.Condition()
        self._by_stamp: dict[str, OrderedDict[int, Any]] = {name: OrderedDict() for name in [*sources, CLOCK]}
        self._contacts: list[tuple[int, tuple[str, ...]]] = []
        self._robot = robot
        self._tree = TransformTree()
        self._attach_state: str | None = None
        self.sources = dict(sources)
        self._subscriptions: list[Subscription[Any]] = [
            node.subscribe(topic, typename, functools.partial(self._file, name))
            for name, (topic, typename) in sources.items()
        ]
        self._subscriptions += [
            node.subscribe(CLOCK, "rosgraph_msgs/msg/Clock", functools.partial(self._file, CLOCK)),
            node.subscribe(contact_topic, "ros_gz_interfaces/msg/Contacts", self._contact),
            node.subscribe("tf_static", "tf2_msgs/msg/TFMessage", self._tf, latched=True),
        ]
        if state_topic is not None:
            self._subscriptions.append(node.subscribe(state_topic, "std_msgs/msg/String", self._state, latched=True))

    # --- Zenoh's threads: file and notify, nothing more -----------------------------------------

    def _file(self, name: str, msg: Any) -> None:
        stamp = messages.stamp_ns(msg.clock if name == CLOCK else msg.header)
        with self._cond:
            kept = self._by_stamp[name]
            kept[stamp] = msg
            while len(kept) > KEEP:
                kept.popitem(last=False)
            self._cond.notify_all()

    def _contact(self, msg: Any) -> None:
        mine = f"{self._robot}::"
        others = tuple(c.collision2.name for c in msg.contacts if not c.collision2.name.startswith(mine))
        if others:
            with self._cond:
                self._contacts.append((messages.stamp_ns(msg.header), others))

    def _tf(self, msg: Any) -> None:
        with self._cond:
            self._tree.update(msg)
            self._cond.notify_all()

    def _state(self, msg: Any) -> None:
        with self._cond:
            self._attach_state = str(msg.data)
            self._cond.notify_all()

    # --- the environment's thread ---------------------------------------------------------------

    def wait(self, stamp: int, check: Callable[[str], None], timeout: float) -> dict[str, Any]:
        """Each source's message stamped `stamp` (ns), and the clock's; `check(what)` raises when the
        server is gone; SimServerError naming the topics still missing after `timeout` s."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while True:
                missing = [name for name, kept in self._by_stamp.items() if stamp not in kept]
                if not missing:
                    return {name: self._by_stamp[name][stamp] for name in self.sources}
                if time.monotonic() > deadline:
                    break
                self._cond.wait(POLL_S)
                self._cond.release()
                try:
                    check(f"the observation at {stamp / 1e9:g} s")
                finally:
                    self._cond.acquire()
        topics = ", ".join(self.sources[name][0] if name in self.sources else name for name in missing)
        raise SimServerError(
            f"no message stamped {stamp / 1e9:g} s on {topics} within {timeout:g} s of the step "
            "(is each sensor due at every environment step? see docs/learning.md)"
        )

    def received_any(self) -> bool:
        """Whether every source (and the clock) has brought at least one message: the server routes to us."""
        with self._cond:
            return all(self._by_stamp.values())

    def contacts(self, after: int, upto: int) -> list[str]:
        """What the bumpers touched at stamps in (after, upto], sorted, once each; older reports are forgotten."""
        with self._cond:
            touched = sorted({name for stamp, names in self._contacts if after < stamp <= upto for name in names})
            self._contacts = [(stamp, names) for stamp, names in self._contacts if stamp > upto]
        return touched

    def forget(self) -> None:
        """Drops every message kept: after a world reset sim time starts again, and a message of the
        last episode stamped T must not pass for this one's."""
        with self._cond:
            for kept in self._by_stamp.values():
                kept.clear()
            self._contacts.clear()

    def expect_attach_state(self) -> None:
        """Forgets the joint's state, so that `attach_state` waits for one reported after this."""
        with self._cond:
            self._attach_state = None

    def sensor_pose(self, target: str, frame: str, check: Callable[[str], None], timeout: float) -> Matrix:
        """`frame` in `target` from tf_static, waiting for it to arrive (latched: at once, normally)."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while (pose := self._tree.lookup(target, frame)) is None:
                if time.monotonic() > deadline:
                    raise SimServerError(f"no transform from {frame!r} to {target!r} on tf_static within {timeout:g} s")
                self._cond.wait(POLL_S)
                self._cond.release()
                try:
                    check("tf_static")
                finally:
                    self._cond.acquire()
            return pose

    def attach_state(self, want: str, check: Callable[[str], None], timeout: float) -> str | None:
        """The docking joint's state, waiting up to `timeout` s for it to read `want`."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while self._attach_state != want and time.monotonic() < deadline:
                self._cond.wait(POLL_S)
                self._cond.release()
                try:
                    check("detachable_joint/state")
                finally:
                    self._cond.acquire()
            return self._attach_state

    def close(self) -> None:
        for subscription in self._subscriptions:
            subscription.close()
        self._subscriptions.clear()


# --- making observations of messages ----------------------------------------------------------


def merged_scan(merger: ScanMerger, scans: Sequence[tuple[Any, Matrix]], reach: float) -> npt.NDArray[np.float32]:
    """The lidars' scans as one 360° scan in base_link (the merger client's `scan`), no return and
    anything beyond `reach` read as `reach`."""
    _, combined = merger.merge(scans)
    ranges = np.where(np.isfinite(combined.ranges), combined.ranges, reach)
    return np.clip(ranges, 0.0, reach).astype(np.float32)


def scan_merger(bins: int) -> ScanMerger:
    return ScanMerger(Binning(bins))


def planar(msg: Any) -> Planar:
    """(x, y, yaw) of a PoseStamped."""
    p, o = msg.pose.position, msg.pose.orientation
    return float(p.x), float(p.y), yaw_of((o.x, o.y, o.z, o.w))


def twist(msg: Any) -> tuple[float, float]:
    """(v, ω) of an Odometry: the base's forward speed and turn rate, from the wheel encoders."""
    return float(msg.twist.twist.linear.x), float(msg.twist.twist.angular.z)


def pixels(msg: Any, size: tuple[int, int]) -> npt.NDArray[np.uint8]:
    """An rgb8 Image as H × W × 3, a copy (the message's buffer is Zenoh's); SimServerError when its
    size is not the one asked for."""
    image = messages.image_pixels(msg)
    width, height = size
    if image.shape != (height, width, 3):
        raise SimServerError(f"camera image of shape {image.shape}, expected {(height, width, 3)} (rgb8)")
    return np.array(image, dtype=np.uint8, copy=True)
