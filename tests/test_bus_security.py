"""Who may command (docs/security.md): the example Zenoh configurations of docs/zenoh-security/ on a real server.

The test makes a CA and certificates with the `openssl` commands docs/security.md gives (a server
certificate for 127.0.0.1, client certificates with the common names `viewer` and `operator`, one
`stranger` the CA signed but the access control does not name, and an `operator` signed by another
CA), fills the example files' placeholder paths and endpoints with them, and starts a lockstep
server of the empty world with the server file, listening on TLS on loopback only and on a unix
socket in a folder of the test's (for its render workers). Then, with plain Zenoh client sessions
made from the viewer and operator files:

- the viewer receives the server's odom and clock and sees the graph (liveliness tokens);
- the viewer's cmd_vel, on the very key the server subscribes to (found on the graph), never
  reaches the server (its input counter stays, the tug stays put for 2 s), where the operator's
  0.5 m/s for 2 s drives it about 1 m;
- the viewer may read the world's state, but its world control (`multi_step`, `set_pose`,
  `remove`, a wildcard query, the ROS services) gets no reply and changes nothing;
- a plain tcp client, a TLS client without a certificate and one whose certificate another CA
  signed cannot open a session; a certificate of the right CA with another common name opens one
  and may do nothing;
- the viewer receives camera images, which the render workers publish from the unix socket.

Keys are found, not assumed, so that the test holds for simbot's keys (`ns/cmd_vel`) and
rmw_zenoh's (`0/ns/cmd_vel/geometry_msgs::msg::dds_::Twist_/RIHS01_…`) alike.
"""

from __future__ import annotations

import json
import math
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import zenoh
from bus_helpers import free_port, unique_namespace, wait_until

from simbot.bus import DecodeError, decode, encode, messages

REPO = Path(__file__).resolve().parents[1]
EXAMPLES = REPO / "docs" / "zenoh-security"
PLACEHOLDER = "/etc/simbot/certs"
"""Where the example files expect the certificates; docs/security.md says to replace it."""
SOCKET_FOLDER = "/run/simbot"
"""Where the server file puts the unix socket its render workers join."""
WORLD = "empty"
STARTUP_TIMEOUT_S = 120.0
EXIT_TIMEOUT_S = 10.0
CONNECT_TIMEOUT_S = 3.0
"""How long a client tries to open its session before zenoh.open fails."""
STEP_TIMEOUT_S = 120.0
"""A multi_step of 2000 takes about a second here; a loaded CI machine is slower."""
SETTLE_STEPS = 500
"""The empty world steps at 1 kHz; the tug spawns 0.1 m up and settles on its tyres first."""
DRIVE_STEPS = 2000
SPEED = 0.5
ODOM_PERIOD_NS = 20_000_000
"""Odometry goes out at 50 Hz: a step count that is a multiple of 20 lands on a stamp it has."""
QUIET_S = 1.0
"""How long the server's input counter is watched for a denied command that might still arrive."""
TWIST = "geometry_msgs/msg/Twist"
ODOMETRY = "nav_msgs/msg/Odometry"
CLOCK = "rosgraph_msgs/msg/Clock"
IMAGE = "sensor_msgs/msg/Image"


def _openssl_version() -> tuple[int, ...] | None:
    if shutil.which("openssl") is None:
        return None
    done = subprocess.run(["openssl", "version"], capture_output=True, text=True, timeout=30)
    found = re.match(r"OpenSSL (\d+)\.(\d+)", done.stdout)
    return tuple(int(part) for part in found.groups()) if found else (0,)


OPENSSL = _openssl_version()
pytestmark = pytest.mark.skipif(
    OPENSSL is None or OPENSSL < (3, 0),
    reason="needs the openssl command line, 3.0 or later (`openssl req -x509 -CA`), to make the test's certificates",
)


# --- certificates, as docs/security.md makes them -------------------------------------------


def _openssl(folder: Path, *args: str) -> None:
    done = subprocess.run(["openssl", *args], cwd=folder, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, f"openssl {' '.join(args)}: {done.stderr[-1500:]}"


def _make_ca(folder: Path, name: str, common_name: str) -> None:
    _openssl(
        folder,
        *("req", "-x509", "-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:P-256", "-nodes", "-days", "2"),
        *("-subj", f"/CN={common_name}", "-keyout", f"{name}.key", "-out", f"{name}.pem"),
        *("-addext", "basicConstraints=critical,CA:TRUE", "-addext", "keyUsage=critical,keyCertSign,cRLSign"),
    )


def _make_certificate(folder: Path, name: str, common_name: str, usage: str, *extra: str, ca: str = "ca") -> None:
    _openssl(
        folder,
        *("req", "-x509", "-CA", f"{ca}.pem", "-CAkey", f"{ca}.key"),
        *("-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:P-256", "-nodes", "-days", "2"),
        *("-subj", f"/CN={common_name}", "-keyout", f"{name}.key", "-out", f"{name}.pem"),
        *("-addext", "basicConstraints=critical,CA:FALSE", "-addext", f"extendedKeyUsage={usage}", *extra),
    )


@pytest.fixture(scope="module")
def certs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("certs")
    _make_ca(folder, "ca", "simbot test CA")
    _make_certificate(folder, "server", "simbot-server", "serverAuth", "-addext", "subjectAltName=IP:127.0.0.1")
    for role in ("viewer", "operator", "stranger"):
        _make_certificate(folder, role, role, "clientAuth")
    _make_ca(folder, "other-ca", "another CA")
    _make_certificate(folder, "forged", "operator", "clientAuth", ca="other-ca")
    return folder


# --- the example configurations, filled in ---------------------------------------------------


@dataclass(frozen=True)
class Configs:
    folder: Path
    port: int

    @property
    def endpoint(self) -> str:
        return f"tls/127.0.0.1:{self.port}"

    @property
    def socket(self) -> str:
        """The server's unix socket, for its render workers."""
        return f"unixsock-stream/{self.folder / 'simbot.sock'}"

    def path(self, role: str) -> Path:
        return self.folder / f"{role}.json5"


def _fill(example: Path, certs: Path, endpoint: str, sockets: Path) -> str:
    """The example's text with its certificate folder, its socket folder and its tls endpoint replaced."""
    text = example.read_text()
    assert PLACEHOLDER in text, f"{example.name} no longer names its certificates under {PLACEHOLDER}"
    text = text.replace(PLACEHOLDER, str(certs)).replace(SOCKET_FOLDER, str(sockets))
    text, count = re.subn(r'"tls/[^"]+"', json.dumps(endpoint), text)
    assert count == 1, f"{example.name}: expected one tls endpoint, found {count}"
    return text


@pytest.fixture(scope="module")
def configs(certs: Path, tmp_path_factory: pytest.TempPathFactory) -> Configs:
    folder = tmp_path_factory.mktemp("zenoh-configs")
    folder.chmod(0o700)
    filled = Configs(folder, free_port())
    for role in ("server", "viewer", "operator"):
        filled.path(role).write_text(_fill(EXAMPLES / f"{role}.json5", certs, filled.endpoint, folder))
        zenoh.Config.from_file(str(filled.path(role)))  # the schema of this Zenoh accepts it
    # the same client file with another certificate: a stranger to the access control, a forged operator
    for role in ("stranger", "forged"):
        filled.path(role).write_text(filled.path("viewer").read_text().replace("/viewer.", f"/{role}."))
    return filled


def _config(configs: Configs, role: str, edit: Callable[[zenoh.Config], None] | None = None) -> zenoh.Config:
    config = zenoh.Config.from_file(str(configs.path(role)))
    # what the example clients say for themselves: a client, no multicast scouting, the server's TLS endpoint
    assert json.loads(config.get_json("mode")) == "client"
    assert json.loads(config.get_json("scouting/multicast/enabled")) is False
    assert json.loads(config.get_json("connect/endpoints")) == [configs.endpoint]
    config.insert_json5("connect/timeout_ms", str(round(CONNECT_TIMEOUT_S * 1000)))
    if edit is not None:
        edit(config)
    return config


@contextmanager
def session(configs: Configs, role: str) -> Iterator[zenoh.Session]:
    """A Zenoh client session made from the example file of `role`."""
    opened = zenoh.open(_config(configs, role))
    try:
        yield opened
    finally:
        opened.close()


# --- the server ------------------------------------------------------------------------------


@dataclass(frozen=True)
class Server:
    process: subprocess.Popen[bytes]
    namespace: str
    configs: Configs
    stderr: Path

    def log(self) -> str:
        return self.stderr.read_text(errors="replace")[-3000:]


@pytest.fixture(scope="module")
def server(configs: Configs, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    namespace = unique_namespace()
    stderr = tmp_path_factory.mktemp("server") / "stderr.txt"
    # the server file allows tls alone: a ROS 2 router at plain tcp (rmw_zenohd's default) is not joined
    router = ["--ros-router", "none"]
    args = [
        *("--world", WORLD, "--mode", "lockstep", "--seed", "0", "--quiet", "--namespace", namespace, *router),
        *("--renderer", "tiny", "--camera-size", "80x60", "--render-workers", "1"),
        # TLS first: the render workers take the socket whatever the order
        *("--zenoh-config", str(configs.path("server")), "--listen", configs.endpoint, "--listen", configs.socket),
    ]
    with stderr.open("wb") as err:
        process = subprocess.Popen(
            [sys.executable, "-m", "simbot.sim.server", *args],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=err,
            cwd=REPO,
        )
    running = Server(process, namespace, configs, stderr)
    try:
        _wait_ready(running)
        yield running
        process.send_signal(signal.SIGTERM)
        code = process.wait(timeout=EXIT_TIMEOUT_S)
        assert code == 0, f"server exited with code {code} after SIGTERM: {running.log()}"
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()


def _wait_ready(server: Server) -> None:
    """Until the operator's session opens and the world's state answers it."""
    deadline = time.monotonic() + STARTUP_TIMEOUT_S
    while True:
        if server.process.poll() is not None:
            raise AssertionError(f"server exited with code {server.process.returncode} at start: {server.log()}")
        try:
            with session(server.configs, "operator") as operator:
                if any(reply.get("ok") for reply in ask(operator, server, "state", timeout=1.0)):
                    return
        except zenoh.ZError:
            pass  # not listening yet
        if time.monotonic() > deadline:
            raise AssertionError(f"the server did not answer within {STARTUP_TIMEOUT_S} s: {server.log()}")
        time.sleep(0.1)


# --- on the bus ------------------------------------------------------------------------------


def ask(
    client: zenoh.Session, server: Server, name: str, body: dict[str, Any] | None = None, timeout: float = 10.0
) -> list[dict[str, Any]]:
    """The replies of world control's JSON service `name` (an error reply as {"error": text})."""
    key = f"**/{server.namespace}/world/{WORLD}/{name}"
    replies = client.get(key, payload=json.dumps(body or {}), timeout=timeout)
    return [json.loads(r.ok.payload.to_bytes()) if r.ok else {"error": r.err.payload.to_string()} for r in replies]


def state(operator: zenoh.Session, server: Server) -> dict[str, Any]:
    replies = ask(operator, server, "state")
    assert replies and replies[0].get("ok"), f"state: {replies}"
    return replies[0]


def step(operator: zenoh.Session, server: Server, steps: int) -> int:
    """`steps` physics steps by the operator; the sim time reached, in ns."""
    replies = ask(operator, server, "control", {"multi_step": steps}, timeout=STEP_TIMEOUT_S)
    assert replies and replies[0].get("ok") is True, f"multi_step {steps}: {replies}"
    return round(replies[0]["sim_time"] * 1e9)


def is_cmd_vel(key: str, namespace: str) -> bool:
    """Whether `key` (a Zenoh key or a topic name) is the robot's `cmd_vel` in `namespace`, in either layout."""
    chunks = key.strip("/").split("/")
    return any(a == namespace and b == "cmd_vel" for a, b in zip(chunks, chunks[1:]))


def cmd_vel_received(operator: zenoh.Session, server: Server) -> int:
    """How many cmd_vel payloads the server counts as arrived (world state's `received`)."""
    received = state(operator, server)["received"]
    counts = [count for key, count in received.items() if is_cmd_vel(key, server.namespace)]
    assert counts, f"no cmd_vel among the server's inputs: {sorted(received)}"
    return sum(counts)


def graph(client: zenoh.Session) -> list[str]:
    """Every liveliness token `client` may see: simbot's graph (`simbot_graph/…`) and rmw_zenoh's (`@ros2_lv/…`)."""
    found = []
    for selector in ("**", "@ros2_lv/**"):
        found += [str(reply.ok.key_expr) for reply in client.liveliness().get(selector, timeout=5.0) if reply.ok]
    return found


def subscribed_key(tokens: list[str], namespace: str) -> str:
    """The key the server subscribes to for cmd_vel, from its graph token: simbot's
    `simbot_graph/sub/<type>/<key>`, or rmw_zenoh's subscriber token
    `@ros2_lv/<domain>/<zid>/<nid>/<eid>/MS/<enclave>/<ns>/<node>/<topic>/<type>/<hash>/<qos>`
    (names with '/' as '%'), whose data key is `<domain>/<topic>/<type>/<hash>`."""
    keys = []
    for token in tokens:
        chunks = token.split("/")
        if chunks[:2] == ["simbot_graph", "sub"] and len(chunks) > 3:
            keys.append("/".join(chunks[3:]))
        elif chunks[0] == "@ros2_lv" and len(chunks) >= 12 and chunks[5] == "MS":
            topic = chunks[9].replace("%", "/").strip("/")
            keys.append(f"{chunks[1]}/{topic}/{chunks[10]}/{chunks[11]}")
    found = sorted({key for key in keys if is_cmd_vel(key, namespace)})
    assert len(found) == 1, f"expected one cmd_vel subscription in the graph, found {found} among {len(tokens)} tokens"
    return found[0]


class Samples:
    """Decoded messages of one type from a Zenoh subscriber's thread, waited for with deadlines."""

    def __init__(self, typename: str) -> None:
        self.typename = typename
        self.keys: set[str] = set()
        self._messages: list[Any] = []
        self._cond = threading.Condition()

    def __call__(self, sample: zenoh.Sample) -> None:
        try:
            msg = decode(sample.payload.to_bytes(), self.typename)
        except DecodeError:
            return  # a wildcard put that intersects the subscription (a viewer's, were it let through)
        with self._cond:
            self.keys.add(str(sample.key_expr))
            self._messages.append(msg)
            self._cond.notify_all()

    def __len__(self) -> int:
        with self._cond:
            return len(self._messages)

    def wait_for(self, condition: Callable[[Any], bool], timeout: float, what: str) -> Any:
        deadline = time.monotonic() + timeout
        with self._cond:
            while True:
                found = next((msg for msg in self._messages if condition(msg)), None)
                if found is not None:
                    return found
                left = deadline - time.monotonic()
                if left <= 0:
                    raise AssertionError(
                        f"no {what} within {timeout} s ({len(self._messages)} {self.typename} received)"
                    )
                self._cond.wait(min(left, 0.05))

    def stamped(self, ns: int) -> Any:
        return self.wait_for(lambda m: messages.stamp_ns(m.header) == ns, 10.0, f"odom stamped {ns / 1e9:.3f} s")


@contextmanager
def subscribed(client: zenoh.Session, key_expr: str, samples: Samples) -> Iterator[Samples]:
    subscriber = client.declare_subscriber(key_expr, samples)
    try:
        yield samples
    finally:
        subscriber.undeclare()


def odom_key(server: Server) -> str:
    """odom in either layout: `ns/odom`, or `0/ns/odom/<type>/<hash>`."""
    return f"**/{server.namespace}/odom/**"


def stays(condition: Callable[[], bool], seconds: float) -> bool:
    """Whether `condition` holds every time it is polled for `seconds`."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if not condition():
            return False
        time.sleep(0.05)
    return condition()


def moved(odom: Samples, t0: int, t1: int) -> tuple[float, float]:
    """(planar distance between the odom poses stamped t0 and t1, forward speed at t1)."""
    a, b = odom.stamped(t0).pose.pose.position, odom.stamped(t1).pose.pose.position
    return math.hypot(b.x - a.x, b.y - a.y), odom.stamped(t1).twist.twist.linear.x


# --- the tests -------------------------------------------------------------------------------


def test_a_viewer_receives_the_sensors_and_sees_the_graph(server: Server) -> None:
    with session(server.configs, "viewer") as viewer, session(server.configs, "operator") as operator:
        odom, clock = Samples(ODOMETRY), Samples(CLOCK)
        with (
            subscribed(viewer, odom_key(server), odom),
            subscribed(viewer, f"**/{server.namespace}/clock/**", clock),
        ):
            deadline = time.monotonic() + 30.0
            while not (len(odom) and len(clock)):  # lockstep: nothing goes out but on a step
                assert time.monotonic() < deadline, f"viewer received {len(odom)} odom, {len(clock)} clock in 30 s"
                step(operator, server, 20)
        assert all(server.namespace in key for key in odom.keys | clock.keys), odom.keys | clock.keys
        tokens = graph(viewer)
        assert subscribed_key(tokens, server.namespace)


def test_a_viewers_cmd_vel_is_denied_an_operators_drives(server: Server) -> None:
    with (
        session(server.configs, "viewer") as viewer,
        session(server.configs, "operator") as operator,
        subscribed(operator, odom_key(server), Samples(ODOMETRY)) as odom,
    ):
        reset = ask(operator, server, "control", {"reset": {"all": True}})
        assert reset and reset[0].get("ok") is True and reset[0]["sim_time"] == 0.0, reset
        t0 = step(operator, server, SETTLE_STEPS)
        assert t0 % ODOM_PERIOD_NS == 0
        key = subscribed_key(graph(viewer), server.namespace)
        command = encode(messages.twist((SPEED, 0.0, 0.0), (0.0, 0.0, 0.0)))

        # the viewer: its session knows the server subscribes there, so it sends; the server drops it
        before = cmd_vel_received(operator, server)
        publisher = viewer.declare_publisher(key, congestion_control=zenoh.CongestionControl.BLOCK)
        wait_until(
            lambda: publisher.matching_status.matching,  # type: ignore[attr-defined]  # a MatchingStatus; the stub says bool
            10.0,
            f"the viewer to learn the server subscribes to {key}",
        )
        for _ in range(5):
            publisher.put(command)
        viewer.put(f"**/{server.namespace}/cmd_vel/**", command)  # a wildcard is no way around it
        assert ask(viewer, server, "state")[0]["ok"]  # after the puts, on the same link
        assert stays(lambda: cmd_vel_received(operator, server) == before, QUIET_S), "a viewer's cmd_vel arrived"
        t1 = step(operator, server, DRIVE_STEPS)
        still, still_speed = moved(odom, t0, t1)
        assert still < 0.01 and abs(still_speed) < 0.01, f"the viewer's cmd_vel moved the tug {still:.4f} m"

        # the operator, on the same key: 0.5 m/s for 2 s
        operator.put(key, command)
        wait_until(lambda: cmd_vel_received(operator, server) != before, 10.0, "the operator's cmd_vel")
        t2 = step(operator, server, DRIVE_STEPS)
        driven, speed = moved(odom, t1, t2)
        operator.put(key, encode(messages.twist()))
        assert driven == pytest.approx(SPEED * DRIVE_STEPS / 1000, rel=0.05), f"the operator drove {driven:.4f} m"
        assert speed == pytest.approx(SPEED, rel=0.05)
        print(f"cmd_vel at {key}, odom at {sorted(odom.keys)}")
        print(f"viewer's cmd_vel: {still:.4f} m, {still_speed:.4f} m/s; operator's: {driven:.4f} m, {speed:.4f} m/s")


def test_a_viewer_reads_the_world_state_but_cannot_control_it(server: Server) -> None:
    with session(server.configs, "viewer") as viewer, session(server.configs, "operator") as operator:
        before = state(operator, server)
        seen = ask(viewer, server, "state")
        assert seen and seen[0]["ok"] and seen[0]["sim_time"] == before["sim_time"], seen

        tug = before["models"]["flexley_tug"]["position"]
        denied = {
            "control": (f"**/{server.namespace}/world/{WORLD}/control", {"multi_step": 100}),
            "set_pose": (
                f"**/{server.namespace}/world/{WORLD}/set_pose",
                {"name": "flexley_tug", "position": {"x": tug[0] + 5.0, "y": tug[1], "z": tug[2]}},
            ),
            "remove": (f"**/{server.namespace}/world/{WORLD}/remove", {"name": "flexley_tug"}),
            "a wildcard": ("**", {"multi_step": 100}),
        }
        for what, (key, body) in denied.items():
            started = time.monotonic()
            replies = list(viewer.get(key, payload=json.dumps(body), timeout=5.0))
            # a wildcard query answers with the services the viewer may ask (state), never control's
            answered = [str(r.ok.key_expr) for r in replies if r.ok] + [
                r.err.payload.to_string() for r in replies if r.err
            ]
            assert all(k.endswith("/state") for k in answered), f"viewer's {what}: answered {answered}"
            print(f"viewer's {what}: {answered or 'no reply'} after {time.monotonic() - started:.3f} s")
        # the ROS 2 services, where this simbot serves them: the operator gets an answer, the viewer none
        ros_step = f"**/{server.namespace}/world/{WORLD}/step/**"
        served = list(operator.get(ros_step, timeout=5.0))
        if served:
            assert not list(viewer.get(ros_step, timeout=5.0)), "the viewer reached the step service"
        print(f"the ROS step service: {len(served)} replies to the operator, none to the viewer")

        after = state(operator, server)
        assert after["sim_time"] == before["sim_time"], "a viewer's control stepped the world"
        assert after["models"]["flexley_tug"]["position"] == tug, "a viewer's set_pose moved the tug"
        reply = ask(operator, server, "control", {"multi_step": 100})
        assert reply and reply[0]["ok"] is True and reply[0]["sim_time"] == pytest.approx(before["sim_time"] + 0.1)


@pytest.mark.parametrize("who", ["plain tcp", "tls without a certificate", "a certificate of another CA"])
def test_a_peer_without_a_valid_certificate_cannot_connect(server: Server, who: str) -> None:
    configs = server.configs

    def edit(config: zenoh.Config) -> None:
        if who == "plain tcp":
            config.insert_json5("transport/link/protocols", "null")
            config.insert_json5("transport/link/tls", "{}")
            config.insert_json5("connect/endpoints", json.dumps([f"tcp/127.0.0.1:{configs.port}"]))
        elif who == "tls without a certificate":
            config.insert_json5("transport/link/tls/connect_certificate", "null")
            config.insert_json5("transport/link/tls/connect_private_key", "null")

    config = _config(configs, "forged" if who == "a certificate of another CA" else "viewer", edit)
    started = time.monotonic()
    with pytest.raises(zenoh.ZError) as refused:
        zenoh.open(config).close()
    print(f"{who}: refused after {time.monotonic() - started:.2f} s: {' '.join(str(refused.value).split())[:160]}")


def test_a_certificate_the_access_control_does_not_name_may_do_nothing(server: Server) -> None:
    with session(server.configs, "stranger") as stranger, session(server.configs, "operator") as operator:
        odom = Samples(ODOMETRY)
        seen = Samples(ODOMETRY)
        with subscribed(stranger, odom_key(server), odom), subscribed(operator, odom_key(server), seen):
            step(operator, server, 100)
            seen.wait_for(lambda _: True, 10.0, "odom at the operator")
            assert stays(lambda: len(odom) == 0, QUIET_S), "a stranger received odom"
        assert not ask(stranger, server, "state", timeout=5.0)
        assert not graph(stranger)


def test_a_viewer_receives_the_camera_images(server: Server) -> None:
    """The render workers publish the images from their own processes, joining on the unix socket."""
    images: list[Any] = []
    received = threading.Event()

    def image(sample: zenoh.Sample) -> None:
        if "camera_info" in str(sample.key_expr):
            return
        try:
            images.append(decode(sample.payload.to_bytes(), IMAGE))
            received.set()
        except DecodeError:
            pass

    with session(server.configs, "viewer") as viewer, session(server.configs, "operator") as operator:
        subscriber = viewer.declare_subscriber(f"**/{server.namespace}/camera_front/**", image)
        try:
            deadline = time.monotonic() + STARTUP_TIMEOUT_S
            while not received.is_set():  # the render pool starts once somebody watches a camera
                assert time.monotonic() < deadline, f"no image within {STARTUP_TIMEOUT_S} s: {server.log()}"
                sensors = state(operator, server)["sensors"]
                failed = [v["error"] for k, v in sensors.items() if "camera_front" in k and v.get("error")]
                assert not failed, f"the cameras stopped: {failed[0]}"
                step(operator, server, 100)
        finally:
            subscriber.undeclare()
    assert (images[0].width, images[0].height) == (80, 60)
