"""PyBullet, imported without the build-time banner it prints on stderr: a CLI's stderr is for errors;
and `quiet`, for its calls that print from C (loading with merged links reports each merge on stdout)."""

from __future__ import annotations

import os
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from types import ModuleType


@contextmanager
def quiet(*fds: int) -> Iterator[None]:
    """What C code writes on the file descriptors `fds` goes nowhere for the duration."""
    sys.stdout.flush()
    sys.stderr.flush()
    devnull = os.open(os.devnull, os.O_WRONLY)
    saved = [os.dup(fd) for fd in fds]
    try:
        for fd in fds:
            os.dup2(devnull, fd)
        yield
    finally:
        for fd, copy in zip(fds, saved):
            os.dup2(copy, fd)
            os.close(copy)
        os.close(devnull)


def _import_quietly() -> ModuleType:
    with quiet(2):
        import pybullet

        return pybullet


pb = _import_quietly()
