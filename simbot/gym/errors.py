"""The two ways an environment fails: the user asked for something that cannot be (`EnvConfigError`,
raised before anything starts, or by `reset` for an explicit start or goal), or its server went
away (`SimServerError`, raised from `step` and `reset`)."""

from __future__ import annotations


class EnvConfigError(ValueError):
    """A bad option: an unknown world, a camera the robot lacks, a goal inside a wall. One line naming it."""


class SimServerError(RuntimeError):
    """The environment's server died or stopped answering: the message names its command (or
    endpoint) and its exit code or the timeout that ran out."""
