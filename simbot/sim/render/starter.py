"""How render workers start: forked from a fork server that has done a worker's imports once.

A spawned worker imported PyBullet, moderngl, OpenCV, trimesh (with SciPy and NetworkX) and
simbot's render modules before it drew anything: about 1.4 s of its 2 s start on two cores.
multiprocessing's fork server imports them once (`PRELOAD`) and forks each worker from itself: a
process with one thread, no GL context and no Zenoh session, so the fork is safe where forking the
server itself (Zenoh's threads) is not.

- The fork server starts with the first pool, or sooner: `warm_up` starts it in a thread when the
  first camera enters the world, so that its imports overlap the world's loading. It lives as
  long as the process that started it.
- A forked worker inherits the fork server's environment, not the server's of the moment: the
  worker's plan carries the environment (`environment`), which the worker takes first.
- A worker's parent is the fork server: the pool watches it through multiprocessing's handle of it
  (its sentinel and exit code, which the fork server reports), never by waiting on a child.

Where there is no fork server (not POSIX), workers are spawned.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import sys
import threading
from multiprocessing.context import ForkServerContext, SpawnContext
from types import ModuleType

log = logging.getLogger(__name__)

PRELOAD = (
    "simbot.sim.render.worker",
    "simbot.sim.render.gl",
    "simbot.sim.render.tiny",
    "simbot.sim.render.publishing",
    "simbot.sim.bullet",
    "moderngl",
    "cv2",
    "trimesh",
)
"""What a worker imports. What the program's main module imports is added (`_main_imports`): a
worker runs the main module anew (multiprocessing's rule; `simbot-server`'s imports the server),
and finds it imported."""

_lock = threading.Lock()
_configured = False


def context() -> ForkServerContext | SpawnContext:
    """The fork server's context (its imports set before it first starts), or spawn's where there is none."""
    global _configured
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    forkserver = multiprocessing.get_context("forkserver")
    with _lock:
        if not _configured:
            forkserver.set_forkserver_preload([*PRELOAD, *_main_imports()])
            _configured = True
    return forkserver


def _main_imports() -> list[str]:
    """What a worker would import running the program's main module anew: the module itself where it
    was run by name (`python -m simbot.sim.server`), the modules a main script names where it was
    run by its path (`simbot-server`); none for a package's `__main__`, which a worker does not run."""
    main = sys.modules.get("__main__")
    if main is None:
        return []
    name = getattr(main.__spec__, "name", None)
    if name:
        return [] if name.endswith(".__main__") else [name]
    if getattr(main, "__file__", None) is None:
        return []
    named = {
        value.__name__ if isinstance(value, ModuleType) else getattr(value, "__module__", None)
        for value in vars(main).values()
    }
    return sorted(name for name in named if isinstance(name, str) and name in sys.modules and name != "__main__")


def warm_up() -> None:
    """Start the fork server now, in a thread, so that the first pool finds it ready."""
    context()
    if "forkserver" in multiprocessing.get_all_start_methods():
        from multiprocessing import forkserver

        threading.Thread(target=forkserver.ensure_running, name="render-fork-server", daemon=True).start()


def environment() -> dict[str, str]:
    """The environment a worker takes: this process's now (a forked worker would have the fork server's)."""
    return dict(os.environ)


def take_environment(environ: dict[str, str]) -> None:
    """In the worker, first: the server's environment in place of the fork server's."""
    if environ != os.environ:
        os.environ.clear()
        os.environ.update(environ)
