"""The ``uavform`` command: fly one episode, list and export scenarios, and plug-in commands.

Every bad flag or file gives one line on stderr naming it and what is allowed (exit status 2), before
any work starts: argparse checks types and ranges (``int_in``, ``number_in``), ``_preflight_fly`` the rest.

Other packages add sub-commands through the entry-point group ``uavform.commands``: each entry is a
function ``register(subparsers)`` that adds its parser and sets ``func`` (``training`` adds
``train``), so this module never imports them.
"""

from __future__ import annotations

import argparse
import math
import sys
from importlib.metadata import entry_points
from pathlib import Path

import numpy as np

from .config import DISTURBANCE_PRESETS, FORMATION_SHAPES, EnvConfig
from .policies import available_policies

COMMAND_GROUP = "uavform.commands"
_DEFAULTS = EnvConfig()
DESCRIPTION = ("uavform: fly multi-UAV formations through 3D obstacle fields, export scenarios, run the leaderboard "
               "(plug-ins add train and reproduce)")
PICTURE_FORMATS = ("png", "svg", "pdf")
# Optional dependencies by import name -> the extra of pyproject.toml that installs them.
EXTRAS = {"torch": "train", "stable_baselines3": "train", "tensorboard": "train", "ray": "ray",
          "octomap": "octomap", "imageio": "viz", "av": "viz", "supersuit": "interop", "torchrl": "interop",
          "tianshou": "interop"}
# Units of the summary's metrics (summary.json "units" and the printed table); counts and flags have none.
METRIC_UNITS = {"flight_time": "s", "path_length_leader": "m", "path_length_mean": "m", "min_clearance": "m",
                "min_separation": "m", "formation_error_rms": "m", "formation_error_max": "m", "time_to_reform": "s",
                "total_turning": "rad", "total_turning_mean": "rad", "altitude_deviation_max": "m",
                "planning_ms_median": "ms", "planning_ms_p95": "ms", "goal_distance": "m"}
_OUTCOMES = {"success": "success", "timeout": "time-out"}  # END_REASONS -> the summary's outcome (crash-*: crash)


def int_in(lo: int, hi: int | None = None):
    """An argparse type: an integer in [lo, hi]; argparse names the flag in its error."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < lo or (hi is not None and value > hi):
            allowed = f"an integer >= {lo}" if hi is None else f"an integer in [{lo}, {hi}]"
            raise argparse.ArgumentTypeError(f"expected {allowed}, got {text!r}")
        return value
    return parse


def number_in(lo: float | None, hi: float | None = None, lo_open: bool = False):
    """An argparse type: a finite number in [lo, hi] (or (lo, hi] with ``lo_open``); None = unbounded."""
    left = "(" if lo_open else "["
    allowed = (f"a number > {lo:g}" if lo_open else f"a number >= {lo:g}") if hi is None else \
        f"a number in {left}{lo:g}, {hi:g}]"

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        below = lo is not None and (value <= lo if lo_open else value < lo)
        if not math.isfinite(value) or below or (hi is not None and value > hi):
            raise argparse.ArgumentTypeError(f"expected {allowed}, got {text!r}")
        return value
    return parse


def _flag(flag: str, value, exc: Exception) -> ValueError:
    """A ValueError naming the flag and its value, keeping the reason."""
    return ValueError(f"{flag} {value}: {exc}")


def _missing_extra(exc: ImportError, what: str) -> ValueError:
    """The pip command that installs what ``what`` needs (a missing optional dependency)."""
    module = (getattr(exc, "name", None) or "").partition(".")[0]
    extra = EXTRAS.get(module)
    if extra is None:
        return ValueError(f"{what}: {exc}")
    return ValueError(f"{what} needs {module}, from the optional extra '{extra}': pip install 'uavform[{extra}]' "
                      "(in a checkout: pip install -c constraints.txt -e '.[" + extra + "]')")


def _check_out_folder(out: str) -> Path:
    path = Path(out)
    if path.exists() and not path.is_dir():
        raise ValueError(f"--out {out}: a file of that name exists; --out is a folder (give a new or existing folder)")
    return path


def flight_outcome(env) -> dict:
    """Why the episode the env just played ended (``metrics.episode_outcome``), for the summary: outcome
    (``success``, ``crash``, ``time-out`` or ``ended``), the reason in words, and the final goal distance
    (leader to goal, m)."""
    from .metrics import episode_outcome

    reason, detail = episode_outcome(env)
    outcome = "crash" if reason.startswith("crash") else _OUTCOMES.get(reason, "ended")
    if outcome == "success":
        detail = (f"the leader is within r_goal = {env.config.episode.r_goal:g} m of the goal, every follower "
                  "within e_f of its slot, and no UAV crashed")
    return {"outcome": outcome, "reason": detail or "no UAV could fly on",
            "goal_distance": float(np.linalg.norm(np.asarray(env.history["positions"][-1][0]) - env.goal))}


def _preflight_fly(args):
    """Check every flag and build the env and policy, before anything flies; errors name the flag or file."""
    from .formation_v0 import parallel_env
    from .policies import load_policy
    from .scenarios import load_scenario

    out = _check_out_folder(args.out)
    try:
        load_scenario(args.scenario, args.seed, n_uavs=args.n_uavs, formation=args.formation,
                      difficulty=args.difficulty)
    except FileNotFoundError:
        raise ValueError(f"--scenario {args.scenario}: no such file") from None
    except ValueError as e:
        flag = "--difficulty" if "difficulty" in str(e).split(":")[0] else "--scenario"
        raise _flag(flag, args.difficulty if flag == "--difficulty" else args.scenario, e) from None
    kwargs = dict(scenario=args.scenario, n_uavs=args.n_uavs, formation=args.formation, difficulty=args.difficulty,
                  render_mode="rgb_array" if args.video else None, top_down=args.top_down, max_cycles=args.max_steps,
                  disturbance=args.wind)
    try:
        penv = parallel_env(**{k: v for k, v in kwargs.items() if v is not None})
    except ValueError as e:  # the scenario file's own problems, or the env's memory check (too many UAVs)
        flag, value = ("--n-uavs", args.n_uavs) if str(e).startswith("n_uavs=") else ("--scenario", args.scenario)
        raise _flag(flag, value, e) from None
    try:
        policy = load_policy(args.policy)
    except ValueError as e:
        raise _flag("--policy", args.policy, e) from None
    except ImportError as e:
        raise _missing_extra(e, f"--policy {args.policy}") from None
    return penv, policy, out


def _fly(args) -> int:
    from tqdm import tqdm

    from .evaluation.runner import code_version
    from .files import atomic_write_json
    from .render import plot_episode, write_video
    from .rollout import run_episode

    penv, policy, out = _preflight_fly(args)          # the env's first reset says when kernels compile
    frames = []

    def grab(env):
        if args.video and env.step_count % args.video_every == 0:
            frames.append(env.render())

    # No ETA: an episode ends at success, usually well before the step limit, and the first steps include
    # the kernels' compilation; the bar shows steps, elapsed time and the leader's distance to the goal.
    with tqdm(total=penv.unwrapped.max_cycles, desc=f"{args.policy} on {args.scenario}", unit="step",
              disable=args.quiet, leave=False,
              bar_format="{desc}: {n_fmt}/{total_fmt} steps |{bar}| {elapsed}{postfix}") as bar:
        metrics = run_episode(penv, policy, args.seed, progress=bar, on_step=grab)
    env = penv.unwrapped
    picture = out / f"trajectory.{args.format}"
    summary = {"scenario": args.scenario, "policy": args.policy, "seed": args.seed, "n_uavs": env.n_uavs,
               "formation": env.config.formation.shape, "wind": args.wind or "calm", "steps": env.step_count,
               "max_steps": env.max_cycles, **flight_outcome(env),
               **{k: v for k, v in metrics.items() if not math.isnan(v)}, "code_version": code_version()}
    summary["units"] = {k: u for k, u in METRIC_UNITS.items() if k in summary}
    atomic_write_json(out / "summary.json", summary)
    plot_episode(env, picture, title=f"{args.policy} on {args.scenario} (seed {args.seed})")
    if args.video and frames:
        write_video(frames, out / "episode.gif", fps=max(1, int(10 / args.video_every)))
    print(outcome_line(summary))
    if not args.quiet:
        _print_summary(summary)
        print(f"wrote {out / 'summary.json'} and {picture}" + (f" and {out / 'episode.gif'}" if args.video else ""))
    return 0


def outcome_line(summary: dict) -> str:
    """One line: the outcome, the mission, and why it ended (what ``--quiet`` prints)."""
    n = summary["n_uavs"]
    head = (f"{summary['outcome'].upper()}: {summary['policy']} on {summary['scenario']}, {n} UAV{'s' if n != 1 else ''}"
            f" ({summary['formation']}), seed {summary['seed']}, {summary['steps']} steps "
            f"({summary['flight_time']:.1f} s)")
    if summary["outcome"] == "success":
        return head
    return f"{head}; the leader ended {summary['goal_distance']:.1f} m from the goal: {summary['reason']}"


def _print_summary(summary: dict) -> None:
    rows = [("flight time", "flight_time"), ("leader path length", "path_length_leader"),
            ("min clearance", "min_clearance"), ("min separation", "min_separation"),
            ("formation error RMS", "formation_error_rms"), ("formation error max", "formation_error_max"),
            ("time to re-form", "time_to_reform"), ("total turning (leader)", "total_turning"),
            ("planning per UAV-step, median", "planning_ms_median"), ("planning per UAV-step, p95", "planning_ms_p95")]
    for label, key in rows:
        if key in summary:                   # formation metrics do not apply to a single UAV
            print(f"  {label:<32} {summary[key]:>9.3f} {METRIC_UNITS[key]}")


def _scenarios(args) -> int:
    from .scenarios import list_scenarios, make_scenario

    if args.export:
        out = Path(args.out)
        if out.is_dir():
            raise ValueError(f"--out {args.out}: is a folder; give a file name such as my.toml")
        if out.suffix != ".toml":
            raise ValueError(f"--out {args.out}: expected a file name ending in .toml (the loaders look for it)")
        if out.exists() and not args.force:
            raise ValueError(f"--out {args.out}: the file exists; add --force to overwrite it, or choose another --out")
        try:
            make_scenario(args.export)
        except ValueError as e:
            raise _flag("--export", args.export, e) from None
        try:
            scn = make_scenario(args.export, seed=args.seed, n_uavs=args.n_uavs, formation=args.formation,
                                difficulty=args.difficulty)
        except ValueError as e:
            raise _flag("--difficulty", args.difficulty, e) from None
        scn.to_toml(out)
        m = scn.mission
        print(f"wrote {out}: {scn.name}@{scn.version} seed {scn.seed}, {m.n_uavs} UAV{'s' if m.n_uavs != 1 else ''} "
              f"({m.formation}), {len(scn.obstacles)} obstacles")
        return 0
    for name in list_scenarios():
        print(name)
    return 0


def _leaderboard(args) -> int:
    from .evaluation.runner import read_manifest, read_results, run_suite
    from .evaluation.suites import load_suite, suite_from_manifest
    from .evaluation.table import summarize, to_brief, to_markdown, write_tables

    if args.brief and not args.show:
        raise ValueError("--brief goes with --show RESULTS_DIR")
    if args.show:
        manifest = read_manifest(args.show)
        if manifest is None:
            raise ValueError(f"--show {args.show!r}: no leaderboard results there (suite.json is missing)")
        suite = suite_from_manifest(manifest, f"{args.show}/suite.json")
        records = read_results(args.show)
        print(to_brief(summarize(suite, records, improvement=False)) if args.brief
              else to_markdown(summarize(suite, records)), end="")
        return 0
    if args.list:
        for episode in load_suite(args.suite).episodes:
            print(episode.key)
        return 0
    if not args.policy:
        raise ValueError("give at least one --policy (or --show RESULTS_DIR, or --list)")
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


def version_text() -> str:
    from . import __version__
    from .evaluation.runner import code_version

    return f"uavform {__version__} (code {code_version()})"


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors: the flag, what is wrong, and where to read the options (no usage dump)."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message} (see '{self.prog} --help')\n")


class _VersionAction(argparse.Action):
    """--version: the package version and the code version (git commit when run from a checkout)."""

    def __init__(self, option_strings, dest=argparse.SUPPRESS, **kwargs):
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        print(version_text())
        parser.exit()


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="uavform", description=DESCRIPTION)
    parser.add_argument("--version", action=_VersionAction,
                        help="print the package version and the code version (git commit in a checkout) and exit")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    fly = sub.add_parser("fly", help="fly one episode with a policy and write a summary and pictures",
                         description="Fly one episode and write OUT/summary.json and OUT/trajectory.FORMAT.")
    fly.add_argument("--scenario", default="forest",
                     help="registered scenario name (see 'uavform scenarios'), optionally NAME@VERSION, or a .toml "
                          "scenario file (default: forest)")
    fly.add_argument("--policy", default="expert",
                     help=f"short name ({', '.join(available_policies())}), module:attr of a policy class, or a "
                          "checkpoint .zip (needs the train extra) (default: expert)")
    fly.add_argument("--n-uavs", type=int_in(1), default=None, metavar="N",
                     help="number of UAVs, >= 1; uav_0 leads (default: the scenario's: drawn from the seed, "
                          "classic-2d 1); refused before flying if the maps would not fit in memory")
    fly.add_argument("--formation", choices=FORMATION_SHAPES, default=None,
                     help="formation shape (default: the scenario's, wedge)")
    fly.add_argument("--difficulty", default=None,
                     help="random-3d: easy | medium | hard (default medium); classic-2d: base | extended "
                          "(default base); other scenarios have none")
    fly.add_argument("--seed", type=int_in(0), default=0,
                     help="episode seed, an integer >= 0: the obstacle layout and sensor noise (default: 0)")
    fly.add_argument("--wind", default=None, choices=list(DISTURBANCE_PRESETS),
                     help="disturbance preset (README, Disturbances; default: the scenario file's, else calm)")
    fly.add_argument("--max-steps", type=int_in(1), default=None, metavar="STEPS",
                     help=f"step limit of the episode, >= 1 (one step = {_DEFAULTS.uav.dt:g} s; "
                          f"default: {_DEFAULTS.episode.max_cycles})")
    fly.add_argument("--out", default="runs/demo", help="output folder, created if needed (default: runs/demo)")
    fly.add_argument("--format", choices=PICTURE_FORMATS, default="png",
                     help="file format of the trajectory picture (default: png)")
    fly.add_argument("--video", action="store_true", help="also write an animation, OUT/episode.gif")
    fly.add_argument("--video-every", type=int_in(1), default=5, metavar="K",
                     help="with --video, draw every K-th step, K >= 1 (default: 5)")
    fly.add_argument("--top-down", action="store_true", help="with --video, draw the animation from above")
    fly.add_argument("--quiet", action="store_true",
                     help="no progress bar and no metric table: print only the one-line outcome")
    fly.set_defaults(func=_fly)

    scn = sub.add_parser("scenarios", help="list the registered scenarios, or export one to a commented TOML file",
                         description="Without --export, list the registered scenarios. With --export NAME, write "
                                     "that generated scenario to --out as a commented TOML file that "
                                     "'uavform fly --scenario FILE' and parallel_env(scenario=FILE) load.")
    scn.add_argument("--export", metavar="NAME", default=None,
                     help="registered scenario to export (one of the names listed without --export)")
    scn.add_argument("--seed", type=int_in(0), default=0,
                     help="generator seed, an integer >= 0: which obstacle layout (default: 0)")
    scn.add_argument("--n-uavs", type=int_in(1), default=None, metavar="N",
                     help="number of UAVs, >= 1 (default: the scenario's)")
    scn.add_argument("--formation", choices=FORMATION_SHAPES, default=None,
                     help="formation shape (default: the scenario's, wedge)")
    scn.add_argument("--difficulty", default=None,
                     help="random-3d: easy | medium | hard; classic-2d: base | extended (default: the scenario's)")
    scn.add_argument("--out", default="scenario.toml", help="file to write (default: scenario.toml)")
    scn.add_argument("--force", action="store_true", help="overwrite --out if it exists")
    scn.set_defaults(func=_scenarios)

    lb = sub.add_parser("leaderboard", help="run a benchmark suite for some policies and write the ranked table")
    lb.add_argument("--suite", default="v0", help="suite name or .toml path (default: v0; 'smoke' for CI)")
    lb.add_argument("--policy", action="append", default=[],
                    help="short name, module:attr or checkpoint path; repeat for several policies")
    lb.add_argument("--out", default="results", help="results folder (default: results)")
    lb.add_argument("--workers", type=int_in(1), default=1, help="parallel episodes (default: 1, in this process)")
    lb.add_argument("--backend", choices=["process", "ray"], default="process",
                    help="process pool (default) or Ray tasks (pip install 'uavform[ray]')")
    lb.add_argument("--ray-address", default=None, metavar="ADDR",
                    help="with --backend ray: join this Ray cluster (e.g. auto, HOST:6379, ray://HOST:10001) "
                         "instead of starting a local one (default: $RAY_ADDRESS if set)")
    lb.add_argument("--resume", action="store_true", help="continue a results folder, skipping finished episodes")
    lb.add_argument("--time-limit", type=number_in(0.0, None, lo_open=True), default=900.0,
                    help="wall-clock seconds per episode before it is recorded as failed (default: 900)")
    lb.add_argument("--show", metavar="RESULTS_DIR", default=None, help="print the table of a results folder and exit")
    lb.add_argument("--brief", action="store_true",
                    help="with --show: the short tables a README shows (ranking, success per preset and family, "
                         "where the top policy's CI parts from the others')")
    lb.add_argument("--list", action="store_true", help="print the suite's episode ids, one per line, and exit")
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
    except ImportError as e:                     # an optional extra that is not installed
        print(f"uavform {args.command}: error: {_missing_extra(e, 'uavform ' + args.command)}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())

