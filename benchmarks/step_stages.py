"""Where a FormationEnv step spends its time, per UAV-step, with every UAV flying, next to MPE simple_spread.

    python benchmarks/step_stages.py [--steps 150] [--ns 5 10 50] [--repeats 3] [--clock wall|cpu]

For each N the fusion expert flies forest@1 (seed 0) once, untimed, and its actions are recorded; the
env then replays them, so every UAV stays alive (a replay that loses a UAV is reported). agent-steps/s
is N x steps / time of the replay loop (``--clock``), the best of ``--repeats`` replays, resets excluded.
MPE ``simple_spread`` (package ``mpe2``) steps pre-drawn random actions in the same run, at the same N,
for the ratio. A further replay times each stage of ``FormationEnv.step`` by wrapping the function
that does it; "rest" is the step's own code (endings, the dicts, the code around the timed calls) and the
timers' overhead.
"""

from __future__ import annotations

import argparse
import contextlib
import time

import numpy as np

# (owner, attribute, label): owner "env" is the env instance, "env.<attr>" one of its attributes, else a module
# whose global the step calls.
# Timers of --clock: elapsed time, or the process's CPU time (both envs run in this one thread; the CPU
# time leaves out the waits of a machine shared with other jobs, though not their cache and memory traffic).
CLOCKS = {"wall": time.perf_counter, "cpu": time.process_time}

STAGES = (
    ("env", "_validate_actions", "actions"),
    ("uavform_env.dynamics", "step_actions", "dynamics"),
    ("env", "_apply_wind", "wind"),
    ("env", "_clearance", "clearance"),
    ("uavform_env.env", "contacts", "crash checks"),
    ("env.sensor", "scan", "ray cast"),
    ("uavform_env.env", "perturb_scan", "sensor faults"),
    ("env._map_store", "integrate", "map integrate"),
    ("env", "true_slots", "slots"),
    ("uavform_env.env", "slot_distances", "slot distances"),
    ("uavform_env.env", "compute_rewards", "rewards"),
    ("uavform_env.env", "build_observations", "observations"),
    ("env", "_infos", "infos"),
    ("env", "_record", "history"),
)


def expert_actions(n: int, steps: int) -> list[dict]:
    """The expert's actions over ``steps`` steps of forest@1 seed 0 with ``n`` UAVs."""
    from uavform_env import parallel_env
    from uavform_env.policies import load_policy

    penv = parallel_env(scenario="forest@1", n_uavs=n, max_cycles=steps)
    obs, _ = penv.reset(seed=0)
    policy = load_policy("expert")
    policy.reset(penv, 0)
    actions = []
    while penv.agents:
        actions.append(policy.act(obs, penv))
        obs, *_ = penv.step(actions[-1])
    return actions


def replay(penv, actions: list[dict], clock=time.perf_counter) -> float:
    """Seconds (of ``clock``) to replay ``actions`` from a seed-0 reset (the reset excluded)."""
    penv.reset(seed=0)
    t0 = clock()
    for acts in actions:
        penv.step(acts)
    return clock() - t0


@contextlib.contextmanager
def stage_timers(env, totals: dict, clock=time.perf_counter):
    """Wrap every function of STAGES so that its calls add their seconds to ``totals[label]``."""
    import importlib

    undo = []
    for owner_name, attr, label in STAGES:
        if owner_name.startswith("env"):
            owner = env
            for part in owner_name.split(".")[1:]:
                owner = getattr(owner, part)
        else:
            owner = importlib.import_module(owner_name)
        inner = getattr(owner, attr)

        def timed(*args, _inner=inner, _label=label, **kwargs):
            t0 = clock()
            out = _inner(*args, **kwargs)
            totals[_label] = totals.get(_label, 0.0) + clock() - t0
            return out

        undo.append((owner, attr, owner.__dict__.get(attr)))
        setattr(owner, attr, timed)
    try:
        yield
    finally:
        for owner, attr, before in reversed(undo):
            if before is None:
                delattr(owner, attr)
            else:
                setattr(owner, attr, before)


def ours(n: int, steps: int, repeats: int, clock=time.perf_counter) -> tuple[float, dict, int]:
    """(agent-steps/s, seconds per UAV-step of each stage, UAVs alive at the end)."""
    from uavform_env import parallel_env

    actions = expert_actions(n, steps)
    penv = parallel_env(scenario="forest@1", n_uavs=n, max_cycles=len(actions))
    best = min(replay(penv, actions, clock) for _ in range(repeats))
    alive = int(penv.unwrapped.active.sum())
    totals: dict = {}
    with stage_timers(penv.unwrapped, totals, clock):
        wall = replay(penv, actions, clock)
    uav_steps = n * len(actions)
    stages = {label: totals.get(label, 0.0) / uav_steps for _, _, label in STAGES}
    stages["rest"] = wall / uav_steps - sum(stages.values())
    return uav_steps / best, stages, alive


def mpe(n: int, steps: int, repeats: int, clock=time.perf_counter) -> float:
    from mpe2 import simple_spread_v3

    penv = simple_spread_v3.parallel_env(N=n, max_cycles=steps + 1, continuous_actions=False)
    rng = np.random.default_rng(0)
    actions = [{a: int(rng.integers(5)) for a in penv.possible_agents} for _ in range(steps)]
    best = np.inf
    for _ in range(repeats):
        penv.reset(seed=0)
        t0 = clock()
        for acts in actions:
            penv.step(acts)
        best = min(best, clock() - t0)
    return n * steps / best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=150)
    parser.add_argument("--ns", type=int, nargs="+", default=[5, 10, 50])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--clock", choices=CLOCKS, default="wall",
                        help="wall: elapsed time; cpu: this process's CPU time, steadier on a busy machine")
    args = parser.parse_args()
    rows = []
    for n in args.ns:
        clock = CLOCKS[args.clock]
        rate, stages, alive = ours(n, args.steps, args.repeats, clock)
        rows.append((n, rate, mpe(n, args.steps, args.repeats, clock), stages, alive))
    print(f"{'N':>3} {'uavform agent-steps/s':>22} {'MPE simple_spread':>18} {'ratio':>6} {'alive':>6}")
    for n, rate, ref, _, alive in rows:
        print(f"{n:>3} {rate:>22.0f} {ref:>18.0f} {rate / ref:>6.2f} {alive:>3}/{n}")
    print("\nmicroseconds per UAV-step, by stage (one timed replay)")
    print(f"{'stage':>16} " + " ".join(f"{'N=' + str(n):>8}" for n, *_ in rows))
    for label in rows[0][3]:
        print(f"{label:>16} " + " ".join(f"{r[3][label] * 1e6:>8.1f}" for r in rows))
    print(f"{'total':>16} " + " ".join(f"{sum(r[3].values()) * 1e6:>8.1f}" for r in rows))


if __name__ == "__main__":
    main()
