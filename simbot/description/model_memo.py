"""Results kept per model object: a fleet's thousand tugs are one `Model`, and what is derived from it
alone (its URDF, its collision triangles) is the same for each of them.

`per_model` keeps the results of a function of a model (and further hashable arguments) for the
last MODELS_KEPT calls, keyed by the model's identity: models are frozen, so the same object gives
the same result, and an equal model read again (a reset's variant) is derived again, not looked up
by a deep comparison. Results must not be changed by their callers (text, tuples, arrays kept read-only).
"""

from __future__ import annotations

import functools
from collections import OrderedDict
from collections.abc import Callable
from typing import Any, Concatenate, ParamSpec, TypeVar

from simbot.description.model import Model

MODELS_KEPT = 64
"""Calls whose results are kept (each holds its model alive)."""
P = ParamSpec("P")
R = TypeVar("R")


def per_model(function: Callable[Concatenate[Model, P], R]) -> Callable[Concatenate[Model, P], R]:
    """`function(model, ...)` computed once per model object and arguments (see the module docstring)."""
    kept: OrderedDict[tuple[Any, ...], tuple[Model, R]] = OrderedDict()

    @functools.wraps(function)
    def remembered(model: Model, *args: P.args, **kwargs: P.kwargs) -> R:
        key = (id(model), args, tuple(sorted(kwargs.items())))
        hit = kept.get(key)
        if hit is not None and hit[0] is model:
            kept.move_to_end(key)
            return hit[1]
        result = function(model, *args, **kwargs)
        kept[key] = (model, result)
        if len(kept) > MODELS_KEPT:
            kept.popitem(last=False)
        return result

    return remembered
