"""simbot for reinforcement learning: Gymnasium environments of the Flexley Tug in simbot's worlds.

`import simbot.gym` registers `simbot/Navigate-v0` (drive to a goal pose, `simbot.gym.navigate`)
and `simbot/Dock-v0` (drive under the trolley and attach, `simbot.gym.dock`) with Gymnasium:

    import gymnasium, simbot.gym
    env = gymnasium.make("simbot/Navigate-v0", world="empty", control_period=0.1)

Each environment steps its world in its own process, off the bus (simbot.gym.local); with
`watch=True` (or a camera not rendered in process) it starts its own lockstep server in a
subprocess (or uses one given by `endpoint=`) and ends it on `close()`.
`gymnasium.make_vec(id, num_envs=N, vectorization_mode="vector_entry_point")` steps N at a time
(simbot.gym.vector). docs/learning.md describes the spaces, rewards, options and the choices
behind them. Needs the `gym` extra (`pip install 'simbot[gym]'`: Gymnasium).
"""

from __future__ import annotations

import gymnasium

from simbot.gym.errors import EnvConfigError, SimServerError

NAVIGATE = "simbot/Navigate-v0"
DOCK = "simbot/Dock-v0"
ENVIRONMENTS = {
    NAVIGATE: "simbot.gym.navigate:NavigateEnv",
    DOCK: "simbot.gym.dock:DockEnv",
}
VECTOR_ENVIRONMENTS = {
    NAVIGATE: "simbot.gym.vector:NavigateVectorEnv",
    DOCK: "simbot.gym.vector:DockVectorEnv",
}

__all__ = ["DOCK", "ENVIRONMENTS", "VECTOR_ENVIRONMENTS", "NAVIGATE", "EnvConfigError", "SimServerError", "register"]


def register() -> None:
    """Registers simbot's environments with Gymnasium (again is harmless: a module may be re-imported)."""
    for env_id, entry_point in ENVIRONMENTS.items():
        if env_id not in gymnasium.registry:
            gymnasium.register(
                id=env_id,
                entry_point=entry_point,
                vector_entry_point=VECTOR_ENVIRONMENTS[env_id],
                disable_env_checker=False,
            )


register()
