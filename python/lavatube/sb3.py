"""lavatube's simulator as a Stable-Baselines3 `VecEnv` (needs `stable-baselines3`).

    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecMonitor
    from lavatube.sb3 import VecEnv

    env = VecMonitor(VecEnv("configs/gym.toml"))
    PPO("MlpPolicy", env).learn(300_000)

Every env of the run is one of the VecEnv's. An episode's end carries SB3's
`terminal_observation`, `TimeLimit.truncated` (cut short, not terminal: SB3 bootstraps its
value) and `is_success` in that env's info.
"""

from typing import Any

import numpy as np
from stable_baselines3.common.vec_env.base_vec_env import VecEnv as _VecEnv

from .gym import VectorEnv


class VecEnv(_VecEnv):
    """`lavatube.gym.VectorEnv(config, **kwargs)` behind SB3's VecEnv interface."""

    def __init__(self, config=None, **kwargs):
        self.envs = VectorEnv(config, **kwargs)
        super().__init__(self.envs.num_envs, self.envs.single_observation_space,
                         self.envs.single_action_space)
        self._actions = None

    def reset(self):
        # One seed rebuilds every env (`seed(s)` gives s, s+1, …: the first is the run's).
        obs, _ = self.envs.reset(seed=self._seeds[0])
        self._reset_seeds()
        self._reset_options()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self):
        obs, rewards, terminated, truncated, info = self.envs.step(self._actions)
        dones = terminated | truncated
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        for i in np.flatnonzero(dones):
            infos[i] = {"terminal_observation": info["final_obs"][i],
                        "TimeLimit.truncated": bool(truncated[i] and not terminated[i]),
                        "is_success": bool(info["final_info"]["success"][i])}
        return obs, rewards.astype(np.float32), dones, infos

    def close(self) -> None:
        self.envs.close()

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        return [getattr(self.envs, attr_name) for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        raise AttributeError(f"lavatube's envs live in the sim process; cannot set {attr_name}")

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs):
        raise AttributeError(f"lavatube's envs live in the sim process; no {method_name}()")

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]
