"""A TorchRL rollout of the env through ``PettingZooWrapper``, with one MLP shared by all UAVs.

The wrapper groups the agents ``uav_0 .. uav_{N-1}`` into one group, ``"uav"``, so observations arrive
as a ``(N, obs_dim)`` tensor per step and a ``MultiAgentMLP(share_params=True)`` maps each UAV's
observation to its action with the same weights. The network here is untrained (random weights):
the example shows the plumbing a TorchRL user starts from (e.g. MAPPO / IPPO from TorchRL's tutorials).

    python examples/torchrl_rollout.py                   # 300 steps, forest, 5 UAVs
    python examples/torchrl_rollout.py --steps 20        # a smoke run
"""

from __future__ import annotations

import argparse

import torch
from tensordict.nn import TensorDictModule
from torch import nn
from torchrl.envs.libs.pettingzoo import PettingZooWrapper
from torchrl.modules import MultiAgentMLP

from uavform_env import parallel_env


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--steps", type=int, default=300, help="rollout length (0.1 s each)")
    p.add_argument("--n-uavs", type=int, default=5, help="UAVs (one group, one shared network)")
    p.add_argument("--seed", type=int, default=0, help="episode seed and torch seed")
    args = p.parse_args(argv)

    torch.manual_seed(args.seed)
    env = PettingZooWrapper(env=parallel_env(scenario="forest", n_uavs=args.n_uavs, max_cycles=args.steps),
                            return_state=True, seed=args.seed)
    obs_dim = env.full_observation_spec["uav", "observation"].shape[-1]
    act_dim = env.full_action_spec["uav", "action"].shape[-1]
    shared = nn.Sequential(MultiAgentMLP(n_agent_inputs=obs_dim, n_agent_outputs=act_dim, n_agents=args.n_uavs,
                                         centralised=False, share_params=True, depth=2, num_cells=64),
                           nn.Tanh())                       # actions in [-1, 1]
    policy = TensorDictModule(shared, in_keys=[("uav", "observation")], out_keys=[("uav", "action")])
    with torch.no_grad():
        td = env.rollout(args.steps, policy=policy, break_when_any_done=True)
    env.close()
    result = {"steps": td.batch_size[0], "actions": tuple(td["uav", "action"].shape),
              "mean_reward": float(td["next", "uav", "reward"].mean()),
              "crashed": int(td["next", "uav", "info", "crashed"][-1].sum())}
    print(f"rolled out {result['steps']} steps; actions {result['actions']} (steps, UAVs, commands); "
          f"mean reward per UAV-step {result['mean_reward']:.3f}; {result['crashed']} UAVs crashed at the end")
    return result


if __name__ == "__main__":
    main()
