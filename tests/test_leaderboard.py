"""Leaderboard: suites and their hash, the runner's backends, resume after a kill, bad input, and the table."""

from __future__ import annotations

import math
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import uavform_env
from uavform_env.cli import main
from uavform_env.evaluation import (WALL_CLOCK_METRICS, bootstrap_ci, list_suites, load_suite, read_results,
                                    run_suite, write_tables)
from uavform_env.evaluation.runner import RESULTS_FILE
from uavform_env.evaluation.suites import Episode, Suite
from uavform_env.evaluation.table import separations, summarize, to_markdown, to_marl_eval
from uavform_env.metrics import METRIC_NAMES
from uavform_env.scenarios import list_scenarios

REPO = Path(__file__).resolve().parents[1]

TINY_SUITE = """
name = "tiny"
description = "two short episodes for the tests"

[[episode]]
scenario = "classic-2d@1"
difficulty = "base"
n_uavs = 1
formation = "wedge"
seed = 0
max_cycles = 15

[[episode]]
scenario = "forest@1"
n_uavs = 2
formation = "column"
seed = 3
max_cycles = 15
"""


class Exploding:
    """A policy that raises in its second step: the runner must record it and go on."""

    def reset(self, env, seed):
        self.calls = 0

    def act(self, observations, env):
        self.calls += 1
        if self.calls > 1:
            raise RuntimeError("boom inside the policy")
        return {a: np.zeros(3, np.float32) for a in env.agents}


class SlowHover(Exploding):
    """Hover, slowly: gives the kill/resume test time to kill a run midway."""

    def act(self, observations, env):
        time.sleep(0.03)
        return {a: np.zeros(3, np.float32) for a in env.agents}


EXPLODING = "tests.test_leaderboard:Exploding"
POLICIES = ["hover", "apf", EXPLODING]


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    path = tmp_path_factory.mktemp("suite") / "tiny.toml"
    path.write_text(TINY_SUITE)
    return load_suite(path)


@pytest.fixture(scope="module")
def serial_run(tiny, tmp_path_factory):
    out = tmp_path_factory.mktemp("serial")
    return out, run_suite(tiny, POLICIES, out, progress=False)


def _exact(records):
    """(episode, policy) -> metrics without the wall-clock ones, which differ from run to run."""
    return {(r["episode"], r["policy"]): (r["status"], r["steps"], None if r["metrics"] is None else
                                          {k: v for k, v in r["metrics"].items() if k not in WALL_CLOCK_METRICS})
            for r in records}


def _exact_table(summary):
    return [(r["rank"], r["policy"], r["episodes"], r["failed"],
             {m: s for m, s in r["metrics"].items() if m not in WALL_CLOCK_METRICS}) for r in summary["policies"]]


# ---------------------------------------------------------------- suites

def test_v0_covers_every_family_tier_and_team_size():
    suite = load_suite("v0")
    assert set(list_suites()) >= {"v0", "smoke"}
    families = {e.scenario.partition("@")[0] for e in suite.episodes}
    assert families == set(list_scenarios()) - {"dog-leg"}  # every family v0 knew (dog-leg came with v1)
    tiers = {(e.scenario.partition("@")[0], e.difficulty) for e in suite.episodes if e.difficulty}
    assert tiers == {("classic-2d", "base"), ("classic-2d", "extended"), ("random-3d", "easy"),
                     ("random-3d", "medium"), ("random-3d", "hard")}
    sizes = {e.n_uavs for e in suite.episodes}
    assert min(sizes) <= 2 and max(sizes) >= 10
    assert {e.formation for e in suite.episodes} == {"wedge", "diamond", "triangle", "line", "column"}


def test_shipped_suites_are_frozen():
    """Editing a shipped suite changes its hash and breaks comparability: add a new suite instead."""
    assert load_suite("v0").hash == "f3db7bca6c122b55"
    assert load_suite("smoke").hash == "5e32a4eab4e90db9"
    assert load_suite("v1").hash == "81b10a899152bcfe"
    assert load_suite("v1-dev").hash == "528344c98875e71e"


def test_hash_covers_episodes_only(tmp_path, tiny):
    relabelled = tmp_path / "b.toml"
    relabelled.write_text(TINY_SUITE.replace('name = "tiny"', 'name = "other"').replace("two short", "2 short"))
    assert load_suite(relabelled).hash == tiny.hash
    reseeded = tmp_path / "c.toml"
    reseeded.write_text(TINY_SUITE.replace("seed = 3", "seed = 4"))
    assert load_suite(reseeded).hash != tiny.hash


@pytest.mark.parametrize("edit, message", [
    (("forest@1", "forest"), "must pin a generator version"),
    (("forest@1", "jungle@1"), "unknown scenario"),
    (("seed = 3", "seed = -1"), "seed=-1"),
    (('formation = "column"', 'formation = "triangle"\nn_uav = 2'), "unknown keys ['n_uav']"),
    (('n_uavs = 2\nformation = "column"', 'n_uavs = 5\nformation = "diamond"'), "at most 4 UAVs"),
    (("seed = 3\nmax_cycles = 15", "seed = 0\nmax_cycles = 15"), None),  # classic-2d is episode 0: no clash
])
def test_bad_suite_files(tmp_path, edit, message):
    path = tmp_path / "bad.toml"
    path.write_text(TINY_SUITE.replace(*edit))
    if message is None:
        load_suite(path)
        return
    with pytest.raises(ValueError, match="episode 1") as info:
        load_suite(path)
    assert message in str(info.value)


def test_duplicate_episodes_and_unknown_suite(tmp_path):
    path = tmp_path / "dup.toml"
    first = TINY_SUITE.split("[[episode]]")
    path.write_text(TINY_SUITE + "[[episode]]" + first[2])
    with pytest.raises(ValueError, match="duplicate episodes"):
        load_suite(path)
    with pytest.raises(ValueError, match=r"unknown suite 'v9'; known suites: \['smoke', 'v0', 'v1', 'v1-dev'\]"):
        load_suite("v9")


# ---------------------------------------------------------------- statistics and table

def test_bootstrap_known_answers():
    assert bootstrap_ci(np.full(7, 2.5)) == (2.5, 2.5, 2.5)
    assert all(math.isnan(x) for x in bootstrap_ci(np.array([math.nan, math.nan])))
    mean, lo, hi = bootstrap_ci(np.array([0.0, 1.0, math.nan]))  # NaN left out: two values 0 and 1
    assert mean == 0.5 and lo == 0.0 and hi == 1.0


@settings(max_examples=15, deadline=None)
@given(st.lists(st.floats(-100, 100), min_size=8, max_size=40), st.integers(0, 2**31))
def test_bootstrap_matches_scipy(values, seed):
    """Percentile interval against SciPy's independent bootstrap: equal up to resampling noise."""
    from scipy.stats import bootstrap

    v = np.array(values)
    mean, lo, hi = bootstrap_ci(v, n_boot=4000, seed=seed)
    ref = bootstrap((v,), np.mean, n_resamples=4000, method="percentile", random_state=seed).confidence_interval
    spread = v.std() / math.sqrt(v.size) + 1e-9
    lattice = (v.max() - v.min()) / v.size        # bootstrap means of few distinct values move in these steps
    tol = 0.35 * spread + lattice
    assert mean == pytest.approx(v.mean())
    assert abs(lo - ref.low) < tol and abs(hi - ref.high) < tol
    assert lo <= mean <= hi


def _record(tiny, i, policy, **metrics):
    values = {m: 0.0 for m in METRIC_NAMES} | metrics
    e = tiny.episodes[i]
    return {"episode": e.key, "policy": policy, "seed": e.seed, "suite_hash": tiny.hash, "status": "ok",
            "steps": 10, "metrics": values}


def test_ranking_is_success_then_safety_formation_efficiency(tiny):
    r = lambda *a, **k: _record(tiny, *a, **k)  # noqa: E731
    failed = dict(r(1, "crashy"), status="failed", metrics=None, steps=None)
    records = [
        r(0, "slow", success=1, flight_time=50), r(1, "slow", success=1, flight_time=50),
        r(0, "fast", success=1, flight_time=10), r(1, "fast", success=1, flight_time=10),
        r(0, "loose", success=1, formation_error_rms=2.0), r(1, "loose", success=1, formation_error_rms=2.0),
        r(0, "bumpy", success=1, collision=1), r(1, "bumpy", success=1),
        r(0, "crashy", success=1), failed,
    ]
    summary = summarize(tiny, records)
    assert [p["policy"] for p in summary["policies"]] == ["fast", "slow", "loose", "bumpy", "crashy"]
    crashy = summary["policies"][-1]
    assert crashy["failed"] == 1 and crashy["metrics"]["success"]["mean"] == 0.5
    assert crashy["metrics"]["flight_time"]["n"] == 1
    with pytest.raises(ValueError, match="two results for episode"):
        summarize(tiny, records + [r(0, "fast")])


def test_table_ignores_the_order_results_arrive_in():
    """Pools and resumes append in completion order; the bootstrap must still see suite order."""
    suite = Suite("synthetic", "", tuple(Episode("forest@1", 2, "wedge", seed, 10) for seed in range(12)))
    rng = np.random.default_rng(1)
    records = [{"episode": e.key, "policy": "p", "seed": e.seed, "suite_hash": suite.hash, "status": "ok",
                "steps": 10, "metrics": {m: float(v) for m, v in zip(METRIC_NAMES, rng.normal(size=len(METRIC_NAMES)))}}
               for e in suite.episodes]
    assert summarize(suite, records) == summarize(suite, records[::-1])


def test_marl_eval_layout(tiny, serial_run):
    _, records = serial_run
    data = to_marl_eval(tiny, records)
    assert set(data) == {"uavform"} and set(data["uavform"]) == {"classic-2d-base", "forest"}
    run = data["uavform"]["forest"]["apf"]["seed_3"]
    assert run["step_0"]["step_count"] == 15
    assert run["absolute_metrics"]["success"] == [0.0] and len(run["step_0"]["path_length_leader"]) == 1
    failed = data["uavform"]["forest"][EXPLODING]["seed_3"]
    assert failed["absolute_metrics"] == {"success": [0.0]}
    assert "min_separation" not in data["uavform"]["classic-2d-base"]["hover"]["seed_0"]["absolute_metrics"]


# ---------------------------------------------------------------- runner

def test_serial_run_records_failures_and_writes_tables(tiny, serial_run):
    out, records = serial_run
    assert len(records) == len(tiny.episodes) * len(POLICIES)
    assert all(r["suite_hash"] == tiny.hash for r in records)
    boom = [r for r in records if r["policy"] == EXPLODING]
    assert all(r["status"] == "failed" and "boom inside the policy" in r["error"] for r in boom)
    assert all(r["status"] == "ok" and r["steps"] == 15 for r in records if r["policy"] != EXPLODING)
    summary = write_tables(tiny, records, out)
    assert [p["policy"] for p in summary["policies"]][-1] == EXPLODING
    for name in ("leaderboard.md", "leaderboard.csv", "leaderboard.json", "leaderboard.png"):
        assert (out / name).stat().st_size > 0
    assert tiny.hash in (out / "leaderboard.md").read_text()
    assert len({r["code"] for r in records}) == 1 and records[0]["code"].startswith(uavform_env.__version__)
    assert f"Code: `{records[0]['code']}`\n" in (out / "leaderboard.md").read_text()
    mixed = to_markdown(summarize(tiny, [{**r, "code": "0.0.1"} if r["policy"] == EXPLODING else r for r in records]))
    assert "**mixed**" in mixed
    csv_rows = (out / "leaderboard.csv").read_text().splitlines()
    assert len(csv_rows) == 1 + len(POLICIES) * len(METRIC_NAMES)


def test_time_limit_is_a_failed_episode(tiny, tmp_path):
    records = run_suite(tiny, ["tests.test_leaderboard:SlowHover"], tmp_path, time_limit=0.05, progress=False)
    assert {r["status"] for r in records} == {"time_limit"}
    assert all("time limit" in r["error"] for r in records)


def test_pool_gives_identical_metrics(tiny, serial_run, tmp_path):
    records = run_suite(tiny, POLICIES, tmp_path, workers=2, progress=False)
    assert _exact(records) == _exact(serial_run[1])


@pytest.mark.slow  # starting a local Ray cluster takes ~10 s
def test_ray_gives_identical_metrics(tiny, serial_run, tmp_path):
    ray = pytest.importorskip("ray")
    try:
        records = run_suite(tiny, ["hover", "apf"], tmp_path, workers=2, backend="ray", progress=False)
    finally:
        ray.shutdown()
    serial = {k: v for k, v in _exact(serial_run[1]).items() if k[1] != EXPLODING}
    assert _exact(records) == serial


def test_killed_run_resumes_to_the_same_table(tiny, tmp_path):
    suite_file = tmp_path / "tiny.toml"
    suite_file.write_text(TINY_SUITE)
    policies = ["tests.test_leaderboard:SlowHover", "hover"]
    killed = tmp_path / "killed"
    args = [sys.executable, "-m", "uavform_env.cli", "leaderboard", "--suite", str(suite_file), "--out", str(killed),
            "--quiet"] + [x for p in policies for x in ("--policy", p)]
    proc = subprocess.Popen(args, cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    results = killed / RESULTS_FILE
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and not (results.exists() and results.read_text().count("\n") >= 1):
        time.sleep(0.05)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    partial = read_results(killed)
    assert 1 <= len(partial) < 4, proc.stderr.read().decode()
    with pytest.raises(ValueError, match="pass --resume"):
        run_suite(tiny, policies, killed, progress=False)
    resumed = run_suite(tiny, policies, killed, resume=True, progress=False)
    assert resumed[:len(partial)] == partial  # nothing written before is lost or rewritten
    straight = run_suite(tiny, policies, tmp_path / "straight", progress=False)
    assert _exact_table(summarize(tiny, resumed)) == _exact_table(summarize(tiny, straight))


# ---------------------------------------------------------------- bad input

def test_bad_input_leaves_results_untouched(tiny, serial_run, tmp_path):
    out, _ = serial_run
    before = (out / RESULTS_FILE).read_bytes()
    with pytest.raises(ValueError, match="already holds 6 results: pass --resume"):
        run_suite(tiny, POLICIES, out, progress=False)
    smoke = load_suite("smoke")
    with pytest.raises(ValueError, match=f"holds suite 'tiny' \\(hash {tiny.hash}\\), not suite 'smoke'"):
        run_suite(smoke, ["hover"], out, resume=True, progress=False)
    with pytest.raises(ValueError, match="unknown policy 'nope'"):
        run_suite(tiny, ["nope"], out, resume=True, progress=False)
    assert (out / RESULTS_FILE).read_bytes() == before
    with pytest.raises(ValueError, match="unknown policy"):
        run_suite(tiny, ["hover", "nope"], tmp_path / "fresh", progress=False)
    assert not (tmp_path / "fresh").exists()


def test_checkpoint_that_does_not_load(tiny, tmp_path, monkeypatch):
    import uavform_env.policies as policies

    ckpt = tmp_path / "model.zip"
    ckpt.write_bytes(b"not a model")
    with pytest.raises(ValueError, match="not a readable zip file"):
        run_suite(tiny, [str(ckpt)], tmp_path / "a", progress=False)
    unknown = tmp_path / "model.ckpt"
    unknown.write_bytes(b"weights")
    with pytest.raises(ValueError, match="no loader for '.ckpt' files"):
        run_suite(tiny, [str(unknown)], tmp_path / "a", progress=False)
    assert not (tmp_path / "a").exists()

    def broken_loader(spec):
        def load():
            raise RuntimeError("truncated weights")
        return load

    monkeypatch.setattr(policies, "policy_factory", broken_loader)
    with pytest.raises(ValueError, match="could not be loaded: RuntimeError: truncated weights"):
        run_suite(tiny, [str(ckpt)], tmp_path / "b", progress=False)
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def test_corrupt_and_torn_lines(tiny, serial_run, tmp_path):
    lines = (serial_run[0] / RESULTS_FILE).read_text().splitlines()
    corrupt = tmp_path / "corrupt"
    corrupt.mkdir()
    (corrupt / RESULTS_FILE).write_text(lines[0] + "\n{not json\n" + lines[1] + "\n")
    with pytest.raises(ValueError, match="line 2: corrupt results line"):
        run_suite(tiny, ["hover"], corrupt, resume=True, progress=False)
    assert (corrupt / RESULTS_FILE).read_text().count("\n") == 3

    torn = tmp_path / "torn"
    torn.mkdir()
    (torn / RESULTS_FILE).write_text("\n".join(lines[:2]) + "\n" + lines[2][:40])
    with pytest.warns(UserWarning, match="torn last line"):
        records = run_suite(tiny, POLICIES, torn, resume=True, progress=False)
    assert _exact(records) == _exact(serial_run[1])
    assert (torn / (RESULTS_FILE + ".torn")).read_text() == lines[2][:40] + "\n"


def test_cli_show_and_errors(tiny, serial_run, capsys):
    out, records = serial_run
    assert main(["leaderboard", "--show", str(out)]) == 0
    shown = capsys.readouterr().out
    assert f"hash `{tiny.hash}`" in shown
    assert "| 1 | `hover` | 2 | 0 |" in shown and f"| 3 | `{EXPLODING}` | 2 | 2 |" in shown
    assert main(["leaderboard", "--suite", "v9", "--policy", "hover", "--out", str(out)]) == 2
    assert "unknown suite 'v9'" in capsys.readouterr().err
    assert main(["leaderboard", "--show", str(out / "nowhere")]) == 2
    assert "suite.json is missing" in capsys.readouterr().err


def _row(policy: str, ci: tuple[float, float], family: dict) -> dict:
    stat = lambda lo, hi: {"mean": (lo + hi) / 2, "ci_low": lo, "ci_high": hi, "n": 10}
    return {"policy": policy, "metrics": {"success": stat(*ci)},
            "groups": {"family": {g: {"success": stat(*c)} for g, c in family.items()}, "disturbance": {}}}


def test_separations_known_answers():
    summary = {"policies": [_row("top", (0.6, 0.8), {"a": (0.5, 0.7), "b": (0.9, 1.0)}),
                            _row("low", (0.1, 0.3), {"a": (0.1, 0.49), "b": (0.2, 0.4)}),
                            _row("touch", (0.5, 0.6), {"a": (0.7, 0.9)}),
                            _row("high", (0.81, 0.9), {"a": (0.71, 0.8), "b": (0.0, 0.95)})]}
    assert separations(summary) == [("all episodes", ["low"], ["high"], ["touch"]),
                                    ("a", ["low"], ["high"], ["touch"]),   # a CI that touches overlaps
                                    ("b", ["low"], [], ["high"])]          # "touch" did not play b


def test_readme_v1_tables_are_generated_from_the_published_results(capsys):
    """The README's v1 tables are what `--show docs/leaderboard/v1 --brief` prints, not numbers written beside it."""
    readme = (REPO / "README.md").read_text()
    begin = "<!-- generated: uavform leaderboard --show docs/leaderboard/v1 --brief -->\n"
    block = readme[readme.index(begin) + len(begin):readme.index("<!-- end generated -->")]
    assert main(["leaderboard", "--show", str(REPO / "docs" / "leaderboard" / "v1"), "--brief"]) == 0
    assert capsys.readouterr().out == block
    assert main(["leaderboard", "--brief"]) == 2
    assert "--brief goes with --show" in capsys.readouterr().err


# ---------------------------------------------------------------- suite v1, outcomes, probability of improvement

def test_v1_and_v1_dev_share_the_recipe_with_disjoint_seeds():
    from uavform_env.config import DISTURBANCE_PRESETS
    from uavform_env.evaluation.suite_v1 import SPLITS, shipped_path, suite_toml

    test, dev, v0 = load_suite("v1"), load_suite("v1-dev"), load_suite("v0")
    for suite in (test, dev):
        assert len(suite.episodes) >= 300
        assert suite_toml(suite.name) == shipped_path(suite.name).read_text(encoding="utf-8")  # the recipe's output
        assert {e.family for e in suite.episodes} == set(list_scenarios())
        assert {e.wind for e in suite.episodes} == set(DISTURBANCE_PRESETS)
        assert all(e.scenario.endswith("@2") or e.scenario == "dog-leg@1" for e in suite.episodes)
        assert {e.task for e in suite.episodes} >= {"random-3d-easy", "random-3d-hard", "dog-leg-hard",
                                                    "classic-2d-extended"}
        sizes = {e.n_uavs for e in suite.episodes}
        assert min(sizes) == 1 and max(sizes) == 10 and len(sizes) == 10
        assert {e.formation for e in suite.episodes} == {"wedge", "diamond", "triangle", "line", "column"}
    strip = [{k: v for k, v in e.to_dict().items() if k not in ("seed", "n_uavs", "formation", "spacing")}
             for e in test.episodes]
    assert strip == [{k: v for k, v in e.to_dict().items() if k not in ("seed", "n_uavs", "formation", "spacing")}
                     for e in dev.episodes]
    seeds = [{e.seed for e in s.episodes} for s in (test, dev, v0)]
    assert not (seeds[0] & seeds[1]) and not (seeds[0] & seeds[2]) and not (seeds[1] & seeds[2])
    assert len(seeds[0]) == len(test.episodes) and set(SPLITS) == {"v1", "v1-dev"}


def test_list_prints_one_episode_id_per_line(capsys):
    assert main(["leaderboard", "--suite", "v1-dev", "--list"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines == [e.key for e in load_suite("v1-dev").episodes] and len(set(lines)) == len(lines)
    assert main(["leaderboard", "--suite", "v7", "--list"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "unknown suite 'v7'" in err


@pytest.mark.parametrize("edit, message", [
    (('max_cycles = 15\n"""', 'max_cycles = 15\ndisturbance = "storm"\n"""'), "unknown disturbance preset 'storm'"),
    (('max_cycles = 15\n"""', 'max_cycles = 15\nspacing = "wide"\n"""'), "spacing='wide'"),
])
def test_bad_disturbance_or_spacing_in_a_suite(tmp_path, edit, message):
    path = tmp_path / "bad.toml"
    path.write_text((TINY_SUITE + '"""').replace(*edit)[:-3])
    with pytest.raises(ValueError, match="episode 1") as info:
        load_suite(path)
    assert message in str(info.value)


def test_disturbed_episode_keys_and_env(tmp_path):
    path = tmp_path / "w.toml"
    path.write_text(TINY_SUITE.replace("max_cycles = 15\n", "max_cycles = 15\nspacing = 2.5\ndisturbance = \"gusty\"\n")
                    .replace("scenario = \"classic-2d@1\"\ndifficulty = \"base\"\nn_uavs = 1\nformation = \"wedge\""
                             "\nseed = 0\nmax_cycles = 15\nspacing = 2.5\ndisturbance = \"gusty\"\n",
                             "scenario = \"classic-2d@1\"\ndifficulty = \"base\"\nn_uavs = 1\nformation = \"wedge\""
                             "\nseed = 0\nmax_cycles = 15\n"))
    suite = load_suite(path)
    first, second = suite.episodes
    assert first.key == "classic-2d@1/base/n1/wedge/s0/c15" and first.wind == "calm" and "spacing" not in first.to_dict()
    assert second.key == "forest@1/-/n2/column/s3/c15/sp2.5/gusty" and second.wind == "gusty"
    env = uavform_env.parallel_env(**second.env_kwargs())
    assert env.config.disturbance.wind_std == 1.0 and env.config.formation.spacing == 2.5


def test_probability_of_improvement_known_answers():
    from uavform_env.evaluation.table import probability_of_improvement

    def ep(success, collision=0.0, ferr=1.0, time=10.0):
        return {"success": success, "collision": collision, "formation_error_rms": ferr, "flight_time": time}

    good, bad = [ep(1.0)] * 8, [ep(0.0, 1.0)] * 8
    assert probability_of_improvement(good, bad) == (1.0, 1.0, 1.0)
    assert probability_of_improvement(bad, good) == (0.0, 0.0, 0.0)
    assert probability_of_improvement(good, good) == (0.5, 0.5, 0.5)
    # wins 1, 0, 1/2 (a tie), 1: mean 0.625; the score is lexicographic (success, then collision, then ...)
    x = [ep(1.0), ep(0.0, 1.0), ep(0.0, 0.0, 2.0), ep(0.0, 0.0, 0.5)]
    y = [ep(0.0), ep(0.0, 0.0), ep(0.0, 0.0, 2.0), ep(0.0, 0.0, 1.0)]
    p, lo, hi = probability_of_improvement(x, y)
    assert p == 0.625 and 0.0 <= lo <= p <= hi <= 1.0
    q, qlo, qhi = probability_of_improvement(y, x)
    assert p + q == 1.0 and lo + qhi == pytest.approx(1.0) and hi + qlo == pytest.approx(1.0)
    assert all(math.isnan(v) for v in probability_of_improvement([], []))


def test_records_written_before_a_metric_or_outcome_existed_stay_readable(tiny, serial_run):
    out, records = serial_run
    old = []
    for r in records:
        r = {k: v for k, v in r.items() if k not in ("outcome", "outcome_detail", "diagnostics")}
        if r["metrics"] is not None:
            r["metrics"] = {k: v for k, v in r["metrics"].items() if k not in ("planning_ms_p95", "time_to_reform")}
        old.append(r)
    summary = summarize(tiny, old)
    text = to_markdown(summary)
    row = next(r for r in summary["policies"] if r["policy"] == "hover")
    assert row["metrics"]["planning_ms_p95"]["recorded"] == 0 and "| planning_ms_p95 (ms) | absent" in text
    assert row["outcomes"] == {"timeout": 2}
    assert next(r for r in summary["policies"] if r["policy"] == EXPLODING)["outcomes"] == {"failed": 2}
    from uavform_env.evaluation.table import record_outcome
    before = {"status": "ok", "metrics": {"success": 1.0, "collision": 1.0}}
    assert record_outcome(before) == "success-with-crash"
    assert record_outcome({"status": "ok", "metrics": {"success": 0.0, "collision": 1.0}}) == "crash"


def test_every_failed_episode_says_why(tiny, serial_run):
    out, records = serial_run
    by = {(r["policy"], r["episode"]): r for r in records}
    assert {r["outcome"] for r in records if r["policy"] == "hover"} == {"timeout"}
    assert all("the step limit (15 steps) ran out" in r["outcome_detail"] for r in records if r["policy"] == "hover")
    boom = by[(EXPLODING, tiny.episodes[0].key)]
    assert boom["outcome"] == "failed" and "boom inside the policy" in boom["outcome_detail"]
    write_tables(tiny, records, out)
    failures = (out / "failures.csv").read_text().splitlines()
    assert failures[0] == "policy,episode,outcome,detail,diagnostics" and len(failures) == 1 + len(records)
    text = (out / "leaderboard.md").read_text()
    assert "## Why episodes ended" in text and "| timeout | 2 |" in text
    assert "## Success and collision rate per family" in text and "| calm |" in text
    assert "## Probability of improvement" in text
