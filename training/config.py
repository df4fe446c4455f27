"""TrainConfig: every setting of a residual-policy training run, validated before anything starts."""

from __future__ import annotations

from dataclasses import dataclass

from uavform_env.config import Config, check_choice, check_int, check_range
from uavform_env.scenarios import list_scenarios

from .residual import ResidualConfig


@dataclass(frozen=True)
class TrainConfig(Config):
    """Everything a training run depends on; checked before any training starts.

    scenario, n_uavs, max_cycles   the training (and evaluation) missions
    timesteps                      agent-steps in total (each UAV-step is one sample of the shared policy)
    n_envs                         env copies, each in its own process when > 1
    n_steps, batch_size, n_epochs, learning_rate, gamma, gae_lambda, clip_range, ent_coef, log_std_init,
    net_arch                       PPO's hyperparameters (n_steps per row: a rollout holds
                                   n_steps * n_envs * n_uavs samples)
    max_factor, reward             the residual bound and the reward mode (ResidualConfig)
    seed                           seeds PPO, the network and the training episodes (seed, seed + 1, ...)
    zero_init                      start from the expert exactly: the action layer's weights and bias are zero,
                                   so the deterministic policy adjusts nothing until training moves it; the
                                   evaluation at step 0 is then the expert's score, and best.zip only replaces
                                   it with a policy that ranks higher on the held-out seeds
    eval_every, eval_seeds         evaluate the deterministic policy every eval_every agent-steps on these
                                   held-out episode seeds; the best by the leaderboard's ranking is kept
    """

    scenario: str = "forest"
    n_uavs: int = 5
    max_cycles: int = 1500
    timesteps: int = 200_000
    n_envs: int = 2
    n_steps: int = 256
    batch_size: int = 640
    n_epochs: int = 5
    learning_rate: float = 3e-4
    gamma: float = 0.99
    gae_lambda: float = 0.95
    clip_range: float = 0.2
    ent_coef: float = 0.0
    log_std_init: float = -1.0
    net_arch: tuple = (128, 128)
    max_factor: float = 4.0
    reward: str = "team"
    zero_init: bool = True
    seed: int = 1000
    eval_every: int = 50_000
    eval_seeds: tuple = (500, 501, 502, 503)

    def __post_init__(self):
        name = "TrainConfig"
        check_choice(name, "scenario", self.scenario, tuple(list_scenarios()))
        check_int(name, "n_uavs", self.n_uavs, 1, 20)
        check_int(name, "max_cycles", self.max_cycles, 10)
        check_int(name, "timesteps", self.timesteps, 1)
        check_int(name, "n_envs", self.n_envs, 1, 64)
        check_int(name, "n_steps", self.n_steps, 2)
        check_int(name, "batch_size", self.batch_size, 2)
        check_int(name, "n_epochs", self.n_epochs, 1)
        check_range(name, "learning_rate", self.learning_rate, 0.0, 1.0, lo_open=True)
        check_range(name, "gamma", self.gamma, 0.0, 1.0, lo_open=True)
        check_range(name, "gae_lambda", self.gae_lambda, 0.0, 1.0)
        check_range(name, "clip_range", self.clip_range, 0.0, 1.0, lo_open=True)
        check_range(name, "ent_coef", self.ent_coef, 0.0, 1.0)
        check_range(name, "log_std_init", self.log_std_init, -5.0, 2.0)
        if not self.net_arch or not all(isinstance(n, int) and not isinstance(n, bool) and n > 0 for n in self.net_arch):
            raise ValueError(f"{name}.net_arch={self.net_arch!r}: expected a non-empty list of positive layer sizes")
        self.residual()
        if not isinstance(self.zero_init, bool):
            raise ValueError(f"{name}.zero_init={self.zero_init!r}: expected true or false")
        check_int(name, "seed", self.seed, 0, 2**31 - 1)
        check_int(name, "eval_every", self.eval_every, 1)
        if not self.eval_seeds or not all(isinstance(s, int) and 0 <= s < self.seed for s in self.eval_seeds):
            raise ValueError(f"{name}.eval_seeds={self.eval_seeds!r}: expected a non-empty list of seeds in "
                             f"[0, seed={self.seed}), held out from the training episodes")
        rollout = self.n_steps * self.n_envs * self.n_uavs
        if self.batch_size > rollout:
            raise ValueError(f"{name}.batch_size={self.batch_size} is larger than a rollout of n_steps * n_envs * "
                             f"n_uavs = {rollout} samples")

    def residual(self) -> ResidualConfig:
        return ResidualConfig(max_factor=self.max_factor, reward=self.reward)

    def env_kwargs(self) -> dict:
        return {"scenario": self.scenario, "n_uavs": self.n_uavs, "max_cycles": self.max_cycles}
