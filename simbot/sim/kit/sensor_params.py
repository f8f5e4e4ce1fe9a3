"""What sensor modules share: reading a `<sensor>`'s own SDF elements, gz-sensors' noise, and the
frame every simple sensor reads.

Reading a `<sensor>`'s own SDF elements. The description layer keeps each `<sensor>` whole (its
children as `Param` trees, as it keeps plugins), and each sensor module parses what it needs into
its own frozen parameter dataclass through `SdfElement`: a new sensor kind is one module, and the
SDF reader knows nothing of lidars or cameras.

A value that is not usable is a `SystemConfigError` naming the sensor and the element path
(`sensor cam: <camera><clip><near> expected a number, got 'near'`): the server's one-line error.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from simbot.description.model import Param, Sensor
from simbot.sim.kit.rates import Sampled
from simbot.sim.loop.naming import sensor_frame, sensor_rate
from simbot.sim.loop.system import SystemConfigError, SystemContext, UpdateInfo


@dataclass(frozen=True)
class Noise:
    """SDF `<noise>`: gaussian with a mean, a deviation, and a bias drawn once per run."""

    type: str = "none"
    mean: float = 0.0
    stddev: float = 0.0
    bias_mean: float = 0.0
    bias_stddev: float = 0.0

    @property
    def applied(self) -> Noise:
        """What simbot applies: `gaussian` (or `gaussian_quantized`) as given, any other kind as none."""
        return self if self.type.startswith("gaussian") else Noise()


class SdfElement:
    """One element of a sensor's SDF, found by tag under the `<sensor>`; errors name the path."""

    def __init__(self, sensor: str, children: Sequence[Param], path: tuple[str, ...] = ()) -> None:
        self.sensor = sensor
        self.children = tuple(children)
        self.path = path

    @staticmethod
    def of(sensor: Sensor) -> SdfElement:
        return SdfElement(sensor.name, sensor.params)

    def _param(self, tag: str) -> Param | None:
        return next((p for p in self.children if p.tag == tag), None)

    def child(self, tag: str) -> SdfElement | None:
        """The first child element `tag`, or None."""
        found = self._param(tag)
        return None if found is None else SdfElement(self.sensor, found.children, self.path + (tag,))

    def child_or_empty(self, tag: str) -> SdfElement:
        """The child, or an empty element (every value its default) when it is absent."""
        return self.child(tag) or SdfElement(self.sensor, (), self.path + (tag,))

    def require(self, tag: str) -> SdfElement:
        found = self.child(tag)
        if found is None:
            raise self.error(tag, "is required")
        return found

    def text(self, tag: str, default: str | None = None) -> str | None:
        found = self._param(tag)
        return default if found is None or found.text.strip() == "" else found.text.strip()

    def number(self, tag: str, default: float) -> float:
        text = self.text(tag)
        if text is None:
            return default
        try:
            value = float(text)
        except ValueError:
            raise self.error(tag, f"expected a number, got {text!r}") from None
        if not math.isfinite(value):
            raise self.error(tag, f"expected a finite number, got {text!r}")
        return value

    def numbers(self, tag: str, default: tuple[float, ...]) -> tuple[float, ...]:
        """A vector of as many finite numbers as `default`, space-separated (`<center>0.5 0.5</center>`)."""
        text = self.text(tag)
        if text is None:
            return default
        try:
            values = tuple(float(part) for part in text.split())
        except ValueError:
            raise self.error(tag, f"expected {len(default)} numbers, got {text!r}") from None
        if len(values) != len(default) or not all(math.isfinite(v) for v in values):
            raise self.error(tag, f"expected {len(default)} finite numbers, got {text!r}")
        return values

    def required_number(self, tag: str) -> float:
        if self.text(tag) is None:
            raise self.error(tag, "is required")
        return self.number(tag, math.nan)

    def integer(self, tag: str, default: int) -> int:
        text = self.text(tag)
        if text is None:
            return default
        try:
            return int(text)
        except ValueError:
            raise self.error(tag, f"expected a whole number, got {text!r}") from None

    def texts(self, tag: str) -> list[str]:
        """The texts of every child `tag`, in file order (a contact sensor's several `<collision>`)."""
        return [p.text.strip() for p in self.children if p.tag == tag and p.text.strip()]

    def noise_of(self, tag: str) -> Noise:
        """What simbot applies for the `<noise>` of child `tag` (`<x>`, `<vertical_position>`...): none when absent."""
        return (self.child_or_empty(tag).noise() or Noise()).applied

    def noise(self) -> Noise | None:
        """The `<noise>` child, or None when there is none."""
        found = self._param("noise")
        if found is None:
            return None
        element = SdfElement(self.sensor, found.children, self.path + ("noise",))
        kind = dict(found.attrs).get("type") or element.text("type", "gaussian") or "gaussian"
        return Noise(
            kind,
            element.number("mean", 0.0),
            element.number("stddev", 0.0),
            element.number("bias_mean", 0.0),
            element.number("bias_stddev", 0.0),
        )

    def error(self, tag: str, message: str) -> SystemConfigError:
        where = "".join(f"<{t}>" for t in self.path + (tag,))
        return SystemConfigError(f"sensor {self.sensor}: {where} {message}")


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
