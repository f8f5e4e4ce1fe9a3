"""A render worker's messages, written in place (simbot/sim/render/publishing.py): the very bytes
that building each message and encoding it give, for every builder a camera publishes with, frame
after frame; and the bus options a worker joins with."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from simbot.bus import BusOptions, messages
from simbot.bus.codec import encode
from simbot.bus.options import helper_options
from simbot.sim.render.publishing import InPlace
from simbot.sim.systems.thermal_camera import mono16_image

RNG = np.random.default_rng(7)
BUILDERS = [
    (messages.image, lambda: RNG.integers(0, 256, (48, 64, 3), dtype=np.uint8)),
    (messages.image, lambda: RNG.integers(0, 256, (48, 64), dtype=np.uint8)),
    (messages.depth_image, lambda: RNG.uniform(0.1, 9.0, (48, 64)).astype(np.float32)),
    (messages.point_cloud, lambda: RNG.uniform(-5, 5, (48, 64, 4)).astype(np.float32)),
    (mono16_image, lambda: RNG.integers(0, 65536, (48, 64), dtype=np.uint16)),
]


@pytest.mark.parametrize(("build", "array"), BUILDERS, ids=["rgb8", "mono8", "32FC1", "points", "mono16"])
def test_each_frame_in_place_is_the_encoding_of_its_message(build: Any, array: Any) -> None:
    writer = InPlace(build, "tug_2/camera_front_optical")
    for stamp_ns in (0, 33_333_333, 1_700_000_000_123_456_789, 2**31 * 1_000_000_000 - 1):
        pixels = array()
        assert bytes(writer.encode(stamp_ns, pixels)) == encode(build(stamp_ns, "tug_2/camera_front_optical", pixels))
    assert writer._data is not None, "the encoding was never written in place"


def test_a_builder_whose_bytes_are_not_its_arrays_is_built_each_frame() -> None:
    def doubled(stamp_ns: int, frame: str, pixels: Any) -> Any:
        return messages.image(stamp_ns, frame, (pixels // 2) * 2)

    writer = InPlace(doubled, "camera")
    for stamp_ns in (1, 2, 3):
        pixels = RNG.integers(0, 256, (4, 5, 3), dtype=np.uint8)
        assert bytes(writer.encode(stamp_ns, pixels)) == encode(doubled(stamp_ns, "camera", pixels))
    assert writer._data is None


@pytest.mark.parametrize(
    ("server", "worker"),
    [
        (BusOptions(), ("tcp/127.0.0.1:7448",)),
        (BusOptions(listen=("tcp/0.0.0.0:9301",)), ("tcp/127.0.0.1:9301",)),
        (BusOptions(listen=("tcp/[::]:9301", "tcp/127.0.0.1:9302")), ("tcp/[::1]:9301", "tcp/127.0.0.1:9302")),
    ],
)
def test_a_worker_connects_where_the_server_listens(server: BusOptions, worker: tuple[str, ...]) -> None:
    options = helper_options(BusOptions(listen=server.listen, namespace="ns_1"))
    assert options.connect == worker
    assert options.listen == ()
    assert options.namespace == "", "the server names a worker's keys in full"
