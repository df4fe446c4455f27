"""The leader's pace (``ExpertConfig.leader_pace``): followers trailing it round a bend on its own way are not lag;
followers off its way or far back along it are (``kernels.trail_lags``)."""

import math
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest

from baselines.expert import ExpertConfig, FusionExpert
from baselines.fusion.controller import _UAVMemory
from baselines.fusion.kernels import trail_lags


def straight_trail(length: float = 10.0, spacing: float = 0.25) -> np.ndarray:
    x = np.arange(0.0, length + 1e-9, spacing)
    return np.column_stack([x, np.zeros_like(x)])


@pytest.mark.parametrize("follower, allowed, lag", [
    ((8.0, 0.0), 2.0, 0.0),          # on the trail, within its slot's range behind the leader
    ((4.0, 0.0), 2.0, 4.0),          # on the trail, 6 m behind: 4 m more than its 2 m
    ((4.0, 3.0), 2.0, 5.0),          # 3 m off it: 5 m to (8, 0), 2 m behind (the least of distance + excess)
    ((-2.0, 0.0), 2.0, 10.0),        # behind the trail's start: 2 m to its first point, 10 m back: 2 + 8
    ((11.0, 0.0), 2.0, 1.0),         # ahead of the leader: its distance to the newest point
    ((5.0, 0.0), 20.0, 0.0),         # a slot range longer than the trail
])
def test_trail_lag_is_least_distance_to_a_trail_point_plus_its_excess_behind_the_slot_range(follower, allowed, lag):
    lags = trail_lags(straight_trail(), np.array([10.0, 0.0]), np.array([follower], dtype=float), np.array([allowed]))
    assert lags == pytest.approx([lag])


def test_trail_lag_follows_the_trail_round_a_bend():
    """An L-shaped trail: (0, 0) -> (5, 0) -> (5, 5), leader at (5, 5), slot range 2 m. A follower at (1, 0), 9 m
    back along the trail, lags 5 m: its distance to (5, 3), 2 m behind the leader; one at (5, 2) lags 1 m."""
    leg1 = np.column_stack([np.arange(0.0, 5.0, 0.25), np.zeros(20)])
    leg2 = np.column_stack([np.full(21, 5.0), np.arange(0.0, 5.0 + 1e-9, 0.25)])
    trail = np.vstack([leg1, leg2])
    lags = trail_lags(trail, np.array([5.0, 5.0]), np.array([[1.0, 0.0], [5.0, 2.0]]), np.array([2.0, 2.0]))
    assert lags == pytest.approx([5.0, 1.0])


def test_where_the_leader_turned_back_along_its_trail_the_newer_points_count():
    """The leader flew east from (0, 0) to (10, 0) and back west to (5.75, 0). A follower at (7, 0) lies 1.25 m
    behind it on the way back (not 11.25 m on the way out): no lag; one at (2, 0) lags 4 m, its distance to the
    trail's newest point, (6, 0)."""
    out = np.column_stack([np.arange(0.0, 10.0 + 1e-9, 0.25), np.zeros(41)])
    back = np.column_stack([np.arange(9.75, 6.0 - 1e-9, -0.25), np.zeros(16)])
    lags = trail_lags(np.vstack([out, back]), np.array([5.75, 0.0]), np.array([[7.0, 0.0], [2.0, 0.0]]),
                      np.array([2.0, 2.0]))
    assert lags == pytest.approx([0.0, 4.0])


def test_trail_lags_match_the_brute_force_formula_on_a_random_walk():
    rng = np.random.default_rng(3)
    trail = np.cumsum(rng.normal(0.0, 0.25, (300, 2)), axis=0)
    leader, followers, allowed = trail[-1] + 0.1, rng.uniform(-8.0, 8.0, (9, 2)), rng.uniform(0.0, 6.0, 9)
    steps = np.r_[0.0, np.linalg.norm(np.diff(trail, axis=0), axis=1)]
    behind = np.linalg.norm(leader - trail[-1]) + (steps.sum() - np.cumsum(steps))
    off = np.linalg.norm(followers[:, None] - trail[None], axis=2)
    expected = (off + np.maximum(0.0, behind[None] - allowed[:, None])).min(axis=1)
    assert trail_lags(trail, leader, followers, allowed) == pytest.approx(expected, rel=1e-12, abs=1e-12)


def pace_view(followers_xy, leader_x: float, leader_psi: float):
    """A leader at (``leader_x``, 0) heading ``leader_psi`` with two followers; formation: a column 2 m apart
    (slots (-2, 0) and (-4, 0) in its body frame)."""
    offsets = np.array([[0.0, 0.0, 0.0], [-2.0, 0.0, 0.0], [-4.0, 0.0, 0.0]])
    ns = np.zeros((2, 7))
    ns[:, :2] = followers_xy
    return SimpleNamespace(state=np.array([leader_x, 0.0, 3.0, leader_psi, 0.8, 0.0, 0.0]), offsets=offsets,
                           neighbour_ids=np.array([1, 2]), neighbour_alive=np.array([True, True]),
                           neighbour_states=ns, config=SimpleNamespace(formation=SimpleNamespace(spacing=2.0)))


def pace_errors(pace: str, followers_xy, leader_psi: float) -> np.ndarray:
    """The pace errors once the leader flew east along y = 0 from x = 0 to x = 10 and turned to ``leader_psi``."""
    cfg = replace(ExpertConfig(), leader_pace=pace)
    mem = _UAVMemory()
    for x in np.arange(0.0, 10.0, 0.25):                # its trail so far, one point a step
        FusionExpert._pace_errors(pace_view(followers_xy, x, 0.0), mem, cfg)
    return FusionExpert._pace_errors(pace_view(followers_xy, 10.0, leader_psi), mem, cfg)


def test_followers_trailing_round_a_bend_do_not_slow_the_leader_on_the_trail_pace():
    """The leader turned north at (10, 0); its column slots swung to (10, -2) and (10, -4), 2.8 and 5.7 m from the
    followers still on its trail at (8, 0) and (6, 0). By slot errors they lag; by the trail, not at all."""
    followers = [[8.0, 0.0], [6.0, 0.0]]
    slot = pace_errors("slot", followers, math.pi / 2)
    assert slot == pytest.approx([math.hypot(2, 2), math.hypot(4, 4)])
    assert pace_errors("trail", followers, math.pi / 2) == pytest.approx([0.0, 0.0])


def test_a_follower_held_off_the_trail_still_slows_the_leader():
    """The leader heads on east. A follower held 5 m off the trail beside its point 6 m back (behind an obstacle)
    lags 5 + (6 - 2) = 9 m by the trail, 6.4 m by its slot: the smaller still paces the leader as the slot pace
    does; a follower 2 m beside its slot lags 2 m either way."""
    errors = pace_errors("trail", [[4.0, 5.0], [6.0, 2.0]], 0.0)
    assert errors == pytest.approx([math.hypot(4.0, 5.0), 2.0])
    assert np.all(errors == pace_errors("slot", [[4.0, 5.0], [6.0, 2.0]], 0.0))


def test_leader_pace_is_validated():
    with pytest.raises(ValueError, match="leader_pace"):
        ExpertConfig(leader_pace="range")


def test_a_follower_filing_at_its_place_on_the_trail_does_not_slow_the_leader():
    """``column_shape="trail"``: a wedge follower (index 2, slot (-2, 2), 2.8 m from the leader) filing in single file
    sits 2 x spacing = 4 m behind the leader along its trail. Round the leader's bend that reads no lag; with the
    rigid column its slot's 2.8 m range stands, and the 1.2 m beyond it paces the leader."""
    follower = [[6.0, 0.0], [6.0, 0.0]]                     # index 1 and 2 both at the point 4 m back

    def errors(shape: str) -> np.ndarray:
        cfg = replace(ExpertConfig(), leader_pace="trail", column_shape=shape)
        mem = _UAVMemory()
        for x, heading in [(x, 0.0) for x in np.arange(0.0, 10.0, 0.25)] + [(10.0, math.pi / 2)]:
            view = pace_view(follower, x, heading)
            view.offsets = np.array([[0.0, 0.0, 0.0], [-2.0, -2.0, 0.0], [-2.0, 2.0, 0.0]])
            last = FusionExpert._pace_errors(view, mem, cfg)
        return last

    assert errors("trail")[1] == pytest.approx(0.0)
    assert errors("rigid")[1] == pytest.approx(4.0 - math.hypot(2.0, 2.0))
