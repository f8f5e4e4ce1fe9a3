"""What simbot's environments share: the world they step, the spaces, the step and the reset.

The world is in the environment's own process, off the bus (simbot.gym.local), unless it is
watched, observes a camera or is given an `endpoint=`: then a lockstep server (simbot.gym.session).
Both have the same requests, and the observations are the same for the same seed.

An environment step is: the action clipped into the action space, sent as `cmd_vel` (and any
other command the task adds) so that the world has it before it steps, `control_period / step
size` physics steps through world control, then the observation of the sim time reached (see
observe.py). A reset is: the robot stopped, the world reset (sim time 0, every model where the
server started it), the robot moved to the episode's start (`set_pose`), one control period
stepped so that it settles on its wheels and every sensor has a reading, and that observation.

The task (Navigate, Dock) says where the robot starts, what its target is, how an action maps to
commands, and how a step is judged (`_draw`, `_target`, `_commands`, `_judge`).
"""

from __future__ import annotations

import logging
import math
import tempfile
import weakref
from collections.abc import Mapping
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
import numpy.typing as npt
from gymnasium import spaces

from simbot.bus import messages
from simbot.bus.tf_tree import Matrix
from simbot.description import DescriptionError
from simbot.description.actor_scripts import is_actor
from simbot.description.additions import addition_path, with_additions
from simbot.description.footprints import Planar, relative
from simbot.description.free_poses import NoFreePose, Places
from simbot.description.model import World
from simbot.gym.errors import EnvConfigError
from simbot.gym.local import LocalSession
from simbot.gym.observe import Observer, Source, merged_scan, pixels, planar, scan_merger, twist
from simbot.gym.options import (
    PEOPLE,
    RENDER_CAMERA,
    EnvOptions,
    check_cameras,
    check_limits,
    profile_file,
    read_world,
    steps_per_period,
)
from simbot.gym.robot import CONTACT_SENSOR, CONTACT_TOPIC, ROBOT, RobotFacts
from simbot.gym.serve import server_spec, task_additions
from simbot.gym.session import Session
from simbot.variation import Variations, read_profile

log = logging.getLogger(__name__)

POSE = "geometry_msgs/msg/PoseStamped"
TARGET_FRAME = "base_link"
"""The merged scan's frame, as the merger client's."""
PRIME_PERIODS = 50
"""Control periods stepped at most, once, until every subscription is served (a camera draws only for a known subscriber)."""

Observation = dict[str, npt.NDArray[Any]]


@dataclass(frozen=True)
class Rewards:
    """The reward's terms (docs/learning.md): per metre of progress towards the target, per step with
    a collision, per step, once on success, and (Dock) per attach asked for outside the docking rule."""

    progress: float = 1.0
    collision: float = 10.0
    step: float = 0.01
    success: float = 10.0
    refused_attach: float = 0.1


@dataclass(frozen=True)
class View:
    """What a step is judged on: the ground truth at its end and what happened during it."""

    robot: Planar
    target: Planar
    touched: list[str]

    @property
    def distance(self) -> float:
        return math.hypot(self.target[0] - self.robot[0], self.target[1] - self.robot[1])

    @property
    def heading_error(self) -> float:
        return abs(relative(self.target, self.robot)[2])


class SimbotEnv(gymnasium.Env[Observation, npt.NDArray[np.float32]]):
    """The base of NavigateEnv and DockEnv; see the module docstring."""

    metadata: dict[str, Any] = {"render_modes": ["rgb_array"], "render_fps": 10}
    task = ""
    """`navigate` or `dock`: what `python -m simbot.gym.serve` calls it."""

    def __init__(self, options: EnvOptions, rewards: Rewards | Mapping[str, float] | None = None) -> None:
        self.options = options
        self.rewards = _rewards(rewards)
        self.world = read_world(options.world)
        self.robot = RobotFacts.read(options.robot, self.world.name)
        self.physics_steps = steps_per_period(options, self.world, self.robot)
        check_cameras(options, self.robot)
        self._check_robot()
        self.limits = check_limits(options, self.robot)
        self._variations = self._variations_of(options)
        self.layout = _still(self._base_world())
        """What stands in the world as an episode starts (no people): where the robot may be placed."""
        self.places = self._places(self.layout)
        self.render_mode = options.render_mode
        self.metadata = {**type(self).metadata, "render_fps": 1.0 / options.control_period}
        self.action_space = self._action_space()  # type: ignore[assignment]
        self.observation_space = self._observation_space()  # type: ignore[assignment]
        self._live: tuple[Session | LocalSession, Observer, weakref.finalize] | None = None
        self._merger = scan_merger(options.scan_bins)
        self._lidar_poses: dict[str, Matrix] = {}
        self._primed = False
        self._spawn_z: float | None = None
        self._time = 0
        self._episode: dict[str, Any] = {"seed": None, "steps": 0, "collisions": 0, "clipped_actions": 0}
        self._last_distance = 0.0
        self._frame: npt.NDArray[np.uint8] | None = None

    # --- what a task adds ---------------------------------------------------------------------

    def _check_robot(self) -> None:
        """EnvConfigError when the robot lacks what the task needs."""

    def _additions(self) -> tuple[Path, ...]:
        """Model files the task adds to the world (Dock: a trolley where the world has none)."""
        return task_additions(self.task, [model.name for model in self.world.models])

    def _extra_sources(self) -> dict[str, Source]:
        return {}

    def _draw(self, rng: np.random.Generator, options: Mapping[str, Any]) -> tuple[Planar, Planar]:
        """The episode's start and target."""
        raise NotImplementedError

    def _target(self, msgs: Mapping[str, Any]) -> Planar:
        """The target at the step's end (the goal stays; a trolley may be pushed)."""
        target: Planar = self._episode["target"]
        return target

    def _commands(self, action: npt.NDArray[np.float64]) -> list[tuple[str, Any]]:
        """The (topic, message) pairs an action puts before the step."""
        return [(self.robot.cmd_topic, messages.twist((float(action[0]), 0.0, 0.0), (0.0, 0.0, float(action[1]))))]

    def _judge(self, view: View) -> tuple[float, bool, dict[str, Any]]:
        """(the task's reward terms beyond progress, collision and step; success; info to add)."""
        raise NotImplementedError

    def _episode_started(self) -> None:
        """The task forgets the last episode."""

    # --- the spaces ---------------------------------------------------------------------------

    def _action_space(self) -> spaces.Box:
        linear, angular = self.limits
        return spaces.Box(np.array([-linear, -angular], np.float32), np.array([linear, angular], np.float32))

    def _observation_space(self) -> spaces.Dict:
        xmin, ymin, xmax, ymax = self.places.area
        reach = float(np.float32(math.hypot(xmax - xmin, ymax - ymin) + 1.0))
        linear, angular = 2 * self.robot.limits.linear, 2 * self.robot.limits.angular
        width, height = self.options.camera_size
        return spaces.Dict(
            {
                "scan": spaces.Box(0.0, self.robot.lidar_reach, (self.options.scan_bins,), np.float32),
                "goal": spaces.Box(
                    np.array([-reach, -reach, -math.pi], np.float32), np.array([reach, reach, math.pi], np.float32)
                ),
                "twist": spaces.Box(np.array([-linear, -angular], np.float32), np.array([linear, angular], np.float32)),
                **{c: spaces.Box(0, 255, (height, width, 3), np.uint8) for c in self.options.cameras},
            }
        )

    # --- the server -----------------------------------------------------------------------------

    def _base_world(self) -> World:
        """The world as the server loads it: its file, the task's additions, the people if asked."""
        people = (addition_path(PEOPLE),) if self.options.people else ()
        return with_additions(self.world, (*self._additions(), *people))

    def _variations_of(self, options: EnvOptions) -> Variations | None:
        """The variants resets draw (the same as the server's, drawn here for the places); None when not randomised."""
        path = profile_file(options)
        if path is None:
            return None
        try:
            return Variations(self._base_world(), None, read_profile(path))
        except DescriptionError as exc:
            raise EnvConfigError(f"randomise: {exc}") from None

    def _vary(self, seed: int) -> None:
        """The episode's world drawn from `seed`: where the robot may stand in it."""
        assert self._variations is not None
        try:
            self.layout = _still(self._variations.draw(seed).world)
        except DescriptionError as exc:
            raise EnvConfigError(f"randomise: {exc}") from None
        self.places = self._places(self.layout)

    def _open(self) -> Session | LocalSession:
        """The world in this process when no one watches it and no camera needs render workers on
        the bus; else a started server; else the one at `endpoint`."""
        options = self.options
        if options.endpoint is None:
            folder = Path(tempfile.mkdtemp(prefix="simbot-gym-"))
            spec = server_spec(options, self.robot, self._additions(), folder)
            if options.on_bus:
                return Session.start(spec, self.world.name, folder, options.timeout)
            return LocalSession(spec, self.world.name, folder)
        session = Session.connect(options.endpoint, options.namespace, self.world.name, options.timeout)
        sensors = session.state().get("sensors", {})
        missing = [f"{ROBOT}/{link}/{CONTACT_SENSOR}" for link in self.robot.bumpers]
        if not all(name in sensors for name in missing):
            session.close()
            raise EnvConfigError(
                f"{session.name} runs no contact sensor {missing[0]}: start it with `python -m simbot.gym.serve` "
                "(docs/learning.md), so that its robot is the environment's"
            )
        return session

    def _sources(self) -> dict[str, Source]:
        sources: dict[str, Source] = {
            name: (topic, "sensor_msgs/msg/LaserScan") for name, topic in self.robot.lidars.items()
        }
        sources["odom"] = (self.robot.odom_topic, "nav_msgs/msg/Odometry")
        sources["robot"] = (f"model/{ROBOT}/pose", POSE)
        for camera in self.options.observed_cameras:
            sources[camera] = (self.robot.cameras[camera], "sensor_msgs/msg/Image")
        return {**sources, **self._extra_sources()}

    def _places(self, world: World) -> Places:
        """Where the robot may stand in `world`; EnvConfigError naming why when nowhere."""
        try:
            return Places.of_world(
                world, self.robot.footprint, self.robot.rest_height + self.robot.top,
                self.options.clearance, self.options.area,
            )  # fmt: skip
        except NoFreePose as exc:
            raise EnvConfigError(str(exc)) from None

    # --- the API ---------------------------------------------------------------------------------

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Observation, dict[str, Any]]:
        if seed is None and self._np_random is None:
            seed = self.options.seed  # an environment made with seed=S starts as reset(seed=S) would
        super().reset(seed=seed)
        episode_seed = seed if seed is not None else int(self.np_random.integers(2**31 - 1))
        if self._variations is not None:
            self._vary(episode_seed)
        try:
            start, target = self._draw(np.random.default_rng(episode_seed), options or {})
        except NoFreePose as exc:
            raise EnvConfigError(str(exc)) from None
        if not self._primed:
            self._prime()
        session = self._session
        session.send([self._stop()])
        session.reset(episode_seed if self._variations is not None else None)
        if self._spawn_z is None:
            self._spawn_z = float(session.state()["models"][ROBOT]["position"][2])
        session.set_pose(ROBOT, start[0], start[1], self._spawn_z, start[2])
        self._episode = {"seed": episode_seed, "steps": 0, "collisions": 0, "clipped_actions": 0, "target": target}
        self._episode_started()
        self._observer.forget()
        self._time = session.step(self.physics_steps)
        obs, view = self._observe()
        self._last_distance = view.distance
        return obs, self._info(view, False)

    def step(self, action: npt.NDArray[np.float32]) -> tuple[Observation, float, bool, bool, dict[str, Any]]:
        self.step_begin(action)
        return self.step_end(self._session.step(self.physics_steps))

    def step_begin(self, action: npt.NDArray[np.float32]) -> None:
        """The first half of `step`: the action checked and sent. A vector env steps its sub-envs'
        worlds together between the halves."""
        if self._episode["seed"] is None:
            raise gymnasium.error.ResetNeeded("call reset() before step()")
        self._session.send(self._commands(self._clip(action)))

    def step_end(self, reached: int) -> tuple[Observation, float, bool, bool, dict[str, Any]]:
        """The second half of `step`, once the world has stepped a control period to `reached` (ns):
        the observation, the reward and whether the episode ended."""
        before, self._time = self._time, reached
        obs, view = self._observe(after=before)
        self._episode["steps"] += 1
        collided = bool(view.touched)
        self._episode["collisions"] += int(collided)
        task_reward, success, extra = self._judge(view)
        r = self.rewards
        reward = r.progress * (self._last_distance - view.distance) - r.step + task_reward
        reward += r.success if success else 0.0
        reward -= r.collision if collided else 0.0
        self._last_distance = view.distance
        terminated = success or (collided and self.options.terminate_on_collision)
        truncated = not terminated and self._episode["steps"] >= self.options.max_episode_steps
        return obs, float(reward), terminated, truncated, {**self._info(view, success), **extra}

    def render(self) -> npt.NDArray[np.uint8] | None:
        """The front camera's image at the last step (render_mode="rgb_array"), else None."""
        if self.render_mode != "rgb_array" or self._frame is None:
            return None
        return self._frame.copy()

    def close(self) -> None:
        """Ends the server the environment started (nothing is left running) and its bus session;
        safe to call twice."""
        live, self._live = getattr(self, "_live", None), None
        if live is not None:
            live[1].close()
            live[2]()
        super().close()

    @property
    def session(self) -> Session | LocalSession:
        """The world's session: a server and its bus node, or the world in this process (for tests and tools)."""
        return self._started()[0]

    @property
    def _session(self) -> Session | LocalSession:
        return self._started()[0]

    @property
    def _observer(self) -> Observer:
        return self._started()[1]

    def _started(self) -> tuple[Session | LocalSession, Observer, weakref.finalize]:
        """The session, its observer and the finaliser that ends it, started at first use rather than
        in `__init__`: a vector env makes one env in its parent to read the spaces, then starts its
        workers (a process forked after Zenoh's threads started hangs in the child), and needs no
        world in the parent."""
        if self._live is None:
            session = self._open()
            finalizer = weakref.finalize(self, session.close)
            observer = Observer(session.node, self._sources(), CONTACT_TOPIC, ROBOT, self.robot.attach_state_topic)
            self._live = (session, observer, finalizer)
        return self._live

    # --- inside a step ---------------------------------------------------------------------------

    def _clip(self, action: Any) -> npt.NDArray[np.float64]:
        """The action within the space; a clip is counted in `info["clipped_actions"]`; ValueError
        for an action of the wrong shape or not finite (no clip can mend it)."""
        space = self.action_space
        assert isinstance(space, spaces.Box)
        values = np.asarray(action, dtype=np.float64)
        if values.shape != space.shape:
            raise ValueError(f"action of shape {values.shape}, expected {space.shape}")
        if not np.all(np.isfinite(values)):
            raise ValueError(f"action {values.tolist()} is not finite")
        clipped = np.clip(values, space.low.astype(np.float64), space.high.astype(np.float64))
        if not np.array_equal(clipped, values):
            self._episode["clipped_actions"] += 1
        return clipped

    def _stop(self) -> tuple[str, Any]:
        return (self.robot.cmd_topic, messages.twist((0.0, 0.0, 0.0), (0.0, 0.0, 0.0)))

    def _prime(self) -> None:
        """Steps until every subscription has a message (from then on the server knows them all), and
        waits for the whole of the last step's, so that none of them comes in after the reset."""
        reached = self._session.step(self.physics_steps)
        for _ in range(PRIME_PERIODS):
            if self._observer.received_any():
                break
            reached = self._session.step(self.physics_steps)
        self._observer.wait(reached, self._session.check, self.options.timeout)
        self._primed = True

    def _observe(self, after: int | None = None) -> tuple[Observation, View]:
        """The observation at the sim time reached, and the ground truth it was made with."""
        session, options = self._session, self.options
        msgs = self._observer.wait(self._time, session.check, options.timeout)
        scans = [(msgs[name], self._lidar_pose(msgs[name].header.frame_id)) for name in self.robot.lidars]
        robot = planar(msgs["robot"])
        target = self._target(msgs)
        obs_space = self.observation_space
        assert isinstance(obs_space, spaces.Dict)
        goal_space, twist_space = obs_space["goal"], obs_space["twist"]
        assert isinstance(goal_space, spaces.Box) and isinstance(twist_space, spaces.Box)
        obs: Observation = {
            "scan": merged_scan(self._merger, scans, self.robot.lidar_reach),
            "goal": np.clip(np.array(relative(target, robot), np.float32), goal_space.low, goal_space.high),
            "twist": np.clip(np.array(twist(msgs["odom"]), np.float32), twist_space.low, twist_space.high),
        }
        for camera in options.observed_cameras:
            image = pixels(msgs[camera], options.camera_size)
            if camera in options.cameras:
                obs[camera] = image
            if camera == RENDER_CAMERA:
                self._frame = image.copy()
        touched = self._observer.contacts(after, self._time) if after is not None else []
        return obs, View(robot, target, touched)

    def _lidar_pose(self, frame: str) -> Matrix:
        if frame not in self._lidar_poses:
            self._lidar_poses[frame] = self._observer.sensor_pose(
                TARGET_FRAME, frame, self._session.check, self.options.timeout
            )
        return self._lidar_poses[frame]

    def _info(self, view: View, success: bool) -> dict[str, Any]:
        episode = self._episode
        return {
            "success": bool(success),
            "collisions": int(episode["collisions"]),
            "clipped_actions": int(episode["clipped_actions"]),
            "seed": episode["seed"],
            "sim_time": self._time / 1e9,
            "distance": float(view.distance),
            "touched": list(view.touched),
        }


def _rewards(given: Rewards | Mapping[str, float] | None) -> Rewards:
    if given is None or isinstance(given, Rewards):
        return given or Rewards()
    known = {f.name for f in fields(Rewards)}
    unknown = set(given) - known
    if unknown:
        raise EnvConfigError(
            f"rewards: unknown term(s) {', '.join(sorted(unknown))} (terms: {', '.join(sorted(known))})"
        )
    return Rewards(**{k: float(v) for k, v in given.items()})


def env_options(kwargs: Mapping[str, Any]) -> EnvOptions:
    """The common options of `kwargs`; EnvConfigError naming any option nobody takes."""
    known = {f.name for f in fields(EnvOptions)}
    unknown = set(kwargs) - known
    if unknown:
        raise EnvConfigError(f"unknown option(s) {', '.join(sorted(unknown))} (options: {', '.join(sorted(known))})")
    return EnvOptions(**kwargs)


def _still(world: World) -> World:
    """`world` without its people: they move, so they are no obstacle to a placement."""
    return replace(world, models=tuple(model for model in world.models if not is_actor(model)))
