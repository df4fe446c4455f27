"""Why the expert's flights collide: the clearance each collision lost, split into the wind's part and the UAV's own
(issue 13: "where a target is missed, say which missions fail and why").

    python benchmarks/crash_causes.py FLIGHTS.jsonl... [--suite v1-dev] [--set NAME=VALUE ...] [--window 3]
                                      [--workers 2] [--out causes.jsonl] [--plot causes.png]

FLIGHTS are ``gust_seeds.py --out`` files, or a leaderboard's ``results.jsonl`` (its ``expert`` records: the
suite's own flights, wind 0). Every flight there that ended in a collision is flown again (its episode, wind seed
and the ``--set`` overrides of gust_seeds' run: the same flight bit for bit; a replay that ends otherwise is
reported, not split). For the first UAV that collided, over the last ``--window`` s up to the contact,
each step's displacement is the wind's (``env.drift`` x dt: the wind its autopilot did not compensate) plus its
own (the rest: the dynamics of its commands). The clearance it lost is split to first order along the way: the
gradient of what it collided on (the world's signed distance for an obstacle, the distance to the nearest x/y bound
for the edge of the world, the separation for another UAV, whose displacement counts too) dotted with each part,
summed over the window. Verdict "wind" when the wind's part of the loss is the larger, else "flown". ``--plot``
draws each collision's two parts against the clearance it had.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter

import numpy as np

from gust_seeds import parse_overrides, wind_seed
from uavform_env.collisions import CRASH_CAUSES
from uavform_env.dynamics import V
from uavform_env.evaluation.suites import Episode, load_suite
from uavform_env.files import atomic_write_figure, atomic_write_text
from uavform_env.parallel import imap_unordered

_STEP = 1e-4  # finite-difference step (m) of the clearance gradients


def gradient(clearance, p: np.ndarray) -> np.ndarray:
    """Central-difference gradient (3,) of the scalar function ``clearance`` of a point (3,) at ``p``."""
    e = np.eye(3) * _STEP
    return np.array([clearance(p + e[a]) - clearance(p - e[a]) for a in range(3)]) / (2.0 * _STEP)


def split_loss(positions: np.ndarray, winds: np.ndarray, clearance) -> tuple[float, float]:
    """(wind's, own) clearance lost along ``positions`` (K + 1, 3) whose K steps moved by ``winds`` (K, 3) in the
    wind and by the rest of each step on their own: the sums of -grad(clearance) . part at each step's start."""
    wind = own = 0.0
    for k in range(len(winds)):
        g = gradient(clearance, positions[k])
        step = positions[k + 1] - positions[k]
        wind -= float(g @ winds[k])
        own -= float(g @ (step - winds[k]))
    return wind, own


def _task(diagnostics: dict) -> str:
    """What the expert's cycle did (its diagnostics): the arrived leader "parked", a UAV with no way "holding", else
    "flying"."""
    return "parked" if diagnostics.get("arrived") else "holding" if diagnostics.get("unreachable") else "flying"


def _verdict(wind: float, own: float) -> str:
    return "wind" if wind > own else "flown"


def explain(episode: dict, k: int, overrides: dict, window: float) -> dict:
    """Fly ``episode`` under wind ``k`` again; split the first collision's clearance loss (``split_loss``)."""
    from baselines.fusion import ExpertConfig, FusionExpert
    from uavform_env.formation_v0 import parallel_env
    from uavform_env.metrics import episode_outcome
    from uavform_env.rollout import run_episode

    ep = Episode(**episode)
    penv = parallel_env(**ep.env_kwargs(), layout_seed=ep.seed)
    env = penv.unwrapped
    track = {"pos": [], "drift": [], "speed": [], "task": [], "crash": None}
    expert = FusionExpert(ExpertConfig(**overrides))

    def on_step(e):
        track["pos"].append(e.states[:, :3].copy())
        track["drift"].append(e.drift.copy())
        track["speed"].append(e.states[:, V].copy())
        track["task"].append([_task(expert.diagnostics.get(a, {})) for a in e.possible_agents])
        if track["crash"] is None and e.crashed.any():
            i = int(np.flatnonzero(e.crashed)[0])
            track["crash"] = (i, CRASH_CAUSES[int(e.crash_cause[i])], len(track["pos"]) - 1)

    run_episode(penv, expert, wind_seed(ep.seed, k), on_step=on_step)
    record = {"episode": ep.key, "wind": k, "outcome": episode_outcome(env)[0]}
    if track["crash"] is None:
        return record
    i, cause, t = track["crash"]
    pos, drift = np.array(track["pos"]), np.array(track["drift"])
    first = max(0, t - int(round(window / env.config.uav.dt)))
    dt, r_uav = env.config.uav.dt, env.config.uav.r_uav
    winds = drift[first + 1:t + 1] * dt
    if cause == "uav":                               # the separation from the nearest other UAV at the contact
        others = [j for j in range(env.n_uavs) if j != i]
        j = others[int(np.argmin(np.linalg.norm(pos[t, others] - pos[t, i], axis=1)))]
        rel = pos[first:t + 1, i] - pos[first:t + 1, j]
        wind, own = split_loss(rel, winds[:, i] - winds[:, j], lambda p: float(np.linalg.norm(p)))
        start = float(np.linalg.norm(rel[0])) - 2.0 * r_uav
    else:
        lo, hi = env.world.bounds_lo, env.world.bounds_hi
        surface = ((lambda p: float(env.world.clearance(p[None])[0])) if cause == "obstacle" else
                   (lambda p: min(p[0] - lo[0], hi[0] - p[0], p[1] - lo[1], hi[1] - p[1])))
        wind, own = split_loss(pos[first:t + 1, i], winds[:, i], surface)
        start = surface(pos[first, i]) - r_uav
    speed = float(np.mean(np.array(track["speed"])[first:max(t, first + 1), i]))        # its own speed (0 once crashed)
    return dict(record, uav=i, cause=cause, t=round((t + 1) * dt, 1), clearance_before=round(start, 3),
                wind_loss=round(wind, 3), own_loss=round(own, 3), mean_speed=round(speed, 3),
                task=Counter(track["task"][s][i] for s in range(first, t + 1)).most_common(1)[0][0],
                verdict=_verdict(wind, own))


def plot(records: list[dict], window: float, title: str, path: str) -> None:
    """Each split collision's clearance lost to the wind and to its own motion against the clearance it had
    ``window`` s before the contact; above the diagonal, that part alone took more than the UAV had."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    split = [r for r in records if "verdict" in r]
    before = np.array([r["clearance_before"] for r in split])
    fig, ax = plt.subplots(figsize=(6.0, 5.0))
    top = max([1.0, *before, *(r["wind_loss"] for r in split), *(r["own_loss"] for r in split)]) * 1.1
    ax.plot([0.0, top], [0.0, top], color="0.5", lw=0.8, ls="--", label="lost = clearance before")
    ax.scatter(before, [r["wind_loss"] for r in split], color="tab:blue", label="lost to the wind")
    ax.scatter(before, [r["own_loss"] for r in split], color="tab:red", marker="x", label="lost to its own motion")
    ax.axhline(0.0, color="0.8", lw=0.8)
    ax.set_xlim(0.0, top)
    ax.set_xlabel(f"clearance {window:g} s before the contact (m)")
    ax.set_ylabel(f"clearance lost over those {window:g} s (m)")
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=8, loc="upper left")
    ax.grid(True, lw=0.3, alpha=0.5)
    fig.tight_layout()
    atomic_write_figure(path, fig, format="png", dpi=90)
    plt.close(fig)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("flights", nargs="+", help="gust_seeds.py --out files")
    parser.add_argument("--suite", default="v1-dev", help="the suite the flights came from (default v1-dev)")
    parser.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE",
                        help="the ExpertConfig overrides the flights were flown with")
    parser.add_argument("--window", type=float, default=3.0, help="seconds before the contact (default 3)")
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--out", default=None, help="write one JSON line per collision here")
    parser.add_argument("--plot", default=None, help="draw the split collisions into this PNG")
    args = parser.parse_args(argv)
    try:
        if args.workers < 1:
            raise ValueError(f"--workers {args.workers}: expected at least 1")
        if not args.window > 0.0:
            raise ValueError(f"--window {args.window}: expected a positive number of seconds")
        overrides = parse_overrides(args.set)
        episodes = {e.key: e for e in load_suite(args.suite).episodes}
        crashed = []
        for path in args.flights:
            try:
                lines = open(path).read().splitlines()
            except OSError as e:
                raise ValueError(f"{path}: cannot read ({e.strerror})") from None
            for n, line in enumerate(lines, 1):
                try:
                    r = json.loads(line)
                    key, k, outcome = r["episode"], int(r.get("wind", 0)), str(r["outcome"])
                except (ValueError, KeyError, TypeError, AttributeError):
                    raise ValueError(f"{path}:{n}: neither a gust_seeds.py flight record nor a leaderboard result")\
                        from None
                if r.get("policy", "expert") != "expert":
                    continue
                if key not in episodes:
                    raise ValueError(f"{path}:{n}: episode {key} is not in --suite {args.suite}")
                if outcome.startswith("crash"):
                    crashed.append((episodes[key].to_dict(), k, overrides, args.window))
    except ValueError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    records = sorted(imap_unordered(explain, crashed, args.workers), key=lambda r: (r["episode"], r["wind"]))
    if args.out:
        atomic_write_text(args.out, "".join(json.dumps(r) + "\n" for r in records))
    split = [r for r in records if "verdict" in r]
    if args.plot:
        votes = Counter(r["verdict"] for r in split)
        plot(records, args.window, f"{args.suite}: {len(split)} collisions of the expert, {votes['wind']} carried by "
             f"the wind, {votes['flown']} flown in", args.plot)
    print(f"{len(crashed)} flights with a collision; over the last {args.window:g} s before the contact:")
    print("| cause | collisions | carried by the wind | flown in | clearance before (median, m) | "
          "lost to the wind (median, m) | lost to own motion (median, m) | own speed (median of means, m/s) |")
    print("|---|---|---|---|---|---|---|---|")
    for cause in sorted({r["cause"] for r in split}):
        rows = [r for r in split if r["cause"] == cause]
        votes = Counter(r["verdict"] for r in rows)
        med = {f: float(np.median([r[f] for r in rows])) for f in ("clearance_before", "wind_loss", "own_loss",
                                                                   "mean_speed")}
        print(f"| {cause} | {len(rows)} | {votes['wind']} | {votes['flown']} | {med['clearance_before']:.2f} | "
              f"{med['wind_loss']:.2f} | {med['own_loss']:.2f} | {med['mean_speed']:.2f} |")
    for r in records:
        if "verdict" not in r:
            print(f"  replay ended {r['outcome']}, not in a collision: {r['episode']} wind {r['wind']}")
        else:
            print(f"  {r['verdict']:5s} {r['task']:7s} uav {r['uav']} t={r['t']:5.1f} s  "
                  f"clearance {r['clearance_before']:5.2f}  wind {r['wind_loss']:5.2f}  own {r['own_loss']:5.2f}  "
                  f"{r['episode']} wind {r['wind']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
