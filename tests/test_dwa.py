"""Standard and improved DWA (spec (b), (c)): known answers, an independent reference, closed loop."""

import math
from dataclasses import replace

import networkx as nx
import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from baselines.dwa import (ABLATIONS, DWAConfig, _heading, _heading_weight, _normalise, _rotation_weight,
                           _select, dwa_plan, window_samples)
from uavform_env.config import UAVLimits
from uavform_env.dynamics import integrate, step

LIM = UAVLimits()
DEG = math.pi / 180.0
SETTINGS = settings(max_examples=40, deadline=None)


def state_row(x=0.0, y=0.0, z=3.0, psi=0.0, v=0.0, w=0.0, vz=0.0):
    return np.array([x, y, z, psi, v, w, vz])


NO_OBSTACLES = np.empty((0, 3))


# ----------------------------------------------------------------------------- reference


def braking_clearance(vs, lim, cfg):
    """The clearance the braking test asks of each speed: the share ``brake_share`` of d_brake(v) = v^2 / (2 a_max)."""
    return cfg.brake_share * vs ** 2 / (2 * lim.a_max)


def rollout_steps(vs, lim, cfg):
    """Steps of each rollout's clearance: T_p, and with a braking share below 1 the stopping time of the top speed."""
    n = round(cfg.T_p / lim.dt)
    return n + (math.ceil(vs.max() / (2 * lim.a_max) / lim.dt - 1e-9) if cfg.brake_share < 1 else 0)


def reference_plan(state, lim, cfg, goal, obstacles, radii, lookahead=None, clearance_now=math.inf,
                   movers_pos=None, movers_vel=None, v_ref=None, prev_alignment=None, mover_dist=True):
    """Straightforward numpy re-implementation of spec (b) + (c), written from the spec formulas; the movers count
    in the dist term only with ``mover_dist``.

    Returns (vs, ws, admissible, clearance_true, score, endpoints); clearance_true is uncapped.
    """
    vs, ws = window_samples(state[4], state[5], lim, cfg)
    n = round(cfg.T_p / lim.dt)
    dt = lim.dt
    psi_k = state[3] + np.outer(ws, np.arange(1, rollout_steps(vs, lim, cfg) + 1)) * dt  # yaw first, unwrapped
    xs = state[0] + np.cumsum(vs[:, None] * np.cos(psi_k) * dt, axis=1)
    ys = state[1] + np.cumsum(vs[:, None] * np.sin(psi_k) * dt, axis=1)
    zs = np.full(xs.shape, state[2])
    pts = np.stack([xs, ys, zs], axis=-1)  # (S, n + tail, 3): the clearance's arc
    xs, ys, psi_k = xs[:, :n], ys[:, :n], psi_k[:, :n]
    if len(obstacles):
        gaps = np.linalg.norm(pts[:, :, None, :] - obstacles[None, None], axis=-1) - radii - lim.r_uav
        c_static = gaps.min(axis=(1, 2))
    else:
        c_static = np.full(len(vs), np.inf)
    d_brake = braking_clearance(vs, lim, cfg)
    adm = (c_static > 0) & (c_static >= d_brake)
    clearance = c_static.copy()
    c_dist = c_static
    if movers_pos is not None:
        t = np.arange(1, n + 1)[:, None, None] * dt
        m_pos = movers_pos[None] + movers_vel[None] * t  # (n, K, 3)
        c_mover = (np.linalg.norm(pts[:, :n, None, :] - m_pos[None], axis=-1) - cfg.R_uu).min(axis=(1, 2))
        adm &= c_mover >= 0
        clearance = np.minimum(clearance, c_mover)
        if mover_dist:
            c_dist = clearance
    ex, ey, psi_end = xs[:, -1], ys[:, -1], psi_k[:, -1]
    g = np.asarray(goal, float)[:2]
    rho_d = math.hypot(*(g - state[:2]))
    bearing = math.atan2(*(g - state[:2])[::-1]) if cfg.heading_ref == "current" else np.arctan2(g[1] - ey, g[0] - ex)
    theta = np.angle(np.exp(1j * (bearing - psi_end)))
    heading = (np.pi - np.abs(theta)) / np.pi
    lam = 1.0
    if cfg.use_goal_dist_correction:
        reach = lim.v_max * cfg.T_p
        lam = min(1.0, rho_d / (cfg.R_sw or reach))
        dg = 1 - np.hypot(g[0] - ex, g[1] - ey) / (rho_d + reach)
        heading = lam * heading + (1 - lam) * dg
    dist = np.minimum(c_dist, cfg.D_cap if cfg.dist_cap is None else cfg.dist_cap)
    if v_ref is not None:
        vel = 1 - np.abs(vs - v_ref) / lim.v_max
    elif cfg.approach_speed_profile and lam < 1:
        v_goal = min(lim.v_max, math.sqrt(2 * lim.a_max * max(rho_d - cfg.r_goal, 0)))
        vel = 1 - np.abs(vs - v_goal) / lim.v_max
    else:
        vel = vs / lim.v_max
    rot = 1 - np.abs(ws - (state[5] if cfg.rotation_mode == "delta" else 0)) / lim.w_max
    la = g if lookahead is None else np.asarray(lookahead, float)[:2]
    a = la - state[:2]
    b = np.column_stack([ex - state[0], ey - state[1]])
    short = np.linalg.norm(b, axis=1) < 1e-3
    b[short] = np.column_stack([np.cos(psi_end), np.sin(psi_end)])[short]
    cos_ab = np.clip(b @ a / (np.linalg.norm(a) * np.linalg.norm(b, axis=1)), -1, 1) \
        if np.linalg.norm(a) >= 1e-9 else np.ones(len(vs))  # the kernel: c = 1 below 1e-9
    c_prev = 1.0 if prev_alignment is None else prev_alignment
    if not cfg.use_astar_weight:
        alpha = np.full(len(vs), cfg.alpha)
    else:
        c_used = cos_ab if cfg.astar_weight_mode == "per_candidate" else np.full(len(vs), c_prev)
        alpha = cfg.alpha0 * (cfg.kappa + (1 - cfg.kappa) * (1 + c_used) / 2)
    eps = 0.0
    if cfg.use_rotation_cost:
        eps = cfg.eps0 * ((1 + c_prev) / 2 if cfg.rot_weight_mode == "alignment"
                          else np.clip((clearance_now - cfg.d_in) / (cfg.d_out - cfg.d_in), 0, 1))

    def norm(term):
        out = np.zeros(len(vs))
        if cfg.norm == "sum":
            total = term[adm].sum()
            if total != 0:
                out[adm] = term[adm] / total
        elif adm.any() and term[adm].max() - term[adm].min() > 1e-12 * max(1, abs(term[adm].max())):
            out[adm] = (term[adm] - term[adm].min()) / (term[adm].max() - term[adm].min())
        return out

    score = alpha * norm(heading) + cfg.beta * norm(dist) + cfg.gamma * norm(vel) + eps * norm(rot)
    score[~adm] = -np.inf
    return vs, ws, adm, clearance, score, np.column_stack([ex, ey, zs[:, -1]])


def random_scene(data, with_movers):
    """A random state, goal and obstacle field (some samples blocked, some free)."""
    f = st.floats
    state = state_row(psi=data.draw(f(-math.pi, math.pi)), v=data.draw(f(0, 1)),
                      w=data.draw(f(-LIM.w_max, LIM.w_max)))
    m = data.draw(st.integers(0, 12))
    ang = np.array(data.draw(st.lists(f(-math.pi, math.pi), min_size=m, max_size=m)))
    rng = np.array(data.draw(st.lists(f(0.8, 5.0), min_size=m, max_size=m)))
    obstacles = np.column_stack([rng * np.cos(ang), rng * np.sin(ang), np.full(m, 3.0)])
    radii = np.array(data.draw(st.lists(f(0.0, 0.6), min_size=m, max_size=m)))
    goal = np.array([data.draw(f(-15, 15)), data.draw(f(-15, 15)), 3.0])
    movers = {}
    if with_movers:
        k = data.draw(st.integers(1, 2))
        movers = dict(movers_pos=np.column_stack([np.array(data.draw(st.lists(f(-4, 4), min_size=2 * k,
                                                                              max_size=2 * k))).reshape(k, 2),
                                                  np.full(k, 3.0)]),
                      movers_vel=np.column_stack([np.array(data.draw(st.lists(f(-1, 1), min_size=2 * k,
                                                                              max_size=2 * k))).reshape(k, 2),
                                                  np.zeros(k)]),
                      mover_dist=data.draw(st.booleans()))
    return state, goal, obstacles, radii, movers


@pytest.mark.parametrize("name,extra", [("DWA", {}), ("IDWA", {}), ("DWA", {"norm": "minmax"}),
                                        ("IDWA", {"astar_weight_mode": "per_step", "rotation_mode": "delta",
                                                  "heading_ref": "current", "approach_speed_profile": True}),
                                        ("IDWA", {"rot_weight_mode": "alignment", "norm": "minmax"}),
                                        ("IDWA", {"dist_cap": 0.5, "approach_speed_profile": True}),
                                        ("IDWA", {"brake_share": 0.0}), ("DWA", {"brake_share": 0.4, "T_p": 1.0})])
@given(data=st.data())
@SETTINGS
def test_matches_independent_reference(name, extra, data):
    """Admissibility, clearance, scores and the pick agree with the numpy reference."""
    cfg = DWAConfig.ablation(name, **extra)
    state, goal, obstacles, radii, movers = random_scene(data, with_movers=data.draw(st.booleans()))
    lookahead = np.array([data.draw(st.floats(-10, 10)), data.draw(st.floats(-10, 10))])
    kw = dict(lookahead=lookahead, clearance_now=data.draw(st.floats(0, 3)),
              prev_alignment=data.draw(st.floats(-1, 1)), **movers)
    res = dwa_plan(state, LIM, cfg, goal, obstacles, radii, **kw)
    vs, ws, adm, clearance, score, endpoints = reference_plan(state, LIM, cfg, goal, obstacles, radii, **kw)
    cand = res.candidates
    np.testing.assert_allclose(cand.v, vs)
    np.testing.assert_allclose(cand.w, ws)
    d_brake = braking_clearance(vs, LIM, cfg)
    clear_of_boundary = np.abs(clearance - np.maximum(d_brake, 0)) > 1e-9
    np.testing.assert_array_equal(cand.admissible[clear_of_boundary], adm[clear_of_boundary])
    # a clearance exactly on the bound (e.g. 0 at rest touching an obstacle) may round either way
    assume(np.array_equal(cand.admissible, adm))
    cap = np.maximum(cfg.D_cap, d_brake)
    np.testing.assert_allclose(cand.clearance[adm], np.minimum(clearance, cap)[adm], atol=1e-9)
    np.testing.assert_allclose(cand.endpoint, endpoints, atol=1e-9)
    assert res.n_admissible == adm.sum()
    if adm.any():
        np.testing.assert_allclose(cand.score[adm], score[adm], rtol=1e-9, atol=1e-12)
        assert res.admissible and score[np.flatnonzero((cand.v == res.v) & (cand.w == res.w))[0]] >= \
            score.max() - 1e-12
    else:
        assert not res.admissible


# ----------------------------------------------------------------------------- Appendix B 1-4


def test_heading_wraps_across_pi():
    """Goal bearing +179 deg with yaw -179 deg is 2 deg off, not 358 deg."""
    assert _heading(179 * DEG, -179 * DEG) == pytest.approx((math.pi - 2 * DEG) / math.pi)
    assert _heading(-179 * DEG, 179 * DEG) == pytest.approx((math.pi - 2 * DEG) / math.pi)
    # closed form: a UAV at yaw -179 deg turns clockwise (w < 0) towards a goal at bearing +179 deg
    goal = 100 * np.array([math.cos(179 * DEG), math.sin(179 * DEG), 0.0]) + [0, 0, 3]
    res = dwa_plan(state_row(psi=-179 * DEG, v=0.5), LIM, DWAConfig(), goal, NO_OBSTACLES, 0.0)
    assert res.admissible and res.w < 0


def test_window_known_answer():
    vs, ws = window_samples(0.5, 0.0, LIM, DWAConfig())
    assert len(vs) == 5 * 11
    np.testing.assert_allclose(np.unique(vs), [0.48, 0.49, 0.50, 0.51, 0.52])
    np.testing.assert_allclose(np.unique(ws), np.arange(-5, 6) * DEG, atol=1e-12)


@given(v0=st.floats(0, 1), w0=st.floats(-LIM.w_max, LIM.w_max),
       v_res=st.sampled_from([0.01, 0.007, 0.05]), w_res=st.sampled_from([DEG, 0.7 * DEG, 3 * DEG]),
       v_cap=st.none() | st.floats(0, 1))
@SETTINGS
def test_window_contains_ends_and_zero(v0, w0, v_res, w_res, v_cap):
    cfg = DWAConfig(v_res=v_res, w_res=w_res)
    vs, ws = window_samples(v0, w0, LIM, cfg, v_cap=v_cap)
    v_lo = max(LIM.v_min, v0 - LIM.a_max * LIM.dt)
    v_hi = min(LIM.v_max, v0 + LIM.a_max * LIM.dt)
    if v_cap is not None:
        v_hi = max(v_lo, min(v_hi, v_cap))
    w_lo = max(-LIM.w_max, w0 - LIM.dw_max * LIM.dt)
    w_hi = min(LIM.w_max, w0 + LIM.dw_max * LIM.dt)
    v_axis, w_axis = np.unique(vs), np.unique(ws)
    assert v_axis[0] == v_lo and v_axis[-1] == v_hi
    assert w_axis[0] == w_lo and w_axis[-1] == w_hi
    assert (w_lo <= 0 <= w_hi) == (0.0 in w_axis)
    # spacing at most res (w = 0 and hi snap onto grid points within 1e-9 res)
    assert np.diff(v_axis).max(initial=0) <= v_res * (1 + 1e-8)
    assert np.diff(w_axis).max(initial=0) <= w_res * (1 + 1e-8)
    assert len(vs) == len(v_axis) * len(w_axis)


def test_clearance_is_the_exact_minimum_over_a_dense_cloud():
    """Nearest-first buckets, the early break and the bounding-sphere skips change no bit of the clearance.

    Every admissible sample's clearance equals the brute-force min over all rollout points and all
    obstacles (same arithmetic, capped at max(D_cap, d_brake)), and shuffling the obstacles changes
    neither the clearances nor the scores nor the pick.
    """
    rng = np.random.default_rng(3)
    state = state_row(psi=0.3, v=0.3, w=0.05)
    vz, radius = 0.1, 0.1732
    obstacles = np.round(rng.uniform([-6, -6, 0], [6, 6, 6], (1500, 3)) / 0.2) * 0.2 + 0.1
    obstacles = obstacles[np.linalg.norm(obstacles - state[:3], axis=1) > 0.9]
    cfg = DWAConfig.ablation("IDWA")
    res = dwa_plan(state, LIM, cfg, [8.0, 3.0], obstacles, radius, vz_cmd=vz)
    again = dwa_plan(state, LIM, cfg, [8.0, 3.0], obstacles[rng.permutation(len(obstacles))], radius, vz_cmd=vz)
    c = res.candidates
    adm = c.admissible
    assert 0 < adm.sum() < adm.size
    np.testing.assert_array_equal(again.candidates.admissible, adm)
    np.testing.assert_array_equal(again.candidates.clearance[adm], c.clearance[adm])
    np.testing.assert_array_equal(again.candidates.score, c.score)
    assert (again.v, again.w) == (res.v, res.w)
    rad = radius + LIM.r_uav
    for i in np.flatnonzero(adm):
        x, y, z, psi = state[:4]
        points = []
        for _ in range(round(cfg.T_p / LIM.dt)):
            x, y, z, psi = integrate(x, y, z, psi, c.v[i], c.w[i], vz, LIM.dt)
            points.append((x, y, z))
        d = np.array(points)[:, None, :] - obstacles[None, :, :]
        exact = (np.sqrt(d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1] + d[..., 2] * d[..., 2]) - rad).min()
        assert c.clearance[i] == min(exact, max(cfg.D_cap, c.v[i] ** 2 / (2 * LIM.a_max)))


def test_obstacle_mid_rollout_is_inadmissible():
    """The obstacle sits halfway along every rollout; the endpoints alone would look safe."""
    lim = UAVLimits(r_uav=0.05, r_safe=0.0)
    state = state_row(v=0.1)
    obstacle = np.array([[0.15, 0.0, 3.0]])
    end_gap = 0.3 - 0.15 - 0.02 - 0.05  # endpoint of the straight rollout to the obstacle surface
    assert end_gap > (0.12 ** 2) / (2 * lim.a_max)  # an endpoint-only check would accept it
    res = dwa_plan(state, lim, DWAConfig(), [5.0, 0.0, 3.0], obstacle, 0.02)
    assert not res.admissible and res.n_admissible == 0
    res = dwa_plan(state, lim, DWAConfig(), [5.0, 0.0, 3.0], obstacle + [0, 0.3, 0], 0.02)
    assert res.admissible and res.n_admissible == res.candidates.v.size


def test_climb_passes_over_a_low_obstacle():
    """3D clearance: with vz_cmd the rollout rises above an obstacle it would hit in level flight."""
    state = state_row(v=0.3, z=3.6)
    obstacle = np.array([[1.0, 0.0, 3.0]])  # top at z = 3.2; level flight passes 0.1 m above the margin
    level = dwa_plan(state, LIM, DWAConfig(), [9.0, 0, 3], obstacle, 0.2)
    assert not level.candidates.admissible[level.candidates.w == 0].any()
    climb = dwa_plan(state, LIM, DWAConfig(), [9.0, 0, 3], obstacle, 0.2, vz_cmd=0.5)
    assert climb.candidates.admissible[climb.candidates.w == 0].all()
    assert climb.endpoint[2] == pytest.approx(3.6 + 0.5 * 3.0)


@given(terms=st.lists(st.floats(0.01, 10), min_size=4 * 6, max_size=4 * 6),
       which=st.integers(0, 3), scale=st.floats(0.01, 100))
@SETTINGS
def test_sum_normalisation_is_scale_free(terms, which, scale):
    """Scaling one term by a constant leaves u* unchanged under sum normalisation (b8)."""
    terms = np.array(terms).reshape(4, 6)
    vs, ws = np.linspace(0.1, 0.6, 6), np.linspace(-0.1, 0.1, 6)
    admissible = np.ones(6, dtype=bool)
    weights = np.array([0.1, 0.2, 0.1, 0.05])

    def pick(t):
        score = sum(wt * _normalise(ti, admissible, False) for wt, ti in zip(weights, t))
        return _select(score, vs, ws)

    scaled = terms.copy()
    scaled[which] *= scale
    np.testing.assert_allclose(_normalise(scaled[which], admissible, False),
                               _normalise(terms[which], admissible, False))
    assert pick(scaled) == pick(terms)


def test_normalisation_skips_degenerate_terms_and_inadmissible_samples():
    adm = np.array([True, True, False])
    np.testing.assert_array_equal(_normalise(np.zeros(3), adm, False), 0.0)
    np.testing.assert_array_equal(_normalise(np.array([2.0, 2.0, 9.0]), adm, True), 0.0)
    np.testing.assert_allclose(_normalise(np.array([1.0, 3.0, 9.0]), adm, False), [0.25, 0.75, 0.0])
    np.testing.assert_allclose(_normalise(np.array([1.0, 3.0, 9.0]), adm, True), [0.0, 1.0, 0.0])


def test_ties_prefer_small_turn_then_high_speed():
    vs = np.array([0.5, 0.5, 0.6, 0.6, 0.4])
    ws = np.array([0.1, -0.05, 0.05, -0.1, 0.0])
    assert _select(np.array([1.0, 1.0, 1.0, 1.0, 0.9]), vs, ws) == 2  # |w| = 0.05 twice: larger v wins
    assert _select(np.array([1.0, 1.0, 1.0, 1.0, 1.0]), vs, ws) == 4  # w = 0
    assert _select(np.full(5, -np.inf), vs, ws) == -1


# ----------------------------------------------------------------------------- fallback, E8, E10, E11


def test_braking_fallback_when_nothing_is_admissible():
    state = state_row(v=0.6, w=0.1)
    wall = np.array([[0.4, y, 3.0] for y in np.linspace(-2, 2, 21)])
    res = dwa_plan(state, LIM, DWAConfig(), [9.0, 0, 3], wall, 0.2)
    assert not res.admissible and res.n_admissible == 0 and math.isnan(res.score)
    assert res.v == pytest.approx(0.6 - LIM.a_max * LIM.dt) and res.w == 0.1
    assert res.clearance < 0
    # the endpoint belongs to the braking command (independent rollout)
    psi = 0.1 * LIM.dt * np.arange(1, 31)
    np.testing.assert_allclose(res.endpoint[:2], [np.sum(res.v * np.cos(psi) * LIM.dt),
                                                  np.sum(res.v * np.sin(psi) * LIM.dt)], atol=1e-12)
    res = dwa_plan(state_row(v=0.01), LIM, DWAConfig(), [9.0, 0, 3], wall - [0.2, 0, 0], 0.2)
    assert res.v == 0.0


def test_brake_share_lets_a_uav_fly_beside_a_wall():
    """1 m beside a wall, parallel to it, at 0.8 m/s: the clearance form (share 1) needs 1.6 m of clearance to
    keep that speed and brakes; Fox's free-arc form (share 0) keeps it, since nothing lies on the path; head-on
    both brake, and so does Fox's form for a wall beyond the horizon but within the stopping distance past it."""
    wall = np.array([[x, 1.0 + 0.1 + LIM.r_uav, 3.0] for x in np.arange(-3.0, 6.0, 0.1)])
    state = state_row(v=0.8)
    goal = [9.0, 0.0, 3.0]
    spec = dwa_plan(state, LIM, DWAConfig(), goal, wall, 0.1)
    fox = dwa_plan(state, LIM, DWAConfig(brake_share=0.0), goal, wall, 0.1)
    assert spec.v < 0.8 and fox.v >= 0.8 and fox.admissible
    assert dwa_plan(state, LIM, DWAConfig(), goal, wall, 0.1, brake_share=0.0).v == fox.v   # the per-call override
    ahead = np.array([[2.0 + 0.1 + LIM.r_uav, y, 3.0] for y in np.arange(-3.0, 3.0, 0.1)])
    head_on = dwa_plan(state, LIM, DWAConfig(brake_share=0.0), goal, ahead, 0.1)
    assert head_on.v < 0.8

    def straight_at_0_8_admissible(wall_x):                 # the sample v = 0.8, w = 0 toward a wall wall_x m ahead
        wall = np.array([[wall_x + 0.1 + LIM.r_uav, y, 3.0] for y in np.arange(-3.0, 3.0, 0.1)])
        c = dwa_plan(state, LIM, DWAConfig(brake_share=0.0), goal, wall, 0.1).candidates
        return bool(c.admissible[(np.abs(c.v - 0.8) < 1e-9) & (c.w == 0.0)][0])
    # horizon 2.4 m + the stopping arc of the window's top speed 0.82 m/s (2.1 s): 4.12 m
    assert not straight_at_0_8_admissible(4.0) and straight_at_0_8_admissible(4.3)
    with pytest.raises(ValueError, match="brake_share"):
        dwa_plan(state, LIM, DWAConfig(), goal, wall, 0.1, brake_share=1.5)


def test_e8_far_from_goal_equals_standard_heading():
    obstacles = np.array([[2.0, 0.5, 3.0], [3.0, -1.0, 3.0]])
    state = state_row(v=0.5, psi=0.2)
    goal = [8.0, 1.0, 3.0]  # rho_D > R_sw = 3 m: lambda = 1
    base = dwa_plan(state, LIM, DWAConfig.ablation("DWA"), goal, obstacles, 0.3)
    e8 = dwa_plan(state, LIM, DWAConfig.ablation("DWA+E8"), goal, obstacles, 0.3)
    assert (e8.v, e8.w) == (base.v, base.w)
    np.testing.assert_array_equal(e8.candidates.score, base.candidates.score)


def test_e8_near_goal_turns_into_distance_progress():
    """With lambda ~ 0 and only the heading term, u* is the endpoint nearest the goal."""
    cfg = DWAConfig.ablation("DWA+E8", R_sw=1e9, beta=0.0, gamma=0.0)
    state = state_row(v=0.5)
    goal = np.array([1.2, 0.2, 3.0])  # every endpoint overshoots it: the azimuth term swings (c1)
    res = dwa_plan(state, LIM, cfg, goal, NO_OBSTACLES, 0.0)
    rho_v = np.hypot(*(res.candidates.endpoint[:, :2] - goal[:2]).T)
    assert np.hypot(*(res.endpoint[:2] - goal[:2])) == pytest.approx(rho_v.min())
    plain = dwa_plan(state, LIM, DWAConfig(beta=0.0, gamma=0.0), goal, NO_OBSTACLES, 0.0)
    assert (plain.v, plain.w) != (res.v, res.w)


def test_e8_goal_distance_is_rho_d_of_the_blend_and_the_approach_profile():
    """``goal_distance`` replaces |goal - D| in lambda and the approach speed profile only: the distance to where the
    UAV stops when DWA steers toward a nearer point (a path's lookahead). inf: as far from any stop as E8 off."""
    obstacles = np.array([[3.5, 1.5, 3.0], [3.0, -2.0, 3.0]])
    state = state_row(v=0.5, psi=0.2)
    goal = np.array([1.5, 0.4, 3.0])                     # 1.55 m ahead: lambda < 1 and the profile brakes
    cfg = DWAConfig.ablation("IDWA", approach_speed_profile=True)
    near = dwa_plan(state, LIM, cfg, goal, obstacles, 0.3)
    same = dwa_plan(state, LIM, cfg, goal, obstacles, 0.3, goal_distance=float(np.hypot(1.5, 0.4)))
    np.testing.assert_array_equal(same.candidates.score, near.candidates.score)
    steer = dwa_plan(state, LIM, cfg, goal, obstacles, 0.3, goal_distance=math.inf)
    no_e8 = dwa_plan(state, LIM, replace(cfg, use_goal_dist_correction=False, approach_speed_profile=False), goal,
                     obstacles, 0.3)
    np.testing.assert_array_equal(steer.candidates.score, no_e8.candidates.score)
    assert not np.array_equal(steer.candidates.score, near.candidates.score)
    far = dwa_plan(state, LIM, cfg, goal, obstacles, 0.3, goal_distance=3.0)  # lambda = 3 / R_sw = 1, no profile
    np.testing.assert_array_equal(far.candidates.score, steer.candidates.score)


def test_e10_weight_known_answers():
    assert _heading_weight(1.0, 0.1, 0.2) == pytest.approx(0.1)
    assert _heading_weight(-1.0, 0.1, 0.2) == pytest.approx(0.02)
    assert _heading_weight(0.0, 0.1, 0.2) == pytest.approx(0.06)


def test_e10_alignment_of_the_chosen_endpoint():
    state = state_row(v=0.5, psi=0.3)
    lookahead = np.array([0.0, 4.0])
    res = dwa_plan(state, LIM, DWAConfig.ablation("DWA+E8+E10"), [20.0, 0, 3], NO_OBSTACLES, 0.0,
                   lookahead=lookahead)
    b = res.endpoint[:2] - state[:2]
    assert res.alignment == pytest.approx(b @ lookahead / (np.linalg.norm(b) * 4.0))
    # per_step: one alpha for all candidates, from the previous alignment (beta = gamma = 0: score = alpha * h)
    cfg = DWAConfig.ablation("DWA+E8+E10", astar_weight_mode="per_step", beta=0.0, gamma=0.0)
    aligned = dwa_plan(state, LIM, cfg, [20.0, 0, 3], NO_OBSTACLES, 0.0, prev_alignment=1.0)
    opposite = dwa_plan(state, LIM, cfg, [20.0, 0, 3], NO_OBSTACLES, 0.0, prev_alignment=-1.0)
    assert (aligned.v, aligned.w) == (opposite.v, opposite.w)
    assert opposite.score == pytest.approx(cfg.kappa * aligned.score)


def test_e11_rotation_weight_fades_near_obstacles():
    cfg = DWAConfig.ablation("IDWA")
    assert _rotation_weight(cfg, math.inf, 1.0) == cfg.eps0
    assert _rotation_weight(cfg, cfg.d_out + 1, 1.0) == cfg.eps0
    assert _rotation_weight(cfg, cfg.d_in, 1.0) == 0.0
    assert _rotation_weight(cfg, -0.1, 1.0) == 0.0
    assert _rotation_weight(cfg, 0.5 * (cfg.d_in + cfg.d_out), 1.0) == pytest.approx(cfg.eps0 / 2)
    assert _rotation_weight(DWAConfig.ablation("DWA+E8+E10"), math.inf, 1.0) == 0.0
    aligned = DWAConfig.ablation("IDWA", rot_weight_mode="alignment")
    assert _rotation_weight(aligned, 0.0, 0.0) == pytest.approx(cfg.eps0 / 2)


@pytest.mark.parametrize("mode,w0,expected_w", [("abs", 0.05, 0.0), ("delta", 0.05, 0.05)])
def test_e11_alone_prefers_the_smallest_turn(mode, w0, expected_w):
    cfg = DWAConfig.ablation("IDWA", alpha0=0.0, beta=0.0, gamma=0.0, eps0=1.0, rotation_mode=mode)
    res = dwa_plan(state_row(v=0.5, w=w0), LIM, cfg, [0.0, 9.0, 3], NO_OBSTACLES, 0.0)
    assert res.w == pytest.approx(expected_w)
    near = dwa_plan(state_row(v=0.5, w=w0), LIM, cfg, [0.0, 9.0, 3], NO_OBSTACLES, 0.0, clearance_now=0.1)
    assert near.score == 0.0  # eps_t = 0 next to an obstacle: no term left


# ----------------------------------------------------------------------------- movers


def test_oncoming_mover_blocks_straight_samples():
    """A neighbour approaching 0.7 m to the left: straight is too close (< R_uu), a right turn is not."""
    state = state_row(v=0.5)
    res = dwa_plan(state, LIM, DWAConfig(), [9.0, 0, 3], NO_OBSTACLES, 0.0,
                   movers_pos=[[3.0, 0.7, 3.0]], movers_vel=[[-0.5, 0.0, 0.0]])
    assert not res.candidates.admissible[res.candidates.w >= 0].any()
    assert res.admissible and res.w < 0


def test_movers_compared_at_the_same_time_step():
    """A mover now at the rollout's end but flying ahead at the same speed never gets close."""
    state = state_row(v=0.5)
    pos = [[1.5, 0.0, 3.0]]
    same_speed = dwa_plan(state, LIM, DWAConfig(), [9.0, 0, 3], NO_OBSTACLES, 0.0,
                          movers_pos=pos, movers_vel=[[0.5, 0.0, 0.0]])
    straight = same_speed.candidates.w == 0
    assert same_speed.candidates.admissible[straight].all()
    parked = dwa_plan(state, LIM, DWAConfig(), [9.0, 0, 3], NO_OBSTACLES, 0.0,
                      movers_pos=pos, movers_vel=[[0.0, 0.0, 0.0]])
    assert not parked.candidates.admissible[straight].any()


def test_mover_clearance_counts_in_dist_but_not_in_braking():
    """A wingman flying alongside 1 m away: admissible at speed, and its gap minus R_uu is the clearance."""
    state = state_row(v=0.8)
    cfg = DWAConfig()
    res = dwa_plan(state, LIM, cfg, [30.0, 0, 3], NO_OBSTACLES, 0.0,
                   movers_pos=[[0.0, 1.0, 3.0]], movers_vel=[[0.8, 0.0, 0.0]])
    straight = (res.candidates.w == 0) & np.isclose(res.candidates.v, 0.8)
    assert res.candidates.admissible[straight].all()
    assert res.candidates.clearance[straight][0] == pytest.approx(1.0 - cfg.R_uu, abs=1e-9)


def test_leader_movers_count_in_admissibility_not_in_dist():
    """``mover_dist=False`` (a leader given right of way, (g6)): a wingman 1.2 m to the left, flying alongside,
    leaves the dist term as in free space, though the clearances report its 0.4 m gap; counted, it lowers the
    score of the samples veering toward it. Oncoming 0.7 m to the left, it blocks the straight samples either way."""
    state = state_row(v=0.8)
    cfg = DWAConfig()
    wing = dict(movers_pos=[[0.0, 1.2, 3.0]], movers_vel=[[0.8, 0.0, 0.0]])
    alone = dwa_plan(state, LIM, cfg, [30.0, 0, 3], NO_OBSTACLES, 0.0)
    counted = dwa_plan(state, LIM, cfg, [30.0, 0, 3], NO_OBSTACLES, 0.0, **wing)
    ignored = dwa_plan(state, LIM, cfg, [30.0, 0, 3], NO_OBSTACLES, 0.0, mover_dist=False, **wing)
    np.testing.assert_array_equal(ignored.candidates.score, alone.candidates.score)
    np.testing.assert_array_equal(ignored.candidates.clearance, counted.candidates.clearance)
    assert 0.0 < ignored.candidates.clearance.min() <= 1.2 - cfg.R_uu + 1e-9 < alone.candidates.clearance.min()
    left = counted.candidates.w == counted.candidates.w.max()
    assert (counted.candidates.score[left] < ignored.candidates.score[left]).all()
    oncoming = dict(movers_pos=[[3.0, 0.7, 3.0]], movers_vel=[[-0.5, 0.0, 0.0]])
    for mover_dist in (True, False):
        res = dwa_plan(state_row(v=0.5), LIM, cfg, [9.0, 0, 3], NO_OBSTACLES, 0.0, mover_dist=mover_dist, **oncoming)
        assert not res.candidates.admissible[res.candidates.w >= 0].any()


# ----------------------------------------------------------------------------- config and inputs


def test_ablation_names_set_the_flags():
    for name, flags in ABLATIONS.items():
        cfg = DWAConfig.ablation(name)
        assert (cfg.use_goal_dist_correction, cfg.use_astar_weight, cfg.use_rotation_cost) == flags
    assert DWAConfig.ablation("IDWA", kappa=0.5).kappa == 0.5
    assert set(ABLATIONS) == {"DWA", "DWA+E8", "DWA+E8+E10", "IDWA"}
    with pytest.raises(ValueError, match="name"):
        DWAConfig.ablation("DWA+E11")
    with pytest.raises(ValueError, match="use_rotation_cost"):
        DWAConfig.ablation("DWA", use_rotation_cost=True)
    with pytest.raises(ValueError, match="unknown"):
        DWAConfig.ablation("DWA", speed=1.0)


@pytest.mark.parametrize("field,value", [
    ("T_p", 0.0), ("alpha", -0.1), ("beta", float("nan")), ("gamma", -1.0), ("D_cap", 0.0),
    ("norm", "max"), ("r_goal", 0.0), ("v_res", 0.0), ("w_res", -1.0), ("use_astar_weight", 1),
    ("alpha0", -0.1), ("kappa", 1.0), ("R_sw", 0.0), ("heading_ref", "goal"), ("approach_speed_profile", True),
    ("astar_weight_mode", "global"), ("eps0", -1.0), ("d_in", 2.0), ("d_out", 0.2),
    ("rotation_mode", "squared"), ("rot_weight_mode", "none"), ("R_uu", 0.0), ("dist_cap", 0.0), ("dist_cap", 3.0),
    ("brake_share", -0.1), ("brake_share", 1.5),
])
def test_bad_config_names_the_field(field, value):
    with pytest.raises(ValueError, match=field):
        DWAConfig(**{field: value})


def test_dist_cap_lets_a_parked_uav_move_past_a_far_obstacle():
    """At rest, 1 m from the goal, with an obstacle about 1 m beside the way: the sum-normalised dist
    term (cap D_cap = 2 m) ranks the centimetre clearance differences of the slow samples first and
    standing still wins; with the clearance saturating at dist_cap = 0.5 m the UAV starts moving."""
    state = state_row()
    obstacles = np.array([[1.5, 0.9, 3.0]])
    kw = dict(goal=[1.0, 0.0, 3.0], obstacles=obstacles, obstacle_radius=0.0)
    base = DWAConfig.ablation("IDWA", approach_speed_profile=True, r_goal=0.1)
    assert dwa_plan(state, LIM, base, **kw).v == 0.0
    capped = replace(base, dist_cap=0.5)
    res = dwa_plan(state, LIM, capped, **kw)
    assert res.admissible and res.v > 0.0


def test_config_round_trip():
    cfg = DWAConfig.ablation("IDWA", R_sw=2.5, norm="minmax")
    assert DWAConfig.from_dict(cfg.to_dict()) == cfg


@pytest.mark.parametrize("kwargs,match", [
    (dict(state=np.zeros(6)), "state"),
    (dict(goal=[1.0]), "goal"),
    (dict(obstacles=np.zeros((2, 2))), "obstacles"),
    (dict(obstacle_radius=[0.1, 0.2, 0.3]), "obstacle_radius"),
    (dict(obstacle_radius=-0.1), "obstacle_radius"),
    (dict(obstacles=np.full((2, 3), np.nan)), "obstacles"),
    (dict(movers_pos=np.zeros((1, 3))), "movers"),
    (dict(prev_alignment=1.5), "prev_alignment"),
    (dict(v_ref=2.0), "v_ref"),
    (dict(v_cap=-1.0), "v_cap"),
    (dict(state=state_row(v=1.5)), "v0"),
    (dict(clearance_now=float("nan")), "clearance_now"),
    (dict(mover_dist=1), "mover_dist"),
    (dict(goal_distance=-1.0), "goal_distance"),
    (dict(goal_distance=float("nan")), "goal_distance"),
])
def test_bad_inputs_name_the_argument(kwargs, match):
    args = dict(state=state_row(), limits=LIM, cfg=DWAConfig(), goal=[5.0, 0, 3],
                obstacles=np.zeros((2, 3)) + [3, 3, 3], obstacle_radius=0.2)
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        dwa_plan(**args)


def test_speed_cap_and_speed_reference():
    capped = dwa_plan(state_row(v=0.5), LIM, DWAConfig(), [9.0, 0, 3], NO_OBSTACLES, 0.0, v_cap=0.3)
    assert capped.candidates.v.max() == pytest.approx(0.48) and capped.v == pytest.approx(0.48)
    matched = dwa_plan(state_row(v=0.5), LIM, DWAConfig(), [9.0, 0, 3], NO_OBSTACLES, 0.0, v_ref=0.49)
    assert matched.v == pytest.approx(0.49)


# ----------------------------------------------------------------------------- closed loop, spec (h2) E1

E1_DISCS = np.array([(0, 2), (4, 2), (4, 4), (5, 4), (5, 5), (5, 6), (5, 9), (8, 8), (8, 9), (7, 9)], float)
E1_GOAL = np.array([10.0, 10.0, 1.0])


def grid_astar(r_block, res=0.25):
    """A* (networkx) on an 8-connected raster of E1, cells within 0.5 + r_block of a disc blocked."""
    xs = np.arange(-2.0, 12.0 + 1e-9, res)
    graph = nx.grid_2d_graph(len(xs), len(xs))
    nx.set_edge_attributes(graph, res, "weight")
    for i in range(len(xs) - 1):
        for j in range(len(xs) - 1):
            graph.add_edge((i, j), (i + 1, j + 1), weight=res * math.sqrt(2))
            graph.add_edge((i + 1, j), (i, j + 1), weight=res * math.sqrt(2))
    cx, cy = np.meshgrid(xs, xs, indexing="ij")
    gap = np.min(np.hypot(cx[..., None] - E1_DISCS[:, 0], cy[..., None] - E1_DISCS[:, 1]), axis=-1)
    graph.remove_nodes_from(map(tuple, np.argwhere(gap < 0.5 + r_block)))
    start, goal = (int(2 / res), int(2 / res)), (int(12 / res), int(12 / res))
    cells = nx.astar_path(graph, start, goal, lambda a, b: res * math.dist(a, b), weight="weight")
    return xs[np.array(cells)]


def fly_e1(cfg, lim, path=None):
    """Closed loop with uavform_env.dynamics.step; with a path, DWA heads for its 3 m lookahead (d6)."""
    obstacles = np.column_stack([E1_DISCS, np.ones(len(E1_DISCS))])
    states = np.array([state_row(z=1.0, psi=math.pi / 2)])
    arc = None if path is None else np.r_[0.0, np.cumsum(np.hypot(*np.diff(path, axis=0).T))]
    i_star, prev, track, w_log, rho_log = 0, None, [states[0, :2].copy()], [], []
    for k in range(1, 5001):
        target = E1_GOAL
        if path is not None:  # monotone progress index and lookahead of spec (d4)
            i_star += int(np.argmin(np.hypot(*(path[i_star:i_star + 20] - states[0, :2]).T)))
            j = np.searchsorted(arc, arc[i_star] + 3.0)
            target = path[j] if j < len(path) else E1_GOAL
        clearance_now = np.min(np.hypot(*(E1_DISCS - states[0, :2]).T)) - 0.5 - lim.r_uav
        assert clearance_now > 0, f"collision at step {k}"
        res = dwa_plan(states[0], lim, cfg, target, obstacles, 0.5, lookahead=target,
                       clearance_now=clearance_now, prev_alignment=prev)
        prev = res.alignment
        rho_log.append(math.dist(states[0, :2], E1_GOAL[:2]))
        step(states, np.array([[res.v, res.w, 0.0]]), np.array([True]), lim)
        track.append(states[0, :2].copy())
        w_log.append(states[0, 5])
        if math.dist(states[0, :2], E1_GOAL[:2]) < cfg.r_goal:
            break
    w, near = np.array(w_log), np.array(rho_log) < 3.0
    signs = np.sign(w[near & (np.abs(w) > DEG)])
    length = float(np.sum(np.hypot(*np.diff(np.array(track), axis=0).T)))
    return k, length, int(np.sum(signs[1:] != signs[:-1])), states[0]


def test_closed_loop_e1_standard_dwa_heading_to_goal():
    """Standard DWA, heading to G, body radius 0.3 m (the 0.41 m pocket mouth at (7.5, 8.5) is closed)."""
    cfg = DWAConfig.ablation("DWA")
    k, length, sign_changes, final = fly_e1(cfg, UAVLimits(r_uav=0.3, r_safe=0.0))
    assert math.dist(final[:2], E1_GOAL[:2]) < cfg.r_goal and k < 5000
    assert length < 20.0


@pytest.mark.parametrize("name", ["DWA", "IDWA"])
def test_closed_loop_e1_classic_with_path_lookahead(name):
    """Classic mode (point UAV: r_uav = 1e-6, r_safe = 0); DWA heads for the A* lookahead (d6)."""
    lim = UAVLimits(r_uav=1e-6, r_safe=0.0)
    cfg = DWAConfig.ablation(name)
    k, length, sign_changes, final = fly_e1(cfg, lim, grid_astar(r_block=0.2))
    assert math.dist(final[:2], E1_GOAL[:2]) < cfg.r_goal and k < 5000
    assert length < 20.0


def test_drift_carries_the_rollouts():
    """``drift`` (a wind estimate) moves every rollout by drift * t: an obstacle 1 m behind a UAV at rest is
    harmless in still air, but a 0.5 m/s drift toward it makes every sample that cannot fly away inadmissible;
    drift=None and a zero drift are the same plan bit for bit."""
    cfg = DWAConfig.ablation("DWA")
    s = state_row(v=0.0)
    behind = np.array([[-1.0, 0.0, 3.0]])
    still = dwa_plan(s, LIM, cfg, (5.0, 0.0), behind, 0.1)
    zero = dwa_plan(s, LIM, cfg, (5.0, 0.0), behind, 0.1, drift=(0.0, 0.0))
    assert (still.v, still.w, still.n_admissible) == (zero.v, zero.w, zero.n_admissible)
    assert np.array_equal(still.candidates.clearance, zero.candidates.clearance)
    pushed = dwa_plan(s, LIM, cfg, (5.0, 0.0), behind, 0.1, drift=(-0.5, 0.0))
    assert pushed.n_admissible < still.n_admissible
    cand = pushed.candidates
    rest = np.flatnonzero((cand.v == 0.0) & (cand.w == 0.0))
    assert rest.size == 1 and not cand.admissible[rest[0]]          # hovering drifts 1.5 m into it
    with pytest.raises(ValueError, match="drift"):
        dwa_plan(s, LIM, cfg, (5.0, 0.0), behind, 0.1, drift=(math.nan, 0.0))
