"""The reproduction report (format 2): tables with bootstrap intervals, figures, and every claim of
``claims.toml`` tested per reading of the spec.

``summarize`` turns the run records into mean and 95% interval per (experiment, setting, variant,
metric); ``claims.evaluate`` decides each claim; ``write_report`` writes ``README.md``, ``claims.json``,
``summary.json`` and the PNG figures. Every verdict, explanation, set-up line and parameter table is
generated from the records and the config objects that ran, never written by hand.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from uavform_env.config import EnvConfig
from uavform_env.evaluation.table import UNITS, bootstrap_ci, ci_cell
from uavform_env.files import atomic_write_figure, atomic_write_json, atomic_write_text

from ..expert import ExpertConfig
from ..paper import PaperConfig
from .claims import HOLDS, evaluate, load_claims
from .experiments import (EXPERIMENTS, FIGURE_SEED, HORIZON_SAMPLE, R_SW, SEEDS, Run, horizon_checks,
                          scenario_of)

# The metrics each experiment's table shows (all metrics are in summary.json).
TABLE_METRICS = {
    "E1": ("success", "timeout", "path_length_leader", "flight_time", "near_goal_loops", "near_goal_dwell",
           "yaw_jitter_per_metre"),
    "E2": ("success", "collision", "timeout", "path_length_leader", "iterations", "yaw_jitter_per_metre"),
    "E3": ("success", "timeout", "near_goal_loops", "near_goal_dwell", "path_length_leader"),
    "E4": ("success", "collision", "timeout", "path_length_leader", "min_clearance", "altitude_deviation_max"),
    "E5": ("success", "collision", "timeout", "path_length_leader", "min_clearance", "altitude_deviation_max"),
    "E6": ("success", "collision", "timeout", "reformed", "formation_error_rms", "min_separation"),
}
EXTRA_UNITS = {"near_goal_loops": "turns", "near_goal_dwell": "s", "yaw_jitter_per_metre": "rad/s per m"}


def summarize(records: list[dict]) -> dict:
    """``{exp: {setting: {variant: {"runs", "failed", metric: {mean, ci_low, ci_high, n}}}}}`` of the main runs."""
    groups: dict[tuple, list[dict]] = {}
    for r in sorted(records, key=lambda r: (r["experiment"], r["setting"], r["variant"], r["seed"])):
        if not r.get("horizon_check"):
            groups.setdefault((r["experiment"], r["setting"], r["variant"]), []).append(r)
    out: dict = {}
    for (exp, setting, variant), recs in groups.items():
        ok = [r["metrics"] for r in recs if r["status"] == "ok"]
        row = {"runs": len(recs), "failed": len(recs) - len(ok)}
        for m in (ok[0] if ok else {}):
            mean, lo, hi = bootstrap_ci(np.array([float(x[m]) for x in ok]))
            row[m] = {"mean": mean, "ci_low": lo, "ci_high": hi,
                      "n": int(np.isfinite([float(x[m]) for x in ok]).sum())}
        out.setdefault(exp, {}).setdefault(setting, {})[variant] = row
    return out


def horizon_report(records: list[dict], quick: bool) -> list[dict]:
    """Per setting: the timed-out runs flown again at twice the horizon and how many still timed out."""
    by_key = {r["key"]: r for r in records}
    out: dict[tuple, dict] = {}
    for run in horizon_checks(records, quick):
        rec = by_key.get(run.key)
        entry = out.setdefault((run.experiment, run.setting), {"experiment": run.experiment, "setting": run.setting,
                                                               "horizon": run.max_cycles // 2, "checked": [],
                                                               "still_timeout": 0, "arrived": 0, "collided": 0})
        if rec is None or rec["status"] != "ok":
            continue
        m = rec["metrics"]
        entry["checked"].append(run.key)
        entry["still_timeout"] += int(m["timeout"])
        entry["arrived"] += int(m["success"])
        entry["collided"] += int(m["collision"])
    for (exp, setting), entry in out.items():
        entry["timeouts"] = sum(1 for r in records if r["experiment"] == exp and r["setting"] == setting
                                and not r.get("horizon_check") and r["status"] == "ok" and r["metrics"]["timeout"])
    return list(out.values())


# ------------------------------------------------------------------------------------------------ figures
def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _save(fig, path: Path) -> None:
    atomic_write_figure(path, fig, format="png", dpi=80, bbox_inches="tight")
    _pyplot().close(fig)


STYLES = ("-", "--", "-.", ":", (0, (6, 2, 1, 2)))   # variants often coincide: dashes keep each visible


def _traces(records: list[dict], exp: str, setting: str) -> dict[str, dict]:
    return {r["variant"]: r["trace"] for r in sorted(records, key=lambda r: r["variant"])
            if r["experiment"] == exp and r["setting"] == setting and r["seed"] == FIGURE_SEED and r.get("trace")}


def _top_view(ax, exp: str, setting: str, variant: str) -> None:
    """Obstacle footprints (coloured by top height), start and goal of the figure seed's scenario."""
    from matplotlib.collections import PolyCollection

    from uavform_env.render import obstacle_footprints

    scn = scenario_of(Run(exp, setting, variant, FIGURE_SEED, 1))
    outlines, tops = obstacle_footprints(scn.build_world())
    if outlines:
        ax.add_collection(PolyCollection(outlines, array=tops, cmap="Greys", clim=(0.0, scn.bounds_hi[2] * 1.3),
                                         edgecolors="0.3", linewidths=0.5))
    ax.plot(*scn.mission.start[:2], "ks", ms=7, mfc="white")
    ax.plot(*scn.mission.goal[:2], "*", ms=14, color="gold", mec="k")
    ax.set_xlim(scn.bounds_lo[0], scn.bounds_hi[0])
    ax.set_ylim(scn.bounds_lo[1], scn.bounds_hi[1])
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")


def _experiment_figure(records, exp, path: Path) -> str | None:
    """Per setting: the figure seed's leader paths (top view) over the obstacles, and goal distance or altitude
    against time."""
    plt = _pyplot()
    e = next(x for x in EXPERIMENTS if x.id == exp)
    panels = [(s.name, _traces(records, exp, s.name)) for s in e.settings]
    panels = [(s, t) for s, t in panels if t]
    if not panels:
        return None
    vertical = exp in ("E4", "E5", "E6")
    fig, axes = plt.subplots(2, len(panels), figsize=(6.5 * len(panels), 10), squeeze=False,
                             gridspec_kw={"height_ratios": [1.6, 1]})
    for col, (setting, traces) in enumerate(panels):
        top, series = axes[0, col], axes[1, col]
        _top_view(top, exp, setting, next(iter(traces)))
        for k, (variant, tr) in enumerate(traces.items()):
            pos = np.asarray(tr["pos"])
            ls = STYLES[k % len(STYLES)]
            top.plot(pos[:, 0], pos[:, 1], lw=1.5, ls=ls, label=variant)
            top.plot(pos[-1, 0], pos[-1, 1], "o", color=top.lines[-1].get_color(), ms=4)
            series.plot(tr["t"], pos[:, 2] if vertical else tr["goal_distance"], lw=1.2, ls=ls, label=variant)
        top.set_title(f"{exp} {setting} (seed {FIGURE_SEED}): leader paths")
        top.legend(fontsize=7, loc="upper left")
        series.set_xlabel("time [s]")
        series.set_ylabel("leader altitude z [m]" if vertical else "distance to the goal [m]")
        if not vertical:
            series.axhline(R_SW, color="k", ls="--", lw=0.8)
            series.set_yscale("symlog", linthresh=0.1)
            series.set_ylim(bottom=0.0)
        series.grid(True, lw=0.3)
    fig.suptitle(e.title)
    _save(fig, path)
    return path.name


def write_figures(records: list[dict], out: Path) -> dict[str, str]:
    """One figure per experiment; missing data (e.g. a quick run) leaves a figure out."""
    figures = {e.id: _experiment_figure(records, e.id, out / f"{e.id.lower()}-paths.png") for e in EXPERIMENTS}
    return {k: v for k, v in figures.items() if v}


# ------------------------------------------------------------------------------------------------ markdown
def _label(metric: str) -> str:
    if metric in ("success", "collision", "timeout", "reformed"):
        return f"{metric} (share)"
    unit = UNITS.get(metric) or EXTRA_UNITS.get(metric)
    return f"{metric} ({unit})" if unit else metric


def _flatten(d: dict, prefix: str = "") -> dict:
    out = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(_flatten(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def _value(v) -> str:
    return f"{v:.4g}" if isinstance(v, float) else f"`{v}`" if isinstance(v, str) else str(v)


def _diff(obj, default) -> str:
    a, b = _flatten(obj.to_dict()), _flatten(default.to_dict())
    return ", ".join(f"`{k}` = {_value(x)}" for k, x in a.items() if b.get(k) != x) or "none"


def _parameters() -> list[str]:
    """Every parameter of every run, from the config objects themselves (angles in radians)."""
    lines = ["", "## Parameters", "",
             "Generated from the config objects (SI units, angles in radians).", "",
             "Paper-faithful planners, `baselines.paper.PaperConfig()` (the variants list what differs):", "",
             "| field | value |", "|---|---|"]
    lines += [f"| `{k}` | {_value(v)} |" for k, v in _flatten(PaperConfig().to_dict()).items()]
    lines += ["", "Engineered expert: `baselines.expert.ExpertConfig()`; its fields are listed in "
              "[docs/deviations.md](../deviations.md).", "", "Variants (fields that differ from their family's "
              "defaults, `PaperConfig()` or `ExpertConfig()`):", ""]
    seen = set()
    for e in EXPERIMENTS:
        for v in e.variants:
            if v.name not in seen:
                seen.add(v.name)
                cfg = v.config()
                lines.append(f"- `{v.name}` ({type(cfg).__name__}): "
                             + _diff(cfg, PaperConfig() if isinstance(cfg, PaperConfig) else ExpertConfig()))
    lines += ["", "Environment, `uavform_env.config.EnvConfig()` (settings list what differs):", "",
              "| field | value |", "|---|---|"]
    env = _flatten({k: v for k, v in EnvConfig().to_dict().items() if k in ("uav", "sensor", "map", "episode")})
    lines += [f"| `{k}` | {_value(v)} |" for k, v in env.items()]
    return lines


def _table(exp: str, rows: dict) -> list[str]:
    metrics = TABLE_METRICS[exp]
    lines = ["| setting | variant | runs | " + " | ".join(_label(m) for m in metrics) + " |",
             "|" + "---|" * (3 + len(metrics))]
    for setting, variants in rows.items():
        for variant, row in variants.items():
            runs = f"{row['runs']}" + (f" ({row['failed']} failed)" if row["failed"] else "")
            lines.append(f"| {setting} | {variant} | {runs} | "
                         + " | ".join(ci_cell(row[m]) if m in row else "n/a" for m in metrics) + " |")
    return lines


def _claim_lines(c: dict) -> list[str]:
    readings = ", ".join(f"`{r['reading']}`: **{r['verdict']}**" for r in c["readings"])
    by = (f"reproduced under {c['reading_field']} = " + ", ".join(f"`{r}`" for r in c["reproduced_by"])
          if c["reproduced_by"] else "reproduced under no reading")
    lines = ["", f"### {c['id']}: {c['verdict']} ({by})", "", f"> {c['statement']}", "",
             f"Source: {c['source']}. Conditions: {c['conditions']}. Per reading of {c['reading_field']}: "
             f"{readings}."]
    for r in c["readings"]:
        lines += ["", f"Reading `{r['reading']}`: **{r['verdict']}**; {r['why']}.", ""]
        lines += [f"- {'PASS' if k['holds'] else 'FAIL' if k['holds'] is False else 'N/A'}: {k['text']}"
                  for k in r["checks"]]
        lines += [f"- runs: {o}" for o in r["outcomes"]]
    return lines


def to_markdown(summary: dict, claims: list[dict], figures: dict[str, str], records: list[dict], command: str,
                horizons: list[dict]) -> str:
    ok = sum(r["status"] == "ok" for r in records)
    codes = sorted({r.get("code", "unknown") for r in records})
    held = [c for c in claims if c["verdict"] == HOLDS]
    default = [c for c in held if c["readings"][0]["verdict"] == HOLDS]
    lines = ["# Reproduction of the paper's claims (format 2: the paper's planners bare)", "",
             "Generated by `" + command + "` (`baselines/reproduce`); do not edit by hand. Paper: \"Multi-UAV "
             "Cooperative Obstacle Avoidance of 3D Vector Field Histogram Plus and Dynamic Window Approach\" "
             "(Drones 2023, 7(8), 504). Its equations, Sections 4-5 and result tables were not recovered (spec 0.2), "
             "so no number of the paper is compared. The claims, their checks and thresholds were written down in "
             "`baselines/reproduce/claims.toml` before the runs; a claim is tested once per reading of what the spec "
             "leaves open, and holds under a reading when every check holds. Each verdict, sentence and table below is "
             "generated from `runs.jsonl`.", "",
             f"{len(records)} runs ({ok} finished, {len(records) - ok} failed)"
             + (f", {sum(r['wall_time'] for r in records) / 60:.1f} min of episode wall time" if records else "")
             + f", code {', '.join(f'`{c}`' for c in codes)}"
             + (" (**mixed code**: rerun into a fresh folder)" if len(codes) > 1 else "") + ". "
             "Cells: mean [95% percentile-bootstrap interval over seeds]; `n/a` where a metric does not apply.", "",
             "## Verdicts", "",
             f"Honest count: **{len(held)} of {len(claims)}** claims hold under at least one reading; "
             f"{len(default)} of {len(claims)} under the first reading listed (the spec's default where it has "
             "one).", "", "| claim | source | verdict | per reading |", "|---|---|---|---|"]
    for c in claims:
        per = ", ".join(f"`{r['reading']}` {r['verdict']}" for r in c["readings"])
        lines.append(f"| {c['id']} | {c['source']} | **{c['verdict']}** | {c['reading_field']}: {per} |")
    lines += ["", "## Claims"]
    for c in claims:
        lines += _claim_lines(c)
    lines += ["", "## Time-outs at twice the horizon", "",
              f"Per setting, the first {HORIZON_SAMPLE} timed-out runs (by key) are flown again at twice the horizon: "
              "a time-out that still times out there is a trap, not a short horizon.", "",
              "| experiment | setting | horizon (steps) | time-outs | flown at 2x | still timed out | arrived | "
              "collided |", "|---|---|---|---|---|---|---|---|"]
    for h in horizons:
        lines.append(f"| {h['experiment']} | {h['setting']} | {h['horizon']} | {h['timeouts']} | {len(h['checked'])} "
                     f"| {h['still_timeout']} | {h['arrived']} | {h['collided']} |")
    for e in EXPERIMENTS:
        lines += ["", f"## {e.id}: {e.title}", "", "**Setup** (generated from the configs that ran):", ""]
        for s in e.settings:
            lines.append(f"- setting `{s.name}`: {s.description}; episode {s.max_cycles} steps "
                         f"({s.max_cycles * s.env.uav.dt:g} s); {SEEDS} seeds; env differs from `EnvConfig()` in: "
                         + _diff(s.env, EnvConfig()))
        lines += [f"- variant `{v.name}`: {v.description}" for v in e.variants]
        lines += [f"- setting `{s.name}` runs only: " + ", ".join(f"`{v}`" for v in s.variants)
                  for s in e.settings if s.variants is not None]
        if e.id in summary:
            lines += ["", "**Results.**", ""] + _table(e.id, summary[e.id])
        if e.id in figures:
            lines += ["", f"![{e.id}]({figures[e.id]})"]
    failed = [r for r in records if r["status"] != "ok"]
    if failed:
        lines += ["", "## Failed runs", ""]
        lines += [f"- `{r['key']}`: {r['error'].strip().splitlines()[-1]}" for r in failed]
    lines += _parameters()
    return "\n".join(lines) + "\n"


def write_report(records: list[dict], out, command: str, quick: bool = False) -> dict:
    """Write README.md, claims.json, summary.json and the figures into ``out``; return the summary."""
    out = Path(out)
    summary = summarize(records)
    claims = evaluate(records, load_claims())
    horizons = horizon_report(records, quick)
    figures = write_figures(records, out)
    atomic_write_text(out / "README.md", to_markdown(summary, claims, figures, records, command, horizons))
    atomic_write_json(out / "claims.json", claims)
    result = {"tables": summary, "claims": claims, "horizon_checks": horizons, "figures": figures}
    atomic_write_json(out / "summary.json", result)
    return result
