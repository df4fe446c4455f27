"""Followers reaching their slots (issue 13, "no frozen followers"): the known-gap altitude held in LEVEL mode
(``ExpertConfig.gap_hold``), the in-place turn into a wall's gap (rule ``gap_turn``) and the stopping-distance
cap of a follower closing on a parking leader's slot (``slot_brake``)."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from baselines.fusion import ExpertConfig, FusionExpert
from baselines.fusion.controller import _Local, _slot_brake_cap, _Target, _UAVMemory
from baselines.fusion.rules import Command, Cycle, gap_turn
from baselines.vertical import LEVEL
from uavform_env import EnvConfig
from uavform_env.occupancy import OccupancyMap

LIM = EnvConfig().uav


def _gap_turn_cycle(psi, heading_goal, gap, cfg=ExpertConfig()):
    v = SimpleNamespace(state=np.array([0.0, 0.0, 4.0, psi, 0.4, 0.0, 0.0]), limits=LIM)
    return Cycle(view=v, mem=_UAVMemory(), cfg=cfg, goal=np.array(heading_goal), lookahead=np.array(heading_goal),
                 heading_goal=np.array(heading_goal), dwa=SimpleNamespace(admissible=True), vfh=None,
                 movers_pos=np.zeros((0, 3)), movers_vel=np.zeros((0, 3)), gap=gap)


def test_gap_turn_turns_in_place_toward_a_gap_abeam_only_while_passing_a_gap():
    abeam = dict(psi=math.pi / 2, heading_goal=(3.0, 0.0))           # flying along the wall (+y), the gap at +x
    cmd = Command(0.25, -0.07, -0.03)
    gap_turn(cmd, _gap_turn_cycle(gap=False, **abeam))               # no gap ahead: DWA's command stands
    assert (cmd.v, cmd.w, cmd.turning) == (0.25, -0.07, False)
    gap_turn(cmd, _gap_turn_cycle(gap=True, **abeam))                # 90 degrees right, > 45: turn in place, right
    assert (cmd.v, cmd.w, cmd.vz, cmd.turning) == (0.0, -LIM.w_max, -0.03, True)
    ahead = Command(0.25, -0.07, 0.0)
    gap_turn(ahead, _gap_turn_cycle(psi=math.radians(-30.0), heading_goal=(3.0, 0.0), gap=True))   # 30 deg < 45
    assert (ahead.v, ahead.w, ahead.turning) == (0.25, -0.07, False)
    off = Command(0.25, -0.07, 0.0)
    gap_turn(off, _gap_turn_cycle(gap=True, cfg=ExpertConfig(gap_turn_angle=math.pi), **abeam))     # disabled
    assert (off.v, off.turning) == (0.25, False)
    docked = Command(0.0, 0.3, 0.0, turning=True)
    gap_turn(docked, _gap_turn_cycle(gap=True, **abeam))              # an earlier turn rule keeps its direction
    assert docked.w == 0.3


@pytest.mark.parametrize("v_leader, distance", [(0.0, 0.9), (0.4, 1.33), (0.8, 0.0), (0.0, 0.0)])
def test_slot_brake_cap_stops_where_the_slot_stops(v_leader, distance):
    a = LIM.a_max
    cap = _slot_brake_cap(v_leader, distance, a)
    assert cap == pytest.approx(math.sqrt(v_leader ** 2 + 2 * a * distance))
    # independent check: brake both at a_max step by step (dt 1 ms); the follower stops where the slot does
    dt, v, x, vl, xl = 1e-3, cap, 0.0, v_leader, distance
    while v > 0.0 or vl > 0.0:
        x, v = x + v * dt - 0.5 * a * dt * dt * (v > 0), max(0.0, v - a * dt)
        xl, vl = xl + vl * dt - 0.5 * a * dt * dt * (vl > 0), max(0.0, vl - a * dt)
    assert x == pytest.approx(xl, abs=2e-3)
    assert _slot_brake_cap(0.0, 0.9, 0.2) == pytest.approx(0.6)          # v^2 / (2 a) = 0.36 / 0.4 = 0.9 m


class _LevelVFH:
    """3D VFH+ stand-in: every cell open, elevation 0: the level way it sees at the UAV's own altitude."""

    def __call__(self, memory, cfg, lim, pos, psi, v, vz, to_aim, centres, probs, resolution, close):
        return SimpleNamespace(blocked=False, emergency=False, elevation=0.0, azimuth=math.atan2(to_aim[1], to_aim[0]),
                               window_open=np.ones((36, 72), bool))     # 5-degree cells, all open


def _wall_with_gap(gap_lo, gap_hi, x_wall=2.0, res=0.2):
    """An own map that has seen a wall across y at x_wall..x_wall + 0.4, occupied outside [gap_lo, gap_hi] and
    known free inside it (level rays from the UAV's side through the gap)."""
    occ = OccupancyMap(np.array([-2.0, -4.0, 0.0]), (40, 40, 40), res)
    zs = np.arange(res / 2, 7.9, res)
    ys = np.arange(-2.9, 3.0, res)
    for y in ys:
        wall = [(x_wall + 0.1, y, z) for z in zs if not gap_lo <= z <= gap_hi]
        occ.integrate(np.array([x_wall - 1.0, y, 4.0]), np.array(wall), np.ones(len(wall), bool))
        for z in zs[(zs > gap_lo) & (zs < gap_hi)]:                  # level rays through the gap
            occ.integrate(np.array([x_wall - 1.0, y, z]), np.array([[x_wall + 2.0, y, z]]), np.zeros(1, bool))
    return occ


def _vertical(gap_hold, z_uav, z_slot, occ):
    cfg = ExpertConfig(gap_hold=gap_hold, debounce=1)
    expert = FusionExpert(cfg, vfh=_LevelVFH())
    state = np.array([0.0, 0.0, z_uav, 0.0, 0.3, 0.0, 0.0])
    view = SimpleNamespace(state=state, limits=LIM, occupancy=occ, neighbour_alive=np.zeros(0, bool))
    mem = _UAVMemory()
    obstacles, probs = occ.occupied_in_sphere(state[:3], 6.0)
    local = _Local(obstacles, probs, occ.resolution * math.sqrt(3) / 2, 6.0, 0, np.zeros((0, 3)), np.zeros((0, 3)))
    target = _Target(np.array([4.0, 0.0]), np.array([4.0, 0.0]), None, None)
    return expert._vertical_decision(view, mem, cfg, target, local, z_slot), mem


def test_gap_hold_keeps_the_gap_altitude_where_the_slot_altitude_is_too_near_the_gap_edge():
    occ = _wall_with_gap(3.3, 5.4)
    # the UAV inside the gap's band at 4.0 sees a level way; its slot altitude 3.65 is within r_uav + r_safe of the
    # gap's floor, so the gap rule finds it blocked and returns the nearest passable altitude of the gap
    on, mem = _vertical(True, 4.0, 3.65, occ)
    assert mem.mode == LEVEL and on.gap
    # known free 3.2..5.4 m (the leaf voxels 3.3..5.3): the lowest passable centre is 3.2 + r_uav + r_safe, plus
    # gap_margin; LEVEL holds that altitude with gain k_z instead of the slot's 3.65
    gap_z = 3.2 + LIM.r_uav + LIM.r_safe + ExpertConfig().gap_margin
    assert on.vz == pytest.approx(ExpertConfig().k_z * (gap_z - 4.0))
    off, _ = _vertical(False, 4.0, 3.65, occ)
    assert off.gap and off.vz == pytest.approx(ExpertConfig().k_z * (3.65 - 4.0))   # before: back down to the slot's
    clear, _ = _vertical(True, 4.3, 4.3, occ)                      # slot altitude passable: no gap rule, the slot's
    assert not clear.gap and clear.vz == pytest.approx(0.0)


def test_gap_altitude_looks_along_the_target_line_out_to_the_lookahead_only():
    from baselines.fusion.controller import _gap_altitude
    occ = _wall_with_gap(3.3, 5.4)                                  # the wall at x = 2.0..2.4, the UAV at x = 0
    view = SimpleNamespace(state=np.array([0.0, 0.0, 4.0, 0.0, 0.3, 0.0, 0.0]), limits=LIM, occupancy=occ)
    cfg = ExpertConfig()
    gap_z = 3.2 + LIM.r_uav + LIM.r_safe + cfg.gap_margin           # as in the gap_hold test above
    assert _gap_altitude(view, np.array([4.0, 0.0]), 3.65, cfg) == pytest.approx(gap_z)
    assert _gap_altitude(view, np.array([4.0, 0.0]), 4.3, cfg) is None          # the slot altitude passes: no gap
    assert _gap_altitude(view, np.array([1.5, 0.0]), 3.65, cfg) is None          # the target short of the wall
    assert _gap_altitude(view, np.array([0.0, 0.0]), 3.65, cfg) is None          # on the target
    assert _gap_altitude(view, np.array([4.0, 0.0]), 3.65, ExpertConfig(gap_lookahead=1.5)) is None   # too short
    assert _gap_altitude(view, np.array([4.0, 0.0]), 3.65, ExpertConfig(gap_lookahead=0)) is None     # ablation
