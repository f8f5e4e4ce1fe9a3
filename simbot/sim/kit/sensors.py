"""What sensor modules share as they run: gz-sensors' per-channel noise (`ChannelNoise`), and the
sensor that reads its own frame each sample (`FramedSensor`). Reading a sensor's SDF elements and
its `<noise>`: simbot.description.sensor_params."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from simbot.description.naming import sensor_frame, sensor_rate
from simbot.description.sensor_params import Noise
from simbot.sim.kit.rates import Sampled
from simbot.sim.loop.system import SystemContext, UpdateInfo


class ChannelNoise:
    """Gaussian noise of a few channels (axes) as gz-sensors applies it: mean, plus a bias drawn once per
    run (N(bias_mean, bias_stddev), random sign) and held until `draw_bias` (a reset), plus white N(0, σ)."""

    def __init__(self, channels: Sequence[Noise], rng: np.random.Generator) -> None:
        self._rng = rng
        self.mean = np.array([n.mean for n in channels], dtype=float)
        self.stddev = np.array([n.stddev for n in channels], dtype=float)
        self._bias_mean = np.array([n.bias_mean for n in channels], dtype=float)
        self._bias_stddev = np.array([n.bias_stddev for n in channels], dtype=float)
        self.bias = np.zeros(len(channels))
        self.draw_bias()

    def draw_bias(self) -> None:
        size = self._rng.normal(self._bias_mean, self._bias_stddev)
        self.bias = size * self._rng.choice((-1.0, 1.0), self.bias.size)

    def __call__(self, value: npt.ArrayLike) -> npt.NDArray[np.float64]:
        return (
            np.asarray(value, dtype=float)
            + self.mean
            + self.bias
            + self._rng.normal(0.0, 1.0, self.bias.size) * self.stddev
        )

    def variances(self) -> npt.NDArray[np.float64]:
        """σ² of each channel (0: no noise; ROS reads a 0 covariance as unknown)."""
        return self.stddev**2

    def covariance(self) -> npt.NDArray[np.float64]:
        """The channels' diagonal covariance, row-major (an IMU's or magnetometer's 3×3)."""
        return np.diag(self.variances()).reshape(-1)


class FramedSensor(Sampled):
    """A sensor that reads its own frame each sample (its pose, its motion, the joint it is on) and adds
    per-channel noise: altimeter, magnetometer, air pressure, navsat, force/torque. It keeps where the
    frame is (`where`: model, link, pose in the link), the noise, the frame id and the publisher on
    Gazebo's `kind` of key; a reset redraws the noise's bias, as a new run would."""

    def __init__(self, ctx: SystemContext, channels: Sequence[Noise], kind: str, msgtype: type[Any]) -> None:
        model, link, sensor = ctx.require_sensor()
        super().__init__(sensor.name, sensor_rate(sensor, 1.0 / ctx.physics.step_size))
        self.physics = ctx.physics
        self.where = (model, link.name, sensor.pose)
        self.noise = ChannelNoise(channels, ctx.rng)
        self.frame = sensor_frame(sensor)
        self.publisher = ctx.bus.publisher(ctx.sensor_topic(kind), msgtype)

    def publish(self, info: UpdateInfo, message: Any) -> None:
        self.publisher.put(message)
        self.published(info.sim_time_ns)

    def reset(self, info: UpdateInfo) -> None:
        super().reset(info)
        self.noise.draw_bias()
