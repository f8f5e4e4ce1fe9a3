"""The fleet's Zenoh router: a Zenoh session in router mode, configured by a JSON5 file.

The eclipse-zenoh package that simbot installs ships no `zenohd`, and Zenoh's own router image
comes from a container registry that a machine with only package indexes cannot reach; so
docker/compose.fleet.yaml runs this in simbot's image, with the same Zenoh as the servers:

    python zenoh_router.py zenoh-router.json5 [--listen EP ...] [--connect EP ...]

`--listen` and `--connect` replace the file's endpoints (the fleet test runs it on fresh loopback
ports). It runs until SIGTERM or SIGINT, then closes its session (exit 0).
"""

from __future__ import annotations

import argparse
import json
import signal
import sys

import zenoh

STOP = {signal.SIGTERM, signal.SIGINT}


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="zenoh_router.py", description="A Zenoh router configured by a JSON5 file.")
    parser.add_argument("config", help="the router's JSON5 configuration")
    parser.add_argument("--listen", nargs="+", metavar="EP", help="endpoints to listen on, instead of the file's")
    parser.add_argument("--connect", nargs="+", metavar="EP", help="endpoints to connect to, instead of the file's")
    args = parser.parse_args(argv)
    try:
        config = zenoh.Config.from_file(args.config)
        for key, endpoints in (("listen/endpoints", args.listen), ("connect/endpoints", args.connect)):
            if endpoints:
                config.insert_json5(key, json.dumps(endpoints))
    except Exception as exc:  # zenoh raises its own ZError for a missing or malformed file or endpoint
        print(f"zenoh_router.py: error: {args.config}: {exc}", file=sys.stderr)
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
