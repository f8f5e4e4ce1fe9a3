"""Benchmark of the server: fast-mode real-time factor against a bare PyBullet loop, and start-up time.

All figures come from one run on one machine, so the ratio holds even where the machine is
shared and noisy:

1. bare loop: the same world and robot in PyBullet, `stepSimulation` at 1 kHz and nothing else,
   with the robot standing, and with its wheel motors turning as the server's drive turns them
   (a moving robot's contacts cost PyBullet more than a standing one's);
2. server: `simbot-server --mode fast` (physics, wheel friction, drive, odom, tf, clock, poses,
   joint states, world control) driving the robot, measured through its world-control state;
3. start-up: wall time from launching `simbot-server` to the first `odom` message a client gets.

    python benchmarks/bench_server.py [--seconds S]
"""

from __future__ import annotations

import argparse
import socket
import subprocess
import sys
import threading
import time
import uuid

from tables import publish

from simbot.bus import BusOptions, Node, messages
from simbot.description import load_model, load_world
from simbot.description.poses import Pose
from simbot.description.resources import asset
from simbot.sim.bullet import pb
from simbot.sim.physics import Physics

STEP_S = 0.001


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


LEFT, RIGHT = 0.3 - 0.1 * 0.2, 0.3 + 0.1 * 0.2
"""Wheel surface speeds (m/s) of the server's command below: 0.3 m/s, 0.1 rad/s, track 0.4 m."""


def bare_loop(seconds: float, driving: bool) -> float:
    """Sim seconds per wall second of PyBullet alone, with the warehouse and the robot loaded."""
    world = load_world(asset("worlds/warehouse.sdf"))
    physics = Physics(world)
    for model in world.models:
        physics.add_model(model)
    physics.add_model(load_model(asset("urdf/flexley_tug.sdf")), "flexley_tug", Pose((-2.5, 0.0, 0.1)))
    if driving:
        for side, speed in (("left", LEFT), ("right", RIGHT)):
            for end in ("front", "back"):
                physics.set_joint_velocity("flexley_tug", f"{end}_{side}_wheel_joint", speed / 0.075, 10000.0)
    steps, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        for _ in range(100):
            pb.stepSimulation(physicsClientId=physics.client)
        steps += 100
    rtf = steps * STEP_S / (time.perf_counter() - start)
    physics.close()
    return rtf


def server(seconds: float) -> tuple[float, float]:
    """(real-time factor in fast mode while driving, seconds from launch to the first odom)."""
    port, namespace = free_port(), f"bench_{uuid.uuid4().hex[:8]}"
    endpoint = f"tcp/127.0.0.1:{port}"
    first_odom = threading.Event()
    launched = time.perf_counter()
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "simbot.sim.server",
            "--mode",
            "fast",
            "--quiet",
            "--listen",
            endpoint,
            "--namespace",
            namespace,
        ],
        stderr=subprocess.DEVNULL,
    )
    try:
        # the server listens only once it has imported and loaded the world: seconds, tens on a loaded machine
        with Node(BusOptions(connect=(endpoint,), namespace=namespace, connect_timeout=60.0), "client") as node:
            node.subscribe("odom", "nav_msgs/msg/Odometry", lambda _msg: first_odom.set())
            if not first_odom.wait(30):
                raise RuntimeError("no odom within 30 s")
            startup = time.perf_counter() - launched
            drive = node.publisher("cmd_vel", messages.Twist, drop=False)
            drive.put(messages.twist((0.3, 0.0, 0.0), (0.0, 0.0, 0.1)))
            sim0, wall0 = node.call("world/warehouse/state", {})["sim_time"], time.perf_counter()
            time.sleep(seconds)
            sim1, wall1 = node.call("world/warehouse/state", {})["sim_time"], time.perf_counter()
        return (sim1 - sim0) / (wall1 - wall0), startup
    finally:
        proc.terminate()
        proc.wait(10)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=5.0, help="wall seconds per measurement")
    args = parser.parse_args()
    standing, driving = bare_loop(args.seconds, driving=False), bare_loop(args.seconds, driving=True)
    fast, startup = server(args.seconds)
    table = [
        "| measurement | figure |",
        "| --- | --- |",
        f"| bare PyBullet 1 kHz loop, warehouse + robot standing | {standing:.1f}× real time |",
        f"| bare PyBullet 1 kHz loop, robot's wheels driven | {driving:.1f}× real time |",
        f"| simbot-server --mode fast, driving | {fast:.1f}× real time |",
        f"| server / bare loop (driving) | {fast / driving:.2f} |",
        f"| server / bare loop (standing) | {fast / standing:.2f} |",
        f"| launch → first odom | {startup:.2f} s |",
    ]
    publish("server", table)


if __name__ == "__main__":
    main()
