"""ResidualWeightEnv: the fusion expert flies, and the agent's action rescales its evaluation weights.

The paper names the expert's fixed weights as its weakness. Here every UAV's action is a bounded
adjustment of the seven weights (DWA alpha0, beta, gamma, eps0; 3D VFH+ k1, k2, k3): weight ``i`` in
use is ``default_i * max_factor ** a_i`` with ``a_i`` in [-1, 1]. A zero action is a factor of exactly
1.0, so it reproduces the expert bit for bit. The observation is the inner observation followed by
the weights in use, encoded as their action (``log(w / default) / log(max_factor)``), in [-1, 1].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from gymnasium import spaces
from pettingzoo.utils import BaseParallelWrapper

from baselines.expert import WEIGHT_NAMES, ExpertConfig, FusionExpert
from baselines.policy import check_flyable
from uavform_env.actions import check_actions
from uavform_env.config import Config, check_choice, check_range

N_WEIGHTS = len(WEIGHT_NAMES)
REWARD_MODES = ("team", "own")


@dataclass(frozen=True)
class ResidualConfig(Config):
    """How far the residual policy may move the expert's weights.

    max_factor  each weight is scaled by a factor in [1 / max_factor, max_factor]
    reward      "team": every UAV gets the mean reward of the live UAVs; "own": the inner env's per-UAV reward.
                The leader's own reward has no formation term, so with "own" a shared policy learns to rush
                the leader (progress) while the followers pay for it; "team" makes that cost everyone's [X]
    """

    max_factor: float = 4.0
    reward: str = "team"

    def __post_init__(self):
        check_range("ResidualConfig", "max_factor", self.max_factor, 1.0, 1e3, lo_open=True)
        check_choice("ResidualConfig", "reward", self.reward, REWARD_MODES)


class WeightAdjuster:
    """The action <-> weights mapping, shared by the training wrapper and the trained-policy object."""

    def __init__(self, expert_config: ExpertConfig, residual: ResidualConfig):
        self.defaults = expert_config.weights()
        self.max_factor = float(residual.max_factor)

    def weights(self, action: np.ndarray) -> np.ndarray:
        """Weights in use for a checked action; a zero action gives the defaults exactly."""
        return self.defaults * np.power(self.max_factor, action)

    @staticmethod
    def observe(inner_obs: np.ndarray, action: np.ndarray) -> np.ndarray:
        """The inner observation followed by the weights in use (encoded as the action that set them)."""
        return np.concatenate([inner_obs, action]).astype(np.float32)


class ResidualWeightEnv(BaseParallelWrapper):
    """A ParallelEnv with the inner env's agents; each action adjusts that UAV's expert weights.

    Args:
        env: a ``FormationEnv`` (e.g. ``uavform_env.parallel_env(...)``) or a wrapper of one.
        expert_config: the expert's configuration; its weights are the zero-action defaults.
        residual: ``ResidualConfig`` (the bound of the adjustment).
    """

    def __init__(self, env, expert_config: ExpertConfig | None = None, residual: ResidualConfig | None = None):
        super().__init__(env)
        check_flyable(env)
        self.expert_config = expert_config if expert_config is not None else ExpertConfig()
        self.residual = residual if residual is not None else ResidualConfig()
        for name, value, cls in (("expert_config", self.expert_config, ExpertConfig),
                                 ("residual", self.residual, ResidualConfig)):
            if not isinstance(value, cls):
                raise ValueError(f"{name}: expected a {cls.__name__}, got {type(value).__name__}")
        self.adjuster = WeightAdjuster(self.expert_config, self.residual)
        self.expert = FusionExpert(self.expert_config)
        inner = env.observation_space(env.possible_agents[0])
        obs_space = spaces.Box(np.concatenate([inner.low, np.full(N_WEIGHTS, -1.0, np.float32)]),
                               np.concatenate([inner.high, np.full(N_WEIGHTS, 1.0, np.float32)]), dtype=np.float32)
        act_space = spaces.Box(-1.0, 1.0, (N_WEIGHTS,), np.float32)
        self.observation_spaces = {a: obs_space for a in env.possible_agents}
        self.action_spaces = {a: act_space for a in env.possible_agents}
        self.metadata = dict(env.metadata, name="formation_residual_v0")
        self._in_use: dict[str, np.ndarray] = {}
        self._inner_obs: dict = {}

    def observation_space(self, agent):
        return self.observation_spaces[agent]

    def action_space(self, agent):
        return self.action_spaces[agent]

    @property
    def weights_in_use(self) -> dict[str, np.ndarray]:
        """{agent: the seven weights the expert flew with at the last step}."""
        return {a: self.adjuster.weights(act) for a, act in self._in_use.items()}

    def reset(self, seed=None, options=None):
        obs, infos = self.env.reset(seed=seed, options=options)
        self.expert.reset(self.env, seed)
        self._in_use = {a: np.zeros(N_WEIGHTS) for a in self.env.possible_agents}
        self._inner_obs = obs
        self.agents = list(self.env.agents)
        return {a: self.adjuster.observe(o, self._in_use[a]) for a, o in obs.items()}, infos

    def step(self, actions):
        checked = check_actions(actions, self.possible_agents, self.env.agents, N_WEIGHTS,
                                f"one adjustment per weight {WEIGHT_NAMES}")
        self._in_use.update(checked)
        weights = {a: self.adjuster.weights(act) for a, act in checked.items()}
        flight = self.expert.act(self._inner_obs, self.env, weights=weights)
        obs, rewards, terms, truncs, infos = self.env.step(flight)
        if self.residual.reward == "team" and rewards:
            team = float(np.mean(list(rewards.values())))
            rewards = {a: team for a in rewards}
        self._inner_obs = obs
        self.agents = list(self.env.agents)
        return ({a: self.adjuster.observe(o, self._in_use[a]) for a, o in obs.items()},
                rewards, terms, truncs, infos)
