"""TrainConfig: every setting of a residual-policy training run, validated before anything starts."""

from __future__ import annotations

from dataclasses import dataclass

from uavform_env.config import Config, check_int, check_range
from uavform_env.scenarios import make_scenario

from .residual import ResidualConfig


# The bounds of the numeric fields, stated once: __post_init__ checks them and ``uavform train --help`` shows them.
# Integers: (lo, hi); numbers: (lo, hi, lo_open). None = unbounded.
INT_BOUNDS = {"n_uavs": (1, None), "max_cycles": (10, None), "timesteps": (1, None), "n_envs": (1, 64),
              "n_steps": (2, None), "batch_size": (0, None), "n_epochs": (1, None), "seed": (0, 2**31 - 1),
              "eval_every": (1, None)}
FLOAT_BOUNDS = {"learning_rate": (0.0, 1.0, True), "gamma": (0.0, 1.0, True), "gae_lambda": (0.0, 1.0, False),
                "clip_range": (0.0, 1.0, True), "ent_coef": (0.0, 1.0, False), "log_std_init": (-5.0, 2.0, False)}
MINIBATCHES = 4          # batch_size 0 (the default) splits each rollout into this many equal minibatches


@dataclass(frozen=True)
class TrainConfig(Config):
    """Everything a training run depends on; checked before any training starts.

    scenario, n_uavs, max_cycles   the training (and evaluation) missions
    timesteps                      agent-steps in total (each UAV-step is one sample of the shared policy);
                                   PPO trains on whole rollouts, so the run stops at the first multiple of the
                                   rollout size (``rollout_size()``) at or above it: ``total_timesteps()``
    n_envs                         env copies (worker processes when > 1 unless train's backend says otherwise)
    n_steps, batch_size, n_epochs, learning_rate, gamma, gae_lambda, clip_range, ent_coef, log_std_init,
    net_arch                       PPO's hyperparameters (n_steps per row: a rollout holds
                                   n_steps * n_envs * n_uavs samples). batch_size 0 (the default) becomes
                                   rollout / MINIBATCHES (the largest divisor of the rollout up to that), so
                                   minibatches are equal at every N; a given batch_size must divide the rollout
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
    batch_size: int = 0
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
        try:  # a registered name, or one pinned to a version ("forest@1": the world of runs rw1-rw4)
            make_scenario(self.scenario, 0)
        except ValueError as e:
            raise ValueError(f"{name}.scenario={self.scenario!r}: {e}") from None
        for field, (lo, hi) in INT_BOUNDS.items():
            check_int(name, field, getattr(self, field), lo, hi)
        for field, (lo, hi, lo_open) in FLOAT_BOUNDS.items():
            check_range(name, field, getattr(self, field), lo, hi, lo_open=lo_open)
        if not self.net_arch or not all(isinstance(n, int) and not isinstance(n, bool) and n > 0 for n in self.net_arch):
            raise ValueError(f"{name}.net_arch={self.net_arch!r}: expected a non-empty list of positive layer sizes")
        self.residual()
        if not isinstance(self.zero_init, bool):
            raise ValueError(f"{name}.zero_init={self.zero_init!r}: expected true or false")
        if not self.eval_seeds or not all(isinstance(s, int) and 0 <= s < self.seed for s in self.eval_seeds):
            raise ValueError(f"{name}.eval_seeds={self.eval_seeds!r}: expected a non-empty list of seeds in "
                             f"[0, seed={self.seed}), held out from the training episodes")
        rollout = self.rollout_size()
        if self.batch_size == 0:
            object.__setattr__(self, "batch_size", next((d for d in range(rollout // MINIBATCHES, 1, -1)
                                                         if rollout % d == 0), rollout))
        elif rollout % self.batch_size:
            raise ValueError(f"{name}.batch_size={self.batch_size} does not divide a rollout of n_steps * n_envs * "
                             f"n_uavs = {rollout} samples (the last minibatch would be cut short); give a divisor, "
                             "or 0 for a quarter of the rollout")

    def rollout_size(self) -> int:
        """Samples per PPO rollout: n_steps per row, one row per UAV of every env copy."""
        return self.n_steps * self.n_envs * self.n_uavs

    def total_timesteps(self) -> int:
        """The agent-steps the run will really train: ``timesteps`` rounded up to whole rollouts."""
        return -(-self.timesteps // self.rollout_size()) * self.rollout_size()

    def residual(self) -> ResidualConfig:
        return ResidualConfig(max_factor=self.max_factor, reward=self.reward)

    def env_kwargs(self) -> dict:
        return {"scenario": self.scenario, "n_uavs": self.n_uavs, "max_cycles": self.max_cycles}
