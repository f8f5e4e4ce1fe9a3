"""simbot launch: a real launch process starting a real server and real clients on a fresh port and namespace.

The test talks to what launch started only as a user would: through launch's output (the
`[launch] started NAME (pid N)` lines), signals to launch's pid alone (not its process group,
so launch must end its children itself), and the bus at launch's endpoint.
"""

from __future__ import annotations

import math
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
from bus_helpers import endpoint, free_port, unique_namespace
from client_helpers import pty_client
from server_helpers import REPO, Collector, wait_until

from simbot.bus import BusOptions, Node
from simbot.clients.terminal import HOME_AND_CLEAR, LEAVE_ALTERNATE

SERVER_ARGS = "--quiet --camera-size 160x120"
START_TIMEOUT_S = 60.0
EXIT_TIMEOUT_S = 20.0
"""Launch ends its clients, then the server, each with SIGINT's 5 s grace (then SIGTERM's 2 s and
SIGKILL's 2 s): within this even where every grace runs out."""
CLIENTS = ("merger", "stitcher", "monitor")
LAUNCH = (sys.executable, "-m", "simbot.clients.launch")
STARTED = re.compile(r"^\[launch\] started (\w+) \(pid (\d+)\)$", re.MULTILINE)


def pid_alive(pid: int) -> bool:
    """Whether `pid` runs (a zombie waiting for its parent counts as ended)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


class Launch:
    """A `python -m simbot.clients.launch` process; its stdout gathered line by line by a thread."""

    def __init__(self, args: Sequence[str]) -> None:
        self.port, self.namespace = free_port(), unique_namespace()
        command = [*LAUNCH, "--listen", endpoint(self.port), "--namespace", self.namespace, *args]
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        self.process = subprocess.Popen(
            command,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            cwd=REPO,
            env=env,
        )
        self.lines: Collector[str] = Collector()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.process.stdout is not None
        for line in self.process.stdout:
            self.lines(line.rstrip("\n"))

    def output(self) -> str:
        return "\n".join(self.lines.messages())

    def wait_line(self, pattern: str, timeout: float = START_TIMEOUT_S) -> re.Match[str]:
        """The first output line matching `pattern` (waits for it)."""
        regex = re.compile(pattern)
        found = self.lines.wait_for(
            lambda lines: any(map(regex.search, lines)), timeout, f"a line matching {pattern!r}"
        )
        return next(m for m in map(regex.search, found) if m)

    def pids(self) -> dict[str, int]:
        """Each child's pid, from launch's `started` lines."""
        return {name: int(pid) for name, pid in STARTED.findall(self.output())}

    def wait_exit(self, timeout: float = EXIT_TIMEOUT_S) -> int:
        code = self.process.wait(timeout=timeout)
        self._reader.join(timeout=5.0)
        return code

    def client(self) -> Node:
        return Node(
            BusOptions(connect=(endpoint(self.port),), namespace=self.namespace, connect_timeout=10.0), "client"
        )

    def close(self) -> None:
        """Whatever is still running after a failed test: launch, then each child it started, killed by pid."""
        if self.process.poll() is None:
            self.process.kill()
            self.process.wait()
        for pid in self.pids().values():
            if pid_alive(pid):
                os.kill(pid, signal.SIGKILL)
        self._reader.join(timeout=5.0)


@contextmanager
def launched(*args: str) -> Iterator[Launch]:
    launch = Launch(args)
    try:
        yield launch
    finally:
        launch.close()


def run_launch(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*LAUNCH, *args], check=False, capture_output=True, text=True, cwd=REPO, timeout=60)


def test_launch_runs_the_pipeline_survives_a_client_crash_and_ends_everything_on_sigint() -> None:
    with launched("--world", "warehouse", "--clients", ",".join(CLIENTS), f"--server-args={SERVER_ARGS}") as launch:
        for name in CLIENTS:
            launch.wait_line(rf"^\[launch\] started {name} \(pid \d+\)$")
        pids = launch.pids()
        assert set(pids) == {"server", *CLIENTS}
        with launch.client() as node:
            scans: Collector[Any] = Collector()
            panoramas: Collector[Any] = Collector()
            fronts: Collector[Any] = Collector()
            node.subscribe("scan", "sensor_msgs/msg/LaserScan", scans)
            node.subscribe("camera_360/image_raw", "sensor_msgs/msg/Image", panoramas)
            node.subscribe("camera_front", "sensor_msgs/msg/Image", fronts)
            scan = scans.wait_count(1, START_TIMEOUT_S, "merged scans")[0]
            panoramas.wait_count(1, START_TIMEOUT_S, "panoramas")
            front = fronts.wait_count(1, START_TIMEOUT_S, "front camera images")[0]
            # the merger's 360° scan in base_link, seeing the warehouse (its nearest wall is within 10 m)
            assert scan.header.frame_id == "base_link"
            assert math.isclose(scan.angle_max - scan.angle_min + scan.angle_increment, 2 * math.pi, rel_tol=1e-6)
            assert any(math.isfinite(r) for r in scan.ranges)
            assert (front.width, front.height) == (160, 120), "--server-args did not reach the server"
            for name in ("server", *CLIENTS):  # the monitor prints its first table a period after it starts
                launch.wait_line(rf"^\[{name}\] ")

            os.kill(pids["merger"], signal.SIGKILL)
            launch.wait_line(r"^\[launch\] merger exited with signal SIGKILL$")
            panoramas.clear()
            panoramas.wait_count(1, START_TIMEOUT_S, "panoramas after the merger's crash")
            assert all(pid_alive(pids[name]) for name in ("server", "stitcher", "monitor"))
            assert launch.process.poll() is None

        launch.process.send_signal(signal.SIGINT)
        assert launch.wait_exit() == 0, launch.output()[-3000:]
        assert not [name for name, pid in pids.items() if pid_alive(pid)]
        for name in ("server", "stitcher", "monitor"):
            assert f"[launch] {name} exited with code 0" in launch.output()


def test_the_server_dying_ends_the_clients_and_launch_with_a_non_zero_code() -> None:
    with launched("--world", "empty", "--clients", "merger", f"--server-args={SERVER_ARGS}") as launch:
        with launch.client() as node:  # the merger is up (its signal handlers too) once it publishes
            scans: Collector[Any] = Collector()
            node.subscribe("scan", "sensor_msgs/msg/LaserScan", scans)
            scans.wait_count(1, START_TIMEOUT_S, "merged scans")
        pids = launch.pids()
        os.kill(pids["server"], signal.SIGKILL)
        assert launch.wait_exit() == 1
        assert not [name for name, pid in pids.items() if pid_alive(pid)]
        output = launch.output()
        assert "[launch] server exited with signal SIGKILL" in output
        assert "[launch] the server is gone: ending the clients" in output
        assert "[launch] merger exited with code 0" in output


def test_sigterm_to_launch_alone_ends_the_server() -> None:
    """No clients: the server's own exit code comes through as 0, and launch's too."""
    with launched("--world", "empty", "--clients", "", f"--server-args={SERVER_ARGS}") as launch:
        launch.wait_line(r"^\[launch\] server ready: world empty$")
        server = launch.pids()["server"]
        launch.process.send_signal(signal.SIGTERM)
        assert launch.wait_exit() == 0
        assert not pid_alive(server)
        assert "[launch] server exited with code 0" in launch.output()


def test_a_server_that_cannot_start_is_its_exit_code() -> None:
    """A world that does not exist: the server's one line, prefixed, and its code 2."""
    port = free_port()
    result = run_launch("--world", "no_such_world", "--clients", "", "--listen", endpoint(port))
    assert result.returncode == 2
    assert re.search(r"^\[server\] simbot-server: error: no_such_world: no such world", result.stdout, re.MULTILINE), (
        result.stdout
    )
    assert "[launch] server exited with code 2" in result.stdout


@pytest.mark.parametrize(
    ("clients", "expected"),
    [
        ("merger,bogus", r"unknown client 'bogus' \(valid: merger, stitcher, monitor, record, foxglove, ros2\)"),
        ("teleop", r"teleop reads the keyboard"),
        ("stitcher,dock", r"dock reads the keyboard"),
        ("topics", r"topics is a one-shot tool"),
    ],
)
def test_a_client_that_cannot_be_launched_is_one_line_and_exit_2(clients: str, expected: str) -> None:
    result = run_launch("--clients", clients)
    assert result.returncode == 2 and result.stdout == ""
    assert len(result.stderr.splitlines()) == 1, result.stderr
    assert re.search(rf"^simbot launch: error: --clients: {expected}", result.stderr), result.stderr


def test_server_args_may_not_take_launchs_own_options() -> None:
    result = run_launch("--server-args=--mode fast --namespace other")
    assert result.returncode == 2 and result.stdout == ""
    assert (
        result.stderr
        == "simbot launch: error: --server-args: --namespace is launch's own option; give it to launch itself\n"
    )


def test_on_a_terminal_the_monitor_takes_it_and_the_others_log_to_files_launch_names() -> None:
    """`make run`'s case: the monitor's full-screen table on launch's terminal; the server's and the
    merger's output (and launch's own lines) in the log files launch names first; Ctrl-C (SIGINT)
    ends everything, gives the terminal back and names the files again."""
    port, namespace = free_port(), unique_namespace()
    command = [*LAUNCH, "--listen", endpoint(port), "--namespace", namespace, "--world", "empty"]
    command += ["--clients", "merger,monitor", f"--server-args={SERVER_ARGS}"]
    with pty_client(command) as screen:
        named = screen.wait_for(r"logs in (\S+): launch\.log, server\.log, merger\.log, monitor\.log", START_TIMEOUT_S)
        logs = Path(named.group(1))
        wait_until(
            lambda: screen.raw_output().count(HOME_AND_CLEAR) >= 2, timeout=START_TIMEOUT_S, what="the monitor's table"
        )
        screen.wait_for(r"scan\s+[0-9.]+ Hz", START_TIMEOUT_S)  # the merger's output, on the monitor's table
        assert "[server]" not in screen.screen() and "[launch] started" not in screen.screen()
        wait_until(lambda: "world empty" in (logs / "server.log").read_text(), START_TIMEOUT_S, "the server's log")
        assert "started merger" in (logs / "launch.log").read_text()
        screen.process.send_signal(signal.SIGINT)
        assert screen.wait_exit(EXIT_TIMEOUT_S) == 0
        screen.wait_for(rf"logs in {re.escape(str(logs))}: launch\.log", since=named.end())
        assert LEAVE_ALTERNATE in screen.raw_output() and screen.attributes() == screen.initial
    shutil.rmtree(logs)
