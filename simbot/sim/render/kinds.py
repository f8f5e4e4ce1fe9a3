"""Camera outputs as plug-ins: an output kind says what one named output of a camera is.

A kind gives its array per camera (dtype, values per pixel: the camera's shared memory layout),
what a renderer draws for it (the raw colour or depth buffer, read straight into the output's
memory), the outputs it is computed from, its finishing step in the worker, and the
sensor_msgs/Image encoding of its array (None when it is no image). A camera asks for outputs by
name (`CameraSpec.outputs`); the kinds they need come with them, finished first.

Kinds are found by name in the entry-point group `simbot.camera_outputs` (simbot's own in its
pyproject.toml, a third party's in theirs). A `CameraSpec` resolves its names once, in the server,
and the kinds travel to the workers inside it: the workers never look a name up. So a kind's
finisher must be a module-level function (pickled by name), and a kind need not be installed to
be used (a test may add one to `output_kinds()`).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from functools import cache
from typing import Any, Literal, Protocol

import numpy as np
import numpy.typing as npt

from simbot.plugins import load_group
from simbot.sim.render.lens import Distortion

log = logging.getLogger(__name__)

GROUP = "simbot.camera_outputs"
Array = npt.NDArray[Any]
Raw = Literal["color", "depth", "labels", "temperature"]
"""The buffers a renderer draws: uint8 colour (H×W×3 rgb, or H×W luminance), window depth (float32,
0..1), each pixel's label and instance (uint32, `label_bits.py`), its temperature (float32, K)."""
Finish = Callable[[Array, Mapping[str, Array]], None]
"""Finishes an output in place, given its array and every output of the camera by name."""


class Optics(Protocol):
    """What a kind may read of its camera (a `CameraSpec` is one): size, clip, noise, focal length, lens."""

    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    @property
    def near(self) -> float: ...
    @property
    def far(self) -> float: ...
    @property
    def noise_stddev(self) -> float: ...
    @property
    def seed(self) -> int: ...
    @property
    def fx(self) -> float: ...
    @property
    def principal_point(self) -> tuple[float, float]: ...
    @property
    def distortion(self) -> Distortion: ...


@dataclass(frozen=True)
class OutputKind:
    """One kind of camera output; see the module docstring."""

    name: str
    dtype: type[np.generic]
    channels: int
    """Values per pixel: 1 gives an H×W array, more an H×W×channels one."""
    encoding: str | None = None
    """sensor_msgs/image_encodings of the array; None for an output that is no image (points)."""
    draws: Raw | None = None
    """The raw buffer the renderer draws straight into this output's memory."""
    needs: tuple[str, ...] = ()
    """The outputs it is computed from: they are in the camera's memory and finished before it."""
    finisher: Callable[[Optics], Finish | None] | None = None
    """Makes the camera's finishing step, once per camera in its worker; None (or a None step): none."""

    def shape(self, spec: Optics) -> tuple[int, ...]:
        return (spec.height, spec.width) if self.channels == 1 else (spec.height, spec.width, self.channels)


@cache
def output_kinds() -> dict[str, OutputKind]:
    """Name → kind, for every installed entry point of `simbot.camera_outputs` that loads as one."""
    kinds = {}
    for name, kind in load_group(GROUP).items():
        if isinstance(kind, OutputKind) and kind.name == name:
            kinds[name] = kind
        else:
            log.warning("camera output %s is no OutputKind named %r; ignored", name, name)
    return kinds


def resolve(names: Iterable[str]) -> tuple[OutputKind, ...]:
    """The kinds of `names`, each after the kinds it needs, each once; ValueError for an unknown name."""
    known = output_kinds()
    placed: dict[str, OutputKind] = {}

    def place(name: str, needed_by: tuple[str, ...]) -> None:
        if name in needed_by:
            raise ValueError(f"camera outputs {' → '.join((*needed_by, name))} need each other")
        if name in placed:
            return
        if name not in known:
            raise ValueError(f"no camera output {name!r}; known: {', '.join(sorted(known))}")
        for need in known[name].needs:
            place(need, (*needed_by, name))
        placed[name] = known[name]

    for name in names:
        place(name, ())
    return tuple(placed.values())
