"""argparse types that every command shares: a number or a whole number within bounds, an image size.

A bad value is argparse's one-line error naming the option, and exit code 2: the server, `simbot map`,
`simbot experiment` and the client programs check their numbers alike. A leaf module (argparse and
math alone), so that every layer may import it.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from typing import TypeVar

Number = TypeVar("Number", int, float)


def number(kind: Callable[[str], Number], *, at_least_zero: bool = False, unit: str = "") -> Callable[[str], Number]:
    """A finite number > 0 (≥ 0 with `at_least_zero`) of `kind`, in `unit` where the message names one."""
    bound = ("≥ 0" if at_least_zero else "> 0") + (f" {unit}" if unit else "")

    def parse(text: str) -> Number:
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"expected a number{f' of {unit}' if unit else ''}, got {text!r}"
            ) from None
        if not math.isfinite(value) or value < 0 or (value == 0 and not at_least_zero):
            raise argparse.ArgumentTypeError(f"expected a finite number {bound}, got {text!r}")
        return value

    return parse


def whole(least: int = 1, most: int | None = None) -> Callable[[str], int]:
    """A whole number from `least` to `most` (no upper bound with None)."""
    span = f"from {least} to {most}" if most is not None else f"≥ {least}"

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a whole number {span}, got {text!r}") from None
        if value < least or (most is not None and value > most):
            raise argparse.ArgumentTypeError(f"expected a whole number {span}, got {text!r}")
        return value

    return parse


MAX_IMAGE_SIDE = 8192


def image_size(text: str) -> tuple[int, int]:
    """`WxH` in pixels, each 1..MAX_IMAGE_SIDE (a camera's `--camera-size`)."""
    parts = text.lower().split("x")
    if len(parts) != 2 or not all(p.strip().isdigit() for p in parts):
        raise argparse.ArgumentTypeError(f"expected WxH such as 320x240, got {text!r}")
    width, height = (int(p) for p in parts)
    if not (1 <= width <= MAX_IMAGE_SIDE and 1 <= height <= MAX_IMAGE_SIDE):
        raise argparse.ArgumentTypeError(f"width and height must be 1..{MAX_IMAGE_SIDE}, got {text!r}")
    return width, height
