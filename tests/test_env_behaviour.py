"""Behaviour of FormationEnv: determinism, endings, crashes, sensing into the onboard map, bad input."""

import hashlib
import subprocess
import sys

import numpy as np
import pytest

from uavform_env import EnvConfig, parallel_env
from uavform_env.config import DisturbanceConfig
from uavform_env.scenarios import Mission, Scenario
from uavform_env.world import Box, Cylinder

from .conftest import small_env_kwargs


def open_field(n_uavs=1, goal=(12.0, 10.0, 3.0), obstacles=(), formation="column", spacing=2.0):
    return Scenario(name="open-field", version=1, seed=None, bounds_lo=(0.0, 0.0, 0.0), bounds_hi=(30.0, 20.0, 10.0),
                    resolution=0.2, obstacles=tuple(obstacles),
                    mission=Mission(start=(8.0, 10.0, 3.0), goal=goal, start_heading=0.0, formation=formation,
                                    spacing=spacing, n_uavs=n_uavs))


def rollout_digest(seed: int, steps: int = 25) -> str:
    penv = parallel_env(**small_env_kwargs(max_cycles=steps + 5))
    obs, _ = penv.reset(seed=seed)
    rng = np.random.default_rng(seed)
    h = hashlib.sha256()
    for _ in range(steps):
        acts = {a: rng.uniform(-1, 1, 3).astype(np.float32) for a in penv.agents}
        obs, rew, term, trunc, info = penv.step(acts)
        for a in sorted(obs):
            h.update(obs[a].tobytes())
            h.update(np.float64(rew[a]).tobytes())
        h.update(penv.unwrapped.states.tobytes())
        if not penv.agents:
            break
    return h.hexdigest()


def test_same_seed_same_episode_bit_for_bit():
    assert rollout_digest(7) == rollout_digest(7)


def test_unseeded_resets_continue_the_seeded_stream():
    def starts(first_seed):
        penv = parallel_env(**small_env_kwargs(scenario="random-3d"))
        penv.reset(seed=first_seed)
        return [penv.reset()[0]["uav_0"].tobytes() + penv.unwrapped.world.occupied.tobytes() for _ in range(3)]

    a, b = starts(3), starts(3)
    assert a == b and len(set(a)) == 3 and starts(4) != a
    assert rollout_digest(7) != rollout_digest(8)


def test_same_seed_same_episode_across_processes():
    code = ("import sys; sys.path.insert(0, '.');"
            "from tests.test_env_behaviour import rollout_digest; print(rollout_digest(7))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()[-1]
    assert out == rollout_digest(7)


def test_truncation_sets_timelimit_flag():
    penv = parallel_env(scenario=open_field(), max_cycles=5)
    penv.reset(seed=0)
    for _ in range(5):
        obs, rew, term, trunc, info = penv.step({"uav_0": np.zeros(3, np.float32)})
    assert trunc == {"uav_0": True} and term == {"uav_0": False}
    assert info["uav_0"]["TimeLimit.truncated"] is True
    assert penv.agents == []
    with pytest.raises(ValueError, match="after the episode ended"):
        penv.step({"uav_0": np.zeros(3, np.float32)})


def test_leader_reaching_goal_is_success():
    penv = parallel_env(scenario=open_field(goal=(11.0, 10.0, 3.0)), max_cycles=200)
    penv.reset(seed=0)
    for _ in range(200):
        obs, rew, term, trunc, info = penv.step({"uav_0": np.array([1.0, 0.0, 0.0], np.float32)})
        if not penv.agents:
            break
    assert term["uav_0"] and info["uav_0"]["success"] == 1
    assert rew["uav_0"] > 5.0  # success bonus


def test_crash_freezes_uav_and_keeps_it_in_agents():
    wall = Box((9.5, 11.0, 0.0), (10.5, 14.0, 10.0))      # in front of the follower at (8, 12)? column: follower behind
    scn = open_field(n_uavs=2, formation="line", obstacles=(wall,))
    penv = parallel_env(scenario=scn, max_cycles=300)
    penv.reset(seed=0)
    crashed_at = None
    for t in range(300):
        obs, rew, term, trunc, info = penv.step({a: np.array([1.0, 0.0, 0.0], np.float32) for a in penv.agents})
        if info["uav_1"]["crashed"] and crashed_at is None:
            crashed_at = t
            frozen = penv.unwrapped.states[1].copy()
            assert rew["uav_1"] < -5.0
        elif crashed_at is not None:
            assert "uav_1" in penv.agents or not penv.agents
            assert rew["uav_1"] == 0.0
            np.testing.assert_array_equal(penv.unwrapped.states[1, :3], frozen[:3])
            break
    assert crashed_at is not None


def test_remove_crashed_removes_the_agent():
    wall = Box((9.5, 11.0, 0.0), (10.5, 14.0, 10.0))
    penv = parallel_env(scenario=open_field(n_uavs=2, formation="line", obstacles=(wall,)), max_cycles=300,
                        remove_crashed=True)
    penv.reset(seed=0)
    for _ in range(300):
        obs, rew, term, trunc, info = penv.step({a: np.array([1.0, 0.0, 0.0], np.float32) for a in penv.agents})
        if "uav_1" in term and term["uav_1"]:
            break
    assert "uav_1" not in penv.agents and "uav_0" in penv.agents


def test_obstacle_appears_in_onboard_map_and_uavs_do_not():
    pillar = Cylinder(14.0, 10.0, 0.6, 0.0, 10.0)
    penv = parallel_env(scenario=open_field(n_uavs=2, formation="line", obstacles=(pillar,)), max_cycles=50)
    penv.reset(seed=0)
    for _ in range(5):
        penv.step({a: np.zeros(3, np.float32) for a in penv.agents})
    view = penv.unwrapped.onboard("uav_0")
    assert view.occupancy.label(np.array([[13.5, 10.0, 3.0]]))[0] == 1         # first voxel of the pillar facing the UAV
    other = view.neighbour_states[0, :3]
    assert view.occupancy.label(other[None])[0] != 1                             # the neighbour is not an obstacle
    assert view.occupancy.label(np.array([[11.0, 10.0, 3.0]]))[0] == 0          # free space between


def test_onboard_view_is_read_only_and_has_no_ground_truth():
    penv = parallel_env(**small_env_kwargs())
    penv.reset(seed=0)
    view = penv.unwrapped.onboard("uav_1")
    with pytest.raises(ValueError):
        view.state[0] = 1.0
    assert not view.is_leader and view.index == 1
    assert not any(hasattr(view, name) for name in ("world", "occupied", "obstacles"))
    with pytest.raises(ValueError, match="unknown agent"):
        penv.unwrapped.onboard("uav_9")


def test_onboard_state_does_not_reach_the_other_uavs_true_states():
    penv = parallel_env(**small_env_kwargs())
    penv.reset(seed=0)
    penv.step({a: np.full(3, 0.5, np.float32) for a in penv.agents})
    env = penv.unwrapped
    for agent in env.possible_agents:
        view = env.onboard(agent)
        chain, a = [], view.state                      # every array the view's state is a view of
        while a is not None:
            chain.append(a)
            a = a.base
        assert all(isinstance(a, np.ndarray) and a.size == 7 for a in chain)
        assert not np.shares_memory(view.state, env.states)
        assert np.array_equal(view.state, env.states[env.agent_name_mapping[agent]])


def test_observation_slices_and_table():
    penv = parallel_env(**small_env_kwargs())
    obs, _ = penv.reset(seed=0)
    layout = penv.unwrapped.layout
    o = obs["uav_0"]
    assert o[layout.slice("role")][0] == 1.0 and obs["uav_1"][layout.slice("role")][0] == 0.0
    assert layout.slice("neighbours").stop - layout.slice("neighbours").start == 7 * 4
    assert "obstacle_histogram" in layout.table()
    with pytest.raises(KeyError, match="fields"):
        layout.slice("nope")


@pytest.mark.parametrize("bad, match", [
    ({"uav_0": np.array([np.nan, 0, 0])}, "finite"),
    ({"uav_0": np.zeros(2)}, r"shape \(3,\)"),
    ({"uav_7": np.zeros(3)}, "unknown agent"),
    ([np.zeros(3)], "expected a dict"),
    ({}, "missing actions"),
])
def test_bad_actions_are_rejected(bad, match):
    penv = parallel_env(scenario=open_field(), max_cycles=10)
    penv.reset(seed=0)
    with pytest.raises(ValueError, match=match):
        penv.step(bad)


@pytest.mark.parametrize("kwargs, match", [
    (dict(scenario="no-such-scenario"), "no-such-scenario"),
    (dict(scenario="forest", n_uavs=5, formation="diamond"), "at most 4"),
    (dict(scenario="forest", spacing=0.5), "spacing"),
    (dict(scenario="forest", render_mode="video"), "render_mode"),
    (dict(scenario="forest", config="fast"), "EnvConfig"),
])
def test_bad_construction_is_rejected(kwargs, match):
    with pytest.raises(ValueError, match=match):
        parallel_env(**kwargs).reset(seed=0)


def test_start_inside_obstacle_is_rejected():
    scn = open_field(obstacles=(Box((7.0, 9.0, 0.0), (9.0, 11.0, 10.0)),))
    with pytest.raises(ValueError, match="start"):
        parallel_env(scenario=scn).reset(seed=0)


def test_config_errors_name_the_field():
    from uavform_env.config import SensorConfig, UAVLimits

    with pytest.raises(ValueError, match=r"UAVLimits\.v_max"):
        UAVLimits(v_max=-1.0)
    with pytest.raises(ValueError, match=r"SensorConfig\.n_azimuth"):
        SensorConfig(n_azimuth=0)
    with pytest.raises(ValueError, match=r"FormationConfig\.spacing"):
        EnvConfig(formation=EnvConfig().formation.replace(spacing=0.4))
    with pytest.raises(ValueError, match="unknown field"):
        UAVLimits.from_dict({"vmax": 1.0})
    cfg = EnvConfig()
    assert EnvConfig.from_dict(cfg.to_dict()) == cfg


def test_wind_changes_motion_but_not_the_map_layout():
    calm = parallel_env(**small_env_kwargs())
    windy = parallel_env(**small_env_kwargs(), config=EnvConfig(disturbance=DisturbanceConfig(wind_std=0.5)))
    calm.reset(seed=4)
    windy.reset(seed=4)
    assert calm.unwrapped.scenario == windy.unwrapped.scenario
    for _ in range(10):
        calm.step({a: np.zeros(3, np.float32) for a in calm.agents})
        windy.step({a: np.zeros(3, np.float32) for a in windy.agents})
    assert not np.allclose(calm.unwrapped.states[:, :2], windy.unwrapped.states[:, :2])
