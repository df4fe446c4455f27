"""The fusion expert's small numba kernels give bit for bit the numpy expressions they replace (the end-state
snapshots depend on it), and the local-voxel answer to "is this slot blocked" equals the map's query."""

import math
from types import SimpleNamespace

import numpy as np

from baselines.fusion import ExpertConfig, FusionExpert
from baselines.fusion.controller import _UAVMemory, _occupied_within
from baselines.fusion.kernels import (closest_approach, closest_approach_of, in_sphere, live_within, mark_cells,
                                      nearest_live, predicted_movers, slot_errors, trail_arc, trail_points)
from uavform_env import parallel_env
from uavform_env.dynamics import PSI, V, VZ
from uavform_env.formation import slot_positions

RNG = np.random.default_rng(7)


def test_nearest_and_near_live_movers_match_numpy_norms():
    for _ in range(200):
        k = int(RNG.integers(0, 7))
        movers, pos = RNG.normal(size=(k, 3)) * 4.0, RNG.normal(size=3)
        alive = RNG.random(k) < 0.7
        dist = np.linalg.norm(movers - pos, axis=1)
        m, d = nearest_live(pos, movers, alive)
        if alive.any():
            live = np.flatnonzero(alive)
            assert m == live[np.argmin(dist[alive])] and d == dist[m]
        else:
            assert m == -1 and d == math.inf
        assert np.array_equal(live_within(pos, movers, alive, 3.0), movers[alive & (dist < 3.0)])


def test_closest_approach_of_a_subset_is_closest_approach_to_that_subset():
    for _ in range(100):
        k = int(RNG.integers(0, 6))
        args = RNG.normal(size=3), RNG.normal(size=3), RNG.normal(size=(k, 3)) * 3.0, RNG.normal(size=(k, 3))
        which = RNG.random(k) < 0.5
        assert closest_approach_of(*args, which, 30, 0.1) == closest_approach(args[0], args[1], args[2][which],
                                                                               args[3][which], 30, 0.1)


def test_in_sphere_keeps_the_points_and_values_inside_in_order():
    pts, vals, centre = RNG.normal(size=(500, 3)) * 3.0, RNG.random(500), RNG.normal(size=3)
    inside, inside_vals = in_sphere(pts, vals, centre, 2.5)
    keep = ((pts - centre) ** 2).sum(axis=1) <= 2.5 ** 2
    assert np.array_equal(inside, pts[keep]) and np.array_equal(inside_vals, vals[keep])


def test_mark_cells_blocks_the_cells_of_the_points_inside_the_raster():
    origin, res, shape = np.array([-3.1, 2.05]), 0.4, (20, 15)
    xy = RNG.uniform(-6.0, 12.0, size=(300, 2))
    blocked = np.zeros(shape, bool)
    mark_cells(blocked, origin[0], origin[1], res, xy)
    cells = np.floor((xy - origin) / res).astype(np.int64)
    ok = np.all((cells >= 0) & (cells < np.asarray(shape)), axis=1)
    expected = np.zeros(shape, bool)
    expected[cells[ok, 0], cells[ok, 1]] = True
    assert np.array_equal(blocked, expected)


def test_predicted_movers_are_the_broadcasts_moved_one_cycle():
    ns = RNG.normal(size=(4, 7))
    for predict in (True, False):
        pos, vel = predicted_movers(ns, np.cos(ns[:, PSI]), np.sin(ns[:, PSI]), 0.1, predict)
        expected = np.column_stack([ns[:, V] * np.cos(ns[:, PSI]), ns[:, V] * np.sin(ns[:, PSI]), ns[:, VZ]])
        assert np.array_equal(pos, ns[:, :3] + expected * 0.1)
        assert np.array_equal(vel, expected if predict else np.zeros_like(expected))


def test_slot_errors_are_the_numpy_slot_distances_bit_for_bit():
    """The leader's view of its followers' slot errors: ``slot_positions`` about the origin, shifted to the leader,
    then ``np.linalg.norm`` of the live followers' differences (the expression ``slot_errors`` replaced)."""
    for _ in range(200):
        n = int(RNG.integers(1, 8))
        offsets = RNG.normal(size=(n, 3)) * 3.0
        ids = np.arange(1, n)
        states = RNG.normal(size=(n - 1, 7)) * 10.0
        alive = RNG.random(n - 1) < 0.7
        x, y, psi = *(RNG.normal(size=2) * 10.0), float(RNG.uniform(-4.0, 4.0))
        slots = np.array([x, y]) + slot_positions(np.zeros(2), psi, offsets[ids], 0.0)[:, :2]
        expected = np.linalg.norm(states[alive, :2] - slots[alive], axis=1)
        got = slot_errors(x, y, float(np.cos(psi)), float(np.sin(psi)), offsets, ids, states, alive)
        assert np.array_equal(got, expected)
    one = slot_errors(1.0, 2.0, 0.0, 1.0, np.array([[0.0, 0.0, 0.0], [-2.0, 0.0, 0.0]]), np.array([1]),
                      np.array([[4.0, 4.0, 0, 0, 0, 0, 0]]), np.array([True]))
    assert np.array_equal(one, [5.0])                  # slot (1, 0) after a quarter turn; the follower 3-4-5 away


def test_slot_blocked_from_the_local_voxels_equals_the_map_query():
    penv = parallel_env(scenario="forest", max_cycles=60)
    obs, _ = penv.reset(seed=0)
    policy = FusionExpert()
    policy.reset(penv, seed=0)
    fast = occupied = 0
    for _ in range(40):
        for agent in penv.agents:
            view = penv.unwrapped.onboard(agent)
            local = policy._local(view, policy.config)
            for _ in range(25):
                radius = RNG.uniform(0.1, 1.5)
                if len(local.obstacles) and RNG.random() < 0.5:     # on the ball's rim around a voxel
                    d = RNG.normal(size=3)
                    point = local.obstacles[RNG.integers(len(local.obstacles))] + d / np.linalg.norm(d) * radius
                else:
                    point = view.state[:3] + RNG.normal(size=3) * 2.0
                want = view.occupancy.occupied_within(point, radius)
                assert _occupied_within(view, local, point, radius) == want
                fast += math.dist(point, view.state[:3]) + radius + view.occupancy.resolution <= local.reach
                occupied += want
        obs, *_ = penv.step(policy.act(obs, penv))
    assert fast > 1000 and occupied > 100           # the fast path and occupied answers were both exercised


def test_clear_turn_radius_known_answers():
    from baselines.fusion.kernels import clear_turn_radius
    w_max, a_max = math.radians(20.0), 0.2
    # the point 3 m left of a UAV at the origin heading +x: pure pursuit onto it is a half circle, r = 1.5
    none = np.empty((0, 3))
    assert clear_turn_radius(0.0, 0.0, 3.0, 0.0, 0.3, 0.0, 3.0, 1.5, none, 0.5, w_max, a_max) == 1.5
    # a wall of voxels at x = 1.0 (y -2..5) cuts the wide arc (it reaches x = 1.5): a tighter turn clears it
    wall = np.array([[1.0, y, 3.0] for y in np.arange(-2.0, 5.0, 0.1)])
    r = clear_turn_radius(0.0, 0.0, 3.0, 0.0, 0.3, 0.0, 3.0, 1.5, wall, 0.5, w_max, a_max)
    assert 0.0 <= r < 1.5 and r <= 0.5 + 1e-9
    # the same wall ahead at 1 m/s: braking to any turn's speed runs 1 m or more straight into it: none clears
    assert clear_turn_radius(0.0, 0.0, 3.0, 0.0, 1.0, 0.0, 3.0, 1.5, wall, 0.5, w_max, a_max) == 1.5
    # a point hidden behind a wall across the way: no turn reaches it, the pure-pursuit radius stands
    across = np.array([[x, 1.5, 3.0] for x in np.arange(-5.0, 5.0, 0.1)])
    assert clear_turn_radius(0.0, 0.0, 3.0, 0.0, 0.3, 0.0, 3.0, 1.5, across, 0.5, w_max, a_max) == 1.5


def test_trail_arc_and_points_known_answers():
    """An L-shaped trail: the leader at (0, 0) came from (0, -4) via (-3, -4) (points oldest first). Arcs run from the
    leader back along the trail: (0, -4) is 4 m back, (-3, -4) 7 m."""
    trail = np.array([[-3.0, -4.0], [-2.0, -4.0], [0.0, -4.0], [0.0, -2.0]])
    leader = np.array([0.0, 0.0])
    points, reached = trail_points(trail, leader, np.array([0.0, 1.5, 4.0, 5.5, 7.0]))
    assert reached
    assert np.allclose(points, [[0.0, 0.0], [0.0, -1.5], [0.0, -4.0], [-1.5, -4.0], [-3.0, -4.0]])
    points, reached = trail_points(trail, leader, np.array([2.0, 9.0]))     # beyond the oldest point: that point
    assert not reached and np.allclose(points, [[0.0, -2.0], [-3.0, -4.0]])
    assert trail_arc(trail, leader, np.array([0.5, -1.0]), 20.0) == 1.0      # beside the newest leg
    assert math.isclose(trail_arc(trail, leader, np.array([-1.0, -5.0]), 20.0), 5.0)   # below the older leg
    assert trail_arc(trail, leader, np.array([-1.0, -5.0]), 3.0) == 4.0      # only the part within 3 m of the leader
    # a trail that doubles back: the newest of equally near points counts
    back = np.array([[0.0, 0.0], [4.0, 0.0]])
    assert trail_arc(back, np.array([0.0, 0.0]), np.array([2.0, 0.0]), 20.0) == 2.0


def test_file_place_follows_the_trail_round_a_corner():
    """A follower (index 1) in single file behind a leader that turned a corner: its place lies on the leader's trail,
    its goal ahead of it along the trail (not across the corner), and its lag is its arc length behind its place."""
    cfg = ExpertConfig()
    trail = np.array([[-6.0, 0.0], [-4.0, 0.0], [-2.0, 0.0], [0.0, 0.0], [0.0, 2.0]])   # east, then north
    mem = _UAVMemory(trail=trail)
    lead = np.zeros(7)
    lead[:2], lead[V] = (0.0, 3.0), 0.0
    view = SimpleNamespace(index=1, config=SimpleNamespace(formation=SimpleNamespace(spacing=2.0)),
                           state=np.array([-4.0, 0.0, 2.0]))
    goal, lookahead, place, e_par = FusionExpert._file_place(view, mem, cfg, lead, lead_moving=False)
    assert np.allclose(place, [0.0, 1.0])                    # 2 m back along the trail from (0, 3)
    assert math.isclose(e_par, 5.0)                          # the follower is 7 m back: 5 m behind its place
    assert np.allclose(goal, [-4.0 + cfg.astar.lookahead, 0.0])   # along the trail's eastward leg, not to (0, 1)
    assert np.allclose(lookahead, [-4.0 + cfg.astar.lookahead + cfg.k_h, 0.0])
    short = _UAVMemory(trail=trail[-1:])                    # 1 m of trail: shorter than the place's 2 m
    assert FusionExpert._file_place(view, short, cfg, lead, lead_moving=False) is None
