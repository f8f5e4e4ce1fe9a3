"""Wide-angle cameras as camera outputs: the cube faces a renderer draws (`wide_faces`, posed by
`views`), remapped into the image (`wide_color`, `wide_mono`); the lens and the remap tables are
in `wide_lens.py`."""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping

import cv2
import numpy as np

from simbot.sim.render.kinds import Array, Finish, Optics, OutputKind, Raw
from simbot.sim.render.outputs import add_noise, luminance
from simbot.sim.render.specs import CameraSpec
from simbot.sim.render.wide_lens import FACES, OPTICAL_IN_CAMERA, Plan, WideLens, plan
from simbot.transform import Transform, matmul, matrix_to_quaternion, quaternion_to_matrix


def _plan_of(spec: Optics) -> tuple[WideLens, Plan]:
    if not isinstance(spec, CameraSpec) or spec.wide is None:
        raise ValueError(f"a wide-angle output needs a camera with a wide-angle lens, got {spec!r}")
    return spec.wide, plan(spec.wide, spec.width, spec.height, spec.hfov)


class FacesKind(OutputKind):
    """The raw faces: each drawn face of `lens.face` pixels a side, one below the other."""

    def shape(self, spec: Optics) -> tuple[int, ...]:
        lens, drawn = _plan_of(spec)
        return (len(drawn.faces) * lens.face, lens.face, 3)


def _remap(spec: Optics) -> Callable[[Mapping[str, Array], Array], None]:
    """The camera's remap of its faces into an rgb image."""
    _, drawn = _plan_of(spec)

    def remap(arrays: Mapping[str, Array], out: Array) -> None:
        cv2.remap(arrays["wide_faces"], drawn.map1, drawn.map2, cv2.INTER_LINEAR, dst=out, borderValue=0)

    return remap


def _noise(spec: Optics) -> Callable[[Array], None]:
    """The camera's seeded pixel noise, after the lens as on a real sensor."""
    rng = np.random.default_rng(spec.seed)

    def noise(pixels: Array) -> None:
        if spec.noise_stddev > 0.0:
            add_noise(pixels, spec.noise_stddev, rng)

    return noise


def color(spec: Optics) -> Finish:
    """The faces remapped into the image, then the camera's pixel noise."""
    remap, noise = _remap(spec), _noise(spec)

    def finish(image: Array, arrays: Mapping[str, Array]) -> None:
        remap(arrays, image)
        noise(image)

    return finish


def mono(spec: Optics) -> Finish:
    """As `color`, then to luminance (the faces are drawn in colour)."""
    remap, noise = _remap(spec), _noise(spec)
    rgb = np.empty((spec.height, spec.width, 3), dtype=np.uint8)

    def finish(image: Array, arrays: Mapping[str, Array]) -> None:
        remap(arrays, rgb)
        image[...] = luminance(rgb)
        noise(image)

    return finish


WIDE_FACES = FacesKind("wide_faces", np.uint8, 3, draws="color")
WIDE_COLOR = OutputKind("wide_color", np.uint8, 3, encoding="rgb8", needs=("wide_faces",), finisher=color)
WIDE_MONO = OutputKind("wide_mono", np.uint8, 1, encoding="mono8", needs=("wide_faces",), finisher=mono)


def views(
    spec: CameraSpec, pose: Transform, drawn: Mapping[Raw, Array]
) -> Iterator[tuple[Transform, dict[Raw, Array]]]:
    """What a renderer draws for a camera at `pose`: the pose and its buffers once for a pinhole
    camera; each face's pose and its slice of the raw faces for a wide-angle one (`spec.rendered`
    is the face's camera)."""
    if spec.wide is None:
        yield pose, dict(drawn)
        return
    lens, drawn_plan = spec.wide, plan(spec.wide, spec.width, spec.height, spec.hfov)
    faces = drawn["color"].reshape(len(drawn_plan.faces), lens.face, lens.face, 3)
    body = quaternion_to_matrix(pose.orientation)
    for slot, index in enumerate(drawn_plan.faces):
        rotation = matmul(matmul(matmul(body, OPTICAL_IN_CAMERA), FACES[index]), OPTICAL_IN_CAMERA.T)
        yield Transform(pose.position, matrix_to_quaternion(rotation)), {"color": faces[slot]}
