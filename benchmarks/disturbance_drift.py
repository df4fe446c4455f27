"""How far each disturbance preset pushes a UAV that commands zero speed (README, "Disturbances").

    python benchmarks/disturbance_drift.py [--seeds 40]

Two UAVs 2 m apart in an empty field command v = w = vz = 0 for 10 s; the table gives the median and 90th
percentile over the seeds of the leader's horizontal distance from its start after 2, 5 and 10 s, and of how far
the two drifted apart (the change of their horizontal offset) after 10 s. Each windy preset is flown twice: with
the default airframe, whose autopilot leans into its lagging wind estimate (``UAVLimits.wind_authority``,
``wind_rejection_tau``), and with the unopposed model (``wind_authority=0``: the whole wind carries the UAV).
"""

from __future__ import annotations

import argparse

import numpy as np

from uavform_env import parallel_env
from uavform_env.config import DISTURBANCE_PRESETS, EnvConfig, UAVLimits
from uavform_env.scenarios import Mission, Scenario

TIMES = (2.0, 5.0, 10.0)
# The airframes compared: (label, limits); the default leans into the wind, wind_authority=0 does not.
AIRFRAMES = (("leans into the wind (default)", UAVLimits()), ("unopposed (`wind_authority=0`)",
                                                               UAVLimits(wind_authority=0.0)))


def field(n_uavs: int = 2) -> Scenario:
    return Scenario(name="open", version=1, seed=None, bounds_lo=(0.0, 0.0, 0.0), bounds_hi=(60.0, 60.0, 12.0),
                    resolution=0.2, obstacles=(),
                    mission=Mission(start=(30.0, 30.0, 3.0), goal=(50.0, 30.0, 3.0), start_heading=0.0,
                                    formation="line", spacing=2.0, n_uavs=n_uavs))


def drift(preset: str, seeds: int, uav: UAVLimits = UAVLimits()) -> np.ndarray:
    """(seeds, len(TIMES) + 1): the leader's horizontal distances from its start, then how far the two drifted apart."""
    steps = int(round(max(TIMES) / uav.dt))
    out = np.empty((seeds, len(TIMES) + 1))
    for s in range(seeds):
        penv = parallel_env(scenario=field(), max_cycles=steps, disturbance=preset, config=EnvConfig(uav=uav))
        penv.reset(seed=s)
        env = penv.unwrapped
        start = env.states[:, :2].copy()
        track = []
        while penv.agents:
            penv.step({a: np.array([-1.0, 0.0, 0.0], np.float32) for a in penv.agents})
            track.append(np.hypot(*(env.states[0, :2] - start[0])))
        moved = env.states[:, :2] - start
        out[s] = [track[int(round(t / uav.dt)) - 1] for t in TIMES] + [np.hypot(*(moved[1] - moved[0]))]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=40)
    args = parser.parse_args()
    if args.seeds < 1:
        parser.error(f"--seeds {args.seeds}: expected at least 1")
    print("| preset | airframe | " + " | ".join(f"drift after {t:g} s: median / p90 (m)" for t in TIMES)
          + f" | drifted apart after {TIMES[-1]:g} s (m) |")
    print("|---|---|" + "---|" * (len(TIMES) + 1))
    for preset, dist in DISTURBANCE_PRESETS.items():
        for label, uav in AIRFRAMES if dist.windy else AIRFRAMES[:1]:
            d = drift(preset, args.seeds, uav)
            cells = [f"{np.median(d[:, k]):.2f} / {np.percentile(d[:, k], 90):.2f}" for k in range(len(TIMES) + 1)]
            print(f"| `{preset}` | {label} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
