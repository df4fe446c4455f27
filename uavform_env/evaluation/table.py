"""The leaderboard table: per-policy means with bootstrap 95% intervals, ranked by a documented score.

Score (lexicographic, best first): success rate (higher), then collision rate (lower: safety), then
mean formation error RMS (lower: formation), then mean flight time (lower: efficiency). A failed
episode (policy exception or wall-clock limit) counts as a non-success; its other metrics are
unknown and left out of the means. Intervals are percentile bootstraps over episodes with a fixed
seed, and values are taken in suite order, so the same results always give the same table.

Beside the ranking: success and collision rates per scenario family and per disturbance preset, why
episodes ended (``OUTCOMES``), and for each pair of policies the probability of improvement
P(X > Y) (Agarwal et al. 2021, rliable): over the episodes both played, the fraction where X's
outcome beats Y's on the score above (ties count one half), with a paired bootstrap interval.
A metric a record does not hold (results written before it existed) is absent, never an error.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from pathlib import Path

import numpy as np

from ..files import atomic_write_figure, atomic_write_json, atomic_write_text
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


# Why an episode ended: the env's END_REASONS minus "running", then the runner's failures.
# Records written before outcomes were kept get "crash" (what was hit is unknown) or "success-with-crash" (their
# success counted although a UAV had crashed: the rule before issue 12).
OUTCOMES = ("success", "timeout", "crash-obstacle", "crash-uav", "crash-geofence", "crash", "success-with-crash",
            "failed", "time_limit")


def episode_values(record: dict) -> dict:
    """The metric values a record contributes: all metrics if it finished, else success 0 and NaNs. A metric
    the record does not hold (written before the metric existed) is NaN."""
    if record["status"] == "ok":
        return {m: float(record["metrics"].get(m, math.nan)) for m in METRIC_NAMES}
    return {m: (0.0 if m == "success" else math.nan) for m in METRIC_NAMES}


def record_outcome(record: dict) -> str:
    """One of ``OUTCOMES``; records written before outcomes were recorded get theirs from the metrics."""
    if "outcome" in record:
        return record["outcome"]
    if record["status"] != "ok":
        return record["status"]
    m = record["metrics"]
    if m.get("collision"):
        return "success-with-crash" if m.get("success") else "crash"
    return "success" if m.get("success") else "timeout"


def _episode_score(values: dict) -> tuple:
    return ranking_key({m: values[m] for m, _ in RANKING})


def probability_of_improvement(x: list[dict], y: list[dict], n_boot: int = N_BOOT,
                               seed: int = BOOT_SEED) -> tuple[float, float, float]:
    """P(X > Y): over paired episodes (x[i] and y[i] are the metric values of one episode), the mean of
    1 if X's outcome scores better, 1/2 if equal, 0 if worse (the ranking's lexicographic score), with
    its 2.5th and 97.5th bootstrap percentiles over episodes. NaNs if there are no episodes."""
    if not x:
        return math.nan, math.nan, math.nan
    sx, sy = [_episode_score(v) for v in x], [_episode_score(v) for v in y]
    wins = np.array([1.0 if a < b else (0.5 if a == b else 0.0) for a, b in zip(sx, sy)])
    idx = np.random.default_rng(seed).integers(0, wins.size, size=(n_boot, wins.size))
    lo, hi = np.percentile(wins[idx].mean(axis=1), [2.5, 97.5])
    return float(wins.mean()), float(lo), float(hi)


def _rate(values: list[dict], metric: str) -> dict:
    column = np.array([v[metric] for v in values])
    mean, lo, hi = bootstrap_ci(column)
    return {"mean": mean, "ci_low": lo, "ci_high": hi, "n": int(np.isfinite(column).sum())}


def summarize(suite: Suite, records: list[dict], improvement: bool = True) -> dict:
    """Rank the policies found in ``records`` (results of ``suite``) and give every metric's mean and CI;
    ``improvement=False`` leaves out the pairwise probabilities of improvement (the slow part)."""
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
    episodes = {e.key: e for e in suite.episodes}
    rows, values_of = [], {}
    for policy, runs in by_policy.items():
        ordered = sorted(runs.values(), key=lambda r: order[r["episode"]])
        values = [episode_values(r) for r in ordered]
        values_of[policy] = dict(zip((r["episode"] for r in ordered), values))
        metrics = {}
        for m in METRIC_NAMES:
            metrics[m] = _rate(values, m)
            metrics[m]["recorded"] = sum(r["status"] != "ok" or m in r["metrics"] for r in ordered)
        groups = {}
        for label, attribute in (("family", "family"), ("disturbance", "wind")):
            split: dict[str, list] = {}
            for r, v in zip(ordered, values):
                split.setdefault(getattr(episodes[r["episode"]], attribute), []).append(v)
            groups[label] = {g: {m: _rate(vs, m) for m in ("success", "collision")} for g, vs in split.items()}
        outcomes = [record_outcome(r) for r in ordered]
        rows.append({"policy": policy, "episodes": len(ordered), "failed": sum(r["status"] != "ok" for r in ordered),
                     "code": sorted({r.get("code", "unknown") for r in ordered}),
                     "complete": len(ordered) == len(suite.episodes), "metrics": metrics, "groups": groups,
                     "outcomes": {o: outcomes.count(o) for o in OUTCOMES if o in outcomes}})
    rows.sort(key=_score_key)
    for rank, row in enumerate(rows, 1):
        row["rank"] = rank
    pairs = {}
    for a in rows:
        for b in rows:
            if improvement and a is not b:
                shared = [k for k in values_of[a["policy"]] if k in values_of[b["policy"]]]
                p, lo, hi = probability_of_improvement([values_of[a["policy"]][k] for k in shared],
                                                       [values_of[b["policy"]][k] for k in shared])
                pairs[f"{a['policy']} > {b['policy']}"] = {"mean": p, "ci_low": lo, "ci_high": hi,
                                                            "n": len(shared)}
    return {"suite": suite.name, "suite_hash": suite.hash, "episodes": len(suite.episodes),
            "ranking": [f"{m} ({better} is better)" for m, better in RANKING], "policies": rows,
            "improvement": pairs}


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


def _group_names(summary: dict, label: str) -> list[str]:
    """The sorted names of the ``label`` groups ("family" or "disturbance") any policy played."""
    return sorted({g for r in summary["policies"] for g in r["groups"][label]})


def separations(summary: dict) -> list[tuple[str, list[str], list[str], list[str]]]:
    """Where the top-ranked policy's success CI parts from the others': one row for all episodes, then one per
    family and per disturbance preset, each (group, the policies whose 95% CI lies wholly below the top
    policy's, wholly above it, overlapping it), the policies in rank order. Groups a policy did not play are left
    out of its row."""
    top, others = summary["policies"][0], summary["policies"][1:]
    groups = [("all episodes", lambda r: r["metrics"]["success"])]
    for label in ("family", "disturbance"):
        for g in _group_names(summary, label):
            groups.append((g, lambda r, label=label, g=g: r["groups"][label].get(g, {}).get("success")))
    out = []
    for name, stat_of in groups:
        mine, split = stat_of(top), ([], [], [])
        for r in others if mine is not None else ():
            theirs = stat_of(r)
            if theirs is not None:
                side = 0 if theirs["ci_high"] < mine["ci_low"] else 1 if theirs["ci_low"] > mine["ci_high"] else 2
                split[side].append(r["policy"])
        out.append((name, *split))
    return out


def _names(policies: list[str]) -> str:
    return ", ".join(f"`{p}`" for p in policies) or "-"


def to_brief(summary: dict) -> str:
    """The short form a README shows: the ranked table, success / collision per disturbance preset and success
    per family (means only), and where the top policy's success CI parts from the others'."""
    rows = summary["policies"]
    presets, families = _group_names(summary, "disturbance"), _group_names(summary, "family")
    out = [*_ranked_table(summary), "", "| policy | " + " | ".join(presets + families) + " |",
           "|" + "---|" * (1 + len(presets) + len(families))]
    for r in rows:
        dist, fam = r["groups"]["disturbance"], r["groups"]["family"]
        cells = [f"{dist[g]['success']['mean']:.3g} / {dist[g]['collision']['mean']:.3g}" if g in dist else "-"
                 for g in presets]
        cells += [f"{fam[g]['success']['mean']:.3g}" if g in fam else "-" for g in families]
        out.append(f"| `{r['policy']}` | " + " | ".join(cells) + " |")
    out += ["", f"Where the success CI of `{rows[0]['policy']}` parts from the others' (95% bootstrap CIs):", "",
            *_separation_table(summary)]
    return "\n".join(out) + "\n"


def ci_cell(stat: dict) -> str:
    """A table cell: mean [95% CI]; "absent" for a metric no record holds, n/a for an unknown value."""
    if stat.get("recorded", 1) == 0:
        return "absent"
    if math.isnan(stat["mean"]):
        return "n/a"
    return f"{stat['mean']:.3g} [{stat['ci_low']:.3g}, {stat['ci_high']:.3g}]"


def _label(metric: str) -> str:
    return f"{metric} ({UNITS[metric]})" if metric in UNITS else metric


def _ranked_table(summary: dict) -> list[str]:
    header = ["rank", "policy", "episodes", "failed", *(_label(m) for m, _ in RANKING)]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for r in summary["policies"]:
        cells = [str(r["rank"]), f"`{r['policy']}`", str(r["episodes"]), str(r["failed"]),
                 *(ci_cell(r["metrics"][m]) for m, _ in RANKING)]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def _separation_table(summary: dict) -> list[str]:
    return ["| episodes | ahead of (CIs apart) | behind (CIs apart) | CIs overlap |", "|---|---|---|---|",
            *(f"| {g} | {_names(a)} | {_names(b)} | {_names(o)} |" for g, a, b, o in separations(summary))]


def to_markdown(summary: dict) -> str:
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
    lines += _ranked_table(summary)
    rows = summary["policies"]
    names = " | ".join(f"`{r['policy']}`" for r in rows)
    head = [f"| {{}} | {names} |", "|" + "---|" * (len(rows) + 1)]
    lines += ["", "## Why episodes ended", "", "Episodes per outcome (crash-*: the first crash and what it hit; "
              "crash, success-with-crash: records written before outcomes were kept, the second counted as a success "
              "under the old rule although a UAV had crashed; failed / time_limit: the policy raised or ran "
              "past its wall-clock limit). Each record in results.jsonl holds the detail, and the policy's "
              "own diagnostics where it exposes them.", "", head[0].format("outcome"), head[1]]
    seen = [o for o in OUTCOMES if any(o in r["outcomes"] for r in rows)]
    lines += [f"| {o} | " + " | ".join(str(r["outcomes"].get(o, 0)) for r in rows) + " |" for o in seen]
    for label in ("family", "disturbance"):
        groups = _group_names(summary, label)
        lines += ["", f"## Success and collision rate per {label}", "",
                  "Cells: success [95% CI] / collision [95% CI] (episodes).", "", head[0].format(label), head[1]]
        for g in groups:
            cells = []
            for r in rows:
                stat = r["groups"][label].get(g)
                cells.append("-" if stat is None else f"{ci_cell(stat['success'])} / {ci_cell(stat['collision'])} "
                                                      f"({stat['success']['n']})")
            lines.append(f"| {g} | " + " | ".join(cells) + " |")
    if len(rows) > 1:
        lines += ["", f"## Where the success CIs part from `{rows[0]['policy']}`'s", "",
                  "For all episodes, each family and each disturbance preset: the policies whose 95% success CI "
                  "lies wholly below the top-ranked policy's (it is ahead of them), wholly above it (behind), "
                  "or overlaps it.", "", *_separation_table(summary)]
    if len(rows) > 1 and summary["improvement"]:
        lines += ["", "## Probability of improvement", "",
                  "P(row > column): over the episodes both played, how often the row's outcome beats the column's "
                  "on the score above (ties count 1/2), with a 95% paired bootstrap CI; 0.5 is a tie.", "",
                  head[0].format("P(row > column)"), head[1]]
        for a in rows:
            cells = ["-" if a is b else ci_cell(summary["improvement"][f"{a['policy']} > {b['policy']}"])
                     for b in rows]
            lines.append(f"| `{a['policy']}` | " + " | ".join(cells) + " |")
    lines += ["", "## All metrics", "", head[0].format("metric"), head[1]]
    for m in METRIC_NAMES:
        lines.append(f"| {_label(m)} | " + " | ".join(ci_cell(r["metrics"][m]) for r in rows) + " |")
    return "\n".join(lines) + "\n"


def to_failures_csv(suite: Suite, records: list[dict]) -> str:
    """One row per episode that did not succeed: policy, episode, outcome, detail and the policy's diagnostics."""
    order = {e.key: i for i, e in enumerate(suite.episodes)}
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(["policy", "episode", "outcome", "detail", "diagnostics"])
    for r in sorted(records, key=lambda r: (r["policy"], order[r["episode"]])):
        outcome = record_outcome(r)
        if outcome != "success":
            diagnostics = r.get("diagnostics")
            writer.writerow([r["policy"], r["episode"], outcome, r.get("outcome_detail", ""),
                             "" if diagnostics is None else json.dumps(diagnostics, sort_keys=True)])
    return buf.getvalue()


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
    atomic_write_figure(path, fig, format="png", dpi=90)
    plt.close(fig)


def write_tables(suite: Suite, records: list[dict], out: str | os.PathLike) -> dict:
    """Write leaderboard.md/.csv/.json (marl-eval layout)/.png and failures.csv into ``out``; return the summary."""
    out = Path(out)
    summary = summarize(suite, records)
    atomic_write_text(out / "leaderboard.md", to_markdown(summary))
    atomic_write_text(out / "leaderboard.csv", to_csv(summary))
    atomic_write_text(out / "failures.csv", to_failures_csv(suite, records))
    atomic_write_json(out / "leaderboard.json", to_marl_eval(suite, records))
    plot(summary, out / "leaderboard.png")
    return summary
