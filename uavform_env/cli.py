"""The ``uavform`` command: fly one episode, list and export scenarios, and plug-in commands.

Other packages add sub-commands through the entry-point group ``uavform.commands``: each entry is a
function ``register(subparsers)`` that adds its parser and sets ``func`` (``training`` adds
``train``), so this module never imports them.
"""

from __future__ import annotations

import argparse
import sys
from importlib.metadata import entry_points
from pathlib import Path

COMMAND_GROUP = "uavform.commands"


def _fly(args) -> int:
    from tqdm import tqdm

    from .files import atomic_write_json
    from .formation_v0 import parallel_env
    from .policies import load_policy
    from .render import plot_episode, write_video
    from .rollout import run_episode

    kwargs = dict(scenario=args.scenario, n_uavs=args.n_uavs, formation=args.formation, difficulty=args.difficulty,
                  render_mode="rgb_array" if args.video else None, top_down=args.top_down)
    if args.max_steps is not None:
        kwargs["max_cycles"] = args.max_steps
    penv = parallel_env(**{k: v for k, v in kwargs.items() if v is not None})
    policy = load_policy(args.policy)
    frames = []

    def grab(env):
        if args.video and env.step_count % args.video_every == 0:
            frames.append(env.render())

    with tqdm(total=penv.unwrapped.max_cycles, desc=f"{args.policy} on {args.scenario}", unit="step",
              disable=args.quiet, leave=False) as bar:
        metrics = run_episode(penv, policy, args.seed, progress=bar, on_step=grab)
    env = penv.unwrapped
    out = Path(args.out)
    summary = {"scenario": args.scenario, "policy": args.policy, "seed": args.seed, "n_uavs": env.n_uavs,
               "formation": env.config.formation.shape, "steps": env.step_count, **metrics}
    atomic_write_json(out / "summary.json", summary)
    plot_episode(env, out / "trajectory.png", title=f"{args.policy} on {args.scenario} (seed {args.seed})")
    if args.video and frames:
        write_video(frames, out / "episode.gif", fps=max(1, int(10 / args.video_every)))
    if not args.quiet:
        _print_summary(summary)
        print(f"wrote {out / 'summary.json'} and {out / 'trajectory.png'}" + (" and episode.gif" if args.video else ""))
    return 0


def _print_summary(summary: dict) -> None:
    outcome = "SUCCESS" if summary["success"] else ("COLLISION" if summary["collision"] else "TIME-OUT")
    print(f"{outcome}: {summary['policy']} on {summary['scenario']}, {summary['n_uavs']} UAVs "
          f"({summary['formation']}), seed {summary['seed']}, {summary['steps']} steps")
    rows = [("flight time", "flight_time", "s"), ("leader path length", "path_length_leader", "m"),
            ("min clearance", "min_clearance", "m"), ("min separation", "min_separation", "m"),
            ("formation error RMS", "formation_error_rms", "m"), ("formation error max", "formation_error_max", "m"),
            ("time to re-form", "time_to_reform", "s"), ("total turning (leader)", "total_turning", "rad"),
            ("planning per UAV-step, median", "planning_ms_median", "ms"),
            ("planning per UAV-step, p95", "planning_ms_p95", "ms")]
    for label, key, unit in rows:
        print(f"  {label:<32} {summary[key]:>9.3f} {unit}")


def _scenarios(args) -> int:
    from .scenarios import list_scenarios, make_scenario

    if args.export:
        scn = make_scenario(args.export, seed=args.seed, difficulty=args.difficulty)
        scn.to_toml(args.out)
        print(f"wrote {args.out}")
        return 0
    for name in list_scenarios():
        print(name)
    return 0


def _leaderboard(args) -> int:
    from .evaluation.runner import read_manifest, read_results, run_suite
    from .evaluation.suites import load_suite, suite_from_manifest
    from .evaluation.table import summarize, to_markdown, write_tables

    if args.show:
        manifest = read_manifest(args.show)
        if manifest is None:
            raise ValueError(f"--show {args.show!r}: no leaderboard results there (suite.json is missing)")
        suite = suite_from_manifest(manifest, f"{args.show}/suite.json")
        print(to_markdown(summarize(suite, read_results(args.show))), end="")
        return 0
    if not args.policy:
        raise ValueError("give at least one --policy (or --show RESULTS_DIR)")
    suite = load_suite(args.suite)
    print(f"suite {suite.name}: {len(suite.episodes)} episodes, hash {suite.hash}", flush=True)
    try:
        records = run_suite(suite, args.policy, args.out, workers=args.workers, backend=args.backend,
                            resume=args.resume, time_limit=args.time_limit, progress=not args.quiet,
                            ray_address=args.ray_address)
    except KeyboardInterrupt:
        print(f"interrupted: finished episodes are in {args.out}; add --resume to continue", file=sys.stderr)
        return 130
    print(to_markdown(write_tables(suite, records, args.out)), end="")
    print(f"wrote {args.out}/leaderboard.md, .csv, .json (marl-eval layout) and .png")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="uavform", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)

    fly = sub.add_parser("fly", help="fly one episode with a policy and write a summary and pictures")
    fly.add_argument("--scenario", default="forest", help="scenario name or .toml path (default: forest)")
    fly.add_argument("--policy", default="expert", help="short name, module:attr or checkpoint (default: expert)")
    fly.add_argument("--n-uavs", type=int, default=None)
    fly.add_argument("--formation", default=None)
    fly.add_argument("--difficulty", default=None)
    fly.add_argument("--seed", type=int, default=0)
    fly.add_argument("--max-steps", type=int, default=None, help="episode length (default: the env's max_cycles)")
    fly.add_argument("--out", default="runs/demo", help="output folder (default: runs/demo)")
    fly.add_argument("--video", action="store_true", help="also write an animation (episode.gif)")
    fly.add_argument("--video-every", type=int, default=5, help="render every k-th step into the video")
    fly.add_argument("--top-down", action="store_true", help="render the video from above")
    fly.add_argument("--quiet", action="store_true")
    fly.set_defaults(func=_fly)

    scn = sub.add_parser("scenarios", help="list the registered scenarios, or export one to TOML")
    scn.add_argument("--export", metavar="NAME", default=None)
    scn.add_argument("--seed", type=int, default=0)
    scn.add_argument("--difficulty", default=None)
    scn.add_argument("--out", default="scenario.toml")
    scn.set_defaults(func=_scenarios)

    lb = sub.add_parser("leaderboard", help="run a benchmark suite for some policies and write the ranked table")
    lb.add_argument("--suite", default="v0", help="suite name or .toml path (default: v0; 'smoke' for CI)")
    lb.add_argument("--policy", action="append", default=[],
                    help="short name, module:attr or checkpoint path; repeat for several policies")
    lb.add_argument("--out", default="results", help="results folder (default: results)")
    lb.add_argument("--workers", type=int, default=1, help="parallel episodes (default: 1, in this process)")
    lb.add_argument("--backend", choices=["process", "ray"], default="process",
                    help="process pool (default) or Ray tasks (pip install 'uavform[ray]')")
    lb.add_argument("--ray-address", default=None, metavar="ADDR",
                    help="with --backend ray: join this Ray cluster (e.g. auto, HOST:6379, ray://HOST:10001) "
                         "instead of starting a local one (default: $RAY_ADDRESS if set)")
    lb.add_argument("--resume", action="store_true", help="continue a results folder, skipping finished episodes")
    lb.add_argument("--time-limit", type=float, default=900.0,
                    help="wall-clock seconds per episode before it is recorded as failed (default: 900)")
    lb.add_argument("--show", metavar="RESULTS_DIR", default=None, help="print the table of a results folder and exit")
    lb.add_argument("--quiet", action="store_true", help="no progress bar")
    lb.set_defaults(func=_leaderboard)

    for ep in entry_points(group=COMMAND_GROUP):
        ep.load()(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except (ValueError, FileNotFoundError) as e:
        print(f"uavform {args.command}: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())

