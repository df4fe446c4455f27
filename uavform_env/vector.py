"""VectorEnv: K copies of a ParallelEnv stepped in one process as arrays, seeded and auto-reset.

    from uavform_env import parallel_env
    from uavform_env.vector import VectorEnv
    venv = VectorEnv(lambda: parallel_env(scenario="forest", n_uavs=5), n_copies=16)
    obs = venv.reset(seed=0)                                  # (16, 5, obs_dim)
    obs, rewards, terminated, truncated, infos = venv.step(actions)   # actions (16, 5, 3)

Every per-step quantity is an array over (copy, agent): with parameter sharing every UAV of every copy
is one sample row. ``training.vecenv.SharedPolicyVecEnv`` is the SB3 ``VecEnv`` view of it (rows
``k * n_agents + i``) and can spread the copies over worker processes or Ray actors with ``serve``;
``uavform_env.torchrl_vector.TorchRLVectorEnv`` is the TorchRL ``EnvBase`` view.

Seeds: after ``seed(s)`` (or ``reset(seed=s)``) copy ``k`` plays the episode seeds ``s + k``,
``s + k + stride``, ``s + k + 2 * stride``, ... (``stride`` = the number of copies), so the copies never
share an episode and the same ``s`` replays the same episodes bit for bit, however the copies are
spread over processes. Unseeded copies reset with ``seed=None`` (the env's own stream).

Auto-reset (``autoreset=True``, SB3's convention): when a copy's episode ends, ``step`` returns the first
observation of its next episode, and each of its agents' infos carries ``terminal_observation`` and
``TimeLimit.truncated`` (the episode hit the time limit without terminating). With ``autoreset=False``
the caller resets ended copies itself (``reset(indices=...)``; TorchRL's convention).

The copies need a constant agent set and one shared observation and action space (FormationEnv's
default ``remove_crashed=False`` keeps crashed UAVs, frozen, until the episode ends).
"""

from __future__ import annotations

import signal
from collections.abc import Callable, Sequence

import cloudpickle
import numpy as np


BACKENDS = ("inline", "process", "ray")   # where the copies of a vector env can run (training.vecenv places them)


def copy_seed(base: int, index: int, stride: int, episode: int) -> int:
    """The episode seed of copy ``index``'s ``episode``-th episode after ``seed(base)``."""
    return base + index + stride * episode


class VectorEnv:
    """``n_copies`` copies of a ParallelEnv, stepped with (copy, agent, ...) arrays.

    Args:
        make_env: a zero-argument callable building one ParallelEnv (picklable by cloudpickle to run it
            in another process).
        n_copies: how many copies this object holds.
        autoreset: restart a copy inside ``step`` when its episode ends (see the module docstring).
        first, stride: this object's copies are copies ``first .. first + n_copies - 1`` of a family of
            ``stride`` copies (default: the whole family, ``first=0, stride=n_copies``); the seed streams
            follow the family index, so a family spread over several ``VectorEnv`` replays the same episodes.
    """

    def __init__(self, make_env: Callable, n_copies: int = 1, *, autoreset: bool = True, first: int = 0,
                 stride: int | None = None):
        if isinstance(n_copies, bool) or not isinstance(n_copies, int) or n_copies < 1:
            raise ValueError(f"n_copies={n_copies!r}: expected an integer >= 1")
        stride = n_copies if stride is None else stride
        if isinstance(first, bool) or not isinstance(first, int) or first < 0 or \
                isinstance(stride, bool) or not isinstance(stride, int) or first + n_copies > stride:
            raise ValueError(f"first={first!r}, stride={stride!r}: expected integers with 0 <= first and "
                             f"first + n_copies ({n_copies}) <= stride")
        self.envs = [make_env() for _ in range(n_copies)]
        self.n_copies, self.first, self.stride, self.autoreset = n_copies, first, stride, bool(autoreset)
        env = self.envs[0]
        self.possible_agents = list(env.possible_agents)
        self.n_agents = len(self.possible_agents)
        self.observation_space = env.observation_space(self.possible_agents[0])
        self.action_space = env.action_space(self.possible_agents[0])
        for k, e in enumerate(self.envs):
            if list(e.possible_agents) != self.possible_agents:
                raise ValueError(f"env copy {first + k}: agents {e.possible_agents} differ from copy {first}'s "
                                 f"{self.possible_agents}; make_env must build the same env every time")
            for a in self.possible_agents:
                if e.observation_space(a) != self.observation_space or e.action_space(a) != self.action_space:
                    raise ValueError(f"env copy {first + k}: agent {a!r} has other spaces than "
                                     f"{self.possible_agents[0]!r}; parameter sharing needs one observation and "
                                     "one action space for every agent")
        self.obs_shape = self.observation_space.shape
        self.act_shape = self.action_space.shape
        self.base_seed: int | None = None
        self.episodes = np.zeros(n_copies, np.int64)       # episodes started since seed(), per copy
        self._obs = np.zeros((n_copies, self.n_agents, *self.obs_shape), self.observation_space.dtype)
        self.reset_infos: list[list[dict]] = [[{} for _ in self.possible_agents] for _ in range(n_copies)]

    def describe(self) -> tuple:
        """(possible_agents, observation_space, action_space): what a caller in another process needs."""
        return self.possible_agents, self.observation_space, self.action_space

    # ------------------------------------------------------------------ seeds and resets
    def seed(self, seed: int | None) -> list[int | None]:
        """Restart the seed streams at ``seed``; returns the first episode seed of every copy."""
        if seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer))):
            raise ValueError(f"seed={seed!r}: expected an integer or None")
        self.base_seed = None if seed is None else int(seed)
        self.episodes[:] = 0
        return [None if seed is None else copy_seed(self.base_seed, self.first + k, self.stride, 0)
                for k in range(self.n_copies)]

    def _next_seed(self, k: int) -> int | None:
        if self.base_seed is None:
            return None
        seed = copy_seed(self.base_seed, self.first + k, self.stride, int(self.episodes[k]))
        self.episodes[k] += 1
        return seed

    def reset(self, seed: int | None = None, indices: Sequence[int] | None = None) -> np.ndarray:
        """Start the next episode of the copies ``indices`` (default all); returns every copy's observation.

        ``seed`` restarts the seed streams first (see ``seed``). Each copy's reset infos (per agent) are in
        ``reset_infos[copy]``, as SB3's VecEnv keeps them.
        """
        if seed is not None:
            self.seed(seed)
        for k in range(self.n_copies) if indices is None else indices:
            self._reset_copy(int(k))
        return self._obs.copy()

    def _reset_copy(self, k: int) -> None:
        env = self.envs[k]
        obs, infos = env.reset(seed=self._next_seed(k))
        if list(env.agents) != self.possible_agents:
            raise ValueError(f"env copy {self.first + k}: reset() left agents {env.agents}; the vector env needs "
                             f"all of {self.possible_agents} live at the start of every episode")
        self._obs[k] = [obs[a] for a in self.possible_agents]
        self.reset_infos[k] = [dict(infos[a]) for a in self.possible_agents]

    # ------------------------------------------------------------------ stepping
    def step(self, actions: np.ndarray):
        """Step every copy with ``actions`` of shape (n_copies, n_agents, *action_shape).

        Returns ``obs`` (n_copies, n_agents, *obs_shape), ``rewards`` (n_copies, n_agents) float32,
        ``terminated`` and ``truncated`` (n_copies, n_agents) bool, and ``infos``: per copy, a list of
        each agent's info dict.
        """
        acts = np.asarray(actions)
        if acts.shape != (self.n_copies, self.n_agents, *self.act_shape):
            raise ValueError(f"actions: expected shape {(self.n_copies, self.n_agents, *self.act_shape)} "
                             f"(copies, agents, action), got {acts.shape}")
        out = self._step_copies(acts)
        if self.autoreset:
            self._restart_ended(*out)
        return out

    def _step_copies(self, acts: np.ndarray):
        """One step of every copy, as ``step`` returns it (before the auto-reset).

        The only per-copy loop of a step, and the seam for batched stepping: once the env's stages
        (dynamics, collisions, sensing, map update, observations, rewards) run as array kernels over any
        number of UAVs, one call per stage over all n_copies x n_agents UAVs replaces this loop and fills
        the same arrays; seeding, resets and the adapters above stay as they are."""
        agents = self.possible_agents
        rewards = np.zeros((self.n_copies, self.n_agents), np.float32)
        terminated = np.zeros((self.n_copies, self.n_agents), bool)
        truncated = np.zeros((self.n_copies, self.n_agents), bool)
        infos = []
        for k, env in enumerate(self.envs):
            obs, rew, term, trunc, info = env.step(dict(zip(agents, acts[k])))
            if env.agents and list(env.agents) != agents:
                raise ValueError(f"env copy {self.first + k}: agents {sorted(set(agents) - set(env.agents))} left "
                                 "before the episode ended; the vector env needs a constant agent set "
                                 "(FormationEnv's default remove_crashed=False keeps crashed UAVs, frozen)")
            self._obs[k] = [obs[a] for a in agents]
            rewards[k] = [rew[a] for a in agents]
            terminated[k] = [term[a] for a in agents]
            truncated[k] = [trunc[a] for a in agents]
            infos.append([dict(info[a]) for a in agents])
        return self._obs.copy(), rewards, terminated, truncated, infos

    def ended(self) -> np.ndarray:
        """(n_copies,) bool: which copies have no live agent (their episode is over)."""
        return np.array([not env.agents for env in self.envs])

    def _restart_ended(self, obs, rewards, terminated, truncated, infos) -> None:
        for k in np.flatnonzero(self.ended()):
            for i, info in enumerate(infos[k]):
                info["terminal_observation"] = obs[k, i].copy()
                info["TimeLimit.truncated"] = bool(truncated[k, i] and not terminated[k, i])
            self._reset_copy(int(k))
            obs[k] = self._obs[k]

    # ------------------------------------------------------------------ the copies' attributes
    def get_attr(self, name: str, indices: Sequence[int] | None = None) -> list:
        return [getattr(self.envs[k], name) for k in self._copies(indices)]

    def set_attr(self, name: str, value, indices: Sequence[int] | None = None) -> list[None]:
        """Set the attribute on the copies ``indices`` (default all); one None per copy, like ``env_method``."""
        return [setattr(self.envs[k], name, value) for k in self._copies(indices)]

    def env_method(self, name: str, args: tuple = (), kwargs: dict | None = None,
                   indices: Sequence[int] | None = None) -> list:
        return [getattr(self.envs[k], name)(*args, **(kwargs or {})) for k in self._copies(indices)]

    def _copies(self, indices) -> list[int]:
        copies = list(range(self.n_copies)) if indices is None else [int(k) for k in indices]
        bad = [k for k in copies if not 0 <= k < self.n_copies]
        if bad:
            raise ValueError(f"indices {bad}: this vector env holds copies 0..{self.n_copies - 1}")
        return copies

    def close(self) -> None:
        for env in self.envs:
            env.close()


def serve(remote, parent_remote, make_env_pickle: bytes, kwargs: dict) -> None:
    """A worker process's loop: build ``VectorEnv(make_env, **kwargs)`` and answer (method, args) requests
    until 'close'; an exception is sent back (the caller re-raises it naming the copies)."""
    parent_remote.close()
    signal.signal(signal.SIGINT, signal.SIG_IGN)   # Ctrl-C is the parent's to handle; it closes the workers
    try:
        venv = VectorEnv(cloudpickle.loads(make_env_pickle), **kwargs)
    except Exception as e:  # reported on the first request
        venv = e
    while True:
        cmd, data = remote.recv()
        if cmd == "close":
            remote.close()
            return
        try:
            if isinstance(venv, Exception):
                raise venv
            result = getattr(venv, cmd)(*data)
        except Exception as e:  # sent back and re-raised in the parent, with the copies named
            result = e
        remote.send(result)


__all__ = ["BACKENDS", "VectorEnv", "copy_seed", "serve"]
