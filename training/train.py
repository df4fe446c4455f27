"""Training a residual weight policy with SB3 PPO: one policy shared by all UAVs of all env copies.

Layout of a run folder::

    config.json        the TrainConfig (a resumed run must match it)
    last.zip, best.zip checkpoints (SB3 zip + uavform metadata, written atomically)
    state.json         timesteps done, best evaluation so far (written after the checkpoints)
    evaluations.csv    one line per evaluation on the held-out seeds (append-only)
    logs/segment-K/    SB3's progress.csv and TensorBoard events, one folder per (re)start
    learning_curve.png

Seeds: training episodes use seeds from ``seed`` upwards; evaluation uses ``eval_seeds``, which must
lie below ``seed`` (the v0 leaderboard suite uses seeds 0-5, the defaults keep clear of both).
"""

from __future__ import annotations

import csv
import json
import os
import time
from pathlib import Path

import numpy as np
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import configure
from stable_baselines3.common.vec_env import VecMonitor, VecNormalize

from uavform_env.evaluation.table import RANKING, ranking_key as leaderboard_key
from uavform_env.files import append_line, atomic_write_figure, atomic_write_json
from uavform_env.formation_v0 import parallel_env
from uavform_env.parallel import connect_ray
from uavform_env.rollout import run_episode

from .checkpoint import ResidualPolicy, checkpoint_meta, read_meta, save_checkpoint
from .config import TrainConfig
from .residual import ResidualWeightEnv
from .vecenv import BACKENDS, SharedPolicyVecEnv

EVAL_COLUMNS = ("timesteps", "wall_time", "success", "collision", "formation_error_rms", "flight_time", "best")


class _MakeEnv:
    """A picklable env factory for the worker processes."""

    def __init__(self, cfg: TrainConfig):
        self.cfg = cfg

    def __call__(self):
        return ResidualWeightEnv(parallel_env(**self.cfg.env_kwargs()),
                                 residual=self.cfg.residual())


def evaluate(policy: ResidualPolicy, cfg: TrainConfig) -> dict:
    """Mean leaderboard metrics of the deterministic policy over the held-out seeds."""
    runs = [run_episode(parallel_env(**cfg.env_kwargs()), policy, seed) for seed in cfg.eval_seeds]
    return {m: float(np.mean([r[m] for r in runs])) for m, _ in RANKING}


def ranking_key(metrics: dict) -> tuple:
    """The leaderboard's score of ``metrics``, negated so that larger is better (as stored in state.json)."""
    return tuple(-k for k in leaderboard_key(metrics))


def _prepare_folder(cfg: TrainConfig, out: Path, resume: bool) -> dict:
    state_path, config_path = out / "state.json", out / "config.json"
    if resume:
        if not (out / "last.zip").is_file() or not state_path.is_file():
            raise ValueError(f"--resume: {str(out)!r} holds no last.zip and state.json to continue from")
        saved, given = json.loads(config_path.read_text()), json.loads(json.dumps(cfg.to_dict()))
        changed = sorted(k for k in saved if k != "timesteps" and saved[k] != given.get(k))
        if changed:
            raise ValueError(f"--resume: the run in {str(out)!r} was started with other settings "
                             f"({', '.join(f'{k}={saved[k]}' for k in changed)}); resume with the same arguments "
                             "(only --timesteps may change)")
        atomic_write_json(config_path, given)
        return json.loads(state_path.read_text())
    if (out / "last.zip").exists() or state_path.exists():
        raise ValueError(f"{str(out)!r} already holds a training run: pass --resume to continue it, or choose "
                         "another --out (nothing was overwritten)")
    atomic_write_json(config_path, cfg.to_dict())
    return {"timesteps": 0, "best": None, "wall_time": 0.0}


def train(cfg: TrainConfig, out: str | os.PathLike, *, resume: bool = False, progress: bool = True,
          backend: str | None = None, ray_address: str | None = None) -> dict:
    """Train (or continue) a residual policy into ``out``; returns the final state (see the module docstring).

    ``backend`` places the ``cfg.n_envs`` env copies (``SharedPolicyVecEnv``): "inline" (all in this
    process), "process" (worker processes; the default when ``n_envs > 1``) or "ray" (Ray actors, on the
    cluster at ``ray_address`` or ``RAY_ADDRESS``). The backend does not change the results.
    """
    if not isinstance(cfg, TrainConfig):
        raise ValueError(f"cfg: expected a TrainConfig, got {type(cfg).__name__}")
    backend = backend if backend is not None else ("process" if cfg.n_envs > 1 else "inline")
    if backend not in BACKENDS:
        raise ValueError(f"backend={backend!r}: expected one of {list(BACKENDS)}")
    if ray_address is not None and backend != "ray":
        raise ValueError(f"ray_address={ray_address!r}: only with backend 'ray'")
    if backend == "ray":
        connect_ray(ray_address, cfg.n_envs)    # no Ray, or no cluster at the address: fail before writing anything
    out = Path(out)
    state = _prepare_folder(cfg, out, resume)
    torch.set_num_threads(1)          # a small MLP: one thread is fastest and leaves the cores to the env copies
    segment = len(list((out / "logs").glob("segment-*")))   # one log folder per (re)start: SB3's CSV overwrites
    venv = SharedPolicyVecEnv(_MakeEnv(cfg), cfg.n_envs, backend=backend, ray_address=ray_address)
    venv = VecNormalize(VecMonitor(venv), norm_obs=True, norm_reward=True, gamma=cfg.gamma)
    probe_env = _MakeEnv(cfg)()
    try:
        if resume:
            meta = read_meta(out / "last.zip")
            _restore_normalisation(venv, meta)
            model = PPO.load(out / "last.zip", env=venv, device="cpu")
            venv.seed(cfg.seed + 7919 * segment)   # fresh training episodes for the new segment
            model.set_random_seed(cfg.seed + segment)
        else:
            model = PPO("MlpPolicy", venv, n_steps=cfg.n_steps, batch_size=cfg.batch_size, n_epochs=cfg.n_epochs,
                        learning_rate=cfg.learning_rate, gamma=cfg.gamma, gae_lambda=cfg.gae_lambda,
                        clip_range=cfg.clip_range, ent_coef=cfg.ent_coef, seed=cfg.seed, device="cpu",
                        policy_kwargs={"net_arch": list(cfg.net_arch), "log_std_init": cfg.log_std_init})
            if cfg.zero_init:
                model.policy.action_net.weight.data.zero_()
                model.policy.action_net.bias.data.zero_()
        model.set_logger(configure(str(out / "logs" / f"segment-{segment}"), ["csv", "tensorboard"]))
        callback = _EvalCheckpoints(cfg, out, state, probe_env, venv, progress)
        remaining = cfg.timesteps - state["timesteps"]
        if remaining > 0:
            model.learn(total_timesteps=remaining, reset_num_timesteps=not resume, callback=callback)
        callback.checkpoint(model)
    finally:
        venv.close()
    plot_learning_curve(out)
    return callback.state


def _restore_normalisation(venv, meta: dict) -> None:
    norm = meta["obs_norm"]
    venv.obs_rms.mean = np.asarray(norm["mean"])
    venv.obs_rms.var = np.asarray(norm["var"])
    venv.obs_rms.count = norm["count"]
    ret = meta["ret_norm"]
    venv.ret_rms.mean, venv.ret_rms.var, venv.ret_rms.count = ret["mean"], ret["var"], ret["count"]


class _EvalCheckpoints(BaseCallback):
    """Every ``eval_every`` agent-steps: evaluate on held-out seeds, write last (and best) checkpoints."""

    def __init__(self, cfg: TrainConfig, out: Path, state: dict, probe_env, venv, progress: bool):
        super().__init__()
        self.cfg, self.out, self.state, self.probe_env, self.norm = cfg, out, state, probe_env, venv
        self.show_progress = progress
        self.started = time.perf_counter()
        self.bar = None
        self.next_eval = (state["timesteps"] // cfg.eval_every + 1) * cfg.eval_every

    def _on_training_start(self) -> None:
        from tqdm import tqdm

        self.bar = tqdm(total=self.cfg.total_timesteps(), initial=self.state["timesteps"], unit="step",
                        desc="training", disable=not self.show_progress, dynamic_ncols=True)
        if self.state["best"] is None:
            self.checkpoint(self.model)               # the starting point is the reference to beat

    def _on_step(self) -> bool:
        self.bar.update(self.training_env.num_envs)
        if self.model.num_timesteps >= self.next_eval:
            self.next_eval += self.cfg.eval_every
            self.checkpoint(self.model)
        return True

    def _on_training_end(self) -> None:
        self.bar.close()

    def _meta(self, model) -> dict:
        ret = self.norm.ret_rms
        return checkpoint_meta(self.probe_env, self.probe_env.expert_config, self.probe_env.residual,
                               self.norm.obs_rms, self.norm.clip_obs, self.norm.epsilon,
                               {"train_config": self.cfg.to_dict(), "timesteps": int(model.num_timesteps),
                                "ret_norm": {"mean": float(ret.mean), "var": float(ret.var),
                                             "count": float(ret.count)}})

    def checkpoint(self, model) -> None:
        """Evaluate, then write best.zip (if better), last.zip and state.json, each atomically, in that order."""
        if self.state["best"] is not None and self.state["timesteps"] == model.num_timesteps:
            return                                         # nothing new since the last one
        meta = self._meta(model)
        if self.bar is not None:                           # the evaluation takes a while: say so, not a stall
            self.bar.set_description(f"evaluating on {len(self.cfg.eval_seeds)} held-out seeds")
        metrics = evaluate(ResidualPolicy(model, meta, name="training"), self.cfg)
        if self.bar is not None:
            self.bar.set_description("training", refresh=False)
        key = list(ranking_key(metrics))
        best = self.state["best"] is None or key > self.state["best"]["key"]
        if best:
            save_checkpoint(model, self.out / "best.zip", meta)
        save_checkpoint(model, self.out / "last.zip", meta)
        wall = self.state["wall_time"] + time.perf_counter() - self.started
        self.started = time.perf_counter()
        self.state = {"timesteps": int(model.num_timesteps), "wall_time": wall,
                      "best": {"key": key, "timesteps": int(model.num_timesteps), "metrics": metrics}
                      if best else self.state["best"]}
        row = [int(model.num_timesteps), round(wall, 1), *(metrics[m] for m, _ in RANKING), int(best)]
        path = self.out / "evaluations.csv"
        if not path.exists():
            append_line(path, ",".join(EVAL_COLUMNS))
        append_line(path, ",".join(str(v) for v in row))
        atomic_write_json(self.out / "state.json", self.state)
        if self.bar is not None:
            self.bar.set_postfix(success=f"{metrics['success']:.2f}", best="*" if best else "", refresh=False)


def read_evaluations(out: str | os.PathLike) -> list[dict]:
    with open(Path(out) / "evaluations.csv", newline="") as f:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]


def plot_learning_curve(out: str | os.PathLike) -> Path:
    """learning_curve.png: the training return (SB3's rollout/ep_rew_mean) and the held-out evaluations."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out)
    train_x, train_y = [], []
    for progress in sorted((out / "logs").glob("segment-*/progress.csv"), key=lambda p: int(p.parent.name[8:])):
        with open(progress, newline="") as f:
            for row in csv.DictReader(f):
                if row.get("rollout/ep_rew_mean") not in (None, ""):
                    train_x.append(float(row["time/total_timesteps"]))
                    train_y.append(float(row["rollout/ep_rew_mean"]))
    evals = read_evaluations(out) if (out / "evaluations.csv").exists() else []
    # The training-return panel only when some training episode has finished (a short run may have none).
    fig, axes = plt.subplots(1, 3 if train_x else 2, figsize=(13 if train_x else 9, 3.6))
    if train_x:
        axes[0].plot(train_x, train_y, color="tab:blue")
        axes[0].set(title="training return per UAV-episode", xlabel="agent-steps")
    for ax, metric, label in ((axes[-2], "success", "held-out success rate"),
                              (axes[-1], "formation_error_rms", "held-out formation error RMS (m)")):
        xs = [e["timesteps"] for e in evals]
        ax.plot(xs, [e[metric] for e in evals], "o-", color="tab:green")
        bx = [e["timesteps"] for e in evals if e["best"]]
        ax.plot(bx, [e[metric] for e in evals if e["best"]], "*", color="tab:red", ms=12, label="new best")
        ax.set(title=label, xlabel="agent-steps")
        ax.legend(loc="best")
    for ax in axes:
        ax.grid(alpha=0.3)
    fig.tight_layout()
    path = out / "learning_curve.png"
    atomic_write_figure(path, fig, format="png", dpi=110)
    plt.close(fig)
    return path


__all__ = ["TrainConfig", "evaluate", "plot_learning_curve", "ranking_key", "read_evaluations", "train"]
