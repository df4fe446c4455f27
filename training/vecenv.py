"""A parameter-sharing SB3 ``VecEnv`` over ``uavform_env.vector.VectorEnv``: every agent of every copy is one row.

SuperSuit's ``concat_vec_envs_v1`` does the same but cannot be seeded (``PPO(seed=...)`` fails with
"'ConcatVecEnv' object has no attribute 'seed'"), so training uses this adapter. The copies, their seed
streams (copy ``k`` plays episode seeds ``s + k``, ``s + k + n_copies``, ...), the auto-reset and the
``terminal_observation`` / ``TimeLimit.truncated`` infos are ``VectorEnv``'s; this module only flattens
(copy, agent) to rows and places the copies:

    backend="inline"   one VectorEnv of all copies in this process
    backend="process"  the copies split over ``workers`` worker processes (``forkserver``), a VectorEnv each
    backend="ray"      the same split over Ray actors, on the cluster at ``ray_address`` (else ``RAY_ADDRESS``,
                       else a local Ray)

The rows, and so a seeded run, are the same bit for bit on every backend and for every ``workers``.
"""

from __future__ import annotations

import multiprocessing as mp
import os
from collections.abc import Callable

import cloudpickle
import numpy as np
from stable_baselines3.common.vec_env import VecEnv

from uavform_env.parallel import connect_ray
from uavform_env.vector import BACKENDS, VectorEnv, copy_seed, serve


class SharedPolicyVecEnv(VecEnv):
    """``n_copies`` copies of a ParallelEnv as one VecEnv of ``n_copies * n_agents`` rows.

    Args:
        make_env: a zero-argument callable building one ParallelEnv (picklable by cloudpickle).
        n_copies: how many env copies.
        backend: "inline", "process" or "ray" (see the module docstring).
        workers: processes or Ray actors the copies are split over (default: one per copy, at most one
            per CPU of this machine, or of the Ray cluster); ignored inline.
        ray_address: the Ray cluster to join (backend "ray" only).
    """

    def __init__(self, make_env: Callable, n_copies: int = 1, backend: str = "inline", workers: int | None = None,
                 ray_address: str | None = None):
        if isinstance(n_copies, bool) or not isinstance(n_copies, int) or n_copies < 1:
            raise ValueError(f"n_copies={n_copies!r}: expected an integer >= 1")
        if backend not in BACKENDS:
            raise ValueError(f"backend={backend!r}: expected one of {list(BACKENDS)}")
        if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int) or workers < 1):
            raise ValueError(f"workers={workers!r}: expected an integer >= 1 or None")
        if ray_address is not None and backend != "ray":
            raise ValueError(f"ray_address={ray_address!r}: only with backend='ray'")
        self.backend, self.n_copies, self.closed = backend, n_copies, False
        if backend == "inline":
            self.shards = [VectorEnv(make_env, n_copies)]
            self.firsts, self.sizes = [0], [n_copies]
        else:
            ray = connect_ray(ray_address, min(n_copies, os.cpu_count() or 1)) if backend == "ray" else None
            cpus = int(ray.cluster_resources().get("CPU", 1)) if ray else (os.cpu_count() or 1)
            n_shards = min(n_copies, workers if workers is not None else cpus)
            self.sizes = [len(part) for part in np.array_split(np.arange(n_copies), n_shards)]
            self.firsts = [int(f) for f in np.cumsum([0] + self.sizes[:-1])]
            kwargs = [{"n_copies": size, "first": first, "stride": n_copies}
                      for size, first in zip(self.sizes, self.firsts)]
            self.shards = self._start_ray(ray, make_env, kwargs) if ray else self._start_processes(make_env, kwargs)
        agents, obs_space, act_space = self._call("describe")[0]
        self.possible_agents = agents
        self.n_agents = len(agents)
        super().__init__(n_copies * self.n_agents, obs_space, act_space)
        self._actions = None

    # ------------------------------------------------------------------ placing the copies
    def _start_processes(self, make_env: Callable, kwargs: list[dict]) -> list:
        ctx = mp.get_context("forkserver")
        self.workers = []
        remotes = []
        payload = cloudpickle.dumps(make_env)
        for kw in kwargs:
            remote, work_remote = ctx.Pipe()
            proc = ctx.Process(target=serve, args=(work_remote, remote, payload, kw), daemon=True)
            proc.start()
            work_remote.close()
            self.workers.append(proc)
            remotes.append(remote)
        return remotes

    @staticmethod
    def _start_ray(ray, make_env: Callable, kwargs: list[dict]) -> list:
        actor = ray.remote(num_cpus=1)(VectorEnv)
        return [actor.remote(make_env, **kw) for kw in kwargs]

    def _where(self, s: int) -> str:
        return f"env copies {self.firsts[s]}..{self.firsts[s] + self.sizes[s] - 1}"

    def _call(self, cmd: str, args: list[tuple] | None = None, shards: list[int] | None = None) -> list:
        """Call ``cmd(*args[j])`` on shard ``shards[j]`` (default: every shard, no arguments); returns the results
        in that order. A failure names the copies."""
        shards = list(range(len(self.shards))) if shards is None else shards
        args = args if args is not None else [()] * len(shards)
        if self.backend == "inline":
            return [getattr(self.shards[0], cmd)(*args[0])]
        if self.backend == "ray":
            import ray

            refs = [getattr(self.shards[s], cmd).remote(*a) for s, a in zip(shards, args)]
            results = []
            for s, ref in zip(shards, refs):
                try:
                    results.append(ray.get(ref))
                except ray.exceptions.RayError as e:
                    raise RuntimeError(f"{self._where(s)} (Ray actor): {cmd} failed: {e}") from e
            return results
        for s, a in zip(shards, args):
            self.shards[s].send((cmd, a))
        try:
            results = [self.shards[s].recv() for s in shards]
        except (EOFError, ConnectionError) as e:
            raise RuntimeError(f"a worker process of SharedPolicyVecEnv died during {cmd}: {e!r}") from e
        for s, r in zip(shards, results):
            if isinstance(r, Exception):
                raise RuntimeError(f"{self._where(s)}: {cmd} failed: {r!r}") from r
        return results

    # ------------------------------------------------------------------ VecEnv
    def seed(self, seed: int | None = None):
        if seed is None:
            seed = int(np.random.randint(0, np.iinfo(np.uint32).max - 10_000_000, dtype=np.uint32))
        self._call("seed", [(seed,)] * len(self.shards))
        return [copy_seed(seed, k, self.n_copies, 0) for k in range(self.n_copies) for _ in range(self.n_agents)]

    def reset(self):
        obs = np.concatenate(self._call("reset"))
        self.reset_infos = [{} for _ in range(self.num_envs)]
        return obs.reshape(self.num_envs, *obs.shape[2:])

    def step_async(self, actions: np.ndarray) -> None:
        acts = np.asarray(actions).reshape(self.n_copies, self.n_agents, *self.action_space.shape)
        self._actions = [(acts[f:f + n],) for f, n in zip(self.firsts, self.sizes)]

    def step_wait(self):
        results = self._call("step", self._actions)
        obs, rew, term, trunc = (np.concatenate([r[j] for r in results]) for j in range(4))
        infos = [info for r in results for copy in r[4] for info in copy]
        return (obs.reshape(self.num_envs, *obs.shape[2:]), rew.ravel(), (term | trunc).ravel(), infos)

    def close(self) -> None:
        if self.closed:
            return
        if self.backend == "process":
            for remote in self.shards:
                remote.send(("close", None))
            for proc in self.workers:
                proc.join(timeout=10)
        elif self.backend == "ray":
            import ray

            for actor in self.shards:
                ray.kill(actor)
        else:
            self.shards[0].close()
        self.closed = True

    def _copies_of_rows(self, indices) -> list[int]:
        return [i // self.n_agents for i in self._get_indices(indices)]

    def _per_copy(self, cmd: str, rows, *args) -> dict[int, object]:
        """``cmd(*args, local copy indices)`` on the shards holding the copies of ``rows``: {copy: result}."""
        copies = sorted(set(self._copies_of_rows(rows)))
        shards, local = [], []
        for s, (first, size) in enumerate(zip(self.firsts, self.sizes)):
            mine = [c - first for c in copies if first <= c < first + size]
            if mine:
                shards.append(s)
                local.append(mine)
        results = self._call(cmd, [(*args, mine) for mine in local], shards)
        return {self.firsts[s] + c: v for s, mine, values in zip(shards, local, results)
                for c, v in zip(mine, values)}

    def get_attr(self, attr_name: str, indices=None) -> list:
        values = self._per_copy("get_attr", indices, attr_name)
        return [values[c] for c in self._copies_of_rows(indices)]

    def set_attr(self, attr_name: str, value, indices=None) -> None:
        self._per_copy("set_attr", indices, attr_name, value)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list:
        """Call the method once per env copy of the rows ``indices``; every row gets its copy's result."""
        values = self._per_copy("env_method", indices, method_name, method_args, method_kwargs)
        return [values[c] for c in self._copies_of_rows(indices)]

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        return [False for _ in self._get_indices(indices)]

