"""Tests of spec (d): A* against scipy/networkx shortest paths, hand-checked grids, the classic
DWA map, inflation, snapping, pruning and the global-path interface used by DWA."""

from __future__ import annotations

import math

import networkx as nx
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import ndimage
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from baselines.astar import (AStarConfig, GlobalPath, Raster, _segment_free, astar, inflate, needs_replan,
                             plan_path, prune_line_of_sight, replan_trigger, resample, snap_to_free)
from uavform_env.config import UAVLimits

MOVES = [(1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (1, -1), (-1, 1), (-1, -1)]


# ---------------------------------------------------------------------------------------------
# independent references
# ---------------------------------------------------------------------------------------------

def scipy_cost(blocked, start, goal, corner_cut):
    """Shortest 8-connected cost by scipy's Dijkstra on a vectorised sparse graph (inf if none)."""
    nx_, ny_ = blocked.shape
    free = ~blocked
    idx = np.arange(nx_ * ny_).reshape(nx_, ny_)
    rows, cols, weights = [], [], []
    for di, dj in MOVES:
        src = (slice(max(0, -di), nx_ - max(0, di)), slice(max(0, -dj), ny_ - max(0, dj)))
        dst = (slice(max(0, di), nx_ + min(0, di)), slice(max(0, dj), ny_ + min(0, dj)))
        ok = free[src] & free[dst]
        if di and dj and not corner_cut:
            side_i = (dst[0], src[1])  # cell (i + di, j)
            side_j = (src[0], dst[1])  # cell (i, j + dj)
            ok &= free[side_i] & free[side_j]
        rows.append(idx[src][ok])
        cols.append(idx[dst][ok])
        weights.append(np.full(ok.sum(), math.sqrt(2.0) if di and dj else 1.0))
    graph = csr_matrix((np.concatenate(weights), (np.concatenate(rows), np.concatenate(cols))),
                       shape=(nx_ * ny_, nx_ * ny_))
    return dijkstra(graph, indices=idx[start])[idx[goal]]


def networkx_cost(blocked, start, goal, corner_cut):
    """Same graph built cell by cell with explicit rules (small grids only)."""
    g = nx.Graph()
    nx_, ny_ = blocked.shape
    for i in range(nx_):
        for j in range(ny_):
            if blocked[i, j]:
                continue
            g.add_node((i, j))
            for di, dj in MOVES:
                a, b = i + di, j + dj
                if not (0 <= a < nx_ and 0 <= b < ny_) or blocked[a, b]:
                    continue
                if di and dj and not corner_cut and (blocked[a, j] or blocked[i, b]):
                    continue
                g.add_edge((i, j), (a, b), weight=math.hypot(di, dj))
    if start not in g or goal not in g:
        return math.inf
    try:
        return nx.dijkstra_path_length(g, start, goal)
    except nx.NetworkXNoPath:
        return math.inf


def assert_valid_path(path, blocked, start, goal, cost, corner_cut):
    """Connected 8-neighbour steps over free cells, endpoints right, cost = sum of step costs."""
    assert tuple(path[0]) == tuple(start) and tuple(path[-1]) == tuple(goal)
    assert not blocked[path[:, 0], path[:, 1]].any()
    steps = np.diff(path, axis=0)
    assert np.all(np.abs(steps).max(axis=1) == 1)
    assert cost == pytest.approx(np.hypot(steps[:, 0], steps[:, 1]).sum(), abs=1e-9)
    if not corner_cut:
        diag = (steps[:, 0] != 0) & (steps[:, 1] != 0)
        p = path[:-1][diag]
        s = steps[diag]
        assert not blocked[p[:, 0] + s[:, 0], p[:, 1]].any()
        assert not blocked[p[:, 0], p[:, 1] + s[:, 1]].any()


def random_case(rng, max_side=100):
    nx_, ny_ = rng.integers(2, max_side + 1, size=2)
    blocked = rng.random((nx_, ny_)) < rng.uniform(0.0, 0.6)
    free = np.argwhere(~blocked)
    if len(free) == 0:
        blocked[0, 0] = False
        free = np.array([[0, 0]])
    start, goal = (tuple(int(v) for v in free[k]) for k in rng.integers(0, len(free), size=2))
    return blocked, start, goal


# ---------------------------------------------------------------------------------------------
# search
# ---------------------------------------------------------------------------------------------

@pytest.mark.parametrize("corner_cut", [False, True])
def test_astar_matches_scipy_dijkstra_on_random_grids(corner_cut):
    rng = np.random.default_rng(7 if corner_cut else 3)
    n_found = n_none = 0
    for _ in range(60):
        blocked, start, goal = random_case(rng)
        expected = scipy_cost(blocked, start, goal, corner_cut)
        res = astar(blocked, start, goal, allow_corner_cut=corner_cut)
        assert res.found == np.isfinite(expected)
        if res.found:
            n_found += 1
            assert res.cost == pytest.approx(expected, abs=1e-9)
            assert_valid_path(res.path, blocked, start, goal, res.cost, corner_cut)
        else:
            n_none += 1
            assert res.path.shape == (0, 2) and res.cost == math.inf
    assert n_found > 20 and n_none > 3  # both outcomes are exercised


def test_astar_matches_networkx_built_cell_by_cell():
    rng = np.random.default_rng(11)
    for _ in range(8):
        blocked, start, goal = random_case(rng, max_side=14)
        for corner_cut in (False, True):
            expected = networkx_cost(blocked, start, goal, corner_cut)
            res = astar(blocked, start, goal, allow_corner_cut=corner_cut)
            assert res.found == math.isfinite(expected)
            if res.found:
                assert res.cost == pytest.approx(expected, abs=1e-9)


def test_heuristics_and_weights_agree_on_cost():
    rng = np.random.default_rng(5)
    for _ in range(15):
        blocked, start, goal = random_case(rng, max_side=60)
        octile = astar(blocked, start, goal)
        euclid = astar(blocked, start, goal, heuristic="euclidean")
        uninformed = astar(blocked, start, goal, weight=0.0)  # Dijkstra: expands every node with g < C*
        for other in (euclid, uninformed):
            assert other.found == octile.found
            if octile.found:
                assert other.cost == pytest.approx(octile.cost, abs=1e-9)
        assert uninformed.expanded >= octile.expanded
        greedy = astar(blocked, start, goal, weight=2.0)
        if octile.found:
            assert octile.cost - 1e-9 <= greedy.cost <= 2.0 * octile.cost + 1e-9


def test_hand_checked_grid_with_a_centre_block():
    blocked = np.zeros((3, 3), dtype=bool)
    blocked[1, 1] = True
    strict = astar(blocked, (0, 0), (2, 2))
    assert strict.cost == pytest.approx(4.0)  # around the block: two axial legs of 2
    assert_valid_path(strict.path, blocked, (0, 0), (2, 2), strict.cost, corner_cut=False)
    cut = astar(blocked, (0, 0), (2, 2), allow_corner_cut=True)
    assert cut.cost == pytest.approx(2.0 + math.sqrt(2.0))  # one diagonal squeezes past the block
    assert len(cut.path) == 4


def test_open_grid_octile_cost_and_straight_expansion():
    res = astar(np.zeros((50, 50), dtype=bool), (0, 0), (49, 30))
    assert res.cost == pytest.approx(19 + 30 * math.sqrt(2.0))
    assert res.expanded == len(res.path) == 50  # (f, h) ties go to the node nearer the goal


def test_wall_with_a_gap_forces_the_detour():
    blocked = np.zeros((7, 7), dtype=bool)
    blocked[3, :6] = True  # wall along i = 3, gap at j = 6
    res = astar(blocked, (0, 0), (6, 0))
    assert [3, 6] in res.path.tolist()
    # (0,0)->(2,6): 4 + 2 sqrt2; through the gap (2,6)->(3,6)->(4,6) axially, since the wall
    # end (3,5) forbids the diagonals; (4,6)->(6,0): 4 + 2 sqrt2 again
    assert res.cost == pytest.approx(10 + 4 * math.sqrt(2.0))


def test_blocked_endpoints_and_trivial_paths():
    blocked = np.zeros((4, 4), dtype=bool)
    blocked[2, 2] = True
    assert not astar(blocked, (2, 2), (0, 0)).found
    assert not astar(blocked, (0, 0), (2, 2)).found
    same = astar(blocked, (1, 1), (1, 1))
    assert same.found and same.cost == 0.0 and same.path.tolist() == [[1, 1]]


def test_astar_rejects_bad_input():
    grid = np.zeros((4, 4), dtype=bool)
    with pytest.raises(ValueError, match="blocked"):
        astar(np.zeros((4, 4)), (0, 0), (1, 1))
    with pytest.raises(ValueError, match="start"):
        astar(grid, (4, 0), (1, 1))
    with pytest.raises(ValueError, match="goal"):
        astar(grid, (0, 0), (0.5, 1))
    with pytest.raises(ValueError, match="heuristic"):
        astar(grid, (0, 0), (1, 1), heuristic="manhattan")
    with pytest.raises(ValueError, match="weight"):
        astar(grid, (0, 0), (1, 1), weight=-1.0)


# ---------------------------------------------------------------------------------------------
# inflation and snapping
# ---------------------------------------------------------------------------------------------

def test_inflation_of_one_cell_is_the_hand_computed_disc():
    blocked = np.zeros((9, 9), dtype=bool)
    blocked[4, 4] = True
    grown = inflate(blocked, radius=0.5, res=0.25)  # 2 cells: offsets with di^2 + dj^2 <= 4
    di, dj = np.nonzero(grown)
    assert grown.sum() == 13
    assert set(zip(di - 4, dj - 4)) == {(a, b) for a in range(-2, 3) for b in range(-2, 3) if a * a + b * b <= 4}
    assert np.array_equal(inflate(blocked, 0.0, 0.25), blocked)
    assert not inflate(np.zeros((3, 3), dtype=bool), 1.0, 0.25).any()


def test_inflation_matches_brute_force_distances():
    rng = np.random.default_rng(2)
    blocked = rng.random((25, 30)) < 0.05
    res, radius = 0.4, 1.1
    centres = np.stack(np.meshgrid(np.arange(25), np.arange(30), indexing="ij"), -1).reshape(-1, 2) * res
    occ = np.argwhere(blocked) * res
    d = np.sqrt(((centres[:, None, :] - occ[None, :, :]) ** 2).sum(-1)).min(axis=1)
    assert np.array_equal(inflate(blocked, radius, res).ravel(), d <= radius)


@pytest.mark.parametrize("seed", range(20))
def test_inflation_matches_scipy_distance_transform(seed):
    """The independent reference: scipy's exact Euclidean distance transform, thresholded the same way."""
    rng = np.random.default_rng(seed)
    blocked = rng.random(tuple(rng.integers(1, 40, size=2))) < rng.uniform(0.0, 0.3)
    res = rng.uniform(0.1, 1.0)
    radius = int(rng.integers(0, 4)) * res if seed % 2 else rng.uniform(0.0, 2.0)   # odd seeds: on a cell centre
    expected = ndimage.distance_transform_edt(~blocked, sampling=res) <= radius * (1.0 + 1e-12)
    assert np.array_equal(inflate(blocked, radius, res), expected if blocked.any() else blocked)


def test_snap_to_free_known_answers():
    blocked = np.ones((5, 5), dtype=bool)
    blocked[0, 4] = False
    blocked[4, 1] = False
    assert snap_to_free(blocked, (2, 2)) == (4, 1)  # sqrt(5) beats sqrt(8)
    assert snap_to_free(blocked, (0, 4)) == (0, 4)
    assert snap_to_free(np.ones((3, 3), dtype=bool), (1, 1)) is None
    with pytest.raises(ValueError, match="cell"):
        snap_to_free(blocked, (5, 0))


def test_snap_to_free_matches_the_distance_transform():
    rng = np.random.default_rng(4)
    for _ in range(10):
        blocked = rng.random((30, 20)) < 0.7
        cells = np.argwhere(blocked)[:20]
        dist = ndimage.distance_transform_edt(blocked)
        for cell in cells:
            snapped = snap_to_free(blocked, tuple(cell))
            assert not blocked[snapped]
            assert math.dist(snapped, cell) == pytest.approx(dist[tuple(cell)])


# ---------------------------------------------------------------------------------------------
# segment walk and pruning
# ---------------------------------------------------------------------------------------------

def cells_touched(p0, p1, shape, closed):
    """Cells whose square the segment between centres meets (Liang-Barsky clip against every cell).

    closed=False: the open interior must be crossed; closed=True: touching a corner counts too.
    """
    ii, jj = np.meshgrid(np.arange(shape[0]), np.arange(shape[1]), indexing="ij")
    a = np.asarray(p0, float) + 0.5
    d = np.asarray(p1, float) - np.asarray(p0, float)
    t_in = np.full(shape, -np.inf)
    t_out = np.full(shape, np.inf)
    for axis, lo in ((0, ii), (1, jj)):
        if d[axis] == 0:
            inside = (lo < a[axis]) & (a[axis] < lo + 1)
            t_in = np.where(inside, t_in, np.inf)
            continue
        t1 = (lo - a[axis]) / d[axis]
        t2 = (lo + 1 - a[axis]) / d[axis]
        t_in = np.maximum(t_in, np.minimum(t1, t2))
        t_out = np.minimum(t_out, np.maximum(t1, t2))
    lo_t, hi_t = np.maximum(t_in, 0.0), np.minimum(t_out, 1.0)
    return lo_t <= hi_t if closed else lo_t < hi_t


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.booleans())
def test_segment_walk_matches_an_exact_clip(seed, corner_cut):
    rng = np.random.default_rng(seed)
    shape = (12, 12)
    p0, p1 = rng.integers(0, 12, size=(2, 2))
    if rng.random() < 0.3:  # force exact diagonals, which pass through cell corners
        k = int(rng.integers(0, 12 - max(p0)))
        p1 = p0 + k * np.array([1, 1])
    touched = cells_touched(p0, p1, shape, closed=not corner_cut)
    for _ in range(5):
        blocked = rng.random(shape) < 0.06
        expected = not (blocked & touched).any()
        assert _segment_free(blocked, p0[0], p0[1], p1[0], p1[1], corner_cut) == expected


def test_pruning_keeps_endpoints_and_only_visible_shortcuts():
    rng = np.random.default_rng(8)
    for _ in range(20):
        blocked, start, goal = random_case(rng, max_side=40)
        res = astar(blocked, start, goal)
        if not res.found:
            continue
        pruned = prune_line_of_sight(res.path, blocked)
        assert pruned[0].tolist() == res.path[0].tolist() and pruned[-1].tolist() == res.path[-1].tolist()
        kept = {tuple(c) for c in res.path}
        assert all(tuple(c) in kept for c in pruned)
        for a, b in zip(pruned[:-1], pruned[1:]):
            assert _segment_free(blocked, a[0], a[1], b[0], b[1], False)
        assert np.hypot(*np.diff(pruned, axis=0).T).sum() <= res.cost + 1e-9


def test_pruning_open_grid_and_l_corridor():
    open_path = astar(np.zeros((20, 20), dtype=bool), (0, 0), (19, 7)).path
    assert prune_line_of_sight(open_path, np.zeros((20, 20), dtype=bool)).tolist() == [[0, 0], [19, 7]]
    blocked = np.ones((6, 6), dtype=bool)
    blocked[0, :] = False
    blocked[:, 5] = False  # L corridor: along j, then along i
    path = astar(blocked, (0, 0), (5, 5)).path
    assert prune_line_of_sight(path, blocked).tolist() == [[0, 0], [0, 5], [5, 5]]


# ---------------------------------------------------------------------------------------------
# raster, config, plan_path
# ---------------------------------------------------------------------------------------------

def test_raster_cells_and_centres():
    r = Raster(origin=(-1.0, 2.0), res=0.5, shape=(10, 4))
    assert r.to_cell((-1.0, 2.0)) == (0, 0)
    assert r.to_cell((3.99, 3.99)) == (9, 3)
    assert r.to_cell(np.array([[0.1, 2.6], [-0.6, 3.4]])).tolist() == [[2, 1], [0, 2]]
    assert r.to_world(np.array([[0, 0], [9, 3]])).tolist() == [[-0.75, 2.25], [3.75, 3.75]]
    for bad in ((4.0, 2.5), (-1.01, 2.5), (0.0, float("nan"))):
        with pytest.raises(ValueError, match="xy"):
            r.to_cell(bad)
    with pytest.raises(ValueError, match="res"):
        Raster((0, 0), 0.0, (3, 3))
    with pytest.raises(ValueError, match="shape"):
        Raster((0, 0), 1.0, (3, 0))


@settings(max_examples=50, deadline=None)
@given(st.integers(0, 39), st.integers(0, 29), st.floats(-50, 50), st.floats(-50, 50), st.floats(0.05, 2.0))
def test_raster_round_trip(i, j, ox, oy, res):
    r = Raster((ox, oy), res, (40, 30))
    assert r.to_cell(r.to_world(np.array([[i, j]]))[0]) == (i, j)


def test_config_validation():
    assert AStarConfig().heuristic == "octile" and not AStarConfig().allow_corner_cut
    for field, value in (("heuristic", "manhattan"), ("weight", -0.5), ("window", 0), ("lookahead", -1.0),
                         ("d_replan", 0.0), ("heading_target", "slot"), ("prune", 1), ("res_g", 0.0)):
        with pytest.raises(ValueError, match=f"AStarConfig.{field}"):
            AStarConfig(**{field: value})
    assert AStarConfig.from_dict(AStarConfig(prune=True).to_dict()) == AStarConfig(prune=True)


CLASSIC = [(0, 2), (4, 2), (4, 4), (5, 4), (5, 5), (5, 6), (5, 9), (8, 8), (8, 9), (7, 9)]
EXTENDED = CLASSIC + [(6, 5), (6, 3), (6, 8), (6, 7), (7, 4), (9, 8), (9, 11), (9, 6)]


def disc_raster(raster, centres, radius):
    """Occupied = the disc meets the cell square."""
    lo = np.asarray(raster.origin) + np.stack(np.meshgrid(np.arange(raster.shape[0]), np.arange(raster.shape[1]),
                                                          indexing="ij"), -1) * raster.res
    occ = np.zeros(raster.shape, dtype=bool)
    for c in np.asarray(centres, float):
        nearest = np.clip(c, lo, lo + raster.res)
        occ |= np.hypot(*(nearest - c).transpose(2, 0, 1)) <= radius
    return occ


@pytest.mark.parametrize("obstacles", [CLASSIC, EXTENDED], ids=["classic", "extended"])
def test_classic_dwa_map_has_a_safe_path(obstacles):
    limits = UAVLimits()
    cfg = AStarConfig(res_g=0.25)
    raster = Raster(origin=(-2.0, -2.0), res=cfg.res_g, shape=(60, 60))
    world = disc_raster(raster, obstacles, 0.5)
    path = plan_path(world, raster, (0.0, 0.0), (10.0, 10.0), limits.r_uav + limits.r_safe, cfg)
    assert path is not None
    assert np.allclose(path.points[0], (0.125, 0.125)) and np.allclose(path.points[-1], (10.125, 10.125))
    inflated = inflate(world, limits.r_uav + limits.r_safe, raster.res)
    cells = raster.to_cell(path.points)
    assert_valid_path(cells, inflated, cells[0], cells[-1], path.length / raster.res, corner_cut=False)
    assert not path.corridor_blocked(inflated, raster)
    t = np.linspace(0, 1, 20)[:, None]
    dense = (path.points[:-1, None, :] * (1 - t) + path.points[1:, None, :] * t).reshape(-1, 2)
    clearance = np.hypot(*(dense[:, None, :] - np.asarray(obstacles, float)[None]).transpose(2, 0, 1)).min() - 0.5
    assert clearance > limits.r_uav


def test_plan_path_snaps_blocked_endpoints_and_reports_no_path():
    raster = Raster((0.0, 0.0), 1.0, (10, 10))
    cfg = AStarConfig(res_g=1.0)
    world = np.zeros((10, 10), dtype=bool)
    world[5, 5] = True
    path = plan_path(world, raster, (0.5, 0.5), (5.5, 5.5), 1.0, cfg)  # goal cell inside the inflated block
    assert path is not None
    # inflation by one cell blocks the plus-shaped 5 cells; the nearest free centre is a diagonal one
    assert math.dist(path.points[-1], (5.5, 5.5)) == pytest.approx(math.sqrt(2.0))
    wall = np.zeros((10, 10), dtype=bool)
    wall[4, :] = True
    assert plan_path(wall, raster, (0.5, 0.5), (9.5, 9.5), 0.0, cfg) is None
    assert plan_path(np.ones((10, 10), dtype=bool), raster, (0.5, 0.5), (9.5, 9.5), 0.0, cfg) is None
    with pytest.raises(ValueError, match="res_g"):
        plan_path(world, raster, (0.5, 0.5), (9.5, 9.5), 0.0, AStarConfig())
    with pytest.raises(ValueError, match="blocked_world"):
        plan_path(world[:5], raster, (0.5, 0.5), (9.5, 9.5), 0.0, cfg)
    pruned = plan_path(np.zeros((10, 10), dtype=bool), raster, (0.5, 0.5), (9.5, 6.5), 0.0, cfg.replace(prune=True))
    # one straight segment after pruning, resampled at the raster resolution (11 steps of 0.99 m)
    assert pruned.points.tolist()[0] == [0.5, 0.5] and pruned.points.tolist()[-1] == [9.5, 6.5]
    assert len(pruned.points) == 12 and pruned.length == pytest.approx(math.hypot(9.0, 6.0))
    np.testing.assert_allclose(np.diff(pruned.points, axis=0), [[9.0 / 11, 6.0 / 11]] * 11)


def test_resample_keeps_corners_and_bounds_spacing():
    pts = np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 1.0], [3.0, 1.0]])
    out = resample(pts, 1.0)
    assert out.tolist() == [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0], [3.0, 1.0], [3.0, 1.0]]
    dense = resample(np.array([[0.0, 0.0], [2.5, 2.5]]), 0.5)
    assert np.all(np.hypot(*np.diff(dense, axis=0).T) <= 0.5 + 1e-12) and dense[-1].tolist() == [2.5, 2.5]
    assert resample(pts[:1], 1.0).tolist() == [[0.0, 0.0]]
    with pytest.raises(ValueError, match="spacing"):
        resample(pts, 0.0)


# ---------------------------------------------------------------------------------------------
# global path: progress, lookahead, distance, replanning
# ---------------------------------------------------------------------------------------------

def u_path():
    """Up x = 0 (y 0..10), across y = 10, down x = 2 (y 10..0): 23 nodes, 1 m apart."""
    up = [(0.0, float(y)) for y in range(11)]
    down = [(2.0, float(y)) for y in range(10, -1, -1)]
    return np.array(up + [(1.0, 10.0)] + down)


def test_lookahead_known_answers():
    path = GlobalPath(np.array([[float(k), 0.0] for k in range(6)]))
    assert path.lookahead((0.2, 0.1), 3.0).tolist() == [3.0, 0.0]
    assert path.lookahead((2.4, 0.0), 2.5).tolist() == [5.0, 0.0]  # progress 2, arc 2.5 -> node 5
    assert path.lookahead((4.8, 0.0), 3.0).tolist() == [5.0, 0.0]  # ends earlier: the goal
    assert path.progress == 5
    with pytest.raises(ValueError, match="L_a"):
        path.lookahead((0.0, 0.0), -1.0)
    with pytest.raises(ValueError, match="pos_xy"):
        path.update_progress((0.0,))


def test_lookahead_is_monotone_where_the_path_doubles_back():
    path = GlobalPath(u_path(), window=20)
    track = [(0.3, y) for y in np.arange(0.0, 10.0, 0.5)] + [(1.0, 10.3)] + [(1.2, y) for y in np.arange(9.5, 0.0, -0.5)]
    last_progress, last_arc = 0, 0.0
    for pos in track:
        p_la = path.lookahead(pos, 3.0)
        arc = path._arc[np.flatnonzero((path.points == p_la).all(axis=1))[0]]
        assert path.progress >= last_progress and arc >= last_arc
        last_progress, last_arc = path.progress, arc
    # on the way down, drifted toward the first leg (nearer to (0, 1) than to (2, 1)):
    p_la = path.lookahead((0.9, 1.0), 3.0)
    assert p_la.tolist() == [2.0, 0.0]  # still the end of the down leg, never back to the up leg
    assert path.progress >= 21


def test_progress_window_limits_forward_jumps():
    path = GlobalPath(u_path(), window=3)
    assert path.update_progress((1.9, 2.0)) == 2  # the down leg is nearer, but 18 nodes ahead
    assert GlobalPath(u_path(), window=20).update_progress((1.9, 2.0)) == 20


def test_distance_to_the_path_ahead():
    path = GlobalPath(np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 4.0]]))
    assert path.distance((2.0, 1.5)) == pytest.approx(1.5)
    assert path.distance((6.0, 2.0)) == pytest.approx(2.0)
    assert path.distance((-3.0, -4.0)) == pytest.approx(5.0)
    assert GlobalPath(np.array([[1.0, 1.0]])).distance((4.0, 5.0)) == pytest.approx(5.0)
    u = GlobalPath(u_path())
    for y in np.arange(0.0, 10.0):  # fly up, across and down to (2, 1)
        u.update_progress((0.0, y))
    for pos in ((1.0, 10.0), *((2.0, y) for y in np.arange(10.0, 0.0, -1.0))):
        u.update_progress(pos)
    assert u.distance((0.0, 1.0)) == pytest.approx(2.0)  # the up leg already flown does not count
    with pytest.raises(ValueError, match="points"):
        GlobalPath(np.zeros((0, 2)))


def test_replan_triggers_each_fire():
    raster = Raster((0.0, 0.0), 0.5, (20, 20))
    cfg = AStarConfig(res_g=0.5)
    world = np.zeros(raster.shape, dtype=bool)
    path = plan_path(world, raster, (0.2, 0.2), (9.8, 9.8), 0.5, cfg)
    inflated = inflate(world, 0.5, raster.res)
    on_path = path.points[5]

    def trigger(**kw):
        args = dict(path=path, pos_xy=on_path, blocked_inflated=inflated, raster=raster, t_since_plan=0.5,
                    new_data=True, cfg=cfg) | kw
        assert needs_replan(**args) == (replan_trigger(**args) is not None)
        return replan_trigger(**args)

    assert trigger() is None
    new_block = world.copy()
    new_block[tuple(raster.to_cell(path.points[10]))] = True
    assert trigger(blocked_inflated=inflate(new_block, 0.5, raster.res)) == "corridor"
    off = world.copy()
    off[0, 19] = True  # far from the path: no trigger
    assert trigger(blocked_inflated=inflate(off, 0.5, raster.res)) is None
    assert trigger(pos_xy=on_path + (1.5, -1.5)) == "off_path"  # 2.12 m > d_replan = 2
    assert trigger(pos_xy=on_path + (1.0, -1.0)) is None
    assert trigger(t_since_plan=2.0) == "periodic"
    assert trigger(t_since_plan=2.0, new_data=False) is None
    assert trigger(path=None) is None and trigger(path=None, t_since_plan=3.0) == "periodic"


def test_corridor_of_a_corner_cutting_path_is_not_blocked_by_its_corners():
    raster = Raster((0.0, 0.0), 1.0, (3, 3))
    world = np.zeros((3, 3), dtype=bool)
    world[1, 1] = True
    cfg = AStarConfig(res_g=1.0, allow_corner_cut=True)
    path = plan_path(world, raster, (0.5, 0.5), (2.5, 2.5), 0.0, cfg)
    assert path.length == pytest.approx(2.0 + math.sqrt(2.0))
    assert not path.corridor_blocked(world, raster)
    strict = GlobalPath(path.points, allow_corner_cut=False)
    assert strict.corridor_blocked(world, raster)  # the same diagonal is illegal without corner cutting
