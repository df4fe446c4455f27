"""Followers reaching their slots (issue 13, "no frozen followers"): the known-gap altitude held in LEVEL mode
(``ExpertConfig.gap_hold``), the in-place turn into a wall's gap (rule ``gap_turn``), the stopping-distance
cap of a follower closing on a parking leader's slot (``slot_brake``), a wall unseen at the slot's altitude
(``gap_unseen_wall``); and the leader's arrival: the lookahead on the goal at the path's end (``path_to_goal``),
its speed when it flies alone (``solo_full_speed``)."""

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


def _wall_with_gap(gap_lo, gap_hi, x_wall=2.0, res=0.2, seen_from=0.0):
    """An own map that has seen a wall across y at x_wall..x_wall + 0.4, occupied outside [gap_lo, gap_hi] and
    known free inside it (level rays from the UAV's side through the gap); below ``seen_from`` it is unknown."""
    occ = OccupancyMap(np.array([-2.0, -4.0, 0.0]), (40, 40, 40), res)
    zs = np.arange(seen_from + res / 2, 7.9, res)
    ys = np.arange(-2.9, 3.0, res)
    for y in ys:
        wall = [(x_wall + 0.1, y, z) for z in zs if not gap_lo <= z <= gap_hi]
        occ.integrate(np.array([x_wall - 1.0, y, 4.0]), np.array(wall), np.ones(len(wall), bool))
        for z in zs[(zs > gap_lo) & (zs < gap_hi)]:                  # level rays through the gap
            occ.integrate(np.array([x_wall - 1.0, y, z]), np.array([[x_wall + 2.0, y, z]]), np.zeros(1, bool))
    return occ


def _gap_view(occ, z_uav):
    """The view ``_gap_altitude`` reads: a UAV at (0, 0, ``z_uav``) heading +x at 0.3 m/s, with own map ``occ``."""
    return SimpleNamespace(state=np.array([0.0, 0.0, z_uav, 0.0, 0.3, 0.0, 0.0]), limits=LIM, occupancy=occ)


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
    view, still, ahead = _gap_view(occ, 4.0), _UAVMemory(), np.array([4.0, 0.0])
    cfg = ExpertConfig()
    gap_z = 3.2 + LIM.r_uav + LIM.r_safe + cfg.gap_margin           # as in the gap_hold test above
    assert _gap_altitude(view, still, ahead, 3.65, cfg) == pytest.approx(gap_z)
    assert _gap_altitude(view, still, ahead, 4.3, cfg) is None                      # the slot altitude passes: no gap
    assert _gap_altitude(view, still, np.array([1.5, 0.0]), 3.65, cfg) is None      # the target short of the wall
    assert _gap_altitude(view, still, np.array([0.0, 0.0]), 3.65, cfg) is None      # on the target
    assert _gap_altitude(view, still, ahead, 3.65, ExpertConfig(gap_lookahead=1.5)) is None     # too short
    assert _gap_altitude(view, still, ahead, 3.65, ExpertConfig(gap_lookahead=0)) is None       # ablation


def test_gap_altitude_keeps_the_vertical_gust_standoff_off_the_gap_edge():
    """``vertical_margin``: under a vertical RMS drift of 0.2 m/s the altitude keeps wind_margin x 0.2 m/s less
    gust_allowance x r_safe more off the gap's floor; a drift whose standoff fills the gap takes its middle; still
    air or the switch off: the edge plus gap_margin, as before."""
    from baselines.fusion.controller import _gap_altitude
    occ = _wall_with_gap(3.3, 5.4)
    view, target, cfg = _gap_view(occ, 4.0), np.array([4.0, 0.0]), ExpertConfig()
    lowest = 3.2 + LIM.r_uav + LIM.r_safe                           # the lowest passable centre (test above)
    gusty = _UAVMemory(drift_z_ms=0.2 ** 2)
    standoff = cfg.wind_margin * 0.2 - cfg.gust_allowance * LIM.r_safe
    assert standoff > 0.0
    assert _gap_altitude(view, gusty, target, 3.65, cfg) == pytest.approx(lowest + cfg.gap_margin + standoff)
    assert _gap_altitude(view, gusty, target, 3.65, cfg.replace(vertical_margin=False)) == pytest.approx(
        lowest + cfg.gap_margin)
    assert _gap_altitude(view, _UAVMemory(), target, 3.65, cfg) == pytest.approx(lowest + cfg.gap_margin)
    highest = 5.4 - LIM.r_uav - LIM.r_safe                          # the known-free run ends at the voxel 5.3's top
    stormy = _UAVMemory(drift_z_ms=1.0)
    assert _gap_altitude(view, stormy, target, 3.65, cfg) == pytest.approx((lowest + highest) / 2)


def test_gap_unseen_wall_keeps_the_gap_when_the_wall_is_unseen_at_the_slot_altitude():
    from baselines.fusion.controller import _gap_altitude
    occ = _wall_with_gap(3.3, 5.4, seen_from=2.0)                   # the wall seen from 2.0 m up only
    view = _gap_view(occ, 4.0)
    gap_z = 3.2 + LIM.r_uav + LIM.r_safe + ExpertConfig().gap_margin  # as in the tests above
    # the slot 3 m below, where the map knows nothing: the band there holds no voxel, so without the flag the
    # level reads as clear and the UAV would descend along the wall; with it, the seen wall above the band blocks
    still, ahead = _UAVMemory(), np.array([4.0, 0.0])
    assert _gap_altitude(view, still, ahead, 1.0, ExpertConfig(gap_unseen_wall=False)) is None
    assert _gap_altitude(view, still, ahead, 1.0, ExpertConfig(gap_unseen_wall=True)) == pytest.approx(gap_z)
    open_below = _wall_with_gap(3.3, 5.4, seen_from=2.0)
    below = np.array([[2.3, y, z] for y in np.arange(-2.9, 3.0, 0.2) for z in (1.9, 1.7)])   # through the wall
    open_below.integrate(np.array([-1.0, 0.0, 1.8]), below, np.zeros(len(below), bool))   # free just below 2.0
    # the first known voxel from the band upward is free now (rays under the seen wall): no wall is assumed
    assert _gap_altitude(_gap_view(open_below, 4.0), still, ahead, 1.0, ExpertConfig(gap_unseen_wall=True)) is None
    # the UAV below the band: the voxels above the band toward it are not searched past its altitude
    low = _gap_view(occ, 0.8)
    assert _gap_altitude(low, still, ahead, 0.6, ExpertConfig(gap_unseen_wall=True)) is None


def _leader_on_path(goal, points, cfg):
    """A leader at the start of ``points`` (its A* path, just checked) with goal ``goal``; its ``_guidance``."""
    from baselines.astar import GlobalPath, Raster
    expert = FusionExpert(cfg)
    expert.raster = Raster(origin=(0.0, 0.0), shape=(40, 40), res=0.5)
    mem = _UAVMemory()
    mem.replans, mem.last_check_time, mem.path_found = 1, 0.0, True
    mem.path = GlobalPath(np.asarray(points, dtype=np.float64))
    view = SimpleNamespace(state=np.array([*points[0], 3.0, 0.0, 0.0, 0.0, 0.0]), limits=LIM, is_leader=True)
    return expert._guidance(view, mem, cfg, 0.0, np.asarray(goal, dtype=np.float64))


def test_path_to_goal_puts_the_lookahead_on_the_goal_in_the_path_end_cell():
    end = (5.25, 5.25)                                             # the centre of cell (10, 10) of the 0.5 m raster
    points = [(4.75, 5.25), end]
    goal = (5.45, 5.45)                                            # in that cell, 0.28 m from its centre
    assert np.allclose(_leader_on_path(goal, points, ExpertConfig(path_to_goal=False)), end)
    assert np.allclose(_leader_on_path(goal, points, ExpertConfig(path_to_goal=True)), goal)
    snapped = (5.55, 5.25)                                         # the goal in the next cell: the path was snapped
    assert np.allclose(_leader_on_path(snapped, points, ExpertConfig(path_to_goal=True)), end)
    long = [(0.25, 5.25), (1.25, 5.25), (2.25, 5.25), (3.25, 5.25), (4.25, 5.25), end]
    ahead = _leader_on_path(goal, long, ExpertConfig(path_to_goal=True))  # lookahead short of the end: a path node
    assert ahead.tolist() in [list(p) for p in long[:-1]]


class _StraightOn(FusionExpert):
    """The expert with its A* guidance replaced by a point 3 m ahead: ``_leader_target``'s speed cap alone."""

    def _guidance(self, view, mem, cfg, t, goal_xy):
        return view.state[:2] + np.array([3.0, 0.0])


@pytest.mark.parametrize("followers", [0, 1])
def test_solo_full_speed_lifts_the_followers_margin_from_a_leader_flying_alone(followers):
    cfg_on, cfg_off = ExpertConfig(solo_full_speed=True), ExpertConfig(solo_full_speed=False)
    states = np.array([[-2.0, 0.0, 3.0, 0.0, 0.5, 0.0, 0.0]] * followers).reshape(-1, 7)   # on its slot (-2, 0)
    view = SimpleNamespace(state=np.array([0.0, 0.0, 3.0, 0.0, 0.5, 0.0, 0.0]), limits=LIM,
                           goal=np.array([20.0, 0.0, 3.0]), config=EnvConfig(),
                           offsets=np.array([[0.0, 0.0, 0.0], [-2.0, 0.0, 0.0]]),
                           neighbour_ids=np.arange(1, 1 + followers), neighbour_states=states,
                           neighbour_alive=np.ones(followers, bool))
    caps = [_StraightOn(cfg)._leader_target(view, _UAVMemory(), cfg, 0.0)[2] for cfg in (cfg_on, cfg_off)]
    margin = ExpertConfig().leader_speed_cap * LIM.v_max
    assert caps == pytest.approx([LIM.v_max, margin] if followers == 0 else [margin, margin])
