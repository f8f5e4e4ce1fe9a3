"""A seeded reset applied in place (simbot/sim/loop/world_edit.py, the render pool kept warm): the warehouse with
its people, in this process (a LocalNode: the cameras' frames come back to the world), its front camera's first
frame after `reset(seed)` compared pixel for pixel with a fresh world started on that seed, whatever came before;
no frame of the old world after the reset; a variant that cannot be applied in place loaded anew, saying why.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace

import numpy as np
import numpy.typing as npt
import pytest
from gl_helpers import NO_EGL
from server_helpers import wait_until

from simbot.bus.local import LocalInbox, LocalNode
from simbot.description.poses import Pose
from simbot.sim.loop.bus_view import SimBus
from simbot.sim.loop.world import SimWorld
from simbot.sim.server import build_world, parse_config
from simbot.variation import Variations

pytestmark = pytest.mark.skipif(NO_EGL is not None, reason=NO_EGL or "")

WORLD = ("--world", "warehouse", "--add", "warehouse_people", "--camera-size", "320x240", "--render-workers", "1")
IMAGE = "sensor_msgs/msg/Image"
MAX_STEPS = 200


@contextmanager
def world(*extra: str) -> Iterator[tuple[SimWorld, LocalInbox]]:
    """The warehouse in this process, and an inbox of its front camera's images."""
    node = LocalNode()
    sim_world = build_world(parse_config([*WORLD, *extra]), SimBus(node))
    try:
        yield sim_world, node.inbox("camera_front", IMAGE, maxlen=256)
    finally:
        sim_world.close()
        node.close()


def next_frame(sim_world: SimWorld, inbox: LocalInbox) -> tuple[npt.NDArray[np.uint8], int]:
    """Steps until the camera's next image; its pixels and its stamp (ns)."""
    for _ in range(MAX_STEPS):
        sim_world.sim.step()
        images = inbox.drain()
        if images:
            image = images[0]
            pixels = np.frombuffer(bytes(image.data), np.uint8).reshape(image.height, image.width, 3)
            return pixels.copy(), image.header.stamp.sec * 10**9 + image.header.stamp.nanosec
    raise AssertionError(f"no camera_front image in {MAX_STEPS} steps")


def differing(a: npt.NDArray[np.uint8], b: npt.NDArray[np.uint8]) -> int:
    return int((a != b).any(axis=2).sum())


def test_a_seeded_reset_in_place_draws_what_a_fresh_world_of_the_seed_draws(caplog: pytest.LogCaptureFixture) -> None:
    """Seed 3 applied in place after the world as its file says, and again after seed 19 (a variant with more
    clutter, other textures, lights, people, noise): both first frames equal the first frame of a world started
    with `--randomise 3`, pixel for pixel. The workers batch an edited scene in a fresh one's order, so no pixel
    differs (a different order would show where surfaces lie at one depth); the noise starts again from each
    camera's seed at every reset."""
    with world("--mode", "lockstep", "--randomise", "3") as (fresh, inbox):
        expected, stamp = next_frame(fresh, inbox)
    caplog.set_level(logging.INFO, logger="simbot.sim.loop.world")
    with world("--mode", "lockstep") as (edited, inbox):
        first, _ = next_frame(edited, inbox)
        edited.reset(3)
        after_start, after_start_stamp = next_frame(edited, inbox)
        edited.reset(19)
        other, _ = next_frame(edited, inbox)
        edited.reset(3)
        after_other, _ = next_frame(edited, inbox)
    assert "drawn from seed 3 in place" in caplog.text and "loaded anew" not in caplog.text, caplog.text
    assert after_start_stamp == stamp
    assert differing(after_start, expected) == 0, f"{differing(after_start, expected)} pixels differ"
    assert differing(after_other, expected) == 0, f"{differing(after_other, expected)} pixels differ"
    assert differing(first, expected) > 1000 and differing(other, expected) > 1000, "other worlds look other"


def test_no_frame_of_the_old_world_comes_after_a_seeded_reset() -> None:
    """Fast mode (the physics never waits for a frame): a reset while a set of frames is being drawn drops them;
    every image after the reset is stamped on the new timeline (not after the sim time it arrives at, which is
    still short of where the old one was)."""
    with world("--mode", "fast") as (sim_world, inbox):

        def stepped_and_drained() -> list[object]:
            sim_world.sim.step()
            return inbox.drain()

        wait_until(stepped_and_drained, 120.0, "the render workers' first frame")
        while sim_world.sim.clock.now_ns < 10**9:  # a second of the old timeline, its frames as they come
            sim_world.sim.step()
        rendering = next(s for s in sim_world.systems if type(s).__name__ == "Rendering")
        pool = rendering.pool  # type: ignore[attr-defined]
        for _ in range(MAX_STEPS):  # a step that leaves the front camera's frame being drawn
            sim_world.sim.step()
            if pool.busy(0):
                break
        assert pool.busy(0), "a frame being drawn when the reset comes"
        before = sim_world.sim.clock.now_ns
        inbox.drain()
        sim_world.reset(5)
        stamps: list[int] = []

        def new_images() -> int:
            sim_world.sim.step()
            for image in inbox.drain():
                stamps.append(image.header.stamp.sec * 10**9 + image.header.stamp.nanosec)
                assert stamps[-1] <= sim_world.sim.clock.now_ns < before, f"an image stamped {stamps[-1]} ns"
            return len(stamps)

        wait_until(lambda: new_images() >= 3, 60.0, "three images after the reset")


def test_a_variant_that_cannot_be_applied_in_place_is_loaded_anew_saying_why(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """A profile drawn for another robot (its front lidar 10 cm further ahead) cannot be applied to the running one:
    the seeded reset loads the world anew, with one log line saying why, and the cameras render on."""
    with world("--mode", "lockstep") as (sim_world, inbox):
        assert sim_world.variations is not None and sim_world.robot is not None
        robot = sim_world.robot
        moved = tuple(
            replace(link, pose=Pose((1.1, 0.0, 0.04), link.pose.rpy)) if link.name == "base_scan_front" else link
            for link in robot.links
        )
        sim_world.variations = Variations(
            sim_world.variations.world, replace(robot, links=moved), sim_world.variations.profile
        )
        caplog.set_level(logging.INFO, logger="simbot.sim.loop.world")
        sim_world.reset(4)
        assert "seed 4 cannot be applied in place (the variant's robot differs" in caplog.text, caplog.text
        assert sim_world.variant is not None and sim_world.variant.seed == 4
        pixels, stamp = next_frame(sim_world, inbox)
        assert stamp < 10**9 and pixels.std() > 10
