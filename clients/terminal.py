"""The terminal of the keyboard clients (teleop, dock): keys in, a screen out, the terminal always given back;
and the full screen of the monitor's live table (`FullScreen`).

A keyboard client puts its terminal in cbreak mode: keys arrive one at a time and unechoed, yet
Ctrl-C still raises SIGINT (which `run_client` turns into a clean stop) and output keeps its
newline translation, so log lines stay readable. However the client ends (q, SIGINT, SIGTERM, an
exception), the `Terminal` context manager restores the attributes it saved, in `finally`.

The screen is a few fixed lines (the keys) and one status line redrawn in place. Messages, and
every log record while the terminal is held (Zenoh threads log too), print above the status line
under one lock, so neither garbles the other.
"""

from __future__ import annotations

import logging
import os
import re
import select
import shutil
import sys
import termios
import threading
import tty
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, TextIO

from .common import ClientError

if TYPE_CHECKING:
    from typing_extensions import Self  # typing.Self from Python 3.11

CLEAR_LINE = "\r\x1b[K"
HIDE_CURSOR, SHOW_CURSOR = "\x1b[?25l", "\x1b[?25h"
ENTER_ALTERNATE, LEAVE_ALTERNATE = "\x1b[?1049h", "\x1b[?1049l"
"""xterm's alternate screen: a full-screen view whose leaving gives back the screen as it was."""
HOME_AND_CLEAR = "\x1b[H\x1b[J"
ESCAPE_SEQUENCE = re.compile(r"\x1b(\[[0-9;?]*[ -/]*[@-~]|O.|.)?")
"""Arrow and function keys: dropped whole, so that their letters are not taken for commands."""


class Terminal:
    """Cbreak keyboard on stdin and a status-line screen on stdout, restored on any exit."""

    def __init__(self, keys_help: Sequence[str]) -> None:
        self._keys_help = list(keys_help)
        self._in: TextIO = sys.stdin
        self._out: TextIO = sys.stdout
        self._fd = -1
        self._saved: list[Any] | None = None
        self._status = ""
        self._lock = threading.Lock()
        self._log_handler = _ScreenHandler(self)
        self._displaced: list[logging.Handler] = []

    def __enter__(self) -> Self:
        self._fd = terminal_input(self._in)
        self._saved = termios.tcgetattr(self._fd)
        try:
            tty.setcbreak(self._fd, termios.TCSANOW)
            self._route_logging()
            self._write(HIDE_CURSOR + "".join(line + "\n" for line in self._keys_help))
        except BaseException:
            self._restore()
            raise
        return self

    def __exit__(self, *_exc: object) -> None:
        self._restore()

    def _restore(self) -> None:
        """Logging back to its handlers, the cursor shown, the saved attributes back."""
        try:
            self._unroute_logging()
            self._write(("\n" if self._status else "") + SHOW_CURSOR)
        finally:
            if self._saved is not None:
                termios.tcsetattr(self._fd, termios.TCSADRAIN, self._saved)
                self._saved = None

    def _route_logging(self) -> None:
        """Root log records go through the screen while the terminal is held, formatted as before."""
        root = logging.getLogger()
        self._displaced = list(root.handlers)
        if self._displaced and self._displaced[0].formatter is not None:
            self._log_handler.setFormatter(self._displaced[0].formatter)
        for handler in self._displaced:
            root.removeHandler(handler)
        root.addHandler(self._log_handler)

    def _unroute_logging(self) -> None:
        root = logging.getLogger()
        root.removeHandler(self._log_handler)
        for handler in self._displaced:
            root.addHandler(handler)
        self._displaced = []

    def read_keys(self, timeout: float) -> str | None:
        """Keys typed within `timeout` seconds (lower case, escape sequences dropped; "" when none); None once the terminal is gone."""
        try:
            ready, _, _ = select.select([self._fd], [], [], max(timeout, 0.0))
            if not ready:
                return ""
            data = os.read(self._fd, 64)
        except OSError:  # the terminal hung up
            return None
        if not data:
            return None
        return ESCAPE_SEQUENCE.sub("", data.decode(errors="ignore")).lower()

    def status(self, text: str) -> None:
        """Redraw the status line (only when it changed: the screen is not flooded at 10 Hz).

        Cut to the terminal's width: a wrapped line could not be redrawn in place.
        """
        text = text[: max(shutil.get_terminal_size().columns - 1, 20)]
        with self._lock:
            if text != self._status:
                self._status = text
                self._write(CLEAR_LINE + text)

    def message(self, text: str) -> None:
        """A line above the status line, which is drawn again under it."""
        with self._lock:
            self._write(CLEAR_LINE + text + "\n" + self._status)

    def _write(self, text: str) -> None:
        self._out.write(text)
        self._out.flush()


class FullScreen:
    """A view that fills the terminal (the alternate screen, the cursor hidden), redrawn whole in place;
    leaving it, however the program ends, brings back the screen and the cursor as they were."""

    def __init__(self, out: TextIO | None = None) -> None:
        self._out = out or sys.stdout

    def __enter__(self) -> Self:
        self._write(ENTER_ALTERNATE + HIDE_CURSOR)
        return self

    def __exit__(self, *_exc: object) -> None:
        self._write(SHOW_CURSOR + LEAVE_ALTERNATE)

    def draw(self, text: str) -> None:
        """The whole view: each line cut to the terminal's width and the rows it has (a wrapped or scrolled
        line could not be redrawn in place)."""
        size = shutil.get_terminal_size()
        lines = [line[: max(size.columns - 1, 20)] for line in text.splitlines()][: max(size.lines - 1, 1)]
        self._write(HOME_AND_CLEAR + "\n".join(lines))

    def _write(self, text: str) -> None:
        self._out.write(text)
        self._out.flush()


def terminal_input(stream: TextIO | None = None) -> int:
    """The file descriptor of standard input (or `stream`) when it is a terminal; ClientError otherwise.

    A keyboard client checks this before it connects (`run_client(..., check=...)`), so that a pipe
    as input is the one error the user sees.
    """
    try:
        fd = (stream or sys.stdin).fileno()
    except (AttributeError, ValueError, OSError):
        fd = -1
    if fd < 0 or not os.isatty(fd):
        raise ClientError(
            "standard input is not a terminal: run it in an interactive terminal (no pipes or redirection)"
        )
    return fd


class _ScreenHandler(logging.Handler):
    """Log records as screen messages."""

    def __init__(self, terminal: Terminal) -> None:
        super().__init__()
        self._terminal = terminal

    def emit(self, record: logging.LogRecord) -> None:
        try:
            self._terminal.message(self.format(record))
        except Exception:  # noqa: BLE001  # logging.Handler's contract: report through handleError, never raise
            self.handleError(record)
