"""Test helpers for the server: a real `simbot-server` subprocess on a free loopback port, a client on it.

`running_server(...)` starts `python -m simbot.sim.server` with its own port and namespace and
`--quiet`, waits until its world control answers, and on the way out sends SIGTERM and asserts
that the process exits with code 0 within EXIT_TIMEOUT_S, or within the time it took to start
where that was longer. `SimServer` wraps the client node with the world
control calls the tests use (state, step, reset, poses); `Collector` gathers messages from Zenoh
callback threads into a list under a lock and waits for conditions with a timeout.

Lockstep is the mode for exact sim durations: a command is put on the bus, then `step(n)` runs
n physics steps. `send` returns only once the server's state counts the command as received
(queued for the next step), so the command is consumed in the first of those steps however
loaded the machine is. (Zenoh may deliver a sample and a later query out of order: they can
travel at different priorities.)
"""

from __future__ import annotations

import logging
import math
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Generic, TypeVar

import pytest
import zenoh
from bus_helpers import endpoint, free_port, unique_namespace
from gl_helpers import NO_EGL

from simbot.bus import BusOpenError, BusOptions, Node, Publisher, ServiceError, Subscription, messages
from simbot.bus.rmw import RosGraph

REPO = Path(__file__).resolve().parents[1]
STARTUP_TIMEOUT_S = 120.0
"""A server listens within seconds; at a load average of 15 on two cores one took over 30 s."""
EXIT_TIMEOUT_S = 10.0
"""A server exits in 0.3–0.7 s here (0.5–0.7 s with two render workers, measured quiet); 10 s bounds
a machine loaded by other work: a server with render workers once took over 2 s at a load average
of 5, and with two workers over 5 s in CI's three test processes on two cores."""
SEND_TIMEOUT_S = 10.0

TWIST = "geometry_msgs/msg/Twist"
ODOMETRY = "nav_msgs/msg/Odometry"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
CLOCK = "rosgraph_msgs/msg/Clock"
STRING = "std_msgs/msg/String"
EMPTY = "std_msgs/msg/Empty"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
JOINT_STATE = "sensor_msgs/msg/JointState"

T = TypeVar("T")

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]


# --- geometry -------------------------------------------------------------------------------


def wrap(angle: float) -> float:
    """`angle` in (−π, π]."""
    return math.atan2(math.sin(angle), math.cos(angle))


def unwrap(yaws: Sequence[float]) -> list[float]:
    """A continuous heading from wrapped samples (successive samples less than π apart)."""
    if not yaws:
        return []
    out = [yaws[0]]
    for yaw in yaws[1:]:
        out.append(out[-1] + wrap(yaw - out[-1]))
    return out


def planar_distance(a: Sequence[float], b: Sequence[float]) -> float:
    return math.hypot(b[0] - a[0], b[1] - a[1])


def pose_of(msg: Any) -> tuple[Vec3, Quat]:
    """(xyz, xyzw) of a Pose message."""
    p, o = msg.position, msg.orientation
    return (p.x, p.y, p.z), (o.x, o.y, o.z, o.w)


def stamp_ns(msg: Any) -> int:
    """Integer nanoseconds of a message's header stamp (or of a Clock's clock)."""
    if hasattr(msg, "header"):
        return messages.stamp_ns(msg.header)
    return messages.stamp_ns(msg.clock)


# --- collecting -----------------------------------------------------------------------------


class Collector(Generic[T]):
    """Messages from a Zenoh callback thread, each with the monotonic time it arrived.

    Use the instance as the callback; it only appends under a lock and notifies waiters.
    """

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._items: list[tuple[float, T]] = []

    def __call__(self, msg: T) -> None:
        now = time.monotonic()
        with self._cond:
            self._items.append((now, msg))
            self._cond.notify_all()

    def __len__(self) -> int:
        with self._cond:
            return len(self._items)

    def messages(self) -> list[T]:
        """A snapshot of the messages so far, oldest first."""
        with self._cond:
            return [msg for _, msg in self._items]

    def timed(self) -> list[tuple[float, T]]:
        """A snapshot of (arrival time, message) pairs."""
        with self._cond:
            return list(self._items)

    def clear(self) -> None:
        with self._cond:
            self._items.clear()

    def wait_for(self, condition: Callable[[list[T]], object], timeout: float = 5.0, what: str = "messages") -> list[T]:
        """Waits until `condition(messages)` holds; AssertionError naming `what` after `timeout` s."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while True:
                snapshot = [msg for _, msg in self._items]
                if condition(snapshot):
                    return snapshot
                left = deadline - time.monotonic()
                if left <= 0:
                    raise AssertionError(f"timed out after {timeout} s waiting for {what} ({len(snapshot)} received)")
                self._cond.wait(min(left, 0.05))

    def wait_count(self, count: int, timeout: float = 5.0, what: str = "messages") -> list[T]:
        return self.wait_for(lambda items: len(items) >= count, timeout, f"{count} {what}")

    def wait_stamp(self, ns: int, timeout: float = 5.0, what: str = "message") -> T:
        """The message stamped exactly `ns` (waits for it)."""
        found = self.wait_for(
            lambda items: any(stamp_ns(m) == ns for m in items), timeout, f"{what} stamped {ns / 1e9:.3f} s"
        )
        return next(m for m in found if stamp_ns(m) == ns)


def payload(sample: zenoh.Sample) -> bytes:
    """What `raw_samples` keeps of a sample: its payload."""
    return sample.payload.to_bytes()


def keyed_payload(sample: zenoh.Sample) -> tuple[str, bytes]:
    """What `raw_samples` keeps of a sample: its topic's name (`ns/odom`, from rmw_zenoh's data key
    `0/ns/odom/<type>/<hash>`; another key as it is) and its payload."""
    key = str(sample.key_expr)
    return RosGraph().name_of(key) or key, sample.payload.to_bytes()


def data_keys(namespace: str) -> str:
    """Every data key of topics in `namespace` (domain 0), for a plain Zenoh subscriber."""
    return f"0/{namespace}/**"


@contextmanager
def raw_samples(session: zenoh.Session, key_expr: str, keep: Callable[[zenoh.Sample], T]) -> Iterator[Collector[T]]:
    """What a plain Zenoh subscriber of the test receives on `key_expr`, in arrival order (`keep` picks what of each)."""
    collector: Collector[T] = Collector()
    subscriber = session.declare_subscriber(key_expr, lambda sample: collector(keep(sample)))
    try:
        yield collector
    finally:
        subscriber.undeclare()


def wait_until(
    condition: Callable[[], object], timeout: float = 5.0, what: str = "condition", poll: float = 0.01
) -> None:
    """Poll `condition` until it is true; AssertionError naming `what` after `timeout` seconds."""
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout} s waiting for {what}")
        time.sleep(poll)


# --- the server -----------------------------------------------------------------------------


def render_workers(pid: int) -> list[int]:
    """The server's render worker processes: the children of its fork server (simbot.sim.render.starter), or
    its spawned children other than multiprocessing's resource tracker where it has none."""
    found = []
    for child in _children(pid):
        cmdline = Path(f"/proc/{child}/cmdline").read_bytes()
        if b"forkserver" in cmdline:
            found += _children(child)
        elif b"spawn_main" in cmdline and b"resource_tracker" not in cmdline:
            found.append(child)
    return found


def _children(pid: int) -> list[int]:
    try:
        return [int(child) for child in Path(f"/proc/{pid}/task/{pid}/children").read_text().split()]
    except FileNotFoundError:  # gone meanwhile
        return []


def killed_script(code: str, timeout: float = 300.0) -> str:
    """Runs `code` in a Python process of its own, which ends by SIGKILLing itself (no finaliser
    runs); its standard output."""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=timeout)
    assert done.returncode == -signal.SIGKILL, done.stderr[-2000:]
    return done.stdout


def descendants(pid: int) -> set[int]:
    """Every process below `pid` (/proc's parent links), however deep: an async env's server is
    a grandchild, a Ray actor's a great-grandchild."""
    parents: dict[int, int] = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                stat = Path(f"/proc/{entry}/stat").read_text()
                parents[int(entry)] = int(stat.rsplit(")", 1)[1].split()[1])
            except (OSError, ValueError, IndexError):
                continue
    found: set[int] = set()
    frontier = {pid}
    while frontier:
        frontier = {child for child, parent in parents.items() if parent in frontier} - found
        found |= frontier
    return found


def alive(pids: set[int]) -> set[int]:
    """Those of `pids` still running (not gone, not a zombie)."""
    left = set()
    for pid in pids:
        try:
            state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except (OSError, IndexError):
            continue
        if state != "Z":
            left.add(pid)
    return left


def dropped(caplog: pytest.LogCaptureFixture) -> list[str]:
    """The lines a world logged for the systems it left out for bad parameters (in this process)."""
    return [r.getMessage() for r in caplog.records if r.name == "simbot.sim.loop.world" and r.levelno == logging.ERROR]


def server_command(*args: str) -> list[str]:
    return [sys.executable, "-m", "simbot.sim.server", *args]


@dataclass
class SimServer:
    """A running server process and a client node on its bus."""

    process: subprocess.Popen[bytes]
    port: int
    namespace: str
    world: str
    mode: str
    node: Node
    stderr_path: Path
    args: tuple[str, ...] = ()
    """The server's command-line arguments (what `restarted` starts again)."""
    started_s: float = 0.0
    """How long it took from its spawn to a world control that answers: the measure of how long it may take to stop."""
    stopped: bool = False
    _publishers: dict[tuple[str, str], Publisher] = field(default_factory=dict)
    _subscriptions: list[Subscription[Any]] = field(default_factory=list)

    # bus

    @property
    def endpoint(self) -> str:
        return endpoint(self.port)

    def key(self, topic: str) -> str:
        """The name of `topic` in the server's namespace (as in `received`, `dropped` and `last_errors`)."""
        return self.node.key(topic)

    def data_key(self, topic: str, typename: str) -> str:
        """The Zenoh key of `topic`'s samples of `typename` (rmw_zenoh's), for a plain Zenoh put or subscriber."""
        return self.node.data_key(topic, typename)

    def any_type_key(self, topic: str) -> str:
        """Every Zenoh key of `topic`, whatever type it carries."""
        return self.node.graph.any_type_key(self.node.key(topic))

    def client(self) -> Node:
        """A new client node on the server's bus (the caller closes it)."""
        return Node(BusOptions(connect=(self.endpoint,), namespace=self.namespace, connect_timeout=10.0), "client")

    def publisher(self, topic: str, typename: str) -> Publisher:
        """One reliable (BLOCK) publisher per topic and type, kept for the server's life."""
        if (topic, typename) not in self._publishers:
            self._publishers[topic, typename] = self.node.publisher(topic, typename, drop=False)
        return self._publishers[topic, typename]

    def subscribe(self, topic: str, typename: str, *, latched: bool = False) -> Collector[Any]:
        """Messages of `topic` collected on the server's client node, until `unsubscribe_all`."""
        collector: Collector[Any] = Collector()
        self._subscriptions.append(self.node.subscribe(topic, typename, collector, latched=latched))
        return collector

    def unsubscribe_all(self) -> None:
        """Undeclares what `subscribe` declared (a test's collectors do not outlive it)."""
        subscriptions, self._subscriptions = self._subscriptions, []
        for subscription in subscriptions:
            subscription.close()

    def send(self, topic: str, msg: Any) -> None:
        """Puts `msg` on one of the server's input topics and waits until the server has received it."""
        key = self.key(topic)
        received = self.state()["received"]
        assert key in received, f"{topic!r} is not an input of the server ({', '.join(received)})"
        self.publisher(topic, msg.__msgtype__).put(msg)
        wait_until(
            lambda: self.state()["received"][key] > received[key],
            SEND_TIMEOUT_S,
            f"the server to receive {topic}",
            poll=0.002,
        )

    def send_raw(self, topic: str, typename: str, data: bytes) -> None:
        """`data` as it is, on `topic`'s key of `typename` (garbage, to see it refused)."""
        self.publisher(topic, typename).put_raw(data)

    def drive(self, vx: float, wz: float = 0.0) -> None:
        self.send("cmd_vel", messages.twist((vx, 0.0, 0.0), (0.0, 0.0, wz)))

    # world control

    def call(self, name: str, payload: dict[str, Any] | bytes, timeout: float = 10.0) -> dict[str, Any]:
        """World control's `name`; a TimeoutError also says whether the server still runs and how its log ends."""
        try:
            return self.node.call(f"world/{self.world}/{name}", payload, timeout=timeout)
        except TimeoutError as exc:
            raise TimeoutError(f"{exc}; {self.health()}") from None

    def health(self) -> str:
        """Whether the process runs, and the end of its standard error: what a failure should show."""
        code = self.process.poll()
        state = "the server runs" if code is None else f"the server exited with code {code}"
        tail = " | ".join(self.stderr().strip().splitlines()[-8:]) or "(nothing)"
        return f"{state}; its stderr ends: {tail}"

    def control(self, body: dict[str, Any] | bytes, timeout: float = 60.0) -> dict[str, Any]:
        return self.call("control", body, timeout)

    def state(self) -> dict[str, Any]:
        return self.call("state", {})

    def step(self, steps: int) -> dict[str, Any]:
        """`steps` physics steps; returns the reply (sim_time, iterations) once they are done."""
        reply = self.control({"multi_step": steps})
        assert reply.get("ok") is True, f"multi_step {steps} refused: {reply}"
        return reply

    @property
    def has_robot(self) -> bool:
        """Whether the server has its robot (it was not started with `--robot none`)."""
        return not any(a == "--robot" and b == "none" for a, b in zip(self.args, self.args[1:], strict=False))

    def reset(self) -> None:
        """Stop command first (it is consumed at the next step), then every model back where it began."""
        if self.mode == "lockstep" and self.has_robot:
            self.drive(0.0, 0.0)
        reply = self.control({"reset": {"all": True}})
        assert reply.get("ok") is True and reply["sim_time"] == 0.0, f"reset refused: {reply}"

    def pose(self, model: str = "flexley_tug", state: dict[str, Any] | None = None) -> tuple[Vec3, Quat]:
        """A model's ground-truth pose from the world state."""
        models = (state or self.state())["models"]
        assert model in models, f"no model {model!r} in the world state ({', '.join(models)})"
        p, q = models[model]["position"], models[model]["orientation"]
        return (p[0], p[1], p[2]), (q[0], q[1], q[2], q[3])

    def prime(self, *collectors: Collector[Any], chunk: int = 20, timeout: float = 5.0) -> None:
        """Lockstep: steps in small chunks until every collector has a message (subscriptions are live)."""
        deadline = time.monotonic() + timeout
        while not all(len(c) for c in collectors):
            if time.monotonic() > deadline:
                raise AssertionError(f"no messages within {timeout} s of subscribing: {[len(c) for c in collectors]}")
            self.step(chunk)
            time.sleep(0.01)

    def latest(self, topics: Mapping[str, str], chunk: int = 20, timeout: float = 60.0) -> dict[str, Any]:
        """Lockstep: subscribes to each topic (key → type), steps until each has a message, and
        returns the last of each; unsubscribes again, so cameras stop rendering."""
        collectors = {topic: self.subscribe(topic, typename) for topic, typename in topics.items()}
        try:
            self.prime(*collectors.values(), chunk=chunk, timeout=timeout)
            return {topic: c.messages()[-1] for topic, c in collectors.items()}
        finally:
            self.unsubscribe_all()

    # process

    def alive(self) -> bool:
        return self.process.poll() is None

    def stderr(self) -> str:
        return self.stderr_path.read_text(errors="replace")

    def errors(self) -> list[str]:
        """The ERROR lines it logged (a system it left out for bad parameters, say)."""
        return [line for line in self.stderr().splitlines() if line.startswith("ERROR")]

    def stop(self, sig: int = signal.SIGTERM, timeout: float | None = None) -> float:
        """Sends `sig` and asserts a clean exit (code 0) within `timeout` seconds (by default
        EXIT_TIMEOUT_S, or as long as the server took to start where that was longer: a loaded
        machine slows both alike); returns the seconds it took."""
        timeout = max(EXIT_TIMEOUT_S, self.started_s) if timeout is None else timeout
        self.node.close()
        self.stopped = True
        if self.process.poll() is not None:
            raise AssertionError(
                f"server died before it was stopped (code {self.process.returncode}): {self.stderr()[-2000:]}"
            )
        start = time.monotonic()
        self.process.send_signal(sig)
        try:
            code = self.process.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
            raise AssertionError(f"server did not exit within {timeout} s of {signal.Signals(sig).name}") from None
        elapsed = time.monotonic() - start
        assert code == 0, f"server exited with code {code} after {signal.Signals(sig).name}: {self.stderr()[-2000:]}"
        return elapsed


def _spawn(
    args: Sequence[str], stderr_path: Path, cwd: Path = REPO, env: Mapping[str, str] | None = None
) -> subprocess.Popen[bytes]:
    env = {**os.environ, "PYTHONUNBUFFERED": "1", **(env or {})}
    with stderr_path.open("wb") as err:
        return subprocess.Popen(
            server_command(*args), stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=err, cwd=cwd, env=env
        )


def _connect(process: subprocess.Popen[bytes], port: int, namespace: str, stderr_path: Path) -> Node:
    """A client node on the server, tried a second at a time so that a server dying at start is seen at once."""
    deadline = time.monotonic() + STARTUP_TIMEOUT_S
    while True:
        if process.poll() is not None:
            raise AssertionError(
                f"server exited with code {process.returncode} at start: {stderr_path.read_text()[-2000:]}"
            )
        try:
            return Node(BusOptions(connect=(endpoint(port),), namespace=namespace, connect_timeout=1.0), "client")
        except BusOpenError:
            if time.monotonic() > deadline:
                raise


def _wait_ready(process: subprocess.Popen[bytes], node: Node, world: str, stderr_path: Path) -> None:
    deadline = time.monotonic() + STARTUP_TIMEOUT_S
    while True:
        if process.poll() is not None:
            raise AssertionError(
                f"server exited with code {process.returncode} at start: {stderr_path.read_text()[-2000:]}"
            )
        try:
            state = node.call(f"world/{world}/state", {}, timeout=0.5)
        except (TimeoutError, ServiceError):
            state = None
        if state is not None and state.get("ok"):
            return
        if time.monotonic() > deadline:
            raise AssertionError(
                f"server's world control did not answer within {STARTUP_TIMEOUT_S} s: {stderr_path.read_text()[-2000:]}"
            )
        time.sleep(0.05)


@contextmanager
def running_server(
    world: str = "empty",
    mode: str = "lockstep",
    seed: int = 0,
    extra: Sequence[str] = (),
    world_name: str | None = None,
    cwd: Path = REPO,
    env: Mapping[str, str] | None = None,
) -> Iterator[SimServer]:
    """A `simbot-server` on a fresh loopback port and namespace, working in `cwd` (where a camera's
    relative `<save>` path lands), with `env` added to its environment; stopped with SIGTERM, exit 0
    asserted (`SimServer.stop`)."""
    port = free_port()
    namespace = unique_namespace()
    name = world_name or Path(world).stem
    args = [
        "--world",
        world,
        "--mode",
        mode,
        "--seed",
        str(seed),
        "--listen",
        endpoint(port),
        "--namespace",
        namespace,
        "--quiet",
        *extra,
    ]
    with (
        tempfile.TemporaryDirectory(prefix="simbot-server-") as tmp,
        _serving(args, port, namespace, name, mode, Path(tmp) / "stderr.txt", cwd, env) as server,
    ):
        yield server


@contextmanager
def _serving(
    args: Sequence[str],
    port: int,
    namespace: str,
    name: str,
    mode: str,
    stderr_path: Path,
    cwd: Path = REPO,
    env: Mapping[str, str] | None = None,
) -> Iterator[SimServer]:
    """The server process of `args`, once its world control answers; stopped (or killed) on the way out."""
    spawned = time.monotonic()
    process = _spawn(args, stderr_path, cwd, env)
    node: Node | None = None
    try:
        node = _connect(process, port, namespace, stderr_path)
        _wait_ready(process, node, name, stderr_path)
        started_s = time.monotonic() - spawned
        server = SimServer(process, port, namespace, name, mode, node, stderr_path, tuple(args), started_s)
        yield server
        if not server.stopped:
            server.stop()
    finally:
        if node is not None:
            node.close()
        if process.poll() is None:
            process.kill()
            process.wait()


@contextmanager
def restarted(server: SimServer) -> Iterator[SimServer]:
    """`server` killed with SIGKILL (a crash) and another started with the same arguments on the same
    port and namespace, as a supervisor restarts it; yielded once its world control answers, stopped
    as `running_server` stops its own. Sim time on the new one starts again from zero."""
    server.node.close()
    server.stopped = True
    server.process.kill()
    server.process.wait()
    stderr_path = server.stderr_path.with_name(f"restarted-{server.stderr_path.name}")
    with _serving(server.args, server.port, server.namespace, server.world, server.mode, stderr_path) as again:
        yield again


def left_out(world: str, world_name: str, *extra: str) -> list[str]:
    """The lines a server of `world` logs for the systems it leaves out for bad parameters (one
    each), once its world control answers and it steps (the rest of the world runs)."""
    with running_server(world, "lockstep", extra=extra, world_name=world_name) as sim:
        sim.step(10)
        errors = sim.errors()
    assert errors, "no system was left out"
    return errors


@contextmanager
def drawn_by(
    renderer: str, world: str, extra: Sequence[str] = (), world_name: str | None = None
) -> Iterator[SimServer]:
    """A lockstep server of `world` whose cameras `renderer` draws (gl or tiny); skips gl where no EGL context opens."""
    if renderer == "gl" and NO_EGL:
        pytest.skip(NO_EGL)
    with running_server(world, "lockstep", extra=[*extra, "--renderer", renderer], world_name=world_name) as sim:
        yield sim


def module_server(world: str, mode: str = "lockstep", extra: Sequence[str] = ()) -> Any:
    """A test module's `sim` fixture: one server for the whole module (`sim = module_server("empty")`)."""

    @pytest.fixture(scope="module", name="sim")
    def sim() -> Iterator[SimServer]:
        with running_server(world, mode, extra=extra) as server:
            yield server

    return sim


def reset_before_each(settle_steps: int = 0) -> Any:
    """A module's autouse fixture: the world reset (then stepped `settle_steps`) before each test, its subscriptions gone after."""

    @pytest.fixture(autouse=True, name="fresh_world")
    def fresh(sim: SimServer) -> Iterator[SimServer]:
        sim.reset()
        if settle_steps:
            sim.step(settle_steps)
        yield sim
        sim.unsubscribe_all()

    return fresh


ROUTER_CONFIG = REPO / "docker" / "zenoh-router.json5"
ROUTER = REPO / "docker" / "zenoh_router.py"


@contextmanager
def router(port: int, servers: list[SimServer]) -> Iterator[str]:
    """docker/zenoh_router.py (a Zenoh session in router mode, configured by docker/zenoh-router.json5
    with only its endpoints replaced) on `port`, connected to `servers`; yields its endpoint."""
    listen, connect = endpoint(port), [s.endpoint for s in servers]
    args = [sys.executable, str(ROUTER), str(ROUTER_CONFIG), "--listen", listen, "--connect", *connect]
    process = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        assert process.stdout is not None and process.stdout.readline().startswith(b"zenoh router: "), process.stderr
        yield listen
    finally:
        process.send_signal(signal.SIGTERM)
        assert process.wait(timeout=10) == 0, process.stderr.read() if process.stderr else ""
