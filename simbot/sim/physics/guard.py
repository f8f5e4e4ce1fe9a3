"""The read-only guard: methods that change the world refuse while post-update systems run."""

from __future__ import annotations

from collections.abc import Callable
from functools import wraps
from typing import Concatenate, ParamSpec, Protocol, TypeVar


class PhysicsReadOnly(RuntimeError):
    """A system changed the world where it may only read it (in post_update, as Gazebo's PostUpdate)."""


class Guarded(Protocol):
    read_only: bool
    """True while post-update systems run: they read the step's result and change nothing."""


S = TypeVar("S", bound=Guarded)
P = ParamSpec("P")
R = TypeVar("R")


def changes_world(method: Callable[Concatenate[S, P], R]) -> Callable[Concatenate[S, P], R]:
    """Marks a method that changes the world: refused while the physics is read-only."""

    @wraps(method)
    def guarded(self: S, *args: P.args, **kwargs: P.kwargs) -> R:
        if self.read_only:
            raise PhysicsReadOnly(f"Physics.{method.__name__}: the physics is read-only after the step (post_update)")
        return method(self, *args, **kwargs)

    return guarded
