"""Planning time of the fusion expert per UAV-step, next to its DWA and 3D VFH+ parts and the env step.

    python benchmarks/planner.py [--scenario forest] [--n 5] [--steps 300] [--seed 0] [--clock wall|cpu]

One episode: the expert flies, the env steps. Expert time is whole ``act()`` calls divided by the
live UAVs, so the leader's A* (re)plans are amortised over every UAV-step. DWA and 3D VFH+ are
timed per call inside the same run, with exactly the arguments the expert passes (the planners are
injected into the expert wrapped in a timer, not re-run). The env figure is ``penv.step`` time
divided by the live UAVs. ``--clock cpu`` times with the process's CPU time instead of elapsed time
(``benchmarks/step_stages.py``'s clocks): steadier on a machine shared with other jobs.
Issue 13's target: expert per UAV-step <= env per UAV-step, and <= 0.5 ms median.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from step_stages import CLOCKS


def _timed(fn, log: list, clock=time.perf_counter):
    """``fn`` with each call's time (of ``clock``) appended to ``log`` (same arguments, same result)."""
    def wrapper(*args, **kwargs):
        t0 = clock()
        out = fn(*args, **kwargs)
        log.append(clock() - t0)
        return out
    return wrapper


def measure(scenario: str, n: int, steps: int, seed: int, clock=time.perf_counter) -> dict[str, np.ndarray]:
    """Per-sample times (s): expert and env per UAV-step, DWA and VFH per call; warm-up excluded."""
    from baselines.dwa import dwa_plan
    from baselines.expert import FusionExpert
    from baselines.vfh3d import VFHPlanner
    from uavform_env import parallel_env

    times = {"expert": [], "dwa": [], "vfh": [], "env": []}
    penv = parallel_env(scenario=scenario, n_uavs=n, max_cycles=steps + 10)
    policy = FusionExpert(dwa=_timed(dwa_plan, times["dwa"], clock),
                          vfh=_timed(VFHPlanner(), times["vfh"], clock))
    for warm in (True, False):                       # the first episode compiles / loads the numba kernels
        obs, _ = penv.reset(seed=seed)
        policy.reset(penv, seed=seed)
        for log in times.values():
            log.clear()
        for _ in range(5 if warm else steps):
            live = len(penv.agents)
            t0 = clock()
            actions = policy.act(obs, penv)
            t1 = clock()
            obs, *_ = penv.step(actions)
            t2 = clock()
            times["expert"].append((t1 - t0) / live)
            times["env"].append((t2 - t1) / live)
            if not penv.agents:
                break
    return {k: np.asarray(v) for k, v in times.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="forest")
    parser.add_argument("--n", type=int, default=5)
    parser.add_argument("--steps", type=int, default=300)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--clock", choices=CLOCKS, default="wall",
                        help="wall: elapsed time; cpu: this process's CPU time, steadier on a busy machine")
    args = parser.parse_args()
    t = measure(args.scenario, args.n, args.steps, args.seed, CLOCKS[args.clock])
    print(f"{args.scenario}, {args.n} UAVs, {len(t['env'])} steps, seed {args.seed}, {args.clock} clock")
    print(f"{'part':<32} {'samples':>8} {'median ms':>10} {'p95 ms':>8}")
    rows = (("expert act() per UAV-step", "expert"), ("  DWA (dwa_plan) per call", "dwa"),
            ("  3D VFH+ (VFHPlanner) per call", "vfh"), ("env step per UAV", "env"))
    for label, key in rows:
        ms = 1e3 * t[key]
        print(f"{label:<32} {ms.size:>8} {np.median(ms):>10.3f} {np.percentile(ms, 95):>8.3f}")
    ratio = np.median(t["expert"]) / np.median(t["env"])
    print(f"expert / env (medians): {ratio:.2f}; target: <= 1 and expert median <= 0.5 ms")


if __name__ == "__main__":
    main()
