"""Agent-steps per second of FormationEnv (default sensing and maps) next to PettingZoo MPE simple_spread.

    python benchmarks/env_step.py [--steps 300] [--ns 1 5 10 20]

Both envs get uniformly random actions; the figure is (live agents x steps) / wall time of the
step loop, resets excluded. MPE comes from the `mpe2` package (extra `dev`).
"""

from __future__ import annotations

import argparse
import time

import numpy as np


def ours(n: int, steps: int) -> float:
    from uavform_env import parallel_env

    spacing = 2.0 if n <= 10 else 1.0
    penv = parallel_env(scenario="forest", n_uavs=n, formation="wedge", spacing=spacing, max_cycles=10 ** 6)
    penv.reset(seed=0)
    rng = np.random.default_rng(0)
    for _ in range(5):                                   # compile / warm up
        penv.step({a: rng.uniform(-1, 1, 3).astype(np.float32) for a in penv.agents})
    penv.reset(seed=0)
    agent_steps, t0 = 0, time.perf_counter()
    for _ in range(steps):
        if not penv.agents:
            penv.reset(seed=1)
        acts = {a: rng.uniform(-1, 1, 3).astype(np.float32) for a in penv.agents}
        agent_steps += len(acts)
        penv.step(acts)
    return agent_steps / (time.perf_counter() - t0)


def mpe(n: int, steps: int) -> float:
    from mpe2 import simple_spread_v3

    penv = simple_spread_v3.parallel_env(N=n, max_cycles=10 ** 6, continuous_actions=False)
    penv.reset(seed=0)
    agent_steps, t0 = 0, time.perf_counter()
    for _ in range(steps):
        if not penv.agents:
            penv.reset(seed=1)
        acts = {a: penv.action_space(a).sample() for a in penv.agents}
        agent_steps += len(acts)
        penv.step(acts)
    return agent_steps / (time.perf_counter() - t0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--ns", type=int, nargs="+", default=[1, 3, 5, 10, 20])
    args = parser.parse_args()
    print(f"{'N':>3} {'uavform agent-steps/s':>22} {'MPE simple_spread':>18} {'ratio':>6}")
    for n in args.ns:
        a, b = ours(n, args.steps), mpe(n, args.steps)
        print(f"{n:>3} {a:>22.0f} {b:>18.0f} {a / b:>6.2f}")


if __name__ == "__main__":
    main()
