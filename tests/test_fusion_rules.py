"""The fusion expert's command rules (``baselines.fusion.rules``): their order, and each one's known answer
on a constructed command record; and the planners injected into the controller."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from baselines.dwa import dwa_plan
from baselines.fusion import ExpertConfig, FusionExpert
from baselines.fusion.controller import _UAVMemory
from baselines.fusion.kernels import braking_arc_clearance
from baselines.fusion.rules import (RULES, Command, Cycle, braking_fallback, braking_share, braking_turn, dock_approach,
                                    dock_turn,
                                    drift_guard, drift_persistence, emergency_escape, fence_clearance, gust_speed,
                                    gust_radii, gust_standoff, rest_standoff, reverse_turn, station_keep,
                                    vertical_separation, wind_estimate, wind_margin)
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

    def occupied_within(self, pos, radius):
        return len(self.occupied_in_sphere(np.asarray(pos), radius)[0]) > 0


def view(state=(0.0, 0.0, 3.0, 0.0, 0.0, 0.0, 0.0), is_leader=True, goal=(10.0, 0.0, 3.0), leader_speed=0.5,
         voxels=(), alive=(), index=0, neighbour_ids=(), limits=LIM):
    return SimpleNamespace(state=np.array(state, dtype=np.float64), is_leader=is_leader,
                           goal=np.array(goal, dtype=np.float64), limits=limits, config=EnvConfig(),
                           leader_state=np.array([0.0, 0.0, 3.0, 0.0, leader_speed, 0.0, 0.0]),
                           occupancy=FakeMap(voxels), neighbour_alive=np.array(alive, dtype=bool), index=index,
                           neighbour_ids=np.array(neighbour_ids, dtype=np.int64))


def cycle(v, mem=None, goal=(10.0, 0.0), lookahead=(10.0, 0.0), heading_goal=None, admissible=True,
          vfh=None, movers=np.zeros((0, 3)), cfg=CFG, obstacles=np.zeros((0, 3)), radius=0.0, docking=False,
          dwa_v=0.0, dwa_clearance=0.0):
    dwa = SimpleNamespace(admissible=admissible, v=dwa_v, clearance=dwa_clearance)     # DWA's choice
    return Cycle(view=v, mem=mem or _UAVMemory(), cfg=cfg, goal=np.array(goal), lookahead=np.array(lookahead),
                 heading_goal=np.array(goal if heading_goal is None else heading_goal), dwa=dwa, vfh=vfh,
                 movers_pos=movers, movers_vel=np.zeros_like(movers), obstacles=np.asarray(obstacles, dtype=float),
                 radii=np.full(len(obstacles), radius), docking=docking)


def test_rules_are_named_and_ordered():
    assert [r.__name__ for r in RULES] == ["braking_fallback", "dock_turn", "dock_approach", "reverse_turn",
                                           "gap_turn", "braking_turn", "drift_guard", "vertical_separation",
                                           "emergency_escape"]
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
    dock_turn(far, cycle(view(goal=(0.0, 5.0, 3.0))))               # abeam but beyond dock_radius
    assert (far.v, far.turning) == (0.3, False)


def test_dock_turn_of_a_follower_needs_a_parked_leader_and_its_own_rest():
    follower = dict(is_leader=False, goal=(30.0, 0.0, 3.0))
    cmd = Command(0.0, 0.0, 0.0)
    dock_turn(cmd, cycle(view(leader_speed=0.0, **follower), goal=(-0.5, 2.0)))
    assert cmd.turning and cmd.w == W_MAX
    for moving in (dict(leader_speed=0.5), dict(leader_speed=0.0, state=(0, 0, 3, 0, 0.4, 0, 0))):
        cmd = Command(0.0, 0.0, 0.0)
        dock_turn(cmd, cycle(view(**moving, **follower), goal=(-0.5, 2.0)))
        assert not cmd.turning


def test_dock_turn_stops_a_creeping_follower_circling_its_slot():
    """A follower creeping at 0.1 m/s round a parked slot 0.7 m away, 80 degrees off its nose (forest seed 0 circled
    so for 25 s): it stops within e_f / 2 at a_max (0.1^2 < 0.2 x 0.5), so it turns in place; at 0.4 m/s it would not
    stop within e_f / 2 and DWA keeps its arc; with ``dock_turn_speed="stopped"`` only a follower at rest turns."""
    follower = dict(is_leader=False, goal=(30.0, 0.0, 3.0), leader_speed=0.0)
    slot = (0.7 * math.cos(math.radians(-80.0)), 0.7 * math.sin(math.radians(-80.0)))
    for speed, cfg, turns in ((0.1, CFG, True), (0.31, CFG, True), (0.33, CFG, False),
                              (0.1, CFG.replace(dock_turn_speed="stopped"), False)):
        cmd = Command(speed, 0.0, 0.0)
        dock_turn(cmd, cycle(view(state=(0, 0, 3, 0, speed, 0, 0), **follower), goal=slot, cfg=cfg))
        assert cmd.turning == turns
        if turns:
            assert cmd.v == 0.0 and cmd.w == -W_MAX


def test_dock_turn_of_a_follower_turns_toward_the_heading_goal_dwa_steers_for():
    """A follower at rest with its slot ahead but 3D VFH+'s detour (DWA's heading goal) behind-left turns toward the
    detour; turning toward the slot behind a tree, a follower at rest against the tree turned to and fro with DWA."""
    follower = dict(is_leader=False, goal=(30.0, 0.0, 3.0), leader_speed=0.0)
    cmd = Command(0.0, -0.1, 0.0)
    dock_turn(cmd, cycle(view(**follower), goal=(2.0, 0.1), heading_goal=(-0.5, 2.0)))
    assert cmd.turning and cmd.v == 0.0 and cmd.w == W_MAX
    cmd = Command(0.0, -0.1, 0.0)
    dock_turn(cmd, cycle(view(**follower), goal=(-0.5, 2.0), heading_goal=(2.0, 0.1)))
    assert not cmd.turning and cmd.w == -0.1                         # the detour lies ahead: DWA's command stands
    cmd = Command(0.0, -0.1, 0.0)                                    # dock_turn_toward="target": the rule before
    dock_turn(cmd, cycle(view(**follower), goal=(-0.5, 2.0), heading_goal=(2.0, 0.1),
                         cfg=CFG.replace(dock_turn_toward="target")))
    assert cmd.turning and cmd.w == W_MAX


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


def test_drift_guard_flies_away_from_a_near_obstacle_only_without_an_admissible_sample():
    near = dict(obstacles=[[0.5, 0.0, 3.0]], radius=0.1)           # 0.1 m clearance, straight ahead
    cmd = Command(0.0, 0.0, 0.0)
    drift_guard(cmd, cycle(view(), admissible=True, **near))       # DWA found a way: it stands
    assert (cmd.v, cmd.w) == (0.0, 0.0)
    drift_guard(cmd, cycle(view(), admissible=False, **near))      # away is behind: turn, no speed
    assert (cmd.v, cmd.w) == (0.0, W_MAX)
    behind = Command(0.0, 0.0, 0.0)
    mem = _UAVMemory(wind=np.array([-0.2, 0.0]))                   # 0.2 m/s blowing toward the obstacle
    drift_guard(behind, cycle(view(), mem, admissible=False, obstacles=[[-0.5, 0.0, 3.0]], radius=0.1))
    assert behind.v == pytest.approx(CFG.guard_speed + 0.2) and behind.w == 0.0
    far = Command(0.0, 0.0, 0.0)
    drift_guard(far, cycle(view(), admissible=False, obstacles=[[-2.0, 0.0, 3.0]], radius=0.1))
    assert far.v == 0.0                                            # 1.6 m clearance: brake as before
    above = Command(0.0, 0.0, 0.0)
    drift_guard(above, cycle(view(), admissible=False, obstacles=[[0.1, 0.0, 3.5]], radius=0.1))
    assert above.v == 0.0                                          # above: the emergency escape's case


def test_vertical_separation_moves_the_higher_uav_up_and_the_lower_down():
    two = dict(alive=[True], neighbour_ids=[1])
    cmd = Command(0.3, 0.0, 0.0)
    vertical_separation(cmd, cycle(view(**two), movers=np.array([[2.0, 0.0, 3.0]])))   # 2 m away: nothing
    assert cmd.vz == 0.0
    vertical_separation(cmd, cycle(view(**two), movers=np.array([[0.6, 0.0, 2.9]])))   # it is lower: climb
    assert (cmd.v, cmd.vz) == (0.3, LIM.vz_max)
    vertical_separation(cmd, cycle(view(**two), movers=np.array([[0.6, 0.0, 3.0]])))   # level: index 0 descends
    assert cmd.vz == -LIM.vz_max
    blocked = Command(0.3, 0.0, 0.0)
    vertical_separation(blocked, cycle(view(voxels=[[0.0, 0.0, 2.5]], **two), movers=np.array([[0.6, 0.0, 3.0]])))
    assert blocked.vz == LIM.vz_max                                # a voxel below: the other way
    floor = Command(0.3, 0.0, 0.0)
    low = view(state=(0.0, 0.0, 0.6, 0.0, 0.0, 0.0, 0.0), **two)
    vertical_separation(floor, cycle(low, movers=np.array([[0.6, 0.0, 0.6]])))
    assert floor.vz == LIM.vz_max                                  # at the band's floor: up


def test_vertical_separation_parts_two_uavs_that_each_see_the_other_below():
    """Climbing together, each UAV sees the other's predicted broadcast a few millimetres below itself: within
    ``separation_tie`` the index decides, so one climbs and the other descends; without the tie both climbed."""
    a = view(state=(0.0, 0.0, 3.000, 0.0, 0.0, 0.0, 0.3), alive=[True], index=0, neighbour_ids=[1])
    b = view(state=(0.6, 0.0, 3.001, 0.0, 0.0, 0.0, 0.3), alive=[True], index=1, neighbour_ids=[0])
    sees_a, sees_b = np.array([[0.6, 0.0, 2.995]]), np.array([[0.0, 0.0, 2.996]])
    for cfg, expected in ((CFG, (-LIM.vz_max, LIM.vz_max)), (CFG.with_checked(separation_tie=0.0), (LIM.vz_max,) * 2)):
        cmd_a, cmd_b = Command(0.3, 0.0, 0.3), Command(0.3, 0.0, 0.3)
        vertical_separation(cmd_a, cycle(a, movers=sees_a, cfg=cfg))
        vertical_separation(cmd_b, cycle(b, movers=sees_b, cfg=cfg))
        assert (cmd_a.vz, cmd_b.vz) == expected
    apart = Command(0.3, 0.0, 0.0)                     # beyond the tie the altitudes decide, whatever the index
    vertical_separation(apart, cycle(a, movers=np.array([[0.6, 0.0, 2.8]])))
    assert apart.vz == LIM.vz_max


def test_braking_arc_clearance_knows_the_stopping_distance_and_the_turn():
    """Braking straight from 1 m/s at 0.2 m/s^2 (dt 0.1 s): v_k = 1 - 0.02 k for k = 1..50, so the UAV stops
    0.1 x (50 - 0.02 x 1275) = 2.45 m on; a ball of radius 0.1 at x = 3 is then 0.55 - 0.1 away, less r_uav."""
    lim = LIM.replace(a_max=0.2, dt=0.1, v_min=0.0)
    state = np.array([0.0, 0.0, 3.0, 0.0, 1.0, 0.0, 0.0])
    ball = np.array([[3.0, 0.0, 3.0]])

    def arc(w_c, obstacles=ball, radius=0.1, s=state):
        return braking_arc_clearance(s, w_c, lim.dt, lim.v_min, lim.v_max, lim.a_max, lim.w_max, lim.dw_max,
                                     obstacles, np.full(len(obstacles), radius), lim.r_uav)

    assert arc(0.0) == pytest.approx(0.55 - 0.1 - lim.r_uav, abs=1e-9)
    left = np.array([[1.5, 0.8, 3.0]])                  # beside the way, to the left: a left turn comes nearer
    assert arc(lim.w_max, left) < arc(0.0, left) < arc(-lim.w_max, left)
    assert arc(0.0, np.array([[9.0, 0.0, 3.0]])) == math.inf       # beyond the stopping distance: not counted
    at_rest = state.copy()
    at_rest[4] = 0.0
    assert arc(0.0, s=at_rest) == math.inf


def test_braking_turn_swerves_a_coasting_turn_off_a_wall():
    """A follower at 0.8 m/s whose turn in place swings its nose toward a wall on its right while it coasts
    (the arc would touch it) flies the turn away from it; left alone where the commanded arc stays clear, when
    DWA's own sample stands, and with the rule off."""
    wall = np.array([[x, -0.9, 3.0] for x in np.arange(0.0, 4.0, 0.2)])      # a wall 0.9 m to the right
    coasting = view(state=(0.0, 0.0, 3.0, 0.0, 0.8, 0.0, 0.0), is_leader=False)
    cmd = Command(0.0, -W_MAX, 0.0, turning=True)              # reverse_turn: the short way round, to the right
    braking_turn(cmd, cycle(coasting, obstacles=wall, radius=0.1, cfg=CFG.with_checked(braking_turn=False)))
    assert cmd.w == -W_MAX
    braking_turn(cmd, cycle(coasting, obstacles=wall, radius=0.1))
    assert cmd.w == W_MAX and cmd.v == 0.0                      # away from the wall, still braking
    far = wall - np.array([0.0, 3.0, 0.0])                      # the wall 3.9 m off: the right turn is clear
    cmd = Command(0.0, -W_MAX, 0.0, turning=True)
    braking_turn(cmd, cycle(coasting, obstacles=far, radius=0.1))
    assert cmd.w == -W_MAX
    dwa_choice = Command(0.5, -W_MAX, 0.0)                      # DWA's own admissible sample: not a rule's brake
    braking_turn(dwa_choice, cycle(coasting, obstacles=wall, radius=0.1))
    assert dwa_choice.w == -W_MAX


UNOPPOSED = LIM.replace(wind_authority=0.0)     # the airframe the wind carries whole (drift_persistence = 1)


def test_station_keep_flies_back_and_against_the_wind_and_rests_in_still_air():
    mem = _UAVMemory()
    # at the point, still air
    held = station_keep(view(limits=UNOPPOSED), mem, CFG, np.array([0.1, 0.0]), 0.5, math.inf)
    assert (held.v, held.w) == (0.0, W_MAX) and mem.held                                # stops, turns to heading
    mem.held = False
    # 1 m past: turn, no speed
    behind = station_keep(view(limits=UNOPPOSED), mem, CFG, np.array([-1.0, 0.0]), 0.0, math.inf)
    assert (behind.v, behind.w) == (0.0, W_MAX)
    mem.wind = np.array([-0.3, 0.0])                                      # a 0.3 m/s headwind
    ahead = station_keep(view(limits=UNOPPOSED), mem, CFG, np.array([1.0, 0.0]), 0.0, math.inf)
    assert ahead.v == pytest.approx(CFG.k_hold * 1.0 + 0.3) and ahead.w == 0.0
    on_point = station_keep(view(limits=UNOPPOSED), mem, CFG, np.array([0.0, 0.0]), 0.0, math.inf)   # on the point: fly
    assert on_point.v == pytest.approx(0.3) and on_point.w == 0.0                           # against the wind
    mem.wind = np.array([0.0, 0.3])                                       # crosswind from the right: nose into it
    cross = station_keep(view(limits=UNOPPOSED), mem, CFG, np.array([0.0, 0.0]), 0.0, math.inf)
    assert cross.v == pytest.approx(0.0, abs=1e-12) and cross.w == -W_MAX


def test_station_keep_counters_only_the_drift_the_autopilot_leaves_and_holds_until_released():
    mem = _UAVMemory(wind=np.array([-0.3, 0.0]))                          # a 0.3 m/s head drift, default airframe
    ahead = station_keep(view(), mem, CFG, np.array([1.0, 0.0]), 0.0, math.inf)
    share = drift_persistence(LIM, 1.0 / CFG.k_hold)                       # 0.5 / 2 (1 - e^-4) = 0.2454
    assert share == pytest.approx(0.25 * (1.0 - math.exp(-4.0)))
    assert ahead.v == pytest.approx(CFG.k_hold * 1.0 + 0.3 * share) and not mem.held
    rest = _UAVMemory()
    assert station_keep(view(), rest, CFG, np.array([0.1, 0.0]), 0.0, math.inf).v == 0.0 and rest.held
    for off in (0.3, CFG.hold_release - 1e-9):                            # carried off, within hold_release: held
        cmd = station_keep(view(), rest, CFG, np.array([off, 0.0]), 0.0, math.inf)
        assert (cmd.v, cmd.w) == (0.0, 0.0) and rest.held
    # released: flies back
    out = station_keep(view(), rest, CFG, np.array([CFG.hold_release + 0.05, 0.0]), 0.0, math.inf)
    assert not rest.held and out.v == pytest.approx(CFG.k_hold * (CFG.hold_release + 0.05))
    fresh = _UAVMemory()                                                  # not yet held: 0.3 m is outside hold_radius
    assert station_keep(view(), fresh, CFG, np.array([0.3, 0.0]), 0.0, math.inf).v > 0.0 and not fresh.held


def test_station_keep_rests_only_where_clear_of_the_gust_standoff():
    gusty = _UAVMemory(drift_ms=0.25)                                     # RMS drift 0.5 m/s
    need = rest_standoff(gusty, CFG, LIM.r_safe)
    assert need == pytest.approx(LIM.r_safe + CFG.rest_gust_time * 0.5 - CFG.gust_allowance * LIM.r_safe)
    assert rest_standoff(_UAVMemory(), CFG, LIM.r_safe) == LIM.r_safe     # still air: r_safe
    point = np.array([0.5, 0.0])                                          # within the gusts' rest radius
    cmd = station_keep(view(), gusty, CFG, point, 0.0, need + 0.01)
    assert gusty.held and cmd.v == 0.0                                    # clear: rests
    cmd = station_keep(view(), gusty, CFG, point, 0.0, need - 0.01)
    assert not gusty.held and cmd.v == pytest.approx(CFG.k_hold * 0.5)    # carried near a voxel: flies back
    cmd = station_keep(view(), gusty, CFG, point, 0.0, need + 0.01)
    assert gusty.held and cmd.v == 0.0                                    # clear again: rests


def test_station_keep_in_gusts_rests_within_the_gust_excursion():
    gusty = _UAVMemory(drift_ms=0.25)                                     # RMS drift 0.5 m/s > vane_wind
    slack = CFG.hold_gust_time * 0.5
    off = CFG.hold_radius + slack - 0.01                                  # still air would fly back from here
    cmd = station_keep(view(), gusty, CFG, np.array([off, 0.0]), 0.3, math.inf)
    assert gusty.held and cmd.v == 0.0 and cmd.w == pytest.approx(0.3)    # rests, turns to the park heading only
    cmd = station_keep(view(), gusty, CFG, np.array([CFG.hold_release + slack - 0.01, 0.0]), 0.0, math.inf)
    assert gusty.held and cmd.v == 0.0
    cmd = station_keep(view(), gusty, CFG, np.array([CFG.hold_release + slack + 0.01, 0.0]), 0.0, math.inf)
    assert not gusty.held and cmd.v > 0.0                                 # carried beyond it: flies back
    breeze = _UAVMemory(drift_ms=0.05 ** 2)                               # RMS drift below vane_wind: still-air radii
    assert station_keep(view(), breeze, CFG, np.array([off, 0.0]), 0.0, math.inf).v > 0.0 and not breeze.held
    assert station_keep(view(), _UAVMemory(drift_ms=0.25), CFG.replace(hold_gust_time=0.0),   # the still-air rule
                        np.array([off, 0.0]), 0.0, math.inf).v > 0.0


def test_drift_persistence_known_answers():
    assert drift_persistence(UNOPPOSED, 3.0) == 1.0                       # the wind carries the UAV whole
    assert drift_persistence(LIM.replace(wind_rejection_tau=0.0), 3.0) == 0.0   # an instant autopilot
    assert drift_persistence(LIM, math.inf) == 0.0
    tau = LIM.wind_rejection_tau                                          # d tau (1 - e^(-T/tau)) / T
    assert drift_persistence(LIM, 3.0) == pytest.approx(tau / 3.0 * (1.0 - math.exp(-3.0 / tau)))
    assert drift_persistence(LIM, 1e-6) == pytest.approx(1.0, abs=1e-5)  # over an instant all of it


def test_dock_approach_flies_the_home_in_law_only_when_docking():
    tail = np.array([0.2, 0.0])                                           # 0.2 m/s from behind
    cmd = Command(0.6, 0.2, 0.1)
    dock_approach(cmd, cycle(view(goal=(2.0, 0.0, 3.0)), _UAVMemory(wind=tail), docking=False))
    assert (cmd.v, cmd.w, cmd.vz) == (0.6, 0.2, 0.1)                      # not docking: DWA's command stands
    dock_approach(cmd, cycle(view(goal=(2.0, 0.0, 3.0)), docking=True))   # still air: DWA's command stands
    assert (cmd.v, cmd.w, cmd.vz) == (0.6, 0.2, 0.1)
    dock_approach(cmd, cycle(view(goal=(2.0, 0.0, 3.0)), _UAVMemory(wind=tail), docking=True))   # 2 m ahead
    assert (cmd.v, cmd.w, cmd.vz) == (pytest.approx(CFG.k_hold * 2.0), 0.0, 0.1)
    abeam = Command(0.6, 0.0, 0.0)
    dock_approach(abeam, cycle(view(goal=(0.0, 2.0, 3.0)), _UAVMemory(wind=tail), docking=True))  # 90 deg left
    assert (abeam.v, abeam.w, abeam.turning) == (0.0, W_MAX, True)
    near = Command(0.6, 0.0, 0.0)                                         # 30 deg off, 1 m: pure-pursuit cap
    dock_approach(near, cycle(view(goal=(math.cos(0.5236), math.sin(0.5236), 3.0)), _UAVMemory(wind=tail),
                              docking=True))
    assert near.v == pytest.approx(min(CFG.k_hold * math.cos(0.5236), W_MAX * 1.0 / (2 * math.sin(0.5236))))


def test_wind_estimate_is_the_drift_the_commands_do_not_explain():
    mem = _UAVMemory()
    wind_estimate(view(state=(0.0, 0.0, 3.0, 0.0, 0.5, 0.0, 0.0)), mem, CFG)
    assert mem.wind.tolist() == [0.0, 0.0]                                  # no previous pose yet
    dt = LIM.dt
    # 0.5 m/s along x commanded; it moved 0.5 dt + 0.2 dt along x and 0.1 dt along y
    wind_estimate(view(state=(0.7 * dt, 0.1 * dt, 3.0, 0.0, 0.5, 0.0, 0.0)), mem, CFG)
    gain = min(1.0, dt / CFG.wind_tau)
    assert mem.wind == pytest.approx([0.2 * gain, 0.1 * gain])
    assert mem.drift_ms == pytest.approx(min(1.0, dt / CFG.gust_tau) * (0.2 ** 2 + 0.1 ** 2))
    assert gust_speed(mem) == pytest.approx(math.sqrt(mem.drift_ms))
    still = _UAVMemory()
    for k in range(3):                                                      # exactly the model: no wind
        wind_estimate(view(state=(0.5 * k * dt, 0.0, 3.0, 0.0, 0.5, 0.0, 0.0)), still, CFG)
    assert still.wind == pytest.approx([0.0, 0.0], abs=1e-12) and still.drift_ms == pytest.approx(0.0, abs=1e-20)


def test_wind_estimate_keeps_the_vertical_drift_apart():
    """The climb the state's vz does not explain is the vertical drift: its mean square goes into ``drift_z_ms`` (with
    ``gust_tau``), not into the horizontal wind or ``drift_ms``."""
    mem, dt = _UAVMemory(), LIM.dt
    wind_estimate(view(state=(0.0, 0.0, 3.0, 0.0, 0.0, 0.0, 0.3)), mem, CFG)
    wind_estimate(view(state=(0.0, 0.0, 3.0 + 0.4 * dt, 0.0, 0.0, 0.0, 0.3)), mem, CFG)     # 0.3 commanded, 0.4 flown
    assert mem.drift_z_ms == pytest.approx(min(1.0, dt / CFG.gust_tau) * 0.1 ** 2)
    assert mem.drift_ms == pytest.approx(0.0, abs=1e-20) and mem.wind.tolist() == [0.0, 0.0]
    lifted = _UAVMemory(drift_z_ms=0.2 ** 2)
    assert gust_standoff(lifted, CFG, 2.0, LIM.r_safe, vertical=True) == pytest.approx(0.4 - CFG.gust_allowance * 0.2)
    assert gust_standoff(lifted, CFG, 2.0, LIM.r_safe) == 0.0                             # no horizontal drift
    assert wind_margin(lifted, CFG, 0.1, LIM.r_safe, vertical=True) == pytest.approx(CFG.wind_margin_share * 0.1)
    assert gust_standoff(_UAVMemory(drift_ms=1.0), CFG, 2.0, LIM.r_safe, vertical=True) == 0.0


def test_gust_radii_grow_by_the_horizontal_margin_only_where_a_horizontal_drift_reaches():
    """``vertical_margin``: a voxel within the vertical margin + radius + r_uav of the altitudes the rollouts fly (here
    3.0 m level, or climbing 1.5 m) grows by the horizontal margin, one above or below that band by the vertical one
    (the floor and ceiling of a wall's gap, wall-gap v1-dev gusty); equal margins: every voxel alike, as before."""
    voxels = np.array([[1.0, 0.0, 3.0], [1.0, 0.0, 3.55], [1.0, 0.0, 3.65], [0.0, 0.0, 2.35], [0.0, 0.0, 4.4]])
    r_uav, radius = 0.3, 0.1                                        # the band: 3.0 -+ (0.2 + 0.1 + 0.3) m
    assert gust_radii(3.0, 0.0, voxels, radius, 0.8, 0.2, r_uav) == pytest.approx([0.9, 0.9, 0.3, 0.3, 0.3])
    assert gust_radii(3.0, 1.5, voxels, radius, 0.8, 0.2, r_uav) == pytest.approx([0.9, 0.9, 0.9, 0.3, 0.9])
    assert gust_radii(3.0, -1.5, voxels, radius, 0.8, 0.2, r_uav) == pytest.approx([0.9, 0.9, 0.3, 0.9, 0.3])
    assert np.all(gust_radii(3.0, 0.0, voxels, radius, 0.5, 0.5, r_uav) == 0.6)
    assert gust_radii(3.0, 0.0, np.zeros((0, 3)), radius, 0.8, 0.2, r_uav).shape == (0,)


def test_gust_speed_is_the_rms_drift_of_alternating_gusts():
    """Drift alternating +-0.4 m/s along y: the mean wind estimate stays near zero, the gust speed nears 0.4."""
    mem, dt = _UAVMemory(), LIM.dt
    y = 0.0
    for k in range(400):
        y += (0.4 if k % 2 else -0.4) * dt
        wind_estimate(view(state=(0.0, y, 3.0, 0.0, 0.0, 0.0, 0.0)), mem, CFG)
    assert abs(mem.wind[1]) < 0.05 and gust_speed(mem) == pytest.approx(0.4, rel=0.01)


def test_braking_share_rises_with_the_gusts():
    """Still air: the config's share (the expert's 0, Fox's free-arc form); the share grows with the RMS drift and is
    1 (the clearance form of spec (b6)) from ``gust_braking`` m/s on; a config share above the gust share is kept."""
    assert CFG.dwa.brake_share == 0.0 and braking_share(_UAVMemory(), CFG) == 0.0
    half = _UAVMemory(drift_ms=(0.5 * CFG.gust_braking) ** 2)
    assert braking_share(half, CFG) == pytest.approx(0.5)
    assert braking_share(_UAVMemory(drift_ms=(2 * CFG.gust_braking) ** 2), CFG) == 1.0
    assert braking_share(half, ExpertConfig.planar("DWA")) == 1.0          # the planar baselines keep spec (b6)


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

    frozen = FusionExpert(ExpertConfig(dock_approach=False), dwa=frozen_dwa)   # (docking flies without DWA)
    assert np.all(_flight(frozen, 10)[:, :, 0] == -1.0)                 # speed action -1: v = 0


def test_planners_must_be_callable():
    with pytest.raises(ValueError, match="dwa: expected a callable"):
        FusionExpert(dwa="idwa")


def test_hold_point_keeps_the_clearance_a_gust_takes_to_turn_into():
    """A UAV with no way to its goal 1 m from the world's x = 0 bound (0.7 m clearance) holds where it is in still
    air (r_safe suffices); drifting at 0.25 m/s (``rules.gust_speed``) it needs r_safe + hold_drift_time x 0.25 =
    1.325 m and holds at the nearest grid point that has it, 0.8 m farther in (grid ``geofence_spacing`` = 0.4 m);
    a post there moves it on, and with nowhere clear enough it holds at the clearest point it can reach."""
    def holding(wind, voxels=()):
        v = view(state=(1.0, 3.0, 3.0, 0.0, 0.0, 0.0, 0.0), voxels=voxels)
        v.bounds_lo, v.bounds_hi = np.array([0.0, 0.0, 0.0]), np.array([20.0, 6.0, 12.0])
        mem = _UAVMemory(drift_ms=float(np.dot(wind, wind)))
        return FusionExpert._hold_point(v, CFG, FusionExpert._hold_margin(v, mem, CFG))
    assert holding([0.0, 0.0]).tolist() == [1.0, 3.0]
    margin = LIM.r_safe + CFG.hold_drift_time * 0.25
    assert margin == pytest.approx(1.325)
    assert holding([0.25, 0.0]) == pytest.approx([1.8, 3.0])
    xy = holding([0.25, 0.0], voxels=[[2.2, 3.0, 3.0]])
    assert np.hypot(xy[0] - 2.2, xy[1] - 3.0) - LIM.r_uav >= margin and xy[0] - LIM.r_uav >= margin
    assert np.hypot(xy[0] - 1.0, xy[1] - 3.0) <= CFG.hold_search
    xy = holding([1.0, 0.0])                       # 4.7 m needed, 2.7 m at best in a 6 m wide world: the nearest
    assert xy == pytest.approx([3.0, 3.0])           # point as clear from x = 0 as from the side bounds


def _wall_clearance(path, blocked, raster):
    """The smallest distance from a path's points to the centres of the blocked cells."""
    centres = (np.argwhere(blocked) + 0.5) * raster.res + np.asarray(raster.origin)
    return float(np.min(np.linalg.norm(path.points[:, None, :] - centres[None], axis=2)))


def test_search_keeps_path_margin_off_walls_and_falls_back_to_a_narrow_way():
    from baselines.astar import Raster, plan_path
    raster = Raster((0.0, 0.0), CFG.astar.res_g, (40, 20))
    expert = FusionExpert()
    expert.raster = raster
    h_b = LIM.r_uav + LIM.r_safe
    start, goal = np.array([2.0, 2.0]), np.array([18.0, 2.0])
    wall = np.zeros(raster.shape, bool)
    wall[20, :12] = True                                             # a wall from y = 0 to 6 m, open above
    kept = expert._search(wall, start, goal, LIM, CFG.path_margin, CFG.margin_detour)
    plain = plan_path(wall, raster, start, goal, h_b, CFG.astar)
    assert _wall_clearance(kept, wall, raster) > h_b + CFG.path_margin                 # 1.29 m
    assert _wall_clearance(plain, wall, raster) < h_b + CFG.path_margin                # (d1) alone: 0.87 m
    door = np.zeros(raster.shape, bool)
    door[20, :] = True
    door[20, 9:12] = False                                           # a 1.5 m door: too narrow for the margin
    assert plan_path(door, raster, start, goal, h_b + CFG.path_margin, CFG.astar) is None
    narrow = expert._search(door, start, goal, LIM, CFG.path_margin, CFG.margin_detour)
    at_wall = narrow.points[np.abs(narrow.points[:, 0] - 10.25) < 0.3]
    assert len(at_wall) and np.all((at_wall[:, 1] > 4.5) & (at_wall[:, 1] < 6.0))   # through the door
    assert expert._search(door, start, goal, LIM, 0.0, CFG.margin_detour) is not None
    door[20, 10] = True                                              # closed: no path at all
    assert expert._search(door, start, goal, LIM, CFG.path_margin, CFG.margin_detour) is None
    expert.raster = Raster((0.0, 0.0), CFG.astar.res_g, (40, 30))
    detour = np.zeros(expert.raster.shape, bool)
    detour[20, :25] = True
    detour[20, 9:12] = False                                         # the narrow door, and a wide way 12 m longer
    through_door = expert._search(detour, start, goal, LIM, CFG.path_margin, CFG.margin_detour)
    round_wall = expert._search(detour, start, goal, LIM, CFG.path_margin, math.inf)
    assert through_door.points[:, 1].max() < 6.0 and round_wall.points[:, 1].max() > 12.5
    assert round_wall.length > through_door.length + CFG.margin_detour
    near_wall = np.array([10.0 - 0.75, 2.0])                        # 0.75 m before the wall: free for (d1) only
    to_wall = expert._search(detour, start, near_wall, LIM, CFG.path_margin, CFG.margin_detour)
    assert np.allclose(to_wall.points[-1], [9.25, 2.25])             # ends in the goal's cell, not snapped off


def test_drift_guard_clearance_grows_with_the_gust_speed():
    gusty = _UAVMemory(drift_ms=0.25)                              # RMS drift 0.5 m/s
    near = dict(admissible=False, obstacles=[[-0.9, 0.0, 3.0]], radius=0.1)   # 0.5 m clearance, behind
    off = ExpertConfig(guard_gust_time=0.0, guard_hover_speed=0.0)
    cfg = ExpertConfig(guard_gust_time=1.0, guard_hover_speed=0.1, gust_allowance=0.0)   # 0.4 + 1.0 x 0.5 = 0.9 m
    still = Command(0.0, 0.0, 0.0)
    drift_guard(still, cycle(view(), gusty, cfg=off, **near))      # without: 0.5 m >= 0.4 m, it brakes as before
    assert (still.v, still.w) == (0.0, 0.0)
    flees = Command(0.0, 0.0, 0.0)
    drift_guard(flees, cycle(view(), gusty, cfg=cfg, **near))      # inside 0.9 m: flies off, away is ahead
    assert flees.v == pytest.approx(cfg.guard_speed) and flees.w == 0.0
    calm = Command(0.0, 0.0, 0.0)
    drift_guard(calm, cycle(view(), _UAVMemory(), cfg=cfg, **near))   # no gusts: the plain 0.4 m
    assert (calm.v, calm.w) == (0.0, 0.0)


def test_drift_guard_moves_a_hovering_uav_off_an_obstacle_in_gusts_even_when_dwa_finds_a_way():
    gusty = _UAVMemory(drift_ms=0.25)                              # RMS drift 0.5 m/s: gust standoff 0.5 m
    near = dict(admissible=True, obstacles=[[-0.8, 0.0, 3.0]], radius=0.1)   # 0.4 m clearance, behind
    cfg = ExpertConfig(guard_gust_time=1.0, guard_hover_speed=0.1, gust_allowance=0.0)
    hover = Command(0.0, W_MAX, 0.0)                               # DWA: turn in place
    drift_guard(hover, cycle(view(), gusty, cfg=cfg, **near))
    assert hover.v == pytest.approx(cfg.guard_speed) and hover.w == 0.0
    moving = Command(0.5, 0.0, 0.0)
    drift_guard(moving, cycle(view(state=(0.0, 0.0, 3.0, 0.0, 0.5, 0.0, 0.0)), gusty, cfg=cfg, **near))
    assert (moving.v, moving.w) == (0.5, 0.0)                      # at speed it can steer: DWA's choice stands
    outside = Command(0.0, W_MAX, 0.0)
    drift_guard(outside, cycle(view(), gusty, cfg=cfg, **{**near, "obstacles": [[-1.0, 0.0, 3.0]]}))
    assert (outside.v, outside.w) == (0.0, W_MAX)                  # 0.6 m >= 0.5 m: DWA's choice stands
    calm = Command(0.0, W_MAX, 0.0)
    drift_guard(calm, cycle(view(), _UAVMemory(), cfg=cfg, **near))    # still air: no gust standoff
    assert (calm.v, calm.w) == (0.0, W_MAX)


def test_drift_guard_leaves_a_hovering_uav_to_dwa_accelerating_it_along_a_rollout_no_nearer():
    """``guard_dwa_exit``: the obstacle point ahead (the way away behind the nose), DWA speeding the UAV up along a
    rollout at least as clear as it is now: the command stands; a rollout nearer the point, DWA turning in place, or
    the switch off: the guard turns the UAV in place toward the way away."""
    gusty = _UAVMemory(drift_ms=0.25)                              # RMS drift 0.5 m/s: gust standoff 0.5 m
    cfg = ExpertConfig(guard_gust_time=1.0, guard_hover_speed=0.1, gust_allowance=0.0)
    ahead = dict(admissible=True, obstacles=[[0.8, 0.0, 3.0]], radius=0.1)    # 0.4 m clearance, ahead
    leaving = Command(0.02, W_MAX, 0.0)
    drift_guard(leaving, cycle(view(), gusty, cfg=cfg, dwa_v=0.02, dwa_clearance=0.45, **ahead))
    assert (leaving.v, leaving.w) == (0.02, W_MAX)
    off = cfg.replace(guard_dwa_exit=False)
    for dwa_v, dwa_clearance, guard in ((0.02, 0.35, cfg), (0.0, 0.5, cfg), (0.02, 0.5, off)):
        cmd = Command(dwa_v, W_MAX / 2, 0.0)
        drift_guard(cmd, cycle(view(), gusty, cfg=guard, dwa_v=dwa_v, dwa_clearance=dwa_clearance, **ahead))
        assert cmd.v == 0.0 and abs(cmd.w) == W_MAX                # turned in place toward the way away
    beside = Command(0.02, 0.0, 0.0)                               # the point behind: the guard flies it off
    drift_guard(beside, cycle(view(), gusty, cfg=cfg, dwa_v=0.02, dwa_clearance=0.5,
                              **{**ahead, "obstacles": [[-0.8, 0.0, 3.0]]}))
    assert beside.v == pytest.approx(cfg.guard_speed) and beside.w == 0.0


def test_gust_standoff_leaves_out_what_r_safe_covers():
    """``gust_allowance``: time x RMS drift less gust_allowance x r_safe (0.2 m), never below 0."""
    breeze, gusty, still = _UAVMemory(drift_ms=0.16 ** 2), _UAVMemory(drift_ms=0.6 ** 2), _UAVMemory()
    assert gust_standoff(breeze, CFG, 3.0, LIM.r_safe) == pytest.approx(3.0 * 0.16 - 0.2)       # 0.28 m
    assert gust_standoff(breeze, CFG, 1.0, LIM.r_safe) == 0.0                                   # 0.16 m < 0.2 m
    assert gust_standoff(gusty, CFG, 1.0, LIM.r_safe) == pytest.approx(0.6 - 0.2)
    assert gust_standoff(still, CFG, 3.0, LIM.r_safe) == 0.0
    whole = ExpertConfig(gust_allowance=0.0)                                # the margins before (session 8)
    assert gust_standoff(breeze, whole, 3.0, LIM.r_safe) == pytest.approx(0.48)
    half = ExpertConfig(gust_allowance=0.5)
    assert gust_standoff(breeze, half, 3.0, LIM.r_safe) == pytest.approx(0.48 - 0.1)
    with pytest.raises(ValueError, match="gust_allowance"):
        ExpertConfig(gust_allowance=-0.1)


def test_drift_guard_leaves_a_hovering_uav_in_a_breeze_to_dwa_where_r_safe_covers_the_drift():
    """A UAV turning in place 0.4 m from a wall in a breeze (RMS drift 0.16 m/s): the gust standoff 3 s x 0.16 = 0.48 m
    less r_safe is 0.28 m, so DWA's turn stands; without the allowance (0.48 m) the guard flew it off the wall (wall-gap
    v1-dev s200119 breeze: 425 such overrides, the leader never turned into the gap)."""
    breeze = _UAVMemory(drift_ms=0.16 ** 2)
    near = dict(admissible=True, obstacles=[[-0.8, 0.0, 3.0]], radius=0.1)   # 0.4 m clearance, behind
    turn = Command(0.0, W_MAX, 0.0)
    drift_guard(turn, cycle(view(), breeze, cfg=CFG, **near))
    assert (turn.v, turn.w) == (0.0, W_MAX)
    before = Command(0.0, W_MAX, 0.0)
    drift_guard(before, cycle(view(), breeze, cfg=ExpertConfig(gust_allowance=0.0), **near))
    assert before.v == pytest.approx(CFG.guard_speed) and before.w == 0.0
    closer = Command(0.0, W_MAX, 0.0)                                      # 0.2 m: inside 0.28 m, still guarded
    drift_guard(closer, cycle(view(), breeze, cfg=CFG, **{**near, "obstacles": [[-0.6, 0.0, 3.0]]}))
    assert closer.v == pytest.approx(CFG.guard_speed) and closer.w == 0.0


def test_dwa_wind_margin_in_a_breeze_is_what_r_safe_does_not_cover():
    """``gust_allowance`` in DWA's obstacle radii: with ``wind_margin`` 1 s, in a breeze (RMS drift ~0.16 m/s, below
    r_safe / wind_margin = 0.2 m/s) the voxels keep their own radius; with the allowance off they grow by wind_margin
    x the RMS drift (at most ``wind_margin_share`` of the clearance). Every DWA call of a 40-step, 3-UAV forest
    flight is checked."""
    def margins(cfg):
        seen = []

        def capturing_dwa(state, limits, dwa_cfg, goal, obstacles, radii, **kwargs):
            own = radii[radii > 0.0]                                    # voxels (the fence points have radius 0)
            if len(own):
                seen.append((float(own.max() - own.min()), float(own.max()), kwargs["clearance_now"]))
            return dwa_plan(state, limits, dwa_cfg, goal, obstacles, radii, **kwargs)

        expert = FusionExpert(cfg, dwa=capturing_dwa)
        penv = parallel_env(scenario="forest", n_uavs=3, formation="triangle", max_cycles=40, disturbance="breeze")
        obs, _ = penv.reset(seed=4)
        expert.reset(penv, seed=4)
        while penv.agents:
            obs, *_ = penv.step(expert.act(obs, penv))
        gusts = [gust_speed(m) for m in expert.memory.values()]
        return np.array(seen), gusts

    voxel = 0.2 * math.sqrt(3.0) / 2.0
    cfg = ExpertConfig(wind_margin=1.0)
    now, gusts = margins(cfg)
    assert len(now) > 40 and max(gusts) * cfg.wind_margin < LIM.r_safe
    assert np.allclose(now[:, 1], voxel) and np.all(now[:, 0] == 0.0)             # no margin at all
    before, _ = margins(ExpertConfig(wind_margin=1.0, gust_allowance=0.0))
    grown = before[:, 1] - voxel
    assert grown.max() > 0.05 and np.all(grown <= CFG.wind_margin_share * np.maximum(before[:, 2], 0.0) + 1e-12)


def test_wind_margin_is_the_gust_time_times_the_rms_drift_capped_by_its_share_of_the_clearance():
    """With ``gust_allowance`` 0 (its own test above): the margin is the gust standoff, capped by the share."""
    gusty = _UAVMemory(drift_ms=0.25)                              # RMS drift 0.5 m/s
    cfg = ExpertConfig(wind_margin=2.0, wind_margin_share=0.8, gust_allowance=0.0)
    assert wind_margin(gusty, cfg, 3.0, LIM.r_safe) == pytest.approx(1.0)      # 2 s x 0.5 m/s, below 0.8 x 3 m
    assert wind_margin(gusty, cfg, 1.0, LIM.r_safe) == pytest.approx(0.8)      # capped: 0.8 x 1 m
    assert wind_margin(gusty, ExpertConfig(wind_margin=2.0, wind_margin_share=0.5, gust_allowance=0.0), 1.0,
                       LIM.r_safe) == pytest.approx(0.5)
    assert wind_margin(gusty, cfg, -0.1, LIM.r_safe) == 0.0                    # inside an obstacle: no margin
    assert wind_margin(_UAVMemory(), cfg, 1.0, LIM.r_safe) == 0.0              # still air: none (calm unchanged)


def test_wind_margin_share_stops_dwa_closing_on_a_wall_inside_the_margin():
    """A UAV 1.6 m from a wall ahead (x = 2, voxel radius 0.1) at 0.2 m/s, its goal beyond, RMS drift 0.5 m/s, margin
    3 s (1.5 m): with a share of 1/2 (the cap before session 9) DWA's margin is 0.8 m, and it flies on toward the
    wall (its rollout ends 0.26 m outside the margin); with a share of 0.9 the margin is 1.44 m, and no sample is
    admissible (DWA brakes, ``drift_guard`` takes over)."""
    wall = np.array([[2.0, y, z] for y in np.arange(-3.0, 3.01, 0.2) for z in (2.8, 3.0, 3.2)])
    state = np.array([0.0, 0.0, 3.0, 0.0, 0.2, 0.0, 0.0])
    clearance = 2.0 - 0.1 - LIM.r_uav
    gusty = _UAVMemory(drift_ms=0.25)

    def plan(share):
        cfg = ExpertConfig(wind_margin=3.0, wind_margin_share=share, gust_allowance=0.0)
        radii = np.full(len(wall), 0.1 + wind_margin(gusty, cfg, clearance, LIM.r_safe))
        return dwa_plan(state, LIM, cfg.dwa, np.array([10.0, 0.0]), wall, radii, clearance_now=clearance,
                        brake_share=braking_share(gusty, cfg))          # as the controller passes it: 1 in gusts

    half, most = plan(0.5), plan(0.9)
    assert half.admissible and half.v > 0.0 and half.w == 0.0
    assert half.clearance == pytest.approx(0.26) and half.endpoint[0] == pytest.approx(0.54)
    assert not most.admissible and most.n_admissible == 0


def test_fence_clearance_is_the_nearest_horizontal_bound_less_r_uav():
    lo, hi = np.array([0.0, 0.0, 0.0]), np.array([20.0, 10.0, 8.0])
    assert fence_clearance(np.array([3.0, 8.5, 7.9]), lo, hi, 0.3) == pytest.approx(1.2)   # y bound 1.5 m; z ignored
    assert fence_clearance(np.array([0.1, 5.0, 3.0]), lo, hi, 0.3) == pytest.approx(-0.2)  # closer than r_uav


def test_gust_margins_leave_still_air_flights_unchanged():
    """In still air the RMS drift is exactly 0, so the wind margin is 0 whatever its time, share and fence flag."""
    before = ExpertConfig(wind_margin_share=0.5, fence_margin=False)              # the margins before session 9
    gusts = ExpertConfig(wind_margin=2.5, wind_margin_share=0.8, fence_margin=True)
    np.testing.assert_array_equal(_flight(FusionExpert(gusts)), _flight(FusionExpert(before)))
