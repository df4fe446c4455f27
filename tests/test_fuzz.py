"""Hypothesis fuzzing of the env's configuration and actions: bad values fail with a named field, good ones run."""

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from uavform_env import EnvConfig, parallel_env
from uavform_env.config import DisturbanceConfig, EpisodeConfig, MapConfig, ObservationConfig, SensorConfig, UAVLimits

from .test_env_behaviour import open_field

FIELDS = {
    UAVLimits: ["dt", "v_max", "w_max", "a_max", "dw_max", "vz_max", "r_uav", "z_min", "z_max", "wind_authority",
                "wind_rejection_tau"],
    SensorConfig: ["n_azimuth", "n_elevation", "r_max"],
    MapConfig: ["resolution", "p_hit", "p_miss", "p_min", "p_max"],
    ObservationConfig: ["k_neighbours", "histogram_cell_deg", "histogram_radius"],
    EpisodeConfig: ["max_cycles", "r_goal"],
    DisturbanceConfig: ["wind_std", "wind_tau", "wind_mean", "range_noise_std", "ray_dropout"],
}
CASES = [(cls, name) for cls, names in FIELDS.items() for name in names]
weird = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10 ** 6, 10 ** 6), st.text(max_size=3),
                  st.none(), st.booleans())


@settings(max_examples=150, deadline=None)
@given(case=st.sampled_from(CASES), value=weird)
def test_any_config_value_is_accepted_or_rejected_by_name(case, value):
    cls, name = case
    try:
        cls(**{name: value})
    except ValueError as e:
        assert f"{cls.__name__}.{name}" in str(e)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(actions=st.lists(st.lists(st.floats(allow_nan=True, allow_infinity=True, width=32), min_size=0, max_size=4),
                        min_size=2, max_size=2))
def test_any_action_is_applied_or_rejected_by_agent(actions):
    penv = parallel_env(scenario=open_field(n_uavs=2, formation="line"), max_cycles=20)
    penv.reset(seed=0)
    acts = {a: np.asarray(v, dtype=np.float32) for a, v in zip(penv.agents, actions)}
    good = all(len(v) == 3 and all(math.isfinite(x) for x in v) for v in actions)
    if good:
        obs, *_ = penv.step(acts)
        for a, o in obs.items():
            assert penv.observation_space(a).contains(o)
    else:
        with pytest.raises(ValueError, match="uav_"):
            penv.step(acts)


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(n_az=st.integers(1, 48), n_el=st.integers(1, 9), r_max=st.floats(0.5, 12.0), k=st.integers(0, 6),
       cell=st.sampled_from([10.0, 15.0, 30.0, 45.0]), crop=st.booleans())
def test_valid_configs_give_valid_observations(n_az, n_el, r_max, k, cell, crop):
    cfg = EnvConfig(sensor=SensorConfig(n_azimuth=n_az, n_elevation=n_el, r_max=r_max),
                    observation=ObservationConfig(k_neighbours=k, histogram_cell_deg=cell, include_crop=crop))
    penv = parallel_env(scenario=open_field(n_uavs=2, formation="line"), max_cycles=5, config=cfg)
    obs, _ = penv.reset(seed=1)
    while penv.agents:
        for a, o in obs.items():
            assert penv.observation_space(a).contains(o)
        obs, *_ = penv.step({a: penv.action_space(a).sample() for a in penv.agents})
