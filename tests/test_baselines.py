"""The simple baselines (Hover, Random, APF) and the policy registry: every short name flies a 3-UAV env."""

import numpy as np
import pytest

from baselines.simple import APF, Hover, Random
from uavform_env import parallel_env
from uavform_env.policies import available_policies, load_policy
from uavform_env.scenarios import Mission, Scenario
from uavform_env.world import Cylinder


def field(obstacles=(), goal=(20.0, 10.0, 3.0), n_uavs=3):
    return Scenario(name="baselines-field", version=1, seed=None, bounds_lo=(0.0, 0.0, 0.0),
                    bounds_hi=(30.0, 20.0, 10.0), resolution=0.2, obstacles=tuple(obstacles),
                    mission=Mission(start=(6.0, 10.0, 3.0), goal=goal, start_heading=0.0, formation="triangle",
                                    spacing=2.0, n_uavs=n_uavs))


def fly(policy, steps, scenario=None, seed=0):
    """Positions (steps + 1, N, 3) and the actions of every step, flying ``policy``."""
    penv = parallel_env(scenario=scenario or field(), max_cycles=steps + 5)
    obs, _ = penv.reset(seed=seed)
    policy.reset(penv, seed=seed)
    positions, actions = [penv.unwrapped.states[:, :3].copy()], []
    for _ in range(steps):
        acts = policy.act(obs, penv)
        actions.append(np.array([acts[a] for a in sorted(acts)]))
        obs, *_ = penv.step(acts)
        positions.append(penv.unwrapped.states[:, :3].copy())
        if not penv.agents:
            break
    return np.array(positions), np.array(actions)


def test_hover_keeps_uavs_still():
    positions, actions = fly(Hover(), 20)
    np.testing.assert_array_equal(positions, np.broadcast_to(positions[0], positions.shape))
    # zero commands map to v = v_min = 0: action -1 on the speed axis, 0 on yaw and climb
    np.testing.assert_array_equal(actions[..., 0], -1.0)
    np.testing.assert_array_equal(actions[..., 1:], 0.0)


def test_random_is_seeded():
    _, a = fly(Random(), 15, seed=3)
    _, b = fly(Random(), 15, seed=3)
    _, c = fly(Random(), 15, seed=4)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    assert np.all(np.abs(a) <= 1.0) and a.dtype == np.float32


def test_apf_moves_the_formation_toward_the_goal():
    tree = Cylinder(13.0, 11.5, 0.5, 0.0, 12.0)             # off the straight line: repulsion acts, no trap
    positions, _ = fly(APF(), 150, scenario=field(obstacles=(tree,)))
    goal = np.array([20.0, 10.0, 3.0])
    start_gap, end_gap = (np.linalg.norm(positions[i, 0] - goal) for i in (0, -1))
    assert end_gap < start_gap - 8.0                        # 14 m to go; at most 0.8-1 m/s for 15 s
    assert np.all(positions[-1, 1:, 0] > positions[0, 1:, 0] + 5.0)  # the followers come along


def test_apf_config_rejects_negative_gains():
    from baselines.simple import APFConfig
    with pytest.raises(ValueError, match="APFConfig.k_rep"):
        APFConfig(k_rep=-1.0)


@pytest.mark.parametrize("name", available_policies())
def test_every_short_name_loads_and_acts(name):
    penv = parallel_env(scenario=field(), max_cycles=10)
    obs, _ = penv.reset(seed=0)
    policy = load_policy(name)
    policy.reset(penv, seed=0)
    for _ in range(3):
        acts = policy.act(obs, penv)
        assert sorted(acts) == sorted(penv.agents)
        for a in acts.values():
            assert np.shape(a) == (3,) and np.all(np.isfinite(a)) and np.all(np.abs(a) <= 1.0)
        obs, *_ = penv.step(acts)


def test_short_names_include_every_builtin():
    from baselines.registry import BUILTIN
    assert set(BUILTIN) <= set(available_policies())


@pytest.mark.parametrize("cls, cross_field", [
    ("baselines.fusion.config:ExpertConfig", {"e1"}),                  # e1 > e0
    ("baselines.dwa:DWAConfig", {"dist_cap"}),                         # dist_cap <= D_cap
    ("baselines.vfh3d:VFHConfig", {"r_e", "tau_high"}),                # r_e < R_w, tau_high >= tau_low
    ("baselines.astar:AStarConfig", set()),
    ("baselines.simple:APFConfig", set()),
    ("baselines.paper:PaperConfig", set()),
])
def test_every_config_field_has_its_bounds_declared_once(cls, cross_field):
    import dataclasses
    import importlib

    module, name = cls.split(":")
    config = getattr(importlib.import_module(module), name)
    names = {f.name for f in dataclasses.fields(config)}
    assert set(config.BOUNDS) | cross_field == names and not set(config.BOUNDS) & cross_field
    first = sorted(config.BOUNDS)[0]
    with pytest.raises(ValueError, match=f"^{name}.{first}"):
        config(**{first: "not a value"})
