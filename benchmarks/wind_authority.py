"""What the airframe can do against each wind preset: how often the wind outruns it, and how far it wanders
holding a point (issue 13: "keep station under wind"; README, "Disturbances").

    python benchmarks/wind_authority.py [--seeds 20] [--seconds 60]

One UAV in an empty field (``disturbance_drift.field``), per preset, airframe and seed, for ``--seconds``:
- the share of steps whose horizontal wind (the env's gust plus its mean, ``env.air``) is faster than v_max, and
  the share whose drift (the wind the autopilot has not compensated, ``env.drift`` = air - lean) is faster than
  v_max and than v_max / 2;
- the largest distance from its start of the UAV flying ``rules.station_keep`` about the start through the env's
  own dynamics (unicycle: v in [0, v_max], a_max, w_max), once with the exact drift of the last step ("oracle")
  and once with its own estimate (``rules.wind_estimate``, as the expert flies);
- the same for an ideal holder that turns instantly and moves in any direction at up to v_max, knowing the drift
  (u = -(drift + k_hold p), capped at v_max), integrated on the recorded drift: what the speed limit alone allows;
- the clearance a holding UAV needs (issue 13, gusts): the 99th percentile, over every step of every seed after the
  first 5 s, of the distance from the start of the unicycle holding with the exact drift and of one hovering at
  v = 0 (its autopilot alone), and the median RMS drift (``rules.gust_speed``) it measures, which wind margins
  scale with; their ratio is the margin time (s) that covers the p99 wander.
Airframes (``disturbance_drift.AIRFRAMES``): the default, whose autopilot leans into its lagging wind estimate
(``UAVLimits.wind_authority``, ``wind_rejection_tau``), and the unopposed model (``wind_authority=0``).
"""

from __future__ import annotations

import argparse
import math
from types import SimpleNamespace

import numpy as np

from baselines.fusion import ExpertConfig
from baselines.fusion.rules import WindMemory, gust_speed, station_keep, wind_estimate
from disturbance_drift import AIRFRAMES, field
from uavform_env import parallel_env
from uavform_env.config import EnvConfig, UAVLimits
from uavform_env.dynamics import commands_to_actions


def hold(preset: str, seed: int, seconds: float, mode: str, uav: UAVLimits) -> tuple[np.ndarray, np.ndarray]:
    """Each step's distance from the start (m) of one holding flight, and the RMS drift the UAV measures then:
    ``mode`` "own" (station keeping on its own wind estimate), "oracle" (on the exact drift), "hover" (v = 0)."""
    cfg = ExpertConfig()
    steps = int(round(seconds / uav.dt))
    penv = parallel_env(scenario=field(1), max_cycles=steps, disturbance=preset, config=EnvConfig(uav=uav))
    penv.reset(seed=seed)
    env = penv.unwrapped
    lim = env.config.uav
    start = env.states[0, :2].copy()
    mem = WindMemory()
    dist, gust = [], []
    while penv.agents:
        view = SimpleNamespace(state=env.states[0].copy(), limits=lim)
        wind_estimate(view, mem, cfg)
        if mode == "oracle":
            mem.wind = env.drift[0, :2].copy()      # the drift of the last step, exactly
        cmd = station_keep(view, mem, cfg, start, 0.0, math.inf) if mode != "hover" else SimpleNamespace(v=0.0, w=0.0)
        penv.step({"uav_0": commands_to_actions(np.array([cmd.v, cmd.w, 0.0]), lim)})
        dist.append(float(np.hypot(*(env.states[0, :2] - start))))
        gust.append(gust_speed(mem))
    return np.array(dist), np.array(gust)


def ideal(speeds_xy: np.ndarray, v_max: float, k: float, dt: float) -> float:
    """Largest distance from the start of the ideal holder on the drift series ``speeds_xy`` (T, 2)."""
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


def wind_series(preset: str, seed: int, seconds: float, uav: UAVLimits) -> tuple[np.ndarray, np.ndarray]:
    """(T, 2) horizontal wind and (T, 2) horizontal drift of a UAV that commands zero speed (with a 20 m
    correlation length the gusts barely change over the few metres a holder moves)."""
    steps = int(round(seconds / uav.dt))
    penv = parallel_env(scenario=field(1), max_cycles=steps, disturbance=preset, config=EnvConfig(uav=uav))
    penv.reset(seed=seed)
    env = penv.unwrapped
    air, drift = [], []
    while penv.agents:
        penv.step({"uav_0": np.array([-1.0, 0.0, 0.0], np.float32)})
        air.append(env.air[0, :2].copy())
        drift.append(env.drift[0, :2].copy())
    return np.array(air), np.array(drift)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--seconds", type=float, default=60.0)
    args = parser.parse_args()
    warm_up = 5.0                                   # s: the p99 and RMS columns leave out each flight's first seconds
    if args.seeds < 1:
        parser.error(f"--seeds {args.seeds}: expected at least 1")
    if not args.seconds > warm_up:
        parser.error(f"--seconds {args.seconds:g}: expected more than the {warm_up:g} s warm-up the p99 and RMS "
                     "columns leave out")
    cfg = ExpertConfig()
    v_max = UAVLimits().v_max
    print(f"| preset | airframe | wind > v_max ({v_max:g} m/s), share of time | drift > v_max | drift > 0.5 v_max | "
          f"largest excursion holding a point for {args.seconds:g} s, median / p95 (m): unicycle, own wind "
          "estimate | unicycle, exact drift | ideal holonomic holder | distance from the point, p99 of all steps (m): "
          "unicycle, exact drift / hovering at v = 0 | median RMS drift (m/s) | p99 / RMS drift (s) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    warm = int(round(warm_up / UAVLimits().dt))
    for preset in ("breeze", "gusty"):
        for label, uav in AIRFRAMES:
            own = [hold(preset, s, args.seconds, "own", uav)[0].max() for s in range(args.seeds)]
            flights = [hold(preset, s, args.seconds, "oracle", uav) for s in range(args.seeds)]
            exact = [d.max() for d, _ in flights]
            p99 = np.percentile(np.concatenate([d[warm:] for d, _ in flights]), 99)
            rms = np.median(np.concatenate([g[warm:] for _, g in flights]))
            hover = np.percentile(np.concatenate([hold(preset, s, args.seconds, "hover", uav)[0][warm:]
                                                  for s in range(args.seeds)]), 99)
            series = [wind_series(preset, s, args.seconds, uav) for s in range(args.seeds)]
            wind = np.concatenate([np.hypot(a[:, 0], a[:, 1]) for a, _ in series])
            drift = np.concatenate([np.hypot(d[:, 0], d[:, 1]) for _, d in series])
            best = [ideal(d, uav.v_max, cfg.k_hold, uav.dt) for _, d in series]

            def cell(x):
                return f"{np.median(x):.2f} / {np.percentile(x, 95):.2f}"
            print(f"| `{preset}` | {label} | {np.mean(wind > uav.v_max):.3f} | {np.mean(drift > uav.v_max):.3f} | "
                  f"{np.mean(drift > 0.5 * uav.v_max):.3f} | {cell(own)} | {cell(exact)} | {cell(best)} | "
                  f"{p99:.2f} / {hover:.2f} | {rms:.2f} | {p99 / rms:.1f} |")


if __name__ == "__main__":
    main()
