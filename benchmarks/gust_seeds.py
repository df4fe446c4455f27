"""A fair judge of a wind rule: each windy episode of a suite flown under several wind seeds (issue 13, gusts).

    python benchmarks/gust_seeds.py --suite v1-dev --wind gusty --winds 4 [--first-wind 0]
                                    [--set wind_margin=2.0 dwa.brake_share=1]
                                    [--workers 2] [--only forest@2 corridor@2] [--out flights.jsonl]

A suite fixes each episode's obstacle layout and its wind by one seed, so a slice of single flights swings by a
few crashes from any change of the flight (session 8: +-2 crashes of 28). Here the layout stays the episode's
(``FormationEnv(layout_seed=episode.seed)``) and the reset seed, which draws the gust field, runs over ``--winds``
seeds: wind 0 is the episode's own seed (its flight is the suite's, bit for bit), wind k > 0 the seed
``SeedSequence([episode.seed, k])`` draws; ``--first-wind k`` starts at wind k, so a later run adds winds to an
earlier one (``compare_flights.py`` reads both files as one side). The policy is the expert (``FusionExpert``) with
the ``--set`` overrides of its ``ExpertConfig`` fields (``part.name`` for a field of its ``dwa``, ``vfh`` or
``astar`` config). Printed: flights, flights with a collision, successes, the median over flights of the formation
error's RMS (``episode_metrics``); the end game of the flights that failed after their leader came within r_goal of
the goal (how long before the end, how often the leader was within r_goal and the followers all within e_f since:
success needs both at once; whether a live follower never came within e_f after the arrival); and per episode the
outcomes of its winds (s success, t time-out, c crash);
``--out`` keeps one JSON line per flight (written whole or not at all), which ``benchmarks/compare_flights.py``
pairs with another run's flight by flight.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import fields, replace

import numpy as np

from baselines.fusion import ExpertConfig
from uavform_env.evaluation.suites import Episode, load_suite
from uavform_env.files import atomic_write_text
from uavform_env.parallel import imap_unordered

MARKS = {"success": "s", "timeout": "t"}
PARTS = ("dwa", "vfh", "astar")  # the sub-configs of ExpertConfig that --set part.name reaches


def wind_seed(episode_seed: int, k: int) -> int:
    """The reset seed of wind ``k`` of an episode: its own seed for k = 0, else one drawn from (seed, k)."""
    return episode_seed if k == 0 else int(np.random.SeedSequence([episode_seed, k]).generate_state(1)[0])


def fly(episode: dict, k: int, overrides: dict) -> dict:
    """One flight of ``episode`` (its layout) under wind ``k`` by the expert with ``overrides``: a result record."""
    from baselines.fusion import FusionExpert
    from uavform_env.formation_v0 import parallel_env
    from uavform_env.metrics import episode_metrics, episode_outcome
    from uavform_env.rollout import run_episode

    ep = Episode(**episode)
    penv = parallel_env(**ep.env_kwargs(), layout_seed=ep.seed)
    reach = {"step": None, "steps": 0, "leader": 0, "followers": 0, "ever": np.zeros(ep.n_uavs - 1, dtype=bool)}

    def after_reach(env):
        """From the first step the leader is within r_goal of the goal: how often it is, all live followers within
        e_f of their slots (success needs both at once), and which followers have been within e_f since."""
        leader_in = env.goal_distance() < env.config.episode.r_goal
        if reach["step"] is None and leader_in:
            reach["step"] = env.step_count
        if reach["step"] is not None:
            live = ~env.history["crashed"][-1][1:]
            near = env.history["formation_error"][-1][1:] < env.config.formation.e_f
            reach["steps"] += 1
            reach["leader"] += leader_in
            reach["followers"] += bool(near[live].all())
            reach["ever"] |= near & live

    start = time.perf_counter()
    run_episode(penv, FusionExpert(ExpertConfig(**overrides)), wind_seed(ep.seed, k), on_step=after_reach)
    env = penv.unwrapped
    outcome, detail = episode_outcome(env)
    reached = reach["step"] is not None
    return {"episode": ep.key, "scenario": ep.scenario, "preset": ep.wind, "wind": k, "outcome": outcome,
            "detail": detail, "steps": int(env.step_count), "wall_time": time.perf_counter() - start,
            "formation_error_rms": episode_metrics(env)["formation_error_rms"], "n_uavs": ep.n_uavs,
            "after_reach_s": (env.step_count - reach["step"]) * env.config.uav.dt if reached else None,
            "after_reach_leader_in": reach["leader"] / reach["steps"] if reached else None,
            "after_reach_followers_in": reach["followers"] / reach["steps"] if reached else None,
            "after_reach_followers_never": int((~reach["ever"] & ~env.crashed[1:]).sum()) if reached else None}


def end_game(records: list[dict]) -> str:
    """One line on the flights whose leader came within r_goal of the goal and that still failed (records that
    carry ``after_reach_s``)."""
    late = [r for r in records if r.get("after_reach_s") is not None and r["outcome"] != "success"]
    if not late:
        return "no flight failed after its leader came within r_goal of the goal"
    never = sum(r["after_reach_followers_in"] == 0.0 for r in late)
    wait = np.median([r["after_reach_s"] for r in late])
    line = (f"{len(late)} flights failed after the leader came within r_goal of the goal (median {wait:.0f} s before "
            f"the end; UAVs {min(r['n_uavs'] for r in late)}-{max(r['n_uavs'] for r in late)}): in {never} of them the "
            f"followers were never all within e_f at once; the leader was within r_goal in a median "
            f"{100 * np.median([r['after_reach_leader_in'] for r in late]):.0f} % of those steps")
    split = [r for r in late if r.get("after_reach_followers_never") is not None]
    if not split:
        return line
    lost = sum(r["after_reach_followers_never"] > 0 for r in split)
    return (f"{line}; in {lost} of {len(split)} a live follower never came within e_f of its slot after the arrival "
            f"(in the other {len(split) - lost} each one did, but not all together with the leader)")


def parse_overrides(items: list[str]) -> dict:
    """``name=value`` pairs of ExpertConfig fields, or ``part.name=value`` of a field of its ``dwa``, ``vfh`` or
    ``astar`` config, each value converted to the type of the field's default (a choice's is checked by the config)."""
    base = ExpertConfig()
    out, parts = {}, {}
    for item in items:
        name, sep, text = item.partition("=")
        part, dot, field = name.rpartition(".")
        owner = (getattr(base, part) if part in PARTS else None) if dot else base
        default = getattr(owner, field) if owner is not None and field in {f.name for f in fields(owner)} else None
        if not sep or not isinstance(default, (bool, int, float, str)):
            raise ValueError(f"--set {item!r}: expected name=value with name a number, flag or choice field of "
                             "ExpertConfig, or of its dwa, vfh or astar config as part.name")
        kind = type(default)
        try:
            value = (text.lower() in ("1", "true", "yes")) if kind is bool else kind(text)
        except ValueError:
            raise ValueError(f"--set {item!r}: expected a {kind.__name__} value for {name}") from None
        (parts.setdefault(part, {}) if dot else out)[field] = value
    for part, values in parts.items():
        out[part] = replace(getattr(base, part), **values)
    ExpertConfig(**out)                                               # bounds checked before any flight
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--suite", default="v1-dev", help="suite name or .toml path (default v1-dev)")
    parser.add_argument("--wind", default="gusty", help="keep the episodes of this disturbance preset (default gusty)")
    parser.add_argument("--only", nargs="*", default=None, help="keep the episodes of these scenarios (e.g. forest@2)")
    parser.add_argument("--winds", type=int, default=4, help="wind seeds per episode (default 4)")
    parser.add_argument("--first-wind", type=int, default=0,
                        help="fly winds first-wind .. first-wind + winds - 1 (default 0: the episode's own first)")
    parser.add_argument("--set", nargs="*", default=[], metavar="NAME=VALUE", help="ExpertConfig overrides")
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--out", default=None, help="write one JSON line per flight here")
    args = parser.parse_args(argv)
    try:
        if args.winds < 1 or args.workers < 1:
            raise ValueError("--winds and --workers: expected at least 1")
        if args.first_wind < 0:
            raise ValueError(f"--first-wind {args.first_wind}: expected 0 or more")
        overrides = parse_overrides(args.set)
        episodes = [e for e in load_suite(args.suite).episodes if e.wind == args.wind
                    and (args.only is None or e.scenario in args.only)]
        if not episodes:
            raise ValueError(f"--suite {args.suite}: no episode with disturbance {args.wind!r}"
                             + (f" in scenarios {args.only}" if args.only else ""))
    except ValueError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    winds = range(args.first_wind, args.first_wind + args.winds)
    calls = [(e.to_dict(), k, overrides) for e in episodes for k in winds]
    records = sorted(imap_unordered(fly, calls, args.workers), key=lambda r: (r["episode"], r["wind"]))
    if args.out:
        atomic_write_text(args.out, "".join(json.dumps(r) + "\n" for r in records))
    crashed = [r for r in records if r["outcome"].startswith("crash")]
    success = [r for r in records if r["outcome"] == "success"]
    errors = [r["formation_error_rms"] for r in records if not math.isnan(r["formation_error_rms"])]
    print(f"overrides {' '.join(args.set) or 'none'}; {len(episodes)} episodes x {args.winds} winds = "
          f"{len(records)} flights: {len(crashed)} with a collision, {len(success)} successes; formation error RMS "
          + (f"median {np.median(errors):.2f} m (flights with followers)" if errors else "- (no followers)"))
    print(end_game(records))
    for e in episodes:
        marks = "".join(MARKS.get(r["outcome"], "c") for r in records if r["episode"] == e.key)
        print(f"  {marks}  {e.key}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
