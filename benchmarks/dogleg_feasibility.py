"""How long a dog-leg mission's leader route must be, for any controller: the oracle and a greedy explorer.

    python benchmarks/dogleg_feasibility.py [--suite v1-dev] [--scenario dog-leg@1] [--speed 0.8]

For each episode of the suite's ``--scenario`` episodes (the v1 suites' ids, so tuning stays on v1-dev) it prints
the leader's shortest route on the true obstacle raster (A*, inflated by r_uav + r_safe: a controller that knew the
map) and the route of a greedy explorer: a point that sees the true raster within the sensor's r_max over 360
degrees (rays stop at the first obstacle cell), plans A* on what it has seen with the unseen as free (the expert's
``explore_unknown`` reading of unknown space) and moves ``step`` m along that plan, replanning after every step. It
picks a door's side by the route through unseen space, as any controller without the map must, and turns back when
the wall is seen to reach the world's bound. Each length is also given in seconds at ``--speed`` (the expert's leader
cap, 0.8 x v_max) against the episode's step limit: a route longer than speed x time limit cannot be flown in time
at that speed, whatever the controller does on it (turns and followers cost more).
"""

from __future__ import annotations

import argparse
import math

import numpy as np


def visible(blocked: np.ndarray, origin, res: float, pos, r_max: float, n_rays: int = 720) -> np.ndarray:
    """The raster cells a 360-degree range sensor at ``pos`` sees out to ``r_max``: each ray's cells up to and
    including the first blocked one (vectorised over rays and samples)."""
    ang = np.linspace(0.0, 2.0 * math.pi, n_rays, endpoint=False)
    r = np.arange(0.0, r_max + res / 4, res / 2)
    px = pos[0] + np.cos(ang)[:, None] * r[None, :]
    py = pos[1] + np.sin(ang)[:, None] * r[None, :]
    i = np.floor((px - origin[0]) / res).astype(int)
    j = np.floor((py - origin[1]) / res).astype(int)
    inside = (i >= 0) & (j >= 0) & (i < blocked.shape[0]) & (j < blocked.shape[1])
    hit = np.zeros_like(inside)
    hit[inside] = blocked[i[inside], j[inside]]
    hit |= ~inside
    first = np.where(hit.any(axis=1), hit.argmax(axis=1), r.size - 1)          # the first blocked sample per ray
    keep = (np.arange(r.size)[None, :] <= first[:, None]) & inside
    seen = np.zeros(blocked.shape, bool)
    seen[i[keep], j[keep]] = True
    return seen


def greedy_explorer(blocked, raster, start, goal, inflate_radius: float, r_max: float, cfg, step: float = 0.5,
                    arrive: float = 0.3, max_length: float = 300.0) -> float:
    """The length a greedy explorer flies from ``start`` to within ``arrive`` of ``goal`` (inf: none by
    ``max_length``)."""
    from baselines.astar import plan_path

    known = np.zeros(blocked.shape, bool)
    pos = np.asarray(start, dtype=np.float64)
    flown = 0.0
    while flown < max_length:
        known |= visible(blocked, raster.origin, raster.res, pos, r_max) & blocked
        if math.dist(pos, goal) <= arrive:
            return flown
        path = plan_path(known, raster, pos, goal, inflate_radius, cfg)
        if path is None:
            return math.inf
        nxt = path.lookahead(pos, step) if path.length > step else np.asarray(goal, dtype=np.float64)
        flown += math.dist(pos, nxt)
        pos = nxt
    return math.inf


def main(argv=None) -> int:
    from baselines.astar import AStarConfig, Raster, plan_path
    from uavform_env.evaluation.suites import load_suite
    from uavform_env.formation_v0 import parallel_env

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--suite", default="v1-dev")
    p.add_argument("--scenario", default="dog-leg@1")
    p.add_argument("--speed", type=float, default=0.8)
    p.add_argument("--res", type=float, default=0.2)
    a = p.parse_args(argv)
    if not a.speed > 0.0 or not a.res > 0.0:
        p.error("--speed and --res: expected positive numbers")
    cfg = AStarConfig(prune=True, res_g=a.res)
    try:
        suite = load_suite(a.suite)
    except ValueError as e:
        p.error(f"--suite: {e}")
    episodes = [ep for ep in suite.episodes if ep.scenario == a.scenario]
    if not episodes:
        p.error(f"--scenario {a.scenario!r}: no episode of suite {a.suite!r} flies it")
    print(f"{'episode':<46} {'oracle m':>8} {'greedy m':>8} {'oracle s':>8} {'greedy s':>8} {'limit s':>7}")
    for ep in episodes:
        penv = parallel_env(**ep.env_kwargs())
        penv.reset(seed=ep.seed)
        env = penv.unwrapped
        lim = env.config.uav
        origin, res, heights = env.world.heightmap(a.res)
        blocked = heights > 0.0
        raster = Raster(tuple(origin), res, blocked.shape)
        start, goal = env.states[0, :2].copy(), env.goal[:2].copy()
        h = lim.r_uav + lim.r_safe
        best = plan_path(blocked, raster, start, goal, h, cfg)
        oracle = best.length if best is not None else math.inf
        greedy = greedy_explorer(blocked, raster, start, goal, h, env.config.sensor.r_max, cfg)
        limit = ep.max_cycles * lim.dt
        print(f"{ep.key:<46} {oracle:8.1f} {greedy:8.1f} {oracle / a.speed:8.0f} {greedy / a.speed:8.0f} {limit:7.0f}",
              flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
