"""OccupancyMap: OctoMap update rules (known answers), queries against brute force, pyramid, views."""

import math
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from uavform_env.config import MapConfig
from uavform_env.occupancy import MapStore, OccupancyMap

RES = 0.2
CFG = MapConfig()
L_HIT = np.float32(math.log(0.7 / 0.3))
L_MISS = np.float32(math.log(0.4 / 0.6))
L_MIN, L_MAX = np.float32(CFG.logodds(CFG.p_min)), np.float32(CFG.logodds(CFG.p_max))


def centre(i, j, k, origin=(0.0, 0.0, 0.0)):
    return np.asarray(origin) + (np.array([i, j, k]) + 0.5) * RES


def random_scans(m, rng, n_scans=4, n_rays=150, reach=2.5):
    """Integrate random scans (hits and max-range rays) from random origins inside the map."""
    lo = m.origin + 0.3
    hi = m.origin + np.array(m.shape) * RES - 0.3
    for _ in range(n_scans):
        o = rng.uniform(lo, hi)
        d = rng.normal(size=(n_rays, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        ends = o + d * rng.uniform(0.2, reach, size=(n_rays, 1))
        m.integrate(o, ends, rng.random(n_rays) < 0.6)


def test_single_ray_known_answer():
    m = OccupancyMap((0, 0, 0), (10, 3, 3), RES)
    m.integrate(centre(0, 1, 1), [centre(5, 1, 1)], [True])
    row = m.logodds[:, 1, 1]
    np.testing.assert_array_equal(row[:5], L_MISS)
    assert row[5] == L_HIT
    assert np.isnan(row[6:]).all()
    assert np.isfinite(m.logodds).sum() == 6
    # a miss-only ray excludes its endpoint voxel
    m2 = OccupancyMap((0, 0, 0), (10, 3, 3), RES)
    m2.integrate(centre(0, 1, 1), [centre(5, 1, 1)], [False])
    assert np.isfinite(m2.logodds).sum() == 5 and np.isnan(m2.logodds[5, 1, 1])


def test_twenty_hits_then_nine_misses_leave_a_voxel_free():
    m = OccupancyMap((0, 0, 0), (6, 3, 3), RES)
    o, target = centre(0, 1, 1), centre(3, 1, 1)
    for _ in range(20):
        m.integrate(o, [target], [True])
    assert m.logodds[3, 1, 1] == L_MAX  # clamped at logit(0.971) = 3.5
    for n in range(9):
        assert m.label([target])[0] == 1, n
        m.integrate(o, [centre(5, 1, 1)], [True])  # passes through the target: a miss
    assert m.label([target])[0] == 0
    want = L_MAX
    for _ in range(9):
        want = np.float32(want + L_MISS)
    assert m.logodds[3, 1, 1] == want
    for _ in range(20):
        m.integrate(o, [centre(5, 1, 1)], [False])
    assert m.logodds[0, 1, 1] == L_MIN  # clamped at logit(0.1192) = -2


def test_one_update_per_voxel_per_scan_and_hit_beats_miss():
    m = OccupancyMap((0, 0, 0), (10, 3, 3), RES)
    o = centre(0, 1, 1)
    ends = [centre(8, 1, 1), centre(8, 1, 1), centre(4, 1, 1), centre(9, 1, 1)]
    m.integrate(o, ends, np.array([True, True, True, False]))
    row = m.logodds[:, 1, 1]
    np.testing.assert_array_equal(row[[0, 1, 2, 3, 5, 6, 7]], L_MISS)  # crossed by up to 4 rays: one miss
    assert row[4] == L_HIT and row[8] == L_HIT  # hit by two rays, crossed by others: one hit
    assert np.isnan(row[9])


def test_log_odds_stay_clamped_and_reach_both_bounds():
    rng = np.random.default_rng(0)
    m = OccupancyMap((-1.0, -1.0, 0.0), (16, 16, 8), RES)
    o = np.array([0.55, 0.45, 0.75])
    ends = o + rng.normal(size=(40, 3))
    hit = rng.random(40) < 0.5
    for _ in range(10):  # the same scan over and over saturates its hits and misses
        m.integrate(o, ends, hit)
        random_scans(m, rng, n_scans=1, n_rays=60)
    v = m.logodds[np.isfinite(m.logodds)]
    assert v.min() == L_MIN and v.max() == L_MAX
    assert np.all((v >= L_MIN) & (v <= L_MAX))


def test_out_of_grid_voxels_are_skipped_consistently():
    rng = np.random.default_rng(1)
    big = OccupancyMap((-2.0, -2.0, -2.0), (40, 40, 40), RES)
    small = OccupancyMap((0.0, 0.4, -0.2), (12, 8, 10), RES)
    for _ in range(6):
        o = rng.uniform([-1.5, -1.5, -1.5], [5.5, 5.5, 5.5])
        d = rng.normal(size=(80, 3))
        ends = o + 3.0 * d / np.linalg.norm(d, axis=1, keepdims=True)
        hit = rng.random(80) < 0.5
        big.integrate(o, ends, hit)
        small.integrate(o, ends, hit)
    off = np.round((small.origin - big.origin) / RES).astype(int)
    window = big.logodds[off[0]:off[0] + 12, off[1]:off[1] + 8, off[2]:off[2] + 10]
    np.testing.assert_array_equal(small.logodds, window)
    assert np.isfinite(small.logodds).any()


def test_point_queries():
    m = OccupancyMap((0, 0, 0), (10, 3, 3), RES)
    m.integrate(centre(0, 1, 1), [centre(5, 1, 1)], [True])
    pts = np.array([centre(2, 1, 1), centre(5, 1, 1), centre(7, 1, 1), [-1.0, 0.3, 0.3], [50.0, 0.3, 0.3]])
    assert m.label(pts).tolist() == [0, 1, -1, -1, -1]
    assert m.label(pts).dtype == np.int8
    assert m.is_known(pts).tolist() == [True, True, False, False, False]
    p = m.probability(pts)
    assert p[0] == pytest.approx(0.4) and p[1] == pytest.approx(0.7) and np.isnan(p[2:]).all()
    assert m.label(pts.reshape(5, 1, 3)).shape == (5, 1)
    assert m.label(centre(5, 1, 1)).shape == ()


def sort_cells(centres, probs):
    order = np.lexsort(centres.T[::-1])
    return centres[order], probs[order]


def brute_sphere(origin, res, grid, center, radius):
    idx = np.argwhere(grid >= 0)
    c = origin + (idx + 0.5) * res
    keep = np.sum((c - center) ** 2, axis=1) <= radius ** 2
    v = grid[tuple(idx[keep].T)].astype(np.float64)
    return c[keep], 1.0 / (1.0 + np.exp(-v))


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), radius=st.floats(0.0, 4.0), level=st.integers(0, 2))
def test_sphere_queries_match_brute_force(seed, radius, level):
    rng = np.random.default_rng(seed)
    m = OccupancyMap((-1.2, 0.6, -0.4), (30, 26, 14), RES)
    random_scans(m, rng)
    center = rng.uniform([-2.0, 0.0, -1.0], [5.0, 6.0, 3.0])
    centres, probs = sort_cells(*m.occupied_in_sphere(center, radius, level=level))
    origin, res, grid = m.level(level)
    want_c, want_p = brute_sphere(origin, res, grid, center, radius)
    np.testing.assert_allclose(centres, want_c, atol=1e-12)
    np.testing.assert_allclose(probs, want_p, rtol=1e-12)
    assert m.occupied_within(center, radius) == (len(brute_sphere(m.origin, RES, m.logodds, center, radius)[0]) > 0)


def test_sphere_query_known_answer_and_block_counts_follow_frees():
    m = OccupancyMap((0, 0, 0), (40, 5, 5), RES)
    o = centre(0, 2, 2)
    m.integrate(o, [centre(20, 2, 2)], [True])  # 4.0 m away
    c, p = m.occupied_in_sphere(o, 4.05)
    np.testing.assert_allclose(c, [centre(20, 2, 2)])
    assert p[0] == pytest.approx(0.7)
    assert m.occupied_within(o, 4.05) and not m.occupied_within(o, 3.95)
    assert m.occupied_in_sphere(o, 3.95)[0].shape == (0, 3)
    for _ in range(3):  # the voxel turns free: its block must drop it
        m.integrate(o, [centre(30, 2, 2)], [True])
    assert not m.occupied_within(o, 4.05)
    assert m.occupied_within(o, 6.05)


def brute_level(m, depth):
    """Max over known children of each aligned 2**depth cube (NaN if none), computed from scratch."""
    f = 2 ** depth
    key0 = np.round(m.origin / RES).astype(int)
    lo = np.floor_divide(key0, f)
    hi = np.floor_divide(key0 + np.array(m.shape) - 1, f)
    out = np.full(tuple(hi - lo + 1), np.nan, np.float32)
    pad = key0 - lo * f
    big = np.full(tuple((hi - lo + 1) * f), np.nan, np.float32)
    big[pad[0]:pad[0] + m.shape[0], pad[1]:pad[1] + m.shape[1], pad[2]:pad[2] + m.shape[2]] = m.logodds
    blocks = big.reshape(out.shape[0], f, out.shape[1], f, out.shape[2], f).transpose(0, 2, 4, 1, 3, 5)
    flat = blocks.reshape(out.shape + (-1,))
    known = ~np.isnan(flat).all(axis=-1)
    out[known] = np.nanmax(flat[known], axis=-1)
    return lo * f * RES, out


def test_pyramid_known_answer():
    m = OccupancyMap((0, 0, 0), (4, 2, 2), RES)
    o = centre(0, 0, 0)
    m.integrate(o, [centre(3, 0, 0)], [False])  # misses in voxels 0..2
    m.integrate(centre(3, 1, 1), [centre(1, 1, 1)], [True])  # hit at (1, 1, 1), misses at (3, 1, 1), (2, 1, 1)
    origin, res, grid = m.level(1)
    assert res == pytest.approx(0.4) and grid.shape == (2, 1, 1)
    np.testing.assert_allclose(origin, 0.0)
    assert grid[0, 0, 0] == L_HIT  # max(miss, miss, hit, unknown ...)
    assert grid[1, 0, 0] == L_MISS
    assert m.n_levels == 3 and m.level(2)[2].shape == (1, 1, 1)
    assert not grid.flags.writeable


@pytest.mark.parametrize("origin", [(0.0, 0.0, 0.0), (-1.4, 0.6, -0.2), (0.2, -3.0, 1.0)])
def test_pyramid_matches_brute_force_and_refreshes_incrementally(origin):
    rng = np.random.default_rng(4)
    m = OccupancyMap(origin, (27, 22, 13), RES)
    random_scans(m, rng)
    for depth in range(min(m.n_levels, 6)):
        lo, want = brute_level(m, depth)
        got_origin, got_res, got = m.level(depth)
        np.testing.assert_allclose(got_origin, lo, atol=1e-12)
        assert got_res == pytest.approx(RES * 2 ** depth)
        np.testing.assert_array_equal(got, want)
    random_scans(m, rng, n_scans=2)  # levels are cached: only the changed region is refreshed
    for depth in (3, 1, 2):
        np.testing.assert_array_equal(m.level(depth)[2], brute_level(m, depth)[1])
        centres, _ = sort_cells(*m.occupied_in_sphere(m.origin + 2.0, 3.0, level=depth))
        want_c, _ = brute_sphere(*m.level(depth), m.origin + 2.0, 3.0)
        np.testing.assert_allclose(centres, want_c)


def test_levels_stop_at_octomap_depth_for_grids_around_zero():
    m = OccupancyMap((-1.0, -1.0, -1.0), (10, 10, 10), RES)
    assert m.n_levels == 16  # every level straddles the origin: 2 cells up to OctoMap's depth-1 nodes
    assert m.level(15)[2].shape == (2, 2, 2)


def test_read_only_view_follows_updates_and_refuses_writes():
    m = OccupancyMap((0, 0, 0), (10, 3, 3), RES)
    view = m.read_only()
    m.integrate(centre(0, 1, 1), [centre(5, 1, 1)], [True])
    assert view.label([centre(5, 1, 1)])[0] == 1
    assert view.occupied_within(centre(0, 1, 1), 2.0)
    assert isinstance(view, OccupancyMap) and view.read_only() is view
    with pytest.raises(TypeError, match="read-only"):
        view.integrate(centre(0, 1, 1), [centre(5, 1, 1)], [True])
    with pytest.raises(TypeError, match="read-only"):
        view.integrate_scan(centre(0, 1, 1), [centre(5, 1, 1)], [1])
    with pytest.raises(ValueError):
        view.logodds[0, 0, 0] = 1.0


def test_maps_of_one_store_equal_standalone_maps():
    rng_a, rng_b = np.random.default_rng(5), np.random.default_rng(5)
    store = MapStore((0, 0, 0), (20, 20, 10), RES, CFG, 2)
    alone = [OccupancyMap((0, 0, 0), (20, 20, 10), RES) for _ in range(2)]
    for _ in range(3):
        for a, b in zip(store.maps, alone):
            random_scans(a, rng_a, n_scans=1)
            random_scans(b, rng_b, n_scans=1)
    for a, b in zip(store.maps, alone):
        np.testing.assert_array_equal(a.logodds, b.logodds)


def test_integrate_scan_treats_only_static_hits_as_hits():
    m = OccupancyMap((0, 0, 0), (10, 3, 3), RES)
    ends = np.array([centre(5, 1, 1), centre(5, 0, 0), centre(5, 2, 2)])
    m.integrate_scan(centre(0, 1, 1), ends, np.array([1, 2, 0], np.int8))
    assert m.label(ends).tolist() == [1, -1, -1]


def test_bad_input_raises_value_error():
    with pytest.raises(ValueError, match="origin"):
        OccupancyMap((0.1, 0, 0), (4, 4, 4), RES)
    with pytest.raises(ValueError, match="shape"):
        OccupancyMap((0, 0, 0), (4, 4), RES)
    with pytest.raises(ValueError, match="cfg"):
        OccupancyMap((0, 0, 0), (4, 4, 4), RES, cfg={"p_hit": 0.7})
    m = OccupancyMap((0, 0, 0), (4, 4, 4), RES)
    with pytest.raises(ValueError, match="endpoints"):
        m.integrate((0.1, 0.1, 0.1), np.zeros((3, 2)), np.ones(3, bool))
    with pytest.raises(ValueError, match="hit"):
        m.integrate((0.1, 0.1, 0.1), np.zeros((3, 3)), np.ones(3))
    with pytest.raises(ValueError, match="sensor_origin"):
        m.integrate((np.nan, 0.1, 0.1), np.zeros((3, 3)), np.ones(3, bool))
    with pytest.raises(ValueError, match="level"):
        m.level(m.n_levels)
    with pytest.raises(ValueError, match="radius"):
        m.occupied_in_sphere((0, 0, 0), -1.0)
    with pytest.raises(ValueError, match="points"):
        m.label(np.zeros((2, 2)))


def test_to_octomap_without_the_extra_raises_a_clear_import_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "octomap", None)
    with pytest.raises(ImportError, match="octomap-python"):
        OccupancyMap((0, 0, 0), (4, 4, 4), RES).to_octomap()
