"""One env copy of the parameter-sharing VecEnv, and the loop that runs it in a worker process.

Kept apart from ``vecenv`` (which needs SB3 and so torch) so that a worker process imports only the
env, the expert and cloudpickle.
"""

from __future__ import annotations

import signal
from collections.abc import Callable

import cloudpickle
import numpy as np


class EpisodeCopy:
    """One ParallelEnv copy, stepped with an (n_agents, act_dim) array; restarts itself when its episode ends."""

    def __init__(self, make_env: Callable, index: int, n_copies: int):
        self.env = make_env()
        self.agents = list(self.env.possible_agents)
        self.index, self.n_copies = index, n_copies
        self.base_seed: int | None = None
        self.episodes = 0

    def seed(self, seed: int | None) -> None:
        self.base_seed, self.episodes = seed, 0

    def _next_seed(self) -> int | None:
        if self.base_seed is None:
            return None
        seed = self.base_seed + self.index + self.n_copies * self.episodes
        self.episodes += 1
        return seed

    def reset(self) -> np.ndarray:
        obs, _ = self.env.reset(seed=self._next_seed())
        if list(self.env.agents) != self.agents:
            raise ValueError(f"env copy {self.index}: reset() left agents {self.env.agents}; the adapter needs all of "
                             f"{self.agents} live at the start of every episode")
        return np.stack([obs[a] for a in self.agents])

    def step(self, actions: np.ndarray):
        obs, rewards, terms, truncs, infos = self.env.step(dict(zip(self.agents, actions)))
        if self.env.agents and list(self.env.agents) != self.agents:
            raise ValueError(f"env copy {self.index}: agents {sorted(set(self.agents) - set(self.env.agents))} left "
                             "before the episode ended; parameter sharing needs a constant agent set "
                             "(FormationEnv's default remove_crashed=False keeps crashed UAVs, frozen)")
        rows = np.stack([obs[a] for a in self.agents])
        rew = np.array([rewards[a] for a in self.agents], dtype=np.float32)
        done = not self.env.agents
        out_infos = []
        for a, row in zip(self.agents, rows):
            info = dict(infos[a])
            if done:
                info["terminal_observation"] = row
                info["TimeLimit.truncated"] = bool(truncs[a] and not terms[a])
            out_infos.append(info)
        if done:
            rows = self.reset()
        return rows, rew, np.full(len(self.agents), done), out_infos

    def get_attr(self, name: str):
        return getattr(self.env, name)


def worker(remote, parent_remote, make_env_pickle: bytes, index: int, n_copies: int) -> None:
    """A worker process's loop: build one copy and answer (method, args) requests until 'close'."""
    parent_remote.close()
    signal.signal(signal.SIGINT, signal.SIG_IGN)   # Ctrl-C is the parent's to handle; it closes the workers
    copy = EpisodeCopy(cloudpickle.loads(make_env_pickle), index, n_copies)
    while True:
        cmd, data = remote.recv()
        if cmd == "close":
            remote.close()
            return
        try:
            result = getattr(copy, cmd)(*data)
        except Exception as e:  # sent back and re-raised in the parent, with the copy named
            result = e
        remote.send(result)
