"""``uavform train``: the training command, plugged into the ``uavform`` CLI through ``uavform.commands``."""

from __future__ import annotations

import argparse
import re
import sys
from dataclasses import fields

from uavform_env.cli import int_in, number_in
from uavform_env.config import UAVLimits
from uavform_env.scenarios import list_scenarios
from uavform_env.vector import BACKENDS

from .config import FLOAT_BOUNDS, INT_BOUNDS, MINIBATCHES, TrainConfig
from .residual import REWARD_MODES

# What each TrainConfig field means and its unit; the allowed values come from the bounds in config.py.
FIELD_HELP = {
    "scenario": f"training and evaluation scenario: {' | '.join(list_scenarios())}, or NAME@VERSION to pin a "
                "generator version (forest@1: the worlds of runs rw1-rw4)",
    "n_uavs": "UAVs per episode",
    "max_cycles": f"step limit of every training and evaluation episode (steps of {UAVLimits().dt:g} s)",
    "timesteps": "agent-steps to train (one UAV for one step is one agent-step); PPO trains whole rollouts, so "
                 "this is rounded up to a multiple of n_steps x n_envs x n_uavs (the run prints the figure)",
    "n_envs": "env copies (see --backend for where they run)",
    "n_steps": "steps per UAV per rollout",
    "batch_size": f"PPO minibatch size in samples; must divide the rollout (n_steps x n_envs x n_uavs); 0 = a "
                  f"1/{MINIBATCHES} of the rollout",
    "n_epochs": "passes over each rollout",
    "learning_rate": "Adam step size",
    "gamma": "discount factor per step",
    "gae_lambda": "GAE lambda",
    "clip_range": "PPO clip range (ratio)",
    "ent_coef": "entropy bonus weight",
    "log_std_init": "initial log standard deviation of the Gaussian policy (natural log)",
    "net_arch": "hidden layer sizes of the policy and value networks",
    "max_factor": "each expert weight is scaled by a factor in [1/max_factor, max_factor], > 1",
    "reward": f"{' | '.join(REWARD_MODES)}: each UAV gets the team's mean reward, or its own",
    "zero_init": "start exactly from the expert (zero action layer)",
    "seed": "seed of PPO, the network and the training episodes",
    "eval_every": "agent-steps between evaluations on the held-out seeds",
    "eval_seeds": "held-out evaluation seeds, each below --seed",
}


def _train(args) -> int:
    given = {f.name: getattr(args, f.name) for f in fields(TrainConfig) if getattr(args, f.name, None) is not None}
    for name in ("net_arch", "eval_seeds"):
        if name in given:
            given[name] = tuple(given[name])
    try:
        cfg = TrainConfig(**given)             # invalid hyperparameters fail here, before any env is built
    except ValueError as e:                    # name the flag, not the config field
        raise ValueError(re.sub(r"(?:TrainConfig|ResidualConfig)\.(\w+)=",
                                lambda m: "--" + m.group(1).replace("_", "-") + " ", str(e))) from None
    from .train import train                   # needs the train extra (torch, SB3): a missing one is named

    print(f"training {cfg.total_timesteps()} agent-steps: --timesteps {cfg.timesteps} rounded up to "
          f"{cfg.total_timesteps() // cfg.rollout_size()} whole rollouts of n_steps x n_envs x n_uavs = "
          f"{cfg.n_steps} x {cfg.n_envs} x {cfg.n_uavs} = {cfg.rollout_size()}, minibatches of {cfg.batch_size}",
          flush=True)
    try:
        state = train(cfg, args.out, resume=args.resume, progress=not args.quiet, backend=args.backend,
                      ray_address=args.ray_address)
    except KeyboardInterrupt:
        print(f"interrupted: the last and best checkpoints in {args.out} are intact; add --resume to continue",
              file=sys.stderr)
        return 130
    best = state["best"]
    print(f"trained {state['timesteps']} agent-steps in {state['wall_time'] / 60:.1f} min; best at "
          f"{best['timesteps']} agent-steps: held-out success {best['metrics']['success']:.2f}, "
          f"collision {best['metrics']['collision']:.2f}, formation RMS {best['metrics']['formation_error_rms']:.2f} m")
    print(f"wrote {args.out}/best.zip, last.zip, evaluations.csv, learning_curve.png and logs/ (TensorBoard, CSV)")
    return 0


def _allowed(name: str) -> str:
    if name in INT_BOUNDS:
        lo, hi = INT_BOUNDS[name]
        return f"an integer >= {lo}" if hi is None else f"an integer in [{lo}, {hi}]"
    if name in FLOAT_BOUNDS:
        lo, hi, lo_open = FLOAT_BOUNDS[name]
        return f"a number in {'(' if lo_open else '['}{lo:g}, {hi:g}]"
    return ""


def register(subparsers) -> None:
    p = subparsers.add_parser("train", help="train a residual weight policy for the fusion expert (SB3 PPO)",
                              description="Train a residual weight policy (needs the train extra: "
                                          "pip install 'uavform[train]'); every TrainConfig field is a flag.")
    p.add_argument("--out", required=True, help="run folder (checkpoints, logs, learning curve)")
    p.add_argument("--resume", action="store_true", help="continue the run in --out from its last checkpoint")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--backend", choices=BACKENDS, default=None,
                   help="where the --n-envs env copies run: inline (this process), process (worker processes; "
                        "default when --n-envs > 1) or ray (Ray actors, pip install -e \".[ray]\"); same results")
    p.add_argument("--ray-address", default=None, metavar="ADDR",
                   help="with --backend ray: join this Ray cluster (default: $RAY_ADDRESS, else a local Ray)")
    for f in fields(TrainConfig):
        flag = "--" + f.name.replace("_", "-")
        allowed = _allowed(f.name)
        text = FIELD_HELP[f.name] + (f"; {allowed}" if allowed else "")
        if f.name in ("net_arch", "eval_seeds"):
            p.add_argument(flag, type=int_in(1 if f.name == "net_arch" else 0), nargs="+", default=None,
                           metavar="N", help=f"{text} (default: {' '.join(map(str, f.default))})")
        elif isinstance(f.default, bool):
            p.add_argument(flag, action=argparse.BooleanOptionalAction, default=None,
                           help=f"{text} (default: {f.default})")
        elif f.name in INT_BOUNDS:
            p.add_argument(flag, type=int_in(*INT_BOUNDS[f.name]), default=None, metavar="N",
                           help=f"{text} (default: {f.default})")
        elif f.name in FLOAT_BOUNDS:
            p.add_argument(flag, type=number_in(*FLOAT_BOUNDS[f.name]), default=None, metavar="X",
                           help=f"{text} (default: {f.default:g})")
        elif f.name == "reward":
            p.add_argument(flag, choices=REWARD_MODES, default=None, help=f"{text} (default: {f.default})")
        else:
            p.add_argument(flag, type=type(f.default), default=None, help=f"{text} (default: {f.default})")
    p.set_defaults(func=_train)
