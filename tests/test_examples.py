"""The scripts in examples/ run, with tiny settings (a few hundred agent-steps)."""

import importlib.util
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"

pytestmark = pytest.mark.interop


def _example(name):
    spec = importlib.util.spec_from_file_location(f"example_{name}", EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_sb3_ppo_from_scratch_trains_saves_and_flies(tmp_path, capsys):
    out = tmp_path / "ppo.zip"
    result = _example("sb3_ppo_from_scratch").main(
        ["--timesteps", "200", "--n-uavs", "2", "--n-copies", "1", "--n-steps", "50", "--max-cycles", "20",
         "--out", str(out)])
    assert result["trained_agent_steps"] == 200          # 2 rollouts of 50 steps x 2 UAV rows
    assert out.is_file() and 1 <= result["steps"] <= 20
    assert capsys.readouterr().out.startswith(f"trained 200 agent-steps, saved {out}; evaluation episode: ")


def test_torchrl_rollout_with_one_shared_network(capsys):
    result = _example("torchrl_rollout").main(["--steps", "12", "--n-uavs", "3"])
    assert result["steps"] == 12 and result["actions"] == (12, 3, 3)
    assert "rolled out 12 steps" in capsys.readouterr().out
