"""PettingZoo conformance: the official test suite on the parallel and AEC views, every scenario."""

import pickle

import numpy as np
import pytest
from pettingzoo.test import (api_test, max_cycles_test, parallel_api_test, parallel_seed_test, render_test,
                             state_test)

from uavform_env import env, formation_v0, parallel_env
from uavform_env.env import INFO_KEYS
from uavform_env.scenarios import list_scenarios

from .conftest import small_env_kwargs


def test_parallel_api():
    parallel_api_test(parallel_env(**small_env_kwargs()), num_cycles=80)


def test_parallel_seed():
    parallel_seed_test(lambda: parallel_env(**small_env_kwargs()), num_cycles=40)


def test_aec_api():
    api_test(env(**small_env_kwargs()), num_cycles=40)


def test_render_modes():
    render_test(lambda render_mode=None: env(render_mode=render_mode, **small_env_kwargs(max_cycles=10)))


def test_max_cycles():
    max_cycles_test(formation_v0)


def test_state():
    state_test(env(**small_env_kwargs()), parallel_env(**small_env_kwargs()))


def test_spaces_are_built_once():
    penv = parallel_env(**small_env_kwargs())
    for a in penv.possible_agents:
        assert penv.observation_space(a) is penv.observation_space(a)
        assert penv.action_space(a) is penv.action_space(a)
    assert penv.possible_agents == ["uav_0", "uav_1", "uav_2"]


@pytest.mark.parametrize("name", list_scenarios())
def test_every_scenario_runs(name):
    penv = parallel_env(scenario=name, max_cycles=15)
    obs, infos = penv.reset(seed=1)
    while penv.agents:
        for a, o in obs.items():
            assert penv.observation_space(a).contains(o), (name, a)
        for a, info in infos.items():
            assert set(info) == set(INFO_KEYS)
            assert all(isinstance(v, (int, float, bool, np.number)) for v in info.values())
        obs, rewards, terms, truncs, infos = penv.step({a: penv.action_space(a).sample() for a in penv.agents})
        assert set(obs) == set(rewards) == set(terms) == set(truncs) == set(infos)


def test_pickle_roundtrip_continues_identically():
    penv = parallel_env(**small_env_kwargs())
    penv.reset(seed=3)
    act = {a: np.array([0.5, 0.1, 0.0], np.float32) for a in penv.agents}
    penv.step(act)
    clone = pickle.loads(pickle.dumps(penv))
    o1 = penv.step(act)[0]
    o2 = clone.step(act)[0]
    for a in o1:
        np.testing.assert_array_equal(o1[a], o2[a])


def test_registered_in_pettingzoo():
    import pettingzoo

    if not hasattr(pettingzoo, "make"):
        pytest.skip("this PettingZoo has no registry")
    penv = pettingzoo.make("parallel", "uavform/formation-v0", **small_env_kwargs())
    assert penv.possible_agents[0] == "uav_0"
