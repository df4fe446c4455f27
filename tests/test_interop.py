"""Interoperability: the base env and ResidualWeightEnv through the ecosystem's adapters.

SuperSuit -> SB3 PPO, our seeded SharedPolicyVecEnv -> SB3 PPO, TorchRL's PettingZooWrapper and
Tianshou's PettingZooEnv (AEC view), each for both envs. The PettingZoo conformance suite itself lives in
test_env_api.py. No Gymnasium/SB3 ``check_env`` here: the project has no single-agent ``gymnasium.Env``
view (the adapters below are VecEnvs or multi-agent wrappers, which those checkers do not accept).

Select with ``pytest -m interop``; the packages are the ``interop`` and ``train`` extras (CI installs both).
"""

import numpy as np
import pytest
import supersuit as ss
import torch
from pettingzoo.utils.conversions import parallel_to_aec
from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import VecMonitor
from tianshou.env import PettingZooEnv
from torchrl.envs.libs.pettingzoo import PettingZooWrapper
from torchrl.envs.utils import check_env_specs

from training import ResidualWeightEnv
from training.residual import N_WEIGHTS
from training.vecenv import SharedPolicyVecEnv
from uavform_env import env as aec_env
from uavform_env import parallel_env
from uavform_env.env import INFO_KEYS

from .conftest import small_env_kwargs

pytestmark = pytest.mark.interop

MAX_CYCLES = 20
KW = small_env_kwargs(max_cycles=MAX_CYCLES)   # 3 UAVs, forest, 20 steps
N_AGENTS = 3
AGENTS = [f"uav_{i}" for i in range(N_AGENTS)]

# Lambdas on purpose: cloudpickle ships a lambda by value, so the worker processes of
# SharedPolicyVecEnv(backend="process") import uavform_env and training only, not this module (and with it
# torchrl and tianshou, several seconds per worker).
MAKERS = {
    "base": lambda: parallel_env(**KW),
    "residual": lambda: ResidualWeightEnv(parallel_env(**KW)),
}
AEC_MAKERS = {
    "base": lambda: aec_env(**KW),
    "residual": lambda: parallel_to_aec(ResidualWeightEnv(parallel_env(**KW))),
}
BASE_OBS_DIM = parallel_env(**KW).observation_space("uav_0").shape[0]
OBS_DIM = {"base": BASE_OBS_DIM, "residual": BASE_OBS_DIM + N_WEIGHTS}
ACT_DIM = {"base": 3, "residual": N_WEIGHTS}
VARIANTS = list(MAKERS)

# PPO small enough for seconds: 2 copies x 3 agents = 6 rows, 50 steps per row per rollout.
PPO_KW = dict(n_steps=50, batch_size=100, n_epochs=2, device="cpu", verbose=0)
TIMESTEPS = 300


def _params(model) -> list[torch.Tensor]:
    return [p.detach().clone() for p in model.policy.parameters()]


def _learn_and_check(vec, variant: str, **ppo_kw) -> PPO:
    """PPO learns TIMESTEPS steps on ``vec``; checks the spaces, the update and the episode records."""
    assert vec.num_envs == 2 * N_AGENTS
    assert vec.observation_space.shape == (OBS_DIM[variant],)
    assert vec.action_space.shape == (ACT_DIM[variant],)
    model = PPO("MlpPolicy", vec, **PPO_KW, **ppo_kw)
    before = _params(model)
    model.learn(TIMESTEPS)
    assert model.num_timesteps == TIMESTEPS
    assert any(not torch.equal(a, b) for a, b in zip(before, _params(model))), "PPO did not update the policy"
    # Every row finishes at least two episodes of at most MAX_CYCLES steps in 50 steps.
    episodes = list(model.ep_info_buffer)
    assert len(episodes) >= 2 * vec.num_envs
    assert all(0 < ep["l"] <= MAX_CYCLES and np.isfinite(ep["r"]) for ep in episodes)
    obs = vec.reset()
    actions, _ = model.predict(obs, deterministic=True)
    assert actions.shape == (vec.num_envs, ACT_DIM[variant])
    assert np.all(np.abs(actions) <= 1.0)
    return model


# ---------------------------------------------------------------------------------------------- SuperSuit
@pytest.mark.parametrize("variant", VARIANTS)
def test_supersuit_to_sb3_ppo(variant):
    vec = ss.pettingzoo_env_to_vec_env_v1(MAKERS[variant]())
    vec = ss.concat_vec_envs_v1(vec, 2, num_cpus=0, base_class="stable_baselines3")
    vec = VecMonitor(vec)
    try:
        # No seed=: SuperSuit's ConcatVecEnv has no seed() and PPO(seed=...) fails with "'ConcatVecEnv'
        # object has no attribute 'seed'" (SuperSuit 3.11). training.vecenv.SharedPolicyVecEnv is our
        # seeded replacement, which training uses (tested below).
        _learn_and_check(vec, variant)
    finally:
        vec.close()


# ------------------------------------------------------------------------------ our SharedPolicyVecEnv
@pytest.mark.parametrize("variant", VARIANTS)
def test_shared_policy_vecenv_ppo_is_reproducible(variant):
    runs = []
    for _ in range(2):
        vec = VecMonitor(SharedPolicyVecEnv(MAKERS[variant], n_copies=2))
        try:
            model = _learn_and_check(vec, variant, seed=7)
        finally:
            vec.close()
        runs.append((model.policy.state_dict(), [(float(ep["r"]), int(ep["l"])) for ep in model.ep_info_buffer]))
    (params_a, episodes_a), (params_b, episodes_b) = runs
    assert params_a.keys() == params_b.keys()
    for name in params_a:
        assert torch.equal(params_a[name], params_b[name]), f"seed=7 twice gave different {name}"
    assert episodes_a == episodes_b   # the env copies replayed the same episodes, not only the same torch RNG


def _assert_same_step(a, b, where):
    for i, (x, y) in enumerate(zip(a[:3], b[:3])):
        np.testing.assert_array_equal(x, y, err_msg=f"{where}: output {i}")
    assert len(a[3]) == len(b[3])
    for info_a, info_b in zip(a[3], b[3]):
        assert info_a.keys() == info_b.keys(), where
        for k in info_a:
            np.testing.assert_array_equal(info_a[k], info_b[k], err_msg=f"{where}: info {k}")


# The base env only: tests/test_training.py already compares backend="process" with in-process copies for
# ResidualWeightEnv (zero actions), and every worker process costs seconds of imports (SB3 and torch).
@pytest.mark.parametrize("variant", ["base"])
def test_shared_policy_vecenv_processes_match_in_process(variant):
    local = SharedPolicyVecEnv(MAKERS[variant], n_copies=2)
    remote = SharedPolicyVecEnv(MAKERS[variant], n_copies=2, backend="process")
    try:
        assert (local.num_envs, local.observation_space, local.action_space) == \
               (remote.num_envs, remote.observation_space, remote.action_space)
        assert local.seed(3) == remote.seed(3) == [3] * N_AGENTS + [4] * N_AGENTS
        obs_local, obs_remote = local.reset(), remote.reset()
        assert obs_local.shape == (2 * N_AGENTS, OBS_DIM[variant])
        np.testing.assert_array_equal(obs_local, obs_remote)
        assert not np.array_equal(obs_local[:N_AGENTS], obs_local[N_AGENTS:]), "the copies play the same seed"
        rng = np.random.default_rng(0)
        n_done = 0
        for t in range(MAX_CYCLES + 5):   # across the first episode end: auto-reset on the next seeds
            actions = rng.uniform(-1, 1, (local.num_envs, ACT_DIM[variant])).astype(np.float32)
            out_local = local.step(actions)
            out_remote = remote.step(actions)
            _assert_same_step(out_local, out_remote, f"step {t}")
            for done, info in zip(out_local[2], out_local[3]):
                assert set(INFO_KEYS) <= set(info)
                if done:
                    n_done += 1
                    assert info["terminal_observation"].shape == (OBS_DIM[variant],)
                    assert isinstance(info["TimeLimit.truncated"], bool)
        assert n_done >= local.num_envs   # every row ended an episode at least once
    finally:
        local.close()
        remote.close()


# ------------------------------------------------------------------------------------------------ TorchRL
@pytest.mark.parametrize("variant", VARIANTS)
def test_torchrl_pettingzoo_wrapper(variant):
    penv = MAKERS[variant]()
    env = PettingZooWrapper(env=penv, return_state=True, seed=0)
    assert env.group_map == {"uav": AGENTS}   # uav_<i> names: one group, parameter sharing for free
    check_env_specs(env)
    torch.manual_seed(0)
    td = env.rollout(25, break_when_any_done=False)   # 25 > MAX_CYCLES: crosses an auto-reset
    assert td.batch_size == torch.Size([25])
    assert td["uav", "action"].shape == (25, N_AGENTS, ACT_DIM[variant])
    nxt = td["next"]
    assert nxt["uav", "observation"].shape == (25, N_AGENTS, OBS_DIM[variant])
    assert nxt["uav", "reward"].shape == (25, N_AGENTS, 1)
    assert nxt["state"].shape == (25,) + penv.state_space.shape
    assert set(nxt["uav", "info"].keys()) == set(INFO_KEYS)
    obs_spec = env.full_observation_spec["uav", "observation"]
    assert all(obs_spec.is_in(nxt["uav", "observation"][t]) for t in range(25))
    assert torch.all(torch.isfinite(nxt["uav", "reward"]))
    done = nxt["done"].squeeze(-1)
    assert done.any(), "no episode ended within 25 steps of a 20-step horizon"
    first_end = int(torch.nonzero(done)[0])
    assert first_end <= MAX_CYCLES - 1
    # After the auto-reset the step counter starts again.
    assert torch.all(nxt["uav", "info", "step"][first_end + 1] == 1)
    env.close()


def test_torchrl_seeded_rollout_is_reproducible():
    rollouts = []
    for _ in range(2):
        torch.manual_seed(0)
        env = PettingZooWrapper(env=MAKERS["base"](), return_state=True, seed=0)
        rollouts.append(env.rollout(5, break_when_any_done=False))
    torch.testing.assert_close(rollouts[0]["state"], rollouts[1]["state"], rtol=0, atol=0)


# ----------------------------------------------------------------------------------------------- Tianshou
@pytest.mark.parametrize("variant", VARIANTS)
def test_tianshou_pettingzoo_env_on_aec_view(variant):
    env = PettingZooEnv(AEC_MAKERS[variant]())
    assert env.agents == AGENTS
    assert env.observation_space.shape == (OBS_DIM[variant],)
    assert env.action_space.shape == (ACT_DIM[variant],)
    env.action_space.seed(0)
    obs, info = env.reset(seed=0)
    assert obs["agent_id"] == "uav_0" and "mask" not in obs   # continuous actions: no mask
    assert set(info) == set(INFO_KEYS) and info["step"] == 0
    terminated = truncated = False
    turns = 0
    while not (terminated or truncated):
        assert env.observation_space.contains(obs["obs"]), f"turn {turns}"
        obs, rewards, terminated, truncated, info = env.step(env.action_space.sample())
        turns += 1
        assert obs["agent_id"] == AGENTS[turns % N_AGENTS]   # the AEC view cycles the agents in order
        assert len(rewards) == N_AGENTS and all(np.isfinite(rewards))
        assert turns <= N_AGENTS * MAX_CYCLES
    assert info["step"] == turns // N_AGENTS
    if truncated:
        assert turns == N_AGENTS * MAX_CYCLES and info["TimeLimit.truncated"]
    env.close()
