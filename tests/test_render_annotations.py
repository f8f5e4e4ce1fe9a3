"""Labels and temperatures as both renderers draw them (`label_bits.py`, the `labels` and
`temperature` outputs): what segmentation, bounding-box and thermal cameras are made from."""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import pytest
from gl_helpers import NO_EGL, box_body

from simbot.sim.render import Annotation, CameraSpec, Light, RenderPool, SceneBody
from simbot.sim.render.label_bits import instance_of, label_of, labelled
from simbot.transform import Transform

W, H, HFOV = 160, 120, math.radians(90.0)
FX = (W / 2) / math.tan(HFOV / 2)
GREY = (0.5, 0.5, 0.5, 1.0)
AMBIENT_K, GRADIENT = 300.0, -0.5
"""A steep lapse, so that the atmosphere's temperature visibly changes over a box's height."""


def at(x: float, y: float, z: float = 0.0) -> Transform:
    return Transform((x, y, z), (0.0, 0.0, 0.0, 1.0))


def bodies() -> list[SceneBody]:
    """Two crates of label 7 side by side 4 m ahead, a hot unlabelled block before the left one's
    inner half, and a cool floor-to-ceiling wall behind, unannotated."""
    whole = (Annotation(label=7),)
    return [
        box_body("crate_a", (0.2, 1.0, 1.0), GREY, True, at(4.1, 0.8), whole, instance=3),
        box_body("crate_b", (0.2, 1.0, 1.0), GREY, True, at(4.1, -0.8), whole, instance=4),
        box_body("stove", (0.2, 0.4, 0.4), GREY, True, at(2.1, 0.3), (Annotation(temperature=350.0),), 5),
        box_body("wall", (0.2, 20.0, 2.0), GREY, True, at(8.1, 0.0, 0.0), (), 6),
    ]


def column(y: float, depth: float) -> int:
    """The image column of a point `y` left of the axis at `depth` ahead (x right in the image)."""
    return round((W - 1) / 2 - FX * y / depth)


def row(z: float, depth: float) -> int:
    return round((H - 1) / 2 - FX * z / depth)


@pytest.fixture(scope="module", params=["gl", "tiny"])
def frame(request: pytest.FixtureRequest) -> Iterator[dict[str, np.ndarray]]:
    if request.param == "gl" and NO_EGL:
        pytest.skip(NO_EGL)
    camera = CameraSpec("annotated", W, H, HFOV, 0.05, 50.0, outputs=("labels", "temperature"))
    light = Light(ambient_temperature=AMBIENT_K, temperature_gradient=GRADIENT)
    with RenderPool(bodies(), [camera], workers=1, renderer=str(request.param), light=light) as pool:
        pool.request(0, 1, at(0.0, 0.0), {})
        (done,) = pool.collect(wait_for=0, timeout=120.0)
        yield {name: array.copy() for name, array in done.items()} | {"renderer": request.param}


def test_labelled_crates_show_their_label_and_an_instance_each(frame: dict[str, np.ndarray]) -> None:
    packed = frame["labels"]
    assert packed.shape == (H, W) and packed.dtype == np.uint32
    mid = row(0.0, 4.0)
    left, right = packed[mid, column(1.2, 4.0)], packed[mid, column(-0.8, 4.0)]
    assert labelled(left) and labelled(right)
    assert label_of(left) == label_of(right) == 7
    assert (int(instance_of(left)), int(instance_of(right))) == (3, 4)


def test_unlabelled_geometry_hides_what_lies_behind_it(frame: dict[str, np.ndarray]) -> None:
    """The stove (no label) stands before crate_a: its pixels are unlabelled, with its own instance."""
    stove = frame["labels"][row(0.0, 2.0), column(0.3, 2.0)]
    assert not labelled(stove) and instance_of(stove) == 5


def test_the_sky_is_nothing(frame: dict[str, np.ndarray]) -> None:
    top = frame["labels"][0, W // 2]  # above the 2 m wall 8 m ahead: sky
    assert top == 0 and frame["temperature"][0, W // 2] == 0.0


def test_temperatures_are_the_thermal_systems_else_the_atmospheres_at_that_height(frame: dict[str, np.ndarray]) -> None:
    kelvin = frame["temperature"]
    assert kelvin[row(0.0, 2.0), column(0.3, 2.0)] == pytest.approx(350.0)
    z = 0.6  # a point of the wall 8 m ahead, 0.6 m up
    wall = kelvin[row(z, 8.0), column(0.0, 8.0)]
    expected = AMBIENT_K + GRADIENT * (z if frame["renderer"] == "gl" else 0.0)  # TinyRenderer: at z = 0
    assert wall == pytest.approx(expected, abs=abs(GRADIENT) * 8.0 / FX * 2)
