"""``uavform reproduce``: the paper's planners bare (``baselines.paper``) on experiments E1-E6, and the report
that tests each claim of ``claims.toml`` per reading of the spec.

``experiments`` holds the experiments as data and plays the runs (append-only ``runs.jsonl``,
resumable, optionally on a process pool); ``claims`` holds the verdict logic; ``report`` writes the
Markdown report, ``claims.json`` and the figures.
The command is plugged into ``uavform`` through the entry-point group ``uavform.commands``.
"""

from __future__ import annotations

import sys
import time

DEFAULT_OUT = "docs/reproduction"


def _reproduce(args) -> int:
    from .experiments import run_all
    from .report import write_report

    start = time.perf_counter()
    try:
        from .claims import load_claims

        load_claims()                       # a broken claims.toml stops the command before any run
        records = run_all(args.out, seeds=args.seeds, quick=args.quick, resume=args.resume, workers=args.workers,
                          progress=not args.quiet)
    except KeyboardInterrupt:
        print(f"interrupted: finished runs are in {args.out}/runs.jsonl; add --resume to continue", file=sys.stderr)
        return 130
    options = [f"--out {args.out}"] + ([f"--seeds {args.seeds}"] if args.seeds else []) + \
        (["--quick"] if args.quick else [])
    result = write_report(records, args.out, "uavform reproduce " + " ".join(options), quick=args.quick)
    if not args.quiet:
        for c in result["claims"]:
            print(f"{c['id']}: {c['verdict']}" + (f" (under {', '.join(c['reproduced_by'])})" if c["reproduced_by"]
                                                  else ""))
        print(f"wrote {args.out}/README.md, claims.json, summary.json and {len(result['figures'])} figures "
              f"in {(time.perf_counter() - start) / 60:.1f} min")
    return 0


def register(subparsers) -> None:
    """Add ``reproduce`` to the ``uavform`` command (entry point ``uavform.commands``)."""
    from uavform_env.cli import int_in

    p = subparsers.add_parser("reproduce", help="fly the paper's planners on E1-E6 and test the paper's claims "
                                                "(claims.toml)")
    p.add_argument("--out", default=DEFAULT_OUT, help=f"output folder (default: {DEFAULT_OUT})")
    p.add_argument("--seeds", type=int_in(1), default=None,
                   help="seeds per setting for every experiment (default: each experiment's own count)")
    p.add_argument("--quick", action="store_true",
                   help="one seed, one or two settings per experiment, short episodes (a smoke test, minutes)")
    p.add_argument("--resume", action="store_true", help="continue an output folder, skipping finished runs")
    p.add_argument("--workers", type=int_in(1), default=1, help="parallel runs (default: 1, in this process)")
    p.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    p.set_defaults(func=_reproduce)
