"""Success / collision table of the fusion expert over a scenario x seed grid.

    python benchmarks/expert_success.py [--scenarios forest corridor ...] [--seeds 0 1 2] [--n N]
                                        [--workers 1] [--max-steps 3000] [--policy expert]

One episode per (scenario, seed) at the scenario's default size (``--n`` overrides it); at most ``--workers`` processes
(1-2: the machine is shared). Prints one row per scenario (S = success, C = collision, . = time-out
per seed) and the wall time, so the number in docs and issues is reproducible.
"""

from __future__ import annotations

import argparse
import time

from uavform_env.parallel import imap_unordered

SCENARIOS = ("forest@1", "corridor@1", "urban@1", "wall-gap@1", "random-3d@1", "classic-2d@1")  # the tuned-on worlds


def fly(scenario: str, seed: int, n: int | None, max_steps: int, policy_name: str):
    from uavform_env.formation_v0 import parallel_env
    from uavform_env.policies import load_policy
    from uavform_env.rollout import run_episode

    t0 = time.perf_counter()
    size = {} if n is None else {"n_uavs": n}
    penv = parallel_env(scenario=scenario, max_cycles=max_steps, **size)
    metrics = run_episode(penv, load_policy(policy_name), seed)
    return scenario, seed, bool(metrics["success"]), bool(metrics["collision"]), time.perf_counter() - t0


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenarios", nargs="+", default=list(SCENARIOS))
    p.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    p.add_argument("--n", type=int, default=None, help="UAVs per episode (default: each scenario's default size)")
    p.add_argument("--max-steps", type=int, default=3000)
    p.add_argument("--workers", type=int, default=1, choices=(1, 2))
    p.add_argument("--policy", default="expert")
    a = p.parse_args(argv)
    jobs = [(s, seed, a.n, a.max_steps, a.policy) for s in a.scenarios for seed in a.seeds]
    t0 = time.perf_counter()
    results = {}
    for scenario, seed, ok, crash, secs in imap_unordered(fly, jobs, a.workers):
        results[scenario, seed] = (ok, crash)
        print(f"  {scenario:<11} seed {seed}: {'SUCCESS' if ok else 'COLLISION' if crash else 'time-out'}"
              f" ({secs:.0f} s)", flush=True)
    print(f"\n{a.policy}, {a.n or 'default'} UAVs, seeds {a.seeds}, max {a.max_steps} steps")
    print(f"{'scenario':<11} {'per seed':<{max(8, len(a.seeds))}} success collisions")
    tot_ok = tot_c = 0
    for s in a.scenarios:
        marks = "".join("S" if results[s, k][0] else "C" if results[s, k][1] else "." for k in a.seeds)
        ok = sum(results[s, k][0] for k in a.seeds)
        c = sum(results[s, k][1] for k in a.seeds)
        tot_ok, tot_c = tot_ok + ok, tot_c + c
        print(f"{s:<11} {marks:<{max(8, len(a.seeds))}} {ok:>3}/{len(a.seeds):<3} {c:>6}")
    print(f"total: {tot_ok}/{len(jobs)} success, {tot_c} collisions; wall time {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
