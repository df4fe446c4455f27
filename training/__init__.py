"""training: residual reinforcement learning of the fusion expert's evaluation weights (SB3 PPO).

    from training import ResidualWeightEnv
    renv = ResidualWeightEnv(parallel_env(scenario="forest", n_uavs=5))

Dependencies run one way: ``training`` -> ``baselines`` -> ``uavform_env``.
"""

from .residual import ResidualConfig, ResidualWeightEnv

__all__ = ["ResidualConfig", "ResidualWeightEnv"]
