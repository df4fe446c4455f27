"""A parameter-sharing SB3 ``VecEnv`` over PettingZoo ParallelEnvs: every agent of every copy is one row.

SuperSuit's ``concat_vec_envs_v1`` does the same but cannot be seeded (``PPO(seed=...)`` fails with
"'ConcatVecEnv' object has no attribute 'seed'"), so training uses this adapter: copies run in
worker processes (or in-process for tests), auto-reset when their episode ends, report
``terminal_observation`` and ``TimeLimit.truncated`` the way SB3 expects, and are seeded so that
``seed=s`` reproduces a run: copy ``k`` plays episode seeds ``s + k``, ``s + k + n_copies``, ...
"""

from __future__ import annotations

import multiprocessing as mp
import signal
from collections.abc import Callable

import numpy as np
from stable_baselines3.common.vec_env import VecEnv
from stable_baselines3.common.vec_env.base_vec_env import CloudpickleWrapper


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


def _worker(remote, parent_remote, fn_wrapper: CloudpickleWrapper, index: int, n_copies: int) -> None:
    parent_remote.close()
    signal.signal(signal.SIGINT, signal.SIG_IGN)   # Ctrl-C is the parent's to handle; it closes the workers
    copy = EpisodeCopy(fn_wrapper.var, index, n_copies)
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
                proc = ctx.Process(target=_worker, args=(work_remote, remote, CloudpickleWrapper(make_env), k, n_copies),
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
