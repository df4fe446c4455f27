"""The leaderboard table: per-policy means with bootstrap 95% intervals, ranked by a documented score.

Score (lexicographic, best first): success rate (higher), then collision rate (lower: safety), then
mean formation error RMS (lower: formation), then mean flight time (lower: efficiency). A failed
episode (policy exception or wall-clock limit) counts as a non-success; its other metrics are
unknown and left out of the means. Intervals are percentile bootstraps over episodes with a fixed
seed, and values are taken in suite order, so the same results always give the same table.
"""

from __future__ import annotations

import csv
import io
import math
import os
from pathlib import Path

import numpy as np

from ..files import atomic_write_bytes, atomic_write_json, atomic_write_text
from ..metrics import METRIC_NAMES
from .suites import Suite

RANKING = (("success", "higher"), ("collision", "lower"), ("formation_error_rms", "lower"), ("flight_time", "lower"))
UNITS = {"flight_time": "s", "path_length_leader": "m", "path_length_mean": "m", "min_clearance": "m",
         "min_separation": "m", "formation_error_rms": "m", "formation_error_max": "m", "time_to_reform": "s",
         "total_turning": "rad", "total_turning_mean": "rad", "altitude_deviation_max": "m",
         "planning_ms_median": "ms", "planning_ms_p95": "ms"}
WALL_CLOCK_METRICS = ("planning_ms_median", "planning_ms_p95")  # differ run to run; everything else is exact
N_BOOT = 2000
BOOT_SEED = 0
MARL_EVAL_ENV = "uavform"


def bootstrap_ci(values: np.ndarray, n_boot: int = N_BOOT, seed: int = BOOT_SEED) -> tuple[float, float, float]:
    """(mean, 2.5th, 97.5th percentile of the bootstrap means) of the finite ``values``; NaNs if none."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return math.nan, math.nan, math.nan
    idx = np.random.default_rng(seed).integers(0, v.size, size=(n_boot, v.size))
    lo, hi = np.percentile(v[idx].mean(axis=1), [2.5, 97.5])
    return float(v.mean()), float(lo), float(hi)


def episode_values(record: dict) -> dict:
    """The metric values a record contributes: all metrics if it finished, else success 0 and NaNs."""
    if record["status"] == "ok":
        return {m: float(record["metrics"][m]) for m in METRIC_NAMES}
    return {m: (0.0 if m == "success" else math.nan) for m in METRIC_NAMES}


def summarize(suite: Suite, records: list[dict]) -> dict:
    """Rank the policies found in ``records`` (results of ``suite``) and give every metric's mean and CI."""
    order = {e.key: i for i, e in enumerate(suite.episodes)}
    by_policy: dict[str, dict[str, dict]] = {}
    for r in records:
        if r["suite_hash"] != suite.hash:
            raise ValueError(f"result {r['episode']!r} of {r['policy']!r} has suite hash {r['suite_hash']}, "
                             f"not {suite.hash}")
        if r["episode"] not in order:
            raise ValueError(f"result for unknown episode {r['episode']!r} of suite {suite.name!r}")
        runs = by_policy.setdefault(r["policy"], {})
        if r["episode"] in runs:
            raise ValueError(f"two results for episode {r['episode']!r} of policy {r['policy']!r}")
        runs[r["episode"]] = r
    rows = []
    for policy, runs in by_policy.items():
        ordered = sorted(runs.values(), key=lambda r: order[r["episode"]])
        values = [episode_values(r) for r in ordered]
        metrics = {}
        for m in METRIC_NAMES:
            column = np.array([v[m] for v in values])
            mean, lo, hi = bootstrap_ci(column)
            metrics[m] = {"mean": mean, "ci_low": lo, "ci_high": hi, "n": int(np.isfinite(column).sum())}
        rows.append({"policy": policy, "episodes": len(ordered), "failed": sum(r["status"] != "ok" for r in ordered),
                     "code": sorted({r.get("code", "unknown") for r in ordered}),
                     "complete": len(ordered) == len(suite.episodes), "metrics": metrics})
    rows.sort(key=_score_key)
    for rank, row in enumerate(rows, 1):
        row["rank"] = rank
    return {"suite": suite.name, "suite_hash": suite.hash, "episodes": len(suite.episodes),
            "ranking": [f"{m} ({better} is better)" for m, better in RANKING], "policies": rows}


def ranking_key(means: dict) -> tuple:
    """The documented score of {metric: mean} as a tuple; smaller ranks first, an unknown (NaN) value last."""
    key = []
    for metric, better in RANKING:
        mean = means[metric]
        if math.isnan(mean):
            mean = -math.inf if better == "higher" else math.inf
        key.append(-mean if better == "higher" else mean)
    return tuple(key)


def _score_key(row: dict) -> tuple:
    return (*ranking_key({m: row["metrics"][m]["mean"] for m, _ in RANKING}), row["policy"])


def ci_cell(stat: dict) -> str:
    """A table cell: mean [95% CI], or n/a for an unknown value."""
    if math.isnan(stat["mean"]):
        return "n/a"
    return f"{stat['mean']:.3g} [{stat['ci_low']:.3g}, {stat['ci_high']:.3g}]"


def _label(metric: str) -> str:
    return f"{metric} ({UNITS[metric]})" if metric in UNITS else metric


def to_markdown(summary: dict) -> str:
    ranked = [m for m, _ in RANKING]
    lines = [f"# Leaderboard: suite `{summary['suite']}` (hash `{summary['suite_hash']}`)", "",
             f"{summary['episodes']} episodes per policy. Cells: mean [95% bootstrap CI] over episodes. "
             f"Ranked by {', then '.join(summary['ranking'])}.", ""]
    incomplete = [f"{r['policy']} ({r['episodes']}/{summary['episodes']})" for r in summary["policies"]
                  if not r["complete"]]
    if incomplete:
        lines += [f"**Incomplete** (rank not final): {', '.join(incomplete)}", ""]
    codes = sorted({c for r in summary["policies"] for c in r["code"]})
    lines += [f"Code: {', '.join(f'`{c}`' for c in codes)}" + (" (**mixed**: rows come from different code)"
                                                               if len(codes) > 1 else ""), ""]
    header = ["rank", "policy", "episodes", "failed", *(_label(m) for m in ranked)]
    lines += ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for r in summary["policies"]:
        cells = [str(r["rank"]), f"`{r['policy']}`", str(r["episodes"]), str(r["failed"]),
                 *(ci_cell(r["metrics"][m]) for m in ranked)]
        lines.append("| " + " | ".join(cells) + " |")
    names = " | ".join(f"`{r['policy']}`" for r in summary["policies"])
    lines += ["", "## All metrics", "", f"| metric | {names} |", "|" + "---|" * (len(summary["policies"]) + 1)]
    for m in METRIC_NAMES:
        lines.append(f"| {_label(m)} | " + " | ".join(ci_cell(r["metrics"][m]) for r in summary["policies"]) + " |")
    return "\n".join(lines) + "\n"


def to_csv(summary: dict) -> str:
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(["suite_hash", "rank", "policy", "episodes", "failed", "metric", "mean", "ci_low", "ci_high", "n"])
    for r in summary["policies"]:
        for m in METRIC_NAMES:
            s = r["metrics"][m]
            writer.writerow([summary["suite_hash"], r["rank"], r["policy"], r["episodes"], r["failed"], m,
                             repr(s["mean"]), repr(s["ci_low"]), repr(s["ci_high"]), s["n"]])
    return buf.getvalue()


def to_marl_eval(suite: Suite, records: list[dict]) -> dict:
    """Per-episode values in marl-eval's raw-data layout, which BenchMARL's plotting also reads.

    ``{env: {task: {algorithm: {"seed_<s>": {"step_0": {"step_count": steps, metric: [values]},
    "absolute_metrics": {metric: [values]}}}}}}`` with env ``uavform``, task the scenario family and
    difficulty, algorithm the policy. A scripted policy has no training curve, so there is one
    evaluation step; NaN values (a metric that does not apply) are left out of the lists.
    """
    order = {e.key: i for i, e in enumerate(suite.episodes)}
    tasks = {e.key: e.task for e in suite.episodes}
    data: dict = {MARL_EVAL_ENV: {}}
    for r in sorted(records, key=lambda r: (r["policy"], order[r["episode"]])):
        run = (data[MARL_EVAL_ENV].setdefault(tasks[r["episode"]], {}).setdefault(r["policy"], {})
               .setdefault(f"seed_{r['seed']}", {"step_0": {"step_count": 0}, "absolute_metrics": {}}))
        run["step_0"]["step_count"] += int(r["steps"] or 0)
        for m, v in episode_values(r).items():
            if math.isfinite(v):
                run["step_0"].setdefault(m, []).append(v)
                run["absolute_metrics"].setdefault(m, []).append(v)
    return data


def plot(summary: dict, path: str | os.PathLike) -> None:
    """Bar chart per metric: one bar per policy (rank order) with its 95% interval as the error bar."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = summary["policies"]
    cols = 4
    nrows = math.ceil(len(METRIC_NAMES) / cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(4 * cols, 2.8 * nrows), squeeze=False)
    x = np.arange(len(rows))
    for ax, m in zip(axes.flat, METRIC_NAMES):
        stats = [r["metrics"][m] for r in rows]
        mean = np.array([s["mean"] for s in stats])
        err = np.array([[s["mean"] - s["ci_low"] for s in stats], [s["ci_high"] - s["mean"] for s in stats]])
        ax.bar(x, np.nan_to_num(mean), yerr=np.nan_to_num(err), capsize=3, color=plt.cm.tab10(x % 10))
        ax.set_title(_label(m), fontsize=9)
        ax.set_xticks(x, [r["policy"] for r in rows], rotation=45, ha="right", fontsize=7)
    for ax in axes.flat[len(METRIC_NAMES):]:
        ax.axis("off")
    fig.suptitle(f"suite {summary['suite']} ({summary['suite_hash']}): mean and 95% bootstrap CI")
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())


def write_tables(suite: Suite, records: list[dict], out: str | os.PathLike) -> dict:
    """Write leaderboard.md/.csv/.json (marl-eval layout)/.png into ``out`` and return the summary."""
    out = Path(out)
    summary = summarize(suite, records)
    atomic_write_text(out / "leaderboard.md", to_markdown(summary))
    atomic_write_text(out / "leaderboard.csv", to_csv(summary))
    atomic_write_json(out / "leaderboard.json", to_marl_eval(suite, records))
    plot(summary, out / "leaderboard.png")
    return summary
