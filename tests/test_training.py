"""Residual weight RL: the wrapper, the parameter-sharing VecEnv, checkpoints, the trained-policy loader, training."""

import json
import zipfile

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test

from baselines.expert import WEIGHT_NAMES, ExpertConfig, FusionExpert
from training import ResidualConfig, ResidualWeightEnv
from training.checkpoint import META_MEMBER, ResidualPolicy, read_meta
from training.config import TrainConfig
from training.train import train
from training.vecenv import SharedPolicyVecEnv
from uavform_env import EnvConfig, parallel_env
from uavform_env.policies import load_policy
from uavform_env.rollout import run_episode

from .conftest import small_env_kwargs

TINY = dict(scenario="forest", n_uavs=2, max_cycles=30, timesteps=240, n_envs=1, n_steps=40, batch_size=40,
            n_epochs=1, eval_every=120, eval_seeds=(500,), net_arch=(16,))


def residual_env(**kw):
    return ResidualWeightEnv(parallel_env(**small_env_kwargs(**kw)))


def flight(policy_act, penv, seed):
    """Leader and follower states after every step of one episode flown by ``policy_act(obs)``."""
    obs, _ = penv.reset(seed=seed)
    states = []
    while penv.agents:
        obs, *_ = penv.step(policy_act(obs))
        states.append(penv.unwrapped.states.copy())
    return np.array(states)


def test_zero_action_reproduces_the_expert_bit_for_bit():
    renv = residual_env(max_cycles=40)
    with_wrapper = flight(lambda obs: {a: np.zeros(len(WEIGHT_NAMES), np.float32) for a in obs}, renv, seed=3)
    penv = parallel_env(**small_env_kwargs(max_cycles=40))
    expert = FusionExpert()
    penv.reset(seed=3)
    expert.reset(penv, 3)
    plain = flight(lambda obs: expert.act(obs, penv), penv, seed=3)
    assert np.array_equal(with_wrapper, plain)


def test_a_nonzero_action_changes_the_weights_and_the_flight():
    renv = residual_env(max_cycles=120)          # the first seconds fly the same: the window's edge wins
    action = np.array([1, -1, 0.5, 0, 0, 0, 0], np.float32)
    adjusted = flight(lambda obs: {a: action for a in obs}, renv, seed=3)
    w = renv.weights_in_use["uav_0"]
    assert np.allclose(w[:3], ExpertConfig().weights()[:3] * np.array([4.0, 0.25, 2.0]))
    zero = flight(lambda obs: {a: np.zeros(7, np.float32) for a in obs}, residual_env(max_cycles=120), seed=3)
    assert not np.array_equal(adjusted, zero)


def test_observation_appends_the_weights_in_use():
    renv = residual_env()
    obs, _ = renv.reset(seed=0)
    inner = renv.unwrapped.observation_space("uav_0").shape[0]
    assert obs["uav_0"].shape == (inner + 7,) and np.all(obs["uav_0"][inner:] == 0)
    action = np.linspace(-1, 1, 7).astype(np.float32)
    obs, *_ = renv.step({a: action for a in renv.agents})
    assert np.allclose(obs["uav_1"][inner:], action)
    assert renv.observation_space("uav_1").contains(obs["uav_1"])


def test_team_reward_is_the_mean_of_the_inner_rewards():
    team, own = residual_env(), ResidualWeightEnv(parallel_env(**small_env_kwargs()),
                                                  residual=ResidualConfig(reward="own"))
    for renv in (team, own):
        renv.reset(seed=2)
    action = {a: np.zeros(7, np.float32) for a in team.agents}
    team_rewards, own_rewards = team.step(action)[1], own.step(action)[1]
    assert len(set(own_rewards.values())) > 1
    assert all(r == np.mean(list(own_rewards.values())) for r in team_rewards.values())


def test_parallel_api():
    parallel_api_test(residual_env(max_cycles=20), num_cycles=20)


@pytest.mark.parametrize("actions, message", [
    ("go", "expected a dict"),
    ({"uav_9": np.zeros(7)}, "unknown agent"),
    ({"uav_0": np.zeros(7)}, "no action for live agent"),
    ({"uav_0": np.zeros(3), "uav_1": np.zeros(7), "uav_2": np.zeros(7)}, r"action of uav_0: expected shape \(7,\)"),
    ({"uav_0": np.zeros(7), "uav_1": np.full(7, np.nan), "uav_2": np.zeros(7)}, "action of uav_1: expected finite"),
])
def test_bad_actions_are_named(actions, message):
    renv = residual_env()
    renv.reset(seed=0)
    with pytest.raises(ValueError, match=message):
        renv.step(actions)


def test_bad_configs_are_rejected():
    with pytest.raises(ValueError, match="ResidualConfig.max_factor"):
        ResidualConfig(max_factor=1.0)
    with pytest.raises(ValueError, match="ResidualConfig.reward"):
        ResidualConfig(reward="selfish")
    with pytest.raises(ValueError, match="expert_config: expected a ExpertConfig"):
        ResidualWeightEnv(parallel_env(**small_env_kwargs()), expert_config="fast")


def make_small():
    return ResidualWeightEnv(parallel_env(**small_env_kwargs(n_uavs=2, max_cycles=12)))


def vec_rollout(venv, steps=30, seed=5):
    venv.seed(seed)
    out = [venv.reset()]
    dones, infos = [], []
    for _ in range(steps):
        obs, rew, done, info = venv.step(np.zeros((venv.num_envs, 7), np.float32))
        out.append(obs)
        dones.append(done)
        infos.append(info)
    return np.array(out), np.array(dones), infos


def test_vecenv_rows_auto_reset_and_time_limits():
    venv = SharedPolicyVecEnv(make_small, n_copies=2)
    assert venv.num_envs == 4
    obs, dones, infos = vec_rollout(venv)
    assert obs.shape == (31, 4, 336)
    assert np.array_equal(np.flatnonzero(dones[:, 0]), [11, 23])      # max_cycles 12: ends and restarts
    assert dones[11].all() and not dones[10].any()
    end = infos[11][0]
    assert end["TimeLimit.truncated"] and end["terminal_observation"].shape == (336,)
    assert not np.array_equal(end["terminal_observation"], obs[12, 0])  # the row continues with a reset observation


def test_vecenv_seeding_reproduces_and_processes_match():
    first = vec_rollout(SharedPolicyVecEnv(make_small, n_copies=2))[0]
    again = vec_rollout(SharedPolicyVecEnv(make_small, n_copies=2))[0]
    other = vec_rollout(SharedPolicyVecEnv(make_small, n_copies=2), seed=6)[0]
    assert np.array_equal(first, again) and not np.array_equal(first, other)
    venv = SharedPolicyVecEnv(make_small, n_copies=2, backend="process")
    try:
        assert np.array_equal(vec_rollout(venv)[0], first)
    finally:
        venv.close()


def test_invalid_hyperparameters_are_rejected_before_training(tmp_path):
    for bad, message in ((dict(gamma=1.5), "TrainConfig.gamma"), (dict(n_envs=0), "TrainConfig.n_envs"),
                         (dict(eval_seeds=(2000,)), "eval_seeds"), (dict(batch_size=10_000), "batch_size"),
                         (dict(scenario="moon"), "TrainConfig.scenario"), (dict(net_arch=(0,)), "net_arch")):
        with pytest.raises(ValueError, match=message):
            TrainConfig(**{**TINY, **bad})
    from uavform_env.cli import main

    with pytest.raises(SystemExit) as exit_:                  # argparse checks the bound and names the flag
        main(["train", "--out", str(tmp_path / "run"), "--learning-rate", "-1"])
    assert exit_.value.code == 2
    assert main(["train", "--out", str(tmp_path / "run"), "--batch-size", "7"]) == 2   # TrainConfig's check
    assert not (tmp_path / "run").exists()


def test_batch_size_0_splits_every_rollout_into_equal_minibatches():
    for n_uavs, n_envs, n_steps in ((5, 2, 256), (3, 2, 256), (7, 1, 100), (1, 1, 2)):
        cfg = TrainConfig(n_uavs=n_uavs, n_envs=n_envs, n_steps=n_steps, timesteps=1000)
        rollout = n_steps * n_envs * n_uavs
        assert cfg.rollout_size() == rollout and rollout % cfg.batch_size == 0
        assert cfg.batch_size <= max(2, rollout // 4)
        assert cfg.total_timesteps() % rollout == 0 and 0 <= cfg.total_timesteps() - 1000 < rollout
    assert TrainConfig().batch_size == 640                    # the documented runs' value at N = 5, 2 copies


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    out = tmp_path_factory.mktemp("rw") / "run"
    state = train(TrainConfig(**TINY), out, progress=False)
    return out, state


def test_training_writes_checkpoints_logs_and_a_curve(trained):
    out, state = trained
    assert state["timesteps"] >= 240 and state["best"] is not None
    for name in ("best.zip", "last.zip", "state.json", "config.json", "evaluations.csv", "learning_curve.png"):
        assert (out / name).is_file(), name
    assert list((out / "logs" / "segment-0").glob("events.out.tfevents.*"))
    assert (out / "logs" / "segment-0" / "progress.csv").stat().st_size > 0
    rows = (out / "evaluations.csv").read_text().splitlines()
    assert rows[0].startswith("timesteps,") and len(rows) == 4          # at 0, 120 and 240 (= the end: no repeat)
    meta = read_meta(out / "best.zip")
    assert meta["env"] == "formation_v0" and len(meta["obs_norm"]["mean"]) == 336


def test_the_zero_initialised_start_is_scored_as_the_expert(trained):
    out, _ = trained
    start = (out / "evaluations.csv").read_text().splitlines()[1].split(",")
    expert = run_episode(parallel_env(scenario="forest", n_uavs=2, max_cycles=30), FusionExpert(), seed=500)
    assert start[0] == "0"
    assert float(start[4]) == expert["formation_error_rms"] and float(start[5]) == expert["flight_time"]


def test_refuses_to_overwrite_and_resumes_without_losing_best(trained, tmp_path):
    out, _ = trained
    with pytest.raises(ValueError, match="pass --resume"):
        train(TrainConfig(**TINY), out, progress=False)
    with pytest.raises(ValueError, match="other settings"):
        train(TrainConfig(**{**TINY, "learning_rate": 1e-3}), out, resume=True, progress=False)
    best_before = (out / "best.zip").read_bytes()
    best_state = json.loads((out / "state.json").read_text())["best"]
    state = train(TrainConfig(**{**TINY, "timesteps": 320}), out, resume=True, progress=False)
    assert state["timesteps"] >= 320
    assert list((out / "logs").glob("segment-*")) and (out / "logs" / "segment-1").is_dir()
    if state["best"]["timesteps"] == best_state["timesteps"]:
        assert (out / "best.zip").read_bytes() == best_before
    assert state["best"]["key"] >= best_state["key"]


def test_a_checkpoint_loads_as_a_leaderboard_entry_and_flies(trained):
    out, _ = trained
    policy = load_policy(str(out / "best.zip"))
    assert isinstance(policy, ResidualPolicy)
    metrics = run_episode(parallel_env(**small_env_kwargs(n_uavs=2, max_cycles=20)), policy, seed=0)
    assert metrics["collision"] in (0.0, 1.0) and np.isfinite(metrics["formation_error_rms"])


def test_a_zero_network_policy_is_the_expert(trained):
    out, _ = trained
    policy = ResidualPolicy.load(out / "best.zip")
    net = policy.model.policy.action_net
    net.weight.data.zero_()
    net.bias.data.zero_()
    kwargs = small_env_kwargs(n_uavs=2, max_cycles=25)
    penv = parallel_env(**kwargs)
    penv.reset(seed=1)
    policy.reset(penv, 1)
    residual = flight(lambda obs: policy.act(obs, penv), penv, seed=1)
    penv = parallel_env(**kwargs)
    expert = FusionExpert()
    penv.reset(seed=1)
    expert.reset(penv, 1)
    assert np.array_equal(residual, flight(lambda obs: expert.act(obs, penv), penv, seed=1))


def test_incompatible_checkpoints_refuse_with_the_reason(trained, tmp_path):
    out, _ = trained
    policy = ResidualPolicy.load(out / "best.zip")
    other_layout = parallel_env(**small_env_kwargs(n_uavs=2), config=EnvConfig().replace(
        observation=EnvConfig().observation.replace(k_neighbours=2)))
    other_layout.reset(seed=0)
    with pytest.raises(ValueError, match="observation_fields"):
        policy.reset(other_layout, 0)

    def tampered(name, **changes):
        path = tmp_path / name
        with zipfile.ZipFile(out / "best.zip") as src, zipfile.ZipFile(path, "w") as dst:
            for item in src.namelist():
                data = src.read(item)
                if item == META_MEMBER:
                    data = json.dumps({**json.loads(data), **changes}).encode()
                dst.writestr(item, data)
        return path

    with pytest.raises(ValueError, match="env version 'formation_v1'"):
        load_policy(str(tampered("v1.zip", env="formation_v1")))
    with pytest.raises(ValueError, match="adjusts weights"):
        load_policy(str(tampered("w.zip", weight_names=["alpha0"])))
    corrupt = tmp_path / "corrupt.zip"
    corrupt.write_bytes(b"not a zip")
    with pytest.raises(ValueError, match="not a readable zip"):
        load_policy(str(corrupt))
    with pytest.raises(ValueError, match="checkpoint file not found"):
        load_policy(str(tmp_path / "missing.zip"))


def test_the_published_checkpoint_still_loads_and_flies():
    from pathlib import Path

    published = Path(__file__).resolve().parents[1] / "docs" / "training" / "rw1" / "best.zip"
    policy = load_policy(str(published))
    assert read_meta(published)["train_config"]["scenario"] == "forest"
    metrics = run_episode(parallel_env(**small_env_kwargs(n_uavs=2, max_cycles=10)), policy, seed=0)
    assert metrics["collision"] == 0.0


def test_learning_curve_leaves_out_the_training_panel_until_an_episode_finished(tmp_path):
    """A short run may finish no training episode (SB3 logs no ep_rew_mean): no empty first panel then."""
    import matplotlib.image as mpimg

    from training.train import EVAL_COLUMNS, plot_learning_curve

    (tmp_path / "evaluations.csv").write_text(",".join(EVAL_COLUMNS) + "\n0,1.0,0.5,0.0,2.0,90.0,1\n")
    (tmp_path / "logs" / "segment-0").mkdir(parents=True)
    (tmp_path / "logs" / "segment-0" / "progress.csv").write_text("time/total_timesteps,rollout/ep_rew_mean\n80,\n")
    assert mpimg.imread(plot_learning_curve(tmp_path)).shape[1] == 9 * 110            # two panels
    (tmp_path / "logs" / "segment-0" / "progress.csv").write_text("time/total_timesteps,rollout/ep_rew_mean\n80,-1\n")
    assert mpimg.imread(plot_learning_curve(tmp_path)).shape[1] == 13 * 110           # three panels
