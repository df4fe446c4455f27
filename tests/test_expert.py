"""The fusion expert (spec (g)) in short closed-loop episodes on small hand-built scenarios.

Episodes are the slow part of the suite, so every scenario here is a few metres across and every
episode ends within a few hundred steps.
"""

import dataclasses
import hashlib
import math
import os
import subprocess
import sys

import numpy as np
import pytest
from gymnasium import spaces

from baselines.dwa import dwa_plan
from baselines.expert import WEIGHT_NAMES, ExpertConfig, FusionExpert, StandardDWA
from baselines.fusion.kernels import columns_without_gap, open_level_way, segment_clear
from baselines.fusion.rules import away_vertically
from uavform_env import EnvConfig, parallel_env
from uavform_env.config import DisturbanceConfig, UAVLimits
from uavform_env.occupancy import OccupancyMap
from uavform_env.scenarios import Mission, Scenario, make_scenario
from uavform_env.world import Box

HEIGHTMAP_PRIOR = EnvConfig().replace(episode=EnvConfig().episode.replace(prior_map="heightmap"))


def scenario(obstacles=(), start=(4.0, 10.0, 3.0), goal=(16.0, 10.0, 3.0), hi=(30.0, 20.0, 12.0), n_uavs=3,
             formation="triangle", heading=0.0, slot_altitude="z_ref"):
    return Scenario(name="expert-test", version=1, seed=None, bounds_lo=(0.0, 0.0, 0.0), bounds_hi=hi,
                    resolution=0.2, obstacles=tuple(obstacles),
                    mission=Mission(start=start, goal=goal, start_heading=heading, formation=formation, spacing=2.0,
                                    n_uavs=n_uavs, slot_altitude=slot_altitude))


def wall_across(x, y_hi, z_ranges):
    """A 0.4 m thick wall through the whole world width, solid over each (z_lo, z_hi) range."""
    return [Box((x, -1.0, lo), (x + 0.4, y_hi + 1.0, hi)) for lo, hi in z_ranges]


def fly(policy, scn, steps, config=None, seed=0, disturbance=None):
    """Fly one episode; returns the env, the last infos and the per-step leader diagnostics and states."""
    penv = parallel_env(scenario=scn, max_cycles=steps, config=config, disturbance=disturbance)
    obs, infos = penv.reset(seed=seed)
    policy.reset(penv, seed=seed)
    diagnostics, states = [], []
    while penv.agents:
        obs, _, _, _, infos = penv.step(policy.act(obs, penv))
        diagnostics.append(dict(policy.diagnostics.get("uav_0", {})))
        states.append(penv.unwrapped.states.copy())
    return penv, infos, diagnostics, np.array(states)


# ----------------------------------------------------------------------------- flying


def test_open_field_mission_succeeds_without_collision():
    penv, infos, _, states = fly(FusionExpert(), scenario(), 400)
    assert infos["uav_0"]["success"] == 1 and infos["uav_0"]["step"] < 400
    assert not penv.unwrapped.crashed.any()
    assert min(np.min(h) for h in penv.unwrapped.history["clearance"]) > 0.0
    assert np.abs(states[:, :, 2] - 3.0).max() < 0.5           # nothing to avoid: the formation stays level


class OnboardOnly:
    """An env stand-in that lets a policy reach only what a UAV has on board (plus the public spaces).

    Any other attribute (world, states, goal, scenario, maps, ...) raises, so a policy that peeks at
    ground truth fails the test instead of silently cheating.
    """

    ALLOWED = ("onboard", "agents", "possible_agents", "action_space", "config")

    def __init__(self, env):
        object.__setattr__(self, "_env", env.unwrapped)

    @property
    def unwrapped(self):
        return self

    def __getattr__(self, name):
        if name in OnboardOnly.ALLOWED:
            return getattr(self._env, name)
        raise AssertionError(f"the policy read env.{name}: ground truth is off limits, use onboard()")


def test_expert_reads_only_the_onboard_view():
    scn = scenario(obstacles=wall_across(10.0, 20.0, [(0.0, 4.0), (6.5, 12.0)]), n_uavs=2, formation="column")
    penv = parallel_env(scenario=scn, max_cycles=60)
    twin = parallel_env(scenario=scn, max_cycles=60)
    obs, _ = penv.reset(seed=1)
    twin_obs, _ = twin.reset(seed=1)
    guarded, reference = FusionExpert(), FusionExpert()
    view = OnboardOnly(penv)
    guarded.reset(view, seed=1)
    reference.reset(twin, seed=1)
    while penv.agents:
        acts = guarded.act(obs, view)
        expected = reference.act(twin_obs, twin)
        assert {a: v.tobytes() for a, v in acts.items()} == {a: v.tobytes() for a, v in expected.items()}
        obs, *_ = penv.step(acts)
        twin_obs, *_ = twin.step(expected)


def test_default_weights_are_bit_identical_to_no_weights():
    scn = scenario(obstacles=wall_across(10.0, 20.0, [(0.0, 4.0), (6.5, 12.0)]))
    runs = []
    for weighted in (False, True):
        penv = parallel_env(scenario=scn, max_cycles=80)
        obs, _ = penv.reset(seed=2)
        expert = FusionExpert()
        expert.reset(penv, seed=2)
        w = ExpertConfig().weights()
        trace = []
        while penv.agents:
            acts = expert.act(obs, penv, weights={a: w for a in penv.agents} if weighted else None)
            trace.append(b"".join(acts[a].tobytes() for a in sorted(acts)))
            obs, *_ = penv.step(acts)
        runs.append(trace)
    assert len(runs[0]) == 80 and runs[0] == runs[1]


def gusty_noisy_flight_digest(seed: int, steps: int = 40) -> str:
    """The expert flying forest in gusts with sensor noise and dropped rays: every observation and state, hashed."""
    weather = DisturbanceConfig(wind_std=1.0, wind_mean=(0.3, 0.0), range_noise_std=0.05, ray_dropout=0.1)
    penv = parallel_env(scenario="forest", n_uavs=3, formation="triangle", max_cycles=steps, disturbance=weather)
    obs, _ = penv.reset(seed=seed)
    policy = FusionExpert()
    policy.reset(penv, seed=seed)
    h = hashlib.sha256()
    while penv.agents:
        obs, *_ = penv.step(policy.act(obs, penv))
        h.update(b"".join(obs[a].tobytes() for a in sorted(obs)) + penv.unwrapped.states.tobytes())
    return h.hexdigest()


def test_gusty_noisy_flight_is_the_same_in_another_process():
    """Wind, sensor noise and the expert's memory draw nothing from the process (hash seed, import order)."""
    code = ("import sys; sys.path.insert(0, '.'); from tests.test_expert import gusty_noisy_flight_digest;"
            "print(gusty_noisy_flight_digest(11))")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         env={**os.environ, "PYTHONHASHSEED": "12345"})
    assert run.stdout.split()[-1] == gusty_noisy_flight_digest(11) != gusty_noisy_flight_digest(12)


def test_weights_change_the_actions():
    """The override is live: facing north with the goal east, only the heading term asks for a turn."""
    penv = parallel_env(scenario=scenario(heading=np.pi / 2), max_cycles=5)
    obs, _ = penv.reset(seed=0)
    plain, reweighted = FusionExpert(), FusionExpert()
    plain.reset(penv, seed=0)
    reweighted.reset(penv, seed=0)
    w = ExpertConfig().weights()
    w[WEIGHT_NAMES.index("alpha0")] = 0.0
    a = plain.act(obs, penv)
    b = reweighted.act(obs, penv, weights={"uav_0": w})
    assert a["uav_1"].tobytes() == b["uav_1"].tobytes()      # only uav_0 was given weights
    assert a["uav_0"][1] < 0.0 and b["uav_0"][1] == 0.0      # turn right toward the goal / keep straight


@pytest.mark.parametrize("right_of_way", [True, False])
def test_the_leader_never_yields_in_the_dist_term(right_of_way):
    """(g6) with ``leader_right_of_way``: the leader's DWA call leaves its neighbours out of the dist term, the
    followers' keep them (every call passes them as movers for admissibility); off, every UAV counts them."""
    seen = []

    def spy(*args, **kwargs):
        seen.append((kwargs["mover_dist"], len(kwargs["movers_pos"])))
        return dwa_plan(*args, **kwargs)

    penv = parallel_env(scenario=scenario(), max_cycles=5)
    obs, _ = penv.reset(seed=0)
    policy = FusionExpert(ExpertConfig(leader_right_of_way=right_of_way), dwa=spy)
    policy.reset(penv, seed=0)
    policy.act(obs, penv)
    assert seen == [(not right_of_way, 2), (True, 2), (True, 2)]             # uav_0 (leader), uav_1, uav_2


# ----------------------------------------------------------------------------- bad input


@pytest.mark.parametrize("kwargs, match", [
    (dict(e0=1.0, e1=1.0), "ExpertConfig.e1"),
    (dict(e0=2.0, e1=1.5), "ExpertConfig.e1"),
    (dict(astar_layer="voxels"), "ExpertConfig.astar_layer"),
    (dict(k_f=-0.5), "ExpertConfig.k_f"),
    (dict(leader_speed_cap=0.0), "ExpertConfig.leader_speed_cap"),
    (dict(debounce=0), "ExpertConfig.debounce"),
    (dict(dwa="IDWA"), "ExpertConfig.dwa"),
    (dict(climb_target_limit=1), "ExpertConfig.climb_target_limit"),
    (dict(park_turn=None), "ExpertConfig.park_turn"),
    (dict(rejoin="leader"), "ExpertConfig.rejoin"),
    (dict(park_heading="goal"), "ExpertConfig.park_heading"),
    (dict(reverse_turn_angle=4.0), "ExpertConfig.reverse_turn_angle"),
    (dict(dock_radius=-1.0), "ExpertConfig.dock_radius"),
    (dict(level_line="yes"), "ExpertConfig.level_line"),
    (dict(repark_time=-1.0), "ExpertConfig.repark_time"),
    (dict(repark_radius=float("nan")), "ExpertConfig.repark_radius"),
])
def test_bad_config_names_the_field(kwargs, match):
    with pytest.raises(ValueError, match=match):
        ExpertConfig(**kwargs)


@pytest.mark.parametrize("weights", [
    [-0.1, 0.2, 0.1, 0.05, 5.0, 2.0, 2.0],                   # a negative weight
    [0.1, 0.2, 0.1, 0.05, 5.0, 2.0],                         # one short
    [0.1, 0.2, 0.1, 0.05, 5.0, 2.0, np.nan],                 # not finite
    [[0.1] * 7],                                             # wrong shape
])
def test_bad_weight_vectors_are_rejected(weights):
    with pytest.raises(ValueError, match="weights: expected 7 finite values >= 0"):
        ExpertConfig().with_weights(weights)
    penv = parallel_env(scenario=scenario(), max_cycles=5)
    obs, _ = penv.reset(seed=0)
    expert = FusionExpert()
    expert.reset(penv, seed=0)
    with pytest.raises(ValueError, match="weights"):
        expert.act(obs, penv, weights={"uav_0": weights})


def test_climb_toward_the_target_altitude_does_not_overshoot():
    """3D VFH+'s elevation cells never give 0: at a slot 0.1 m below, the next cell up would climb at
    0.3 * tan(2.5 deg) = 0.013 m/s, at 0.5 m below a 27 deg cell at 0.15 m/s; the rate toward the target
    altitude is capped at k_z times the error, and a climb over an obstacle (away from it) is left alone."""
    from baselines.fusion.controller import _climb_rate
    cfg = ExpertConfig()
    lim = UAVLimits()
    e = math.radians(27.5)
    assert _climb_rate(e, 0.0, 0.1, cfg, lim) == pytest.approx(cfg.k_z * 0.1)
    assert _climb_rate(-e, 0.0, -0.1, cfg, lim) == pytest.approx(-cfg.k_z * 0.1)
    assert _climb_rate(e, 0.0, -0.5, cfg, lim) == pytest.approx(0.3 * math.tan(e))
    assert _climb_rate(e, 0.0, 5.0, cfg, lim) == pytest.approx(0.3 * math.tan(e))
    off = ExpertConfig(climb_target_limit=False)
    assert _climb_rate(e, 0.0, 0.1, off, lim) == pytest.approx(0.3 * math.tan(e))


def test_parked_leader_turns_until_every_slot_is_free():
    """A slot inside an obstacle (in the leader's own map) makes the parked leader pick the nearest heading
    whose slots are all free and inside the bounds; it keeps that heading while it stays free."""
    from types import SimpleNamespace

    from baselines.fusion.controller import _park_heading, _UAVMemory

    class Map:                                   # one occupied disc of radius 1 m around (-2, 2)
        resolution = 0.2

        def occupied_within(self, c, r):
            return math.hypot(c[0] + 2.0, c[1] - 2.0) < 1.0 + r

    offsets = np.array([[0.0, 0.0, 0.0], [-2.0, 2.0, 0.0], [-2.0, -2.0, 0.0]])   # two rear slots
    view = SimpleNamespace(limits=UAVLimits(), occupancy=Map(), offsets=offsets, z_ref=3.0, slot_altitude="z_ref",
                           goal=np.array([0.0, 0.0, 3.0]),
                           state=np.array([0.0, 0.0, 3.0, 0.0, 0.0, 0.0, 0.0]),
                           bounds_lo=np.array([-10.0, -10.0, 0.0]), bounds_hi=np.array([10.0, 10.0, 12.0]))
    mem, nearest = _UAVMemory(), ExpertConfig(park_heading="nearest")
    psi = _park_heading(view, mem, nearest)
    assert psi != 0.0 and mem.park_psi == psi
    c, s_ = math.cos(psi), math.sin(psi)
    for off in offsets[1:]:
        slot = np.array([c * off[0] - s_ * off[1], s_ * off[0] + c * off[1], 3.0])
        assert not view.occupancy.occupied_within(slot, 0.7)
    view.state[3] = psi * 0.5                      # half-way through the turn: the target heading stays
    assert _park_heading(view, mem, nearest) == psi
    free = SimpleNamespace(**{**vars(view), "occupancy": SimpleNamespace(resolution=0.2,
                                                                         occupied_within=lambda c, r: False)})
    free.state = np.array([0.0, 0.0, 3.0, 0.3, 0.0, 0.0, 0.0])
    assert _park_heading(free, _UAVMemory(), nearest) == 0.3
    # "followers": of the free headings, the one whose slots lie nearest the followers' broadcasts. Both followers
    # sit 0.1 m off their slots of heading +90 deg: the leader parks on +90 deg, not its own 0.3 rad
    slots_90 = np.array([[-2.0, -2.0], [2.0, -2.0]]) + 0.1        # offsets (-2, 2), (-2, -2) turned by +90 deg
    states = np.zeros((2, 7))
    states[:, :2] = slots_90
    free.neighbour_states, free.neighbour_ids, free.neighbour_alive = states, np.array([1, 2]), np.array([True, True])
    assert _park_heading(free, _UAVMemory(), ExpertConfig()) == pytest.approx(0.3 + 2.0 * math.pi * 15 / 72)
    free.neighbour_alive = np.array([False, False])                # no live follower: its own heading
    assert _park_heading(free, _UAVMemory(), ExpertConfig()) == 0.3
    # with the obstacle map, the nearest-followers heading is among the free ones only
    view.neighbour_states, view.neighbour_ids, view.neighbour_alive = states, np.array([1, 2]), np.array([True, True])
    view.state[3] = 0.0
    psi_f = _park_heading(view, _UAVMemory(), ExpertConfig())
    c, s_ = math.cos(psi_f), math.sin(psi_f)
    for off in offsets[1:]:
        assert not view.occupancy.occupied_within(np.array([c * off[0] - s_ * off[1], s_ * off[0] + c * off[1], 3.0]),
                                                  0.7)


def test_parked_leader_reparks_away_from_a_slot_a_follower_does_not_reach():
    """``repark_time``: a follower 1.3 m off its slot (e_f 0.5 m) that gains less than ``trail_spacing`` on it for
    ``repark_time`` s marks that slot point; the leader then parks on the heading nearest its own whose slots all keep
    ``repark_radius`` from the mark. Slot (-2, -2) turned by psi moves 2 * |(-2, -2)| * sin(psi / 2) = 1 m at psi =
    20.4 deg: of the 5-deg headings 0, +5, -5, +10, ..., +25 deg is the first."""
    from types import SimpleNamespace

    from baselines.fusion.controller import _mark_unreached_slots, _park_heading, _UAVMemory

    offsets = np.array([[0.0, 0.0, 0.0], [-2.0, 2.0, 0.0], [-2.0, -2.0, 0.0]])
    states = np.zeros((2, 7))
    states[:, :3] = [[-2.0, 2.0, 3.0], [-2.0, -0.7, 3.0]]            # follower 1 on its slot, follower 2 1.3 m off
    view = SimpleNamespace(limits=UAVLimits(), offsets=offsets, z_ref=3.0, slot_altitude="z_ref",
                           occupancy=SimpleNamespace(resolution=0.2, occupied_within=lambda c, r: False),
                           goal=np.array([0.0, 0.0, 3.0]), state=np.array([0.0, 0.0, 3.0, 0.0, 0.0, 0.0, 0.0]),
                           bounds_lo=np.array([-10.0, -10.0, 0.0]), bounds_hi=np.array([10.0, 10.0, 12.0]),
                           neighbour_states=states, neighbour_ids=np.array([1, 2]),
                           neighbour_alive=np.array([True, True]), config=EnvConfig())
    cfg = ExpertConfig(park_heading="nearest")
    mem = _UAVMemory()
    assert _park_heading(view, mem, cfg) == 0.0
    _mark_unreached_slots(view, mem, cfg, 10.0)                       # the watch starts
    states[1, 1] = -0.7 - cfg.trail_spacing                    # it gains trail_spacing at 20 s: the clock restarts
    _mark_unreached_slots(view, mem, cfg, 20.0)
    _mark_unreached_slots(view, mem, cfg, 20.0 + cfg.repark_time - 0.1)
    assert len(mem.park_marks) == 0 and _park_heading(view, mem, cfg) == 0.0
    _mark_unreached_slots(view, mem, cfg, 20.0 + cfg.repark_time)
    np.testing.assert_allclose(mem.park_marks, [[-2.0, -2.0]])        # only follower 2's slot: follower 1 is on its own
    assert _park_heading(view, mem, cfg) == pytest.approx(2.0 * math.pi * 5 / 72)
    # "followers" too parks only on headings whose slots keep repark_radius from the mark
    psi = _park_heading(view, _UAVMemory(park_marks=mem.park_marks), ExpertConfig())
    slots = np.array([[math.cos(psi) * x - math.sin(psi) * y, math.sin(psi) * x + math.cos(psi) * y]
                      for x, y in offsets[1:, :2]])
    assert np.all(np.hypot(*(slots - [-2.0, -2.0]).T) >= cfg.repark_radius)
    # repark_time = 0 switches the watch off (the leader's _park does not call it): no mark, no turn
    assert _park_heading(view, _UAVMemory(), ExpertConfig(park_heading="nearest", repark_time=0.0)) == 0.0


def test_followers_take_the_column_fallback_only_until_the_leader_parks_at_the_goal():
    """``_leader_at_goal``: the broadcast leader slower than ``leader_stopped_speed`` and within ``arrive_radius`` of
    the goal (horizontally); then a follower closes on its own slot, the one the env judges (``column_at_goal``)."""
    from types import SimpleNamespace

    from baselines.fusion.controller import _leader_at_goal

    cfg = ExpertConfig()
    def at(x, v):
        return SimpleNamespace(goal=np.array([10.0, 0.0, 3.0]), leader_state=np.array([x, 0.0, 5.0, 0.0, v, 0.0, 0.0]))
    assert _leader_at_goal(at(9.8, 0.0), cfg)                      # 0.2 m off, at rest (altitude does not count)
    assert not _leader_at_goal(at(9.6, 0.0), cfg)                  # at rest 0.4 m off: not parked at the goal
    assert not _leader_at_goal(at(10.0, 0.06), cfg)                # on the goal but still moving


def test_weight_names_follow_the_config():
    cfg = ExpertConfig()
    w = cfg.weights()
    assert w.tolist() == [cfg.dwa.alpha0, cfg.dwa.beta, cfg.dwa.gamma, cfg.dwa.eps0, cfg.vfh.k1, cfg.vfh.k2, cfg.vfh.k3]
    w2 = np.arange(1.0, 8.0)
    assert cfg.with_weights(w2).weights().tolist() == w2.tolist()


def test_with_weights_equals_the_fully_checked_copy():
    # with_weights skips the checks of fields it does not change; the copy equals the one replace() validates
    cfg = ExpertConfig()
    w = np.array([0.3, 0.1, 0.0, 0.2, 4.0, 1.0, 3.0])
    full = dataclasses.replace(cfg, dwa=dataclasses.replace(cfg.dwa, alpha0=w[0], alpha=w[0], beta=w[1], gamma=w[2],
                                                            eps0=w[3]),
                               vfh=dataclasses.replace(cfg.vfh, k1=w[4], k2=w[5], k3=w[6]))
    fast = cfg.with_weights(w)
    assert fast == full and hash(fast) == hash(full) and fast is not cfg and fast.dwa is not cfg.dwa
    assert cfg.weights().tolist() != w.tolist()                    # the original is untouched
    with pytest.raises(ValueError, match=r"DWAConfig.beta=-1.0 is out of range"):
        cfg.dwa.with_checked(beta=-1.0)                            # the field's declared bound still holds


class NoOnboard:
    possible_agents = ["uav_0"]

    def action_space(self, agent):
        return spaces.Box(-1.0, 1.0, (3,), np.float32)


class WrongActions:
    """An env that has an onboard view but flies two-axis actions."""

    possible_agents = ["uav_0"]

    def onboard(self, agent):
        raise AssertionError("not reached: the action space is checked first")

    def action_space(self, agent):
        return spaces.Box(-1.0, 1.0, (2,), np.float32)


@pytest.mark.parametrize("env, match", [(NoOnboard(), "has no onboard"), (WrongActions(), "expected Box\\(-1, 1, \\(3,\\)\\)")])
def test_unflyable_env_is_rejected(env, match):
    with pytest.raises(ValueError, match=match):
        FusionExpert().reset(env, seed=0)


def test_act_on_another_env_is_rejected():
    penv = parallel_env(scenario=scenario(), max_cycles=5)
    other = parallel_env(scenario=scenario(), max_cycles=5)
    obs, _ = penv.reset(seed=0)
    other.reset(seed=0)
    expert = FusionExpert()
    expert.reset(penv, seed=0)
    with pytest.raises(ValueError, match="not reset"):
        expert.act(obs, other)


# ----------------------------------------------------------------------------- unreachable goal

# A wall through the full width and height of a narrow world (top 12 m > z_max = 10 m): with the world's
# side bounds it encloses the goal. The leader starts 4 m in front of it.
def enclosed_goal():
    return scenario(obstacles=wall_across(10.0, 6.0, [(0.0, 12.0)]), start=(6.0, 3.0, 3.0), goal=(14.0, 3.0, 3.0),
                    hi=(20.0, 6.0, 12.0), n_uavs=1, formation="column")


def test_goal_behind_a_low_wall_is_reached_over_it_on_the_prior_map():
    scn = scenario(obstacles=wall_across(10.0, 6.0, [(0.0, 5.0)]), start=(6.0, 3.0, 3.0), goal=(14.0, 3.0, 3.0),
                   hi=(20.0, 6.0, 12.0), n_uavs=1, formation="column")
    expert = FusionExpert()
    penv, infos, diagnostics, states = fly(expert, scn, 400, config=HEIGHTMAP_PRIOR)
    assert infos["uav_0"]["success"] == 1 and not penv.unwrapped.crashed.any()
    at_wall = np.abs(states[:, 0, 0] - 10.0) < 0.5
    assert at_wall.any() and np.all(states[at_wall, 0, 2] > 5.0)      # 5 m top: the 'passable' raster flies over it
    assert expert.memory["uav_0"].replans >= 1 and not any(d.get("stuck") for d in diagnostics[:50])


@pytest.mark.parametrize("config", [None, HEIGHTMAP_PRIOR], ids=["no-prior", "heightmap-prior"])
def test_leader_discovers_the_enclosure_and_holds(config):
    """The leader explores, then holds safely and reports stuck; with the 2.5D prior too, on which the wall closes
    the way from the start (a heightmap shows tops, not what lies below them, so that proves nothing).

    It is stuck either because its own map closes every column (A* finds no path: ``unreachable``) or
    because it has made no progress toward the goal for ``ExpertConfig.stuck_window`` seconds.
    """
    penv, infos, diagnostics, states = fly(FusionExpert(), enclosed_goal(), 450, config=config)
    assert not penv.unwrapped.crashed.any() and infos["uav_0"]["success"] == 0
    stuck = [bool(d["stuck"]) for d in diagnostics]
    assert all(stuck[-30:])
    assert abs(states[-1, 0, 4]) < 0.05                       # braked to (nearly) a standstill ...
    settled = states[-30:, 0, :2]
    assert np.ptp(settled, axis=0).max() < 0.1                 # ... and holds there
    assert states[-1, 0, 0] < 10.0                            # never through the wall


@pytest.mark.parametrize("disturbance", ["calm", "breeze"])
@pytest.mark.parametrize("goal_z", [11.5, 0.0])
def test_goal_outside_the_altitude_band_is_reported_stuck_and_held(disturbance, goal_z):
    """No UAV of the band [0.5, 10] m comes within r_goal = 0.5 m of the goal: the env flies the mission, the
    leader reports ``stuck`` (``unreachable``) from the first cycle and the formation holds where it started."""
    scn = scenario(goal=(16.0, 10.0, goal_z), n_uavs=2, formation="column", slot_altitude="leader")
    penv, infos, diagnostics, states = fly(FusionExpert(), scn, 150, disturbance=disturbance, seed=2)
    env = penv.unwrapped
    assert not env.crashed.any() and infos["uav_0"]["success"] == 0 and env.step_count == 150
    assert all(d["stuck"] and d["unreachable"] for d in diagnostics)
    moved = np.hypot(*(states[-1, :, :2] - states[0, :, :2]).T)
    assert moved.max() < 1.0                                  # held near the start, calm or breezy
    assert np.all((states[:, :, 2] >= env.config.uav.z_min) & (states[:, :, 2] <= env.config.uav.z_max))


# ----------------------------------------------------------------------------- goals in 3D, wind


def test_formation_reaches_a_goal_above_z_ref():
    scn = scenario(goal=(14.0, 10.0, 6.0), n_uavs=2, formation="column", slot_altitude="leader")
    penv, infos, _, states = fly(FusionExpert(), scn, 400)
    assert infos["uav_0"]["success"] == 1 and not penv.unwrapped.crashed.any()
    assert abs(states[-1, 0, 2] - 6.0) < 0.5 and abs(states[-1, 1, 2] - states[-1, 0, 2]) < 0.5   # slot: leader z


def test_parked_leader_keeps_station_in_a_breeze():
    """With r_goal too small to end the episode, the arrived leader holds the goal against 0.3 m/s gusts: with the
    default airframe (its autopilot leans into the wind) inside r_goal, without turning its followers' slots
    round; with the unopposed wind model as well as a 20 deg/s unicycle can, where hovering is carried off."""
    never = EnvConfig().replace(episode=EnvConfig().episode.replace(r_goal=1e-6))
    scn = scenario(goal=(10.0, 10.0, 3.0), n_uavs=1, formation="column")
    penv, _, diagnostics, states = fly(FusionExpert(), scn, 700, config=never, disturbance="breeze", seed=1)
    assert not penv.unwrapped.crashed.any() and diagnostics[-1].get("arrived")
    drift = np.hypot(states[-300:, 0, 0] - 10.0, states[-300:, 0, 1] - 10.0)
    assert drift.max() < EnvConfig().episode.r_goal and np.ptp(states[-300:, 0, 3]) < 0.2   # no turning round
    unopposed = never.replace(uav=never.uav.replace(wind_authority=0.0))
    penv, _, diagnostics, states = fly(FusionExpert(), scn, 700, config=unopposed, disturbance="breeze", seed=1)
    assert not penv.unwrapped.crashed.any() and diagnostics[-1].get("arrived")
    drift = np.hypot(states[-300:, 0, 0] - 10.0, states[-300:, 0, 1] - 10.0)
    assert drift.max() < 3.5 and np.median(drift) < 1.0       # what a 20 deg/s unicycle achieves in 0.3 m/s gusts
    # without the return to the point the gusts carry it off: over two gust sequences (one alone is a coin toss
    # of where the random walk ends) it sits further out than the held leader
    held, loose = [drift], []
    for seed, policy in ((0, FusionExpert()), (0, FusionExpert(ExpertConfig(k_hold=0.0, vane_wind=100.0))),
                         (1, FusionExpert(ExpertConfig(k_hold=0.0, vane_wind=100.0)))):
        _, _, _, other = fly(policy, scn, 700, config=unopposed, disturbance="breeze", seed=seed)
        (held if policy.config.k_hold > 0.0 else loose).append(np.hypot(other[-300:, 0, 0] - 10.0,
                                                                            other[-300:, 0, 1] - 10.0))
    assert np.median(np.concatenate(loose)) > 1.5 * np.median(np.concatenate(held))


# ----------------------------------------------------------------------------- wall gap (3D vs 2D)


def gap_wall():
    """A single UAV, a full-height wall 6 m ahead with a 2.5 m gap from 4 m up (z_ref = 3 m is blocked)."""
    return scenario(obstacles=wall_across(10.0, 8.0, [(0.0, 4.0), (6.5, 12.0)]), start=(4.0, 4.0, 3.0),
                    goal=(16.0, 4.0, 3.0), hi=(20.0, 8.0, 12.0), n_uavs=1, formation="column")


@pytest.mark.parametrize("config", [None, HEIGHTMAP_PRIOR], ids=["no-prior", "heightmap-prior"])
def test_expert_passes_the_wall_gap_by_changing_altitude(config):
    """Also with the 2.5D prior, on which the full-height wall closes the way: the gap lies below its top."""
    penv, infos, _, states = fly(FusionExpert(), gap_wall(), 450, config=config)
    assert infos["uav_0"]["success"] == 1 and not penv.unwrapped.crashed.any()
    at_wall = np.abs(states[:, 0, 0] - 10.2) < 0.5
    assert at_wall.any() and np.all((states[at_wall, 0, 2] > 4.0) & (states[at_wall, 0, 2] < 6.5))


def test_prior_tops_do_not_close_a_way_the_own_map_has_seen():
    """On the 2.5D prior the full-height wall closes every way (its top is all a heightmap shows); once the own map
    has seen the gap under it, the leader's strict raster (own map + prior) holds a path through the gap again."""
    from baselines.astar import plan_path

    penv = parallel_env(scenario=gap_wall(), max_cycles=400, config=HEIGHTMAP_PRIOR)
    obs, _ = penv.reset(seed=0)
    expert = FusionExpert()
    expert.reset(penv, seed=0)
    env = penv.unwrapped

    def strict_path():
        view = env.onboard("uav_0")
        lim = view.limits
        blocked = expert._blocked_raster(view, expert.config)
        return plan_path(blocked, expert.raster, view.state[:2], view.goal[:2], lim.r_uav + lim.r_safe,
                         expert.config.astar)

    assert strict_path() is None
    while env.states[0, 0] < 8.5 and penv.agents:          # up to the wall (x = 10), its gap in view
        obs, *_ = penv.step(expert.act(obs, penv))
    path = strict_path()
    assert path is not None and abs(path.points[:, 1] - 4.0).max() < 4.0 and path.points[-1, 0] > 14.0


def test_rejoining_follower_of_a_fast_airframe_passes_the_wall_gap():
    """v_max = 2 m/s makes E8's R_sw = v_max T_p = 6 m, beyond A*'s 3 m lookahead. While E8 took a rejoining
    follower's lookahead point for where it stops, the approach profile flattened DWA's velocity term and the
    clearance term held the follower at rest 0.3 m from the wall, 15 m from its slot, to the end (wall-gap seed 2)."""
    fast = EnvConfig().replace(uav=UAVLimits(v_max=2.0))
    scn = make_scenario("wall-gap", seed=2, n_uavs=3, formation="diamond", spacing=1.55)
    penv, infos, _, _ = fly(FusionExpert(), scn, 900, config=fast, seed=2)
    assert infos["uav_0"]["success"] == 1 and not penv.unwrapped.crashed.any()


def test_standard_dwa_does_not_pass_the_wall_gap():
    penv, infos, diagnostics, states = fly(StandardDWA(), gap_wall(), 300)
    assert infos["uav_0"]["success"] == 0 and not penv.unwrapped.crashed.any()
    assert np.all(states[:, 0, 0] < 10.0) and np.all(states[:, 0, 2] == 3.0)
    assert diagnostics[-1]["stuck"]


# ----------------------------------------------------------------------------- own-map raster and geometry


def column_blocked(occupied_z, free_z, scans: int = 1, misses: int = 0) -> bool:
    """Whether the A* raster blocks one map column whose voxels at ``occupied_z`` were hit and at ``free_z``
    were crossed by a ray in ``scans`` scans (every other voxel unknown); altitude band 0.5-10 m, way height 1.2 m,
    a way's free voxel crossed at least ``misses`` times (0: once)."""
    occ = OccupancyMap((0.0, 0.0, 0.0), (3, 1, 60), 0.2)
    for z in occupied_z:
        occ.integrate((0.1, 0.1, z), [[0.5, 0.1, z]], np.array([True]))
    for _ in range(scans):
        for z in free_z:
            occ.integrate((0.1, 0.1, z), [[0.7, 0.1, z]], np.array([False]))
    centres, _ = occ.occupied_in_sphere((0.3, 0.1, 6.0), 10.0)
    columns = columns_without_gap(occ, centres, 0.5, 10.0, 1.2, misses=misses)
    assert len(columns) <= 1 and (len(columns) == 0 or np.allclose(columns[0], (0.5, 0.1)))
    return len(columns) == 1


def test_raster_needs_a_seen_way_through_a_column():
    wall = np.arange(1.1, 4.6, 0.2)                              # hit from 1.0 m to 4.6 m
    assert column_blocked(wall, [])                               # unseen top: a wall, not a way over it
    assert not column_blocked(wall, [6.1])                        # one ray above the top opens 4.6-10 m
    assert column_blocked(wall, [0.7, 0.9])                       # seen, but 0.5-1.0 m is too low to pass
    upper = np.arange(5.5, 10.0, 0.2)                             # a second slab from 5.4 m: the gap is 0.8 m
    assert column_blocked(np.concatenate([wall, upper]), [4.9, 5.1])
    assert not column_blocked([], [])                              # nothing occupied: no column at all


def test_raster_way_needs_free_evidence_of_way_misses_scans():
    """``ExpertConfig.way_misses``: a lost ray of ``noisy`` reads as free space once, through the obstacle it
    would have hit; a way through a column needs a voxel crossed in that many scans (3 miss updates)."""
    wall = np.arange(1.1, 4.6, 0.2)
    for scans, blocked in ((1, True), (2, True), (3, False), (9, False)):   # 9: clamped at l_min, still a way
        assert column_blocked(wall, [6.1], scans, misses=3) is blocked
    assert not column_blocked(wall, [6.1], 1, misses=0)           # 0: any known non-occupied voxel (one ray)
    assert column_blocked(wall, [6.1], 4, misses=6)               # 6 misses lie beyond the clamp at l_min, which
    assert not column_blocked(wall, [6.1], 5, misses=6)           # 5 reach: the clamp is enough


def columns_reference(occ, centres, z_min, z_max, gap, misses=0):
    """The same rule vectorised over whole columns (runs labelled by a cumulative sum), as a cross-check."""
    res, origin = occ.resolution, occ.origin
    inside = (centres[:, 2] >= z_min - res) & (centres[:, 2] <= z_max + res)
    ij = np.unique(np.floor((centres[inside, :2] - origin[:2]) / res).astype(np.int64), axis=0).reshape(-1, 2)
    k_lo = max(0, int(math.ceil((z_min - origin[2]) / res - 0.5)))
    k_hi = min(occ.shape[2], int(math.floor((z_max - origin[2]) / res - 0.5)) + 1)
    cols = occ.logodds[ij[:, 0], ij[:, 1], k_lo:k_hi]
    l_occ = np.float32(occ.cfg.logodds(occ.cfg.p_occ))
    occupied = cols >= l_occ
    n_z = cols.shape[1]
    run = np.cumsum(occupied, axis=1) + np.arange(len(cols))[:, None] * (n_z + 1)
    length = np.bincount(run[~occupied], minlength=len(cols) * (n_z + 1))
    l_way = max((misses - 0.5) * occ.cfg.logodds(occ.cfg.p_miss), occ.cfg.logodds(occ.cfg.p_min)) if misses else np.inf
    free = (cols < l_occ) & (cols <= np.float32(l_way))
    seen = np.bincount(run[~occupied], weights=free[~occupied], minlength=len(cols) * (n_z + 1))
    blocked = ~((length * res >= gap - 1e-9) & (seen > 0)).reshape(len(cols), n_z + 1).any(axis=1)
    return origin[:2] + (ij[blocked] + 0.5) * res


@pytest.mark.parametrize("seed, misses", [(0, 0), (1, 0), (2, 3), (3, 0), (4, 2)])
def test_raster_columns_match_a_vectorised_reference(seed, misses):
    rng = np.random.default_rng(seed)
    occ = OccupancyMap((0.0, 0.0, 0.0), (12, 10, 40), 0.2)
    for _ in range(60):                                           # random rays: hits, and the free space they cross
        start = rng.uniform((0.1, 0.1, 0.1), (2.3, 1.9, 7.9))
        ends = np.clip(start + rng.normal(scale=0.6, size=(20, 3)), 0.05, (2.35, 1.95, 7.95))
        occ.integrate(start, ends, rng.random(20) < 0.8)
    centres, _ = occ.occupied_in_sphere((1.2, 1.0, 4.0), 10.0)
    z_min, z_max, gap = rng.uniform(0.0, 2.0), rng.uniform(5.0, 8.5), rng.uniform(0.4, 2.5)
    got = columns_without_gap(occ, centres, z_min, z_max, gap, misses=misses)
    expected = columns_reference(occ, centres, z_min, z_max, gap, misses)
    assert 0 < len(expected) < len(np.unique(np.floor(centres[:, :2] / 0.2), axis=0))   # both outcomes occur
    assert np.array_equal(got[np.lexsort(got.T[::-1])], expected)


def test_level_way_known_answers():
    cell = math.radians(5.0)
    window_open = np.zeros((36, 72), dtype=bool)
    window_open[17, 10] = True                                    # a level row, azimuth 52.5 deg
    assert open_level_way(window_open, cell, math.radians(60.0), math.radians(10.0))
    assert not open_level_way(window_open, cell, math.radians(60.0), math.radians(5.0))
    window_open[:] = False
    window_open[18, 71] = True                                    # the other level row, 357.5 deg
    assert open_level_way(window_open, cell, 0.0, math.radians(5.0))   # across the 0/360 seam
    window_open[:] = False
    window_open[16, 12] = True                                    # open, but one row below the level rows
    assert not open_level_way(window_open, cell, math.radians(62.5), math.radians(10.0))


def testsegment_clearance_is_the_distance_to_the_segment():
    centres = np.array([[1.0, 1.0, 0.0], [5.0, 0.0, 0.0]])
    a, b = np.zeros(3), np.array([2.0, 0.0, 0.0])
    assert segment_clear(centres, a, b, 0.99) and not segment_clear(centres, a, b, 1.01)   # abeam: 1 m
    assert not segment_clear(centres, a, np.array([4.5, 0.0, 0.0]), 0.6)                   # end: 0.5 m
    assert segment_clear(np.empty((0, 3)), a, b, 10.0) and segment_clear(centres, a, a, 1.4)


def test_emergency_beside_a_wall_is_left_to_dwa():
    lim = UAVLimits()
    occ = OccupancyMap((0.0, 0.0, 0.0), (10, 10, 30), 0.2)
    occ.integrate((1.0, 1.0, 3.0), [[1.5, 1.0, 3.1]], np.array([True]))   # a voxel 0.5 m beside the UAV
    pos = np.array([1.0, 1.0, 3.0])
    assert away_vertically(pos, occ, 0.4, lim, lateral_to_dwa=True) is None          # none within r_e: a neighbour's
    assert away_vertically(pos, occ, 0.4, lim, lateral_to_dwa=False) == 0.0
    assert away_vertically(pos, occ, 5.0, lim, lateral_to_dwa=True) is None
    assert away_vertically(pos, occ, 5.0, lim, lateral_to_dwa=False) == -lim.vz_max   # spec: away from it
    occ.integrate((1.0, 1.0, 2.9), [[1.0, 1.0, 3.3]], np.array([True]))   # nearer, and above
    assert away_vertically(pos, occ, 5.0, lim, lateral_to_dwa=True) == -lim.vz_max


def corridor_wall():
    """A full-height wall 0.6 m thick across the world with a 2.6 m opening on the line from start to goal."""
    return scenario(obstacles=[Box((10.0, -1.0, 0.0), (10.6, 11.7, 12.0)), Box((10.0, 14.3, 0.0), (10.6, 21.0, 12.0))],
                    start=(4.0, 13.0, 3.0), goal=(16.0, 13.0, 3.0), hi=(22.0, 20.0, 12.0), n_uavs=3)


def test_formation_passes_an_opening_in_single_file():
    """Followers whose slots lie behind the wall rejoin along A* paths on their own maps, through the opening."""
    penv, infos, _, states = fly(FusionExpert(), corridor_wall(), 600)
    assert infos["uav_0"]["success"] == 1 and not penv.unwrapped.crashed.any()
    in_opening = (states[:, :, 0] > 10.0) & (states[:, :, 0] < 10.6)
    assert np.all(in_opening.any(axis=0))                              # every UAV went through the opening
    assert np.all((states[:, :, 1][in_opening] > 11.7) & (states[:, :, 1][in_opening] < 14.3))
    assert np.all(states[:, :, 0].max(axis=0) < 17.0)                  # no detours past the goal either


def test_trail_rejoin_still_flies_the_opening_safely():
    """``rejoin="trail"`` (the earlier rule, kept for comparison) follows the leader's trail without collisions."""
    penv, _, _, states = fly(FusionExpert(ExpertConfig(rejoin="trail")), corridor_wall(), 300)
    assert not penv.unwrapped.crashed.any()
    assert np.any(states[:, 1:, 0] > 10.6)                            # a follower got through behind the leader


def test_dist_term_freezes_dwa_at_rest_and_the_final_approach_drops_it():
    """At rest beside a voxel (0.98 m away), the first 2 cm toward a goal 0.5 m ahead cost clearance below
    dist_cap: the expert's DWA stays at rest. Without the dist term (its final approach on a clear segment)
    it moves, and admissibility still guards the clearance."""
    cfg = ExpertConfig().dwa
    state = np.zeros(7)
    state[:3] = (0.0, 0.0, 3.0)
    voxel, goal = np.array([[0.6, -0.78, 3.0]]), np.array([0.5, 0.0])
    radius = np.full(1, 0.2 * math.sqrt(3.0) / 2.0)
    frozen = dwa_plan(state, UAVLimits(), cfg, goal, voxel, radius, lookahead=goal, v_ref=0.25)
    moving = dwa_plan(state, UAVLimits(), cfg.replace(beta=0.0), goal, voxel, radius, lookahead=goal, v_ref=0.25)
    assert frozen.admissible and frozen.v == 0.0
    assert moving.admissible and moving.v == pytest.approx(0.02) and moving.w == 0.0
