"""``uavform reproduce --quick``: a reduced rerun of every experiment E1-E6 (one seed, short episodes).

The command must write the report, and each claim's direction on the reduced runs must agree with the
verdict the committed report (docs/reproduction/summary.json) states, holds or does not hold: a code
change that flips a difference the report relies on fails here. Where one seed and short episodes decide
a claim the other way from the full run, the quick verdict is pinned instead (``QUICK_DIFFERS``).
"""

import argparse
import json
from importlib.metadata import entry_points
from pathlib import Path

import pytest

from baselines.reproduce.experiments import (EXPERIMENTS, PLAN_FILE, RUNS_FILE, plan_runs, read_runs, run_all,
                                            scenario_of)
from baselines.reproduce.report import CLAIMS, check_claims, summarize
from baselines.reproduce import register
from uavform_env.cli import COMMAND_GROUP

COMMITTED = Path(__file__).resolve().parents[1] / "docs" / "reproduction" / "summary.json"


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
    for e in EXPERIMENTS:
        assert f"## {e.id}: {e.title}" in text
    for c in CLAIMS:
        assert f"**{c.id}: " in text
    summary = json.loads((quick / "summary.json").read_text())
    for name in summary["figures"].values():
        assert (quick / name).stat().st_size > 10_000
    assert {"E1", "near-goal", "E4", "E5", "E6"} <= set(summary["figures"])


def test_one_record_per_planned_run(quick):
    records = read_runs(quick)
    assert sorted(r["key"] for r in records) == sorted(r.key for r in plan_runs(quick=True))
    assert all(r["status"] == "ok" for r in records), [r["error"] for r in records if r["status"] != "ok"]


COMMITTED_CLAIMS = {c["id"]: c for c in json.loads(COMMITTED.read_text())["claims"]} if COMMITTED.exists() else {}


# Claims whose one-seed, short-episode rerun comes out the other way from the full report, with the quick verdict
# pinned: on seed 0 alone IDWA turns less per metre than DWA+E8+E10 (C5), the planar single UAV fails the blocks
# world (C6), and the crossing's separations tie at 1.09 m (C11, a strict comparison); the full run's other seeds
# decide each the other way (dense fields: IDWA turns more; some planar UAVs pass; prediction keeps more room).
QUICK_DIFFERS = {"C5": "holds", "C6": "holds", "C11": "does not hold"}


@pytest.mark.parametrize("claim", [c.id for c in CLAIMS])
def test_reduced_rerun_agrees_with_the_committed_verdict(quick, claim):
    committed = COMMITTED_CLAIMS.get(claim)
    assert committed is not None, f"{COMMITTED} has no verdict for {claim}: regenerate the report"
    rerun = {c["id"]: c for c in check_claims(summarize(read_runs(quick)))}[claim]
    if claim in QUICK_DIFFERS:
        assert committed["verdict"] != QUICK_DIFFERS[claim], f"{claim} now agrees: drop it from QUICK_DIFFERS"
    expected = QUICK_DIFFERS.get(claim, committed["verdict"])
    assert rerun["verdict"] == expected, (rerun["evidence"], committed["evidence"])


def test_resume_plays_nothing_twice_and_a_full_folder_needs_resume(quick):
    before = (quick / RUNS_FILE).read_bytes()
    assert len(run_all(quick, quick=True, resume=True, progress=False)) == len(plan_runs(quick=True))
    assert (quick / RUNS_FILE).read_bytes() == before
    with pytest.raises(ValueError, match="--resume"):
        run_all(quick, quick=True, progress=False)
    with pytest.raises(ValueError, match="was started with"):
        run_all(quick, seeds=2, resume=True, progress=False)
    assert json.loads((quick / PLAN_FILE).read_text()) == {"seeds": None, "quick": True}


def test_a_torn_last_line_is_skipped(tmp_path):
    run = plan_runs(quick=True)[0]
    (tmp_path / PLAN_FILE).write_text(json.dumps({"seeds": None, "quick": True}))
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
        if run.setting in ("base", "extended", "corridor", "wall-gap", "urban"):
            continue                                   # registered or fixed maps: checked in test_scenarios
        worlds.setdefault((run.experiment, run.setting), {})[run.seed] = scenario_of(run)
        assert scenario_of(run) == worlds[(run.experiment, run.setting)][run.seed]
    assert all(w[0] != w[1] for w in worlds.values())
