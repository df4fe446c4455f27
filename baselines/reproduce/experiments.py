"""The experiments of reproduction v2 as data, and the function that plays one run of them.

Every experiment flies the paper's planners bare (``baselines.paper``); the fusion experiments add the
engineered expert (``baselines.expert``) with and without its gap rule, so the report can say which
family reproduces a claim. An experiment is a list of settings (a seed -> ``Scenario`` builder, the env
configuration and an episode length) and a list of variants (a named policy configuration); a run is
one (experiment, setting, variant, seed). The UAVs sense the world with their own range sensor and map
(the paper's unknown environment). Besides ``uavform_env.metrics.episode_metrics`` each record holds
the metrics the claims need (``paper_metrics``). After the planned runs, a sample of the runs that timed
out is flown again at twice the horizon (``HORIZON_SAMPLE``), so the report can say whether a time-out
means a trap. Nothing depends on the seed except the scenario, so nothing is tuned per seed.
"""

from __future__ import annotations

import json
import math
import time
import traceback
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Callable

import numpy as np

from uavform_env.config import EnvConfig, EpisodeConfig, FormationConfig, UAVLimits
from uavform_env.evaluation.runner import code_version
from uavform_env.files import append_line, atomic_write_json, read_jsonl, set_aside_torn_line
from uavform_env.formation import slot_offsets, slot_positions
from uavform_env.formation_v0 import parallel_env
from uavform_env.metrics import episode_metrics
from uavform_env.parallel import imap_unordered
from uavform_env.scenarios import GRID_RESOLUTION, Mission, Scenario, make_scenario
from uavform_env.world import Box, Cylinder

from ..dwa import DWAConfig
from ..expert import ExpertConfig, FusionExpert
from ..paper import PaperConfig, PaperPlanner

FORMAT = 2                            # runs.jsonl / plan.json format of this module
FIGURE_SEED = 0                       # the seed whose runs keep a trace for the report's figures
Z_REF = FormationConfig().z_ref       # the altitude every mission starts and ends at
RESOLUTION = GRID_RESOLUTION          # the voxel size of every registered scenario
CEILING = UAVLimits().z_max + 2.0     # world top, as in the registered scenarios: "tall" obstacles reach it
R_DISC = 0.5                          # spec (h2) E1: disc obstacles of radius 0.5 m
R_SW = UAVLimits().v_max * DWAConfig().T_p   # spec (c1): "near the goal" = within one horizon of travel
SEEDS = 20                            # spec (h2): 20 seeds per world
HORIZON_SAMPLE = 3                    # timed-out runs per setting flown again at twice the horizon (1 with --quick)
TIGHT_GOAL = 0.1                      # m: the tight goal tolerance of C1/C3 (env success radius and DWA stop)
CLASSIC_R_UAV = 0.05                  # m: spec (a) "classic mode" wants a point robot; the env needs r_uav > 0
CLASSIC_RESOLUTION = 0.1              # m: map voxels of the classic mode (the discs' gaps are 0.4 m wide)

# The metrics a run record adds to episode_metrics (see paper_metrics).
METRICS = ("near_goal_loops", "near_goal_dwell", "yaw_jitter_per_metre", "iterations", "reformed")


@dataclass(frozen=True)
class Setting:
    """One world of an experiment: ``build(seed)`` gives the scenario, ``env`` the env configuration."""

    name: str
    build: Callable[[int], Scenario]
    max_cycles: int
    quick_cycles: int
    description: str
    env: EnvConfig = field(default_factory=EnvConfig)
    variants: tuple[str, ...] | None = None   # the experiment's variants this world runs (None: all)


@dataclass(frozen=True)
class Variant:
    """A named policy: ``config()`` gives its PaperConfig or ExpertConfig (the policy class follows from it)."""

    name: str
    config: Callable[[], PaperConfig | ExpertConfig]
    description: str

    def policy(self):
        cfg = self.config()
        return PaperPlanner(cfg) if isinstance(cfg, PaperConfig) else FusionExpert(cfg)


@dataclass(frozen=True)
class Experiment:
    id: str
    title: str
    settings: tuple[Setting, ...]
    variants: tuple[Variant, ...]
    quick_settings: tuple[str, ...]  # the settings --quick keeps (seed 0, quick_cycles steps)
    quick_variants: tuple[str, ...] | None = None  # the variants --quick keeps (None: all)


def _scenario(name, obstacles, start, goal, heading, hi, n_uavs=1, formation="column", spacing=2.0,
              resolution=RESOLUTION) -> Scenario:
    return Scenario(name=name, version=1, seed=None, bounds_lo=(0.0, 0.0, 0.0), bounds_hi=(hi[0], hi[1], CEILING),
                    resolution=resolution, obstacles=tuple(obstacles),
                    mission=Mission(start=(start[0], start[1], Z_REF), goal=(goal[0], goal[1], Z_REF),
                                    start_heading=heading, formation=formation, spacing=spacing, n_uavs=n_uavs))


def _column(x, y, r=R_DISC) -> Cylinder:
    return Cylinder(float(x), float(y), float(r), 0.0, CEILING)


# ------------------------------------------------------------------------------------------------ worlds
def classic(difficulty: str) -> Callable[[int], Scenario]:
    """The registered classic map at ``CLASSIC_RESOLUTION``; seed 0 is the spec's start (0, 0, pi/2), other seeds
    move the start by up to 0.25 m and turn it by up to 15 degrees [D]."""
    def build(seed: int) -> Scenario:
        scn = replace(make_scenario("classic-2d@1", difficulty=difficulty), resolution=CLASSIC_RESOLUTION)
        if seed == 0:
            return scn
        rng = np.random.default_rng([1, seed])
        dx, dy = rng.uniform(-0.25, 0.25, 2)
        turn = rng.uniform(-1, 1) * math.radians(15)
        return scn.with_mission(start=(dx, dy, Z_REF), start_heading=math.pi / 2 + turn)
    return build


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


def goal_beside_obstacle(seed: int) -> Scenario:
    """The goal 3-5 m ahead of the start, a disc (R = 0.5 m) 1.0-1.4 m beside it, and the UAV starting
    with its back to the goal [D]: it has to turn round and settle next to an obstacle."""
    rng = np.random.default_rng([4, seed])
    start, dist = np.array([6.0, 7.0]), rng.uniform(3.0, 5.0)
    goal = start + (dist, 0.0)
    side, offset, along = rng.choice([-1.0, 1.0]), rng.uniform(1.0, 1.4), rng.uniform(-0.5, 0.5)
    return _scenario("goal-beside-obstacle", [_column(goal[0] + along, goal[1] + side * offset)], start, goal, math.pi,
                     (16.0, 14.0))


def block_world(seed: int) -> Scenario:
    """30 x 30 x 10 m [D]: 10 tall columns (R 0.4-0.8 m) up to the world top, and 8 low boxes (1.6-3 m
    wide, tops 3.2-4 m, above z_ref = 3 m) centred within 5 m of the start-goal line; footprints keep
    1.6 m apart and clear of the start and the goal."""
    rng = np.random.default_rng([5, seed])
    start, goal = np.array([6.0, 15.0 + rng.uniform(-2, 2)]), np.array([26.0, 15.0 + rng.uniform(-2, 2)])
    heading = math.atan2(*(goal - start)[::-1])
    zones = np.vstack([slot_positions(p, heading, slot_offsets("column", 1, 2.0), Z_REF)[:, :2] for p in (start, goal)])
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
    return _scenario("block-world", obstacles, start, goal, heading, (30.0, 30.0))


def registered(name: str, **overrides) -> Callable[[int], Scenario]:
    def build(seed: int) -> Scenario:
        return make_scenario(name, seed=seed, **overrides)
    return build


# ------------------------------------------------------------------------------------------------ variants
def _paper(ablation: str, reading: str, use_vfh: bool = False, **dwa) -> Callable[[], PaperConfig]:
    def make() -> PaperConfig:
        return PaperConfig.named(ablation, use_vfh=use_vfh, heading_ref=reading, **dwa)
    return make


def _ablations(reading: str, names=("DWA", "DWA+E8", "DWA+E8+E10"), idwa=True, r_goal=TIGHT_GOAL):
    out = [Variant(f"{a}/{reading}", _paper(a, reading, r_goal=r_goal),
                   f"`PaperConfig.named(\"{a}\", heading_ref=\"{reading}\", r_goal={r_goal})`") for a in names]
    if idwa:
        out += [Variant(f"IDWA-{mode}/{reading}", _paper("IDWA", reading, rotation_mode=mode, r_goal=r_goal),
                        f"`PaperConfig.named(\"IDWA\", heading_ref=\"{reading}\", rotation_mode=\"{mode}\", "
                        f"r_goal={r_goal})`") for mode in ("abs", "delta")]
    return tuple(out)


def _expert_2d() -> ExpertConfig:
    return replace(ExpertConfig(), use_vfh=False, astar_layer="band")


FUSION_VARIANTS = (
    Variant("fusion/paper", _paper("IDWA", "endpoint", use_vfh=True), "`paper-fusion`: "
            "`PaperConfig.named(\"IDWA\", use_vfh=True)`, the paper's fusion rule bare"),
    Variant("2D/paper", _paper("IDWA", "endpoint"), "`paper-idwa`: `PaperConfig.named(\"IDWA\")`, held at z_ref"),
    Variant("fusion/expert", ExpertConfig, "`expert`: `ExpertConfig()`, the engineered fusion expert"),
    Variant("fusion/expert-no-gap", lambda: ExpertConfig(gap_lookahead=0.0),
            "`ExpertConfig(gap_lookahead=0)`: the expert without its known-gap altitude rule"),
    Variant("2D/expert", _expert_2d, "`ExpertConfig(use_vfh=False, astar_layer=\"band\")`: the expert held at z_ref "
            "(the gap rule needs 3D VFH+, so it is the 2D counterpart of both expert readings)"),
)

E10_ONLY = tuple(f"{a}/{r}" for a in ("DWA+E8", "DWA+E8+E10") for r in ("endpoint", "current"))
CLASSIC_ENV = EnvConfig(uav=UAVLimits(r_uav=CLASSIC_R_UAV, r_safe=0.0), episode=EpisodeConfig(r_goal=TIGHT_GOAL))
TIGHT_ENV = EnvConfig(episode=EpisodeConfig(r_goal=TIGHT_GOAL))

EXPERIMENTS = (
    Experiment(
        "E1", "Classic map at the paper's conditions: the DWA ablation, both readings of theta", (
            Setting("classic", classic("base"), 800, 800,
                    "the classic MATLAB map, 10 discs (R = 0.5 m), start (0, 0, pi/2), goal (10, 10) [R]; classic "
                    f"mode: r_uav = {CLASSIC_R_UAV} m, r_safe = 0, map voxels {CLASSIC_RESOLUTION} m; goal "
                    f"tolerance {TIGHT_GOAL} m", CLASSIC_ENV),
        ), _ablations("endpoint") + _ablations("current"), ("classic",),
        ("DWA/endpoint", "DWA+E8/endpoint", "DWA/current", "DWA+E8/current")),
    Experiment(
        "E2", "Efficiency of E10 and smoothness of E11: extended classic map, dense fields, U-traps", (
            Setting("extended", classic("extended"), 1000, 600, "the classic map plus the 8 discs of the extended set "
                    "[R], classic mode as E1", CLASSIC_ENV, E10_ONLY),
            Setting("dense", dense_field, 1000, 600, "20 x 20 m, 15-30 discs of R = 0.5 m; default UAV (r_uav 0.3 m)",
                    TIGHT_ENV),
            Setting("u-trap", u_trap, 1000, 600, "a U of full-height walls open toward the start, goal behind it; "
                    "default UAV", TIGHT_ENV, E10_ONLY),
        ), _ablations("endpoint", ("DWA+E8", "DWA+E8+E10")) + _ablations("current", ("DWA+E8", "DWA+E8+E10"), False),
        ("dense",), ("DWA+E8/endpoint", "DWA+E8+E10/endpoint", "IDWA-abs/endpoint", "IDWA-delta/endpoint")),
    Experiment(
        "E3", "Goal beside an obstacle, start facing away", (
            Setting("beside", goal_beside_obstacle, 600, 600, "goal 3-5 m behind the UAV, a disc 1.0-1.4 m beside the "
                    f"goal; default UAV; goal tolerance {TIGHT_GOAL} m", TIGHT_ENV),
        ), _ablations("endpoint", ("DWA", "DWA+E8"), False) + _ablations("current", ("DWA", "DWA+E8"), False),
        ("beside",)),
    Experiment(
        "E4", "Single UAV in 3D: fused against fixed-altitude planners", (
            Setting("blocks", block_world, 1200, 500, "30 x 30 x 10 m: 10 tall columns to the world top, 8 low boxes "
                    "(tops 3.2-4 m) near the start-goal line; goal tolerance 0.5 m (env default)"),
        ), FUSION_VARIANTS, ("blocks",), ("fusion/paper", "2D/paper")),
    Experiment(
        "E5", "Single UAV at a wall whose only opening is above or below z_ref", (
            Setting("wall-gap", registered("wall-gap@1", n_uavs=1, formation="column"), 1200, 600,
                    "registered `wall-gap@1` with one UAV"),
        ), FUSION_VARIANTS, ("wall-gap",), ("fusion/paper", "fusion/expert")),
    Experiment(
        "E6", "Five-UAV wedge at the wall gap", (
            Setting("wall-gap", registered("wall-gap@1"), 1500, 300, "registered `wall-gap@1`: five UAVs in a 2 m wedge"),
        ), FUSION_VARIANTS, ("wall-gap",), ("fusion/paper",)),
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
    horizon_check: bool = False      # a timed-out run flown again at twice its horizon

    @property
    def key(self) -> str:
        return f"{self.experiment}/{self.setting}/{self.variant}/{self.seed}" + ("/2H" if self.horizon_check else "")


def plan_runs(seeds: int | None = None, quick: bool = False) -> list[Run]:
    """Every planned run. ``quick``: the quick settings and variants, seed 0, ``quick_cycles`` steps;
    ``seeds`` overrides the seed count (default ``SEEDS``)."""
    if seeds is not None and (isinstance(seeds, bool) or not isinstance(seeds, int) or seeds < 1):
        raise ValueError(f"seeds={seeds!r}: expected an integer >= 1")
    runs = []
    for e in EXPERIMENTS:
        for s in e.settings:
            if quick and s.name not in e.quick_settings:
                continue
            n = seeds if seeds is not None else (1 if quick else SEEDS)
            for v in e.variants:
                if s.variants is not None and v.name not in s.variants:
                    continue
                if quick and e.quick_variants is not None and v.name not in e.quick_variants:
                    continue
                runs += [Run(e.id, s.name, v.name, k, s.quick_cycles if quick else s.max_cycles) for k in range(n)]
    return runs


def horizon_checks(records: list[dict], quick: bool = False) -> list[Run]:
    """Per setting, the first ``HORIZON_SAMPLE`` (1 with ``quick``) timed-out runs in key order, at twice the horizon."""
    sample = 1 if quick else HORIZON_SAMPLE
    picked: dict[tuple, list[Run]] = {}
    for r in sorted(records, key=lambda r: r["key"]):
        if r.get("horizon_check") or r["status"] != "ok" or not r["metrics"]["timeout"]:
            continue
        group = picked.setdefault((r["experiment"], r["setting"]), [])
        if len(group) < sample:
            group.append(Run(r["experiment"], r["setting"], r["variant"], r["seed"], 2 * r["max_cycles"], True))
    return [run for group in picked.values() for run in group]


def _parts(run: Run) -> tuple[Experiment, Setting, Variant]:
    e = experiment(run.experiment)
    setting = next((s for s in e.settings if s.name == run.setting), None)
    variant = next((v for v in e.variants if v.name == run.variant), None)
    if setting is None or variant is None:
        raise ValueError(f"run {run.key!r}: unknown setting or variant of {e.id}")
    return e, setting, variant


def scenario_of(run: Run) -> Scenario:
    return _parts(run)[1].build(run.seed)


def paper_metrics(env) -> dict:
    """The claims' metrics from the leader's history (spec (h1) and the issue's loops-and-dwell test).

    near_goal_loops       full turns of the goal-to-UAV bearing while within R_sw of the goal: |sum of wrapped
                          bearing steps| / 2 pi (an orbit adds up, a straight pass adds at most half a turn)
    near_goal_dwell       seconds from the first entry within R_sw of the goal to the end of the episode
    yaw_jitter_per_metre  sum |w_(k+1) - w_k| over the episode per metre flown (rad/s per m; spec (c4) note)
    iterations            planning cycles to arrival (NaN if the mission did not succeed)
    reformed              formation closed up after its last break (NaN for one UAV; see episode_metrics)
    """
    h = env.history
    dt = env.config.uav.dt
    pos = np.asarray(h["positions"])[:, 0, :2]
    rel = pos - np.asarray(env.goal)[:2]
    rho = np.hypot(rel[:, 0], rel[:, 1])
    bearing = np.arctan2(rel[:, 1], rel[:, 0])
    near = (rho[1:] < R_SW) & (rho[:-1] < R_SW)
    steps = np.angle(np.exp(1j * np.diff(bearing)))
    loops = abs(float(steps[near].sum())) / (2 * math.pi)
    inside = np.flatnonzero(rho < R_SW)
    dwell = (len(rho) - 1 - inside[0]) * dt if inside.size else 0.0
    w = np.asarray(h["w"])[:, 0]
    length = float(np.linalg.norm(np.diff(pos, axis=0), axis=1).sum())
    jitter = float(np.abs(np.diff(w)).sum()) / length if length > 0.5 else math.nan
    return {"near_goal_loops": loops, "near_goal_dwell": float(dwell), "yaw_jitter_per_metre": jitter,
            "iterations": float(env.step_count) if env.success else math.nan}


def _trace(env, stride: int) -> dict:
    """Downsampled per-step series for the figures: time, leader position and yaw rate, goal distance."""
    h = env.history
    pos = np.asarray(h["positions"])[::stride, 0]
    return {"t": np.round(np.arange(len(pos)) * stride * env.config.uav.dt, 2).tolist(),
            "pos": np.round(pos, 3).tolist(),
            "w": np.round(np.asarray(h["w"])[::stride, 0], 4).tolist(),
            "goal_distance": np.round(np.linalg.norm(pos[:, :2] - np.asarray(env.goal)[:2], axis=1), 3).tolist()}


def play(run: Run) -> dict:
    """Play one run and return its record (never raises: an exception becomes a ``failed`` record).

    Runs of ``FIGURE_SEED`` keep a trace. A top-level function of plain data, so a process pool can ship it.
    """
    record = {"key": run.key, "experiment": run.experiment, "setting": run.setting, "variant": run.variant,
              "seed": run.seed, "max_cycles": run.max_cycles, "horizon_check": run.horizon_check}
    start = time.perf_counter()
    try:
        _, setting, variant = _parts(run)
        penv = parallel_env(scenario=setting.build(run.seed), max_cycles=run.max_cycles, config=setting.env)
        policy = variant.policy()
        obs, _ = penv.reset(seed=run.seed)
        policy.reset(penv, run.seed)
        while penv.agents:
            obs, *_ = penv.step(policy.act(obs, penv))
        env = penv.unwrapped
        metrics = episode_metrics(env)
        metrics.update(paper_metrics(env))
        metrics["reformed"] = (math.nan if env.n_uavs == 1 else float(math.isfinite(metrics["time_to_reform"])))
        record.update(status="ok", steps=int(env.step_count), metrics=metrics, error=None)
        if run.seed == FIGURE_SEED and not run.horizon_check:
            record["trace"] = _trace(env, 1 if env.n_uavs == 1 else 5)
    except Exception as e:  # one broken run must not stop the others: record it
        record.update(status="failed", steps=None, metrics=None,
                      error="".join(traceback.format_exception(type(e), e, e.__traceback__)))
    record["wall_time"] = round(time.perf_counter() - start, 3)
    return record


RUNS_FILE = "runs.jsonl"
PLAN_FILE = "plan.json"


def read_runs(out) -> list[dict]:
    """The records of ``out/runs.jsonl`` (see ``files.read_jsonl``: a torn last line is skipped).

    A folder written by reproduction format 1 (experiments E1-E6 on the engineered controllers, before the
    paper-faithful planners) is refused with a clear message: its records cannot answer the v2 claims.
    """
    out = Path(out)
    records = read_jsonl(out / RUNS_FILE, "run record", frozenset({"key"}))
    plan = json.loads((out / PLAN_FILE).read_text()) if (out / PLAN_FILE).exists() else {}
    if records and plan.get("format") != FORMAT:
        raise ValueError(f"out={str(out)!r} holds {len(records)} runs of reproduction format {plan.get('format', 1)} "
                         f"(the engineered controllers); this is format {FORMAT}: choose another --out or move the "
                         "old folder away (its README.md and summary.json stay readable as they are)")
    return records


def _play_all(out: Path, runs: list[Run], records: list[dict], workers: int, progress: bool, desc: str,
              code: str) -> None:
    from tqdm import tqdm

    with tqdm(total=len(runs), desc=desc, unit="run", disable=not progress) as bar:
        for rec in imap_unordered(play, [(run,) for run in runs], workers):
            rec["code"] = code
            append_line(out / RUNS_FILE, json.dumps(rec, allow_nan=True))
            records.append(rec)
            bar.update(1)
            bar.set_postfix(last=rec["key"], refresh=False)


def run_all(out, *, seeds: int | None = None, quick: bool = False, resume: bool = False, workers: int = 1,
            progress: bool = True) -> list[dict]:
    """Play every planned run not yet in ``out/runs.jsonl``, appending one line per run, then the horizon
    checks of the runs that timed out; return all records.

    ``out/plan.json`` records the options the folder was started with, so ``resume`` never mixes runs of
    different seed counts or horizons.
    """
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ValueError(f"workers={workers!r}: expected an integer >= 1")
    planned = plan_runs(seeds, quick)
    out = Path(out)
    plan = {"format": FORMAT, "seeds": seeds, "quick": bool(quick)}
    records = read_runs(out)
    old_plan = json.loads((out / PLAN_FILE).read_text()) if (out / PLAN_FILE).exists() else None
    if records and not resume:
        raise ValueError(f"out={str(out)!r} already holds {len(records)} runs: pass --resume to continue them "
                         "or choose another --out")
    if old_plan is not None and records and old_plan != plan:
        raise ValueError(f"out={str(out)!r} was started with {old_plan}, not {plan}: resume with the same "
                         "--seeds/--quick or choose another --out")
    out.mkdir(parents=True, exist_ok=True)
    set_aside_torn_line(out / RUNS_FILE)
    atomic_write_json(out / PLAN_FILE, plan)
    done = {r["key"] for r in records}
    code = code_version()                   # once: both phases of one invocation are the same code
    _play_all(out, [r for r in planned if r.key not in done], records, workers, progress, "reproduce", code)
    checks = [r for r in horizon_checks(records, quick) if r.key not in done]
    _play_all(out, checks, records, workers, progress, "horizon x2", code)
    return records
