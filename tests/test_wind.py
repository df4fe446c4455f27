"""Known answers of the gust field (uavform_env.wind): its spread, its correlation in space and time, and what it
does to a formation (nearby UAVs drift together)."""

import math

import numpy as np

from uavform_env import parallel_env
from uavform_env.config import DisturbanceConfig, EnvConfig
from uavform_env.wind import GUST_MODES, GustField

from .conftest import small_env_kwargs

L, STD, TAU = 20.0, 0.3, 2.0


def _fields(n, **kw):
    args = dict(std=STD, tau=TAU, length=L, n_modes=GUST_MODES, vertical_scale=0.3) | kw
    return [GustField(np.random.default_rng(s), **args) for s in range(n)]


def test_spread_per_axis_and_the_vertical_scale():
    u = np.array([f.at(np.array([[3.0, -4.0, 2.0]]))[0] for f in _fields(2000)])
    np.testing.assert_allclose(u.std(axis=0), [STD, STD, 0.3 * STD], rtol=0.06)
    np.testing.assert_allclose(u.mean(axis=0), 0.0, atol=0.03)


def test_spatial_correlation_is_gaussian_in_distance():
    for d in (2.0, 10.0, 20.0, 40.0):
        pts = np.array([[0.0, 0.0, 3.0], [d * 0.6, d * 0.8, 3.0]])
        u = np.array([f.at(pts) for f in _fields(1500)])[..., :2]
        corr = (u[:, 0] * u[:, 1]).mean() / (u[:, 0] ** 2).mean()
        assert abs(corr - math.exp(-d * d / (2 * L * L))) < 0.05, (d, corr)


def test_temporal_correlation_is_exp_minus_lag_over_tau():
    fields, x = _fields(1500), np.array([[1.0, 2.0, 3.0]])
    before = np.array([f.at(x)[0, :2] for f in fields])
    for f in fields:
        for _ in range(20):  # 20 steps of 0.1 s = tau
            f.advance(0.1)
    after = np.array([f.at(x)[0, :2] for f in fields])
    corr = (before * after).mean() / (before ** 2).mean()
    assert abs(corr - math.exp(-1.0)) < 0.06
    np.testing.assert_allclose(after.std(axis=0), STD, rtol=0.08)  # stationary: the spread stays


def test_same_seed_same_field():
    a, b = (GustField(np.random.default_rng(7), STD, TAU, L, GUST_MODES, 0.3) for _ in range(2))
    pts = np.random.default_rng(0).uniform(0, 30, (5, 3))
    for _ in range(3):
        a.advance(0.1)
        b.advance(0.1)
    np.testing.assert_array_equal(a.at(pts), b.at(pts))


def test_a_formation_drifts_together():
    """Hovering UAVs 2 m apart: under a field with L = 20 m they drift apart far less than they drift; with a
    correlation length far below their spacing they drift apart about as much as they drift."""
    def spread(length):
        moved, apart = [], []
        for seed in range(6):
            penv = parallel_env(**small_env_kwargs(), config=EnvConfig(
                disturbance=DisturbanceConfig(wind_std=0.5, wind_length=length)))
            penv.reset(seed=seed)
            start = penv.unwrapped.states[:, :2].copy()
            for _ in range(30):
                penv.step({a: np.zeros(3, np.float32) for a in penv.agents})
            drift = penv.unwrapped.states[:, :2] - start
            moved.append(np.linalg.norm(drift[0]))
            apart.append(np.linalg.norm(drift[1] - drift[0]))
        return np.mean(moved), np.mean(apart)
    moved, apart = spread(20.0)
    assert apart < 0.2 * moved
    moved, apart = spread(0.05)
    assert apart > 0.8 * moved
