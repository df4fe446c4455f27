"""Playing one episode of a policy in an env, timing the policy: shared by the CLI, leaderboard and experiments."""

from __future__ import annotations

import time

import numpy as np

from .metrics import episode_metrics


class EpisodeTimeout(RuntimeError):
    """The episode ran longer than its wall-clock limit."""


def run_episode(penv, policy, seed: int, *, time_limit: float | None = None, progress=None, on_step=None) -> dict:
    """Reset ``penv`` with ``seed``, let ``policy`` fly it to the end and return the episode metrics.

    ``progress`` is an optional tqdm-like bar (``update``/``set_postfix``); ``on_step(env)`` is called
    after every step (e.g. to grab video frames).
    """
    obs, infos = penv.reset(seed=seed)
    policy.reset(penv, seed)
    env = penv.unwrapped
    planning = []
    start = time.perf_counter()
    while penv.agents:
        t0 = time.perf_counter()
        actions = policy.act(obs, penv)
        planning.append((time.perf_counter() - t0) / max(1, int(env.active.sum())))
        obs, rewards, terms, truncs, infos = penv.step(actions)
        if on_step is not None:
            on_step(env)
        if progress is not None:
            progress.update(1)
            progress.set_postfix(goal=f"{env.goal_distance():.1f}m", refresh=False)
        if time_limit is not None and time.perf_counter() - start > time_limit:
            raise EpisodeTimeout(f"episode exceeded its time limit of {time_limit:g} s at step {env.step_count}")
    return episode_metrics(env, np.asarray(planning))
