"""``uavform train``: the training command, plugged into the ``uavform`` CLI through ``uavform.commands``."""

from __future__ import annotations

import argparse
import sys
from dataclasses import fields

from uavform_env.vector import BACKENDS

from .config import TrainConfig


def _train(args) -> int:
    from .train import train

    given = {f.name: getattr(args, f.name) for f in fields(TrainConfig) if getattr(args, f.name, None) is not None}
    for name in ("net_arch", "eval_seeds"):
        if name in given:
            given[name] = tuple(given[name])
    cfg = TrainConfig(**given)                 # invalid hyperparameters fail here, before any env is built
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


def register(subparsers) -> None:
    p = subparsers.add_parser("train", help="train a residual weight policy for the fusion expert (SB3 PPO)",
                              description="Train a residual weight policy; every TrainConfig field is a flag.")
    p.add_argument("--out", required=True, help="run folder (checkpoints, logs, learning curve)")
    p.add_argument("--resume", action="store_true", help="continue the run in --out from its last checkpoint")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--backend", choices=BACKENDS, default=None,
                   help="where the --n-envs env copies run: inline (this process), process (worker processes; "
                        "default when --n-envs > 1) or ray (Ray actors, pip install -e \".[ray]\"); same results")
    p.add_argument("--ray-address", default=None, metavar="ADDR",
                   help="with --backend ray: join this Ray cluster (default: $RAY_ADDRESS, else a local Ray)")
    types = {int: int, float: float, str: str}
    for f in fields(TrainConfig):
        flag = "--" + f.name.replace("_", "-")
        if f.name in ("net_arch", "eval_seeds"):
            p.add_argument(flag, type=int, nargs="+", default=None, help=f"(default: {list(f.default)})")
        elif isinstance(f.default, bool):
            p.add_argument(flag, action=argparse.BooleanOptionalAction, default=None, help=f"(default: {f.default})")
        else:
            p.add_argument(flag, type=types[type(f.default)], default=None, help=f"(default: {f.default})")
    p.set_defaults(func=_train)
