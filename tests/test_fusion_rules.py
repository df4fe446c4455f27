"""The fusion expert's command rules (``baselines.fusion.rules``): their order, and each one's known answer
on a constructed command record; and the planners injected into the controller."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from baselines.dwa import dwa_plan
from baselines.fusion import ExpertConfig, FusionExpert
from baselines.fusion.controller import _UAVMemory
from baselines.fusion.rules import (RULES, Command, Cycle, braking_fallback, dock_turn, emergency_escape,
                                    reverse_turn)
from baselines.vfh3d import VFHPlanner
from uavform_env import EnvConfig, parallel_env

CFG = ExpertConfig()
LIM = EnvConfig().uav
W_MAX = LIM.w_max


class FakeMap:
    """The two things the rules ask of a map: its resolution and the occupied voxels in a sphere."""

    resolution = 0.2

    def __init__(self, voxels=()):
        self.voxels = np.asarray(voxels, dtype=np.float64).reshape(-1, 3)

    def occupied_in_sphere(self, pos, radius):
        near = self.voxels[np.linalg.norm(self.voxels - pos, axis=1) <= radius]
        return near, np.ones(len(near))


def view(state=(0.0, 0.0, 3.0, 0.0, 0.0, 0.0, 0.0), is_leader=True, goal=(10.0, 0.0, 3.0), leader_speed=0.5,
         voxels=(), alive=()):
    return SimpleNamespace(state=np.array(state, dtype=np.float64), is_leader=is_leader,
                           goal=np.array(goal, dtype=np.float64), limits=LIM, config=EnvConfig(),
                           leader_state=np.array([0.0, 0.0, 3.0, 0.0, leader_speed, 0.0, 0.0]),
                           occupancy=FakeMap(voxels), neighbour_alive=np.array(alive, dtype=bool))


def cycle(v, mem=None, goal=(10.0, 0.0), lookahead=(10.0, 0.0), heading_goal=(10.0, 0.0), admissible=True,
          vfh=None, movers=np.zeros((0, 3)), cfg=CFG):
    return Cycle(view=v, mem=mem or _UAVMemory(), cfg=cfg, goal=np.array(goal), lookahead=np.array(lookahead),
                 heading_goal=np.array(heading_goal), dwa=SimpleNamespace(admissible=admissible), vfh=vfh,
                 movers_pos=movers, movers_vel=np.zeros_like(movers))


def test_rules_are_named_and_ordered():
    assert [r.__name__ for r in RULES] == ["braking_fallback", "dock_turn", "reverse_turn", "emergency_escape"]
    assert all(r.__doc__ for r in RULES)


def test_braking_fallback_turns_toward_the_heading_goal_and_escapes_vertically_after_t_stuck():
    mem = _UAVMemory(stuck_time=2.0)
    cmd = Command(0.4, 0.1, 0.2)
    braking_fallback(cmd, cycle(view(), mem))                      # admissible: nothing changes, the timer resets
    assert (cmd.v, cmd.w, cmd.vz, mem.stuck_time) == (0.4, 0.1, 0.2, 0.0)
    free_above = SimpleNamespace(binary=np.vstack([np.ones((35, 72)), np.zeros((1, 72))]), emergency=False)
    braking_fallback(cmd, cycle(view(), mem, heading_goal=(0.0, 5.0), admissible=False, vfh=free_above))
    assert cmd.w == W_MAX and cmd.vz == 0.2 and mem.stuck_time == pytest.approx(LIM.dt)   # heading goal 90 deg left
    mem.stuck_time = CFG.T_stuck
    braking_fallback(cmd, cycle(view(), mem, heading_goal=(5.0, -0.1), admissible=False, vfh=free_above))
    assert cmd.w == pytest.approx(-math.atan2(0.1, 5.0)) and cmd.vz == LIM.vz_max      # stuck: up, the way is free


def test_dock_turn_turns_the_leader_in_place_toward_a_goal_abeam():
    cmd = Command(0.3, 0.0, 0.0)
    dock_turn(cmd, cycle(view(goal=(1.0, 0.1, 3.0))))               # goal ahead: DWA's command stands
    assert (cmd.v, cmd.w, cmd.turning) == (0.3, 0.0, False)
    dock_turn(cmd, cycle(view(goal=(0.5, -1.0, 3.0))))              # 63 degrees right, 1.1 m away
    assert (cmd.v, cmd.w, cmd.turning) == (0.0, -W_MAX, True)
    far = Command(0.3, 0.0, 0.0)
    dock_turn(far, cycle(view(goal=(0.0, 3.0, 3.0))))               # abeam but beyond dock_radius
    assert (far.v, far.turning) == (0.3, False)


def test_dock_turn_of_a_follower_needs_a_parked_leader_and_its_own_rest():
    follower = dict(is_leader=False, goal=(30.0, 0.0, 3.0))
    cmd = Command(0.0, 0.0, 0.0)
    dock_turn(cmd, cycle(view(leader_speed=0.0, **follower), goal=(-0.5, 2.0)))
    assert cmd.turning and cmd.w == W_MAX
    for moving in (dict(leader_speed=0.5), dict(leader_speed=0.0, state=(0, 0, 3, 0, 0.3, 0, 0))):
        cmd = Command(0.0, 0.0, 0.0)
        dock_turn(cmd, cycle(view(**moving, **follower), goal=(-0.5, 2.0)))
        assert not cmd.turning


def test_reverse_turn_turns_toward_a_lookahead_behind_unless_already_turning():
    behind = dict(lookahead=(-3.0, 0.1))
    cmd = Command(0.5, 0.0, 0.1)
    reverse_turn(cmd, cycle(view(), _UAVMemory(on_path=False), **behind))   # not on a path: no turn
    assert cmd.v == 0.5
    reverse_turn(cmd, cycle(view(), _UAVMemory(on_path=True), **behind))
    assert (cmd.v, cmd.w, cmd.vz, cmd.turning) == (0.0, W_MAX, 0.1, True)
    docked = Command(0.0, -0.2, 0.0, turning=True)
    reverse_turn(docked, cycle(view(), _UAVMemory(on_path=True), **behind))
    assert docked.w == -0.2                                                 # the dock turn came first


def test_emergency_escape_moves_away_vertically_unless_into_a_neighbour():
    emergency = SimpleNamespace(emergency=True)
    cmd = Command(0.5, 0.1, 0.0)
    emergency_escape(cmd, cycle(view(voxels=[[0.0, 0.0, 3.4]]), vfh=None))  # planar mode: no 3D VFH+
    assert (cmd.v, cmd.vz) == (0.5, 0.0)
    emergency_escape(cmd, cycle(view(voxels=[[0.0, 0.0, 3.4]]), vfh=emergency))
    assert (cmd.v, cmd.w, cmd.vz) == (0.0, 0.1, -LIM.vz_max)               # a voxel above: down
    beside = Command(0.5, 0.1, 0.0)
    emergency_escape(beside, cycle(view(voxels=[[0.4, 0.0, 3.1]]), vfh=emergency))
    assert (beside.v, beside.vz) == (0.5, 0.0)                             # beside: left to DWA
    below = Command(0.5, 0.1, 0.0)
    emergency_escape(below, cycle(view(voxels=[[0.0, 0.0, 3.4]], alive=[True]), vfh=emergency,
                                  movers=np.array([[0.0, 0.0, 2.6]])))
    assert (below.v, below.vz) == (0.0, 0.0)                               # a neighbour below: hold altitude


def _flight(policy, steps=25):
    penv = parallel_env(scenario="forest", n_uavs=3, formation="triangle", max_cycles=steps)
    obs, _ = penv.reset(seed=4)
    policy.reset(penv, seed=4)
    actions = []
    while penv.agents:
        act = policy.act(obs, penv)
        actions.append(np.array([act[a] for a in sorted(act)]))
        obs, *_ = penv.step(act)
    return np.array(actions)


def test_injected_planners_are_the_ones_called():
    calls = {"dwa": 0, "vfh": 0}
    real_vfh = VFHPlanner()

    def counting_dwa(*args, **kwargs):
        calls["dwa"] += 1
        return dwa_plan(*args, **kwargs)

    def counting_vfh(*args, **kwargs):
        calls["vfh"] += 1
        return real_vfh(*args, **kwargs)

    counted = _flight(FusionExpert(dwa=counting_dwa, vfh=counting_vfh))
    assert calls["dwa"] >= 3 * 25 and calls["vfh"] == 3 * 25            # once per UAV-step (DWA: a retry at most)
    assert np.array_equal(counted, _flight(FusionExpert()))              # the defaults are these planners

    def frozen_dwa(state, limits, cfg, goal, *args, **kwargs):
        return dwa_plan(state, limits, cfg, goal, *args, **{**kwargs, "v_cap": 0.0})

    assert np.all(_flight(FusionExpert(dwa=frozen_dwa), 10)[:, :, 0] == -1.0)   # speed action -1: v = 0


def test_planners_must_be_callable():
    with pytest.raises(ValueError, match="dwa: expected a callable"):
        FusionExpert(dwa="idwa")
