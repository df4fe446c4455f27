"""Train SB3 PPO from scratch on the raw env: one policy shared by all UAVs (parameter sharing).

The policy outputs the raw flight commands (forward speed, yaw rate, climb rate in [-1, 1]); there is
no expert inside, unlike ``uavform train`` (residual RL on the expert's weights). Every UAV of every
env copy is one row of ``training.vecenv.SharedPolicyVecEnv`` (a seedable SuperSuit
``concat_vec_envs_v1``), so SB3 sees one single-agent VecEnv of ``n_copies * n_uavs`` rows.

    python examples/sb3_ppo_from_scratch.py                       # 100k agent-steps
    python examples/sb3_ppo_from_scratch.py --timesteps 200 --n-steps 50 --max-cycles 20   # a smoke run

The defaults are a starting point, not a tuned recipe: we have not measured what they reach (the
project's documented training is ``uavform train``, see the README). ``tests/test_examples.py`` runs
the smoke settings.
"""

from __future__ import annotations

import argparse

import numpy as np
from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import VecMonitor

from training.vecenv import SharedPolicyVecEnv
from uavform_env import parallel_env


class MakeEnv:
    """A picklable env factory (SharedPolicyVecEnv may ship it to worker processes)."""

    def __init__(self, n_uavs: int, max_cycles: int):
        self.kwargs = dict(scenario="forest", n_uavs=n_uavs, max_cycles=max_cycles)

    def __call__(self):
        return parallel_env(**self.kwargs)


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--timesteps", type=int, default=100_000, help="agent-steps (UAV-steps) to train")
    p.add_argument("--n-uavs", type=int, default=3, help="UAVs per episode (one shared policy)")
    p.add_argument("--max-cycles", type=int, default=600, help="steps per episode (0.1 s each)")
    p.add_argument("--n-copies", type=int, default=2, help="env copies (rows = copies x UAVs)")
    p.add_argument("--n-steps", type=int, default=256, help="PPO rollout length per row")
    p.add_argument("--seed", type=int, default=0, help="seeds PPO and the training episodes")
    p.add_argument("--out", default="runs/ppo_from_scratch.zip", help="where to save the policy")
    args = p.parse_args(argv)

    vec = VecMonitor(SharedPolicyVecEnv(MakeEnv(args.n_uavs, args.max_cycles), n_copies=args.n_copies))
    rollout = args.n_steps * vec.num_envs
    model = PPO("MlpPolicy", vec, n_steps=args.n_steps, batch_size=rollout // 4 if rollout % 4 == 0 else rollout,
                seed=args.seed, device="cpu", verbose=0)
    model.learn(args.timesteps)
    model.save(args.out)
    vec.close()

    # Fly one evaluation episode with the deterministic shared policy: every UAV asks the same network.
    penv = MakeEnv(args.n_uavs, args.max_cycles)()
    obs, infos = penv.reset(seed=10_000)
    while penv.agents:
        actions = {a: model.predict(obs[a], deterministic=True)[0] for a in penv.agents}
        obs, rewards, terms, truncs, infos = penv.step(actions)
    env = penv.unwrapped
    result = {"trained_agent_steps": int(model.num_timesteps), "steps": env.step_count, "success": env.success,
              "crashed": int(np.count_nonzero(env.crashed)),
              "leader_goal_distance_m": env.goal_distance()}
    print(f"trained {result['trained_agent_steps']} agent-steps, saved {args.out}; evaluation episode: "
          f"{result['steps']} steps, success {result['success']}, {result['crashed']} crashed, the leader ended "
          f"{result['leader_goal_distance_m']:.1f} m from the goal")
    return result


if __name__ == "__main__":
    main()
