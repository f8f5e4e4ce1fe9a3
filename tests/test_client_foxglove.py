"""`simbot foxglove` (clients/foxglove.py): a real server, a real bridge process, a WebSocket client in the test.

The client here speaks Foxglove's WebSocket protocol as the app does (subprotocol
`foxglove.sdk.v1`, or `foxglove.websocket.v1` as Lichtblick and `@foxglove/ws-protocol` offer): JSON `serverInfo`, `advertise`
and `unadvertise` in; `subscribe` / `unsubscribe` out; binary frames in, `messageData` (opcode
0x01: uint32 subscription id, uint64 timestamp, payload) and `time` (0x02: uint64), little-endian.

What it checks against the bus itself: a channel per published key with the ROS 2 schema that
decodes it (parsed by rosbags from the advertisement alone, as the app parses it); payloads
byte-identical to what a Zenoh subscriber in the test receives on the same key; timestamps and
time broadcasts that are sim times of `clock`, each message at a clock tick or its own stamp,
never before that stamp and within one clock period (10 ms, the clock's 100 Hz) of it; a camera rendered only while a viewer subscribes (the
server's world state counts its images); garbage on a watched key dropped, the next valid scan
forwarded. The official client, `@foxglove/ws-protocol` in Node, lists the channels and decodes a
scan with `@foxglove/rosmsg2-serialization` (skipped where Node is absent). One server in real time
(160×120 cameras) and one bridge serve the module.
"""

from __future__ import annotations

import base64
import itertools
import json
import shutil
import signal
import socket
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from bus_helpers import free_port
from client_helpers import ClientProcess, bus_args, client_command, client_process
from conftest import REPO
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from server_helpers import Collector, SimServer, payload, raw_samples, running_server, stamp_ns, wait_until
from websockets.exceptions import ConnectionClosed, InvalidStatus
from websockets.sync.client import ClientConnection, connect
from websockets.typing import Subprotocol

from simbot.bus import decode, encode, messages
from simbot.bus.codec import TYPESTORE
from simbot.clients.subprotocols import legacy_only, offered, rename
from simbot.clients.tap import published

SUBPROTOCOL = Subprotocol("foxglove.sdk.v1")
LEGACY_SUBPROTOCOL = Subprotocol("foxglove.websocket.v1")  # Lichtblick, @foxglove/ws-protocol 0.8
NODE_CLIENT = Path(__file__).resolve().parent / "node"
MESSAGE_DATA, TIME, FETCH_ASSET_RESPONSE = 0x01, 0x02, 0x04
CHEAP_CAMERAS = ("--camera-size", "160x120")
CLOCK_PERIOD_NS = 10_000_000  # the server's clock, 100 Hz of sim time
CLOCK_LAG_NS = (
    100_000_000  # how far the bridge's latest clock may trail the server's sim time (transport, a loaded CPU)
)
WAIT_S = 30.0  # generous: two cores shared with other test runs
SERVER_KEYS = {  # SPEC §4: what the server alone publishes in the empty world
    "clock", "odom", "tf", "tf_static", "robot_description", "joint_states", "imu_scan", "lidar_front", "lidar_back",
    "detachable_joint/state", "model/flexley_tug/pose", "scene",
    *(f"camera_{name}{suffix}" for name in ("front", "back", "front_right", "front_left", "back_right", "back_left")
      for suffix in ("", "/camera_info")),
}  # fmt: skip
LAYOUT = REPO / "layouts" / "simbot.json"


# --- a Foxglove WebSocket client ------------------------------------------------------------


@dataclass(frozen=True)
class Frame:
    """One messageData frame: the subscription it answers, its timestamp (ns) and the message bytes."""

    subscription: int
    timestamp: int
    payload: bytes


class Viewer:
    """What the Foxglove app does on the wire: a reader thread collects JSON ops, messages and time."""

    def __init__(self, ws: ClientConnection) -> None:
        self.ws = ws
        self.ops: Collector[dict[str, Any]] = Collector()
        self.frames: Collector[Frame] = Collector()
        self.times: Collector[int] = Collector()
        self.assets: Collector[tuple[int, int, str, bytes]] = Collector()
        self._ids = itertools.count(1)
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        try:
            for message in self.ws:
                if isinstance(message, str):
                    self.ops(json.loads(message))
                elif message[0] == MESSAGE_DATA:
                    subscription, timestamp = struct.unpack_from("<IQ", message, 1)
                    self.frames(Frame(subscription, timestamp, bytes(message[13:])))
                elif message[0] == TIME:
                    self.times(struct.unpack_from("<Q", message, 1)[0])
                elif message[0] == FETCH_ASSET_RESPONSE:
                    request, status, length = struct.unpack_from("<IBI", message, 1)
                    error = bytes(message[10 : 10 + length]).decode()
                    self.assets((request, status, error, bytes(message[10 + length :])))
        except ConnectionClosed:
            return

    def server_info(self) -> dict[str, Any]:
        ops = self.ops.wait_for(lambda ops: any(op["op"] == "serverInfo" for op in ops), WAIT_S, "serverInfo")
        return next(op for op in ops if op["op"] == "serverInfo")

    def channels(self) -> dict[str, dict[str, Any]]:
        """The advertised channels now, by topic (advertisements replayed, unadvertised ones gone)."""
        channels: dict[int, dict[str, Any]] = {}
        for op in self.ops.messages():
            if op["op"] == "advertise":
                channels.update((channel["id"], channel) for channel in op["channels"])
            elif op["op"] == "unadvertise":
                for channel_id in op["channelIds"]:
                    channels.pop(channel_id, None)
        return {channel["topic"]: channel for channel in channels.values()}

    def wait_channels(
        self, condition: Callable[[dict[str, dict[str, Any]]], object], what: str
    ) -> dict[str, dict[str, Any]]:
        wait_until(lambda: condition(self.channels()), WAIT_S, what, poll=0.05)
        return self.channels()

    def subscribe(self, topic: str) -> int:
        """Subscribe to the channel of `topic` (waiting for its advertisement); the subscription id."""
        channel = self.wait_channels(lambda channels: topic in channels, f"{topic} advertised")[topic]
        subscription = next(self._ids)
        self.ws.send(
            json.dumps({"op": "subscribe", "subscriptions": [{"id": subscription, "channelId": channel["id"]}]})
        )
        return subscription

    def unsubscribe(self, subscription: int) -> None:
        self.ws.send(json.dumps({"op": "unsubscribe", "subscriptionIds": [subscription]}))

    def fetch_asset(self, uri: str) -> tuple[int, str, bytes]:
        """fetchAsset as the app sends it for a mesh: (status, 0 ok, 1 error; the error; the bytes)."""
        request = next(self._ids)
        self.ws.send(json.dumps({"op": "fetchAsset", "uri": uri, "requestId": request}))
        replies = self.assets.wait_for(lambda got: any(r[0] == request for r in got), WAIT_S, f"asset {uri}")
        return next(r[1:] for r in replies if r[0] == request)

    def received(self, subscription: int, count: int, timeout: float = WAIT_S) -> list[Frame]:
        """The frames of a subscription, once there are `count` of them."""
        frames = self.frames.wait_for(
            lambda frames: sum(f.subscription == subscription for f in frames) >= count, timeout, f"{count} messages"
        )
        return [f for f in frames if f.subscription == subscription]


@contextmanager
def viewer(port: int, subprotocol: Subprotocol = SUBPROTOCOL) -> Iterator[Viewer]:
    """A Viewer connected to the bridge on `port` (retried while the bridge is still starting)."""
    deadline = time.monotonic() + WAIT_S
    while True:
        try:
            ws = connect(f"ws://127.0.0.1:{port}", subprotocols=[subprotocol], max_size=None, open_timeout=5)
            break
        except OSError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.1)
    with ws:
        client = Viewer(ws)
        yield client


def typestore_of(channel: dict[str, Any]) -> Any:
    """A typestore built from a channel's advertised schema alone: what the app decodes the channel with."""
    store = get_typestore(Stores.EMPTY)
    store.register(get_types_from_msg(channel["schema"], channel["schemaName"]))
    return store


def decode_with(channel: dict[str, Any], payload: bytes) -> Any:
    return typestore_of(channel).deserialize_cdr(payload, channel["schemaName"])


# --- the bus side ---------------------------------------------------------------------------


@contextmanager
def on_bus(sim: SimServer, *topics: str) -> Iterator[dict[str, Collector[bytes]]]:
    """The raw payloads of `topics` as a plain Zenoh subscriber in the test receives them."""
    with ExitStack() as stack:
        yield {
            topic: stack.enter_context(raw_samples(sim.node.session, sim.any_type_key(topic), payload))
            for topic in topics
        }


def camera_images(sim: SimServer) -> tuple[float, dict[str, int]]:
    """Sim time and the images each camera has published, from the world state."""
    state = sim.state()
    cameras = {scoped.rsplit("/", 1)[-1]: figures for scoped, figures in state["sensors"].items()}
    return state["sim_time"], {
        name: figures["messages"] for name, figures in cameras.items() if name.startswith("camera_")
    }


def images_counted(sim: SimServer, camera: str, received: int) -> dict[str, int]:
    """Each camera's images once world state counts the `received` images of `camera` a subscriber
    got: its render worker publishes a frame before it reports it done, so the server's count may
    follow what a subscriber has by a step of its loop."""
    wait_until(lambda: camera_images(sim)[1][camera] >= received, WAIT_S, f"world state to count {received} images")
    return camera_images(sim)[1]


def wait_camera_stopped(sim: SimServer, camera: str) -> None:
    """Until `camera` publishes no image over half a second of sim time (15 of its 30 Hz periods), however
    slowly a loaded machine runs the world."""

    def stopped() -> bool:
        t0, first = camera_images(sim)
        wait_until(lambda: camera_images(sim)[0] - t0 >= 0.5, WAIT_S, "half a second of sim time", poll=0.05)
        return camera_images(sim)[1][camera] == first[camera]

    wait_until(stopped, WAIT_S, f"{camera} to stop rendering once unwatched", poll=0.0)


# --- fixtures -------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def sim() -> Iterator[SimServer]:
    with running_server("empty", mode="realtime", extra=CHEAP_CAMERAS) as server:
        yield server


@dataclass(frozen=True)
class Bridge:
    process: ClientProcess
    port: int


@pytest.fixture(scope="module")
def bridge(sim: SimServer) -> Iterator[Bridge]:
    """`simbot foxglove` on a free port for the module, serving once it yields; stopped with SIGTERM, exit 0 asserted."""
    port = free_port()
    with client_process(sim, "foxglove", "--port", str(port)) as process:
        with viewer(port) as client:
            client.server_info()
        yield Bridge(process, port)


@pytest.fixture
def app(bridge: Bridge) -> Iterator[Viewer]:
    with viewer(bridge.port) as client:
        yield client


@pytest.fixture(scope="module")
def node_client(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """tests/node's script with its pinned packages (@foxglove/ws-protocol, ...) installed by npm into a temp folder."""
    if shutil.which("node") is None or shutil.which("npm") is None:
        pytest.skip("Node.js and npm are not installed: the official Foxglove client runs in Node")
    folder = tmp_path_factory.mktemp("node")
    for name in ("package.json", "foxglove_client.mjs"):
        shutil.copy(NODE_CLIENT / name, folder / name)
    command = ["npm", "install", "--no-audit", "--no-fund", "--loglevel=error"]
    done = subprocess.run(command, cwd=folder, capture_output=True, text=True, timeout=300, check=False)
    assert done.returncode == 0, f"npm install in {folder}:\n{done.stderr}"
    return folder / "foxglove_client.mjs"


# --- tests ----------------------------------------------------------------------------------


def test_advertises_every_published_key_with_its_ros2_schema(sim: SimServer, app: Viewer) -> None:
    """One channel per published key, `/` + topic; its schema, parsed alone, is exactly the ROS 2 type."""
    with sim.client() as node:
        expected = published(node)
    assert set(expected) >= SERVER_KEYS, f"the server does not publish {sorted(SERVER_KEYS - set(expected))}"
    info = app.server_info()
    assert "time" in info["capabilities"] and info["name"] == f"simbot {sim.namespace}"
    topics = {"/" + name for name in expected}
    channels = app.wait_channels(lambda channels: topics <= set(channels), "a channel per published key")
    assert set(channels) == topics  # inputs nobody publishes (cmd_vel, attach) and services have none
    for name, topic in expected.items():
        channel = channels["/" + name]
        assert (channel["encoding"], channel["schemaEncoding"], channel["schemaName"]) == (
            "cdr",
            "ros2msg",
            topic.typename,
        )
        parsed = get_types_from_msg(channel["schema"], topic.typename)
        assert topic.typename in parsed and all(parsed[t] == TYPESTORE.fielddefs[t] for t in parsed), name
    scan_schema = channels["/lidar_front"]["schema"]
    assert (
        scan_schema.startswith("std_msgs/Header header\nfloat32 angle_min\n")
        and "\nMSG: builtin_interfaces/Time\n" in scan_schema
    )


LATE_TICKS = 10
"""How many clock ticks a sample may reach the bridge after its own on a loaded machine (measured: up to 1.5)."""


def test_forwards_bus_payloads_unchanged_at_sim_time(sim: SimServer, app: Viewer) -> None:
    """Scans and IMU samples arrive byte for byte as on the bus, stamped with the latest clock."""
    with on_bus(sim, "lidar_front", "imu_scan", "clock") as bus:
        bus["clock"].wait_count(1, WAIT_S, "clock on the bus")
        lidar, imu = app.subscribe("/lidar_front"), app.subscribe("/imu_scan")
        scans, samples = app.received(lidar, 5), app.received(imu, 50)
        times = app.times.messages()
        app.unsubscribe(lidar)
        app.unsubscribe(imu)
        for frames, topic in ((scans, "lidar_front"), (samples, "imu_scan")):
            sent = {frame.payload for frame in frames}
            bus[topic].wait_for(sent.issubset, 5.0, f"the {topic} payloads the viewer got, on the bus")
        clock_ns = {
            messages.stamp_ns(decode(data, "rosgraph_msgs/msg/Clock").clock) for data in bus["clock"].messages()
        }

    scan = decode_with(app.channels()["/lidar_front"], scans[0].payload)
    assert scan.header.frame_id == "base_scan_front" and len(scan.ranges) == 720
    assert scan.angle_min == pytest.approx(-1.396263, abs=1e-6)
    lags = []
    for frames, typename in ((scans, "sensor_msgs/msg/LaserScan"), (samples, "sensor_msgs/msg/Imu")):
        for frame in frames:
            stamp = stamp_ns(decode(frame.payload, typename))
            assert frame.timestamp in clock_ns | {stamp}, (
                f"timestamp {frame.timestamp} is neither a clock tick nor the stamp {stamp}"
            )
            lags.append(frame.timestamp - stamp)
    at_stamp = sum(lag == 0 for lag in lags)
    print(
        f"{len(scans)} scans, {len(samples)} IMU samples; timestamp − stamp {min(lags) / 1e6:.0f}…{max(lags) / 1e6:.0f} ms, {at_stamp} at the stamp"
    )
    # never before the data was taken; a message that reaches the bridge after later clock ticks (a
    # loaded machine: the keys arrive on separate threads) is logged at the latest tick it has seen
    assert min(lags) >= 0 and max(lags) <= LATE_TICKS * CLOCK_PERIOD_NS
    broadcast = [t for t in times if t >= min(clock_ns)]  # from when the test's own clock subscriber was live
    assert len(broadcast) >= 10 and set(broadcast) <= clock_ns and times == sorted(times)


def test_cameras_render_only_while_watched(sim: SimServer, app: Viewer) -> None:
    """No image is rendered until a viewer subscribes to a camera; then that camera only, and it stops after."""
    app.wait_channels(lambda channels: "/camera_front" in channels, "/camera_front advertised")
    _, before = camera_images(sim)
    assert before and not any(before.values()), f"cameras rendered with no viewer: {before}"
    subscription = app.subscribe("/camera_front")
    frames = app.received(subscription, 3, timeout=60.0)  # the render worker starts on the first subscription
    during = images_counted(sim, "camera_front", len(frames))
    image = decode_with(app.channels()["/camera_front"], frames[-1].payload)
    assert (image.width, image.height, image.encoding, len(image.data)) == (160, 120, "rgb8", 160 * 120 * 3)
    assert during["camera_front"] >= 3 and not any(n for name, n in during.items() if name != "camera_front"), during
    app.unsubscribe(subscription)
    wait_camera_stopped(sim, "camera_front")
    print(f"camera_front: {during['camera_front']} images while watched, other cameras 0")


def test_malformed_payloads_are_dropped_and_the_next_scan_forwarded(
    sim: SimServer, bridge: Bridge, app: Viewer
) -> None:
    """Garbage and a truncated scan on a watched key never reach the viewer; the scans after them do."""
    with on_bus(sim, "lidar_back") as bus:
        subscription = app.subscribe("/lidar_back")
        first = app.received(subscription, 1)[0]
        garbage = [b"\x00\x01\x00\x00" + b"\xff" * 7, first.payload[: len(first.payload) // 2]]
        for data in garbage:
            sim.send_raw("lidar_back", "sensor_msgs/msg/LaserScan", data)
        bus["lidar_back"].wait_for(lambda payloads: all(g in payloads for g in garbage), 5.0, "the garbage on the bus")
        after = len(bus["lidar_back"])
        bus["lidar_back"].wait_count(after + 2, WAIT_S, "two scans after the garbage")
        valid = bus["lidar_back"].messages()[after:]
        frames = app.frames.wait_for(
            lambda frames: any(f.payload in valid for f in frames), WAIT_S, "a scan after the garbage"
        )
        app.unsubscribe(subscription)
    payloads = [f.payload for f in frames if f.subscription == subscription]
    assert not any(g in payloads for g in garbage)
    wait_until(
        lambda: f"{sim.key('lidar_back')}: dropped a sample" in bridge.process.stderr(), 5.0, "the bridge's warning"
    )


def test_channels_follow_the_graph(sim: SimServer, app: Viewer) -> None:
    """A key published later gets a channel (and carries its messages); when its publisher goes, so does the channel."""
    note = messages.string("hello from the bus")
    with sim.client() as node:
        publisher = node.publisher("fox_test/note", "std_msgs/msg/String")
        channel = app.wait_channels(lambda channels: "/fox_test/note" in channels, "/fox_test/note advertised")[
            "/fox_test/note"
        ]
        assert (channel["schemaName"], channel["schema"]) == ("std_msgs/msg/String", "string data\n")
        subscription = app.subscribe("/fox_test/note")

        def delivered() -> bool:
            publisher.put(note)  # until the bridge has subscribed on the bus
            return any(f.subscription == subscription for f in app.frames.messages())

        wait_until(delivered, WAIT_S, "the note at the viewer", poll=0.1)
        assert app.received(subscription, 1)[0].payload == encode(note)
        publisher.close()
        app.wait_channels(lambda channels: "/fox_test/note" not in channels, "/fox_test/note unadvertised")


def test_a_second_viewer_also_gets_the_latched_keys(sim: SimServer, bridge: Bridge) -> None:
    """A viewer that subscribes to tf_static after another still gets it, the bytes the server latched,
    logged (it has no header) at a clock tick of the sim time meanwhile."""
    latched = [
        reply.ok.payload.to_bytes()
        for reply in sim.node.session.get(sim.any_type_key("tf_static"), timeout=5.0)
        if reply.ok
    ]
    assert len(latched) == 1
    begun = round(sim.state()["sim_time"] * 1e9)
    with viewer(bridge.port) as first, viewer(bridge.port) as second:
        frames = [client.received(client.subscribe("/tf_static"), 1)[0] for client in (first, second)]
    ended = round(sim.state()["sim_time"] * 1e9)
    for frame in frames:
        assert frame.payload == latched[0]
        assert frame.timestamp % CLOCK_PERIOD_NS == 0 and begun - CLOCK_LAG_NS <= frame.timestamp <= ended


@pytest.mark.parametrize("subprotocol", [SUBPROTOCOL, LEGACY_SUBPROTOCOL])
def test_both_names_of_the_protocol_are_served(bridge: Bridge, subprotocol: Subprotocol) -> None:
    """A client offering only one name of the protocol gets that name back, the server's info and its channels."""
    with viewer(bridge.port, subprotocol) as client:
        assert client.ws.subprotocol == subprotocol
        assert client.server_info()["name"].startswith("simbot")
        client.wait_channels(lambda channels: "/lidar_front" in channels, "/lidar_front advertised")


def test_the_front_renames_only_the_protocol_header() -> None:
    """Golden bytes: the old name becomes the new one in Sec-WebSocket-Protocol lines only, case-insensitively."""
    request = (
        b"GET / HTTP/1.1\r\nHost: foxglove.websocket.v1\r\n"
        b"sec-WebSocket-Protocol: x, foxglove.websocket.v1\r\nSec-WebSocket-Key: k\r\n\r\n"
    )
    renamed = rename(request, LEGACY_SUBPROTOCOL.encode(), SUBPROTOCOL.encode())
    assert renamed == request.replace(b"x, foxglove.websocket.v1", b"x, foxglove.sdk.v1")
    assert offered(request) == [b"x", b"foxglove.websocket.v1"] and legacy_only(request)
    assert not legacy_only(renamed) and not legacy_only(b"GET / HTTP/1.1\r\n\r\n")


def test_another_subprotocol_is_refused(bridge: Bridge) -> None:
    """The front renames only Foxglove's old name; anything else meets the SDK's own refusal (HTTP 400)."""
    with pytest.raises(InvalidStatus) as refused:
        connect(f"ws://127.0.0.1:{bridge.port}", subprotocols=[Subprotocol("foxglove.websocket.v2")], open_timeout=5)
    assert refused.value.response.status_code == 400


def test_the_official_client_decodes_a_scan(sim: SimServer, bridge: Bridge, node_client: Path) -> None:
    """@foxglove/ws-protocol (subprotocol foxglove.websocket.v1) lists every channel and, with
    @foxglove/rosmsg2-serialization and the channel's schema, decodes a scan that is byte for byte one on the bus."""
    with on_bus(sim, "lidar_front") as bus:
        command = ["node", str(node_client), f"ws://127.0.0.1:{bridge.port}", "/lidar_front", str(WAIT_S)]
        done = subprocess.run(command, capture_output=True, text=True, timeout=WAIT_S + 30, check=False)
        assert done.returncode == 0, done.stderr
        seen = json.loads(done.stdout)
        data = base64.b64decode(seen["payload"])
        bus["lidar_front"].wait_for(lambda payloads: data in payloads, 5.0, "the scan the client decoded, on the bus")
    assert seen["subprotocol"] == LEGACY_SUBPROTOCOL and seen["schemaName"] == "sensor_msgs/msg/LaserScan"
    assert {"/" + key for key in SERVER_KEYS} <= set(seen["topics"]), seen["topics"]
    scan = decode(data, "sensor_msgs/msg/LaserScan")
    expected = {
        "frame_id": "base_scan_front", "stamp": [scan.header.stamp.sec, scan.header.stamp.nanosec],
        "angle_min": float(scan.angle_min), "angle_max": float(scan.angle_max), "range_max": float(scan.range_max),
        "ranges": [float(r) if np.isfinite(r) else str(r).replace("inf", "Infinity") for r in scan.ranges],
    }  # fmt: skip
    assert len(seen["ranges"]) == 720
    assert {name: seen[name] for name in expected} == expected


def test_a_port_in_use_is_one_line(sim: SimServer, bridge: Bridge) -> None:
    result = subprocess.run(
        client_command("foxglove", *bus_args(sim), "--port", str(bridge.port)),
        check=False,
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=60,
    )
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("simbot foxglove: error: ") and str(bridge.port) in lines[0], lines


def test_sigint_stops_the_server(sim: SimServer) -> None:
    port = free_port()
    with client_process(sim, "foxglove", "--port", str(port)) as process, viewer(port) as client:
        client.server_info()
        assert process.stop(signal.SIGINT) == 0
    with pytest.raises(ConnectionRefusedError), socket.create_connection(("127.0.0.1", port), timeout=2.0):
        pass


def test_committed_layout_is_what_make_layout_writes(tmp_path: Path) -> None:
    """layouts/simbot.json is up to date (`make layout`) and shows the panorama, the merged scan and the frames."""
    out = tmp_path / "simbot.json"
    subprocess.run(
        [sys.executable, str(REPO / "layouts" / "make_layout.py"), "--out", str(out)], check=True, timeout=60
    )
    assert out.read_text() == LAYOUT.read_text(), "layouts/simbot.json is stale: run `make layout`"
    panels = list(_panels(json.loads(LAYOUT.read_text())["content"]))
    by_type = {panel["panelType"]: panel for panel in panels}
    assert by_type["Image"]["config"]["imageMode"]["imageTopic"] == "/camera_360/image_raw"
    scan = next(p for p in panels if p["panelType"] == "ThreeDee" and "/scan" in p["config"]["topics"])
    assert scan["config"]["fixedFrame"] == "odom" and scan["config"]["followTf"] == "base_link"
    assert scan["config"]["topics"]["/scan"]["visible"] is True
    frames = [
        p
        for p in panels
        if p["panelType"] == "ThreeDee" and p["config"].get("scene", {}).get("transforms", {}).get("visible")
    ]
    assert frames and "TransformTree" in by_type


def _panels(content: dict[str, Any]) -> Iterator[dict[str, Any]]:
    """Every panel of a layout's content, through its split containers."""
    if content["type"] == "panel":
        yield content
    for item in content.get("items", ()):
        yield from _panels(item["content"])


def test_the_scene_is_offered_and_its_meshes_fetched_as_assets(sim: SimServer, app: Viewer) -> None:
    """/scene is a channel like any key; a mesh its markers name comes back byte for byte through
    fetchAsset; a file the scene does not name is refused, however it is spelled."""
    scene = app.subscribe("/scene")
    channel = app.channels()["/scene"]
    markers = decode_with(channel, app.received(scene, 1)[0].payload).markers
    meshes = sorted({m.mesh_resource for m in markers if m.mesh_resource})
    assert "assets" in app.server_info()["capabilities"] and meshes, "no mesh in the empty world's scene"
    status, error, data = app.fetch_asset(meshes[0])
    assert (status, error) == (0, "") and data == Path(meshes[0].removeprefix("file://")).read_bytes()
    for outside in (
        (REPO / "pyproject.toml").as_uri(),
        meshes[0].rsplit("/", 1)[0] + "/../../pyproject.toml",
        "file:///etc/passwd",
        "package://simbot/meshes/wheel.stl.missing",
    ):
        status, error, data = app.fetch_asset(outside)
        assert status == 1 and error and not data, outside
