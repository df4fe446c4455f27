"""Success / collision table of the fusion expert over a scenario x seed grid.

    python benchmarks/expert_success.py [--scenarios forest corridor ...] [--seeds 0 1 2] [--n N]
                                        [--formation wedge] [--difficulty medium] [--wind breeze]
                                        [--workers 1] [--max-steps 3000] [--policy expert]

One episode per (scenario, seed) at the scenario's default size, formation, difficulty and disturbance (``--n``,
``--formation``, ``--difficulty``, ``--wind`` override them: missions outside the suites, such as larger formations
than v1 flies); at most ``--workers`` processes (1-2: the machine is shared). Prints one row per scenario
(S = success, C = collision, . = time-out per seed) and the wall time, so the number in docs and issues is
reproducible. The policy and every scenario (with the overrides) are built once before any flight, so a bad name or
combination is a one-line error.
"""

from __future__ import annotations

import argparse
import time

from uavform_env.parallel import imap_unordered

SCENARIOS = ("forest@1", "corridor@1", "urban@1", "wall-gap@1", "random-3d@1", "classic-2d@1")  # the tuned-on worlds


def env_kwargs(scenario: str, max_steps: int, n: int | None, formation: str | None, difficulty: str | None,
               wind: str | None) -> dict:
    """``parallel_env``'s arguments for one scenario with the overrides that are set."""
    given = {"n_uavs": n, "formation": formation, "difficulty": difficulty, "disturbance": wind}
    return {"scenario": scenario, "max_cycles": max_steps, **{k: v for k, v in given.items() if v is not None}}


def fly(scenario: str, seed: int, kwargs: dict, policy_name: str) -> dict:
    """One episode of ``parallel_env(**kwargs)`` flown by the policy from ``seed``: ``fly_env``'s record."""
    from uavform_env.formation_v0 import parallel_env

    t0 = time.perf_counter()
    return fly_env(parallel_env(**kwargs), scenario, seed, policy_name, t0)


def fly_env(penv, scenario: str, seed: int, policy_name: str, t0: float) -> dict:
    """One episode of ``penv`` flown by the policy from ``seed``: whether it succeeded and collided, the env's end
    reason and its sentence (``metrics.episode_outcome``), the steps and the wall time since ``t0``."""
    from uavform_env.metrics import episode_outcome
    from uavform_env.policies import load_policy
    from uavform_env.rollout import run_episode

    metrics = run_episode(penv, load_policy(policy_name), seed)
    outcome, detail = episode_outcome(penv.unwrapped)
    return {"scenario": scenario, "seed": seed, "success": bool(metrics["success"]),
            "collision": bool(metrics["collision"]), "outcome": outcome, "detail": detail,
            "steps": int(penv.unwrapped.step_count), "seconds": time.perf_counter() - t0}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scenarios", nargs="+", default=list(SCENARIOS))
    p.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    p.add_argument("--n", type=int, default=None, help="UAVs per episode (default: each scenario's default size)")
    p.add_argument("--formation", default=None, help="formation shape (default: each scenario's)")
    p.add_argument("--difficulty", default=None, help="difficulty of scenarios that have levels (default: each's)")
    p.add_argument("--wind", default=None, help="disturbance preset (default: each scenario's)")
    p.add_argument("--max-steps", type=int, default=3000)
    p.add_argument("--workers", type=int, default=1, choices=(1, 2))
    p.add_argument("--policy", default="expert")
    a = p.parse_args(argv)
    from uavform_env.formation_v0 import parallel_env
    from uavform_env.policies import load_policy
    try:
        load_policy(a.policy)
    except ValueError as e:
        p.error(f"--policy: {e}")
    kwargs = {}
    for s in a.scenarios:
        kwargs[s] = env_kwargs(s, a.max_steps, a.n, a.formation, a.difficulty, a.wind)
        try:
            parallel_env(**kwargs[s]).close()
        except ValueError as e:
            p.error(f"--scenarios {s}: {e}")
    jobs = [(s, seed, kwargs[s], a.policy) for s in a.scenarios for seed in a.seeds]
    t0 = time.perf_counter()
    results = {}
    for r in imap_unordered(fly, jobs, a.workers):
        ok, crash = results[r["scenario"], r["seed"]] = (r["success"], r["collision"])
        print(f"  {r['scenario']:<11} seed {r['seed']}: {'SUCCESS' if ok else 'COLLISION' if crash else 'time-out'}"
              f" ({r['seconds']:.0f} s)", flush=True)
    print(f"\n{a.policy}, {a.n or 'default'} UAVs, formation {a.formation or 'default'}, difficulty "
          f"{a.difficulty or 'default'}, wind {a.wind or 'default'}, seeds {a.seeds}, max {a.max_steps} steps")
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
