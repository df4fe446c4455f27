"""Whole episodes of the scripted policies end in exactly the states recorded in ``tests/data/end_states.npz``.

The expert, the planar baselines (the same controller with ``use_vfh=False``) and APF fly short
episodes; any change to their arithmetic, however small, moves the end state. A deliberate change of
behaviour re-records the file: ``python -m tests.test_end_states`` (and says so in its commit).
"""

from pathlib import Path

import numpy as np
import pytest

from baselines.expert import ExpertConfig
from baselines.registry import BUILTIN
from uavform_env import parallel_env

FIXTURE = Path(__file__).parent / "data" / "end_states.npz"
# (policy, scenario, seed, steps); "expert-weights" is the expert with per-UAV residual weights varying every step
EPISODES = (("expert", "forest@1", 0, 300), ("expert", "wall-gap@1", 1, 700), ("expert", "corridor@1", 2, 300),
            ("standard-dwa", "forest@1", 0, 200), ("idwa-2d", "corridor@1", 2, 200), ("apf", "forest@1", 0, 200),
            ("expert-weights", "forest@1", 3, 200))


def _key(name, scn, seed, steps):
    return f"{name}/{scn}/{seed}/{steps}"


def end_state(name: str, scn: str, seed: int, steps: int) -> np.ndarray:
    """The true states, crash flags and step count after the episode."""
    penv = parallel_env(scenario=scn, max_cycles=steps)
    obs, _ = penv.reset(seed=seed)
    policy = BUILTIN["expert" if name == "expert-weights" else name]()
    policy.reset(penv, seed=seed)
    w0 = ExpertConfig().weights()
    k = 0
    while penv.agents:
        if name == "expert-weights":
            weights = {a: w0 * (1.0 + 0.2 * np.sin(0.1 * k + i)) for i, a in enumerate(penv.agents)}
            actions = policy.act(obs, penv, weights=weights)
        else:
            actions = policy.act(obs, penv)
        obs, *_ = penv.step(actions)
        k += 1
    env = penv.unwrapped
    return np.concatenate([env.states.ravel(), env.crashed.astype(np.float64), [env.step_count]])


@pytest.mark.parametrize("episode", EPISODES, ids=[_key(*e) for e in EPISODES])
def test_episode_ends_in_the_recorded_state(episode):
    recorded = np.load(FIXTURE)[_key(*episode)]
    assert np.array_equal(end_state(*episode), recorded)


if __name__ == "__main__":
    np.savez(FIXTURE, **{_key(*e): end_state(*e) for e in EPISODES})
    print(f"recorded {len(EPISODES)} end states in {FIXTURE}")
