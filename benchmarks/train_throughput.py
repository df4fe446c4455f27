"""Training throughput of the residual weight policy, in agent-steps per second.

    python benchmarks/train_throughput.py [--scenario forest] [--n 5] [--timesteps 6000] [--copies 1 2]

Two figures per number of env copies: the rollout alone (ResidualWeightEnv = env + expert, stepped through
SharedPolicyVecEnv with zero actions) and whole PPO training (rollouts + network forward passes + updates,
no evaluation), both counted in agent-steps (one UAV-step = one sample of the shared policy). Copies > 1
run in worker processes. A warm-up rollout first, so numba compilation is not timed.
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def rollout_rate(make_env, copies: int, steps: int) -> float:
    from training.vecenv import SharedPolicyVecEnv

    venv = SharedPolicyVecEnv(make_env, copies, backend="process" if copies > 1 else "inline")
    try:
        venv.seed(0)
        venv.reset()
        actions = np.zeros((venv.num_envs, venv.action_space.shape[0]), np.float32)
        t0 = time.perf_counter()
        for _ in range(steps):
            venv.step(actions)
        return steps * venv.num_envs / (time.perf_counter() - t0)
    finally:
        venv.close()


def training_rate(make_env, copies: int, timesteps: int) -> float:
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

    from training.config import TrainConfig
    from training.vecenv import SharedPolicyVecEnv

    torch.set_num_threads(1)                # as training.train does: its spinning threads took the copies' cores
    cfg = TrainConfig(n_envs=copies, n_uavs=make_env.n)     # the minibatches of this many copies and UAVs
    backend = "process" if copies > 1 else "inline"
    venv = VecNormalize(VecMonitor(SharedPolicyVecEnv(make_env, copies, backend=backend)))
    try:
        model = PPO("MlpPolicy", venv, n_steps=cfg.n_steps, batch_size=cfg.batch_size, n_epochs=cfg.n_epochs,
                    seed=0, device="cpu", policy_kwargs={"net_arch": list(cfg.net_arch)})
        t0 = time.perf_counter()
        model.learn(total_timesteps=timesteps)
        return model.num_timesteps / (time.perf_counter() - t0)
    finally:
        venv.close()


class MakeEnv:
    def __init__(self, scenario: str, n: int):
        self.scenario, self.n = scenario, n

    def __call__(self):
        from training import ResidualWeightEnv
        from uavform_env import parallel_env

        return ResidualWeightEnv(parallel_env(scenario=self.scenario, n_uavs=self.n, max_cycles=1500))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="forest")
    parser.add_argument("--n", type=int, default=5)
    parser.add_argument("--timesteps", type=int, default=6000, help="agent-steps of PPO training per measurement")
    parser.add_argument("--copies", type=int, nargs="+", default=[1, 2])
    args = parser.parse_args()
    make_env = MakeEnv(args.scenario, args.n)
    rollout_rate(make_env, 1, 20)                     # compile / load the numba cache
    print(f"{args.scenario}, {args.n} UAVs: agent-steps per second")
    print("| env copies | rollout (env + expert) | PPO training (rollout + updates) |\n|---|---|---|")
    for copies in args.copies:
        steps = max(20, args.timesteps // (copies * args.n))
        print(f"| {copies} | {rollout_rate(make_env, copies, steps):.0f} | "
              f"{training_rate(make_env, copies, args.timesteps):.0f} |", flush=True)


if __name__ == "__main__":
    main()
