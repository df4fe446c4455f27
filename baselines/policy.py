"""The policy contract shared by every scripted baseline.

A policy is an object with ``reset(env, seed)`` and ``act(observations, env) -> {agent: action}``.
``OnboardPolicy`` implements both for controllers that compute one command (v, w, vz) per UAV from
that UAV's ``onboard`` view, and checks once that the env is one it can fly.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from uavform_env.dynamics import commands_to_actions


def check_flyable(env) -> object:
    """The unwrapped env, after checking it offers ``onboard`` and Box(-1, 1, (3,)) actions for every agent."""
    base = getattr(env, "unwrapped", env)
    if not callable(getattr(base, "onboard", None)):
        raise ValueError(f"policy: the env {type(base).__name__} has no onboard(agent) view; scripted policies fly "
                         "uavform_env.FormationEnv (or a wrapper whose .unwrapped is one)")
    for agent in base.possible_agents:
        space = base.action_space(agent)
        if not (isinstance(space, spaces.Box) and space.shape == (3,) and np.all(space.low == -1)
                and np.all(space.high == 1)):
            raise ValueError(f"policy: action space of {agent} is {space}; expected Box(-1, 1, (3,)) "
                             "(forward speed, yaw rate, climb rate)")
    return base


class OnboardPolicy:
    """Base class: one command per live UAV from its onboard view; subclasses implement ``command``."""

    def reset(self, env, seed: int | None = None) -> None:
        self.env = check_flyable(env)
        self.rng = np.random.default_rng(seed)
        self.diagnostics: dict[str, dict] = {}

    def act(self, observations: dict, env) -> dict:
        base = getattr(env, "unwrapped", env)
        if getattr(self, "env", None) is not base:
            raise ValueError("policy: act() called with an env this policy was not reset() on; call reset(env, seed)")
        out = {}
        for agent in base.agents:
            cmd = self.command(base.onboard(agent))
            out[agent] = commands_to_actions(np.asarray(cmd, dtype=np.float64), base.config.uav)
        return out

    def command(self, view) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError
