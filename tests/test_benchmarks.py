"""The wind benchmarks in benchmarks/ run, with tiny settings: they fly the expert's station keeping and wind
estimate (``baselines.fusion.rules``) outside the controller, so a change of those rules' signatures must show here
(session 22 found ``wind_authority.py`` broken since ``station_keep`` took a clearance)."""

import importlib.util
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


def _run(name, argv, monkeypatch):
    monkeypatch.syspath_prepend(str(BENCHMARKS))        # as a script: its siblings import by name
    spec = importlib.util.spec_from_file_location(f"benchmark_{name}", BENCHMARKS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    monkeypatch.setattr(sys, "argv", [f"{name}.py", *argv])
    module.main()


def _rows(text):
    return [line for line in text.splitlines() if line.startswith("| `")]


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
