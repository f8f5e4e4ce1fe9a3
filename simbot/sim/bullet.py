"""PyBullet, imported without the build-time banner it prints on stderr: a CLI's stderr is for errors."""

from __future__ import annotations

import os
import sys
from types import ModuleType


def _import_quietly() -> ModuleType:
    sys.stderr.flush()
    saved, devnull = os.dup(2), os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 2)
        import pybullet

        return pybullet
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(devnull)


pb = _import_quietly()
