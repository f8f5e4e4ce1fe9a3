"""Zenoh and fork: a process forked after its Zenoh session started is told so, not left to hang.

Zenoh's runtime threads do not survive a fork: a session opened in the child seems to open, then
hangs at its first use (Gymnasium's `AsyncVectorEnv` forking its workers after the program used an
env hung this way for ever). The first session of a process registers a fork handler; a child
forked from then on raises `ForkedSessionError` when it asks for a session, before Zenoh is
touched. `Node` checks it; so does whatever starts processes before it opens its session.
"""

from __future__ import annotations

import os


class ForkedSessionError(RuntimeError):
    """A session asked for in a process forked from one whose Zenoh had started: Zenoh's threads do
    not survive a fork, so the child's session would hang at its first use. str() is the one line
    that says what to do instead."""


FORK_ADVICE = (
    "this process was forked from one whose Zenoh session had started, and Zenoh's threads do not survive "
    "a fork: start it with the 'spawn' method (multiprocessing.get_context('spawn'); for Gymnasium, "
    "make_vec(..., vector_kwargs={'context': 'spawn'}))"
)
_zenoh_started = False
"""Whether this process has opened a Zenoh session (its runtime threads run from then on)."""
_forked_after_zenoh = False
"""Whether this process was forked from one where `_zenoh_started` was true."""


def _note_forked() -> None:
    global _forked_after_zenoh
    _forked_after_zenoh = True


def check_fork_safe() -> None:
    """ForkedSessionError when this process may not open a Zenoh session (see its docstring)."""
    if _forked_after_zenoh:
        raise ForkedSessionError(FORK_ADVICE)


def zenoh_starts() -> None:
    """The first session of the process: a child forked from now on is told, not left to hang."""
    global _zenoh_started
    if not _zenoh_started:
        _zenoh_started = True
        os.register_at_fork(after_in_child=_note_forked)
