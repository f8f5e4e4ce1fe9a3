"""Inputs converted to what the CDR serializer expects: Python floats, float64 numpy arrays.

Every constructor checks its sizes here, so that a wrong-length pose or covariance fails where it
is built with a one-line message, not deep in the serializer.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

Floats = Sequence[float] | npt.NDArray[np.floating[Any]]


def three(values: Floats, what: str) -> tuple[float, float, float]:
    """Exactly three floats (a point, a vector)."""
    x, y, z = floats(values, 3, what)
    return x, y, z


def floats(values: Floats, size: int, what: str) -> list[float]:
    """Exactly `size` Python floats."""
    result = [float(v) for v in values]
    if len(result) != size:
        raise ValueError(f"{what}: expected {size} values, got {len(result)}")
    return result


def float_array(values: Floats, what: str, size: int | None = None) -> npt.NDArray[np.float64]:
    """A flat float64 array (a covariance, joint values), of `size` values when given."""
    array = np.ascontiguousarray(values, dtype=np.float64).reshape(-1)
    if size is not None and array.size != size:
        raise ValueError(f"{what}: expected {size} values, got {array.size}")
    return array


def diagonal(variances: Floats) -> npt.NDArray[np.float64]:
    """A 3×3 row-major covariance with the three variances on its diagonal."""
    return np.diag(float_array(variances, "variances", 3)).reshape(-1)
