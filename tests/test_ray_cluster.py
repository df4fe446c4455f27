"""Ray beyond one machine: a local two-node cluster (1 CPU each), joined by the leaderboard and by training.

``ray.cluster_utils.Cluster`` starts a head node and a second node as separate raylets on this machine,
so tasks and actors really are spread over two nodes. Starting it takes about 8 s here; the module takes
about 50 s in all on this 2-core machine. Results must equal those of the process backend.
"""

import dataclasses
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from training import ResidualWeightEnv
from training.vecenv import SharedPolicyVecEnv
from uavform_env import parallel_env
from uavform_env.evaluation.runner import read_results, run_suite
from uavform_env.evaluation.suites import load_suite
from uavform_env.evaluation.table import WALL_CLOCK_METRICS

from .conftest import small_env_kwargs

ray = pytest.importorskip("ray")
from ray.cluster_utils import Cluster  # noqa: E402

pytestmark = pytest.mark.slow
REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def cluster():
    c = Cluster(initialize_head=True, head_node_args={"num_cpus": 1, "include_dashboard": False})
    try:
        c.add_node(num_cpus=1)
        c.wait_for_nodes()
        yield c
    finally:
        ray.shutdown()
        c.shutdown()


@pytest.fixture(scope="module")
def two_episodes(tmp_path_factory):
    """The first two episodes of the smoke suite, as a suite file (the CLI takes a path)."""
    smoke = load_suite("smoke")
    path = tmp_path_factory.mktemp("suite") / "smoke2.toml"
    lines = ['name = "smoke2"\ndescription = "the first two smoke episodes"\n']
    for e in smoke.episodes[:2]:
        lines.append("[[episode]]\n" + "".join(f"{k} = {json.dumps(v)}\n" for k, v in e.to_dict().items()
                                                if v is not None))
    path.write_text("\n".join(lines))
    suite = load_suite(path)
    assert suite.episodes == dataclasses.replace(smoke, episodes=smoke.episodes[:2]).episodes
    return path, suite


def _metrics(records):
    return {(r["episode"], r["policy"]): (r["status"], r["steps"],
                                          {k: v for k, v in r["metrics"].items() if k not in WALL_CLOCK_METRICS})
            for r in records}


def test_leaderboard_joins_the_cluster(cluster, two_episodes, tmp_path):
    path, suite = two_episodes
    serial = run_suite(suite, ["expert"], tmp_path / "process", progress=False)
    # The CLI in a fresh process, told the cluster only by RAY_ADDRESS: it used to call ray.init(num_cpus=...),
    # which Ray refuses when RAY_ADDRESS names a cluster.
    env = dict(os.environ, RAY_ADDRESS=cluster.address)
    proc = subprocess.run([sys.executable, "-m", "uavform_env.cli", "leaderboard", "--suite", str(path), "--policy",
                           "expert", "--backend", "ray", "--out", str(tmp_path / "cli"), "--quiet"],
                          cwd=REPO, env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "Connecting to existing Ray cluster" in proc.stderr
    assert _metrics(read_results(tmp_path / "cli")) == _metrics(serial)
    # In this process, with the address given explicitly.
    records = run_suite(suite, ["expert"], tmp_path / "ray", backend="ray", ray_address=cluster.address,
                        progress=False)
    assert len(records) == 2 and all(r["status"] == "ok" for r in records)
    assert _metrics(records) == _metrics(serial)
    assert len({n["NodeID"] for n in ray.nodes() if n["Alive"]}) == 2


def make_small():
    return ResidualWeightEnv(parallel_env(**small_env_kwargs(n_uavs=2, max_cycles=12)))


def _rollout(venv, steps=16):
    try:
        venv.seed(5)
        out = [venv.reset()]
        rng = np.random.default_rng(0)
        for _ in range(steps):   # across an episode end (max_cycles 12): auto-reset on the next seeds
            obs, rew, done, infos = venv.step(rng.uniform(-1, 1, (venv.num_envs, 7)).astype(np.float32))
            out += [obs, rew[:, None], done[:, None]]
        return out
    finally:
        venv.close()


def test_training_copies_run_as_ray_actors(cluster):
    ray_venv = SharedPolicyVecEnv(make_small, n_copies=2, backend="ray", ray_address=cluster.address)
    assert len(ray_venv.shards) == 2          # one actor per node (1 CPU each)
    nodes = {ray.get(a.__ray_call__.remote(lambda self: ray.get_runtime_context().get_node_id()))
             for a in ray_venv.shards}
    assert len(nodes) == 2
    on_ray = _rollout(ray_venv)
    inline = _rollout(SharedPolicyVecEnv(make_small, n_copies=2))   # = worker processes (test_training.py)
    for a, b in zip(on_ray, inline):
        np.testing.assert_array_equal(a, b)


def test_uavform_train_on_the_cluster_matches_worker_processes(cluster, tmp_path):
    from stable_baselines3 import PPO

    from training.config import TrainConfig
    from training.train import train

    cfg = TrainConfig(scenario="forest", n_uavs=2, max_cycles=12, timesteps=80, n_envs=2, n_steps=20, batch_size=40,
                      n_epochs=1, eval_every=10_000, eval_seeds=(500,), net_arch=(16,))
    states, params = [], []
    for backend, address in (("process", None), ("ray", cluster.address)):
        out = tmp_path / backend
        states.append(train(cfg, out, progress=False, backend=backend, ray_address=address))
        params.append(PPO.load(out / "last.zip", device="cpu").policy.state_dict())
    assert states[0]["timesteps"] == states[1]["timesteps"] == 80
    assert states[0]["best"] == states[1]["best"]
    for name in params[0]:
        assert params[0][name].equal(params[1][name]), f"{name} differs between the process and Ray backends"


def test_a_local_ray_does_not_join_another_cluster_on_the_machine(cluster):
    """Without an address (and no RAY_ADDRESS) the backend starts its own local Ray with its ``num_cpus``, even
    while another process's cluster runs on this machine (Ray's default would join that one and refuse
    ``num_cpus``: the leaderboard's Ray test failed that way beside this module's cluster under ``-n 2``)."""
    code = ("from uavform_env.parallel import connect_ray\n"
            "ray = connect_ray(None, 3)\n"
            "print(int(ray.cluster_resources()['CPU']))\n")
    env = {k: v for k, v in os.environ.items() if k != "RAY_ADDRESS"}
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, env=env, capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split()[-1] == "3"                # its own 3 CPUs, not the cluster's 2
