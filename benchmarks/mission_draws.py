"""Missions, disturbances and airframes beyond the suites, drawn at random: how the expert does on cases nobody
tuned on.

    python benchmarks/mission_draws.py [--draws 60] [--seed 0] [--scenarios forest@2 urban@2 ...]
                                       [--n 1 16] [--spacing 1.2 3.5] [--wind-std 0 0.6] [--still-share 0.4]
                                       [--airframes 0] [--max-steps 3000] [--workers 2] [--policy expert]
                                       [--out draws.jsonl]

Draw ``i`` of ``--seed`` s has its own generator (``numpy.random.default_rng((s, i))``), so a draw is the same
mission whatever the other arguments are, and any flight can be flown again from its record. Each draw picks a
scenario of ``--scenarios`` (default: every family, both versions), a team of ``--n`` UAVs (lo, hi; classic-2d
flies one), a formation that holds it, a spacing in ``--spacing`` (m), the scenario's difficulty and a disturbance
(``DisturbanceConfig``): with probability ``--still-share`` still air, else gusts of standard deviation uniform in
``--wind-std`` with a mean wind of up to 1 m/s, a correlation time of 0.5-5 s and a vertical share of 0-1; range
noise of 0-0.15 m and 0-30 % lost rays, each present half the time. With probability ``--airframes`` the draw
also changes the env's config (``EnvConfig``, its own generator ``(s, i, 1)``, so the mission stays the same):
each of these, half the time: the UAV's v_max (0.5-2 m/s), w_max (15-45 deg/s), a_max (0.1-0.5 m/s^2), dt (0.05,
0.1 or 0.2 s) and r_uav (0.2-0.35 m); the sensor's rays (18, 36 or 72 x 5, 7 or 11) and r_max (4-10 m); the map's
resolution (0.1 or 0.4 m); a 2.5D prior map. The layout and episode seed is 700000 + i.
The flights run in at most ``--workers`` processes. Prints one line per flight (its outcome and the env's sentence
saying why) and a table of outcomes per family; ``--out`` writes one JSON record per flight (mission,
disturbance, outcome). Ranges are checked before any flight: a bad one is a one-line error.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from collections import Counter, defaultdict

import numpy as np

import expert_success
from uavform_env.parallel import imap_unordered

FAMILIES = ("classic-2d@1", "classic-2d@2", "forest@1", "forest@2", "urban@1", "urban@2", "wall-gap@1", "wall-gap@2",
            "corridor@1", "corridor@2", "random-3d@1", "random-3d@2", "dog-leg@1")
SEED_BASE = 700000


def draw(seed: int, i: int, scenarios, n_range, spacing_range, wind_std_range, still_share: float,
         airframes: float = 0.0) -> dict:
    """Draw ``i`` of ``seed``: the ``parallel_env`` keyword arguments (the disturbance as a dict of
    ``DisturbanceConfig`` fields, the config changes as {part: {field: value}} of ``EnvConfig``) and the episode
    seed."""
    from uavform_env.formation import MAX_UAVS
    from uavform_env.scenarios import scenario_options

    rng = np.random.default_rng((seed, i))
    scenario = str(scenarios[rng.integers(len(scenarios))])
    info = scenario_options(scenario)
    kwargs = {"scenario": scenario}
    if info["n_uavs"] != 1:                          # classic-2d's maps fly one UAV
        n = int(rng.integers(n_range[0], n_range[1] + 1))
        shapes = [s for s, cap in MAX_UAVS.items() if cap is None or n <= cap]
        kwargs.update(n_uavs=n, formation=str(shapes[rng.integers(len(shapes))]),
                      spacing=round(float(rng.uniform(*spacing_range)), 2))
    if info["difficulties"]:
        kwargs["difficulty"] = str(info["difficulties"][rng.integers(len(info["difficulties"]))])
    disturbance = {}
    if rng.random() >= still_share:
        disturbance.update(wind_std=round(float(rng.uniform(*wind_std_range)), 2),
                           wind_mean=tuple(round(float(m), 2) for m in rng.uniform(-0.7, 0.7, 2)),
                           wind_tau=round(float(rng.uniform(0.5, 5.0)), 2),
                           wind_vertical=round(float(rng.uniform(0.0, 1.0)), 2))
    if rng.random() < 0.5:
        disturbance["range_noise_std"] = round(float(rng.uniform(0.0, 0.15)), 3)
    if rng.random() < 0.5:
        disturbance["ray_dropout"] = round(float(rng.uniform(0.0, 0.3)), 3)
    return {"draw": i, "kwargs": kwargs, "disturbance": disturbance, "config": _airframe(seed, i, airframes),
            "seed": SEED_BASE + i}


def _airframe(seed: int, i: int, share: float) -> dict:
    """The config changes of draw ``i`` (``draw``'s docstring): none with probability 1 - ``share``."""
    rng = np.random.default_rng((seed, i, 1))
    if rng.random() >= share:
        return {}
    options = {
        "uav": {"v_max": lambda: round(float(rng.uniform(0.5, 2.0)), 2),
                "w_max": lambda: round(math.radians(float(rng.uniform(15.0, 45.0))), 3),
                "a_max": lambda: round(float(rng.uniform(0.1, 0.5)), 2),
                "dt": lambda: float(rng.choice([0.05, 0.1, 0.2])),
                "r_uav": lambda: round(float(rng.uniform(0.2, 0.35)), 2)},
        "sensor": {"n_azimuth": lambda: int(rng.choice([18, 36, 72])),
                   "n_elevation": lambda: int(rng.choice([5, 7, 11])),
                   "r_max": lambda: round(float(rng.uniform(4.0, 10.0)), 1)},
        "map": {"resolution": lambda: float(rng.choice([0.1, 0.4]))},
        "episode": {"prior_map": lambda: "heightmap"},
    }
    changes = {}
    for part, fields in options.items():
        for name, value in fields.items():
            if rng.random() < 0.5:
                changes.setdefault(part, {})[name] = value()
    return changes


def fly(mission: dict, max_steps: int, policy_name: str) -> dict:
    """Fly one drawn mission (``expert_success.fly_env``), or refuse it when its env cannot be built or reset (a
    mission its drawn airframe cannot fly); its record with the outcome, the env's reason and the steps."""
    from uavform_env.config import DisturbanceConfig, EnvConfig
    from uavform_env.formation_v0 import parallel_env

    t0 = time.perf_counter()
    try:                                    # a mission its drawn airframe cannot fly is refused here (validate_scenario)
        penv = parallel_env(**mission["kwargs"], max_cycles=max_steps, layout_seed=mission["seed"],
                            disturbance=DisturbanceConfig(**mission["disturbance"]),
                            config=EnvConfig.from_dict(mission.get("config", {})))
        penv.reset(seed=mission["seed"])
    except ValueError as e:
        return {**mission, "outcome": "refused", "detail": str(e).splitlines()[0], "steps": 0, "seconds": 0.0}
    r = expert_success.fly_env(penv, mission["kwargs"]["scenario"], mission["seed"], policy_name, t0)
    return {**mission, "outcome": r["outcome"], "detail": r["detail"], "steps": r["steps"],
            "seconds": round(r["seconds"], 1)}


def _pair(p, flag: str, values, lo: float, hi: float, integer: bool = False) -> tuple:
    """``values`` (lo, hi) of ``flag`` checked to lie in order within [lo, hi] (integers if ``integer``)."""
    a, b = values
    if not lo <= a <= b <= hi or (integer and (a != int(a) or b != int(b))):
        kind = "integers" if integer else "numbers"
        p.error(f"{flag} {a:g} {b:g}: expected two {kind} lo <= hi within [{lo:g}, {hi:g}]")
    return (int(a), int(b)) if integer else (float(a), float(b))


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--draws", type=int, default=60)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--scenarios", nargs="+", default=list(FAMILIES))
    p.add_argument("--n", nargs=2, type=float, default=(1, 16), metavar=("LO", "HI"))
    p.add_argument("--spacing", nargs=2, type=float, default=(1.2, 3.5), metavar=("LO", "HI"))
    p.add_argument("--wind-std", nargs=2, type=float, default=(0.0, 0.6), metavar=("LO", "HI"))
    p.add_argument("--still-share", type=float, default=0.4)
    p.add_argument("--airframes", type=float, default=0.0, help="share of draws that also change the env's config")
    p.add_argument("--max-steps", type=int, default=3000)
    p.add_argument("--workers", type=int, default=1, choices=(1, 2))
    p.add_argument("--policy", default="expert")
    p.add_argument("--out", default=None)
    a = p.parse_args(argv)
    if a.draws < 1 or a.seed < 0 or a.max_steps < 1:
        p.error(f"--draws {a.draws}, --seed {a.seed}, --max-steps {a.max_steps}: expected --draws >= 1, "
                "--seed >= 0 and --max-steps >= 1")
    for flag, share in (("--still-share", a.still_share), ("--airframes", a.airframes)):
        if not 0.0 <= share <= 1.0:
            p.error(f"{flag} {share:g}: expected a share in [0, 1]")
    n_range = _pair(p, "--n", a.n, 1, 64, integer=True)
    spacing = _pair(p, "--spacing", a.spacing, 0.6, 10.0)
    wind_std = _pair(p, "--wind-std", a.wind_std, 0.0, 10.0)
    from uavform_env.policies import load_policy
    from uavform_env.scenarios import scenario_options
    try:
        load_policy(a.policy)
    except ValueError as e:
        p.error(f"--policy: {e}")
    for s in a.scenarios:
        try:
            scenario_options(s)
        except ValueError as e:
            p.error(f"--scenarios {s}: {e}")
    missions = [draw(a.seed, i, a.scenarios, n_range, spacing, wind_std, a.still_share, a.airframes)
                for i in range(a.draws)]
    t0 = time.perf_counter()
    records = []
    for r in imap_unordered(fly, [(m, a.max_steps, a.policy) for m in missions], a.workers):
        records.append(r)
        config = f" {json.dumps(r['config'])}" if r["config"] else ""
        print(f"  draw {r['draw']:>3} {r['outcome']:<14} {json.dumps(r['kwargs'])} {json.dumps(r['disturbance'])}"
              f"{config}{'  ' + r['detail'] if r['detail'] else ''} ({r['seconds']:.0f} s)", flush=True)
    records.sort(key=lambda r: r["draw"])
    if a.out:
        from uavform_env.files import atomic_write_text
        atomic_write_text(a.out, "".join(json.dumps(r) + "\n" for r in records))
    by_family = defaultdict(Counter)
    for r in records:
        by_family[r["kwargs"]["scenario"]][r["outcome"]] += 1
    outcomes = sorted({r["outcome"] for r in records})
    print(f"\n{a.policy}, {a.draws} draws of seed {a.seed} (airframes {a.airframes:g}), max {a.max_steps} steps; "
          f"wall time {time.perf_counter() - t0:.0f} s")
    print("| scenario | " + " | ".join(outcomes) + " |\n|---|" + "---|" * len(outcomes))
    for s in sorted(by_family):
        print(f"| {s} | " + " | ".join(str(by_family[s][o]) for o in outcomes) + " |")
    total = Counter(r["outcome"] for r in records)
    print("| all | " + " | ".join(str(total[o]) for o in outcomes) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
