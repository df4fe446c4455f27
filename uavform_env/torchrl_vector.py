"""TorchRLVectorEnv: ``uavform_env.vector.VectorEnv`` as a TorchRL ``EnvBase`` of batch size (n_copies,).

    from torchrl.envs.utils import check_env_specs
    env = TorchRLVectorEnv(lambda: parallel_env(scenario="forest", n_uavs=5), n_copies=8, seed=0)
    check_env_specs(env)
    td = env.rollout(100, break_when_any_done=False)   # td["next", "agents", "observation"]: (100, 8, 5, obs_dim)

The agents form one group, ``"agents"`` (parameter sharing: a policy maps ``("agents", "observation")``
of shape (n_copies, n_agents, obs_dim) to ``("agents", "action")``); ``("agents", "reward")`` is per
agent, ``done`` / ``terminated`` / ``truncated`` are per copy, since the agents of a copy end their episode
together. The env's per-agent infos (``uavform_env.env.INFO_KEYS``: clearance, formation error, crash cause,
end reason, ...) are ``("agents", "info", key)`` of shape (n_copies, n_agents, 1), after every reset and step
(``TimeLimit.truncated`` is the copy's ``truncated``). Ended copies are reset by TorchRL (``"_reset"``, e.g. in
``rollout`` and collectors), each on the next seed of its stream (see ``uavform_env.vector``). Needs ``torchrl``
(the ``interop`` extra).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase

from .env import INFO_INTEGERS, INFO_KEYS
from .vector import VectorEnv

GROUP = "agents"
# The infos as TorchRL entries: counts and codes as integers, measurements as floats.
INFO_DTYPES = {key: torch.int64 if key in INFO_INTEGERS else torch.float32
               for key in INFO_KEYS if key != "TimeLimit.truncated"}


class TorchRLVectorEnv(EnvBase):
    """``n_copies`` copies of a ParallelEnv for TorchRL (see the module docstring).

    Args:
        make_env: a zero-argument callable building one ParallelEnv.
        n_copies: how many copies (the env's batch size).
        seed: seed the copies' episode streams (or later, ``set_seed``).
    """

    def __init__(self, make_env: Callable, n_copies: int = 1, seed: int | None = None):
        self.venv = VectorEnv(make_env, n_copies, autoreset=False)
        super().__init__(batch_size=torch.Size([n_copies]), device="cpu")
        k, n = n_copies, self.venv.n_agents
        obs, act = self.venv.observation_space, self.venv.action_space
        info = Composite({key: Unbounded(shape=(k, n, 1), dtype=dtype) for key, dtype in INFO_DTYPES.items()},
                         shape=(k, n))
        self.observation_spec = Composite({GROUP: Composite(observation=_box(obs, k, n), info=info, shape=(k, n))},
                                          shape=(k,))
        self.action_spec = Composite({GROUP: Composite(action=_box(act, k, n), shape=(k, n))}, shape=(k,))
        self.reward_spec = Composite({GROUP: Composite(reward=Unbounded(shape=(k, n, 1)), shape=(k, n))}, shape=(k,))
        self.done_spec = Composite({name: Categorical(2, shape=(k, 1), dtype=torch.bool)
                                    for name in ("done", "terminated", "truncated")}, shape=(k,))
        if seed is not None:
            self.set_seed(seed)

    def _set_seed(self, seed: int | None):
        self.venv.seed(seed)

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs) -> TensorDictBase:
        reset = tensordict.get("_reset", None) if tensordict is not None else None
        indices = None if reset is None else np.flatnonzero(reset.reshape(-1).numpy())
        obs = self.venv.reset(indices=indices)
        no = torch.zeros(self.batch_size[0], 1, dtype=torch.bool)
        return TensorDict({GROUP: TensorDict(observation=torch.as_tensor(obs), info=_infos(self.venv.reset_infos),
                                             batch_size=obs.shape[:2]),
                           "done": no, "terminated": no.clone(), "truncated": no.clone()}, batch_size=self.batch_size)

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        actions = tensordict.get((GROUP, "action")).detach().cpu().numpy()
        obs, rewards, terminated, truncated, infos = self.venv.step(actions)
        term = torch.as_tensor(terminated.any(axis=1, keepdims=True))
        trunc = torch.as_tensor(truncated.any(axis=1, keepdims=True) & ~terminated.any(axis=1, keepdims=True))
        return TensorDict({GROUP: TensorDict(observation=torch.as_tensor(obs), info=_infos(infos),
                                             reward=torch.as_tensor(rewards)[..., None], batch_size=obs.shape[:2]),
                           "done": term | trunc, "terminated": term, "truncated": trunc}, batch_size=self.batch_size)

    def close(self, *, raise_if_closed: bool = True):
        self.venv.close()
        super().close(raise_if_closed=raise_if_closed)


def _infos(infos: list[list[dict]]) -> TensorDict:
    """Per copy, per agent info dicts as a TensorDict of (copies, agents, 1) entries (``INFO_DTYPES``)."""
    k, n = len(infos), len(infos[0])
    return TensorDict({key: torch.tensor([[[info[key]] for info in copy] for copy in infos], dtype=dtype)
                       for key, dtype in INFO_DTYPES.items()}, batch_size=(k, n))


def _box(space, k: int, n: int) -> Bounded:
    """A gymnasium Box of one agent as a TorchRL spec over (copies, agents)."""
    shape = (k, n, *space.shape)
    return Bounded(torch.tensor(np.broadcast_to(space.low, shape)), torch.tensor(np.broadcast_to(space.high, shape)),
                   shape=shape, dtype=torch.float32)


__all__ = ["TorchRLVectorEnv"]
