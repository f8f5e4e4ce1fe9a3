"""The options every simbot environment takes, checked before anything starts.

Each bad value is one `EnvConfigError` naming the option: an unknown world, a camera the robot
lacks, a control period the observed messages cannot be stamped at.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from simbot.description import DescriptionError, load_world
from simbot.description.footprints import Planar
from simbot.description.free_poses import Area
from simbot.description.model import World
from simbot.description.resources import asset
from simbot.gym.errors import EnvConfigError
from simbot.gym.robot import RobotFacts
from simbot.sim.physics.kinematic_world import KINEMATIC, kinematic
from simbot.variation import profile_beside

RENDER_MODES = ("rgb_array",)
PHYSICS = ("dynamic", KINEMATIC)
"""How the server moves the robot (`simbot-server --physics`)."""
PEOPLE = "warehouse_people"
"""The warehouse's walking people, a file of their own (`simbot-server --add warehouse_people`)."""
GROUND_TRUTH_PERIOD_S = 0.02
"""The server publishes ground-truth poses at 50 Hz and the clock at 100 Hz (simbot.sim.systems'
pose and clock publishers): the control period must be a multiple of both, and of odometry's."""
RENDER_CAMERA = "camera_front"


@dataclass(frozen=True)
class EnvOptions:
    """What `gymnasium.make("simbot/...", **kwargs)` may set for every environment (docs/learning.md)."""

    world: str = "warehouse"
    people: bool = False
    control_period: float = 0.1
    seed: int = 0
    endpoint: str | None = None
    namespace: str = ""
    cameras: tuple[str, ...] = ()
    camera_size: tuple[int, int] = (160, 120)
    render_mode: str | None = None
    max_episode_steps: int = 500
    scan_bins: int = 360
    clearance: float = 0.3
    area: Area | None = None
    max_linear: float | None = None
    max_angular: float | None = None
    terminate_on_collision: bool = True
    randomise: bool | str = False
    """Each reset loads the world its episode's seed draws (simbot.variation): True, from the world's
    own profile; a path, from that profile."""
    timeout: float = 60.0
    physics: str = "dynamic"
    """How the server moves the robot (docs/learning.md): "dynamic", forces and wheel friction at the
    world's step; "kinematic", the drive's command applied to the base at 200 Hz, stopping at contact.
    With `endpoint=`, what the given server runs (as `world` says which world it runs)."""
    watch: bool = False
    """Run the world in a server on the bus (Foxglove, the clients and `simbot view` can watch it);
    by default it steps in the environment's own process, off the bus (simbot.gym.local)."""
    cameras_in_process: bool = False
    """With cameras, step the world off the bus too, its render workers started from this process
    (multiprocessing's "spawn") and their frames taken back: for a script whose main module is
    guarded (`if __name__ == "__main__":`, which spawn needs), and what the native vector env's
    simulation processes do. Otherwise an env that observes a camera runs a server."""
    robot: Path = field(default_factory=lambda: asset("urdf/flexley_tug.sdf"))

    def __post_init__(self) -> None:
        object.__setattr__(self, "cameras", tuple(self.cameras))
        object.__setattr__(self, "camera_size", tuple(int(v) for v in self.camera_size))
        if not isinstance(self.control_period, (int, float)) or not self.control_period > 0:
            raise EnvConfigError(f"control_period {self.control_period!r}: must be a positive number of seconds")
        if self.render_mode is not None and self.render_mode not in RENDER_MODES:
            raise EnvConfigError(f"render_mode {self.render_mode!r}: simbot's environments offer {RENDER_MODES}")
        if len(self.camera_size) != 2 or min(self.camera_size) < 1:
            raise EnvConfigError(f"camera_size {self.camera_size!r}: expected (width, height) in pixels")
        for name, value, low in (("max_episode_steps", self.max_episode_steps, 1), ("scan_bins", self.scan_bins, 8)):
            if not isinstance(value, int) or value < low:
                raise EnvConfigError(f"{name} {value!r}: must be an integer ≥ {low}")
        if not self.clearance >= 0:
            raise EnvConfigError(f"clearance {self.clearance!r}: must be ≥ 0 m")
        if not self.timeout > 0:
            raise EnvConfigError(f"timeout {self.timeout!r}: must be > 0 s")
        if self.randomise is not False and not isinstance(self.randomise, (bool, str)):
            raise EnvConfigError(f"randomise {self.randomise!r}: True, or a variation profile's path")
        if self.physics not in PHYSICS:
            raise EnvConfigError(f"physics {self.physics!r}: one of {', '.join(PHYSICS)}")
        if self.endpoint is not None and self.people:
            raise EnvConfigError(
                "people=True starts the server with the people: give it to the server, not with endpoint="
            )

    @property
    def on_bus(self) -> bool:
        """Whether the world runs on the bus: watched, given by `endpoint`, or rendering cameras
        whose workers this process is not to start (`cameras_in_process`)."""
        cameras_on_bus = bool(self.observed_cameras) and not self.cameras_in_process
        return self.watch or self.endpoint is not None or cameras_on_bus

    @property
    def observed_cameras(self) -> tuple[str, ...]:
        """The cameras subscribed: those observed, and the front one when render() shows it."""
        extra = (RENDER_CAMERA,) if self.render_mode == "rgb_array" and RENDER_CAMERA not in self.cameras else ()
        return self.cameras + extra


def world_file(name_or_path: str) -> Path:
    """A world file, or the name of one of simbot's own worlds (as `simbot-server --world` takes it)."""
    path = Path(name_or_path)
    if path.suffix == ".sdf" or path.exists():
        if not path.is_file():
            raise EnvConfigError(f"world {name_or_path!r}: no such file")
        return path
    own = asset(f"worlds/{name_or_path}.sdf")
    if own.is_file():
        return own
    known = sorted(p.stem for p in asset("worlds").glob("*.sdf"))
    raise EnvConfigError(f"unknown world {name_or_path!r}: give an SDF file or one of {', '.join(known)}")


def read_world(name_or_path: str) -> World:
    path = world_file(name_or_path)
    try:
        return load_world(path)
    except DescriptionError as exc:
        raise EnvConfigError(f"world {name_or_path!r}: {exc}") from None


def steps_per_period(options: EnvOptions, world: World, robot: RobotFacts) -> int:
    """Physics steps per environment step, at the step the server takes (a kinematic world's is
    longer); EnvConfigError unless the control period is a whole number of steps and of the periods
    the observed messages come at."""
    stepped = kinematic(world) if KINEMATIC in (options.physics, world.physics.type) else world
    step = stepped.physics.max_step_size
    steps = round(options.control_period / step)
    if steps < 1 or not math.isclose(steps * step, options.control_period, rel_tol=0, abs_tol=1e-9):
        raise EnvConfigError(f"control_period {options.control_period:g} s: not a whole number of {step:g} s steps")
    for what, period in (("ground truth and clock", GROUND_TRUTH_PERIOD_S), ("odometry", 1.0 / robot.odom_rate)):
        ratio = options.control_period / period
        if abs(ratio - round(ratio)) > 1e-6 or round(ratio) < 1:
            raise EnvConfigError(
                f"control_period {options.control_period:g} s: must be a multiple of {period:g} s, the period of "
                f"the {what} an observation is stamped with"
            )
    return steps


def check_cameras(options: EnvOptions, robot: RobotFacts) -> None:
    for camera in options.observed_cameras:
        if camera not in robot.cameras:
            raise EnvConfigError(
                f"camera {camera!r}: the robot has no such camera ({', '.join(sorted(robot.cameras))})"
            )


def check_limits(options: EnvOptions, robot: RobotFacts) -> tuple[float, float]:
    """The action's bounds: the drive's SDF limits, or narrower ones asked for."""
    bounds = []
    for name, asked, limit in (
        ("max_linear", options.max_linear, robot.limits.linear),
        ("max_angular", options.max_angular, robot.limits.angular),
    ):
        if asked is not None and not 0 < asked <= limit:
            raise EnvConfigError(f"{name} {asked!r}: must be in (0, {limit:g}], the drive's limit in the robot's SDF")
        bounds.append(limit if asked is None else float(asked))
    return bounds[0], bounds[1]


def parse_pose(value: Any, what: str) -> Planar:
    """(x, y, yaw) of a reset option; EnvConfigError naming it when it is not three finite numbers."""
    try:
        x, y, yaw = (float(v) for v in value)
    except (TypeError, ValueError):
        raise EnvConfigError(f"{what} {value!r}: expected (x, y, yaw)") from None
    if not all(math.isfinite(v) for v in (x, y, yaw)):
        raise EnvConfigError(f"{what} {value!r}: expected finite numbers")
    return x, y, yaw


def profile_file(options: EnvOptions) -> Path | None:
    """The variation profile resets draw from: the world's own (`randomise=True`) or the path given."""
    if options.randomise is False:
        return None
    path = profile_beside(world_file(options.world)) if options.randomise is True else Path(str(options.randomise))
    if not path.is_file():
        raise EnvConfigError(f"randomise: no variation profile {path}")
    return path.resolve()
