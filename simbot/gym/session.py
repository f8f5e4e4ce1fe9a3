"""An environment's simulator: a lockstep `simbot-server` it starts (or one it is given) and a client
node on its bus, with the few requests an environment makes: send a command so that the next
step sees it, step, reset, move a model, read the world state, and close.

A started server runs under `simbot.gym.keeper` (which stops it when the environment's process
ends, however it ends) in a process group of its own, on a fresh loopback port (found by binding
port 0) with a unique namespace, `--ros-router none` (an environment never joins a ROS graph) and
`--quiet`; its standard error goes to a file whose tail an error quotes. `close()` asks it to stop
(SIGTERM), kills it after `STOP_TIMEOUT_S`, and then kills whatever is left of its group (render
workers of a server that was killed), so nothing outlives the environment.

Zenoh and fork: Zenoh's threads do not survive a fork, and Gymnasium's `AsyncVectorEnv` forks its
workers by default (on Linux), after the program has often used an env itself (`check_env`). So
the first session an environment opens in a process makes "spawn" the start method of a program
that has not chosen one (`multiprocessing.set_start_method`: Python 3.14 stops defaulting to fork
for the same reason), and a process forked after Zenoh started gets `ForkedSessionError`, one line
naming the fix, before any server starts (simbot/bus/forks.py), never a hang.

Every failure of the server surfaces as `SimServerError` naming the server (its command line, or
the endpoint given) and what ended it: the exit code where the process is gone, else the request
and the timeout that ran out.
"""

from __future__ import annotations

import contextlib
import itertools
import logging
import multiprocessing
import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from simbot.bus import BusOpenError, BusOptions, Node, Publisher, ServiceError
from simbot.bus.forks import check_fork_safe
from simbot.gym.errors import SimServerError
from simbot.transform import yaw_quaternion

log = logging.getLogger(__name__)

START_TIMEOUT_S = 120.0
"""A server answers within seconds; on two loaded cores one took over 30 s (tests/server_helpers.py)."""
STOP_TIMEOUT_S = 10.0
POLL_S = 0.002
EXIT_GRACE_S = 0.5
"""After a failed request: how long a dying server is given to be reaped before it is called hung."""
_NAMESPACES = itertools.count()


@dataclass(frozen=True)
class ServerSpec:
    """What a started server runs: its world, the files added to it, the robot, and the options an
    environment sets. `args` is the command line without the bus options."""

    world: Path
    robot: Path
    additions: tuple[str, ...] = ()
    seed: int = 0
    camera_size: tuple[int, int] | None = None
    camera_rate: float | None = None
    render_workers: int | None = None
    profile: Path | None = None
    """The variation profile its seeded resets draw from, when not the world's own."""
    physics: str = "dynamic"
    """`--physics`: dynamic, or kinematic (robots move by their drives' commands and stop at contact)."""

    def args(self) -> list[str]:
        args = ["--world", str(self.world), "--robot", str(self.robot), "--mode", "lockstep", "--seed", str(self.seed)]
        args += ["--physics", self.physics]
        for addition in self.additions:
            args += ["--add", addition]
        if self.camera_size is not None:
            args += ["--camera-size", f"{self.camera_size[0]}x{self.camera_size[1]}"]
        if self.camera_rate is not None:
            args += ["--camera-rate", repr(self.camera_rate)]
        if self.render_workers is not None:
            args += ["--render-workers", str(self.render_workers)]
        if self.profile is not None:
            args += ["--randomise", f"0:{self.profile}"]
        return args


def server_command(spec: ServerSpec, listen: str, namespace: str) -> list[str]:
    """The command line of a server for `spec` on `listen` in `namespace`: what an environment runs,
    and what to run by hand for an environment given `endpoint=`."""
    bus = ["--listen", listen, "--namespace", namespace, "--ros-router", "none", "--quiet"]
    return [sys.executable, "-m", "simbot.sim.server", *spec.args(), *bus]


def free_port() -> int:
    """A loopback TCP port that nothing listens on now (the kernel's pick for port 0)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind(("127.0.0.1", 0))
        return int(probe.getsockname()[1])


def unique_namespace() -> str:
    """A namespace no other environment uses: process, counter and a random part."""
    return f"gym_{os.getpid()}_{next(_NAMESPACES)}_{secrets.token_hex(3)}"


class Session:
    """A lockstep server and a client node on its bus; see the module docstring."""

    def __init__(
        self,
        node: Node,
        world: str,
        timeout: float,
        name: str,
        process: subprocess.Popen[bytes] | None = None,
        folder: Path | None = None,
    ) -> None:
        self.node = node
        self.world = world
        self.timeout = timeout
        self.name = name
        """How errors name the server: its command line, or its endpoint and namespace."""
        self.process = process
        """What the session started: `simbot.gym.keeper`, which runs the server and ends as it does."""
        self.server_pid: int | None = None
        """The server's own process (a child of `process`, in its process group)."""
        self.folder = folder
        self._publishers: dict[tuple[str, str], Publisher] = {}
        self._expected: dict[str, int] = {}
        self.closed = False

    @staticmethod
    def start(spec: ServerSpec, world: str, folder: Path, timeout: float) -> Session:
        """Starts a server for `spec` (its robot already written into `folder`, which the session then
        owns) and waits until its world control answers."""
        _fork_safe()
        port, namespace = free_port(), unique_namespace()
        endpoint = f"tcp/127.0.0.1:{port}"
        command = server_command(spec, endpoint, namespace)
        log.info("starting %s", " ".join(command))
        with (folder / "server.log").open("wb") as err:
            process = subprocess.Popen(
                [sys.executable, "-m", "simbot.gym.keeper", *command],
                stdin=subprocess.PIPE,  # held open, never written: it closes when this process ends
                stdout=subprocess.PIPE,
                stderr=err,
                env={**os.environ, "PYTHONUNBUFFERED": "1"},
                start_new_session=True,
            )
        assert process.stdout is not None
        line = process.stdout.readline().strip()
        server_pid = int(line) if line.isdigit() else None
        name = f"simbot server `{' '.join(command)}` (pid {server_pid})"
        session: Session | None = None
        try:
            if server_pid is None:
                raise SimServerError(f"{name} did not start (exit code {process.wait()})")
            node = _connect(endpoint, namespace, process, name, timeout)
            session = Session(node, world, timeout, name, process, folder)
            session.server_pid = server_pid
            session.wait_ready(START_TIMEOUT_S)
            return session
        except BaseException:
            if session is not None:
                session.close()
            else:
                _end(process)
                shutil.rmtree(folder, ignore_errors=True)
            raise

    @staticmethod
    def connect(endpoint: str, namespace: str, world: str, timeout: float) -> Session:
        """A session on a server someone else runs (and stops)."""
        _fork_safe()
        name = f"simbot server at {endpoint} (namespace {namespace!r})"
        node = _connect(endpoint, namespace, None, name, timeout)
        session = Session(node, world, timeout, name)
        try:
            session.wait_ready(timeout)
        except BaseException:
            session.close()
            raise
        return session

    # --- the server's health -------------------------------------------------------------

    def check(self, what: str) -> None:
        """SimServerError when the server process has exited (`what`: the request it was needed for)."""
        if self.process is not None and self.process.poll() is not None:
            raise SimServerError(
                f"{self.name} exited with code {self.process.returncode} during {what}; its last words: {self._tail()}"
            )

    def _settle(self) -> None:
        """A moment for a process the bus just lost to be reaped, so that its exit code is what is reported."""
        if self.process is not None:
            with contextlib.suppress(subprocess.TimeoutExpired):
                self.process.wait(timeout=EXIT_GRACE_S)

    def _tail(self, lines: int = 5) -> str:
        log_file = self.folder / "server.log" if self.folder is not None else None
        if log_file is None or not log_file.is_file():
            return "(none)"
        text = log_file.read_text(errors="replace").strip().splitlines()[-lines:]
        return " | ".join(text) or "(none)"

    def wait_ready(self, timeout: float) -> None:
        """Until world control answers (a starting server's queryables come up last)."""
        deadline = time.monotonic() + timeout
        while True:
            self.check("start")
            try:
                if self.node.call(f"world/{self.world}/state", {}, timeout=1.0).get("ok"):
                    return
            except (TimeoutError, ServiceError):
                pass
            if time.monotonic() > deadline:
                raise SimServerError(f"{self.name}: world {self.world!r} did not answer within {timeout:g} s of start")
            time.sleep(0.05)

    # --- requests --------------------------------------------------------------------------

    def call(self, name: str, payload: Mapping[str, Any], timeout: float | None = None) -> dict[str, Any]:
        """World control's `name` (control, state, set_pose); SimServerError when it fails or is refused."""
        what = f"world/{self.world}/{name} {dict(payload) if name != 'state' else ''}".strip()
        self.check(what)
        limit = self.timeout if timeout is None else timeout
        try:
            reply = self.node.call(f"world/{self.world}/{name}", payload, timeout=limit)
        except (TimeoutError, ServiceError) as exc:
            self._settle()
            self.check(what)
            raise SimServerError(f"{self.name} did not answer {what} within {limit:g} s: {exc}") from None
        if reply.get("ok") is not True:
            raise SimServerError(f"{self.name} refused {what}: {reply.get('error', reply)}")
        return reply

    def state(self) -> dict[str, Any]:
        return self.call("state", {})

    def step(self, steps: int) -> int:
        """`steps` physics steps; the sim time reached, in nanoseconds."""
        reply = self.call("control", {"multi_step": steps})
        return round(float(reply["sim_time"]) * 1e9)

    def reset(self, seed: int | None = None) -> None:
        """Every model back where the server started it, sim time 0; with a seed, the world that
        seed draws from the server's variation profile."""
        self.call("control", {"reset": {"all": True} if seed is None else {"seed": seed}})
        self._expected.clear()  # counted again from the state that follows

    def set_pose(self, model: str, x: float, y: float, z: float, yaw: float) -> None:
        """Teleports `model` (and stops it) to a pose upright on the floor, heading `yaw`."""
        orientation = dict(zip("xyzw", yaw_quaternion(yaw), strict=True))
        self.call("set_pose", {"name": model, "position": {"x": x, "y": y, "z": z}, "orientation": orientation})

    def send(self, items: Sequence[tuple[str, Any]]) -> None:
        """Puts each (topic, message) reliably and returns once the server has received them all, so
        that the next step acts on them (a sample and a later query may travel apart on Zenoh)."""
        if not items:
            return
        if any(self.node.key(topic) not in self._expected for topic, _ in items):
            received = self.state()["received"]
            for topic, _ in items:
                self._expected.setdefault(self.node.key(topic), int(received.get(self.node.key(topic), 0)))
        for topic, msg in items:
            self._publisher(topic, msg.__msgtype__).put(msg)
            self._expected[self.node.key(topic)] += 1
        deadline = time.monotonic() + self.timeout
        keys = [self.node.key(topic) for topic, _ in items]
        while True:
            received = self.state()["received"]
            if all(int(received.get(key, 0)) >= self._expected[key] for key in keys):
                return
            if time.monotonic() > deadline:
                raise SimServerError(f"{self.name} did not receive {', '.join(keys)} within {self.timeout:g} s")
            time.sleep(POLL_S)

    def _publisher(self, topic: str, typename: str) -> Publisher:
        if (topic, typename) not in self._publishers:
            self._publishers[topic, typename] = self.node.publisher(topic, typename, drop=False)
        return self._publishers[topic, typename]

    # --- the end ---------------------------------------------------------------------------

    def close(self) -> None:
        """Closes the node; a started server is stopped (killed, with its group, when it does not
        stop) and its folder removed. Safe to call twice."""
        if self.closed:
            return
        self.closed = True
        self.node.close()
        if self.process is not None:
            _end(self.process)
        if self.folder is not None:
            shutil.rmtree(self.folder, ignore_errors=True)


def _fork_safe() -> None:
    """Before an environment's first session in this process; see the module docstring."""
    check_fork_safe()
    if multiprocessing.get_start_method(allow_none=True) is None:
        multiprocessing.set_start_method("spawn")
        log.info("multiprocessing starts its children with 'spawn' from now on: a fork would not carry Zenoh's threads")


def _connect(endpoint: str, namespace: str, process: subprocess.Popen[bytes] | None, name: str, timeout: float) -> Node:
    """A client node on the server's bus, tried a second at a time so that a server dying at start is seen at once."""
    deadline = time.monotonic() + max(timeout, START_TIMEOUT_S if process is not None else timeout)
    while True:
        if process is not None and process.poll() is not None:
            raise SimServerError(f"{name} exited with code {process.returncode} at start")
        try:
            return Node(BusOptions(connect=(endpoint,), namespace=namespace, connect_timeout=1.0), "client")
        except BusOpenError as exc:
            if time.monotonic() > deadline:
                raise SimServerError(f"{name}: cannot connect: {exc}") from None


def _end(process: subprocess.Popen[bytes]) -> None:
    """SIGTERM (and SIGCONT to its group, for a stopped server), SIGKILL after STOP_TIMEOUT_S, then
    SIGKILL to what is left of its process group (it leads its own session, so the group is its,
    the server's and the render workers'); its pipes closed."""
    group = process.pid
    if process.poll() is None:
        process.terminate()
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(group, signal.SIGCONT)  # a stopped server takes the SIGTERM passed on to it
        try:
            process.wait(timeout=STOP_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            log.warning("simbot server (pid %d) did not stop within %g s: killed", process.pid, STOP_TIMEOUT_S)
            process.kill()
            process.wait()
    else:
        process.wait()
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(group, signal.SIGKILL)
    for pipe in (process.stdin, process.stdout):
        if pipe is not None:
            pipe.close()
