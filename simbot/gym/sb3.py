"""Stable-Baselines3 on a native vector env: its `VecEnv` API over a `SimbotVectorEnv`.

    from stable_baselines3 import PPO
    from simbot.gym.sb3 import vec_env
    envs = vec_env("simbot/Navigate-v0", num_envs=8, world="empty", physics="kinematic")
    PPO("MultiInputPolicy", envs).learn(100_000)

Stable-Baselines3 wants its own vector API (reset returns observations only; a step's `dones`; an
ended episode reset in the same step, its last observation in `info["terminal_observation"]`,
`info["TimeLimit.truncated"]` for a time limit), so the vector env runs with Gymnasium's
SAME_STEP autoreset, and this class reads its per-env infos. Needs the `learning` extra.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import gymnasium
import numpy as np
import numpy.typing as npt
from stable_baselines3.common.vec_env import VecEnv
from stable_baselines3.common.vec_env.base_vec_env import VecEnvIndices, VecEnvObs, VecEnvStepReturn

from simbot.gym.vector import SimbotVectorEnv


def vec_env(env_id: str, num_envs: int, **kwargs: Any) -> SimbotVecEnv:
    """`gymnasium.make_vec(env_id, num_envs, vectorization_mode="vector_entry_point", **kwargs)`, as SB3's VecEnv."""
    vector = gymnasium.make_vec(
        env_id, num_envs=num_envs, vectorization_mode="vector_entry_point", autoreset_mode="SameStep", **kwargs
    )
    assert isinstance(vector, SimbotVectorEnv)
    return SimbotVecEnv(vector)


class SimbotVecEnv(VecEnv):
    """See the module docstring."""

    def __init__(self, vector: SimbotVectorEnv) -> None:
        if vector.autoreset_mode is not gymnasium.vector.AutoresetMode.SAME_STEP:
            raise ValueError("SimbotVecEnv needs the vector env made with autoreset_mode='SameStep'")
        self.vector = vector
        super().__init__(vector.num_envs, vector.single_observation_space, vector.single_action_space)
        self._actions: npt.NDArray[Any] | None = None

    def reset(self) -> VecEnvObs:
        seeds = list(self._seeds) if any(seed is not None for seed in self._seeds) else None
        obs, _ = self.vector.reset(seed=seeds)
        self._reset_seeds()
        return obs

    def step_async(self, actions: npt.NDArray[Any]) -> None:
        self._actions = actions

    def step_wait(self) -> VecEnvStepReturn:
        assert self._actions is not None
        obs, rewards, terminated, truncated, infos = self.vector.step_each(self._actions)
        dones = terminated | truncated
        for i in np.flatnonzero(dones):
            info = infos[i]
            info["terminal_observation"] = info.pop("final_obs")
            info.update(info.pop("final_info"))
            info["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
        return obs, rewards.astype(np.float32), dones, infos

    def close(self) -> None:
        self.vector.close()

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        return [getattr(self.vector, attr_name) for _ in self._indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        raise NotImplementedError("the sub-envs live in simulation processes: set options when making the env")

    def env_method(self, method_name: str, *args: Any, indices: VecEnvIndices = None, **kwargs: Any) -> list[Any]:
        raise NotImplementedError("the sub-envs live in simulation processes: call the vector env instead")

    def env_is_wrapped(
        self, wrapper_class: type[gymnasium.Wrapper[Any, Any, Any, Any]], indices: VecEnvIndices = None
    ) -> list[bool]:
        return [False for _ in self._indices(indices)]

    def _indices(self, indices: VecEnvIndices) -> Iterable[int]:
        if indices is None:
            return range(self.num_envs)
        return [indices] if isinstance(indices, int) else list(indices)

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [None] * self.num_envs
