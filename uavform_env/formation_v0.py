"""The versioned PettingZoo entry point: ``parallel_env``, ``env`` (AEC view) and ``raw_env``."""

from __future__ import annotations

from pettingzoo.utils import wrappers
from pettingzoo.utils.conversions import parallel_to_aec

from .env import FormationEnv


def parallel_env(**kwargs) -> FormationEnv:
    """The ParallelEnv (see ``FormationEnv`` for the arguments)."""
    return FormationEnv(**kwargs)


def raw_env(**kwargs):
    """The AEC view without the default wrappers."""
    return parallel_to_aec(FormationEnv(**kwargs))


def env(**kwargs):
    """The AEC view with PettingZoo's default wrappers (actions clipped to the Box, call order enforced)."""
    aec = raw_env(**kwargs)
    aec = wrappers.ClipOutOfBoundsWrapper(aec)
    return wrappers.OrderEnforcingWrapper(aec)
