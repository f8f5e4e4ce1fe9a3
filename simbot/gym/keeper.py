"""Keeps an environment's server no longer than the environment's process.

`python -m simbot.gym.keeper COMMAND...` starts COMMAND (the server), prints its pid on a line of
its own, and then waits: when its standard input closes, the server is stopped (SIGTERM, SIGKILL
after `STOP_TIMEOUT_S`). The environment holds the other end of that pipe and never writes to it,
so the pipe closes however the environment's process ends: `close()`, an exception, SIGKILL, a
vector env's or Ray's worker leaving through `os._exit` (which runs no finaliser). SIGTERM and
SIGINT to the keeper are passed on to the server, and the keeper ends as the server did (the same
exit code, or the same signal), so the environment reports the server's own exit.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import threading
from collections.abc import Sequence

STOP_TIMEOUT_S = 10.0


def _stop_on_eof(server: subprocess.Popen[bytes]) -> None:
    """Blocks until standard input closes, then stops the server."""
    while os.read(0, 4096):  # os.read, not sys.stdin: a thread blocked in a buffered read holds up the exit
        pass
    if server.poll() is None:
        server.terminate()
        try:
            server.wait(timeout=STOP_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            server.kill()


def main(argv: Sequence[str] | None = None) -> int:
    command = list(sys.argv[1:] if argv is None else argv)
    if not command:
        print("usage: python -m simbot.gym.keeper COMMAND...", file=sys.stderr)
        return 2
    server = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL)
    print(server.pid, flush=True)

    def forward(signum: int, _frame: object) -> None:
        server.send_signal(signum)

    for signum in (signal.SIGTERM, signal.SIGINT):
        signal.signal(signum, forward)
    threading.Thread(target=_stop_on_eof, args=(server,), daemon=True).start()
    code = server.wait()
    if code < 0:  # ended by a signal: end by the same one, so that the environment reads the server's end
        with contextlib.suppress(OSError, ValueError):  # SIGKILL's and SIGSTOP's cannot be set, nor need to be
            signal.signal(-code, signal.SIG_DFL)
        os.kill(os.getpid(), -code)
    os._exit(code & 0xFF)  # at once: the reading thread is still blocked


if __name__ == "__main__":
    sys.exit(main())
