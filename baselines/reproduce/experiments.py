"""Experiments E1-E6 of spec (h2) as data, and the function that plays one run of them.

An experiment is a list of settings (a seed -> ``Scenario`` builder and an episode length) and a list
of variants (a named ``ExpertConfig``); a run is one (experiment, setting, variant, seed). Every run
is one episode of ``FusionExpert`` in ``FormationEnv``: the UAVs sense the world with their own
range sensor and map (the paper's unknown environment), and every metric comes from
``uavform_env.metrics.episode_metrics``. Scenarios not registered in ``uavform_env.scenarios`` are
built here from world primitives; the registered ones are used as they are. Nothing depends on the
seed except the scenario, so nothing is tuned per seed.
"""

from __future__ import annotations

import json
import math
import time
import traceback
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable

import numpy as np

from uavform_env.config import FormationConfig, MapConfig, UAVLimits
from uavform_env.evaluation.runner import code_version
from uavform_env.files import append_line, atomic_write_json, read_jsonl, set_aside_torn_line
from uavform_env.parallel import imap_unordered
from uavform_env.formation import slot_offsets, slot_positions
from uavform_env.formation_v0 import parallel_env
from uavform_env.rollout import run_episode
from uavform_env.scenarios import Mission, Scenario, make_scenario
from uavform_env.world import Box, Cylinder

from ..astar import AStarConfig
from ..dwa import DWAConfig
from ..expert import ExpertConfig, FusionExpert

FIGURE_SEED = 0                       # the seed whose runs keep a trace (and a picture) for the report's figures
Z_REF = FormationConfig().z_ref       # the altitude every mission starts and ends at
RESOLUTION = MapConfig().resolution   # the voxel size of every registered scenario
CEILING = UAVLimits().z_max + 2.0     # world top, as in the registered scenarios: "tall" obstacles reach it
R_DISC = 0.5                          # spec (h2) E1: disc obstacles of radius 0.5 m


@dataclass(frozen=True)
class Setting:
    """One world of an experiment: ``build(seed)`` gives the scenario; ``max_cycles`` its episode length."""

    name: str
    build: Callable[[int], Scenario]
    max_cycles: int
    quick_cycles: int
    description: str
    picture: bool = False  # seed FIGURE_SEED also writes the full trajectory picture (render.plot_episode)
    seeds: int | None = None  # this world's seed count, when it differs from the experiment's


@dataclass(frozen=True)
class Variant:
    name: str
    config: Callable[[], ExpertConfig]
    description: str


@dataclass(frozen=True)
class Experiment:
    id: str
    title: str
    settings: tuple[Setting, ...]
    variants: tuple[Variant, ...]
    seeds: int          # default number of seeds (0 .. seeds-1)
    quick_settings: tuple[str, ...]  # the settings --quick keeps (one seed, quick_cycles steps)
    setup: str          # parameters and [X]/[D] choices, Markdown


def _scenario(name, obstacles, start, goal, heading, hi, n_uavs=1, formation="column", spacing=2.0) -> Scenario:
    return Scenario(name=name, version=1, seed=None, bounds_lo=(0.0, 0.0, 0.0), bounds_hi=(hi[0], hi[1], CEILING),
                    resolution=RESOLUTION, obstacles=tuple(obstacles),
                    mission=Mission(start=(start[0], start[1], Z_REF), goal=(goal[0], goal[1], Z_REF),
                                    start_heading=heading, formation=formation, spacing=spacing, n_uavs=n_uavs))


def _column(x, y, r=R_DISC) -> Cylinder:
    return Cylinder(float(x), float(y), float(r), 0.0, CEILING)


# ------------------------------------------------------------------------------------------------ E1
def classic(difficulty: str) -> Callable[[int], Scenario]:
    """The registered classic map; seed 0 is the spec's start (0, 0, pi/2), other seeds jitter the start
    by up to 0.25 m and 15 degrees [D] so the mean and interval cover more than one trajectory."""
    def build(seed: int) -> Scenario:
        scn = make_scenario("classic-2d", difficulty=difficulty)
        if seed == 0:
            return scn
        rng = np.random.default_rng([1, seed])
        dx, dy = rng.uniform(-0.25, 0.25, 2)
        turn = rng.uniform(-1, 1) * math.radians(15)
        return scn.with_mission(start=(dx, dy, Z_REF), start_heading=math.pi / 2 + turn)
    return build


# ------------------------------------------------------------------------------------------------ E2
def u_trap(seed: int) -> Scenario:
    """20 x 20 m: a U of full-height 0.4 m walls open toward the start, the goal straight behind it [D].

    The U is 5-7 m wide and 3-4.5 m deep, its centre line within 1 m of the start-goal line."""
    rng = np.random.default_rng([2, seed])
    width, depth, y0 = rng.uniform(5.0, 7.0), rng.uniform(3.0, 4.5), 10.0 + rng.uniform(-1.0, 1.0)
    back, t = 12.0, 0.4
    obstacles = [Box((back, y0 - width / 2, 0.0), (back + t, y0 + width / 2, CEILING)),
                 Box((back - depth, y0 - width / 2 - t, 0.0), (back + t, y0 - width / 2, CEILING)),
                 Box((back - depth, y0 + width / 2, 0.0), (back + t, y0 + width / 2 + t, CEILING))]
    return _scenario("u-trap", obstacles, (3.0, 10.0), (17.0, 10.0), 0.0, (20.0, 20.0))


def dense_field(seed: int) -> Scenario:
    """20 x 20 m with 15-30 full-height discs of R = 0.5 m (spec (h2) E2), centres >= 2.2 m apart and
    >= 2 m from start (2, 2) and goal (18, 18) [D]; the UAV starts facing the goal."""
    rng = np.random.default_rng([3, seed])
    count = int(rng.integers(15, 31))
    tries = rng.uniform(1.0, 19.0, (40 * count, 2))
    ends = np.array([(2.0, 2.0), (18.0, 18.0)])
    tries = tries[np.min(np.linalg.norm(tries[:, None] - ends[None], axis=2), axis=1) >= 2.0]
    kept: list[np.ndarray] = []
    for c in tries:
        if len(kept) == count:
            break
        if not kept or np.min(np.linalg.norm(np.asarray(kept) - c, axis=1)) >= 2.2:
            kept.append(c)
    return _scenario("dense-field", [_column(x, y) for x, y in kept], (2.0, 2.0), (18.0, 18.0), math.pi / 4,
                     (20.0, 20.0))


# ------------------------------------------------------------------------------------------------ E3
def goal_beside_obstacle(seed: int) -> Scenario:
    """The goal 3-5 m ahead of the start, a disc (R = 0.5 m) 1.0-1.4 m beside it, and the UAV starting
    with its back to the goal [D]: it has to turn round and settle next to an obstacle."""
    rng = np.random.default_rng([4, seed])
    start, dist = np.array([6.0, 7.0]), rng.uniform(3.0, 5.0)
    goal = start + (dist, 0.0)
    side, offset, along = rng.choice([-1.0, 1.0]), rng.uniform(1.0, 1.4), rng.uniform(-0.5, 0.5)
    return _scenario("goal-beside-obstacle", [_column(goal[0] + along, goal[1] + side * offset)], start, goal, math.pi,
                     (16.0, 14.0))


# ------------------------------------------------------------------------------------------------ E4, E5
def block_world(n_uavs: int, formation: str) -> Callable[[int], Scenario]:
    """30 x 30 x 10 m [D]: 10 tall columns (R 0.4-0.8 m) up to the world top, and 8 low boxes (1.6-3 m
    wide, tops 3.2-4 m, above z_ref = 3 m) centred within 5 m of the start-goal line; footprints keep
    1.6 m apart and clear of every start and goal slot."""
    def build(seed: int) -> Scenario:
        rng = np.random.default_rng([5, seed])
        start, goal = np.array([6.0, 15.0 + rng.uniform(-2, 2)]), np.array([26.0, 15.0 + rng.uniform(-2, 2)])
        heading = math.atan2(*(goal - start)[::-1])
        offsets = slot_offsets(formation, n_uavs, 2.0)
        zones = np.vstack([slot_positions(p, heading, offsets, Z_REF)[:, :2] for p in (start, goal)])
        discs: list[tuple[float, float, float, bool]] = []         # x, y, footprint radius, tall

        def place(count, centre_lo, centre_hi, radius_range, tall):
            for _ in range(60 * count):
                if sum(d[3] == tall for d in discs) == count:
                    return
                c, r = rng.uniform(centre_lo, centre_hi), rng.uniform(*radius_range)
                if np.min(np.linalg.norm(zones - c, axis=1)) - r < 1.5:
                    continue
                if discs and min(math.dist(c, d[:2]) - r - d[2] for d in discs) < 1.6:
                    continue
                discs.append((c[0], c[1], r, tall))

        place(8, (start[0] + 3, 10.0), (goal[0] - 3, 20.0), (0.8, 1.5), False)
        place(10, (1.0, 1.0), (29.0, 29.0), (0.4, 0.8), True)
        obstacles = []
        for x, y, r, tall in discs:
            if tall:
                obstacles.append(Cylinder(x, y, r, 0.0, CEILING))
            else:
                h = r / math.sqrt(2.0)
                obstacles.append(Box((x - h, y - h, 0.0), (x + h, y + h, rng.uniform(3.2, 4.0))))
        return _scenario("block-world", obstacles, start, goal, heading, (30.0, 30.0), n_uavs, formation)
    return build


def registered(name: str) -> Callable[[int], Scenario]:
    def build(seed: int) -> Scenario:
        return make_scenario(name, seed=seed)
    return build


# ------------------------------------------------------------------------------------------------ E6
def turnaround(n_uavs: int, formation: str, spacing: float) -> Callable[[int], Scenario]:
    """An open 24 x 20 m field; the formation starts facing away from a goal 8-10 m behind it (bearing
    jittered by up to 20 degrees) [D]. The leader has to turn round past its followers, whose slots swing
    round it and cross each other's paths: every UAV has to pass its neighbours. ``spacing`` below the
    default 2 m makes the conflicts close."""
    def build(seed: int) -> Scenario:
        rng = np.random.default_rng([6, seed])
        start = np.array([14.0, 10.0])
        bearing = math.pi + rng.uniform(-1, 1) * math.radians(20)
        goal = start + rng.uniform(8.0, 10.0) * np.array([math.cos(bearing), math.sin(bearing)])
        return _scenario(f"turnaround-{formation}", [], start, goal, 0.0, (24.0, 20.0), n_uavs, formation, spacing)
    return build


# ------------------------------------------------------------------------------------------------ variants
def planar(ablation: str) -> Variant:
    return Variant(ablation, lambda: ExpertConfig.planar(ablation),
                   f"`ExpertConfig.planar(\"{ablation}\")`: fixed altitude, no 3D VFH+, band raster, "
                   f"`DWAConfig.ablation(\"{ablation}\")` with the spec's defaults")


DWA_ABLATIONS = tuple(planar(a) for a in ("DWA", "DWA+E8", "DWA+E8+E10", "IDWA"))
IDWA_LOOKAHEAD = Variant("IDWA+lookahead", lambda: ExpertConfig.planar("IDWA", astar=AStarConfig(
    prune=True, heading_target="lookahead")), "IDWA heading for the A* lookahead point instead of the goal "
    "(`AStarConfig.heading_target=\"lookahead\"`, spec (d6)) [X: a deviation from the paper, run to show why "
    "the paper-faithful variants stay trapped]")
E8_PROFILE = Variant("DWA+E8+profile", lambda: replace(ExpertConfig.planar("DWA+E8"), dwa=DWAConfig.ablation(
    "DWA+E8", approach_speed_profile=True, r_goal=0.1)), "DWA+E8 with the approach speed profile of (c1) braking "
    "toward 0.1 m from the goal, as the fusion expert does (`DWAConfig.approach_speed_profile=True, r_goal=0.1`) "
    "[X: off in the paper-faithful variants, run to show what the orbit comes from]")
FUSION = Variant("fusion", ExpertConfig, "`ExpertConfig()`: the fused controller (3D VFH+ vertical decision, 3D-aware "
                 "DWA clearance, 'passable' A* raster)")
IDWA_2D = Variant("IDWA-2D", lambda: replace(ExpertConfig(), use_vfh=False, astar_layer="band"),
                  "`ExpertConfig(use_vfh=False, astar_layer=\"band\")`: the same controller and DWA weights held at "
                  "z_ref, obstacles projected to the flight band [X: the fusion's DWA settings, so only the third "
                  "dimension differs]")
NO_PREDICTION = Variant("no-prediction", lambda: ExpertConfig(neighbour_prediction=False),
                        "`ExpertConfig(neighbour_prediction=False)`: neighbours enter DWA at their broadcast "
                        "position with zero velocity (and the (g6) yield rule sees them standing)")
PREDICTION = Variant("prediction", ExpertConfig, "`ExpertConfig()`: neighbours move at their broadcast velocity over "
                     "the DWA horizon (g6)")

_PLANAR_SETUP = ("Single UAV, planar: altitude held at z_ref = 3 m, obstacles are full-height columns. "
                 "UAV limits (Appendix A): v_max 1 m/s, w_max 20 deg/s, a_max 0.2 m/s^2, dw_max 50 deg/s^2, "
                 "dt 0.1 s, r_uav 0.3 m, r_safe 0.2 m. DWA (b): T_p 3 s, alpha 0.1, beta 0.2, gamma 0.1, "
                 "D_cap 2 m, sum normalisation [R]; IDWA (c): alpha0 0.1, kappa 0.2, R_sw 3 m, "
                 "heading_ref endpoint [X], astar_weight_mode per_candidate [X], eps0 0.05, d_in 0.3 m, "
                 "d_out 2 m, rotation_mode abs [X], rot_weight_mode proximity [X] [D]. A* (d): res_g 0.5 m, "
                 "octile, no corner cutting, line-of-sight pruning on [X, deviation], L_a 3 m, heading_target "
                 "goal. The map is the UAV's own OctoMap from its range sensor (unknown environment). "
                 "Success: within r_goal = 0.5 m of the goal (env).")

EXPERIMENTS = (
    Experiment(
        "E1", "Classic 2D map: standard vs improved DWA and the ablation", (
            Setting("base", classic("base"), 1500, 1500, "the classic MATLAB map, 10 discs (R = 0.5 m), start "
                    "(0, 0, pi/2), goal (10, 10) [R]"),
            Setting("extended", classic("extended"), 1500, 1500, "the same plus the 8 discs of the extended set [R]"),
        ), DWA_ABLATIONS, 5, ("base",),
        _PLANAR_SETUP + " Seeds: seed 0 is the spec's start; seeds 1-4 move the start by up to 0.25 m and turn it "
        "by up to 15 deg [D]. Episode: 1500 steps (150 s)."),
    Experiment(
        "E2", "Traps: a U-trap and random dense fields", (
            Setting("u-trap", u_trap, 600, 300, "a U of full-height walls open toward the start, goal behind it"),
            Setting("dense", dense_field, 600, 300, "20 x 20 m, 15-30 discs of R = 0.5 m"),
        ), DWA_ABLATIONS + (IDWA_LOOKAHEAD,), 8, ("u-trap",),
        _PLANAR_SETUP + " 8 seeds per world (spec (h2) asks for 20; fewer to keep the default run affordable). "
        "Episode: 600 steps (60 s; the straight line is 14-23 m). "
        "A run that has not arrived at the end of the episode counts as trapped."),
    Experiment(
        "E3", "Goal beside an obstacle, start facing away", (
            Setting("beside", goal_beside_obstacle, 600, 600, "goal 3-5 m behind the UAV, a disc 1.0-1.4 m beside "
                    "the goal"),
        ), DWA_ABLATIONS[:2] + (E8_PROFILE,), 8, ("beside",),
        _PLANAR_SETUP + " 8 seeds. Episode: 600 steps (60 s)."),
    Experiment(
        "E4", "Single UAV in 3D: fixed-altitude IDWA vs fusion", (
            Setting("blocks", block_world(1, "column"), 1200, 500, "30 x 30 x 10 m, tall columns and low blocks"),
        ), (IDWA_2D, FUSION), 6, ("blocks",),
        "Single UAV, z_ref = 3 m, z in [0.5, 10] m. World 30 x 30 m [D]: 10 tall columns (R 0.4-0.8 m) to the world "
        "top (12 m; the spec's 8 m columns could be flown over with z_max = 10 m, so 'tall' is made unpassable) "
        "and 8 low boxes 1.6-3 m wide with tops 3.2-4 m (spec 2-4 m; lower tops lie under the flight band "
        "z_ref +- 0.5 m and would not be obstacles for either controller), within 5 m of the start-goal line. "
        "Start x = 6 m, goal x = 26 m. Fusion: ExpertConfig defaults (docs/deviations.md), incl. the DWA "
        "approach speed profile on [X] and r_goal 0.1 m for DWA's braking [X]; 3D VFH+ (f): alpha_h 5 deg, "
        "R_w 5 m, tau 0.3/0.9, k1..k3 = 5, 2, 2 [D], enlargement ceil_2d. 6 seeds. Episode: 1200 steps (120 s)."),
    Experiment(
        "E5", "Five-UAV wedge: planar IDWA formation vs fused formation", (
            Setting("blocks", block_world(5, "wedge"), 1200, 300, "the E4 world with a 5-UAV wedge"),
            Setting("corridor", registered("corridor"), 1200, 300, "registered `corridor`: a 2.5-3.5 m corridor, "
                    "10-14 m long, narrower than the 8 m wedge"),
            Setting("wall-gap", registered("wall-gap"), 2000, 300, "registered `wall-gap`: the only passage is "
                    "above or below z_ref", picture=True, seeds=1),
            Setting("urban", registered("urban"), 2000, 300, "registered `urban`: buildings, some can be flown "
                    "over", picture=True, seeds=1),
        ), (IDWA_2D, FUSION), 2, ("corridor",),
        "N = 5, wedge, spacing s = 2 m, z_ref = 3 m, k_f 0.5, k_h 1, k_z 0.5, leader speed cap 0.8 v_max, "
        "e0 1.5 m / e1 5 m / min leader scale 0.5 (spec 1 m, 3 m, 0.3; docs/deviations.md), e_f 0.5 m, "
        "R_uu 0.8 m, debounce 3, T_stuck 5 s, shape switching on (g7). Both variants share every setting except "
        "use_vfh and the A* raster layer. Time to re-form: from the last moment some follower was more than "
        "1 m from its slot until all are within e_f (metrics.episode_metrics). Seeds: 2 for blocks and "
        "corridor, 1 (seed 0, the pictures) for wall-gap and urban (cost: a 5-UAV episode takes 20-60 s on this "
        "machine). Episodes: 1200 steps (blocks, corridor), 2000 (wall-gap, urban)."),
    Experiment(
        "E6", "Conflicts between UAVs: with and without neighbour prediction", (
            Setting("head-on", turnaround(3, "column", 1.2), 600, 300, "3-UAV column facing away from the goal: "
                    "the leader has to turn round past the followers lined up behind it, toward the goal"),
            Setting("crossing", turnaround(5, "wedge", 1.2), 600, 300, "5-UAV wedge facing away from the goal: "
                    "while the leader turns round, the slots swing round it and the followers' paths cross"),
        ), (PREDICTION, NO_PREDICTION), 4, ("head-on", "crossing"),
        "Open field, no obstacles; goal 8-10 m behind the formation, bearing jittered by up to 20 deg; formation "
        "spacing 1.2 m instead of 2 m, so turning round brings the UAVs within a few R_uu of each other [D]. "
        "R_uu = 2 r_uav + r_safe = 0.8 m [D]; the env counts a collision below 2 r_uav = 0.6 m. The switch is "
        "the existing `ExpertConfig.neighbour_prediction` (default True). A moving obstacle is not run: the "
        "env's worlds are static (uavform_env.world has boxes, cylinders and spheres only), so the spec's "
        "moving-obstacle case cannot be flown without new env code. 4 seeds. Episode: 600 steps (60 s)."),
)


def experiment(exp_id: str) -> Experiment:
    for e in EXPERIMENTS:
        if e.id == exp_id:
            return e
    raise ValueError(f"experiment {exp_id!r}: expected one of {[e.id for e in EXPERIMENTS]}")


@dataclass(frozen=True)
class Run:
    experiment: str
    setting: str
    variant: str
    seed: int
    max_cycles: int

    @property
    def key(self) -> str:
        return f"{self.experiment}/{self.setting}/{self.variant}/{self.seed}"


def plan_runs(seeds: int | None = None, quick: bool = False) -> list[Run]:
    """Every run of E1-E6. ``quick``: the ``quick_settings`` only, seed 0, ``quick_cycles`` steps;
    ``seeds`` overrides every experiment's seed count."""
    if seeds is not None and (isinstance(seeds, bool) or not isinstance(seeds, int) or seeds < 1):
        raise ValueError(f"seeds={seeds!r}: expected an integer >= 1")
    runs = []
    for e in EXPERIMENTS:
        for s in e.settings:
            if quick and s.name not in e.quick_settings:
                continue
            n = seeds if seeds is not None else (1 if quick else s.seeds or e.seeds)
            for v in e.variants:
                runs += [Run(e.id, s.name, v.name, k, s.quick_cycles if quick else s.max_cycles) for k in range(n)]
    return runs


def _parts(run: Run) -> tuple[Experiment, Setting, Variant]:
    e = experiment(run.experiment)
    setting = next((s for s in e.settings if s.name == run.setting), None)
    variant = next((v for v in e.variants if v.name == run.variant), None)
    if setting is None or variant is None:
        raise ValueError(f"run {run.key!r}: unknown setting or variant of {e.id}")
    return e, setting, variant


def scenario_of(run: Run) -> Scenario:
    return _parts(run)[1].build(run.seed)


def _trace(env, stride: int) -> dict:
    """Downsampled per-step series for the figures: time, positions, leader yaw and yaw rate, goal
    distance, worst follower slot error and the smallest pairwise separation."""
    h = env.history
    pos = np.asarray(h["positions"])[::stride]
    ferr = np.asarray(h["formation_error"])[::stride]
    n = pos.shape[1]
    if n > 1:
        d = np.linalg.norm(pos[:, :, None] - pos[:, None], axis=3)
        iu = np.triu_indices(n, 1)
        sep = d[:, iu[0], iu[1]].min(axis=1)
        worst = ferr[:, 1:].max(axis=1)
    else:
        sep = worst = np.full(len(pos), math.nan)
    return {"t": np.round(np.arange(len(pos)) * stride * env.config.uav.dt, 2).tolist(),
            "pos": np.round(pos, 3).tolist(),
            "yaw": np.round(np.asarray(h["yaw"])[::stride, 0], 4).tolist(),
            "w": np.round(np.asarray(h["w"])[::stride, 0], 4).tolist(),
            "goal_distance": np.round(np.linalg.norm(pos[:, 0, :2] - np.asarray(env.goal)[:2], axis=1), 3).tolist(),
            "formation_error_max": np.round(worst, 3).tolist(),
            "separation_min": np.round(sep, 3).tolist()}


def play(run: Run, picture_dir: str | None = None) -> dict:
    """Play one run and return its record (never raises: an exception becomes a ``failed`` record).

    Runs of ``FIGURE_SEED`` keep a trace; with ``picture_dir`` a picture setting also writes its
    trajectory picture there. A top-level function of plain data, so a process pool can ship it.
    """
    from uavform_env.render import plot_episode

    record = {"key": run.key, "experiment": run.experiment, "setting": run.setting, "variant": run.variant,
              "seed": run.seed, "max_cycles": run.max_cycles}
    start = time.perf_counter()
    try:
        _, setting, variant = _parts(run)
        penv = parallel_env(scenario=setting.build(run.seed), max_cycles=run.max_cycles)
        metrics = run_episode(penv, FusionExpert(variant.config()), run.seed)
        env = penv.unwrapped
        record.update(status="ok", steps=int(env.step_count), metrics=metrics, error=None)
        if run.seed == FIGURE_SEED:
            record["trace"] = _trace(env, 1 if env.n_uavs == 1 else 5)
            if setting.picture and picture_dir is not None:
                name = f"{run.experiment}-{run.setting}-{run.variant}.png".lower()
                plot_episode(env, f"{picture_dir}/{name}", title=f"{run.experiment} {run.setting}: {run.variant}, "
                             f"seed {run.seed}")
                record["picture"] = name
    except Exception as e:  # one broken run must not stop the others: record it
        record.update(status="failed", steps=None, metrics=None,
                      error="".join(traceback.format_exception(type(e), e, e.__traceback__)))
    record["wall_time"] = round(time.perf_counter() - start, 3)
    return record


RUNS_FILE = "runs.jsonl"
PLAN_FILE = "plan.json"


def read_runs(out) -> list[dict]:
    """The records of ``out/runs.jsonl`` (see ``files.read_jsonl``: a torn last line is skipped)."""
    return read_jsonl(Path(out) / RUNS_FILE, "run record", frozenset({"key"}))


def run_all(out, *, seeds: int | None = None, quick: bool = False, resume: bool = False, workers: int = 1,
            progress: bool = True) -> list[dict]:
    """Play every planned run not yet in ``out/runs.jsonl``, appending one line per run; return all records.

    ``out/plan.json`` records the options the folder was started with, so ``resume`` never mixes runs of
    different seed counts or horizons.
    """
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers={workers!r}: expected an integer >= 1")
    planned = plan_runs(seeds, quick)
    out = Path(out)
    plan = {"seeds": seeds, "quick": bool(quick)}
    old_plan = json.loads((out / PLAN_FILE).read_text()) if (out / PLAN_FILE).exists() else None
    records = read_runs(out)
    if records and not resume:
        raise ValueError(f"out={str(out)!r} already holds {len(records)} runs: pass --resume to continue them "
                         "or choose another --out")
    if old_plan is not None and records and old_plan != plan:
        raise ValueError(f"out={str(out)!r} was started with {old_plan}, not {plan}: resume with the same "
                         "--seeds/--quick or choose another --out")
    set_aside_torn_line(out / RUNS_FILE)
    atomic_write_json(out / PLAN_FILE, plan)
    done = {r["key"] for r in records}
    todo = [r for r in planned if r.key not in done]
    code = code_version()
    from tqdm import tqdm

    with tqdm(total=len(todo), desc="reproduce", unit="run", disable=not progress) as bar:
        for rec in imap_unordered(play, [(run, str(out)) for run in todo], workers):
            rec["code"] = code
            append_line(out / RUNS_FILE, json.dumps(rec, allow_nan=True))
            records.append(rec)
            bar.update(1)
            bar.set_postfix(last=rec["key"], refresh=False)
    return records
