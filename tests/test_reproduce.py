"""``uavform reproduce --quick``: a reduced rerun of reproduction v2 (seed 0, short episodes, a subset of variants).

The command must write the report and claims.json, and every check that both the reduced rerun and the committed
report (docs/reproduction/claims.json) decide must come out the same way: a code change that flips a difference
the report relies on fails here. Where seed 0 and short episodes decide a check the other way from the full run,
the quick result is pinned instead (``QUICK_DIFFERS``).
"""

import argparse
import json
import math
from importlib.metadata import entry_points
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from baselines.reproduce import register
from baselines.reproduce.claims import evaluate, load_claims
from baselines.reproduce.experiments import (PLAN_FILE, RUNS_FILE, horizon_checks, paper_metrics, plan_runs,
                                            read_runs, run_all, scenario_of)
from uavform_env.cli import COMMAND_GROUP

COMMITTED = Path(__file__).resolve().parents[1] / "docs" / "reproduction" / "claims.json"
CLAIMS = load_claims()


def reproduce(argv: list[str]) -> int:
    """The ``reproduce`` command as ``uavform`` runs it, without the other plug-in commands."""
    parser = argparse.ArgumentParser(prog="uavform")
    register(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(["reproduce", *argv])
    return args.func(args)


def test_the_command_is_plugged_into_uavform():
    (ep,) = [ep for ep in entry_points(group=COMMAND_GROUP) if ep.name == "reproduce"]
    assert ep.load() is register


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    out = tmp_path_factory.mktemp("reproduce")
    assert reproduce(["--out", str(out), "--quick", "--workers", "2", "--quiet"]) == 0
    return out


def test_the_command_writes_the_report(quick):
    text = (quick / "README.md").read_text()
    for c in CLAIMS:
        assert f"### {c.id}: " in text
    claims = json.loads((quick / "claims.json").read_text())
    assert [c["id"] for c in claims] == [c.id for c in CLAIMS]
    for c in claims:
        assert {"statement", "verdict", "readings", "reproduced_by"} <= set(c)
        for r in c["readings"]:
            assert all({"what", "metric", "value", "holds", "text"} <= set(k) for k in r["checks"])
    summary = json.loads((quick / "summary.json").read_text())
    for name in summary["figures"].values():
        assert (quick / name).stat().st_size > 10_000


def test_one_record_per_planned_run_and_horizon_check(quick):
    records = read_runs(quick)
    main = [r for r in records if not r["horizon_check"]]
    assert sorted(r["key"] for r in main) == sorted(r.key for r in plan_runs(quick=True))
    assert sorted(r["key"] for r in records if r["horizon_check"]) == sorted(r.key for r in horizon_checks(main, True))
    assert all(r["status"] == "ok" for r in records), [r["error"] for r in records if r["status"] != "ok"]


COMMITTED_CLAIMS = {c["id"]: c for c in json.loads(COMMITTED.read_text())} if COMMITTED.exists() else {}

# (claim, reading, check index): checks whose seed-0, short-episode rerun comes out the other way from the full
# report, with the quick result pinned. On seed 0 alone: DWA and DWA+E8 (theta at the endpoint) freeze at the same
# spot on the classic map (equal loops, so not fewer); standard DWA circles the goal beside the obstacle for 1.3
# turns (the 20 seeds average below 1); in 600 dense-field steps no planner arrives (success ties at 0) and
# IDWA-delta jitters slightly more than DWA+E8+E10 (0.49 vs 0.46 rad/s per m; over 20 seeds of 1000 steps, less).
QUICK_DIFFERS: dict[tuple[str, str, int], bool] = {
    ("C1", "endpoint", 1): False,
    ("C3", "endpoint", 0): True,
    ("C5", "abs", 3): True,
    ("C5", "delta", 2): False,
    ("C5", "delta", 3): True,
}


@pytest.mark.parametrize("claim", [c.id for c in CLAIMS])
def test_reduced_rerun_keeps_the_committed_directions(quick, claim):
    committed = COMMITTED_CLAIMS.get(claim)
    assert committed is not None, f"{COMMITTED} has no verdict for {claim}: regenerate the report"
    rerun = {c["id"]: c for c in evaluate(read_runs(quick), CLAIMS)}[claim]
    decided = 0
    for new, old in zip(rerun["readings"], committed["readings"]):
        for k, (a, b) in enumerate(zip(new["checks"], old["checks"])):
            if a["holds"] is None or b["holds"] is None:
                continue
            decided += 1
            pinned = QUICK_DIFFERS.get((claim, new["reading"], k))
            if pinned is not None:
                assert b["holds"] != pinned, f"{claim}/{new['reading']}/{k} now agrees: drop it from QUICK_DIFFERS"
                assert a["holds"] == pinned, a["text"]
            else:
                assert a["holds"] == b["holds"], (a["text"], b["text"])
    assert decided or claim in ("C2", "C6"), f"the quick rerun decides no check of {claim}"


def test_resume_plays_nothing_twice_and_a_full_folder_needs_resume(quick):
    before = (quick / RUNS_FILE).read_bytes()
    n = len(read_runs(quick))
    assert len(run_all(quick, quick=True, resume=True, progress=False)) == n
    assert (quick / RUNS_FILE).read_bytes() == before
    with pytest.raises(ValueError, match="--resume"):
        run_all(quick, quick=True, progress=False)
    with pytest.raises(ValueError, match="was started with"):
        run_all(quick, seeds=2, resume=True, progress=False)
    assert json.loads((quick / PLAN_FILE).read_text()) == {"format": 2, "seeds": None, "quick": True}


def test_a_format_1_folder_is_refused_with_a_clear_message(tmp_path):
    (tmp_path / PLAN_FILE).write_text(json.dumps({"seeds": None, "quick": True}))
    (tmp_path / RUNS_FILE).write_text(json.dumps({"key": "E1/base/DWA/0", "status": "ok"}) + "\n")
    with pytest.raises(ValueError, match="format 1"):
        read_runs(tmp_path)
    with pytest.raises(ValueError, match="format 1"):
        run_all(tmp_path, quick=True, resume=True, progress=False)


def test_a_torn_last_line_is_skipped(tmp_path):
    run = plan_runs(quick=True)[0]
    (tmp_path / PLAN_FILE).write_text(json.dumps({"format": 2, "seeds": None, "quick": True}))
    (tmp_path / RUNS_FILE).write_text('{"key": "' + run.key + '", "status": "ok"')      # no newline: torn
    with pytest.warns(UserWarning, match="torn"):
        assert read_runs(tmp_path) == []


@pytest.mark.parametrize("kwargs, match", [(dict(workers=0), "workers=0"), (dict(seeds=0), "seeds=0")])
def test_bad_arguments_are_named(tmp_path, kwargs, match):
    with pytest.raises(ValueError, match=match):
        run_all(tmp_path, quick=True, progress=False, **kwargs)


def test_worlds_depend_on_the_seed_only():
    """Nothing is tuned per seed: the same seed builds the same world, other seeds other worlds."""
    worlds = {}
    for run in plan_runs(seeds=2):
        if run.setting == "wall-gap":
            continue                                   # registered maps: checked in test_scenarios
        worlds.setdefault((run.experiment, run.setting), {})[run.seed] = scenario_of(run)
        assert scenario_of(run) == worlds[(run.experiment, run.setting)][run.seed]
    assert all(w[0] != w[1] for w in worlds.values())


def test_loops_and_dwell_known_answer():
    """Two full circles of radius 2 m round the goal, entered from 5 m away: 2 loops, dwell from the entry on."""
    t = np.linspace(0.0, 4 * math.pi, 401)
    approach = np.column_stack([np.linspace(15.0, 12.0, 31)[:-1], np.full(30, 10.0)])
    circle = np.column_stack([10.0 + 2.0 * np.cos(t), 10.0 + 2.0 * np.sin(t)])
    xy = np.vstack([approach, circle])
    positions = np.concatenate([xy, np.full((len(xy), 1), 3.0)], axis=1)[:, None, :]
    w = np.zeros((len(xy), 1))
    w[::2] = 0.1                                           # alternating yaw rate: |dw| = 0.1 every step
    env = SimpleNamespace(history={"positions": positions, "w": w}, config=SimpleNamespace(uav=SimpleNamespace(dt=0.1)),
                          goal=np.array([10.0, 10.0, 3.0]), success=False, step_count=len(xy) - 1)
    m = paper_metrics(env)
    assert m["near_goal_loops"] == pytest.approx(2.0, abs=1e-6)
    first_inside = int(np.flatnonzero(np.hypot(xy[:, 0] - 10.0, xy[:, 1] - 10.0) < 3.0)[0])
    assert m["near_goal_dwell"] == pytest.approx((len(xy) - 1 - first_inside) * 0.1)
    length = np.linalg.norm(np.diff(xy, axis=0), axis=1).sum()
    assert m["yaw_jitter_per_metre"] == pytest.approx(0.1 * (len(xy) - 1) / length)
    assert math.isnan(m["iterations"])
