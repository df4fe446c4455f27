"""How far each disturbance preset pushes a UAV that commands zero speed (README, "Disturbances").

    python benchmarks/disturbance_drift.py [--seeds 40]

Two UAVs 2 m apart in an empty field command v = w = vz = 0 for 10 s; the table gives the median and 90th
percentile over the seeds of the leader's horizontal distance from its start after 2, 5 and 10 s, and of how far
the two drifted apart (the change of their horizontal offset) after 10 s.
"""

from __future__ import annotations

import argparse

import numpy as np

from uavform_env import parallel_env
from uavform_env.config import DISTURBANCE_PRESETS
from uavform_env.scenarios import Mission, Scenario

TIMES = (2.0, 5.0, 10.0)


def field(n_uavs: int = 2) -> Scenario:
    return Scenario(name="open", version=1, seed=None, bounds_lo=(0.0, 0.0, 0.0), bounds_hi=(60.0, 60.0, 12.0),
                    resolution=0.2, obstacles=(),
                    mission=Mission(start=(30.0, 30.0, 3.0), goal=(50.0, 30.0, 3.0), start_heading=0.0,
                                    formation="line", spacing=2.0, n_uavs=n_uavs))


def drift(preset: str, seeds: int) -> np.ndarray:
    """(seeds, len(TIMES) + 1): the leader's horizontal distances from its start, then how far the two drifted apart."""
    steps = int(round(max(TIMES) / 0.1))
    out = np.empty((seeds, len(TIMES) + 1))
    for s in range(seeds):
        penv = parallel_env(scenario=field(), max_cycles=steps, disturbance=preset)
        penv.reset(seed=s)
        env = penv.unwrapped
        start = env.states[:, :2].copy()
        track = []
        while penv.agents:
            penv.step({a: np.array([-1.0, 0.0, 0.0], np.float32) for a in penv.agents})
            track.append(np.hypot(*(env.states[0, :2] - start[0])))
        moved = env.states[:, :2] - start
        out[s] = [track[int(round(t / 0.1)) - 1] for t in TIMES] + [np.hypot(*(moved[1] - moved[0]))]
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=40)
    args = parser.parse_args()
    print("| preset | " + " | ".join(f"drift after {t:g} s: median / p90 (m)" for t in TIMES)
          + f" | drifted apart after {TIMES[-1]:g} s (m) |")
    print("|---|" + "---|" * (len(TIMES) + 1))
    for preset in DISTURBANCE_PRESETS:
        d = drift(preset, args.seeds)
        cells = [f"{np.median(d[:, k]):.2f} / {np.percentile(d[:, k], 90):.2f}" for k in range(len(TIMES) + 1)]
        print(f"| `{preset}` | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
