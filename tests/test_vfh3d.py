"""3D VFH+ stages of spec (f3)-(f7) and the whole cycle, on hand-checked geometry."""

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from baselines.vfh3d import (VFHConfig, VFHState, masked_histogram, open_cells, passage_cost, select_direction,
                             turning_limits, update_binary, vfh3d_step)
from uavform_env.config import UAVLimits

LIM = UAVLimits()
CELL = math.radians(5.0)
DEG = math.radians(1.0)
POS = np.array([0.0, 0.0, 3.0])
AHEAD = np.array([1.0, 0.0, 0.0])
NO_VOXELS = (np.zeros((0, 3)), np.zeros(0))


def cell_offsets_deg(psi):
    """Azimuth offset from psi of every column centre, wrapped to (-180, 180]."""
    return (np.degrees((np.arange(72) + 0.5) * CELL - psi) + 180.0) % 360.0 - 180.0


def step(state=None, cfg=VFHConfig(), psi=0.0, v=0.0, vz=0.0, target=AHEAD, voxels=NO_VOXELS, neighbours=None,
         pos=POS):
    state = VFHState() if state is None else state
    return vfh3d_step(state, cfg, LIM, pos, psi, v, vz, target, voxels[0], voxels[1], 0.2, neighbours)


def saturated(points):
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    return points, np.full(len(points), 0.971)


# ---------------------------------------------------------------------------- config

def test_default_config_resolves_spec_values():
    r_e, a, b, extra = VFHConfig().resolve(LIM, 0.2)
    assert r_e == pytest.approx(0.7) and a == 2.0 and b == pytest.approx(1.0 / 4.3) and extra == LIM.r_uav
    r_e, a, b, _ = VFHConfig(r_e=1.0, weight_relation="paper_literal").resolve(LIM, 0.2)
    assert r_e == 1.0 and b == pytest.approx(1.0 / 625.0)


@pytest.mark.parametrize("kwargs, match", [
    (dict(tau_low=0.95), "tau_high"),
    (dict(k1=-1.0), "k1"),
    (dict(k4=float("nan")), "k4"),
    (dict(alpha_h=math.radians(7.0)), "alpha_h"),
    (dict(alpha_h=0.0), "alpha_h"),
    (dict(win=-1), "win"),
    (dict(win=1.5), "win"),
    (dict(R_w=0.0), "R_w"),
    (dict(r_e=6.0), "r_e"),
    (dict(a=0.0), "a="),
    (dict(b=-0.1), "b="),
    (dict(enlarge_mode="floor"), "enlarge_mode"),
    (dict(weight_relation="quadratic"), "weight_relation"),
    (dict(neighbour_r_extra=-0.3), "neighbour_r_extra"),
])
def test_bad_config_rejected(kwargs, match):
    with pytest.raises(ValueError, match=match):
        VFHConfig(**kwargs)


@pytest.mark.parametrize("cfg, voxel, match", [
    (VFHConfig(a=0.5), 0.2, "b > 0"),
    (VFHConfig(b=1.0), 0.2, "positive weight"),
    (VFHConfig(R_w=0.6), 0.2, "smaller than R_w"),
    (VFHConfig(), 0.0, "voxel_size"),
])
def test_bad_resolved_config_rejected(cfg, voxel, match):
    with pytest.raises(ValueError, match=match):
        cfg.resolve(LIM, voxel)


def test_config_round_trips_through_dict():
    cfg = VFHConfig(k4=0.5, r_e=0.8)
    assert VFHConfig.from_dict(cfg.to_dict()) == cfg


# ---------------------------------------------------------------------------- (f3) turning limits, (f5) mask

def wall(y, x_values, z=POS[2]):
    return np.array([[x, y, z] for x in x_values])


def test_hovering_masks_no_azimuth():
    """Appendix B 7, first part: v = 0 restricts nothing, even with a wall right beside the UAV."""
    assert turning_limits(wall(-0.8, np.arange(-3, 3, 0.1)), POS, 0.0, 0.0, LIM, 0.7) == (-math.pi, math.pi)
    masked = masked_histogram(np.zeros((36, 72)), 0.0, -math.pi, math.pi, LIM.climb_angle_limit(0.0), 3.0, 5.0,
                              LIM, CELL)
    assert not masked[12:27].any()  # every column open in the rows the climb limit allows


def test_wall_on_the_right_gives_minus_18_degrees():
    """Appendix B 7: psi = 0, v = 1 m/s (r_t = 2.86 m), r_e = 0.7 m, a wall along y = -1 m.

    Right circle centre (0, -2.865): the voxel (x, -1) overlaps it while x^2 + 1.865^2 < 3.565^2, i.e.
    x < 3.04, so the most forward blocker is x = 3.0 and delta_R = atan2(-1, 3) = -18.4 deg.
    """
    r_t = 1.0 / LIM.w_max
    assert r_t == pytest.approx(2.865, abs=1e-3)
    voxels = wall(-1.0, np.arange(0.0, 4.85, 0.1))
    # Voxels 1 m above the flight level (|dz| > r_e) do not obstruct level turning, even nearer the heading.
    voxels = np.concatenate([voxels, wall(-0.5, np.arange(0.0, 4.85, 0.1), z=POS[2] + 1.0)])
    delta_r, delta_l = turning_limits(voxels, POS, 0.0, 1.0, LIM, 0.7)
    assert math.degrees(delta_r) == pytest.approx(math.degrees(math.atan2(-1.0, 3.0)), abs=1e-9)
    assert delta_l == math.pi
    masked = masked_histogram(np.zeros((36, 72)), 0.0, delta_r, delta_l, LIM.climb_angle_limit(1.0), 3.0, 5.0,
                              LIM, CELL)
    offsets = cell_offsets_deg(0.0)
    assert masked[:, offsets < -18.0].all()  # every cell with delta < -18 deg
    assert not masked[13:23][:, offsets > -18.0].any()  # |e| <= atan2(0.5, 1) = 26.6 deg: rows 13..22


def test_turning_limits_rotate_with_the_heading():
    """Heading north (psi = 90 deg): a wall along x = +1 is on the right, a wall along x = -1 on the left."""
    right = np.array([[1.0, y, 3.0] for y in np.arange(0.0, 4.85, 0.1)])
    left = right * [-1.0, 1.0, 1.0]
    delta_r, delta_l = turning_limits(np.concatenate([right, left]), POS, math.pi / 2, 1.0, LIM, 0.7)
    assert math.degrees(delta_r) == pytest.approx(-18.43, abs=0.01)
    assert math.degrees(delta_l) == pytest.approx(18.43, abs=0.01)
    masked = masked_histogram(np.zeros((36, 72)), math.pi / 2, delta_r, delta_l, 0.4, 3.0, 5.0, LIM, CELL)
    offsets = cell_offsets_deg(math.pi / 2)
    assert np.array_equal(~masked[18].astype(bool), np.abs(offsets) < 18.43)


def test_climb_and_altitude_band_mask_rows():
    elevation = -87.5 + 5.0 * np.arange(36)
    masked = masked_histogram(np.zeros((36, 72)), 0.0, -math.pi, math.pi, math.radians(30.0), 1.0, 5.0, LIM, CELL)
    # near z_min = 0.5: a downward ray reaches it within 5 m once sin(e) <= -0.1 (e <= -5.7 deg)
    np.testing.assert_array_equal(masked[:, 0] == 0, (elevation >= -2.5) & (elevation <= 27.5))
    masked = masked_histogram(np.zeros((36, 72)), 0.0, -math.pi, math.pi, math.radians(30.0), 9.0, 5.0, LIM, CELL)
    # near z_max = 10: an upward ray reaches it once sin(e) >= 0.2 (e >= 11.5 deg)
    np.testing.assert_array_equal(masked[:, 0] == 0, (elevation >= -27.5) & (elevation <= 7.5))
    binary = np.zeros((36, 72), dtype=np.uint8)
    binary[18, 5] = 1
    masked = masked_histogram(binary, 0.0, -math.pi, math.pi, math.radians(30.0), 5.0, 5.0, LIM, CELL)
    assert masked[18, 5] == 1 and masked[18, 4] == 0
    with pytest.raises(ValueError, match="binary"):
        masked_histogram(np.zeros((12, 24)), 0.0, -math.pi, math.pi, 0.5, 5.0, 5.0, LIM, CELL)


# ---------------------------------------------------------------------------- (f4) hysteresis

def test_binary_hysteresis_known_answers():
    primary = np.array([0.1, 0.5, 0.95, 0.1, 0.5, 0.95, 0.3, 0.9])
    previous = np.array([0, 0, 0, 1, 1, 1, 1, 0], dtype=np.uint8)
    np.testing.assert_array_equal(update_binary(primary, previous, 0.3, 0.9), [0, 0, 1, 0, 1, 1, 1, 0])
    np.testing.assert_array_equal(update_binary(primary, None, 0.3, 0.9), [0, 0, 1, 0, 0, 1, 0, 0])
    with pytest.raises(ValueError, match="tau_low"):
        update_binary(primary, None, 0.9, 0.3)
    with pytest.raises(ValueError, match="previous_binary"):
        update_binary(primary, previous[:3], 0.3, 0.9)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), low=st.floats(0.0, 1.0), width=st.floats(0.0, 1.0))
def test_binary_hysteresis_property(seed, low, width):
    rng = np.random.default_rng(seed)
    primary, previous = rng.uniform(0, 2, (6, 12)), rng.integers(0, 2, (6, 12)).astype(np.uint8)
    high = low + width
    got = update_binary(primary, previous, low, high)
    for p, b0, b in zip(primary.ravel(), previous.ravel(), got.ravel()):
        assert b == (1 if p > high else 0 if p < low else b0)


def test_hysteresis_through_the_cycle():
    """A single-hit voxel (weight 0.49 * 1.7 = 0.83, inside the band) keeps a blocked cell blocked, cannot block one."""
    state = VFHState()
    ahead = POS + [[2.0, 0.0, 0.0]]
    first = step(state, voxels=saturated(ahead))
    assert first.binary[18, 0] == 1
    weak = (ahead, np.array([0.7]))
    assert step(state, voxels=weak).binary[18, 0] == 1
    state.reset()
    assert state.binary is None and state.previous_dir is None
    assert step(state, voxels=weak).binary[18, 0] == 0


# ---------------------------------------------------------------------------- (f6) windows and selection

def naive_open(masked, win):
    n_e, n_z = masked.shape
    out = np.zeros_like(masked, dtype=bool)
    for e, z in itertools.product(range(n_e), range(n_z)):
        out[e, z] = all(masked[r, (z + c) % n_z] == 0 for r in range(e - win, e + win + 1) if 0 <= r < n_e
                        for c in range(-win, win + 1))
    return out


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), win=st.integers(0, 4), density=st.floats(0.0, 0.2),
       shape=st.sampled_from([(12, 24), (3, 6)]))
def test_open_windows_match_naive(seed, win, density, shape):
    masked = (np.random.default_rng(seed).random(shape) < density).astype(np.uint8)
    np.testing.assert_array_equal(open_cells(masked, win), naive_open(masked, win))


def test_open_window_wraps_and_poles_count_free():
    masked = np.ones((36, 72), dtype=np.uint8)
    masked[10:15, np.r_[70, 71, 0, 1, 2]] = 0  # a 5 x 5 hole across the azimuth seam
    masked[33:36, 30:35] = 0  # 3 rows at the top: the two rows beyond the pole count as free
    assert sorted(zip(*np.nonzero(open_cells(masked, 2)))) == [(12, 0), (35, 32)]


def test_no_candidates_means_blocked():
    masked = np.ones((36, 72), dtype=np.uint8)
    masked[18, :] = 0  # a free ring one cell wide is no 5 x 5 window
    assert select_direction(masked, AHEAD, AHEAD, None, VFHConfig()) == (None, math.inf)


def test_free_space_selects_the_target_cell():
    """Target cell (19, 18) (elevation 7.6 deg, azimuth 90 deg); the current cell (18, 18) is one cell (5 deg) below."""
    cell, cost = select_direction(np.zeros((36, 72)), [0.0, 3.0, 0.4], [0.0, 1.0, 0.0], None, VFHConfig())
    assert cell == (19, 18) and cost == pytest.approx(VFHConfig().k2 * 1.0)


def test_angular_distance_is_the_true_angle_near_the_pole():
    """Target cell (34, 0), centre (82.5, 2.5) deg. Open cells: (34, 36) and (35, 36) across the pole, 15 and
    10 deg away although 36 columns apart, and (22, 0) straight below, 60 deg (12 rows) away."""
    masked = np.ones((36, 72), dtype=np.uint8)
    masked[32:36, 34:39] = 0  # rows beyond the pole count as free
    masked[20:25, 70:] = masked[20:25, :3] = 0
    assert sorted(zip(*np.nonzero(open_cells(masked, 2)))) == [(22, 0), (34, 36), (35, 36)]
    target = [math.cos(math.radians(82.5)), 0.0, math.sin(math.radians(82.5))]
    cell, cost = select_direction(masked, target, AHEAD, None, VFHConfig(k2=0.0, k3=0.0))
    assert cell == (35, 36) and cost == pytest.approx(5.0 * 10.0 / 5.0)


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), density=st.floats(0.0, 0.1), k=st.lists(st.floats(0.0, 6.0), min_size=4,
                                                                               max_size=4))
def test_selection_matches_naive_cost(seed, density, k):
    """The cheapest open cell under k1 D(c, c_t) + k2 D(c, c_cur) + k3 D(c, c_prev) + k4 P/(1 + max P)."""
    rng = np.random.default_rng(seed)
    masked = (rng.random((36, 72)) < density).astype(np.uint8)
    primary = rng.uniform(0.0, 2.0, (36, 72))
    dirs = rng.normal(size=(3, 3))
    cfg = VFHConfig(k1=k[0], k2=k[1], k3=k[2], k4=k[3])
    cell, cost = select_direction(masked, dirs[0], dirs[1], dirs[2], cfg, primary)
    units = np.stack(np.meshgrid(np.radians(-87.5 + 5.0 * np.arange(36)), np.radians(2.5 + 5.0 * np.arange(72)),
                                 indexing="ij"), axis=-1)
    units = np.stack([np.cos(units[..., 0]) * np.cos(units[..., 1]), np.cos(units[..., 0]) * np.sin(units[..., 1]),
                      np.sin(units[..., 0])], axis=-1)

    def cell_of(d):
        el = math.degrees(math.atan2(d[2], math.hypot(d[0], d[1])))
        return min(int((el + 90.0) // 5.0), 35), int((math.degrees(math.atan2(d[1], d[0])) % 360.0) // 5.0)

    naive = np.zeros((36, 72))
    for weight, d in zip(k[:3], dirs):
        naive += weight * np.degrees(np.arccos(np.clip(units @ units[cell_of(d)], -1.0, 1.0))) / 5.0
    passage = passage_cost(primary, cell_of(dirs[1]))
    naive += k[3] * passage / (1.0 + passage.max())
    naive[~open_cells(masked, 2)] = np.inf  # the window test is checked against naive_open above
    if np.isinf(naive.min()):
        assert cell is None
    else:
        tol = 1e-6 * (1.0 + sum(k))  # acos near 1 resolves angles to ~1e-8 rad (2e-7 cells) only
        assert cost == pytest.approx(naive.min(), abs=tol) and naive[cell] == pytest.approx(naive.min(), abs=tol)


def test_reference_directions_are_validated():
    with pytest.raises(ValueError, match="target_dir"):
        select_direction(np.zeros((36, 72)), [0.0, 0.0, 0.0], AHEAD, None, VFHConfig())
    with pytest.raises(ValueError, match="current_dir"):
        select_direction(np.zeros((36, 72)), AHEAD, [1.0, float("nan"), 0.0], None, VFHConfig())
    with pytest.raises(ValueError, match="masked"):
        select_direction(np.zeros((12, 24)), AHEAD, AHEAD, None, VFHConfig())
    with pytest.raises(ValueError, match="primary"):
        select_direction(np.zeros((36, 72)), AHEAD, AHEAD, None, VFHConfig(k4=1.0))


# ---------------------------------------------------------------------------- (f7) DP passage cost

def brute_force_passage(weights, start):
    """Minimum sum over every monotone staircase path (both end cells included) in each quadrant."""
    n_e, n_z = weights.shape
    e0, z0 = start
    best = np.full(weights.shape, np.inf)
    for se, sz in itertools.product((-1, 1), (-1, 1)):
        for di, dj in itertools.product(range(n_e), range(n_z // 2 + 1)):
            if not 0 <= e0 + se * di < n_e:
                continue
            for rows_first in itertools.combinations(range(di + dj), di):
                e, z, total = e0, z0, weights[e0, z0]
                for k in range(di + dj):
                    if k in rows_first:
                        e += se
                    else:
                        z = (z + sz) % n_z
                    total += weights[e, z]
                best[e, z] = min(best[e, z], total)
    return best


@settings(max_examples=12, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n_e=st.integers(1, 4), extra_z=st.integers(0, 1))
def test_passage_cost_matches_brute_force(seed, n_e, extra_z):
    rng = np.random.default_rng(seed)
    weights = rng.uniform(0.0, 3.0, (n_e, 2 * n_e + extra_z))
    start = (int(rng.integers(n_e)), int(rng.integers(weights.shape[1])))
    np.testing.assert_allclose(passage_cost(weights, start), brute_force_passage(weights, start), rtol=1e-12)


def test_passage_cost_uniform_is_cell_distance_plus_one():
    got = passage_cost(np.ones((36, 72)), (18, 70))
    rows, cols = np.indices((36, 72))
    gap = np.abs(cols - 70)
    np.testing.assert_array_equal(got, np.abs(rows - 18) + np.minimum(gap, 72 - gap) + 1)
    with pytest.raises(ValueError, match="current_cell"):
        passage_cost(np.ones((36, 72)), (36, 0))


# ---------------------------------------------------------------------------- whole cycle

def test_free_space_cycle():
    state = VFHState()
    r = step(state)
    assert not r.blocked and not r.emergency
    assert (r.azimuth, r.elevation) == pytest.approx((2.5 * DEG, 2.5 * DEG))
    np.testing.assert_allclose(r.direction, [math.cos(2.5 * DEG) ** 2, math.cos(2.5 * DEG) * math.sin(2.5 * DEG),
                                             math.sin(2.5 * DEG)])
    # rows 12..26 are open (e_max = 45 deg; rays at or below -32.5 deg reach z_min), windows need +/-2 rows
    assert r.n_candidates == 11 * 72
    np.testing.assert_array_equal(state.previous_dir, r.direction)


def test_wall_ahead_with_a_gap_above_climbs():
    voxels = saturated([[4.1, y, z] for y in np.arange(-4.9, 5.0, 0.2) for z in np.arange(0.1, 3.4, 0.2)])
    r = step(v=0.3, voxels=voxels)
    assert not r.blocked
    assert r.elevation > CELL / 2 and abs(r.azimuth) < 2 * CELL


def test_wall_too_high_to_climb_at_speed_turns_instead():
    """At 1 m/s the climb limit is atan2(0.5, 1) = 26.6 deg, too shallow for the gap above."""
    voxels = saturated([[4.1, y, z] for y in np.arange(-4.9, 5.0, 0.2) for z in np.arange(0.1, 3.4, 0.2)])
    r = step(v=1.0, voxels=voxels)
    assert not r.blocked and abs(r.azimuth) > math.radians(30.0)


@pytest.mark.parametrize("side", [1.0, -1.0])
def test_obstacle_on_one_side_turns_to_the_other(side):
    column = saturated([[2.5, side * y, z] for y in (0.1, 0.3, 0.5) for z in np.arange(0.1, 8.0, 0.2)])
    r = step(v=0.5, voxels=column)
    assert not r.blocked and r.binary[18, 0] == 1
    assert side * r.azimuth < 0.0 and abs(r.elevation) < 3 * CELL


def test_cycle_returns_its_candidate_windows():
    voxels = saturated([[4.1, y, z] for y in np.arange(-4.9, 5.0, 0.2) for z in np.arange(0.1, 3.4, 0.2)])
    for v in (0.3, 1.0):
        r = step(v=v, voxels=voxels)
        np.testing.assert_array_equal(r.window_open, open_cells(r.masked, VFHConfig().win))
        assert r.window_open.sum() == r.n_candidates


def test_enclosed_uav_is_blocked():
    k = np.arange(400) + 0.5
    polar, azimuth = np.arccos(1 - 2 * k / 400), math.pi * (1 + 5**0.5) * k
    shell = POS + 2.0 * np.column_stack([np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth),
                                         np.cos(polar)])
    state = VFHState(previous_dir=np.array([0.0, 1.0, 0.0]))
    r = step(state, voxels=saturated(shell))
    assert r.blocked and r.n_candidates == 0 and r.masked.all()
    assert math.isnan(r.azimuth) and math.isnan(r.elevation) and np.isnan(r.direction).all()
    np.testing.assert_array_equal(state.previous_dir, [0.0, 1.0, 0.0])


def test_emergency_and_neighbours():
    near = POS + [[0.9, 0.0, 0.0]]
    assert not step(voxels=saturated(near)).emergency  # 0.9 m > r_e = 0.7 m
    assert step(voxels=saturated(POS + [[0.6, 0.0, 0.0]])).emergency
    r = step(neighbours=near)  # a neighbour is enlarged by r_uav more: 0.9 m <= 1.0 m
    assert r.emergency and r.primary.max() == pytest.approx(2.0)
    r = step(neighbours=POS + [[2.0, 0.0, 0.0]])
    assert not r.blocked and r.binary[18, 0] == 1 and abs(r.azimuth) > 5 * CELL


def test_passage_cost_term_runs_in_the_cycle():
    column = saturated([[2.5, 0.3, z] for z in np.arange(0.1, 8.0, 0.2)])
    r = step(cfg=VFHConfig(k4=3.0), v=0.5, voxels=column)
    assert not r.blocked and r.binary[18, 0] == 1


def test_cycle_rejects_bad_input():
    with pytest.raises(ValueError, match="voxel_probs"):
        step(voxels=(np.zeros((3, 3)), np.zeros(2)))
    with pytest.raises(ValueError, match="v="):
        step(v=-0.1)
    with pytest.raises(ValueError, match="target_dir"):
        step(target=np.zeros(3))


# ---------------------------------------------------------------------------- per-planner setup
def test_planner_keeps_its_setup_per_instance_across_gain_changes():
    import baselines.vfh3d as vfh3d
    from baselines.vfh3d import VFHPlanner

    assert not hasattr(vfh3d, "_last_setup")                 # no module-global cache
    cfg = VFHConfig()
    planner, other = VFHPlanner(), VFHPlanner()
    first = planner.setup(cfg, LIM, 0.2)
    assert planner.setup(cfg, LIM, 0.2) is first
    for k1 in (1.0, 7.5, 0.0):                               # residual weights: a new config every call
        assert planner.setup(VFHConfig(k1=k1, k2=k1 / 2, k3=3.0), LIM, 0.2) is first
    wider = planner.setup(VFHConfig(R_w=4.0), LIM, 0.2)      # a setup field changes: a new setup
    assert wider is not first and wider[2].R_w == 4.0 and first[2].R_w == 5.0
    assert planner.setup(VFHConfig(), LIM, 0.4)[2].r_e == pytest.approx(0.3 + 0.2 + 0.4)
    assert other.setup(cfg, LIM, 0.2) is not first           # another planner holds its own


def test_planner_matches_the_one_off_step_with_varying_gains():
    from baselines.vfh3d import VFHPlanner

    planner = VFHPlanner()
    voxels = saturated([[2.0, 0.4, z] for z in np.arange(2.0, 4.01, 0.2)])      # a pole just left of the way
    target = np.array([1.0, 1.7, 0.0])                                       # 60 degrees left of the heading
    kept, fresh = VFHState(), VFHState()
    directions = set()
    for k1, k2 in ((5.0, 2.0), (0.5, 9.0), (9.0, 0.1), (5.0, 2.0)):
        cfg = VFHConfig(k1=k1, k2=k2)
        got = planner(kept, cfg, LIM, POS, 0.0, 0.0, 0.0, target, voxels[0], voxels[1], 0.2)
        want = step(fresh, cfg, target=target, voxels=voxels)
        assert not got.blocked and np.array_equal(got.direction, want.direction)
        directions.add(tuple(got.direction))
        assert np.array_equal(got.masked, want.masked) and np.array_equal(got.primary, want.primary)
    assert len(directions) > 1                                   # the gains do steer
