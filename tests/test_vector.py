"""The vector env: K copies as (copy, agent) arrays, its seed streams and auto-reset, its SB3 and TorchRL views."""

import sys

import numpy as np
import pytest
from pettingzoo.utils import BaseParallelWrapper

from uavform_env import parallel_env
from uavform_env.env import END_REASONS
from uavform_env.vector import VectorEnv, copy_seed

from .conftest import small_env_kwargs

MAX_CYCLES = 10
N = 3


def make():
    return parallel_env(**small_env_kwargs(max_cycles=MAX_CYCLES))   # 3 UAVs, forest


def actions(k, steps, seed=0):
    return np.random.default_rng(seed).uniform(-1, 1, (steps, k, N, 3)).astype(np.float32)


def rollout(venv, acts, seed):
    out = [venv.reset(seed=seed)]
    for a in acts:
        obs, rew, term, trunc, infos = venv.step(a)
        out += [obs, rew, term, trunc]
    return out


def test_copies_follow_their_own_seed_streams_and_auto_reset():
    venv = VectorEnv(make, 2)
    obs = venv.reset(seed=7)
    assert obs.shape == (2, N, venv.observation_space.shape[0]) and obs.dtype == np.float32
    # Copy k plays the seeds 7 + k, 7 + k + 2, ...: the same as a single env reset with that seed.
    single = make()
    for k in range(2):
        ref, _ = single.reset(seed=copy_seed(7, k, 2, 0))
        np.testing.assert_array_equal(obs[k], np.stack([ref[a] for a in single.possible_agents]))
    acts = actions(2, MAX_CYCLES + 2)
    for t, a in enumerate(acts):
        o, rew, term, trunc, infos = venv.step(a)
        assert rew.shape == term.shape == trunc.shape == (2, N) and len(infos) == 2 and len(infos[0]) == N
        ended = (term | trunc).all(axis=1)
        for k in np.flatnonzero(ended):
            info = infos[k][0]
            assert info["terminal_observation"].shape == venv.observation_space.shape
            assert info["TimeLimit.truncated"] == bool(trunc[k, 0] and not term[k, 0])
            assert not np.array_equal(info["terminal_observation"], o[k, 0])
            # The restarted copy shows its next episode's first observation: seed 7 + k + 2.
            ref, _ = single.reset(seed=copy_seed(7, int(k), 2, 1))
            np.testing.assert_array_equal(o[k], np.stack([ref[a] for a in single.possible_agents]))
        if t == MAX_CYCLES - 1:
            assert ended.all() and trunc.all()    # the time limit ends both copies' first episode
    assert list(venv.episodes) == [2, 2]


def test_every_copy_plays_the_single_envs_episode_bit_for_bit():
    venv = VectorEnv(make, 2, autoreset=False)
    obs = venv.reset(seed=5)
    acts = actions(2, MAX_CYCLES, seed=3)
    steps = [venv.step(a) for a in acts]
    assert venv.ended().all()
    for k in range(2):
        single = make()
        ref, _ = single.reset(seed=copy_seed(5, k, 2, 0))
        agents = single.possible_agents
        np.testing.assert_array_equal(obs[k], np.stack([ref[a] for a in agents]))
        for a, (o, rew, term, trunc, infos) in zip(acts, steps):
            ref, r_rew, r_term, r_trunc, r_infos = single.step(dict(zip(agents, a[k])))
            np.testing.assert_array_equal(o[k], np.stack([ref[a] for a in agents]))
            np.testing.assert_array_equal(rew[k], np.array([r_rew[a] for a in agents], np.float32))
            assert term[k].tolist() == [r_term[a] for a in agents]
            assert trunc[k].tolist() == [r_trunc[a] for a in agents]
            assert infos[k] == [r_infos[a] for a in agents]
        assert not single.agents


def test_same_seed_same_rollout_bit_for_bit_and_split_copies_agree():
    acts = actions(3, MAX_CYCLES + 3)
    first = rollout(VectorEnv(make, 3), acts, seed=11)
    again = rollout(VectorEnv(make, 3), acts, seed=11)
    other = rollout(VectorEnv(make, 3), acts, seed=12)
    for a, b in zip(first, again):
        np.testing.assert_array_equal(a, b)
    assert not np.array_equal(first[0], other[0])
    assert not np.array_equal(first[0][0], first[0][1]), "two copies play the same episode"
    # The same family of three copies held by two vector envs (as worker processes hold them): same rows.
    left, right = VectorEnv(make, 2, first=0, stride=3), VectorEnv(make, 1, first=2, stride=3)
    split = [np.concatenate(p) for p in zip(rollout(left, acts[:, :2], 11), rollout(right, acts[:, 2:], 11))]
    for a, b in zip(first, split):
        np.testing.assert_array_equal(a, b)


def test_partial_reset_without_autoreset_and_the_copies_attributes():
    venv = VectorEnv(make, 2, autoreset=False)
    venv.reset(seed=0)
    for a in actions(2, MAX_CYCLES):
        venv.step(a)
    assert venv.ended().all()
    venv.reset(indices=[1])
    assert list(venv.ended()) == [True, False] and list(venv.episodes) == [1, 2]
    assert venv.get_attr("step_count") == [MAX_CYCLES, 0]
    venv.set_attr("top_down", True, indices=[0])
    assert venv.get_attr("top_down") == [True, False]
    assert [s.shape for s in venv.env_method("state")] == [(9 * N + 3,)] * 2


@pytest.mark.parametrize("kwargs, message", [
    (dict(n_copies=0), "n_copies=0"), (dict(n_copies=2, first=1), "first=1"),
    (dict(n_copies=1, stride=0), "stride=0")])
def test_bad_arguments_are_named(kwargs, message):
    with pytest.raises(ValueError, match=message):
        VectorEnv(make, **kwargs)


def test_bad_actions_seed_and_indices_are_named():
    venv = VectorEnv(make, 2)
    venv.reset(seed=0)
    with pytest.raises(ValueError, match=r"actions: expected shape \(2, 3, 3\)"):
        venv.step(np.zeros((6, 3)))
    with pytest.raises(ValueError, match="seed='a'"):
        venv.seed("a")
    with pytest.raises(ValueError, match=r"indices \[5\]"):
        venv.get_attr("step_count", indices=[5])


class LosesAnAgent(BaseParallelWrapper):
    """The inner env, except that its last agent leaves after the first step (as remove_crashed=True does)."""

    def reset(self, seed=None, options=None):
        out = self.env.reset(seed=seed, options=options)
        self.agents = list(self.env.agents)
        return out

    def step(self, actions):
        out = self.env.step(actions)
        self.agents = list(self.env.agents)[:-1]
        return out


def test_an_agent_leaving_mid_episode_is_refused():
    venv = VectorEnv(lambda: LosesAnAgent(make()), 1)
    venv.reset(seed=0)
    with pytest.raises(ValueError, match=r"env copy 0: agents \['uav_2'\] left before the episode ended"):
        venv.step(np.zeros((1, N, 3), np.float32))


def test_missing_ray_is_a_one_line_error_with_the_pip_command(monkeypatch, tmp_path, capsys):
    from uavform_env.cli import main

    monkeypatch.setitem(sys.modules, "ray", None)          # import ray -> ImportError
    code = main(["leaderboard", "--suite", "smoke", "--policy", "hover", "--backend", "ray",
                 "--out", str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and 'pip install -e ".[ray]"' in err[0]
    assert not (tmp_path / "out").exists()


# --------------------------------------------------------------------------------------- SB3 and TorchRL
def test_sb3_vecenv_view():
    pytest.importorskip("stable_baselines3")
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecCheckNan, VecMonitor
    from stable_baselines3.common.vec_env.util import obs_space_info

    from training.vecenv import SharedPolicyVecEnv

    venv = SharedPolicyVecEnv(make, n_copies=2)
    assert venv.num_envs == 2 * N
    keys, shapes, dtypes = obs_space_info(venv.observation_space)
    assert shapes[None] == venv.observation_space.shape and dtypes[None] == np.float32
    assert venv.seed(4) == [4] * N + [5] * N
    obs = venv.reset()
    assert obs.shape == (2 * N, *venv.observation_space.shape)
    assert all(venv.observation_space.contains(o) for o in obs)
    assert venv.get_attr("step_count") == [0] * (2 * N)
    assert venv.get_attr("n_uavs", indices=[N]) == [N]
    assert venv.env_method("state", indices=[0, N + 1])[1].shape == (9 * N + 3,)
    venv.set_attr("top_down", True, indices=[N])
    assert venv.get_attr("top_down") == [False] * N + [True] * N
    assert venv.env_is_wrapped(object) == [False] * (2 * N)
    # PPO through SB3's own wrappers (VecCheckNan raises on a NaN or inf in observations, rewards or actions).
    model = PPO("MlpPolicy", VecCheckNan(VecMonitor(venv), raise_exception=True), n_steps=50, batch_size=100,
                n_epochs=1, seed=3, device="cpu")
    model.learn(300)
    assert model.num_timesteps == 300
    assert len(model.ep_info_buffer) >= 2 * N      # every row finished episodes of MAX_CYCLES steps
    venv.close()


@pytest.mark.interop
def test_torchrl_view_checks_and_rolls_out_reproducibly():
    torch = pytest.importorskip("torch")
    pytest.importorskip("torchrl")
    from torchrl.envs.utils import check_env_specs

    from uavform_env.torchrl_vector import GROUP, TorchRLVectorEnv

    env = TorchRLVectorEnv(make, n_copies=2, seed=0)
    check_env_specs(env)
    runs = []
    for _ in range(2):
        env = TorchRLVectorEnv(make, n_copies=2, seed=3)
        torch.manual_seed(0)
        runs.append(env.rollout(MAX_CYCLES + 4, break_when_any_done=False))
        env.close()
    td = runs[0]
    assert td.batch_size == (2, MAX_CYCLES + 4)
    assert td["next", GROUP, "observation"].shape == (2, MAX_CYCLES + 4, N, env.venv.observation_space.shape[0])
    assert td["next", GROUP, "reward"].shape == (2, MAX_CYCLES + 4, N, 1)
    done = td["next", "done"].squeeze(-1)
    assert done[:, MAX_CYCLES - 1].all() and not done[:, : MAX_CYCLES - 1].any()   # the time limit, then reset
    assert td["next", "truncated"][:, MAX_CYCLES - 1].all()
    # The env's infos ride along: step counters from the reset on, and the end reason of the time limit.
    steps = td["next", GROUP, "info", "step"]
    assert steps.shape == (2, MAX_CYCLES + 4, N, 1) and steps.dtype == torch.int64
    assert (steps[:, :MAX_CYCLES, :, 0] == torch.arange(1, MAX_CYCLES + 1)[None, :, None]).all()
    assert (td[GROUP, "info", "step"][:, 0] == 0).all() and (td[GROUP, "info", "step"][:, MAX_CYCLES] == 0).all()
    assert (td["next", GROUP, "info", "end_reason"][:, MAX_CYCLES - 1] == END_REASONS.index("timeout")).all()
    assert td["next", GROUP, "info", "clearance"].dtype == torch.float32
    # After TorchRL's partial reset the copies play their second seeds.
    single = make()
    ref, _ = single.reset(seed=copy_seed(3, 1, 2, 1))
    np.testing.assert_array_equal(td[1, MAX_CYCLES][GROUP, "observation"].numpy(),
                                  np.stack([ref[a] for a in single.possible_agents]))
    torch.testing.assert_close(runs[0]["next", GROUP, "observation"], runs[1]["next", GROUP, "observation"],
                               rtol=0, atol=0)
