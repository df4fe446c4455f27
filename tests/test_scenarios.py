"""Scenarios: registry, determinism, feasibility of every generator, validation and the TOML format."""

import math
import os
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import ndimage

from uavform_env.config import UAVLimits
from uavform_env.formation import slot_offsets
from uavform_env.scenarios import (Mission, Scenario, ScenarioFileError, list_scenarios, load_scenario,
                                   make_scenario, scenario_options, validate_scenario)
from uavform_env.world import Box, Cylinder, Sphere

LIMITS = UAVLimits()
Z_REF = 3.0
R_CLEAR = LIMITS.r_uav + LIMITS.r_safe
NAMES = ["classic-2d", "corridor", "forest", "random-3d", "urban", "wall-gap"]  # the version-1 families
# These tests pin version 1 (start near x = 3, goal near x = 37, at z_ref); tests/test_world_v1.py covers version 2.
LEVEL_PASSABLE = ["classic-2d", "corridor", "forest", "random-3d", "urban"]  # wall-gap is built to block z_ref
EXAMPLES = sorted((Path(__file__).parents[1] / "examples" / "scenarios").glob("*.toml"))


def free_grid(scn, h, z_values):
    """Grid points (h apart) whose exact clearance is >= r_clear + h/2: the straight segment between two
    neighbouring free points then keeps clearance >= r_clear (clearance is 1-Lipschitz)."""
    lo, hi = np.array(scn.bounds_lo), np.array(scn.bounds_hi)
    axes = [np.arange(lo[0] + h / 2, hi[0], h), np.arange(lo[1] + h / 2, hi[1], h), np.asarray(z_values, float)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)
    free = scn.build_world().clearance(pts.reshape(-1, 3)) >= R_CLEAR + h / 2
    return axes, free.reshape(pts.shape[:3])


def connected(scn, h=0.3, z_values=None):
    """Whether one UAV can fly from start to goal inside the bounds and the altitude band (6-connected grid)."""
    z_values = np.arange(LIMITS.z_min, LIMITS.z_max + 1e-9, h) if z_values is None else z_values
    axes, free = free_grid(scn, h, z_values)
    labels, _ = ndimage.label(free)
    node = [tuple(int(np.abs(a - v).argmin()) for a, v in zip(axes, p)) for p in (scn.mission.start, scn.mission.goal)]
    return labels[node[0]] != 0 and labels[node[0]] == labels[node[1]]


def footprint_gap(a, b):
    """Horizontal distance between the footprints (rectangles or discs) of two primitives."""
    def shape(ob):
        return ("rect", np.array(ob.lo[:2]), np.array(ob.hi[:2])) if isinstance(ob, Box) else \
            ("disc", np.array([ob.x, ob.y]), ob.radius)
    (ka, *pa), (kb, *pb) = sorted([shape(a), shape(b)], key=lambda t: t[0])
    if ka == kb == "disc":
        return np.linalg.norm(pa[0] - pb[0]) - pa[1] - pb[1]
    if ka == "disc":  # disc and rectangle
        return np.linalg.norm(pa[0] - np.clip(pa[0], pb[0], pb[1])) - pa[1]
    return np.linalg.norm(np.maximum(0.0, np.maximum(pa[0] - pb[1], pb[0] - pa[1])))


def variant(name, seed):
    """Cycle through the difficulty levels with the seed so seeds 0-9 cover all of them."""
    levels = {"classic-2d": ["base", "extended"], "random-3d": ["easy", "medium", "hard"]}.get(name)
    return {"difficulty": levels[seed % len(levels)]} if levels else {}


# ---------------------------------------------------------------- registry and generators

def test_registry_names():
    assert list_scenarios() == sorted(NAMES + ["dog-leg"])


@pytest.mark.parametrize("name", NAMES)
def test_every_scenario_builds_validates_and_is_feasible(name):
    for seed in range(10):
        scn = make_scenario(f"{name}@1", seed, **variant(name, seed))
        world = scn.build_world()
        assert world.occupied.any()
        validate_scenario(scn, LIMITS, Z_REF)
        assert connected(scn), f"{name} seed {seed}: no path from start to goal"
        if name in LEVEL_PASSABLE:  # no gap is ever closed, so flying level at z_ref also works
            assert connected(scn, z_values=[Z_REF]), f"{name} seed {seed}: no level path at z_ref"


@pytest.mark.parametrize("name", ["forest", "urban", "random-3d"])
def test_footprints_leave_every_gap_passable(name):
    """The construction behind feasibility: inflated footprints never touch, so the free space stays connected."""
    for seed in range(10):
        obs = make_scenario(f"{name}@1", seed, **variant(name, seed)).obstacles
        gaps = [footprint_gap(a, b) for i, a in enumerate(obs) for b in obs[i + 1:]]
        assert min(gaps) >= 2 * R_CLEAR + 0.5, f"{name} seed {seed}"


@pytest.mark.parametrize("name, overrides", [
    ("forest", dict(n_uavs=7, formation="line", spacing=3.0)),
    ("urban", dict(n_uavs=6, formation="column")),
    ("random-3d", dict(n_uavs=4, formation="diamond", spacing=2.5, difficulty="hard")),
    ("corridor", dict(n_uavs=12, formation="column")),
    ("wall-gap", dict(n_uavs=9, formation="wedge", spacing=2.0)),
    ("classic-2d", dict(n_uavs=5, formation="wedge")),
])
def test_overrides_shape_the_clear_zones(name, overrides):
    for seed in range(3):
        scn = make_scenario(f"{name}@1", seed, **overrides)
        m = scn.mission
        for key in ("n_uavs", "formation", "spacing"):
            if key in overrides:
                assert getattr(m, key) == overrides[key]
        validate_scenario(scn, LIMITS, Z_REF)
        assert connected(scn)


def test_defaults():
    classic = make_scenario("classic-2d@1")
    m = classic.mission
    assert (m.n_uavs, m.start, m.goal) == (1, (0.0, 0.0, 3.0), (10.0, 10.0, 3.0))
    assert m.start_heading == pytest.approx(math.pi / 2)
    for name in NAMES[1:]:
        m = make_scenario(f"{name}@1", 4).mission
        assert (m.n_uavs, m.formation, m.spacing) == (5, "wedge", 2.0)
        assert m.start[0] == 3.0 and m.goal[0] == 37.0 and m.start[2] == m.goal[2] == Z_REF
        assert make_scenario(f"{name}@1", 4).resolution == 0.2


@pytest.mark.parametrize("name", NAMES)
def test_deterministic_and_versioned(name):
    a = make_scenario(f"{name}@1", 3)
    assert a == make_scenario(f"{name}@1", 3)
    assert (a.name, a.version, a.seed) == (name, 1, 3)
    assert make_scenario(name, 3) == make_scenario(f"{name}@2", 3) != a  # the newest version is the default
    if name != "classic-2d":
        assert make_scenario(f"{name}@1", 4) != a


def test_unknown_names_and_bad_arguments():
    with pytest.raises(ValueError, match="unknown scenario 'meadow'.*classic-2d, corridor, dog-leg, forest"):
        make_scenario("meadow")
    with pytest.raises(ValueError, match=r"no version '9'.*\[1, 2\]"):
        make_scenario("forest@9")
    with pytest.raises(ValueError, match="no version 'x'"):
        load_scenario("forest@x")
    with pytest.raises(ValueError, match="difficulty='hard' for scenario 'forest'.*no difficulty"):
        make_scenario("forest@1", difficulty="hard")
    with pytest.raises(ValueError, match=r"difficulty='insane'.*\['easy', 'medium', 'hard'\]"):
        make_scenario("random-3d@1", difficulty="insane")
    with pytest.raises(ValueError, match="at most 4"):
        make_scenario("forest@1", n_uavs=5, formation="diamond")
    with pytest.raises(ValueError, match="Mission.formation"):
        make_scenario("forest@1", formation="blob")
    with pytest.raises(ValueError, match="Mission.spacing"):
        make_scenario("urban@1", spacing=-1.0)
    with pytest.raises(ValueError, match="seed"):
        make_scenario("forest@1", seed=-1)


def test_classic_map():
    base, ext = make_scenario("classic-2d@1"), make_scenario("classic-2d@1", difficulty="extended")
    centres = [(c.x, c.y) for c in base.obstacles]
    assert centres == [(0, 2), (4, 2), (4, 4), (5, 4), (5, 5), (5, 6), (5, 9), (8, 8), (8, 9), (7, 9)]
    assert [(c.x, c.y) for c in ext.obstacles[10:]] == [(6, 5), (6, 3), (6, 8), (6, 7), (7, 4), (9, 8), (9, 11), (9, 6)]
    assert all(isinstance(c, Cylinder) and c.radius == 0.5 and c.z_lo == 0 and c.z_hi > LIMITS.z_max
               for c in ext.obstacles)
    assert base.bounds_lo[:2] == (-2.0, -2.0) and base.bounds_hi[:2] == (12.0, 12.0)


def test_forest_and_urban_mix_low_and_tall_obstacles():
    for name in ("forest", "urban"):
        tops = np.array([ob.z_hi if isinstance(ob, Cylinder) else ob.hi[2]
                         for seed in range(10) for ob in make_scenario(f"{name}@1", seed).obstacles])
        low = tops <= LIMITS.z_max - 2 * R_CLEAR  # a UAV passes over these inside the altitude band
        assert 0.15 < low.mean() < 0.5 and np.all(low | (tops > LIMITS.z_max)), name
    radii = [ob.radius for ob in make_scenario("forest@1").obstacles]
    assert 0.3 <= min(radii) and max(radii) <= 0.8 and len(radii) >= 40


def test_wall_gap_blocks_level_flight_only():
    sides = set()
    for seed in range(10):
        scn = make_scenario("wall-gap@1", seed)
        lower, upper = scn.obstacles
        gap_lo, gap_hi = lower.hi[2], upper.lo[2]
        assert gap_hi - gap_lo >= 2.0 and LIMITS.z_min <= gap_lo and gap_hi <= LIMITS.z_max
        assert lower.lo[1] < scn.bounds_lo[1] and lower.hi[1] > scn.bounds_hi[1] and upper.hi[2] > LIMITS.z_max
        sides.add("above" if gap_lo > Z_REF else "below")
        assert not connected(scn, z_values=[Z_REF]), f"seed {seed}: level flight at z_ref passes the wall"
    assert sides == {"above", "below"}


def test_corridor_is_narrower_than_the_formation_and_unavoidable():
    width = np.ptp(slot_offsets("wedge", 5, 2.0)[:, 1])
    for seed in range(10):
        scn = make_scenario("corridor@1", seed)
        south, north = scn.obstacles
        x = (south.lo[0] + south.hi[0]) / 2
        ys = np.arange(scn.bounds_lo[1], scn.bounds_hi[1], 0.02)
        for z in np.linspace(LIMITS.z_min, LIMITS.z_max, 7):
            free = scn.build_world().clearance(np.column_stack([np.full_like(ys, x), ys, np.full_like(ys, z)])) > 0
            assert 2 * R_CLEAR < free.sum() * 0.02 < 4.0 < width
        assert south.lo[1] < scn.bounds_lo[1] and north.hi[1] > scn.bounds_hi[1]
        assert min(south.hi[2], north.hi[2]) > LIMITS.z_max


def test_random_3d_difficulty_sets_density():
    def occupancy(level):
        worlds = [make_scenario("random-3d@1", s, difficulty=level).build_world() for s in range(3)]
        return np.mean([w.occupied.mean() for w in worlds])
    easy, medium, hard = occupancy("easy"), occupancy("medium"), occupancy("hard")
    assert easy < medium < hard
    kinds = {type(ob) for ob in make_scenario("random-3d@1", 0).obstacles}
    assert kinds == {Box, Cylinder, Sphere}
    assert make_scenario("random-3d@1", 0) == make_scenario("random-3d@1", 0, difficulty="medium")


@pytest.mark.parametrize("name", [f"{n}@{v}" for n in list_scenarios() for v in (1, 2)
                                  if not (n == "dog-leg" and v == 2)])
def test_scenario_options_are_what_make_scenario_accepts(name):
    options = scenario_options(name)
    for level in options["difficulties"]:
        assert make_scenario(name, 0, difficulty=level).mission
    with pytest.raises(ValueError, match="difficulty='nope'"):
        make_scenario(name, 0, difficulty="nope")
    teams = {make_scenario(name, s).mission.n_uavs for s in range(6)}
    assert teams == {options["n_uavs"]} if options["n_uavs"] is not None else len(teams) > 1


# ---------------------------------------------------------------- validation

def simple_scenario(**mission):
    m = dict(start=(5.0, 10.0, 3.0), goal=(25.0, 10.0, 3.0), start_heading=0.0, formation="wedge", spacing=2.0,
             n_uavs=3)
    m.update(mission)
    return Scenario(name="t", version=1, seed=None, bounds_lo=(0.0, 0.0, 0.0), bounds_hi=(30.0, 20.0, 12.0),
                    resolution=0.2, obstacles=(Cylinder(3.0, 13.5, 0.5, 0.0, 12.0), Sphere(25.0, 15.0, 3.0, 1.0)),
                    mission=Mission(**m))


def test_validate_accepts_a_good_scenario():
    validate_scenario(simple_scenario(), LIMITS, Z_REF)


@pytest.mark.parametrize("mission, match", [
    (dict(spacing=0.5), "spacing 0.5 m does not exceed two UAV radii"),
    (dict(formation="diamond", n_uavs=5), "at most 4"),
    (dict(formation="triangle", n_uavs=4), "at most 3"),
    (dict(start=(31.0, 10.0, 3.0)), r"leader start \(31.00.*outside the world bounds"),
    (dict(start=(1.0, 10.0, 3.0)), r"follower 1 start slot \(-1.00.*outside the world bounds"),
    (dict(start=(5.0, 10.0, 0.2)), "leader start.*outside the altitude band"),
    (dict(start=(5.0, 11.0, 3.0)), r"follower 1 start slot \(3.00, 13.00, 3.00\) has clearance 0.000 m < .* 0.5 m"),
    (dict(goal=(25.0, 14.5, 3.0)), "goal .* has clearance -0.500"),
])
def test_validate_rejects(mission, match):
    with pytest.raises(ValueError, match=match):
        validate_scenario(simple_scenario(**mission), LIMITS, Z_REF)


def test_validate_accepts_a_goal_outside_the_altitude_band_but_not_outside_the_world():
    """An unreachable goal is a mission, flown to the step limit (issue 13); a goal outside the world is an error."""
    validate_scenario(simple_scenario(goal=(25.0, 10.0, 10.5)), LIMITS, Z_REF)      # above z_max
    validate_scenario(simple_scenario(goal=(25.0, 10.0, 0.2)), LIMITS, Z_REF)       # below z_min
    with pytest.raises(ValueError, match="goal.*outside the world bounds"):
        validate_scenario(simple_scenario(goal=(25.0, 10.0, 40.0)), LIMITS, Z_REF)


def test_validate_uses_the_given_limits_and_altitude():
    scn = simple_scenario(start=(5.0, 10.5, 3.0))  # follower 1 slot (3, 12.5) is 0.5 m from the pole's surface
    with pytest.raises(ValueError, match="follower 1"):
        validate_scenario(scn, LIMITS.replace(r_safe=0.3), Z_REF)
    validate_scenario(scn, LIMITS.replace(r_safe=0.1), Z_REF)
    with pytest.raises(ValueError, match="follower 2 start slot.*altitude band"):
        validate_scenario(simple_scenario(), LIMITS, 11.0)
    with pytest.raises(ValueError, match="limits"):
        validate_scenario(simple_scenario(), {"r_uav": 0.3}, Z_REF)


def test_with_mission():
    scn = make_scenario("forest@1", 2)
    other = scn.with_mission(n_uavs=3, formation="triangle")
    assert other.obstacles == scn.obstacles and other.mission.n_uavs == 3 and scn.mission.n_uavs == 5
    with pytest.raises(ValueError, match="unknown field.*'speed'"):
        scn.with_mission(speed=2.0)
    with pytest.raises(ValueError, match="Mission.n_uavs"):
        scn.with_mission(n_uavs=0)


# ---------------------------------------------------------------- TOML files

@pytest.mark.parametrize("name", NAMES)
def test_toml_round_trip_of_every_generator(name, tmp_path):
    scn = make_scenario(f"{name}@1", 7, **variant(name, 7))
    scn.to_toml(tmp_path / "s.toml")
    assert Scenario.from_toml(tmp_path / "s.toml") == scn


finite = st.floats(-1e6, 1e6, allow_nan=False)
positive = st.floats(1e-3, 1e3, allow_nan=False)
obstacles = st.lists(st.one_of(
    st.builds(lambda p, d: Box(p, tuple(a + b for a, b in zip(p, d))), st.tuples(finite, finite, finite),
              st.tuples(positive, positive, positive)),
    st.builds(lambda x, y, r, z, h: Cylinder(x, y, r, z, z + h), finite, finite, positive, finite, positive),
    st.builds(Sphere, finite, finite, finite, positive)), max_size=5)


@settings(max_examples=30, deadline=None)
@given(obstacles, st.one_of(st.none(), st.integers(0, 2**63 - 1)), st.tuples(finite, finite, finite), finite)
def test_toml_round_trip_is_exact(tmp_path_factory, obs, seed, start, heading):
    scn = Scenario(name="field ü", version=3, seed=seed, bounds_lo=(-1e3 / 7, 0.1, 0.0), bounds_hi=(1e6, 1e6, 1e6),
                   resolution=1 / 3, obstacles=tuple(obs),
                   mission=Mission(start=start, goal=(1.0, 2.0, 3.0), start_heading=heading, formation="line",
                                   spacing=math.pi, n_uavs=7))
    path = tmp_path_factory.mktemp("rt") / "s.toml"
    scn.to_toml(path)
    assert Scenario.from_toml(path) == scn


def test_to_toml_is_atomic_and_overwrites(tmp_path):
    path = tmp_path / "out" / "s.toml"
    make_scenario("forest@1", 0).to_toml(path)
    second = make_scenario("urban@1", 1)
    second.to_toml(path)
    assert Scenario.from_toml(path) == second and os.listdir(path.parent) == ["s.toml"]


VALID = """\
[scenario]
name = "my-field"
version = 1
seed = 0
[world]
bounds_lo = [0.0, 0.0, 0.0]
bounds_hi = [40.0, 30.0, 12.0]
resolution = 0.2
[[obstacles]]
type = "box"
lo = [1.0, 2.0, 0.0]
hi = [3.0, 4.0, 8.0]
[[obstacles]]
type = "cylinder"
center = [10.0, 5.0]
radius = 0.5
z_lo = 0.0
z_hi = 9.0
[[obstacles]]
type = "sphere"
center = [20.0, 8.0, 3.0]
radius = 1.0
[mission]
start = [6.0, 15.0, 3.0]
goal = [37.0, 15.0, 3.0]
start_heading = 0.0
formation = "wedge"
spacing = 2.0
n_uavs = 5
"""


def test_valid_file_parses(tmp_path):
    (tmp_path / "ok.toml").write_text(VALID)
    scn = Scenario.from_toml(tmp_path / "ok.toml")
    assert scn.obstacles == (Box((1, 2, 0), (3, 4, 8)), Cylinder(10, 5, 0.5, 0, 9), Sphere(20, 8, 3, 1))
    assert scn.mission.start == (6.0, 15.0, 3.0) and scn.seed == 0
    validate_scenario(scn, LIMITS, Z_REF)


@pytest.mark.parametrize("old, new, entry, problem", [
    ("radius = 0.5\n", "", "obstacles[1]", "missing key 'radius'"),
    ("[mission]", "[missio]", "top level", "missing key 'mission'"),
    ('spacing = 2.0', 'spacing = "2.0"', "[mission].spacing", "expected a number, got str"),
    ("n_uavs = 5", "n_uavs = true", "[mission].n_uavs", "expected an integer, got bool"),
    ("start = [6.0, 15.0, 3.0]", "start = [6.0, 15.0]", "[mission].start", "expected a list of 3 numbers, got 2"),
    ("center = [10.0, 5.0]", "center = [10.0, 5.0, 1.0]", "obstacles[1].center", "expected a list of 2 numbers, got 3"),
    ("lo = [1.0, 2.0, 0.0]", "lo = [1.0, 'a', 0.0]", "obstacles[0].lo[1]", "expected a number"),
    ("radius = 1.0", "radius = -1.0", "obstacles[2]", "Sphere.radius=-1.0: expected a positive number"),
    ("hi = [3.0, 4.0, 8.0]", "hi = [3.0, 4.0, 0.0]", "obstacles[0]", "must be below Box.hi.*fails on z"),
    ("z_hi = 9.0", "z_hi = -1.0", "obstacles[1]", "Cylinder.z_lo=0.0 must be below"),
    ('type = "sphere"', 'type = "cone"', "obstacles[2].type", "unknown obstacle type 'cone'; expected one of box"),
    ("resolution = 0.2", "resolution = 0.2\nresolutoin = 0.1", "[world]", r"unknown key\(s\) \['resolutoin'\]"),
    ('type = "box"', 'type = "box"\ncolor = "red"', "obstacles[0]", r"unknown key\(s\) \['color'\]"),
    ("bounds_lo = [0.0, 0.0, 0.0]", "bounds_lo = [0.0, 0.0, 1.0]", "[world]", "expected z = 0"),
    ('formation = "wedge"', 'formation = "blob"', "[mission]", "Mission.formation='blob'"),
    ("version = 1", "version = 0", "[scenario]", "Scenario.version=0"),
    ("n_uavs = 5", "n_uavs = ", "TOML syntax error", r"line 29"),
])
def test_malformed_files_name_file_entry_and_problem(tmp_path, old, new, entry, problem):
    assert old in VALID
    path = tmp_path / "bad.toml"
    path.write_text(VALID.replace(old, new, 1))
    with pytest.raises(ScenarioFileError) as info:
        Scenario.from_toml(path)
    msg = str(info.value)
    assert isinstance(info.value, ValueError) and msg.startswith(f"{path}: ")
    assert entry in msg
    assert re.search(problem, msg), msg


def test_load_scenario(tmp_path):
    path = tmp_path / "f.toml"
    make_scenario("corridor@1", 5).to_toml(path)
    assert load_scenario(str(path)) == load_scenario(path) == make_scenario("corridor@1", 5)
    assert load_scenario("corridor", 5) == make_scenario("corridor@2", 5)
    assert load_scenario("random-3d@1", 2, difficulty="hard") == make_scenario("random-3d@1", 2, difficulty="hard")
    small = load_scenario(path, n_uavs=3, formation="triangle")
    assert (small.mission.n_uavs, small.mission.formation) == (3, "triangle")
    assert small.obstacles == make_scenario("corridor@1", 5).obstacles
    with pytest.raises(ValueError, match="difficulty.*fixed world"):
        load_scenario(path, difficulty="hard")
    with pytest.raises(FileNotFoundError):
        load_scenario(tmp_path / "missing.toml")


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_example_files(path):
    scn = load_scenario(path)
    validate_scenario(scn, LIMITS, Z_REF)
    assert connected(scn)
    assert len(EXAMPLES) >= 2


def _thin_reference(c, r, keep_out, kept_c, kept_r, zone, sep):
    """The numpy formulation of one hard-core round (the scenarios' code before the kernel), for comparison."""
    ok = np.hypot(c[:, None, 0] - keep_out[None, :, 0], c[:, None, 1] - keep_out[None, :, 1]).min(axis=1) - r >= zone
    if kept_r.size:
        to_kept = np.hypot(c[:, None, 0] - kept_c[None, :, 0], c[:, None, 1] - kept_c[None, :, 1])
        ok &= np.all(to_kept - r[:, None] - kept_r[None, :] >= sep, axis=1)
    pair = np.hypot(c[:, None, 0] - c[None, :, 0], c[:, None, 1] - c[None, :, 1]) - r[:, None] - r[None, :]
    return ok & ~np.any(np.tril(pair < sep, k=-1) & ok[None, :], axis=1)


@pytest.mark.parametrize("seed", range(6))
def test_hard_core_round_keeps_what_the_numpy_formulation_keeps(seed):
    from uavform_env.scenarios import _thin

    rng = np.random.default_rng(seed)
    c, r = rng.uniform(0, 30, (150, 2)), rng.uniform(0.3, 0.8, 150)
    keep_out = rng.uniform(0, 30, (10, 2))
    kept_c, kept_r = (rng.uniform(0, 30, (12 * (seed % 3), 2)), rng.uniform(0.3, 0.8, 12 * (seed % 3)))
    got = _thin(c, r, keep_out, kept_c, kept_r, 1.6, 2.2)
    want = _thin_reference(c, r, keep_out, kept_c, kept_r, 1.6, 2.2)
    assert 0 < want.sum() < want.size                    # the round both keeps and thins
    np.testing.assert_array_equal(got, want)
