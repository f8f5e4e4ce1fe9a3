"""A latched message that may be large (the scene, the map), put on the bus from a thread of its own."""

from __future__ import annotations

import threading
from typing import Any

from simbot.bus import Publisher


class LatestSender:
    """Puts the newest message handed to it on a thread of its own: encoding a large scene never
    holds up the loop, and a message superseded before it went is never sent. In lockstep it puts
    each at once, in its step, as every message of lockstep goes (a seeded run sends the same)."""

    def __init__(self, publisher: Publisher, at_once: bool = False) -> None:
        self._publisher = publisher
        self._at_once = at_once
        self._pending: Any = None
        self._wake = threading.Condition()
        self._closed = False
        self._thread = threading.Thread(target=self._run, name="scene-sender", daemon=True)
        self._thread.start()

    def send(self, msg: Any) -> None:
        if self._at_once:
            self._publisher.put(msg)
            return
        with self._wake:
            self._pending = msg
            self._wake.notify()

    def _run(self) -> None:
        while True:
            with self._wake:
                self._wake.wait_for(lambda: self._pending is not None or self._closed)
                if self._closed:
                    return
                msg, self._pending = self._pending, None
            self._publisher.put(msg)

    def close(self) -> None:
        with self._wake:
            self._closed = True
            self._wake.notify()
        self._thread.join()
        self._publisher.close()
