"""Test helpers for client programs: a real client process on a test server's bus, in a pipe or a pty.

`client_process(sim, "merger", ...)` runs `python -m clients.merger` connected to the server's
port and namespace, and on the way out sends SIGTERM and asserts a clean exit (code 0) within
`EXIT_TIMEOUT_S`, or within the time it took to start where that was longer; it is handed over once the client has installed its stop handlers. `pty_client(...)` runs a keyboard client in a pseudo-terminal, as a person
would: the test types keys into the master side and reads the screen from it; the slave side
stays open in the test so that its terminal attributes can be compared before and after.
"""

from __future__ import annotations

import os
import pty
import re
import signal
import subprocess
import sys
import tempfile
import termios
import threading
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

from server_helpers import REPO

EXIT_TIMEOUT_S = 5.0
START_TIMEOUT_S = 30.0
ANSI = re.compile(r"\x1b\[[0-9;?]*[A-Za-z]|\x1b[()][A-Z0-9]|\r")


def client_command(name: str, *args: str) -> list[str]:
    return [sys.executable, "-m", f"simbot.clients.{name}", *args]


def run_without_terminal(name: str, *args: str) -> subprocess.CompletedProcess[str]:
    """A client run to its end with no terminal on stdin, its output captured: how a mistake is checked."""
    return subprocess.run(
        client_command(name, *args),
        check=False,
        stdin=subprocess.DEVNULL,
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=60,
    )


class OnBus(Protocol):
    """What a client needs of the bus it joins: a SimServer, or a test's own server-role node."""

    @property
    def endpoint(self) -> str: ...

    @property
    def namespace(self) -> str: ...


def bus_args(sim: OnBus) -> list[str]:
    """The options that put a client on the test server's bus."""
    return ["--connect", sim.endpoint, "--namespace", sim.namespace]


def _env() -> dict[str, str]:
    return dict(os.environ, PYTHONUNBUFFERED="1", TERM="xterm")


def _catches_sigterm(pid: int) -> bool:
    """Whether the process has a handler for SIGTERM (Linux: the SigCgt mask in /proc/PID/status)."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return False
    caught = next((line.split()[1] for line in status.splitlines() if line.startswith("SigCgt:")), "0")
    return bool(int(caught, 16) & (1 << (signal.SIGTERM - 1)))


def wait_started(process: subprocess.Popen[bytes], timeout: float = START_TIMEOUT_S) -> None:
    """Until the client has installed its stop handlers (run_client does it first) or has exited.

    A client still importing (OpenCV, Zenoh) when a test ends it would die by the signal's
    default action, not stop cleanly; waiting here keeps "exit 0 on SIGTERM" a fair assertion.
    """
    deadline = time.monotonic() + timeout
    while process.poll() is None and not _catches_sigterm(process.pid):
        if time.monotonic() > deadline:
            raise AssertionError(f"client pid {process.pid} installed no SIGTERM handler within {timeout} s")
        time.sleep(0.02)


@dataclass
class ClientProcess:
    """A client process whose stdout and stderr go to files in a temporary folder."""

    process: subprocess.Popen[bytes]
    out_path: Path
    err_path: Path
    started_s: float = 0.0
    """How long it took to start (to install its stop handlers): the measure of how long it may take to stop."""

    def stdout(self) -> str:
        return self.out_path.read_text(errors="replace")

    def stderr(self) -> str:
        return self.err_path.read_text(errors="replace")

    def alive(self) -> bool:
        return self.process.poll() is None

    def stop(self, sig: int = signal.SIGTERM, timeout: float | None = None) -> int:
        """Send `sig`, wait for the exit; the exit code (the process is killed after `timeout`: by
        default EXIT_TIMEOUT_S, or as long as it took to start where that was longer, since a loaded
        machine slows both alike)."""
        timeout = max(EXIT_TIMEOUT_S, self.started_s) if timeout is None else timeout
        if self.process.poll() is None:
            self.process.send_signal(sig)
        try:
            return self.process.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
            raise AssertionError(
                f"client did not exit within {timeout} s of {signal.Signals(sig).name}: {self.stderr()[-2000:]}"
            ) from None


@contextmanager
def client_process(sim: OnBus, name: str, *args: str) -> Iterator[ClientProcess]:
    """`clients.<name>` on the server's bus; stopped with SIGTERM and asserted to exit 0."""
    with tempfile.TemporaryDirectory(prefix=f"simbot-{name}-") as tmp:
        out_path, err_path = Path(tmp) / "stdout.txt", Path(tmp) / "stderr.txt"
        with out_path.open("wb") as out, err_path.open("wb") as err:
            process = subprocess.Popen(
                client_command(name, *bus_args(sim), *args),
                stdin=subprocess.DEVNULL,
                stdout=out,
                stderr=err,
                cwd=REPO,
                env=_env(),
            )
        client = ClientProcess(process, out_path, err_path)
        try:
            started = time.monotonic()
            wait_started(process)
            client.started_s = time.monotonic() - started
            yield client
            if client.alive():
                code = client.stop()
                assert code == 0, f"{name} exited with code {code}: {client.stderr()[-2000:]}"
        finally:
            if process.poll() is None:
                process.kill()
                process.wait()


@dataclass
class PtyClient:
    """A process on a pseudo-terminal: type into it, read its screen (ANSI escapes stripped)."""

    process: subprocess.Popen[bytes]
    master: int
    slave: int
    initial: list[object]
    """The terminal's attributes before the process started (what it must leave behind)."""
    _output: bytearray = field(default_factory=bytearray)
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def _read(self) -> None:
        while True:
            try:
                chunk = os.read(self.master, 4096)
            except OSError:  # the slave side closed (EIO)
                return
            if not chunk:
                return
            with self._lock:
                self._output += chunk

    def type(self, keys: str) -> None:
        os.write(self.master, keys.encode())

    def raw_output(self) -> str:
        with self._lock:
            return self._output.decode(errors="replace")

    def screen(self) -> str:
        """Everything written so far, escape sequences and carriage returns removed."""
        return ANSI.sub("", self.raw_output())

    def mark(self) -> int:
        """A position in the screen text; `wait_for(..., since=mark)` looks only at what came after."""
        return len(self.screen())

    def wait_for(self, pattern: str, timeout: float = 10.0, since: int = 0) -> re.Match[str]:
        """The first match of the regular expression `pattern` in the screen text after `since`."""
        deadline = time.monotonic() + timeout
        while True:
            found = re.search(pattern, self.screen()[since:])
            if found:
                return found
            if time.monotonic() > deadline:
                raise AssertionError(
                    f"timed out after {timeout} s waiting for {pattern!r}; screen ends with:\n{self.screen()[-1500:]}"
                )
            if self.process.poll() is not None:
                raise AssertionError(
                    f"process exited (code {self.process.returncode}) before {pattern!r}:\n{self.screen()[-1500:]}"
                )
            time.sleep(0.02)

    def attributes(self) -> list[Any]:
        """The terminal's current attributes (termios.tcgetattr of the slave)."""
        return termios.tcgetattr(self.slave)

    def wait_exit(self, timeout: float = EXIT_TIMEOUT_S) -> int:
        try:
            return self.process.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
            raise AssertionError(
                f"process did not exit within {timeout} s; screen ends with:\n{self.screen()[-1500:]}"
            ) from None


@contextmanager
def pty_client(command: Sequence[str]) -> Iterator[PtyClient]:
    """`command` with a pseudo-terminal as its stdin, stdout and stderr (its controlling terminal)."""
    master, slave = pty.openpty()
    initial = termios.tcgetattr(slave)
    process = subprocess.Popen(
        list(command), stdin=slave, stdout=slave, stderr=slave, cwd=REPO, env=_env(), start_new_session=True
    )
    client = PtyClient(process, master, slave, initial)
    reader = threading.Thread(target=client._read, daemon=True)
    reader.start()
    try:
        wait_started(process)
        yield client
    finally:
        if process.poll() is None:
            process.send_signal(signal.SIGTERM)
            try:
                process.wait(timeout=EXIT_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        os.close(slave)
        reader.join(timeout=2.0)
        os.close(master)
