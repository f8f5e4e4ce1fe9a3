"""`simbot state`: the world's state from its world control, once; the container's health check.

    simbot state [--world NAME] [--json] [--timeout SECONDS] [--connect E] [--namespace NS]

The world is the one whose `world/<name>/state` service is on the graph (`--world` picks one
when several are); its reply is printed as a short summary (world, sim time, mode, pause and
real-time factor, every model's planar pose) or, with `--json`, exactly as the server sent it.

Exit codes say what a health check needs to know:
- 0: the world answered: the server is up, past loading its world, and its loop is running;
- 1: the bus is reachable but no world control answers (the server is still loading its world,
  or the named world is not on this bus): one line on stderr;
- 2: a user's mistake, or no server to connect to within `--connect-timeout` (run_client's line).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Sequence
from typing import Any

from simbot.arguments import number
from simbot.bus import Node, ServiceError
from simbot.transform import yaw_of

from .common import ClientError, client_parser, run_client
from .topics import live_topics, world_names

EXIT_NO_WORLD = 1
DEFAULT_TIMEOUT_S = 2.0


class NoWorld(Exception):
    """No world control answers on a reachable bus; str() is the one line printed."""


def build_parser() -> argparse.ArgumentParser:
    parser = client_parser(
        "simbot state", "Print the world's state from its world control; exit 1 when it does not answer."
    )
    add_world_arguments(parser, DEFAULT_TIMEOUT_S)
    parser.add_argument("--json", action="store_true", help="print the server's whole reply as JSON")
    return parser


def add_world_arguments(parser: argparse.ArgumentParser, timeout_s: float) -> None:
    """`--world` and `--timeout`: what every client that asks world control takes."""
    parser.add_argument("--world", metavar="NAME", help="the world to ask (default: the one on the bus)")
    parser.add_argument(
        "--timeout",
        type=number(float),
        default=timeout_s,
        metavar="SECONDS",
        help=f"how long to wait for the world's reply (default {timeout_s:g})",
    )


def choose_world(node: Node, wanted: str | None) -> str:
    """The world to ask: `wanted` if its state service is on the graph, else the only one there.

    NoWorld when none (or not `wanted`) is; ClientError when several are and none was chosen.
    """
    worlds = world_names(live_topics(node).values())
    where = f"in namespace {node.namespace!r}" if node.namespace else "without a namespace"
    if not worlds:
        raise NoWorld(f"no world control on the bus {where}: is the server still loading its world?")
    if wanted is None:
        if len(worlds) > 1:
            raise ClientError(f"several worlds on the bus ({', '.join(worlds)}): choose one with --world")
        return worlds[0]
    if wanted not in worlds:
        raise NoWorld(f"--world {wanted}: no such world control on the bus {where} (there: {', '.join(worlds)})")
    return wanted


def ask(node: Node, world: str, timeout: float) -> dict[str, Any]:
    """The world's state reply; NoWorld when it does not come, or says it is not ok."""
    try:
        state = node.call(f"world/{world}/state", {}, timeout=timeout)
    except (TimeoutError, ServiceError) as exc:
        raise NoWorld(f"world {world} does not answer: {exc}") from None
    if state.get("ok") is not True:
        raise NoWorld(f"world {world} answered without ok: {state.get('error', state)}")
    return state


def model_line(name: str, model: dict[str, Any], width: int) -> str:
    """`name  x  y  z  yaw` of one model; a body that left the world (null coordinates) says so."""
    position, orientation = model.get("position"), model.get("orientation")
    if not position or not orientation or None in position or None in orientation:
        return f"  {name:<{width}}  (left the world)"
    x, y, z = position
    return f"  {name:<{width}}  {x:8.3f} {y:8.3f} {z:7.3f}  {yaw_of(orientation):+6.3f}"


def summary(world: str, state: dict[str, Any]) -> str:
    """The state in a few lines for a person: world, time, how it runs, where every model is."""
    rtf = state.get("real_time_factor")
    mode = state.get("mode", "?")
    running = "paused" if state.get("paused") else "steps on request" if mode == "lockstep" else "running"
    rate = f", real-time factor {rtf:.2f}" if isinstance(rtf, (int, float)) else ""
    models: dict[str, Any] = state.get("models", {})
    width = max((len(name) for name in models), default=0)
    lines = [
        f"world     {world}",
        f"sim time  {state['sim_time']:.3f} s ({state['iterations']} iterations)",
        f"mode      {mode}, {running}{rate}",
        f"models    {len(models)}{'  (x y z m, yaw rad, in world)' if models else ''}",
        *(model_line(name, model, width) for name, model in models.items()),
    ]
    return "\n".join(lines)


def run(node: Node, world: str | None, timeout: float, as_json: bool) -> int:
    """Prints the state of `world` (None: the one on the bus), as JSON or a summary; the exit code."""
    try:
        chosen = choose_world(node, world)
        state = ask(node, chosen, timeout)
    except NoWorld as exc:
        print(f"simbot state: {exc}", file=sys.stderr)
        return EXIT_NO_WORLD
    try:
        print(json.dumps(state, indent=2) if as_json else summary(chosen, state), flush=True)
    except BrokenPipeError:  # `simbot state | head`: the reader is gone, which is no error
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of `simbot state`."""
    return run_client(build_parser(), argv, lambda args, node, _: run(node, args.world, args.timeout, args.json))


if __name__ == "__main__":
    sys.exit(main())
