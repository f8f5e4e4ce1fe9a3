"""The server an environment runs, as a command line: for the environment itself, and to start by
hand (or on another machine) for environments given `endpoint=`.

    python -m simbot.gym.serve dock --world empty --control-period 0.1 \\
        --listen tcp/127.0.0.1:7500 --namespace gym_a

starts (in the foreground, until Ctrl-C) exactly the lockstep server that
`gymnasium.make("simbot/Dock-v0", world="empty", control_period=0.1, watch=True)` would start for
itself (and the world an env off the bus builds in its own process, simbot.gym.local):
the robot's SDF with its lidars due at every environment step and its contact sensors, the
trolley where the world has none, the cameras' size and rate. Then
`gymnasium.make("simbot/Dock-v0", world="empty", control_period=0.1,
endpoint="tcp/127.0.0.1:7500", namespace="gym_a")` uses it.
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

from simbot.arguments import image_size
from simbot.description.resources import asset
from simbot.gym.errors import EnvConfigError
from simbot.gym.options import PEOPLE, PHYSICS, EnvOptions, profile_file, read_world, world_file
from simbot.gym.robot import RobotFacts, write_gym_robot
from simbot.gym.session import ServerSpec, server_command

TROLLEY = "trolley"
TROLLEY_FILE = "worlds/models/trolley/model.sdf"


def task_additions(task: str, world_models: Sequence[str]) -> tuple[Path, ...]:
    """Model files a task adds to the world: Dock a trolley where the world has none."""
    return (asset(TROLLEY_FILE),) if task == "dock" and TROLLEY not in world_models else ()


def server_spec(options: EnvOptions, robot: RobotFacts, additions: Sequence[Path], folder: Path) -> ServerSpec:
    """The server of an environment with `options`, its robot's SDF written into `folder`; a render
    worker per observed camera at most (the server's default is one per core, for six cameras)."""
    rate = 1.0 / options.control_period
    cameras = bool(options.observed_cameras)
    return ServerSpec(
        world=world_file(options.world).resolve(),
        robot=write_gym_robot(robot, rate, folder),
        additions=tuple(str(p) for p in additions) + ((PEOPLE,) if options.people else ()),
        seed=options.seed,
        camera_size=options.camera_size if cameras else None,
        camera_rate=rate if cameras else None,
        render_workers=min(len(options.observed_cameras), os.cpu_count() or 1) if cameras else None,
        profile=profile_file(options),
        physics=options.physics,
    )


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m simbot.gym.serve", description=__doc__.split("\n\n")[0])
    parser.add_argument("task", choices=("navigate", "dock"))
    parser.add_argument("--world", default="warehouse")
    parser.add_argument("--people", action="store_true")
    parser.add_argument("--physics", choices=PHYSICS, default="dynamic")
    parser.add_argument("--control-period", type=float, default=0.1)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--cameras", nargs="*", default=[])
    parser.add_argument("--camera-size", type=image_size, default=(160, 120), metavar="WxH")
    parser.add_argument("--listen", required=True)
    parser.add_argument("--namespace", required=True)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        options = EnvOptions(
            world=args.world,
            people=args.people,
            control_period=args.control_period,
            seed=args.seed,
            cameras=tuple(args.cameras),
            camera_size=args.camera_size,
            physics=args.physics,
        )
        world = read_world(options.world)
        robot = RobotFacts.read(options.robot, world.name)
        with tempfile.TemporaryDirectory(prefix="simbot-gym-") as folder:
            additions = task_additions(args.task, [m.name for m in world.models])
            command = server_command(server_spec(options, robot, additions, Path(folder)), args.listen, args.namespace)
            print(" ".join(command), file=sys.stderr)
            return _run(command)
    except (EnvConfigError, ValueError) as exc:
        print(f"simbot.gym.serve: error: {exc}", file=sys.stderr)
        return 2


def _run(command: list[str]) -> int:
    """Runs the server until it ends; SIGTERM and SIGINT here are passed on to it, so that stopping
    this process stops the server and removes the robot's folder."""
    process = subprocess.Popen(command, env={**os.environ, "PYTHONUNBUFFERED": "1"})

    def forward(signum: int, _frame: object) -> None:
        process.send_signal(signum)

    for signum in (signal.SIGTERM, signal.SIGINT):
        signal.signal(signum, forward)
    code = process.wait()
    return 0 if code in (0, -signal.SIGTERM, -signal.SIGINT) else code


if __name__ == "__main__":
    sys.exit(main())
