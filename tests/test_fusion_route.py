"""The leader's route choice counts the turn onto it (``ExpertConfig.route_turn_cost``, ``controller.route_cost``)."""

import math
from dataclasses import replace

import numpy as np
import pytest

from baselines.expert import ExpertConfig, FusionExpert
from baselines.fusion.controller import route_cost
from uavform_env.evaluation.suites import Episode
from uavform_env.formation_v0 import parallel_env

K = 2.0      # metres per radian of turn


@pytest.mark.parametrize("points, psi, cost", [
    ([(0, 0), (2, 0), (6, 0)], 0.0, 6.0),                              # straight on: its length
    ([(0, 0), (0, 5)], 0.0, 5.0 + K * math.pi / 2),                    # a quarter turn left
    ([(0, 0), (0, -5)], 0.0, 5.0 + K * math.pi / 2),                   # ... or right: the turn's size
    ([(0, 0), (-4, 0)], 0.0, 4.0 + K * math.pi),                       # behind
    ([(0, 0), (1, 1), (1, 6)], math.pi / 4, math.sqrt(2) + 5.0 + K * (math.atan2(6, 1) - math.pi / 4)),  # node past L: (1, 6)
    ([(0, 0), (2, 0)], -math.pi / 2, 2.0 + K * math.pi / 2),           # shorter than L: its end's bearing
    ([(3, 3)], 1.0, 0.0),                                              # already there
])
def test_route_cost_is_length_plus_metres_per_radian_times_the_turn_onto_the_point_lookahead_along(points, psi, cost):
    pts = np.array(points, dtype=float)
    assert route_cost(pts, psi, 3.0, K) == pytest.approx(cost)


def fly_maze(turn_cost: bool, steps: int) -> int:
    """One UAV through the unknown disc maze of classic-2d 'extended' (v1-dev seed 200034, start heading east)."""
    ep = Episode(scenario="classic-2d@2", difficulty="extended", n_uavs=1, formation="wedge", spacing=2.0,
                 seed=200034, max_cycles=steps)
    penv = parallel_env(**ep.env_kwargs())
    obs, _ = penv.reset(seed=ep.seed)
    policy = FusionExpert(replace(ExpertConfig(), route_turn_cost=turn_cost))
    policy.reset(penv, seed=ep.seed)
    while penv.agents:
        obs, _, _, _, infos = penv.step(policy.act(obs, penv))
    return infos["uav_0"]["success"]


def test_counting_the_turn_keeps_the_leader_out_of_the_maze_pocket_it_otherwise_turns_into():
    """Known answer on a dev episode: without the turn cost the leader turns at once onto A*'s first route, north into
    a pocket its map shows closed only on arrival, and times out; with it it flies on east and arrives by step 400."""
    assert fly_maze(True, 400) == 1
    assert fly_maze(False, 400) == 0


def heading_route_in_the_open(keep_margin: float) -> np.ndarray:
    """The leader's route choice (``FusionExpert._heading_route``) at a cell centre heading east, the goal 10 m east and
    5 m north of it (cell centres, so A*'s pruned path is the straight segment), an empty
    20 m x 20 m raster: A*'s direct route costs its length 11.18 + its turn atan(1/2) x 2.29 = 12.24, the route that
    first flies L_a = 3 m straight on 3 + 8.60 + atan(5/7) x 2.29 = 13.02 (raster paths differ by a few cm)."""
    from types import SimpleNamespace

    from baselines.astar import Raster
    from uavform_env.config import UAVLimits

    policy = FusionExpert(replace(ExpertConfig(), route_keep_margin=keep_margin))
    policy.raster = Raster((-5.0, -5.0), policy.config.astar.res_g, (40, 40))
    lim = UAVLimits()
    view = SimpleNamespace(state=np.array([0.25, 0.25, 3.0, 0.0, 0.5, 0.0, 0.0]), limits=lim)
    blocked = np.zeros(policy.raster.shape, bool)
    goal = np.array([10.25, 5.25])
    path = policy._search(blocked, view.state[:2], goal, lim, 0.0, 0.0)
    return policy._heading_route(view, blocked, goal, path, 0.0).points


@pytest.mark.parametrize("margin, straight_on", [(0.0, False), (0.5, False), (1.0, True), (2.0, True)])
def test_route_keep_margin_flies_on_unless_the_turn_saves_more_than_the_margin(margin, straight_on):
    """Known answer: the route straight on costs 0.78 m more; it is kept with a margin above that, not below."""
    points = heading_route_in_the_open(margin)
    first_leg = points[1] - points[0]
    assert (abs(math.atan2(first_leg[1], first_leg[0])) < 1e-9) == straight_on
    assert np.allclose(points[0], [0.25, 0.25]) and np.allclose(points[-1], [10.25, 5.25])
