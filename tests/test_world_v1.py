"""Mission variety, disturbances, honest endings and goal-slot checks (issue 12).

The first test pins version 1 of every generator bit for bit: the digest was computed on the code
before version 2 existed, from a serialisation written here (independent of the package's own TOML).
"""

import hashlib

import numpy as np
import pytest

from uavform_env.scenarios import make_scenario
from uavform_env.world import Box, Cylinder

V1_CASES = [("classic-2d@1", s, {}) for s in (0, 3)] + [("classic-2d@1", 1, {"difficulty": "extended", "n_uavs": 2,
                                                                         "formation": "column"})]
V1_CASES += [(f"{name}@1", s, {}) for name in ("forest", "urban", "wall-gap", "corridor") for s in (0, 1, 7)]
V1_CASES += [("random-3d@1", s, {"difficulty": d}) for s, d in ((0, "easy"), (1, "medium"), (2, "hard"))]
V1_CASES += [("forest@1", 4, {"n_uavs": 10}), ("urban@1", 5, {"n_uavs": 3, "formation": "triangle", "spacing": 2.5})]
V1_DIGEST = "d57e0ebdb7b7311e5af92447e9e8a9a12e701356bcc8cbba8f474f9846233347"


def _canonical(scn) -> str:
    """Every number as float.hex, so the digest changes with any bit of any field."""
    def h(values):
        return ",".join(float(v).hex() for v in values)
    parts = [scn.name, str(scn.version), str(scn.seed), h(scn.bounds_lo), h(scn.bounds_hi), float(scn.resolution).hex()]
    for ob in scn.obstacles:
        if isinstance(ob, Box):
            parts.append("box:" + h(ob.lo + ob.hi))
        elif isinstance(ob, Cylinder):
            parts.append("cyl:" + h((ob.x, ob.y, ob.radius, ob.z_lo, ob.z_hi)))
        else:
            parts.append("sph:" + h((ob.x, ob.y, ob.z, ob.radius)))
    m = scn.mission
    parts += [h(m.start), h(m.goal), float(m.start_heading).hex(), m.formation, float(m.spacing).hex(), str(m.n_uavs)]
    return "|".join(parts)


def v1_digest() -> str:
    text = "\n".join(_canonical(make_scenario(name, seed, **kw)) for name, seed, kw in V1_CASES)
    return hashlib.sha256(text.encode()).hexdigest()


def test_version_1_generators_are_frozen_bit_for_bit():
    assert v1_digest() == V1_DIGEST


# ---------------------------------------------------------------- version 2: variety and feasibility

import math  # noqa: E402

from uavform_env import parallel_env  # noqa: E402
from uavform_env.config import (DISTURBANCE_PRESETS, DisturbanceConfig, EnvConfig, UAVLimits,  # noqa: E402
                                disturbance_preset)
from uavform_env.env import END_REASONS, INFO_KEYS  # noqa: E402
from uavform_env.scenarios import Mission, Scenario, ScenarioFileError, validate_scenario  # noqa: E402
from uavform_env.world import Sphere  # noqa: E402

from .test_scenarios import connected, footprint_gap  # noqa: E402

LIMITS = UAVLimits()
OPEN = ["forest", "urban", "random-3d"]
STRUCTURED = ["corridor", "wall-gap", "dog-leg"]
TIERS = {"classic-2d": ["base", "extended"], "random-3d": ["easy", "medium", "hard"], "dog-leg": ["easy", "hard"]}


def newest(name, seed, **kw):
    levels = TIERS.get(name)
    return make_scenario(name, seed, **({"difficulty": levels[seed % len(levels)]} if levels and not kw else kw))


def bearing(m):
    return math.atan2(m.goal[1] - m.start[1], m.goal[0] - m.start[0])


@pytest.mark.parametrize("name", OPEN)
def test_open_missions_cover_the_circle_the_band_and_the_team_range(name):
    missions = [newest(name, s).mission for s in range(40)]
    octants = {int((bearing(m) + math.pi) // (math.pi / 4)) % 8 for m in missions}
    assert octants == set(range(8))
    for z in (np.array([m.start[2] for m in missions]), np.array([m.goal[2] for m in missions])):
        assert z.min() < 2.5 and z.max() > 6.5 and np.all((1.5 <= z) & (z <= 7.5))
    sizes = {m.n_uavs for m in missions}
    assert min(sizes) == 2 and max(sizes) >= 9 and len(sizes) >= 7
    assert len({m.formation for m in missions}) == 5 and len({m.spacing for m in missions}) > 10
    assert all(m.slot_altitude == "leader" for m in missions)
    assert all(m.start_heading == pytest.approx(bearing(m)) for m in missions)


@pytest.mark.parametrize("name", STRUCTURED)
def test_structured_missions_run_along_x_or_y_in_either_direction(name):
    directions = set()
    for seed in range(24):
        scn = newest(name, seed)
        m = scn.mission
        axis = np.array(m.goal[:2]) - np.array(m.start[:2])
        along = int(np.argmax(np.abs(axis)))
        directions.add((along, int(np.sign(axis[along]))))
        walls = [ob for ob in scn.obstacles]  # every wall spans the world across the mission's axis
        assert all(ob.lo[1 - along] < scn.bounds_lo[1 - along] or ob.hi[1 - along] > scn.bounds_hi[1 - along]
                   for ob in walls)
    assert directions == {(0, 1), (0, -1), (1, 1), (1, -1)}


def test_classic_2d_varies_its_start_pose():
    missions = [make_scenario("classic-2d", s).mission for s in range(10)]
    assert len({m.start for m in missions}) == 10 and len({m.start_heading for m in missions}) == 10
    assert all(m.goal == (10.0, 10.0, 3.0) and m.n_uavs == 1 for m in missions)


@pytest.mark.parametrize("name", sorted(set(OPEN + STRUCTURED + ["classic-2d"])))
def test_version_2_scenarios_validate_over_many_seeds_and_are_connected(name):
    for seed in range(30):
        validate_scenario(newest(name, seed), LIMITS, 3.0)
    for seed in range(3):
        scn = newest(name, seed)
        assert connected(scn, h=0.4), f"{name} seed {seed}: no path from start to goal"


@pytest.mark.parametrize("name", ["forest", "random-3d"])
def test_vectorised_scatter_keeps_every_gap_passable(name):
    for seed in range(6):
        obs = newest(name, seed).obstacles
        gaps = np.array([footprint_gap(a, b) for i, a in enumerate(obs) for b in obs[i + 1:]])
        assert gaps.min() >= 2 * (LIMITS.r_uav + LIMITS.r_safe) + 0.5 - 1e-9, seed
    assert len(newest("forest", 0).obstacles) >= 40


def test_dog_leg_hides_the_goal_at_every_altitude():
    for seed in range(12):
        scn = newest("dog-leg", seed)
        m = scn.mission
        t = np.linspace(0.0, 1.0, 400)[:, None]
        for z in np.linspace(LIMITS.z_min, LIMITS.z_max, 5):
            a, b = np.array([*m.start[:2], z]), np.array([*m.goal[:2], z])
            assert scn.build_world().clearance(a + t * (b - a)).min() < 0.0, seed
    assert len(newest("dog-leg", 1, difficulty="hard").obstacles) == 4


def test_team_overrides_and_drawn_shapes_fit():
    for seed in range(20):
        m = make_scenario("forest", seed, formation="triangle").mission
        assert m.formation == "triangle" and 2 <= m.n_uavs <= 3
        assert make_scenario("urban", seed, n_uavs=4).mission.n_uavs == 4
    # an override never shifts the rest of the stream: the same obstacles whatever the team
    a, b = make_scenario("wall-gap", 5), make_scenario("wall-gap", 5, n_uavs=2, formation="line", spacing=2.0)
    assert a.obstacles[0].lo[2] == b.obstacles[0].lo[2] and a.mission.start[2] == b.mission.start[2]


# ---------------------------------------------------------------- slot altitude

def test_version_2_followers_fly_their_slots_at_the_leader_altitude():
    penv = parallel_env(scenario="forest@2", n_uavs=4, formation="diamond", max_cycles=5)
    penv.reset(seed=3)
    env = penv.unwrapped
    z0 = env.scenario.mission.start[2]
    assert z0 != pytest.approx(3.0) and np.allclose(env.states[:, 2], z0)
    view = env.onboard("uav_2")
    assert view.slot_altitude == "leader" and view.slot[2] == pytest.approx(view.leader_state[2])
    penv.step({a: np.array([1.0, 0.0, 1.0], np.float32) for a in penv.agents})
    view = env.onboard("uav_2")
    assert view.slot[2] == pytest.approx(env.broadcast[0, 2]) and env.true_slots()[1, 2] == env.states[0, 2]
    v1 = parallel_env(scenario="forest@1", n_uavs=4, formation="diamond", max_cycles=5)
    v1.reset(seed=3)
    assert v1.unwrapped.onboard("uav_2").slot[2] == 3.0 and v1.unwrapped.slot_altitude == "z_ref"


# ---------------------------------------------------------------- disturbances

def test_presets_and_their_errors():
    assert set(DISTURBANCE_PRESETS) == {"calm", "breeze", "gusty", "noisy"}
    assert disturbance_preset("calm") == DisturbanceConfig()
    assert disturbance_preset("breeze").wind_std == 0.3
    gusty = disturbance_preset("gusty")
    assert gusty.wind_std == 1.0 and gusty.wind_mean != (0.0, 0.0)
    noisy = disturbance_preset("noisy")
    assert noisy.range_noise_std > 0 and 0 < noisy.ray_dropout < 1
    with pytest.raises(ValueError, match="unknown disturbance preset 'storm'; known presets: calm, breeze"):
        disturbance_preset("storm")
    with pytest.raises(ValueError, match=r"DisturbanceConfig.ray_dropout=1.0 is out of range"):
        DisturbanceConfig(ray_dropout=1.0)
    with pytest.raises(ValueError, match=r"DisturbanceConfig.wind_mean.y=20"):
        DisturbanceConfig(wind_mean=(0.0, 20))
    with pytest.raises(ValueError, match="unknown disturbance preset"):
        parallel_env(scenario="forest@1", disturbance="storm")
    assert parallel_env(scenario="forest@1", disturbance="breeze").config.disturbance.wind_std == 0.3
    assert EnvConfig.from_dict(EnvConfig(disturbance=gusty).to_dict()).disturbance == gusty


def _hover_positions(steps=10, **kwargs):
    penv = parallel_env(scenario="forest@1", n_uavs=2, formation="line", max_cycles=steps, **kwargs)
    penv.reset(seed=4)
    out = []
    for _ in range(steps):
        penv.step({a: np.array([-1.0, 0.0, 0.0], np.float32) for a in penv.agents})
        out.append(penv.unwrapped.states[:, :3].copy())
    return np.array(out), penv.unwrapped


def test_unopposed_steady_wind_pushes_by_its_mean():
    """With no wind authority (the airframe does not lean into the wind) the mean wind carries the UAVs whole; the
    default airframe's rejection is tested in tests/test_wind.py."""
    unopposed = EnvConfig(uav=UAVLimits(wind_authority=0.0))
    calm, _ = _hover_positions(config=unopposed)
    windy, _ = _hover_positions(config=unopposed, disturbance=DisturbanceConfig(wind_mean=(0.5, -0.2)))
    steps = np.arange(1, 11)[:, None] * 0.1
    np.testing.assert_allclose(windy[..., 0] - calm[..., 0], np.broadcast_to(0.5 * steps, (10, 2)), atol=1e-12)
    np.testing.assert_allclose(windy[..., 1] - calm[..., 1], np.broadcast_to(-0.2 * steps, (10, 2)), atol=1e-12)
    np.testing.assert_array_equal(windy[..., 2], calm[..., 2])


def test_sensor_faults_leave_the_wind_stream_and_the_world_alone():
    gusts, env_a = _hover_positions(disturbance=DisturbanceConfig(wind_std=1.0))
    faulty, env_b = _hover_positions(disturbance=DisturbanceConfig(wind_std=1.0, range_noise_std=0.1, ray_dropout=0.3))
    again, env_c = _hover_positions(disturbance=DisturbanceConfig(wind_std=1.0, range_noise_std=0.1, ray_dropout=0.3))
    np.testing.assert_array_equal(gusts, faulty)  # hovering UAVs: the same gusts whether the sensor is faulty or not
    assert env_a.scenario == env_b.scenario
    np.testing.assert_array_equal(env_b.last_scan.ranges, env_c.last_scan.ranges)  # faults are seeded
    lost = (env_b.last_scan.kind == 0) & (env_a.last_scan.kind != 0)
    assert lost.any()


# ---------------------------------------------------------------- honest endings

def _pen_scenario(**mission):
    m = dict(start=(5.0, 10.0, 3.0), goal=(5.2, 10.0, 3.0), start_heading=0.0, formation="line", spacing=2.0,
             n_uavs=2)
    m.update(mission)
    return Scenario(name="t", version=1, seed=None, bounds_lo=(0.0, 0.0, 0.0), bounds_hi=(30.0, 20.0, 12.0),
                    resolution=0.2, obstacles=(Sphere(20.0, 10.0, 3.0, 1.0),), mission=Mission(**m))


def test_success_needs_every_uav_flying_and_the_end_reason_says_why():
    penv = parallel_env(scenario=_pen_scenario(), max_cycles=1)
    _, infos = penv.reset(seed=0)
    assert set(infos["uav_0"]) == set(INFO_KEYS) and infos["uav_0"]["end_reason"] == 0
    env = penv.unwrapped
    env.states[1, :3] = (20.0, 10.0, 3.0)  # the follower inside the sphere; the leader sits on its goal
    _, _, _, _, infos = penv.step({a: np.zeros(3, np.float32) for a in penv.agents})
    assert infos["uav_1"]["crashed"] == 1 and infos["uav_1"]["crash_cause"] == 1
    assert infos["uav_0"]["success"] == 0 and not env.success
    assert END_REASONS[infos["uav_0"]["end_reason"]] == "crash-obstacle"
    assert all(isinstance(v, (int, float, bool)) for v in infos["uav_0"].values())
    from uavform_env.metrics import episode_metrics, episode_outcome
    assert episode_metrics(env)["collision"] == 1.0 and episode_metrics(env)["success"] == 0.0
    assert episode_outcome(env) == ("crash-obstacle", "uav_1 (follower 1) crashed into an obstacle at step 1 "
                                                    "(t = 0.1 s)")


def test_success_and_timeout_end_reasons():
    penv = parallel_env(scenario=_pen_scenario(), max_cycles=3)
    penv.reset(seed=0)
    _, _, term, _, infos = penv.step({a: np.zeros(3, np.float32) for a in penv.agents})
    assert term["uav_0"] and END_REASONS[infos["uav_0"]["end_reason"]] == "success"
    penv = parallel_env(scenario=_pen_scenario(goal=(15.0, 10.0, 3.0)), max_cycles=2)
    penv.reset(seed=0)
    for _ in range(2):
        _, _, _, trunc, infos = penv.step({a: np.zeros(3, np.float32) for a in penv.agents})
    assert trunc["uav_0"] and END_REASONS[infos["uav_0"]["end_reason"]] == "timeout"


# ---------------------------------------------------------------- scenario files

# A pen with 1 m walls: inside 1.9 x 1.4 m, outside 3.9 x 3.4 m, so a point 2 m from its centre is never
# 0.5 m clear of a wall.
PEN = [Box((3.3, 8.3, 0.0), (7.2, 9.3, 12.0)), Box((3.3, 10.7, 0.0), (7.2, 11.7, 12.0)),
       Box((3.3, 9.3, 0.0), (4.3, 10.7, 12.0)), Box((6.2, 9.3, 0.0), (7.2, 10.7, 12.0))]


def test_blocked_goal_slots_in_a_file_fail_before_anything_runs(tmp_path, capsys):
    """The goal (5.25, 10) sits in a pen: a 2 m line formation fits there at no heading."""
    scn = Scenario(name="pen", version=1, seed=None, bounds_lo=(0.0, 0.0, 0.0), bounds_hi=(30.0, 20.0, 12.0),
                   resolution=0.2, obstacles=tuple(PEN),
                   mission=Mission(start=(20.0, 10.0, 3.0), goal=(5.25, 10.0, 3.0), start_heading=math.pi,
                                   formation="line", spacing=2.0, n_uavs=2))
    path = tmp_path / "pen.toml"
    scn.to_toml(path)
    with pytest.raises(ScenarioFileError, match=r"pen.toml cannot be flown: .*goal slots are blocked at every heading.*follower 1"):
        parallel_env(scenario=str(path))
    parallel_env(scenario=str(path), n_uavs=1)  # the leader alone fits
    from uavform_env.cli import main
    assert main(["fly", "--scenario", str(path), "--out", str(tmp_path / "run"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "pen.toml" in err and "goal slots are blocked" in err


def test_disturbance_table_in_a_scenario_file(tmp_path):
    scn = _pen_scenario(goal=(15.0, 10.0, 6.0), slot_altitude="leader")
    path = tmp_path / "s.toml"
    scn.to_toml(path)
    text = path.read_text()
    assert "slot_altitude" in text
    path.write_text(text + '\n[disturbance]\npreset = "gusty"\nray_dropout = 0.2\n')
    loaded = Scenario.from_toml(path)
    assert loaded.mission == scn.mission
    assert loaded.disturbance == disturbance_preset("gusty").replace(ray_dropout=0.2)
    loaded.to_toml(tmp_path / "again.toml")
    assert Scenario.from_toml(tmp_path / "again.toml") == loaded
    assert parallel_env(scenario=str(path)).config.disturbance == loaded.disturbance
    assert parallel_env(scenario=str(path), disturbance="calm").config.disturbance == DisturbanceConfig()
    for extra, match in (('preset = "storm"', r"\[disturbance\].preset: unknown disturbance preset 'storm'"),
                         ("wind_std = 11.0", r"\[disturbance\]: DisturbanceConfig.wind_std=11.0 is out of range"),
                         ("gust = 1.0", r"\[disturbance\]: unknown key\(s\) \['gust'\]")):
        path.write_text(text + f"\n[disturbance]\n{extra}\n")
        with pytest.raises(ScenarioFileError, match="s.toml: " + match):
            Scenario.from_toml(path)


def test_fly_names_a_wind_preset(tmp_path, capsys):
    import json

    from uavform_env.cli import main
    out = tmp_path / "run"
    assert main(["fly", "--policy", "hover", "--wind", "gusty", "--max-steps", "3", "--out", str(out), "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["wind"] == "gusty" and summary["outcome"] == "time-out" and "step limit (3 steps)" in summary["reason"]
    with pytest.raises(SystemExit):
        main(["fly", "--wind", "storm"])
    assert "invalid choice: 'storm'" in capsys.readouterr().err


@pytest.mark.parametrize("name", sorted(set(OPEN + STRUCTURED + ["classic-2d"])))
def test_version_2_toml_round_trip(name, tmp_path):
    scn = newest(name, 7)
    scn.to_toml(tmp_path / "s.toml")
    assert Scenario.from_toml(tmp_path / "s.toml") == scn and scn.version == (1 if name == "dog-leg" else 2)
