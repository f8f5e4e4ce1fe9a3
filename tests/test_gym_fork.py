"""Gymnasium's own async vector env after the program has used an env (issue 46, item 2).

Gymnasium's documented flow: `check_env` on an env, then `make_vec(..., vectorization_mode="async")`
in the same script, with envs on the bus (`watch=True`: an env off the bus opens no Zenoh session). Its workers were forked after the parent's Zenoh threads started and hung
forever opening their own sessions. Each case runs that script as a user does, in a process of
its own: with Gymnasium's defaults it works, and the sub-envs draw the episodes that a single env
with their seeds draws; with `context="fork"` asked for by name, the workers fail at once with
one line naming the fix; and a parent killed with SIGKILL leaves none of its workers, keepers or
servers behind.
"""

from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import sys
from typing import cast

from server_helpers import alive, descendants, wait_until

REPORT_TIMEOUT_S = 240.0
"""Three servers start and stop in the script before it reports (17 s here, alone); a hang never reports."""
SCRIPT = """
import json, signal, sys, time
import gymnasium
import numpy as np
import simbot.gym
from gymnasium.utils.env_checker import check_env

KWARGS = dict(world="empty", max_linear=1.0, max_angular=1.0, watch=True)
env = gymnasium.make("simbot/Navigate-v0", **KWARGS)
check_env(env.unwrapped)
single = {seed: env.reset(seed=seed)[0] for seed in (3, 4)}
env.close()
vector_kwargs = json.loads(sys.argv[1])
envs = gymnasium.make_vec("simbot/Navigate-v0", num_envs=2, vectorization_mode="async", vector_kwargs=vector_kwargs, **KWARGS)
asked = time.monotonic()
try:
    observations, _ = envs.reset(seed=3)
except Exception as exc:
    print(json.dumps({"error": str(exc).splitlines()[0], "after_s": time.monotonic() - asked}), flush=True)
    raise SystemExit(3)
same = [all(np.array_equal(observations[k][i], single[seed][k]) for k in single[seed]) for i, seed in enumerate((3, 4))]
print(json.dumps({"same": same, "pids": [p.pid for p in envs.processes]}), flush=True)
signal.pause()  # until the test kills it
"""


def _script(vector_kwargs: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-c", SCRIPT, vector_kwargs], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )


def _report(process: subprocess.Popen[str]) -> dict[str, object]:
    """The script's one line of JSON (its stderr's end in the failure otherwise)."""
    assert process.stdout is not None and process.stderr is not None
    ready, _, _ = select.select([process.stdout], [], [], REPORT_TIMEOUT_S)
    if not ready:  # the hang this file is about: say so rather than wait for ever
        process.kill()
        raise AssertionError(f"no report within {REPORT_TIMEOUT_S:g} s: {process.communicate()[1][-3000:]}")
    line = process.stdout.readline()
    if not line:
        process.wait(30)
        raise AssertionError(f"the script printed nothing (exit {process.returncode}): {process.stderr.read()[-3000:]}")
    report: dict[str, object] = json.loads(line)
    return report


def test_a_forked_worker_fails_at_once_naming_the_fix() -> None:
    """`context="fork"` by name: the reset fails with the one line that names 'spawn', before any server starts."""
    process = _script('{"context": "fork"}')
    try:
        report = _report(process)
        assert "spawn" in str(report.get("error")) and "forked" in str(report.get("error")), report
        print(f"the forked workers' reset failed after {report['after_s']:.3f} s")
        assert process.wait(120) == 3
    finally:
        process.kill()
        process.wait()


def test_an_async_vector_env_after_check_env_just_works_and_dies_with_its_parent() -> None:
    """Gymnasium's defaults after the parent used an env: the sub-envs seeded 3 and 4 give the very
    first observations a single env with those seeds gives. Then SIGKILL to the parent: its workers
    read the end of their pipes and close their envs, and the keepers end the servers; every
    process it had started is gone."""
    process = _script("{}")
    try:
        report = _report(process)
        assert report.get("same") == [True, True], report
        left = descendants(process.pid)
        workers = set(cast("list[int]", report["pids"]))
        assert workers <= left and len(left) >= 3 * len(workers), f"workers {workers}, processes {left}"
        os.kill(process.pid, signal.SIGKILL)
        process.wait()
        wait_until(lambda: not alive(left), 60.0, f"the processes {sorted(left)} to end")
    finally:
        process.kill()
        process.wait()
