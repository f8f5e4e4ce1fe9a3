"""How many of a folder of Gazebo worlds `simbot describe` accepts, among those that need no
download, and how many of those `simbot-server --robot none --mode lockstep` steps for 2 s.

    python benchmarks/describe_gazebo_worlds.py PATH/TO/gz-sim/examples/worlds [--no-step]

A world needs a download when any `<uri>` in it is an http(s) URL; the others are described one
by one in a subprocess (as a user runs it) with an empty Fuel cache, and each refusal is listed
with its one-line error. Each accepted world is then run as a user runs it: a server on its own
loopback port and namespace, the world alone, stepped through world control (one step, which
tells the step size, then the rest of 2 s of sim time in one `multi_step`); it steps when the
reply says 2 s and the state still answers. Each failure is listed with the last line the server
wrote, or what the client saw. The README's figures are the script's first two lines of output.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
import uuid
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TypeVar

from bench_server import free_port

from simbot.bus import BusOpenError, BusOptions, Node, ServiceError
from simbot.description import load_world

T = TypeVar("T")
REMOTE_URI = re.compile(r"<uri>\s*https?://")
SECONDS = 2.0
START_TIMEOUT_S = 60.0
STEP_TIMEOUT_S = 300.0
"""Wall seconds a world may take to start, and to step 2 s: far beyond what any example needs."""


def describe_refusal(world: Path, env: Mapping[str, str]) -> str | None:
    """None when `simbot describe` accepts the world; else its last line of error."""
    result = subprocess.run(
        [sys.executable, "-m", "simbot.cli", "describe", str(world)], capture_output=True, text=True, env=env
    )
    return None if result.returncode == 0 else (result.stderr.strip().splitlines() or ["?"])[-1]


def _at_start(
    server: subprocess.Popen[bytes], attempt: Callable[[], T | None], errors: tuple[type[Exception], ...]
) -> T:
    """What `attempt` gives once it gives something (it raises one of `errors`, or gives None, while
    the server starts); raises when the server exits first or the start time is up."""
    deadline = time.monotonic() + START_TIMEOUT_S
    while True:
        if server.poll() is not None:
            raise RuntimeError(f"the server exited with code {server.returncode} at start")
        try:
            result = attempt()
        except errors:
            result = None
        if result is not None:
            return result
        if time.monotonic() > deadline:
            raise TimeoutError(f"the server did not answer within {START_TIMEOUT_S:g} s")


def _step(node: Node, world: str, server: subprocess.Popen[bytes]) -> None:
    """Waits for world control, then steps 2 s of sim time; raises with what went wrong."""
    _at_start(
        server,
        lambda: node.call(f"world/{world}/state", {}, timeout=1.0).get("ok") or None,
        (TimeoutError, ServiceError),
    )
    step = node.call(f"world/{world}/control", {"step": True}, timeout=STEP_TIMEOUT_S)["sim_time"]
    rest = round(SECONDS / step) - 1
    reached = node.call(f"world/{world}/control", {"multi_step": rest}, timeout=STEP_TIMEOUT_S)["sim_time"]
    if abs(reached - SECONDS) > step / 2:
        raise RuntimeError(f"stepped to {reached} s, not {SECONDS} s")
    if not node.call(f"world/{world}/state", {}, timeout=10.0).get("ok"):
        raise RuntimeError("the state did not answer after the steps")


def step_failure(world: Path, env: Mapping[str, str]) -> str | None:
    """None when the server steps the world alone for 2 s in lockstep; else why not, in one line."""
    endpoint, namespace = f"tcp/127.0.0.1:{free_port()}", f"gzworlds_{uuid.uuid4().hex[:8]}"
    command = [sys.executable, "-m", "simbot.sim.server", "--world", str(world), "--robot", "none"]
    command += ["--mode", "lockstep", "--quiet", "--listen", endpoint, "--namespace", namespace]
    with tempfile.TemporaryFile() as stderr:
        server = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=stderr, env=env)
        try:
            options = BusOptions(connect=(endpoint,), namespace=namespace, connect_timeout=1.0)
            with _at_start(server, lambda: Node(options, "client"), (BusOpenError,)) as node:
                _step(node, load_world(world).name, server)
            return None
        except (RuntimeError, TimeoutError, ServiceError, BusOpenError, KeyError) as exc:
            stderr.seek(0)
            lines = stderr.read().decode(errors="replace").strip().splitlines()
            return f"{exc} ({lines[-1] if lines else 'nothing on stderr'})"
        finally:
            server.terminate()
            try:
                server.wait(10)
            except subprocess.TimeoutExpired:
                server.kill()
                server.wait()


def main(folder: Path, step: bool) -> int:
    worlds = [w for w in sorted(folder.glob("*.sdf")) if not REMOTE_URI.search(w.read_text(errors="replace"))]
    with tempfile.TemporaryDirectory() as empty_cache:
        env = os.environ | {"GZ_FUEL_CACHE_PATH": empty_cache}
        refused = {w.name: why for w in worlds if (why := describe_refusal(w, env)) is not None}
        accepted = [w for w in worlds if w.name not in refused]
        failed = {w.name: why for w in accepted if step and (why := step_failure(w, env)) is not None}
    print(
        f"simbot describe accepts {len(accepted)} of {len(worlds)} worlds that need no download "
        f"({100 * len(accepted) / max(len(worlds), 1):.0f} %)"
    )
    if step:
        stepped = len(accepted) - len(failed)
        print(f"simbot-server --robot none --mode lockstep steps {stepped} of those {len(accepted)} for {SECONDS:g} s")
    print(
        "\n".join(
            [f"describe {name}: {why}" for name, why in refused.items()]
            + [f"step {name}: {why}" for name, why in failed.items()]
        )
    )
    return 0


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", type=Path, help="a folder of .sdf worlds (gz-sim's examples/worlds)")
    parser.add_argument("--no-step", action="store_true", help="only describe them")
    args = parser.parse_args()
    sys.exit(main(args.folder, not args.no_step))
