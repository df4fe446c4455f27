"""A parameter-sharing SB3 ``VecEnv`` over PettingZoo ParallelEnvs: every agent of every copy is one row.

SuperSuit's ``concat_vec_envs_v1`` does the same but cannot be seeded (``PPO(seed=...)`` fails with
"'ConcatVecEnv' object has no attribute 'seed'"), so training uses this adapter: copies run in
worker processes (or in-process for tests), auto-reset when their episode ends, report
``terminal_observation`` and ``TimeLimit.truncated`` the way SB3 expects, and are seeded so that
``seed=s`` reproduces a run: copy ``k`` plays episode seeds ``s + k``, ``s + k + n_copies``, ...
"""

from __future__ import annotations

import multiprocessing as mp
from collections.abc import Callable

import cloudpickle
import numpy as np
from stable_baselines3.common.vec_env import VecEnv

from .copies import EpisodeCopy, worker


class SharedPolicyVecEnv(VecEnv):
    """``n_copies`` copies of a ParallelEnv as one VecEnv of ``n_copies * n_agents`` rows.

    Args:
        make_env: a zero-argument callable building one ParallelEnv (picklable by cloudpickle).
        n_copies: how many env copies.
        processes: run each copy in its own worker process (``forkserver``); False steps them in-process.
    """

    def __init__(self, make_env: Callable, n_copies: int = 1, processes: bool = False):
        if isinstance(n_copies, bool) or not isinstance(n_copies, int) or n_copies < 1:
            raise ValueError(f"n_copies={n_copies!r}: expected an integer >= 1")
        self.processes = processes
        if processes:
            ctx = mp.get_context("forkserver")
            pipes = [ctx.Pipe() for _ in range(n_copies)]
            self.remotes = [p[0] for p in pipes]
            self.workers = []
            for k, (remote, work_remote) in enumerate(pipes):
                proc = ctx.Process(target=worker, args=(work_remote, remote, cloudpickle.dumps(make_env), k, n_copies),
                                   daemon=True)
                proc.start()
                work_remote.close()
                self.workers.append(proc)
        else:
            self.copies = [EpisodeCopy(make_env, k, n_copies) for k in range(n_copies)]
        self.n_copies = n_copies
        agents = self._broadcast("get_attr", "possible_agents")[0]
        self.n_agents = len(agents)
        obs_space = self._broadcast("get_attr", "observation_spaces")[0][agents[0]]
        act_space = self._broadcast("get_attr", "action_spaces")[0][agents[0]]
        super().__init__(n_copies * self.n_agents, obs_space, act_space)
        self._actions = None

    def _broadcast(self, cmd: str, *args):
        return self._call(cmd, [args] * self.n_copies)

    def _call(self, cmd: str, args: list[tuple]) -> list:
        """Call ``cmd`` on every copy ``k`` with the arguments ``args[k]``; a failure names the copy."""
        if not self.processes:
            return [getattr(c, cmd)(*a) for c, a in zip(self.copies, args)]
        for remote, a in zip(self.remotes, args):
            remote.send((cmd, a))
        try:
            results = [remote.recv() for remote in self.remotes]
        except (EOFError, ConnectionError) as e:
            raise RuntimeError(f"a worker process of SharedPolicyVecEnv died during {cmd}: {e!r}") from e
        for k, r in enumerate(results):
            if isinstance(r, Exception):
                raise RuntimeError(f"env copy {k}: {cmd} failed: {r!r}") from r
        return results

    def seed(self, seed: int | None = None):
        if seed is None:
            seed = int(np.random.randint(0, np.iinfo(np.uint32).max - 10_000_000, dtype=np.uint32))
        self._broadcast("seed", seed)
        return [seed + k for k in range(self.n_copies) for _ in range(self.n_agents)]

    def reset(self):
        obs = np.concatenate(self._broadcast("reset"))
        self.reset_infos = [{} for _ in range(self.num_envs)]
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions).reshape(self.n_copies, self.n_agents, -1)

    def step_wait(self):
        results = self._call("step", [(a,) for a in self._actions])
        obs, rew, done, infos = zip(*results)
        return np.concatenate(obs), np.concatenate(rew), np.concatenate(done), [i for part in infos for i in part]

    def close(self) -> None:
        if self.processes:
            for remote in self.remotes:
                remote.send(("close", None))
            for proc in self.workers:
                proc.join(timeout=10)
        self.closed = True

    def get_attr(self, attr_name: str, indices=None) -> list:
        values = self._broadcast("get_attr", attr_name)
        return [values[i // self.n_agents] for i in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value, indices=None) -> None:
        raise AttributeError(f"set_attr({attr_name!r}): the copies of a SharedPolicyVecEnv are read-only")

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list:
        raise AttributeError(f"env_method({method_name!r}): rows of a SharedPolicyVecEnv are agents, not envs")

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]
