"""Env speed with every UAV flying, next to PettingZoo MPE simple_spread and VMAS at the same N, in one run.

    python benchmarks/env_step.py [--ns 5 10 20 50] [--steps 400] [--resets 5] [--copies 16]
                                  [--vector-workers 1 2] [--budget 60]
                                  [--out env_step.json]

Ours: the fusion expert flies forest (``n_uavs=N``, the episode seed ``--seed``) for ``--steps`` steps and
its actions are recorded; a fresh process then replays them on the same episode and times the step loop
alone, so the UAVs fly (and sense and map) exactly as under the expert, and the expert's own time is not
counted. The ``alive`` column is the mean fraction of UAVs not crashed during the replay (crashed UAVs
freeze and cost little, so a figure is only honest when it is near 1). MPE (``mpe2``) and VMAS (one env,
CPU, ``pip install vmas``) step ``simple_spread`` with N agents and uniformly random actions.

Per configuration, in its own process: agent-steps/s (N x steps / wall time of the step loop), reset time
(median of ``--resets`` resets with new seeds, after a warm-up reset; ours builds a new obstacle layout on
every new seed) and the process's peak RSS (``resource.getrusage``, so it includes the interpreter and
the imports: about 100 MB for ours and MPE, more for VMAS, which imports torch).

The vector-env lines: ``--copies`` copies of N = 5 (``training.vecenv.SharedPolicyVecEnv``, the residual
training's VecEnv: one ``uavform_env.vector.VectorEnv`` inline, or the copies split over
``--vector-workers`` worker processes), every copy replaying the expert's recorded flight on the recorded
layout (``layout_seed``; with the default sensor and no wind the flight does not depend on the episode
seed), so all K x 5 UAVs fly. The ``alive`` column counts the rows whose info says not crashed.
"""

from __future__ import annotations

import argparse
import json
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

SCENARIO = "forest"


def _peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0      # kB on Linux


def _ours_kwargs(n: int, seed: int, steps: int) -> dict:
    # max_cycles past the replay: no truncation, and so no reset, inside a timed loop.
    return dict(scenario=SCENARIO, n_uavs=n, layout_seed=seed, max_cycles=steps + 1)


# ----------------------------------------------------------------------------------- child processes
def record(n: int, seed: int, steps: int, path: str) -> dict:
    """The expert's actions, (steps, N, 3), for the episode ``seed``; fewer steps if the episode ends first."""
    from uavform_env import parallel_env
    from uavform_env.policies import load_policy

    penv = parallel_env(**_ours_kwargs(n, seed, steps))
    policy = load_policy("expert")
    obs, _ = penv.reset(seed=seed)
    policy.reset(penv, seed)
    agents = penv.possible_agents
    actions = []
    t0 = time.perf_counter()
    while penv.agents and len(actions) < steps:
        act = policy.act(obs, penv)
        actions.append(np.stack([np.asarray(act.get(a, np.zeros(3)), np.float32) for a in agents]))
        obs, *_ = penv.step(act)
    np.save(path, np.array(actions))
    return {"recorded_steps": len(actions), "expert_wall_s": time.perf_counter() - t0}


def _timed(step, actions, budget: float) -> tuple[int, float]:
    """Call ``step(a)`` for each batch of actions, stopping after ``budget`` seconds: (steps done, wall s)."""
    done, t0 = 0, time.perf_counter()
    for a in actions:
        step(a)
        done += 1
        if time.perf_counter() - t0 > budget:
            break
    return done, time.perf_counter() - t0


def _reset_ms(reset, seeds) -> float:
    """Median wall time of ``reset(seed)`` over the seeds, in ms."""
    times = []
    for seed in seeds:
        t0 = time.perf_counter()
        reset(seed)
        times.append(time.perf_counter() - t0)
    return 1e3 * statistics.median(times)


def ours(n: int, seed: int, steps: int, resets: int, path: str, budget: float) -> dict:
    from uavform_env import parallel_env

    acts = np.load(path)
    imports = _peak_rss_mb()
    penv = parallel_env(scenario=SCENARIO, n_uavs=n, max_cycles=steps + 1)
    agents = penv.possible_agents
    penv.reset(seed=seed + 10_000)                                   # warm-up (numba cache, first layout)
    reset_ms = _reset_ms(lambda s: penv.reset(seed=s), range(seed + 20_001, seed + 20_001 + resets))  # new layouts
    penv = parallel_env(**_ours_kwargs(n, seed, steps))               # layout_seed: the recorded layout
    env = penv.unwrapped
    penv.reset(seed=seed)
    counts = {"agent_steps": 0, "alive": 0}

    def step(a):
        live = penv.agents
        counts["agent_steps"] += len(live)
        penv.step({ag: a[i] for i, ag in enumerate(agents) if ag in live})
        counts["alive"] += int(env.active.sum())

    done, wall = _timed(step, acts, budget)
    return {"agent_steps_per_s": counts["agent_steps"] / wall, "reset_ms": reset_ms, "peak_rss_mb": _peak_rss_mb(),
            "import_rss_mb": imports, "alive": counts["alive"] / (done * n), "steps": done}


def mpe(n: int, seed: int, steps: int, resets: int, budget: float) -> dict:
    from mpe2 import simple_spread_v3

    imports = _peak_rss_mb()
    penv = simple_spread_v3.parallel_env(N=n, max_cycles=steps + 1, continuous_actions=True)
    penv.reset(seed=seed)
    reset_ms = _reset_ms(lambda s: penv.reset(seed=s), range(seed + 20_001, seed + 20_001 + resets))
    penv.reset(seed=seed)
    rng = np.random.default_rng(seed)
    agents = list(penv.agents)
    dim = penv.action_space(agents[0]).shape[0]
    acts = rng.uniform(0, 1, (steps, n, dim)).astype(np.float32)     # simple_spread's continuous Box is [0, 1]
    done, wall = _timed(lambda a: penv.step({ag: a[i] for i, ag in enumerate(agents)}), acts, budget)
    return {"agent_steps_per_s": n * done / wall, "steps": done, "reset_ms": reset_ms,
            "peak_rss_mb": _peak_rss_mb(), "import_rss_mb": imports}


def vmas(n: int, seed: int, steps: int, resets: int, budget: float) -> dict:
    import torch
    import vmas as vmas_lib

    torch.set_num_threads(1)
    imports = _peak_rss_mb()
    env = vmas_lib.make_env(scenario="simple_spread", num_envs=1, device="cpu", continuous_actions=True,
                            n_agents=n, seed=seed, max_steps=None)
    env.reset()

    def reset(s):
        env.seed(s)
        env.reset()

    reset_ms = _reset_ms(reset, range(seed + 20_001, seed + 20_001 + resets))
    gen = torch.Generator().manual_seed(seed)
    acts = torch.rand((steps, n, 1, 2), generator=gen) * 2 - 1
    done, wall = _timed(lambda a: env.step(list(a)), acts, budget)
    return {"agent_steps_per_s": n * done / wall, "steps": done, "reset_ms": reset_ms,
            "peak_rss_mb": _peak_rss_mb(), "import_rss_mb": imports}


def vector(n: int, copies: int, seed: int, steps: int, path: str, budget: float, workers: int = 1) -> dict:
    from training.vecenv import SharedPolicyVecEnv
    from uavform_env import parallel_env

    acts = np.load(path)
    imports = _peak_rss_mb()
    kwargs = _ours_kwargs(n, seed, steps)
    venv = SharedPolicyVecEnv(lambda: parallel_env(**kwargs), copies, backend="process" if workers > 1 else "inline",
                              workers=workers)
    venv.seed(seed + 10_000)
    venv.reset()                                # warm-up (numba cache)
    venv.seed(seed)                             # copy k: episode seed seed + k, the recorded layout

    reset_all = _reset_ms(lambda s: venv.reset(), [seed])
    counts = {"alive": 0}

    def step(a):
        *_, infos = venv.step(np.broadcast_to(a, (copies, *a.shape)).reshape(copies * n, -1))
        counts["alive"] += sum(1 - info["crashed"] for info in infos)

    done, wall = _timed(step, acts, budget)
    venv.close()
    return {"agent_steps_per_s": copies * n * done / wall, "reset_all_ms": reset_all,
            "peak_rss_mb": _peak_rss_mb(), "import_rss_mb": imports, "alive": counts["alive"] / (done * n * copies),
            "steps": done, "workers": workers}


CHILDREN = {"record": record, "ours": ours, "mpe": mpe, "vmas": vmas, "vector": vector}


# ----------------------------------------------------------------------------------------- the run
def _child(kind: str, **kwargs) -> dict:
    """Run one configuration in a fresh process; its last stdout line is the JSON result."""
    proc = subprocess.run([sys.executable, __file__, "--child", kind, "--child-args", json.dumps(kwargs)],
                          capture_output=True, text=True)
    if proc.returncode != 0:
        reason = (proc.stderr.strip().splitlines() or ["no output"])[-1]
        return {"error": f"{kind} failed: {reason}"}
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _fmt(row: dict, key: str, spec: str) -> str:
    return "n/a" if key not in row else format(row[key], spec)


def _rss(row: dict) -> str:
    """Peak RSS, and in brackets the part already held after the imports (interpreter, numba, torch)."""
    return "n/a" if "peak_rss_mb" not in row else f"{row['peak_rss_mb']:.0f} ({row['import_rss_mb']:.0f})"


def to_markdown(result: dict) -> str:
    lines = [f"{SCENARIO}, {result['steps']} steps replaying the expert (ours); simple_spread with random actions "
             "(MPE, VMAS one env on CPU). agent-steps/s | reset ms (median of "
             f"{result['resets']}) | peak RSS MB (in brackets: after the imports, before the env), each "
             "configuration in its own process.", "",
             "| N | ours agent-steps/s | steps | alive | ours reset ms | ours peak RSS MB | MPE agent-steps/s "
             "| MPE reset ms | MPE peak RSS MB | VMAS agent-steps/s | steps | VMAS reset ms | VMAS peak RSS MB "
             "| ours / MPE |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for row in result["rows"]:
        o, m, v = row["ours"], row["mpe"], row["vmas"]
        ratio = (f"{o['agent_steps_per_s'] / m['agent_steps_per_s']:.2f}"
                 if "agent_steps_per_s" in o and "agent_steps_per_s" in m else "n/a")
        lines.append(f"| {row['n']} | {_fmt(o, 'agent_steps_per_s', '.0f')} | {_fmt(o, 'steps', 'd')} | "
                     f"{_fmt(o, 'alive', '.2f')} | "
                     f"{_fmt(o, 'reset_ms', '.1f')} | {_rss(o)} | "
                     f"{_fmt(m, 'agent_steps_per_s', '.0f')} | {_fmt(m, 'reset_ms', '.2f')} | "
                     f"{_rss(m)} | {_fmt(v, 'agent_steps_per_s', '.0f')} | {_fmt(v, 'steps', 'd')} | "
                     f"{_fmt(v, 'reset_ms', '.2f')} | {_rss(v)} | {ratio} |")
    errors = [f"- N={row['n']} {name}: {row[name]['error']}" for row in result["rows"]
              for name in ("ours", "mpe", "vmas") if "error" in row[name]]
    vecs = result.get("vector")
    if vecs is not None:
        vecs = [vecs] if isinstance(vecs, dict) else vecs        # one line per worker count (older files: one)
        lines += ["", f"Vector env, K = {vecs[0]['copies']} copies of N = {vecs[0]['n']}, every copy replaying the "
                      "expert's flight (training.vecenv.SharedPolicyVecEnv: one VectorEnv inline, or the copies split "
                      "over worker processes):", "",
                  "| K x N | workers | agent-steps/s | steps | alive | reset of all copies ms | peak RSS MB |",
                  "|---|---|---|---|---|---|---|"]
        for vec in vecs:
            lines.append(f"| {vec['copies']} x {vec['n']} | {vec.get('workers', 1)} | "
                         f"{_fmt(vec, 'agent_steps_per_s', '.0f')} | {_fmt(vec, 'steps', 'd')} | "
                         f"{_fmt(vec, 'alive', '.2f')} | {_fmt(vec, 'reset_all_ms', '.0f')} | {_rss(vec)} |")
            if "error" in vec:
                errors.append(f"- vector env, {vec.get('workers', 1)} worker(s): {vec['error']}")
    if errors:
        lines += ["", "Not measured:"] + errors
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ns", type=int, nargs="+", default=[5, 10, 20, 50])
    parser.add_argument("--steps", type=int, default=400, help="recorded expert steps replayed per N")
    parser.add_argument("--resets", type=int, default=5, help="resets with new seeds; the median is reported")
    parser.add_argument("--copies", type=int, default=16, help="copies in the vector-env line (0: skip it)")
    parser.add_argument("--vector-n", type=int, default=5, help="UAVs per copy in the vector-env line")
    parser.add_argument("--vector-workers", type=int, nargs="+", default=[1, 2],
                        help="worker processes the copies are split over; one vector-env line each (1: inline)")
    parser.add_argument("--seed", type=int, default=0, help="the recorded episode's seed")
    parser.add_argument("--budget", type=float, default=60.0,
                        help="seconds per timed step loop: a slower configuration is timed over the steps done by "
                             "then (the steps column says how many)")
    parser.add_argument("--out", default=None, help="also write the results as JSON")
    parser.add_argument("--child", choices=sorted(CHILDREN), help=argparse.SUPPRESS)
    parser.add_argument("--child-args", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        print(json.dumps(CHILDREN[args.child](**json.loads(args.child_args))))
        return
    for name in ("steps", "resets", "budget"):
        if getattr(args, name) <= 0:
            parser.error(f"--{name} must be > 0")
    if min(args.ns) < 1 or args.copies < 0 or args.vector_n < 1 or min(args.vector_workers) < 1:
        parser.error("--ns, --vector-n and --vector-workers must be >= 1 and --copies >= 0")
    result = {"scenario": SCENARIO, "steps": args.steps, "resets": args.resets, "seed": args.seed, "rows": []}
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.ns:
            path = str(Path(tmp) / f"expert-{n}.npy")
            rec = _child("record", n=n, seed=args.seed, steps=args.steps, path=path)
            row = {"n": n, "record": rec}
            common = dict(n=n, seed=args.seed, steps=args.steps, resets=args.resets, budget=args.budget)
            row["ours"] = rec if "error" in rec else _child("ours", path=path, **common)
            row["mpe"] = _child("mpe", **common)
            row["vmas"] = _child("vmas", **common)
            result["rows"].append(row)
            print(f"N={n} done", file=sys.stderr, flush=True)
        if args.copies:
            path = str(Path(tmp) / f"expert-{args.vector_n}.npy")
            if not Path(path).exists():
                _child("record", n=args.vector_n, seed=args.seed, steps=args.steps, path=path)
            result["vector"] = [{"copies": args.copies, "n": args.vector_n, "workers": w,
                                 **_child("vector", n=args.vector_n, copies=args.copies, seed=args.seed,
                                          steps=args.steps, path=path, budget=args.budget, workers=w)}
                                for w in args.vector_workers]
    print(to_markdown(result), end="")
    if args.out:
        from uavform_env.files import atomic_write_json

        atomic_write_json(Path(args.out), result)


if __name__ == "__main__":
    main()
