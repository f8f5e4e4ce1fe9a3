"""The render pool's worker processes (`pool.py`): each started with its plan (forked from the fork
server, `starter.py`), awaited until it has loaded the scene, watched, and stopped.

A worker's parent may be the fork server, not this process: it is watched through
multiprocessing's handle of it (its sentinel and exit code), never by waiting on a child."""

from __future__ import annotations

import contextlib
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from multiprocessing.connection import Connection, wait
from multiprocessing.process import BaseProcess

from simbot.sim.render import starter
from simbot.sim.render.pipe import Ready, StartError, Stop
from simbot.sim.render.worker import WorkerPlan, worker_main

STOP_GRACE_S = 0.5
"""How long stopping lets a worker finish its current frame before terminating it."""


@dataclass
class Worker:
    """A worker process as the pool sees it."""

    index: int
    process: BaseProcess
    conn: Connection
    cameras: list[int]
    death: str | None = None
    """Why it is gone, once it is."""
    edits: int = 0
    """Scene edits sent to it and not yet answered: a death while one is open is a death during an edit."""

    @property
    def alive(self) -> bool:
        return self.death is None and self.process.is_alive()


def launch(index: int, plan: WorkerPlan) -> tuple[BaseProcess, Connection]:
    """A worker process started on `plan`, and the pool's end of its pipe."""
    ctx = starter.context()
    parent_end, child_end = ctx.Pipe()
    process = ctx.Process(target=worker_main, args=(child_end, plan), name=f"simbot-render-{index}", daemon=True)
    process.start()
    child_end.close()  # so that the worker's death reads as EOF here
    return process, parent_end


def await_ready(workers: Sequence[Worker], timeout: float, cameras: Mapping[int, str]) -> list[Ready]:
    """Each worker's ready message; RuntimeError naming it when one fails, dies or takes too long
    (`cameras`: each worker's camera names, for the message)."""
    deadline = time.monotonic() + timeout
    ready: dict[int, Ready] = {}
    while len(ready) < len(workers):
        waiting = [w for w in workers if w.index not in ready]
        left = deadline - time.monotonic()
        if left <= 0:
            names = ", ".join(cameras[w.index] for w in waiting)
            raise RuntimeError(f"render workers did not load the scene within {timeout:.0f} s (cameras {names})")
        wait([h for w in waiting for h in (w.conn, w.process.sentinel)], left)
        for worker in waiting:
            message = _poll_start(worker, cameras[worker.index])
            if message is not None:
                ready[worker.index] = message
    return [ready[w.index] for w in workers]


def _poll_start(worker: Worker, cameras: str) -> Ready | None:
    try:
        if not worker.conn.poll():
            if worker.process.is_alive():
                return None
            raise EOFError
        message = worker.conn.recv()
    except (EOFError, OSError):
        raise RuntimeError(f"render {death(worker, cameras)} while loading the scene") from None
    if isinstance(message, StartError):
        raise RuntimeError(f"render worker {worker.index} failed to start: {message.reason}")
    assert isinstance(message, Ready), message  # a worker's first message is one of the two
    return message


def death(worker: Worker, cameras: str) -> str:
    """Why the worker is gone, in one line naming it and its cameras (its exit, once reported)."""
    worker.process.join(1.0)
    code = worker.process.exitcode
    how = f"killed by signal {-code}" if code is not None and code < 0 else f"exit code {code}"
    return f"render worker {worker.index} (pid {worker.process.pid}) died ({how}); its cameras: {cameras}"


def stop(workers: Sequence[Worker]) -> None:
    """Ask politely, give a frame's time, then terminate, then kill: every worker at each stage
    together, so that stopping takes the same time however many workers there are."""
    for worker in workers:
        with contextlib.suppress(OSError):  # a dead worker's pipe: it is stopped already
            worker.conn.send(Stop())
    _join_all(workers, STOP_GRACE_S)
    for stage, seconds in ((BaseProcess.terminate, 1.0), (BaseProcess.kill, None)):
        alive = [worker for worker in workers if worker.process.is_alive()]
        for worker in alive:
            stage(worker.process)
        _join_all(alive, seconds)
    for worker in workers:
        worker.conn.close()


def _join_all(workers: Sequence[Worker], seconds: float | None) -> None:
    """Waits for the workers to end, `seconds` for all of them together (None: as long as it takes)."""
    deadline = None if seconds is None else time.monotonic() + seconds
    for worker in workers:
        worker.process.join(None if deadline is None else max(0.0, deadline - time.monotonic()))
