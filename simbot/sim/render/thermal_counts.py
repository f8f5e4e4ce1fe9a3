"""Thermal camera outputs (`thermal16`, `thermal8`): the `temperature` a renderer drew (K per pixel,
`outputs.py`) as Gazebo's thermal image counts, finished in the worker.

A count is the temperature clamped to the camera's range, over its linear resolution, rounded to
the nearest whole count and held in 16 bits (mono16) or 8 (mono8), as gz-rendering's
Ogre2ThermalCamera writes it into an R16/R8 unorm target: count = rint(clamp(T, min, max) / resolution),
0 .. 2^bits − 1. So with Gazebo's default 0.01 K a count, 300 K reads 30000; with 3 K a count
(Gazebo's 8-bit default), 300 K reads 100. Where nothing was drawn (the temperature buffer's 0.0)
the camera reads its `ThermalScale.background`, as Gazebo gives the sky the bottom of its ambient band.

The scale travels with the camera as a `ThermalSpec` (a `CameraSpec` that carries it); a plain
`CameraSpec` asking for these outputs gets Gazebo's defaults (`ThermalScale.gazebo`)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields

import numpy as np

from simbot.sim.render.kinds import Array, Finish, Optics, OutputKind
from simbot.sim.render.specs import CameraSpec

DEFAULT_RESOLUTION = {16: 0.01, 8: 3.0}
"""K a count where the camera says none: Gazebo's 10 mK, and the 3 K it takes instead for 8 bits
(at 10 mK, 8 bits would span only 2.55 K)."""
ATMOSPHERE_K = 288.15
"""SDF's default `<atmosphere><temperature>`: the background of a camera that was told no other."""


@dataclass(frozen=True)
class ThermalScale:
    """How a thermal camera turns kelvin into counts: its range, its resolution, its background."""

    resolution: float
    """K a count (> 0)."""
    min_temp: float = -math.inf
    max_temp: float = math.inf
    """Temperatures are clamped to min..max (K) before they are counted."""
    background: float = ATMOSPHERE_K
    """What a pixel where nothing was drawn (the sky) reads, K."""

    @staticmethod
    def gazebo(bits: int) -> ThermalScale:
        return ThermalScale(DEFAULT_RESOLUTION[bits])

    def counts(self, kelvin: Array, bits: int, out: Array, scratch: Array) -> None:
        """Kelvin (0.0: nothing drawn) → counts of `bits`, into `out`, by way of a float32 `scratch`
        of its shape (see the module docstring)."""
        np.copyto(scratch, kelvin)
        scratch[kelvin <= 0.0] = self.background
        np.clip(scratch, self.min_temp, self.max_temp, out=scratch)
        scratch /= np.float32(self.resolution)
        np.rint(scratch, out=scratch)
        np.clip(scratch, 0, (1 << bits) - 1, out=scratch)
        np.copyto(out, scratch, casting="unsafe")


@dataclass(frozen=True)
class ThermalSpec(CameraSpec):
    """A camera whose thermal outputs count on its own scale."""

    scale: ThermalScale = ThermalScale(DEFAULT_RESOLUTION[16])

    @staticmethod
    def of(spec: CameraSpec, scale: ThermalScale) -> ThermalSpec:
        """`spec` counting on `scale` (a ThermalSpec's own scale replaced)."""
        given = {f.name: getattr(spec, f.name) for f in fields(spec) if f.init}
        return ThermalSpec(**given | {"scale": scale})


def _finisher(spec: Optics, bits: int) -> Finish:
    """The camera's scale (Gazebo's defaults for a camera that carries none), and a scratch buffer."""
    scale = spec.scale if isinstance(spec, ThermalSpec) else ThermalScale.gazebo(bits)
    scratch = np.empty((spec.height, spec.width), dtype=np.float32)

    def finish(out: Array, arrays: Mapping[str, Array]) -> None:
        scale.counts(arrays["temperature"], bits, out, scratch)

    return finish


def counts16(spec: Optics) -> Finish:
    return _finisher(spec, 16)


def counts8(spec: Optics) -> Finish:
    return _finisher(spec, 8)


THERMAL16 = OutputKind("thermal16", np.uint16, 1, encoding="mono16", needs=("temperature",), finisher=counts16)
"""Gazebo's L16 thermal image: counts of the camera's resolution (0.01 K by default)."""
THERMAL8 = OutputKind("thermal8", np.uint8, 1, encoding="mono8", needs=("temperature",), finisher=counts8)
"""Gazebo's L8 thermal image: counts of the camera's resolution (3 K by default)."""
