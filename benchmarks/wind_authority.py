"""What the airframe can do against each wind preset: how often the wind outruns it, and how far it wanders
holding a point (issue 13: "keep station under wind"; README, "Disturbances").

    python benchmarks/wind_authority.py [--seeds 20] [--seconds 60]

One UAV in an empty field (``disturbance_drift.field``), per preset and seed, for ``--seconds``:
- the share of steps whose horizontal wind (the env's gust plus its mean, ``env.air``) is faster than v_max;
- the largest distance from its start of the UAV flying ``rules.station_keep`` about the start through the env's
  own dynamics (unicycle: v in [0, v_max], a_max, w_max), once with the exact wind ("oracle") and once with
  its own estimate (``rules.wind_estimate``, as the expert flies);
- the same for an ideal holder that turns instantly and moves in any direction at up to v_max, knowing the wind
  (u = -(wind + k_hold p), capped at v_max), integrated on the recorded wind: what the speed limit alone allows.
"""

from __future__ import annotations

import argparse
import math
from types import SimpleNamespace

import numpy as np

from baselines.fusion import ExpertConfig
from baselines.fusion.rules import station_keep, wind_estimate
from disturbance_drift import field
from uavform_env import parallel_env
from uavform_env.dynamics import commands_to_actions


def hold(preset: str, seed: int, seconds: float, oracle: bool):
    """(largest distance from the start (m), the horizontal wind speed of every step (m/s)) of one holding flight."""
    cfg = ExpertConfig()
    steps = int(round(seconds / 0.1))
    penv = parallel_env(scenario=field(1), max_cycles=steps, disturbance=preset)
    penv.reset(seed=seed)
    env = penv.unwrapped
    lim = env.config.uav
    start = env.states[0, :2].copy()
    mem = SimpleNamespace(wind=np.zeros(2), prev_pose=None)
    air = np.zeros(2)
    worst, speeds = 0.0, []
    while penv.agents:
        view = SimpleNamespace(state=env.states[0].copy(), limits=lim)
        wind_estimate(view, mem, cfg)
        if oracle:
            mem.wind = air.copy()                   # the wind of the last step, exactly
        cmd = station_keep(view, mem, cfg, start, 0.0)
        penv.step({"uav_0": commands_to_actions(np.array([cmd.v, cmd.w, 0.0]), lim)})
        air = env.air[0, :2].copy()
        speeds.append(math.hypot(air[0], air[1]))
        worst = max(worst, float(np.hypot(*(env.states[0, :2] - start))))
    return worst, np.array(speeds)


def ideal(speeds_xy: np.ndarray, v_max: float, k: float, dt: float) -> float:
    """Largest distance from the start of the ideal holder on the wind series ``speeds_xy`` (T, 2)."""
    p = np.zeros(2)
    worst = 0.0
    for air in speeds_xy:
        u = -(air + k * p)
        s = math.hypot(u[0], u[1])
        if s > v_max:
            u *= v_max / s
        p += (air + u) * dt
        worst = max(worst, math.hypot(p[0], p[1]))
    return worst


def wind_series(preset: str, seed: int, seconds: float) -> np.ndarray:
    """(T, 2) horizontal wind of a UAV that holds still (with a 20 m correlation length the gusts barely change
    over the few metres a holder moves)."""
    steps = int(round(seconds / 0.1))
    penv = parallel_env(scenario=field(1), max_cycles=steps, disturbance=preset)
    penv.reset(seed=seed)
    env = penv.unwrapped
    out = []
    while penv.agents:
        penv.step({"uav_0": np.array([-1.0, 0.0, 0.0], np.float32)})
        out.append(env.air[0, :2].copy())
    return np.array(out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--seconds", type=float, default=60.0)
    args = parser.parse_args()
    cfg = ExpertConfig()
    lim = parallel_env(scenario=field(1)).unwrapped.config.uav
    print(f"| preset | wind > v_max ({lim.v_max:g} m/s), share of time | wind > 0.5 v_max | largest excursion "
          f"holding a point for {args.seconds:g} s, median / p95 (m): unicycle, own wind estimate | unicycle, "
          "exact wind | ideal holonomic holder |")
    print("|---|---|---|---|---|---|")
    for preset in ("breeze", "gusty"):
        own = [hold(preset, s, args.seconds, False)[0] for s in range(args.seeds)]
        exact = [hold(preset, s, args.seconds, True)[0] for s in range(args.seeds)]
        series = [wind_series(preset, s, args.seconds) for s in range(args.seeds)]
        speeds = np.concatenate([np.hypot(w[:, 0], w[:, 1]) for w in series])
        best = [ideal(w, lim.v_max, cfg.k_hold, lim.dt) for w in series]

        def cell(x):
            return f"{np.median(x):.2f} / {np.percentile(x, 95):.2f}"
        print(f"| `{preset}` | {np.mean(speeds > lim.v_max):.3f} | {np.mean(speeds > 0.5 * lim.v_max):.3f} | "
              f"{cell(own)} | {cell(exact)} | {cell(best)} |")


if __name__ == "__main__":
    main()
