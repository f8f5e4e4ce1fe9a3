"""`simbot launch`: the server and the chosen clients in one command; Ctrl-C ends them all.

    simbot launch [--world W] [--clients merger,stitcher,monitor] [--server-args "--mode fast ..."]
                  [--zones N | --zone NAME:XMIN:XMAX ...] [--listen E] [--connect E] [--zenoh-config F] [--namespace NS]

Each child is a subprocess (`python -m simbot.sim.server`, `python -m simbot.clients.<name>`) whose
stdout and stderr come out line by line prefixed with its name (`[server] `, `[merger] `). When
the monitor is launched and launch's output is a terminal, the monitor gets the terminal for its
full-screen table instead: every other child's output, the monitor's log lines and launch's own
go to files, one per process (`server.log`, `merger.log`, `launch.log`), in a fresh folder under
the system's temporary folder, which launch names before the table appears and again after it. The
server listens where launch's `--listen` says (default `tcp/127.0.0.1:7447`) and the clients
connect there, all with the same `--namespace` and `--zenoh-config`. The clients start only once
the server's world control answers, so none of them waits out its connect timeout on a server
still loading its world.

A client that exits is reported and the rest keep running; the server exiting ends the clients
and launch with a non-zero code. SIGINT or SIGTERM to launch ends the clients first, then the
server (SIGINT, then SIGTERM, then SIGKILL, each after a grace period), and exits 0. The children
stay in launch's process group, so a terminal's Ctrl-C reaches them too, but launch signals them
itself: a SIGTERM sent to launch alone still ends them.

With `--zones N` (or bands of its own, `--zone NAME:XMIN:XMAX` repeated) launch splits the
`--robots N` fleet of `--server-args` across zone servers, each a band of x of the same world
(`simbot-server --zone`, simbot.description.fleet): the fleet stands in one column per zone
unless `--columns` says otherwise, and the boundaries lie between columns so that each zone holds
about as many robots. Launch itself is the Zenoh router that joins them: it listens where
`--listen` says (the clients connect there) and connects where `--connect` says (other hosts'
routers); each zone server listens on a free loopback port and connects to it. Once every zone
answers, `simbot handover 'tug_*'` runs as one more child and moves each robot to the zone whose
band it enters. Each robot's keys are `tug_7/...` whichever zone holds it; each zone's world
control and clock are under its name (`zone_1/world/<w>/state`). A zone that exits is reported
with its exit code and the others run on; launch ends (non-zero) when the last one has gone. No
clients by default (the default ones follow the one `flexley_tug`). docs/fleets.md says more.

Only long-running clients can be launched: the keyboard clients need the terminal, and the
one-shot tools (topics, echo, snapshot) are meant to be run beside a launch.

Not built on `run_client`: launch has no bus session of its own until the server it starts is
listening; it opens one only to wait for the world control.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import shlex
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, TextIO

import zenoh

from simbot.arguments import whole
from simbot.bus import BusConfigError, BusOpenError, BusOptions, Node, zenoh_config
from simbot.bus.options import zenoh_reason
from simbot.description.fleet import zone

from .common import EXIT_USAGE, client_parser
from .state import NoWorld, ask
from .topics import live_topics, world_names
from .zones import ServerPlan, ZoneError, zone_plan

EXIT_FAILURE = 1
LAUNCHABLE = ("merger", "stitcher", "monitor", "record", "foxglove", "ros2")
DEFAULT_CLIENTS = "merger,stitcher"
NOT_LAUNCHABLE: dict[str, str] = {
    "teleop": "reads the keyboard: run `simbot teleop` in a terminal of its own",
    "dock": "reads the keyboard: run `simbot dock` in a terminal of its own",
    "topics": "is a one-shot tool: run `simbot topics` beside the launch",
    "echo": "is a one-shot tool: run `simbot echo KEY` beside the launch",
    "snapshot": "is a one-shot tool: run `simbot snapshot --out DIR` beside the launch",
    "state": "is a one-shot tool: run `simbot state` beside the launch",
    "play": "publishes a recording in place of a server: run `simbot play BAG` on a bus without one",
    "launch": "is this command",
}
OWN_OPTIONS = ("--world", "--listen", "--connect", "--zenoh-config", "--namespace", "--zone")
"""Server options that launch sets itself (the clients must agree with them), refused in --server-args."""

STARTUP_TIMEOUT_S = 60.0
POLL_S = 0.1
CONNECT_TRY_S = 1.0
GRACE_S: tuple[tuple[signal.Signals, float], ...] = ((signal.SIGINT, 5.0), (signal.SIGTERM, 2.0), (signal.SIGKILL, 2.0))
"""How a child is ended: each signal in turn, waiting its grace period for the exit. SIGINT's is
ros2 launch's 5 s: a server closing its render workers on a loaded two-core machine took over 3 s."""

_output_lock = threading.Lock()
_output: list[TextIO] = []
"""Where launch's own lines go instead of stdout while the monitor holds the terminal (launch.log)."""
MONITOR = "monitor"


class LaunchError(Exception):
    """A user's mistake in launch's options; str() is the one line printed."""


def emit(name: str, text: str) -> None:
    """One whole line `[name] text` on stdout, flushed (reader threads and the main loop share stdout)."""
    with _output_lock:
        try:
            out = _output[-1] if _output else sys.stdout
            out.write(f"[{name}] {text}\n")
            out.flush()
        except (BrokenPipeError, ValueError):  # the reader of our output went away, or stdout is closed
            pass


@dataclass(frozen=True)
class Plan:
    """What to start: the servers (one, or a zone each), each client's command, and for zones the
    router that joins them and the handover (`--world` added once the world's name is known)."""

    servers: list[ServerPlan]
    clients: dict[str, list[str]]
    router: zenoh.Config | None = None
    handover: list[str] = field(default_factory=list)
    startup_timeout: float = STARTUP_TIMEOUT_S

    @property
    def zoned(self) -> bool:
        return self.router is not None

    def names(self) -> list[str]:
        """Every child's name, as its log file is named."""
        return [*(s.name for s in self.servers), *(["handover"] if self.handover else []), *self.clients]


def build_parser() -> argparse.ArgumentParser:
    parser = client_parser("simbot launch", "start the simulator and chosen clients; Ctrl-C ends them all")
    parser.add_argument("--world", default="warehouse", help="world file, or a built-in world (default: warehouse)")
    parser.add_argument(
        "--clients",
        metavar="NAMES",
        help=f"comma-separated clients to start, from {', '.join(LAUNCHABLE)} "
        f"(default: {DEFAULT_CLIENTS}, none with zones; '' for none)",
    )
    parser.add_argument(
        "--server-args",
        default="",
        metavar="ARGS",
        help='more simbot-server options, one shell-quoted string: --server-args="--mode fast --camera-size 320x240"',
    )
    parser.add_argument(
        "--zones",
        type=whole(1),
        metavar="N",
        help="split the --robots fleet of --server-args across N servers, each a band of x (docs/fleets.md)",
    )
    parser.add_argument(
        "--zone",
        type=zone,
        action="append",
        default=[],
        metavar="NAME:XMIN:XMAX",
        help="a zone of your own instead of --zones: its name and band of x (repeat for each)",
    )
    return parser


def client_names(text: str) -> list[str]:
    """The launchable clients named in `text`, in order, each once; LaunchError for any other name."""
    names = list(dict.fromkeys(n.strip() for n in text.split(",") if n.strip()))
    for name in names:
        if name in NOT_LAUNCHABLE:
            raise LaunchError(f"--clients: {name} {NOT_LAUNCHABLE[name]}")
        if name not in LAUNCHABLE:
            raise LaunchError(f"--clients: unknown client {name!r} (valid: {', '.join(LAUNCHABLE)})")
    return names


def server_args(text: str) -> list[str]:
    """`--server-args` split as a shell would; the options launch owns are refused."""
    try:
        words = shlex.split(text)
    except ValueError as exc:
        raise LaunchError(f"--server-args {text!r}: {exc}") from None
    for word in words:
        option = word.split("=", 1)[0]
        if option in OWN_OPTIONS:
            raise LaunchError(f"--server-args: {option} is launch's own option; give it to launch itself")
    return words


def listen_endpoints(args: argparse.Namespace) -> tuple[str, ...]:
    """Where the server will listen: `--listen`, else the config file's, else simbot's default."""
    options = BusOptions(listen=tuple(args.listen), config_file=args.zenoh_config, namespace=args.namespace)
    endpoints = json.loads(zenoh_config(options, "server").get_json("listen/endpoints"))
    if not endpoints:
        raise LaunchError("the server would listen on nothing: give --listen ENDPOINT")
    return tuple(endpoints)


def make_plan(args: argparse.Namespace) -> Plan:
    """The commands to run; LaunchError, ZoneError or BusConfigError for a mistake in the options."""
    zoned = bool(args.zones or args.zone)
    names = client_names(args.clients if args.clients is not None else "" if zoned else DEFAULT_CLIENTS)
    extra = server_args(args.server_args)
    endpoints = listen_endpoints(args)
    shared = ["--namespace", args.namespace] if args.namespace else []
    if args.zenoh_config is not None:
        shared += ["--zenoh-config", str(args.zenoh_config)]
    if args.verbose:
        shared.append("-v")
    server = [sys.executable, "-m", "simbot.sim.server", "--world", args.world, *shared]
    connect = [word for endpoint in endpoints for word in ("--connect", endpoint)]
    connect += ["--connect-timeout", str(args.connect_timeout)]
    clients = {name: client_command(name, connect, shared) for name in names}
    if zoned:
        handover = client_command("handover", connect, shared)
        zones = zone_plan(args, [*server, *extra], endpoints, handover, CONNECT_TRY_S)
        timeout = STARTUP_TIMEOUT_S + zones.startup_timeout_s
        return Plan(zones.servers, clients, zones.router, zones.handover, timeout)
    server += [word for endpoint in args.listen for word in ("--listen", endpoint)]
    server += [word for endpoint in args.connect for word in ("--connect", endpoint)]
    bus = BusOptions(connect=endpoints, namespace=args.namespace, connect_timeout=CONNECT_TRY_S)
    return Plan([ServerPlan("server", [*server, *extra], bus)], clients)


def client_command(name: str, connect: Sequence[str], shared: Sequence[str]) -> list[str]:
    return [sys.executable, "-m", f"simbot.clients.{name}", *connect, *shared]


class Child:
    """A child process whose merged stdout/stderr a reader thread prints, prefixed with its name; or,
    given `logs`, written to `<logs>/<name>.log` (all of it, or only stderr when `terminal` gives it stdout)."""

    def __init__(self, name: str, command: Sequence[str], logs: Path | None = None, terminal: bool = False) -> None:
        self.name = name
        self.reported = False
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        self._reader: threading.Thread | None = None
        if logs is None:
            self.process = subprocess.Popen(
                list(command), stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, env=env
            )
            assert self.process.stdout is not None  # stdout=PIPE
            self._reader = threading.Thread(
                target=self._pump, args=(self.process.stdout,), name=f"launch-{name}", daemon=True
            )
            self._reader.start()
        else:
            with (logs / f"{name}.log").open("ab") as log:
                stdout = None if terminal else log
                self.process = subprocess.Popen(
                    list(command), stdin=subprocess.DEVNULL, stdout=stdout, stderr=log, env=env
                )
        emit("launch", f"started {name} (pid {self.process.pid})")

    def _pump(self, pipe: IO[bytes]) -> None:
        with pipe:
            for raw in iter(pipe.readline, b""):
                emit(self.name, raw.decode(errors="replace").rstrip("\r\n"))

    def exited(self) -> int | None:
        """The exit code once the process has ended (−N: killed by signal N), else None."""
        return self.process.poll()

    def report(self) -> None:
        """Say once how the child ended, after the last of its output."""
        if self.reported or self.exited() is None:
            return
        self.reported = True
        if self._reader is not None:
            self._reader.join(timeout=1.0)
        code = self.process.returncode
        how = f"signal {signal.Signals(-code).name}" if code < 0 else f"code {code}"
        emit("launch", f"{self.name} exited with {how}")


def end(children: Sequence[Child]) -> None:
    """SIGINT, then SIGTERM, then SIGKILL to the children still running, each with its grace period."""
    for sig, grace in GRACE_S:
        running = [c for c in children if c.exited() is None]
        if not running:
            return
        for child in running:
            child.process.send_signal(sig)
        deadline = time.monotonic() + grace
        for child in running:
            with contextlib.suppress(subprocess.TimeoutExpired):
                child.process.wait(timeout=max(0.0, deadline - time.monotonic()))


def try_open(bus: BusOptions) -> Node | None:
    """A client session on the server, or None while it is not listening yet (the attempt waits CONNECT_TRY_S)."""
    try:
        return Node(bus, "client")
    except BusOpenError:
        return None


def world_name(node: Node) -> str | None:
    """The name of the world whose `world/<name>/state` service the bus announces, if any yet."""
    return next(iter(world_names(live_topics(node).values())), None)


def answers(node: Node, world: str) -> bool:
    """Whether the world's state service replies (the server is past loading and stepping)."""
    try:
        ask(node, world, CONNECT_TRY_S)
    except NoWorld:
        return False
    return True


class Launch:
    """The running children and the stop event the signal handlers set."""

    def __init__(self, plan: Plan, stop: threading.Event, logs: Path | None = None) -> None:
        self.plan = plan
        self.stop = stop
        self.logs = logs
        """The folder of every process's log while the monitor holds the terminal; None: all on stdout."""
        self.servers: list[Child] = []
        self.clients: list[Child] = []

    def run(self) -> int:
        """Start, supervise, end everything; the exit code."""
        try:
            with self.router():
                for server in self.plan.servers:
                    if server.about:
                        emit("launch", server.about)
                    self.servers.append(Child(server.name, server.command, self.logs))
                world = self.wait_ready()
                if world is None:
                    return 0 if self.stop.is_set() else self.servers_failed()
                emit("launch", f"{'zones' if self.plan.zoned else 'server'} ready: world {world}")
                if self.plan.handover:
                    self.clients.append(Child("handover", [*self.plan.handover, "--world", world], self.logs))
                self.clients += [
                    Child(name, command, self.logs, terminal=name == MONITOR)
                    for name, command in self.plan.clients.items()
                ]
                return self.supervise()
        except LaunchError as exc:
            emit("launch", f"error: {exc}")
            return EXIT_FAILURE
        finally:
            self.shutdown()

    @contextlib.contextmanager
    def router(self) -> Iterator[None]:
        """For zones, launch's own Zenoh session in router mode, open while the children run."""
        if self.plan.router is None:
            yield
            return
        try:
            session = zenoh.open(self.plan.router)
        except zenoh.ZError as exc:
            raise LaunchError(f"cannot open the router that joins the zones: {zenoh_reason(exc)}") from None
        emit("launch", f"router on {', '.join(json.loads(self.plan.router.get_json('listen/endpoints')))}")
        try:
            yield
        finally:
            self.shutdown()  # the children first, while the router still carries their goodbyes
            session.close()

    def wait_ready(self) -> str | None:
        """The world's name once every server's state service answers; None if a server exited or stop came first."""
        deadline = time.monotonic() + self.plan.startup_timeout
        nodes: dict[str, Node | None] = {}
        worlds: dict[str, str] = {}
        try:
            while not self.stop.is_set() and all(s.exited() is None for s in self.servers):
                if time.monotonic() > deadline:
                    waiting = ", ".join(s.name for s in self.plan.servers if s.name not in worlds)
                    raise LaunchError(
                        f"the world control of {waiting} did not answer within {self.plan.startup_timeout:g} s"
                    )
                for server in self.plan.servers:
                    if server.name not in worlds:
                        node = nodes[server.name] = nodes.get(server.name) or try_open(server.bus)
                        world = world_name(node) if node is not None else None
                        if node is not None and world is not None and answers(node, world):
                            worlds[server.name] = world
                if len(worlds) == len(self.plan.servers):
                    return next(iter(worlds.values()))
                self.stop.wait(POLL_S)
            return None
        finally:
            for node in nodes.values():
                if node is not None:
                    node.close()

    def supervise(self) -> int:
        """Until stop (→ 0) or the server's exit (→ non-zero; with zones, the last zone's): children
        that exit are reported, and a zone's the others outlive."""
        while not self.stop.wait(POLL_S):
            for child in self.clients:
                child.report()
            gone = [s for s in self.servers if s.exited() is not None]
            for server in gone:
                if not server.reported and self.plan.zoned and len(gone) < len(self.servers):
                    server.report()
                    running = ", ".join(s.name for s in self.servers if s.exited() is None)
                    emit("launch", f"{server.name} is gone with the robots it held; still running: {running}")
            if len(gone) == len(self.servers) or (gone and not self.plan.zoned):
                return self.servers_failed()
        return 0

    def servers_failed(self) -> int:
        """Report the servers' ends; launch's exit code: the first positive code among them, else 1
        (a server that says success, or that a signal ended)."""
        for server in self.servers:
            server.report()
        if self.clients:
            emit("launch", f"the {'zones are' if self.plan.zoned else 'server is'} gone: ending the clients")
        codes = [s.process.returncode for s in self.servers if s.exited() is not None]
        return next((code for code in codes if code > 0), EXIT_FAILURE)

    def shutdown(self) -> None:
        """The clients first (they may still want the bus to say goodbye), then the servers."""
        end(self.clients)
        for client in self.clients:
            client.report()
        end(self.servers)
        for server in self.servers:
            server.report()


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of `simbot launch`."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        plan = make_plan(args)
    except (LaunchError, ZoneError, BusConfigError) as exc:
        print(f"{parser.prog}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    return run(plan, stop)


def run(plan: Plan, stop: threading.Event) -> int:
    """Runs `plan` until its clients end or `stop`; with the monitor on a terminal, the others' output
    goes to log files, whose folder it names. The exit code."""
    if MONITOR not in plan.clients or not sys.stdout.isatty():
        return Launch(plan, stop).run()
    logs = Path(tempfile.mkdtemp(prefix="simbot-launch-"))
    print(f"[launch] the monitor takes the terminal; logs in {logs}: {log_names(plan)} (Ctrl-C ends all)", flush=True)
    with (logs / "launch.log").open("a", encoding="utf-8") as own:
        _output.append(own)
        try:
            code = Launch(plan, stop, logs).run()
        finally:
            _output.pop()
    print(f"[launch] logs in {logs}: {log_names(plan)}", flush=True)
    return code


def log_names(plan: Plan) -> str:
    """The log files of a launch whose monitor holds the terminal."""
    return ", ".join(f"{name}.log" for name in ("launch", *plan.names()))


if __name__ == "__main__":
    sys.exit(main())
