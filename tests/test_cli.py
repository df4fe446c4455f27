"""The ``uavform`` command as a new user meets it: help, --version, one-line errors, outcomes, export, extras.

Flights are a few steps long (``--max-steps``) with cheap policies, so the file runs in seconds once the
numba kernels are cached.
"""

import argparse
import json
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from uavform_env import __version__
from uavform_env.cli import build_parser, main
from uavform_env.evaluation.runner import code_version
from uavform_env.kernels import MESSAGE, cold_modules, compile_notice
from uavform_env.scenarios import Scenario, list_scenarios, make_scenario

WINDOW = "examples/scenarios/window.toml"     # one UAV, a wall with a window 8 m ahead


class Forward:
    """Full speed straight ahead, no turning, no climbing: flies into whatever is in front."""

    def reset(self, env, seed):
        pass

    def act(self, observations, env):
        return {a: np.array([1.0, 0.0, 0.0], np.float32) for a in observations}


def fly(tmp_path, *flags, out="run"):
    return main(["fly", "--out", str(tmp_path / out), *flags])


def _subparsers(parser):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            yield from action.choices.items()


# ----------------------------------------------------------------------------- help and version
def test_every_option_of_every_command_has_help():
    parser = build_parser()
    commands = dict(_subparsers(parser))
    assert {"fly", "scenarios", "leaderboard", "train", "reproduce"} <= set(commands)
    for name, sub in [("uavform", parser), *commands.items()]:
        for action in sub._actions:
            if action.option_strings:
                assert action.help and action.help.strip(), f"{name} {action.option_strings[0]} has no help text"
    assert "``" not in parser.format_help() and ":func:" not in parser.format_help()


def test_train_help_gives_units_and_allowed_values():
    text = dict(_subparsers(build_parser()))["train"].format_help()
    for phrase in ("agent-steps", "rounded up", "n_steps x n_envs x n_uavs", "team | own", "in (0, 1]"):
        assert phrase in " ".join(text.split()), phrase


def test_version_names_the_package_and_the_code(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["--version"])
    assert exit_.value.code == 0
    assert capsys.readouterr().out.strip() == f"uavform {__version__} (code {code_version()})"


# ----------------------------------------------------------------------------- bad input
ARGPARSE_ERRORS = [
    (["fly", "--seed", "-1"], "argument --seed: expected an integer >= 0, got '-1'"),
    (["fly", "--max-steps", "0"], "argument --max-steps: expected an integer >= 1, got '0'"),
    (["fly", "--video-every", "0"], "argument --video-every: expected an integer >= 1, got '0'"),
    (["fly", "--format", "jpg"], "argument --format: invalid choice: 'jpg'"),
    (["fly", "--formation", "blob"], "argument --formation: invalid choice: 'blob'"),
    (["scenarios", "--export", "forest", "--n-uavs", "0"], "argument --n-uavs: expected an integer >= 1"),
    (["leaderboard", "--workers", "0", "--policy", "hover"], "argument --workers: expected an integer >= 1"),
    (["leaderboard", "--time-limit", "-5", "--policy", "hover"], "argument --time-limit: expected a number > 0"),
    (["train", "--out", "x", "--n-uavs", "0"], "argument --n-uavs: expected an integer >= 1"),
    (["train", "--out", "x", "--learning-rate", "2"], "argument --learning-rate: expected a number in (0, 1]"),
    (["train", "--out", "x", "--reward", "best"], "argument --reward: invalid choice: 'best'"),
]


@pytest.mark.parametrize("argv, message", ARGPARSE_ERRORS, ids=[" ".join(a[:3]) for a, _ in ARGPARSE_ERRORS])
def test_bad_flags_give_one_line_naming_the_flag(argv, message, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(argv)
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and "Traceback" not in err


def test_too_many_uavs_for_the_memory_names_n_uavs(tmp_path, capsys, monkeypatch):
    env_module = sys.modules["uavform_env.env"]  # the package's `env` attribute is the AEC constructor
    monkeypatch.setattr(env_module, "available_memory", lambda: 2**20)  # a machine with 1 MiB free
    assert main(["fly", "--n-uavs", "100", "--out", str(tmp_path / "never")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("uavform fly: error: --n-uavs 100: n_uavs=100 at map resolution ") and err.count("\n") == 1
    assert "use fewer UAVs" in err and not (tmp_path / "never").exists()


def test_bad_inputs_fail_before_any_work(tmp_path, capsys):
    existing = tmp_path / "taken"
    existing.write_text("mine")
    cases = [
        (["--out", str(existing)], f"--out {existing}: a file of that name exists; --out is a folder"),
        (["--policy", "os:path"], "--policy os:path: policy 'os:path': 'path' is a module, not a class or function"),
        (["--policy", "expertt"], "--policy expertt: unknown policy 'expertt'"),
        (["--scenario", "forrest"], "--scenario forrest: unknown scenario 'forrest'; known scenarios:"),
        (["--scenario", str(tmp_path / "none.toml")], f"--scenario {tmp_path / 'none.toml'}: no such file"),
        (["--scenario", "forest", "--difficulty", "hard"], "--difficulty hard: difficulty='hard' for scenario"),
        (["--scenario", "random-3d", "--difficulty", "insane"], "--difficulty insane: "),
    ]
    for flags, message in cases:
        assert main(["fly", *flags] + ([] if "--out" in flags else ["--out", str(tmp_path / "never")])) == 2
        err = capsys.readouterr().err
        assert err.startswith("uavform fly: error: ") and message in err and err.count("\n") == 1, (flags, err)
    assert existing.read_text() == "mine" and not (tmp_path / "never").exists()


def test_a_loaded_file_is_named_by_its_path(tmp_path, capsys):
    scn = Scenario.from_toml(WINDOW)
    blocked = scn.with_mission(start=(11.5, 8.0, 3.0))          # inside the wall
    path = tmp_path / "blocked.toml"
    blocked.to_toml(path)
    assert fly(tmp_path, "--scenario", str(path), "--policy", "hover", "--max-steps", "3") == 2
    err = capsys.readouterr().err
    assert f"scenario file {path} cannot be flown: leader start" in err and "scenario 'window'" not in err


def test_missing_extras_give_the_pip_command(tmp_path, monkeypatch, capsys):
    for module in ("torch", "stable_baselines3"):
        monkeypatch.setitem(sys.modules, module, None)           # "not installed"
    monkeypatch.delitem(sys.modules, "training.train", raising=False)
    checkpoint = tmp_path / "best.zip"
    checkpoint.write_bytes(b"PK")
    assert fly(tmp_path, "--policy", str(checkpoint), "--max-steps", "3") == 2
    err = capsys.readouterr().err
    assert f"--policy {checkpoint} needs stable_baselines3, from the optional extra 'train': " \
           "pip install 'uavform[train]'" in err
    assert main(["train", "--out", str(tmp_path / "rw"), "--timesteps", "10"]) == 2
    err = capsys.readouterr().err
    assert "uavform train needs torch, from the optional extra 'train': pip install 'uavform[train]'" in err
    assert not (tmp_path / "run").exists() and not (tmp_path / "rw").exists()


def test_an_error_in_a_subprocess_is_one_line_without_traceback(tmp_path):
    run = subprocess.run([sys.executable, "-m", "uavform_env.cli", "fly", "--seed", "-1"], capture_output=True,
                         text=True, timeout=120)
    assert run.returncode == 2 and run.stdout == ""
    assert run.stderr == "uavform fly: error: argument --seed: expected an integer >= 0, got '-1' " \
                         "(see 'uavform fly --help')\n"


# ----------------------------------------------------------------------------- output
def test_quiet_prints_one_outcome_line_and_a_single_uav_has_no_formation_metrics(tmp_path, capsys):
    assert fly(tmp_path, "--policy", "hover", "--n-uavs", "1", "--max-steps", "5", "--quiet") == 0
    out = capsys.readouterr().out
    assert out.count("\n") == 1 and out.startswith("TIME-OUT: hover on forest, 1 UAV (") and ", seed 0, 5 steps" in out
    assert "nan" not in out and out.rstrip().endswith(
        "from the goal: the step limit (5 steps) ran out; the leader flew 0.0 m, 0.00 m/s on average")
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["outcome"] == "time-out" and summary["code_version"] == code_version()
    assert summary["units"]["goal_distance"] == "m" and summary["units"]["flight_time"] == "s"
    assert not {"formation_error_rms", "min_separation", "time_to_reform"} & set(summary)
    assert f"{summary['goal_distance']:.1f} m from the goal" in out
    assert (tmp_path / "run" / "trajectory.png").stat().st_size > 10_000


def test_a_crash_says_which_uav_hit_what(tmp_path, capsys):
    assert fly(tmp_path, "--scenario", WINDOW, "--policy", "tests.test_cli:Forward", "--max-steps", "400",
               "--format", "svg") == 0
    out = capsys.readouterr().out
    first = out.splitlines()[0]
    assert first.startswith("CRASH: tests.test_cli:Forward on " + WINDOW + ", 1 UAV")
    assert "uav_0 (leader) crashed into an obstacle at step" in first
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["outcome"] == "crash" and summary["collision"] == 1.0
    assert (tmp_path / "run" / "trajectory.svg").read_text().lstrip().startswith("<?xml")
    assert "nan m" not in out and "formation error" not in out


def test_a_hovering_formation_times_out_stuck(tmp_path, capsys):
    assert fly(tmp_path, "--policy", "hover", "--n-uavs", "2", "--max-steps", "320", "--quiet") == 0
    line = capsys.readouterr().out
    assert "2 UAVs" in line and "stuck: the leader moved 0.00 m in the last 30 s" in line


# ----------------------------------------------------------------------------- scenario export
def test_export_is_commented_sized_and_round_trips(tmp_path, capsys):
    out = tmp_path / "mine.toml"
    assert main(["scenarios", "--export", "forest", "--seed", "3", "--n-uavs", "3", "--formation", "line",
                 "--out", str(out)]) == 0
    assert capsys.readouterr().out.startswith(f"wrote {out}: forest@2 seed 3, 3 UAVs (line), ")
    text = out.read_text()
    for phrase in ("# Units: lengths and positions in metres", "[mission]", "# number of UAVs", "box:", "cylinder:"):
        assert phrase in text
    assert Scenario.from_toml(out) == make_scenario("forest", 3, n_uavs=3, formation="line")
    assert main(["scenarios", "--export", "urban", "--out", str(out)]) == 2
    assert f"--out {out}: the file exists; add --force to overwrite it" in capsys.readouterr().err
    assert Scenario.from_toml(out).name == "forest"
    assert main(["scenarios", "--export", "urban", "--out", str(out), "--force"]) == 0
    assert Scenario.from_toml(out) == make_scenario("urban")
    assert main(["scenarios", "--export", "nope", "--out", str(tmp_path / "n.toml")]) == 2
    assert "--export nope: unknown scenario 'nope'" in capsys.readouterr().err


@pytest.mark.parametrize("name", list_scenarios())
def test_every_registered_scenario_round_trips_through_the_commented_file(name, tmp_path):
    scn = make_scenario(name, seed=1)
    scn.to_toml(tmp_path / "s.toml")
    assert Scenario.from_toml(tmp_path / "s.toml") == scn


# ----------------------------------------------------------------------------- the compile notice
def test_the_compile_notice_is_printed_once_while_kernels_are_cold(tmp_path, monkeypatch, capsys):
    package = tmp_path / "nu_kernels"
    package.mkdir()
    (package / "__init__.py").write_text(textwrap.dedent("""
        from numba import njit

        @njit(cache=True)
        def twice(x):
            return 2 * x
    """))
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr("uavform_env.kernels.PACKAGES", ("nu_kernels",))
    import nu_kernels

    assert cold_modules() == ["nu_kernels"]
    assert compile_notice()
    assert capsys.readouterr().err == MESSAGE + "\n"
    assert nu_kernels.twice(2) == 4                              # compiles and writes the cache index
    assert cold_modules() == [] and compile_notice() is False
    nu_kernels.twice.overloads.clear()                           # a new process: only the disk cache is left
    assert cold_modules() == []
    monkeypatch.delitem(sys.modules, "nu_kernels")


def test_a_process_that_has_flown_gives_no_notice_even_with_modules_never_called(tmp_path, monkeypatch, capsys):
    """A leaderboard worker makes an env per episode, and modules whose kernels it never calls (the expert's, under
    `--policy hover`; OctoMap's ray-key helper) stay cold: once a kernel has run here, no env repeats the notice.
    Kernels inlined into their callers are never cached alone and do not count."""
    package = tmp_path / "nu_flown"
    package.mkdir()
    (package / "__init__.py").write_text(textwrap.dedent("""
        from numba import njit

        @njit(cache=True, inline="always")
        def helper(x):
            return x + 1

        @njit(cache=True)
        def used(x):
            return helper(x)

        @njit(cache=True)
        def never(x):
            return 3 * x
    """))
    (package / "idle.py").write_text(textwrap.dedent("""
        from numba import njit

        @njit(cache=True)
        def idle(x):
            return x
    """))
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr("uavform_env.kernels.PACKAGES", ("nu_flown",))
    import nu_flown
    import nu_flown.idle

    assert compile_notice() and capsys.readouterr().err == MESSAGE + "\n"
    assert nu_flown.used(1) == 2
    assert cold_modules() == ["nu_flown.idle"]                  # never called: cold for good
    assert compile_notice() is False and capsys.readouterr().err == ""
    for name in ("nu_flown.idle", "nu_flown"):
        monkeypatch.delitem(sys.modules, name)


def test_an_env_checks_for_cold_kernels_at_its_first_reset_only(monkeypatch):
    from uavform_env import parallel_env
    calls = []
    monkeypatch.setattr(sys.modules["uavform_env.env"], "compile_notice", lambda: calls.append(1))
    penv = parallel_env(scenario="forest@1", n_uavs=2, max_cycles=5)
    penv.reset(seed=0)
    penv.reset(seed=1)
    assert calls == [1]


# ----------------------------------------------------------------------------- why a flight ended
def _ended(positions, crashed=None, cause=None, ferr=None, success=False, max_cycles=1000, clearance=np.inf):
    """A stand-in for a finished env: the attributes episode_outcome reads, goal at (40, 0, 3); ``cause``
    is each UAV's crash cause (a name of CRASH_CAUSES); the slots lie in a line to the leader's left, 2 m apart,
    ``clearance`` m from the nearest obstacle."""
    from types import SimpleNamespace

    from uavform_env.config import EnvConfig
    from uavform_env.env import CRASH_CAUSES, END_REASONS

    pos = np.asarray(positions, dtype=float)
    steps, n = pos.shape[:2]
    crashed = np.zeros((steps, n), bool) if crashed is None else crashed
    causes = np.array([CRASH_CAUSES.index(c) for c in (cause or ["none"] * n)])
    if success:
        end = "success"
    elif crashed.any():
        end = f"crash-{CRASH_CAUSES[causes[np.flatnonzero(crashed[np.flatnonzero(crashed.any(axis=1))[0]])[0]]]}"
    else:
        end = "timeout" if steps - 1 >= max_cycles else "running"
    history = {"positions": list(pos), "crashed": list(crashed),
               "formation_error": list(np.zeros((steps, n)) if ferr is None else ferr)}
    slots = pos[-1, :1] + np.arange(n)[:, None] * [0.0, 2.0, 0.0]                           # a line to the left
    return SimpleNamespace(config=EnvConfig(), history=history, goal=np.array([40.0, 0.0, 3.0]), success=success,
                           n_uavs=n, crash_cause=causes, end_reason=END_REASONS.index(end), step_count=steps - 1,
                           max_cycles=max_cycles, true_slots=lambda: slots,
                           scenario=SimpleNamespace(bounds_lo=(-10.0, -10.0, 0.0), bounds_hi=(50.0, 10.0, 12.0)),
                           world=SimpleNamespace(clearance=lambda p: np.full(len(p), clearance)))


def test_flight_outcome_names_the_reason():
    from uavform_env.cli import flight_outcome

    line = np.linspace([0.0, 0.0, 3.0], [39.9, 0.0, 3.0], 400)[:, None, :]                  # one UAV, 399 steps
    assert flight_outcome(_ended(line, success=True))["outcome"] == "success"
    out = flight_outcome(_ended(line, max_cycles=399))
    assert out == {"outcome": "time-out",
                   "reason": "the step limit (399 steps) ran out; the leader flew 39.9 m, 1.00 m/s on average",
                   "goal_distance": pytest.approx(0.1)}
    parked = np.concatenate([line[:200], np.repeat(line[199:200], 600, axis=0)])              # halfway, 60 s still
    assert flight_outcome(_ended(parked, max_cycles=799))["reason"] == "stuck: the leader moved 0.00 m in the last 30 s"
    carried = np.concatenate([line, np.repeat(line[-1:], 400, axis=0)])                      # at the goal, then off
    carried[-301:, 0, 1] = 1.5
    assert flight_outcome(_ended(carried, max_cycles=799))["reason"] == \
        "the leader reached the goal at t = 39.6 s but ended 1.5 m from it (r_goal = 0.5 m)"

    pair = np.stack([line[:, 0], line[:, 0] + [0.0, 2.0, 0.0]], axis=1)                      # leader + follower 1
    crashed = np.zeros((400, 2), bool)
    crashed[250:, 1] = True
    assert flight_outcome(_ended(pair, crashed, ["none", "obstacle"]))["reason"] == \
        "uav_1 (follower 1) crashed into an obstacle at step 250 (t = 25.0 s)"
    pair[250:, 1] = pair[250:, 0] + [0.2, 0.0, 0.0]
    assert flight_outcome(_ended(pair, crashed, ["none", "uav"]))["reason"].startswith(
        "uav_1 (follower 1) crashed into uav_0 (leader) at step 250")
    pair[250:, 1] = [20.0, -11.0, 3.0]
    assert "crashed into the edge of the world (left its x/y bounds)" in flight_outcome(
        _ended(pair, crashed, ["none", "geofence"]))["reason"]
    ferr = np.zeros((400, 2))
    ferr[-1, 1] = 3.5
    pair = np.stack([line[:, 0]] * 2, axis=1)
    late = "the leader reached the goal but uav_1 (follower 1) ended 3.5 m from its slot (e_f = 0.5 m): "
    moving = "; it was still moving"
    assert flight_outcome(_ended(pair, ferr=ferr, max_cycles=399))["reason"] == late + "its slot is clear" + moving
    assert flight_outcome(_ended(pair, ferr=ferr, max_cycles=399, clearance=2.25))["reason"] == \
        late + "its slot is clear (2.2 m from the nearest obstacle)" + moving
    assert flight_outcome(_ended(pair, ferr=ferr, max_cycles=399, clearance=0.3))["reason"] == \
        late + "its slot (39.90, 2.00, 3.00) has clearance 0.300 m < r_uav + r_safe = 0.5 m" + moving
    halted = pair.copy()
    halted[-121:, 1] = halted[-121, 1] + [0.0, 0.25, 0.0] * np.linspace(0.0, 1.0, 121)[:, None]   # 12 s, 0.25 m
    assert flight_outcome(_ended(halted, ferr=ferr, max_cycles=399))["reason"] == \
        late + "its slot is clear; it had stood within 0.3 m of there for the last 12 s"
    halted[-40, 1] += [0.0, -0.3, 0.0]                                          # >= 0.3 m off 3.9 s before the end
    assert flight_outcome(_ended(halted, ferr=ferr, max_cycles=399))["reason"].endswith(moving)
    narrow = _ended(pair, ferr=ferr, max_cycles=399)
    narrow.scenario.bounds_hi = (50.0, 1.0, 12.0)                             # the slot, 2 m to the left, is outside
    assert flight_outcome(narrow)["reason"] == \
        late + "its slot (39.90, 2.00, 3.00) lies outside the world bounds (-10.0, -10.0, 0.0) .. (50.0, 1.0, 12.0)" \
        + moving
