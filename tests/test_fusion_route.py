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
