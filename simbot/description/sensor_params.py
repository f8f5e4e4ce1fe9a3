"""Reading a `<sensor>`'s own SDF elements, and gz-sensors' `<noise>`.

The description layer keeps each `<sensor>` whole (its children as `Param` trees, as it keeps
plugins), and each sensor module parses what it needs into its own frozen parameter dataclass
through `SdfElement`: a new sensor kind is one module, and the SDF reader knows nothing of lidars or
cameras. Where another layer reads a sensor's parameters too (the gym, a lidar's range), the
dataclass lives in this layer beside it (`lidar_params.py`).

A value that is not usable is a `SystemConfigError` naming the sensor and the element path
(`sensor cam: <camera><clip><near> expected a number, got 'near'`): the server's one-line error.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from simbot.description.errors import SystemConfigError
from simbot.description.model import Param, Sensor


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
