"""Scripts of benchmarks/ that tests can afford, with tiny settings: the speed and success benchmarks and the wind
benchmarks reach into the env's and the expert's stages (the wind ones fly ``baselines.fusion.rules``' station keeping
and wind estimate outside the controller), so a change of those signatures must show here (session 22 found
``wind_authority.py`` broken since ``station_keep`` took a clearance); and the paired comparison of flight records
(``compare_flights.py``) against scipy's binomial test; the split of a collision's clearance loss
(``crash_causes.py``) against known answers. The suite-wide ones (``gust_seeds.py``,
``dogleg_feasibility.py``) fly a suite file of one short episode; ``env_step.py`` and ``train_throughput.py`` a
handful of steps."""

import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.stats import binomtest

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


def _module(name, monkeypatch):
    monkeypatch.syspath_prepend(str(BENCHMARKS))        # as a script: its siblings import by name
    spec = importlib.util.spec_from_file_location(f"benchmark_{name}", BENCHMARKS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _run(name, argv, monkeypatch):
    module = _module(name, monkeypatch)
    monkeypatch.setattr(sys, "argv", [f"{name}.py", *argv])
    module.main()


def _rows(text):
    return [line for line in text.splitlines() if line.startswith("| `")]


@pytest.mark.parametrize("name, argv, expect", [
    ("planner", ["--steps", "5", "--n", "2"], "expert / env (medians): "),
    ("step_stages", ["--steps", "5", "--ns", "2", "--repeats", "1"], "microseconds per UAV-step, by stage"),
    ("map_update", ["--uavs", "2", "--steps", "5", "--repeats", "1"], "octomap insertPointCloud"),
    ("expert_success", ["--scenarios", "forest", "--seeds", "0", "--max-steps", "5"], "total: 0/1 success")])
def test_speed_and_success_benchmarks_run_with_tiny_settings(name, argv, expect, monkeypatch, capsys):
    """They time the env's and the expert's stages by name (the injected planners, the map, the kernels): a renamed
    or re-signed stage must break a test, not the next session's measurement."""
    _run(name, argv, monkeypatch)
    assert expect in capsys.readouterr().out


def test_wind_authority_tables_every_windy_preset_and_airframe(monkeypatch, capsys):
    _run("wind_authority", ["--seeds", "1", "--seconds", "6"], monkeypatch)
    rows = _rows(capsys.readouterr().out)
    assert [r.split(" | ")[0] for r in rows] == ["| `breeze`", "| `breeze`", "| `gusty`", "| `gusty`"]
    assert all(r.count("|") == 12 for r in rows)


def test_disturbance_drift_tables_every_preset(monkeypatch, capsys):
    _run("disturbance_drift", ["--seeds", "1"], monkeypatch)
    presets = [r.split(" | ")[0] for r in _rows(capsys.readouterr().out)]
    assert presets == ["| `calm`", "| `breeze`", "| `breeze`", "| `gusty`", "| `gusty`", "| `noisy`"]


@pytest.mark.parametrize("name, argv, flag", [("wind_authority", ["--seconds", "2"], "--seconds 2"),
                                               ("wind_authority", ["--seeds", "0"], "--seeds 0"),
                                               ("disturbance_drift", ["--seeds", "0"], "--seeds 0")])
def test_wind_benchmarks_refuse_bad_settings_in_one_line(name, argv, flag, monkeypatch, capsys):
    with pytest.raises(SystemExit) as exit_:
        _run(name, argv, monkeypatch)
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith(f"{name}.py: error: {flag}: expected")


def test_expert_success_flies_missions_beyond_the_suites(monkeypatch, capsys):
    """Formation, difficulty and wind overrides reach the env; the header names them."""
    _run("expert_success", ["--scenarios", "random-3d@2", "--seeds", "0", "--max-steps", "5", "--n", "12",
                            "--formation", "column", "--difficulty", "hard", "--wind", "breeze"], monkeypatch)
    out = capsys.readouterr().out
    assert "12 UAVs, formation column, difficulty hard, wind breeze" in out and "total: 0/1 success" in out


@pytest.mark.parametrize("argv, flag", [(["--n", "13", "--formation", "diamond"], "--scenarios urban@2"),
                                        (["--wind", "stormy"], "--scenarios urban@2"),
                                        (["--difficulty", "hard"], "--scenarios urban@2"),
                                        (["--policy", "nope"], "--policy")])
def test_expert_success_refuses_a_bad_mission_before_flying(argv, flag, monkeypatch, capsys):
    with pytest.raises(SystemExit) as exit_:
        _run("expert_success", ["--scenarios", "urban@2", "--seeds", "0", *argv], monkeypatch)
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith(f"expert_success.py: error: {flag}: ")
    assert "SUCCESS" not in capsys.readouterr().out


def test_mission_draws_are_fixed_by_seed_and_index_and_every_draw_builds(monkeypatch):
    """A draw is the same mission however many draws are asked for; each fits its scenario (team, formation,
    difficulty) and its disturbance is a valid ``DisturbanceConfig``, so a record can be flown again."""
    from uavform_env.config import DisturbanceConfig
    from uavform_env.formation_v0 import parallel_env

    module = _module("mission_draws", monkeypatch)
    args = (module.FAMILIES, (1, 16), (1.2, 3.5), (0.0, 0.6), 0.4)
    draws = [module.draw(3, i, *args) for i in range(40)]
    assert module.draw(3, 17, *args) == draws[17] and module.draw(4, 17, *args) != draws[17]
    assert {d["kwargs"]["scenario"].split("@")[0] for d in draws} >= {"forest", "urban", "dog-leg"}
    assert any(d["disturbance"] == {} for d in draws) and any("wind_std" in d["disturbance"] for d in draws)
    for d in draws[:12]:
        parallel_env(**d["kwargs"], layout_seed=d["seed"], disturbance=DisturbanceConfig(**d["disturbance"])).close()


def test_mission_draws_airframes_change_the_config_not_the_mission(monkeypatch):
    """``--airframes``: a share of draws also changes the env's config (its own generator, so the mission is the one
    drawn without it); every drawn config is a valid ``EnvConfig`` that an env is built with."""
    from uavform_env.config import EnvConfig
    from uavform_env.formation_v0 import parallel_env

    module = _module("mission_draws", monkeypatch)
    args = (module.FAMILIES, (1, 16), (1.2, 3.5), (0.0, 0.6), 0.4)
    plain = [module.draw(5, i, *args) for i in range(30)]
    varied = [module.draw(5, i, *args, airframes=0.5) for i in range(30)]
    assert all(p["config"] == {} for p in plain)
    assert [{**v, "config": {}} for v in varied] == plain
    changed = [v for v in varied if v["config"]]
    assert 5 <= len(changed) <= 25 and {part for v in changed for part in v["config"]} >= {"uav", "sensor", "map"}
    for v in changed[:6]:
        cfg = EnvConfig.from_dict(v["config"])
        assert all(getattr(getattr(cfg, part), name) == value
                   for part, fields in v["config"].items() for name, value in fields.items())
        parallel_env(**v["kwargs"], layout_seed=v["seed"], config=cfg).close()


def test_mission_draws_fly_and_write_their_records(tmp_path, monkeypatch, capsys):
    out = tmp_path / "draws.jsonl"
    _run("mission_draws", ["--draws", "2", "--scenarios", "forest@2", "--max-steps", "5", "--out", str(out)],
         monkeypatch)
    records = [json.loads(line) for line in out.read_text().splitlines()]
    assert [r["draw"] for r in records] == [0, 1] and {r["outcome"] for r in records} == {"timeout"}
    assert "| all | 2 |" in capsys.readouterr().out


@pytest.mark.parametrize("argv, flag", [(["--n", "5", "2"], "--n 5 2"), (["--n", "0", "3"], "--n 0 3"),
                                        (["--spacing", "0.1", "2"], "--spacing 0.1 2"),
                                        (["--still-share", "2"], "--still-share 2"), (["--draws", "0"], "--draws 0"),
                                        (["--airframes", "-0.1"], "--airframes -0.1"),
                                        (["--scenarios", "forest@9"], "--scenarios forest@9"),
                                        (["--policy", "nope"], "--policy")])
def test_mission_draws_refuse_bad_settings_before_flying(argv, flag, monkeypatch, capsys):
    with pytest.raises(SystemExit) as exit_:
        _run("mission_draws", argv, monkeypatch)
    assert exit_.value.code == 2
    assert capsys.readouterr().err.strip().splitlines()[-1].startswith(f"mission_draws.py: error: {flag}")


@pytest.mark.parametrize("b, c", [(0, 0), (0, 1), (4, 5), (8, 1), (3, 11), (0, 12), (20, 7), (30, 30)])
def test_mcnemar_p_is_scipys_exact_two_sided_binomial_test(b, c, monkeypatch):
    p = _module("compare_flights", monkeypatch).mcnemar_p(b, c)
    assert p == (1.0 if b + c == 0 else pytest.approx(binomtest(min(b, c), b + c, 0.5).pvalue, rel=1e-12))


def _flights(path, outcomes, rms=3.0):
    """Write gust_seeds-style records: ``outcomes`` maps (episode key, wind) to (outcome, steps)."""
    path.write_text("".join(json.dumps({"episode": k, "wind": w, "outcome": o, "steps": n, "formation_error_rms": rms,
                                        "detail": ""}) + "\n" for (k, w), (o, n) in outcomes.items()))
    return str(path)


def test_compare_flights_pairs_by_episode_and_wind_and_counts_the_discordant_pairs(tmp_path, monkeypatch, capsys):
    cf = _module("compare_flights", monkeypatch)
    calm, gusty = "forest@2/-/n4/line/s1/c900/sp2", "dog-leg@1/easy/n2/line/s2/c900/sp2/gusty"
    base = {(calm, 0): ("success", 500), (calm, 1): ("timeout", 900), (gusty, 0): ("crash-obstacle", 300),
            (gusty, 1): ("success", 700), (gusty, 2): ("timeout", 900)}
    new = {(calm, 0): ("success", 480), (calm, 1): ("success", 850), (gusty, 0): ("timeout", 900),
           (gusty, 1): ("success", 690), ("urban@2/-/n3/line/s9/c900/sp2", 0): ("success", 400)}
    rows = cf.compare(cf.load([_flights(tmp_path / "a.jsonl", base)]),
                      cf.load([_flights(tmp_path / "b.jsonl", new, rms=2.5)]))
    by = {r["preset"]: r for r in rows}
    assert [r["preset"] for r in rows] == ["calm", "gusty", "all"]
    assert by["calm"]["success"] == (1, 2, 0, 1, 1.0) and by["calm"]["steps_change"] == -20.0
    assert by["gusty"]["flights"] == 2 and by["gusty"]["collision"] == (1, 0, 1, 0, 1.0)
    assert by["all"]["success"][:4] == (2, 3, 0, 1) and by["all"]["rms_change"] == pytest.approx(-0.5)
    assert by["all"]["steps_change"] == pytest.approx(-15.0) and by["all"]["both_succeed"] == 2
    assert cf.main([str(tmp_path / "a.jsonl"), "--against", str(tmp_path / "b.jsonl")]) == 0
    out = capsys.readouterr().out
    assert out.startswith("4 paired flights (2 without a partner, left out)")
    assert f"{calm} wind 1: timeout -> success" in out and f"{gusty} wind 0: crash-obstacle -> timeout" in out


def test_compare_flights_groups_by_the_recorded_preset_and_scenario_and_reads_old_records_by_the_key(tmp_path,
                                                                                                     monkeypatch):
    cf = _module("compare_flights", monkeypatch)
    key = "urban@2/-/n3/line/s9/c900/sp2"                            # a key naming no preset, as a v0 suite's
    new = tmp_path / "new.jsonl"
    new.write_text(json.dumps({"episode": key, "scenario": "urban@2", "preset": "breeze", "wind": 0,
                               "outcome": "success", "steps": 400, "formation_error_rms": 2.0, "detail": ""}) + "\n")
    old = _flights(tmp_path / "old.jsonl", {(key, 0): ("timeout", 900)})
    assert [r["preset"] for r in cf.compare(cf.load([str(new)]), cf.load([old]))] == ["breeze", "all"]
    assert [r["preset"] for r in cf.compare(cf.load([old]), cf.load([str(new)]))] == ["calm", "all"]   # by the key
    assert cf.families(cf.load([old]), cf.load([str(new)])) == {"urban@2": [0, 1, 1]}


def test_compare_flights_refuses_bad_files_in_one_line(tmp_path, monkeypatch, capsys):
    cf = _module("compare_flights", monkeypatch)
    good = _flights(tmp_path / "a.jsonl", {("forest@2/-/n4/line/s1/c900/sp2", 0): ("success", 500)})
    twice = tmp_path / "twice.jsonl"
    twice.write_text(open(good).read() * 2)
    other = _flights(tmp_path / "o.jsonl", {("urban@2/-/n3/line/s9/c900/sp2", 0): ("success", 400)})
    torn = tmp_path / "torn.jsonl"
    torn.write_text('{"episode": "x", "wind": 0}\n')
    for argv, message in (([str(tmp_path / "missing.jsonl"), "--against", good], "missing.jsonl: no such file"),
                          ([str(twice), "--against", good], "appears twice on one side"),
                          ([good, "--against", other], "no flight of these files flew"),
                          ([good, "--against", str(torn)], "line 1: corrupt flight record")):
        assert cf.main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("error: ") and message in err[0]


def _one_episode_suite(tmp_path, scenario, seed, n_uavs=1, disturbance=None, max_cycles=30, difficulty=None):
    """A suite file of one short episode, so the suite-wide benchmarks run in seconds."""
    lines = [f'name = "one-{scenario}"', 'description = "a benchmark smoke test"', "", "[[episode]]",
             f'scenario = "{scenario}"', f"n_uavs = {n_uavs}", 'formation = "wedge"', "spacing = 2.0",
             f"seed = {seed}", f"max_cycles = {max_cycles}"]
    lines += [f'difficulty = "{difficulty}"'] if difficulty else []
    lines += [f'disturbance = "{disturbance}"'] if disturbance else []
    path = tmp_path / "one.toml"
    path.write_text("\n".join(lines) + "\n")
    return str(path)


def test_gust_seeds_flies_each_wind_and_writes_records_compare_flights_reads(tmp_path, monkeypatch, capsys):
    suite = _one_episode_suite(tmp_path, "classic-2d@2", 5, disturbance="gusty", difficulty="base")
    out = tmp_path / "flights.jsonl"
    _run("gust_seeds", ["--suite", suite, "--winds", "2", "--out", str(out)], monkeypatch)
    assert "1 episodes x 2 winds = 2 flights" in capsys.readouterr().out
    records = [json.loads(line) for line in out.read_text().splitlines()]
    assert sorted(r["wind"] for r in records) == [0, 1] and all(r["steps"] <= 30 for r in records)
    assert {(r["scenario"], r["preset"]) for r in records} == {("classic-2d@2", "gusty")}
    assert all(r["after_reach_s"] is None and r["after_reach_followers_never"] is None and r["n_uavs"] == 1
               for r in records)                                               # 3 s flights: no goal reached
    cf = _module("compare_flights", monkeypatch)
    assert cf.main([str(out), "--against", str(out)]) == 0
    assert capsys.readouterr().out.startswith("2 paired flights")


def test_dogleg_feasibility_prints_the_oracle_and_the_explorer_route(tmp_path, monkeypatch, capsys):
    suite = _one_episode_suite(tmp_path, "dog-leg@1", 200280, difficulty="hard")
    assert _module("dogleg_feasibility", monkeypatch).main(["--suite", suite]) == 0
    row = capsys.readouterr().out.splitlines()[1].split()
    oracle, greedy = float(row[1]), float(row[2])
    assert 20.0 < oracle <= greedy < 300.0                          # no explorer beats the route on the true map


def test_train_throughput_measures_rollout_and_ppo(monkeypatch, capsys, recwarn):
    """With 2 UAVs per copy: PPO's minibatches divide that rollout (they were sized for 5 UAVs, and SB3 warned of a
    truncated minibatch)."""
    pytest.importorskip("stable_baselines3")
    _run("train_throughput", ["--n", "2", "--timesteps", "64", "--copies", "1"], monkeypatch)
    row = capsys.readouterr().out.strip().splitlines()[-1].split("|")
    assert row[1].strip() == "1" and float(row[2]) > 0.0 and float(row[3]) > 0.0
    assert not [w for w in recwarn if "mini-batch" in str(w.message)]


def test_env_step_reports_every_n_with_the_anchors(tmp_path, monkeypatch, capsys):
    out = tmp_path / "speed.json"
    _run("env_step", ["--ns", "2", "--steps", "5", "--resets", "1", "--copies", "2", "--vector-workers", "1",
                      "--budget", "1", "--out", str(out)], monkeypatch)
    result = json.loads(out.read_text())
    ours, mpe, vmas = (result["rows"][0][k] for k in ("ours", "mpe", "vmas"))
    assert result["rows"][0]["n"] == 2 and ours["steps"] == 5 and ours["alive"] == 1.0   # every UAV flew all steps
    assert ours["agent_steps_per_s"] > 0.0 and mpe["agent_steps_per_s"] > 0.0
    assert "agent_steps_per_s" in vmas or "vmas failed" in vmas["error"]    # VMAS: the bench extra, not the tests'
    vector = result["vector"][0]
    assert (vector["copies"], vector["workers"], vector["steps"]) == (2, 1, 5) and vector["agent_steps_per_s"] > 0.0
    assert "| 2 | " in capsys.readouterr().out


def test_crash_causes_splits_a_known_clearance_loss(monkeypatch):
    """A wall at x = 5 (clearance 5 - x): three steps of 0.3 m toward it, 0.2 of each the wind's, lose 0.6 m to the
    wind and 0.3 to the UAV; a step along the wall loses nothing; a separation's gradient is the unit offset."""
    cc = _module("crash_causes", monkeypatch)
    wall = lambda p: 5.0 - float(p[0])                                  # noqa: E731
    pos = np.array([[0.0, 0.0, 3.0], [0.3, 0.0, 3.0], [0.6, 0.0, 3.0], [0.9, 0.5, 3.0]])
    winds = np.array([[0.2, 0.0, 0.0], [0.2, 0.0, 0.0], [0.2, 0.5, 0.0]])
    wind, own = cc.split_loss(pos, winds, wall)
    assert wind == pytest.approx(0.6, abs=1e-9) and own == pytest.approx(0.3, abs=1e-9)
    rel = np.array([[3.0, 4.0, 0.0], [2.4, 3.2, 0.0]])                   # 5 m apart, closing by 1 m, all the wind's
    wind, own = cc.split_loss(rel, np.array([[-0.6, -0.8, 0.0]]), lambda p: float(np.linalg.norm(p)))
    assert wind == pytest.approx(1.0, abs=1e-6) and own == pytest.approx(0.0, abs=1e-6)


def test_crash_causes_replays_each_collision_and_reports_a_replay_that_differs(tmp_path, monkeypatch, capsys):
    suite = _one_episode_suite(tmp_path, "classic-2d@2", 5, disturbance="gusty", difficulty="base")
    key = "classic-2d@2/base/n1/wedge/s5/c30/sp2/gusty"
    flights = tmp_path / "flights.jsonl"
    flights.write_text(json.dumps({"episode": key, "wind": 0, "outcome": "crash-obstacle"}) + "\n"
                       + json.dumps({"episode": key, "wind": 1, "outcome": "timeout"}) + "\n")
    out = tmp_path / "causes.jsonl"
    png = tmp_path / "causes.png"
    assert _module("crash_causes", monkeypatch).main([str(flights), "--suite", suite, "--out", str(out),
                                                      "--plot", str(png)]) == 0
    assert png.read_bytes().startswith(b"\x89PNG")
    text = capsys.readouterr().out
    assert text.startswith("1 flights with a collision") and f"replay ended timeout, not in a collision: {key}" in text
    assert [json.loads(line) for line in out.read_text().splitlines()] == [
        {"episode": key, "wind": 0, "outcome": "timeout"}]


@pytest.mark.parametrize("content, message", [
    (None, "cannot read"),
    ("not json\n", ":1: neither a gust_seeds.py flight record nor a leaderboard result"),
    ('{"episode": "forest@2/-/n3/line/s1/c900/sp2", "outcome": "timeout"}\n', "is not in --suite")])
def test_crash_causes_refuses_bad_files_in_one_line(content, message, tmp_path, monkeypatch, capsys):
    suite = _one_episode_suite(tmp_path, "classic-2d@2", 5, disturbance="gusty", difficulty="base")
    path = tmp_path / "flights.jsonl"
    if content is not None:
        path.write_text(content)
    assert _module("crash_causes", monkeypatch).main([str(path), "--suite", suite]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and message in err[0]


def test_gust_seeds_sets_number_flag_and_choice_fields_and_names_a_bad_one(monkeypatch):
    gs = _module("gust_seeds", monkeypatch)
    out = gs.parse_overrides(["e0=3", "park_turn=0", "leader_pace=slot", "dwa.beta=0.5"])
    assert (out["e0"], out["park_turn"], out["leader_pace"], out["dwa"].beta) == (3.0, False, "slot", 0.5)
    with pytest.raises(ValueError, match="leader_pace=.nose.: expected one of"):
        gs.parse_overrides(["leader_pace=nose"])


def test_gust_seeds_end_game_counts_the_flights_that_failed_after_the_leader_reached_the_goal(monkeypatch):
    gs = _module("gust_seeds", monkeypatch)
    base = {"steps": 900, "n_uavs": 5}
    fields = ("after_reach_s", "after_reach_leader_in", "after_reach_followers_in", "after_reach_followers_never")
    records = [dict(base, outcome="success", **dict(zip(fields, (3.0, 1.0, 0.5, 0)))),
               dict(base, outcome="timeout", **dict(zip(fields, (None, None, None, None)))),
               dict(base, outcome="timeout", **dict(zip(fields, (20.0, 0.2, 0.0, 2)))),
               dict(base, outcome="timeout", **dict(zip(fields, (40.0, 0.4, 0.1, 0))), n_uavs=9),
               {"outcome": "timeout", "steps": 900}]                          # an older record: not counted
    line = ("2 flights failed after the leader came within r_goal of the goal (median 30 s before the end; UAVs 5-9): "
            "in 1 of them the followers were never all within e_f at once; the leader was within r_goal in a median "
            "30 % of those steps")
    assert gs.end_game(records) == (line + "; in 1 of 2 a live follower never came within e_f of its slot after the "
                                    "arrival (in the other 1 each one did, but not all together with the leader)")
    for r in records[2:4]:                                                    # a session-25 record: no split
        del r["after_reach_followers_never"]
    assert gs.end_game(records) == line
    assert gs.end_game(records[:2]) == "no flight failed after its leader came within r_goal of the goal"
