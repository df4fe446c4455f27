"""Known answers of the gust field (uavform_env.wind): its spread, its correlation in space and time, and what it
does to a formation (nearby UAVs drift together), and how the airframe rejects it (``dynamics.wind_drift``)."""

import math

import numpy as np
import pytest

from uavform_env import parallel_env
from uavform_env.config import DisturbanceConfig, EnvConfig, UAVLimits
from uavform_env.dynamics import wind_drift
from uavform_env.wind import GUST_MODES, GustField

from .conftest import small_env_kwargs
from .test_env_behaviour import open_field

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
    correlation length far below their spacing they drift apart about as much as they drift. The field's own
    correlation: the airframe does not oppose the wind here (``wind_authority=0``)."""
    def spread(length):
        moved, apart = [], []
        for seed in range(6):
            penv = parallel_env(**small_env_kwargs(), config=EnvConfig(
                uav=UAVLimits(wind_authority=0.0), disturbance=DisturbanceConfig(wind_std=0.5, wind_length=length)))
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


# ---------------------------------------------------------------- the airframe against the wind (dynamics.wind_drift)
def _hover(disturbance, steps, uav=UAVLimits(), n_uavs=1, seed=0):
    """Positions (steps + 1, N, 3) and drifts (steps, N, 3) of UAVs commanding zero speed."""
    penv = parallel_env(scenario=open_field(n_uavs), max_cycles=steps + 1,
                        config=EnvConfig(uav=uav), disturbance=disturbance)
    penv.reset(seed=seed)
    env = penv.unwrapped
    pos, drift = [env.states[:, :3].copy()], []
    for _ in range(steps):
        penv.step({a: np.array([-1.0, 0.0, 0.0], np.float32) for a in penv.agents})
        pos.append(env.states[:, :3].copy())
        drift.append(env.drift.copy())
    return np.array(pos), np.array(drift), env


def test_steady_wind_below_the_authority_is_rejected_with_the_estimate_lag():
    """lean_k = w (1 - a^k), a = exp(-dt/tau): the drift of step k is w a^k and the offset converges to
    w dt a / (1 - a), the right Riemann sum of the integral of w exp(-t/tau) = w tau."""
    w, lim = np.array([0.6, -0.8, 0.0]), UAVLimits()
    dt, tau = lim.dt, lim.wind_rejection_tau
    assert np.hypot(*w[:2]) < lim.wind_authority
    pos, drift, _ = _hover(DisturbanceConfig(wind_mean=(0.6, -0.8)), 80, lim)
    a = math.exp(-dt / tau)
    k = np.arange(1, 81)
    np.testing.assert_allclose(drift[:, 0], w[None, :] * a ** k[:, None], rtol=1e-9, atol=1e-15)
    offset = pos[-1, 0] - pos[0, 0]
    np.testing.assert_allclose(offset, w * dt * a * (1 - a ** 80) / (1 - a), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(offset, w * 0.45167, rtol=1e-4)               # 0.45167 s for dt 0.1, tau 0.5
    assert np.all(np.abs(offset - w * tau) <= np.abs(w) * dt + 1e-12)        # within one step of w tau
    assert np.linalg.norm(pos[-1, 0] - pos[-20, 0]) < 1e-5                   # at rest: the wind is rejected


def test_wind_above_the_authority_carries_the_excess_along_the_wind():
    lim = UAVLimits(wind_authority=1.5)
    pos, drift, env = _hover(DisturbanceConfig(wind_mean=(1.6, 1.2)), 100, lim)   # |w| = 2 m/s
    np.testing.assert_allclose(drift[-1, 0], [0.4, 0.3, 0.0], atol=1e-9)          # (|w| - 1.5) along w
    np.testing.assert_allclose(np.hypot(*env.lean[0, :2]), 1.5, rtol=1e-12)
    np.testing.assert_allclose(pos[-1, 0] - pos[-2, 0], [0.04, 0.03, 0.0], atol=1e-9)


def test_the_vertical_lean_is_clipped_and_inactive_uavs_keep_theirs():
    lim = UAVLimits(wind_authority=3.0, wind_rejection_tau=0.0)                   # tau 0: the estimate is exact
    air = np.array([[0.0, 0.0, 5.0], [4.0, 0.0, -5.0], [9.0, 9.0, 9.0]])
    lean = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.5, 0.5, 0.5]])
    drift = wind_drift(air, lean, np.array([True, True, False]), lim)
    np.testing.assert_array_equal(lean, [[0.0, 0.0, 3.0], [3.0, 0.0, -3.0], [0.5, 0.5, 0.5]])
    np.testing.assert_array_equal(drift, air - lean)


def test_no_authority_is_the_unopposed_wind():
    pos, drift, env = _hover("gusty", 50, UAVLimits(wind_authority=0.0), n_uavs=2)
    assert np.all(env.lean == 0.0)
    np.testing.assert_array_equal(drift[-1], env.air)
    np.testing.assert_allclose(pos[1:] - pos[:-1], drift * 0.1, atol=1e-12)
    assert np.abs(drift).max() > 0.5                                              # gusty really blew


def test_wind_rejection_is_deterministic():
    runs = [_hover("gusty", 40, n_uavs=2, seed=3) for _ in range(2)]
    np.testing.assert_array_equal(runs[0][0], runs[1][0])
    np.testing.assert_array_equal(runs[0][2].lean, runs[1][2].lean)
    assert np.abs(runs[0][1]).max() > 0.0


def test_bad_wind_rejection_fields_raise_one_line_errors():
    for field, bad in (("wind_authority", -1.0), ("wind_authority", math.nan), ("wind_rejection_tau", -0.1),
                       ("wind_rejection_tau", "fast")):
        with pytest.raises(ValueError, match=f"UAVLimits.{field}=") as err:
            UAVLimits(**{field: bad})
        assert "\n" not in str(err.value)
