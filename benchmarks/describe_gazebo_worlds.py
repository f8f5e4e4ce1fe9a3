"""How many of a folder of Gazebo worlds `simbot describe` accepts, among those that need no download.

    python benchmarks/describe_gazebo_worlds.py PATH/TO/gz-sim/examples/worlds

A world needs a download when any `<uri>` in it is an http(s) URL; the others are described one
by one in a subprocess (as a user runs it) with an empty Fuel cache, and each refusal is listed
with its one-line error. The README's figure is this script's first line of output.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

REMOTE_URI = re.compile(r"<uri>\s*https?://")


def main(folder: Path) -> int:
    worlds = [w for w in sorted(folder.glob("*.sdf")) if not REMOTE_URI.search(w.read_text(errors="replace"))]
    refused = []
    with tempfile.TemporaryDirectory() as empty_cache:
        env = os.environ | {"GZ_FUEL_CACHE_PATH": empty_cache}
        for world in worlds:
            result = subprocess.run(
                [sys.executable, "-m", "simbot.cli", "describe", str(world)], capture_output=True, text=True, env=env
            )
            if result.returncode != 0:
                refused.append(f"{world.name}: {(result.stderr.strip().splitlines() or ['?'])[-1]}")
    accepted = len(worlds) - len(refused)
    print(
        f"simbot describe accepts {accepted} of {len(worlds)} worlds that need no download ({100 * accepted / max(len(worlds), 1):.0f} %)"
    )
    print("\n".join(refused))
    return 0


if __name__ == "__main__":
    sys.exit(main(Path(sys.argv[1])))
