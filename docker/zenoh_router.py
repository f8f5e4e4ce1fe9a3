"""The fleet's Zenoh router: a Zenoh session in router mode, configured by a JSON5 file.

The eclipse-zenoh package that simbot installs ships no `zenohd`, and Zenoh's own router image
comes from a container registry that a machine with only package indexes cannot reach; so
docker/compose.fleet.yaml runs this in simbot's image, with the same Zenoh as the servers:

    python zenoh_router.py zenoh-router.json5

It runs until SIGTERM or SIGINT, then closes its session (exit 0).
"""

from __future__ import annotations

import signal
import sys

import zenoh

STOP = {signal.SIGTERM, signal.SIGINT}


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        print("usage: zenoh_router.py CONFIG.json5", file=sys.stderr)
        return 2
    try:
        config = zenoh.Config.from_file(argv[0])
    except Exception as exc:  # zenoh raises its own ZError for a missing or malformed file
        print(f"{argv[0]}: {exc}", file=sys.stderr)
        return 2
    # Blocked before Zenoh starts its threads, so that they inherit the mask and the signal waits here.
    signal.pthread_sigmask(signal.SIG_BLOCK, STOP)
    with zenoh.open(config):
        print(
            f"zenoh router: {config.get_json('listen/endpoints')} <- {config.get_json('connect/endpoints')}", flush=True
        )
        signal.sigwait(STOP)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
