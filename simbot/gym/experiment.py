"""`simbot experiment`: K episodes of a policy in one of simbot's environments, across Ray actors,
into a CSV table with one row per episode.

    simbot experiment --env simbot/Navigate-v0 --policy random|scripted|module:function
                      --episodes K --actors A --seed S [--world W] [--max-episode-steps N]
                      [--env-arg KEY=VALUE ...] [--num-cpus N | --address ADDR] -o results.csv

Each actor owns one environment, and so one simbot world (a server when it is watched); episode
i has seed S + i whichever actor runs it, so the same command gives the same table (`simbot.gym.ray`). Without `--address`
it starts Ray on this machine (`--num-cpus`, default all cores); with `--address auto` it joins
the cluster `ray start` made, whose machines each need simbot (and the policy's module) installed.
Prints one line: the success rate. Exit codes: 0 done; 1 the run failed (an actor or its server
died: the reason on stderr); 2 a user's mistake (an unknown environment or policy, a policy module
that does not import, fewer than one episode), one line on stderr, before Ray starts.
"""

from __future__ import annotations

import argparse
import csv
import json
import logging
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

from simbot.arguments import whole

EXIT_FAILED = 1
EXIT_USAGE = 2
PROG = "simbot experiment"


class _Parser(argparse.ArgumentParser):
    """argparse, but a mistake is one line (no usage block), as every other bad input here."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message}\n")


def _key_value(text: str) -> tuple[str, Any]:
    key, equals, value = text.partition("=")
    if not equals or not key.isidentifier():
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE, got {text!r}")
    try:
        return key, json.loads(value)
    except ValueError:
        return key, value


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog=PROG, description="Run episodes of a policy in a simbot environment across Ray actors.")
    parser.add_argument("-v", "--verbose", action="store_true", help="log debug messages; the actors' logs too")
    parser.add_argument("--env", default="simbot/Navigate-v0", help="environment id (default: %(default)s)")
    parser.add_argument(
        "--policy", required=True, help="random, scripted, or module:function (a callable obs -> action)"
    )
    parser.add_argument("--episodes", type=whole(), default=10, metavar="K", help="(default: %(default)s)")
    parser.add_argument("--actors", type=whole(), default=1, metavar="A", help="environments at once")
    parser.add_argument("--seed", type=int, default=0, help="episode i has seed SEED + i (default: %(default)s)")
    parser.add_argument("--world", help="the environment's world (its world= argument)")
    parser.add_argument("--max-episode-steps", type=whole(), metavar="N", help="the environment's time limit")
    parser.add_argument(
        "--env-arg",
        type=_key_value,
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="another keyword argument of the environment; VALUE read as JSON where it can be (people=3, "
        "camera_size=[160,120]), else as text; repeatable",
    )
    where = parser.add_mutually_exclusive_group()
    where.add_argument("--num-cpus", type=whole(), metavar="N", help="CPUs of the local Ray (default: all)")
    where.add_argument("--address", help="a Ray cluster to join: auto, HOST:PORT or ray://HOST:PORT")
    parser.add_argument("-o", "--output", required=True, type=Path, help="the CSV table to write")
    return parser


def env_kwargs(args: argparse.Namespace) -> dict[str, Any]:
    """The environment's keyword arguments the command line sets; the rest keep their defaults."""
    kwargs: dict[str, Any] = dict(args.env_arg)
    if args.world is not None:
        kwargs["world"] = args.world
    if args.max_episode_steps is not None:
        kwargs["max_episode_steps"] = args.max_episode_steps
    return kwargs


def write_csv(path: Path, rows: Sequence[dict[str, Any]], columns: Sequence[str]) -> None:
    with path.open("w", newline="") as file:
        writer = csv.DictWriter(file, fieldnames=list(columns))
        writer.writeheader()
        writer.writerows(rows)


def summary(args: argparse.Namespace, results: Sequence[Any]) -> str:
    """The one line printed at the end: the success rate first, then what else a reader checks."""
    successes = sum(r.success for r in results)
    mean_return = sum(r.episode_return for r in results) / len(results)
    collisions = sum(r.collisions for r in results)
    return (
        f"{args.policy} in {args.env}: success {successes / len(results):.0%} ({successes}/{len(results)} episodes), "
        f"mean return {mean_return:.2f}, {collisions} collisions; wrote {args.output}"
    )


def check_args(args: argparse.Namespace) -> None:
    """What would fail in every actor, or after the whole run, fails here first, in one line: the
    environment, the policy, the world (a built-in name, or a file that exists here) and the
    output's folder."""
    from simbot.gym.errors import EnvConfigError
    from simbot.gym.options import world_file
    from simbot.gym.ray import ExperimentError, check_env, check_policy

    check_env(args.env)
    check_policy(args.policy)
    if args.world is not None:
        try:
            world_file(args.world)
        except EnvConfigError as exc:
            raise ExperimentError(str(exc)) from None
    folder = args.output.parent
    if not folder.is_dir() or not os.access(folder, os.W_OK):
        raise ExperimentError(f"cannot write {args.output}: {folder} is not a writable folder")


def _run(args: argparse.Namespace) -> int:
    from simbot.gym import ray as runner

    check_args(args)
    started = runner.start_ray(args.address, args.num_cpus, args.verbose)
    try:
        results = runner.run_episodes(args.env, args.policy, args.episodes, args.actors, args.seed, env_kwargs(args))
    finally:
        if started:
            runner.ray.shutdown()
    try:
        write_csv(args.output, [r.row() for r in results], runner.COLUMNS)
    except OSError as exc:
        raise runner.ExperimentError(f"cannot write {args.output}: {exc.strerror or exc}") from None
    print(summary(args, results))
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of `simbot experiment`; the exit code (argparse's own exits included)."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help (0) or one line of error (2)
        return int(exc.code or 0)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.WARNING, format="%(levelname)s: %(message)s")
    try:
        from simbot.gym.policies import PolicyError  # Ray and gymnasium only once the command line is good
        from simbot.gym.ray import ExperimentError
    except ImportError as exc:  # an install to make, not a failed run
        print(f"{PROG}: error: {exc.name or exc} is not installed (pip install 'simbot[gym,ray]')", file=sys.stderr)
        return EXIT_USAGE
    try:
        return _run(args)
    except (ExperimentError, PolicyError) as exc:
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except Exception as exc:  # an actor or its server died: Ray's error, in one line
        print(f"{PROG}: the run failed: {_first_line(exc)}", file=sys.stderr)
        return EXIT_FAILED


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0] if text else ''}"


if __name__ == "__main__":
    sys.exit(main())
