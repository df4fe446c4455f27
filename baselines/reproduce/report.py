"""The reproduction report: result tables with bootstrap intervals, figures, and every paper claim checked.

``summarize`` turns the run records into mean and 95% interval per (experiment, setting, variant,
metric), with the leaderboard's ``bootstrap_ci``; ``check_claims`` evaluates each claim of spec (h)
on that summary and gives a verdict with its evidence; ``write_report`` writes ``README.md``,
``summary.json`` and the PNG figures into the output folder. The verdicts are computed, never
written by hand, so a rerun that changes a direction changes the report.
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from uavform_env.evaluation.table import UNITS, bootstrap_ci, ci_cell
from uavform_env.files import atomic_write_bytes, atomic_write_json, atomic_write_text
from uavform_env.metrics import METRIC_NAMES

from .experiments import EXPERIMENTS, FIGURE_SEED, Run, scenario_of

R_UU = 0.8      # spec (g6) safe separation, ExpertConfig().dwa.R_uu
R_SW = 3.0      # spec (c1) switching radius v_max * T_p: "near the goal"

# The metrics each experiment's table shows (all metrics are in summary.json).
TABLE_METRICS = {
    "E1": ("success", "flight_time", "path_length_leader", "min_clearance", "total_turning", "turning_per_metre",
           "direction_sign_changes"),
    "E2": ("success", "path_length_leader", "min_clearance", "total_turning", "turning_per_metre",
           "direction_sign_changes"),
    "E3": ("success", "flight_time", "path_length_leader", "total_turning", "direction_sign_changes"),
    "E4": ("success", "collision", "flight_time", "path_length_leader", "min_clearance", "altitude_deviation_max"),
    "E5": ("success", "collision", "path_length_leader", "min_clearance", "min_separation", "formation_error_rms",
           "formation_error_max", "reformed", "time_to_reform"),
    "E6": ("collision", "min_separation", "separation_kept", "formation_error_rms", "altitude_deviation_max"),
}


DERIVED = ("separation_kept", "turning_per_metre", "reformed")


def run_values(record: dict) -> dict:
    """The metric values of one record, plus derived ones: ``separation_kept`` (d_uu >= R_uu),
    ``turning_per_metre`` (leader's total turning / path length: smoothness that does not reward
    stopping early) and ``reformed`` (the formation closed up after its last break before the episode
    ended; ``time_to_reform`` is undefined otherwise). NaN for a failed run or where it does not apply."""
    if record["status"] != "ok":
        return {m: math.nan for m in (*METRIC_NAMES, *DERIVED)}
    m = {k: float(v) for k, v in record["metrics"].items()}
    sep, length = m["min_separation"], m["path_length_leader"]
    m["separation_kept"] = math.nan if math.isnan(sep) else float(sep >= R_UU)
    m["turning_per_metre"] = m["total_turning"] / length if length > 0.5 else math.nan
    m["reformed"] = math.nan if math.isnan(sep) else float(math.isfinite(m["time_to_reform"]))
    return m


def summarize(records: list[dict]) -> dict:
    """``{exp: {setting: {variant: {"runs", "failed", metric: {mean, ci_low, ci_high, n}}}}}``, seeds in order."""
    groups: dict[tuple, list[dict]] = {}
    for r in sorted(records, key=lambda r: (r["experiment"], r["setting"], r["variant"], r["seed"])):
        groups.setdefault((r["experiment"], r["setting"], r["variant"]), []).append(r)
    out: dict = {}
    for (exp, setting, variant), recs in groups.items():
        values = [run_values(r) for r in recs]
        row = {"runs": len(recs), "failed": sum(r["status"] != "ok" for r in recs)}
        for m in values[0]:
            column = np.array([v[m] for v in values])
            mean, lo, hi = bootstrap_ci(column)
            row[m] = {"mean": mean, "ci_low": lo, "ci_high": hi, "n": int(np.isfinite(column).sum())}
        out.setdefault(exp, {}).setdefault(setting, {})[variant] = row
    return out


# ------------------------------------------------------------------------------------------------ claims
@dataclass(frozen=True)
class Claim:
    """A paper claim as a direction test on the summary; ``check`` returns (holds, evidence) or None when
    the runs it needs are missing. ``why_holds``/``why_not`` say what drives the result either way."""

    id: str
    experiment: str
    text: str
    check: Callable[[dict], tuple[bool, str] | None]
    why_holds: str
    why_not: str


def _mean(summary, exp, setting, variant, metric) -> float | None:
    row = summary.get(exp, {}).get(setting, {}).get(variant)
    return None if row is None else row[metric]["mean"]


def _compare(exp: str, metric: str, better: str, worse: str, *, strict: bool, higher: bool,
             settings: tuple[str, ...] | None = None, tol: float = 0.0):
    """A check that ``better`` beats ``worse`` on ``metric`` in every setting of ``exp`` that ran both."""
    def check(summary):
        parts, ok = [], True
        for setting in summary.get(exp, {}):
            if settings is not None and setting not in settings:
                continue
            a, b = _mean(summary, exp, setting, better, metric), _mean(summary, exp, setting, worse, metric)
            if a is None or b is None or math.isnan(a) or math.isnan(b):
                continue
            good = (a > b if strict else a >= b - tol) if higher else (a < b if strict else a <= b + tol)
            ok &= good
            parts.append(f"{exp} {setting}: {better} {a:.3g} vs {worse} {b:.3g}")
        if not parts:
            return None
        return ok, f"{metric} ({'higher' if higher else 'lower'} is better; mean over seeds) - " + "; ".join(parts)
    return check


def _all_of(*checks):
    def check(summary):
        results = [c(summary) for c in checks]
        results = [r for r in results if r is not None]
        if not results:
            return None
        return all(r[0] for r in results), " | ".join(r[1] for r in results)
    return check


def _separation_kept(exp: str, variant: str, contrast: str):
    """Every run of ``variant`` kept d_uu >= R_uu; the evidence also counts ``contrast``'s runs."""
    def check(summary):
        parts, ok = [], True
        for setting, rows in summary.get(exp, {}).items():
            if variant not in rows:
                continue
            ok &= rows[variant]["separation_kept"]["mean"] == 1.0
            counts = [f"{v} in {rows[v]['separation_kept']['mean'] * rows[v]['separation_kept']['n']:.0f}/"
                      f"{rows[v]['separation_kept']['n']} runs (mean minimum separation "
                      f"{rows[v]['min_separation']['mean']:.3g} m)" for v in (variant, contrast) if v in rows]
            parts.append(f"{exp} {setting}: d_uu >= {R_UU} m kept by " + ", ".join(counts))
        return (ok, "; ".join(parts)) if parts else None
    return check


CLAIMS = (
    Claim("C1", "E1", "Improved DWA removes the near-goal oscillation of standard DWA on the classic map: fewer "
          "sign changes of the yaw rate within R_sw = 3 m of the goal.",
          _compare("E1", "direction_sign_changes", "IDWA", "DWA", strict=True, higher=False),
          "IDWA changes turn direction less often near the goal.",
          "On the classic map standard DWA in this env shows (almost) no near-goal sign changes to remove: it "
          "reaches the goal on a smooth arc (see the heading figure), so there is nothing for E8 to fix; where IDWA "
          "stops short of the goal (below) it has no sign changes either, for the wrong reason."),
    Claim("C2", "E1", "Improved DWA reaches the goal on the classic map with a path length and flight time lower "
          "or equal to standard DWA (success rate at least as high).",
          _compare("E1", "success", "IDWA", "DWA", strict=False, higher=True),
          "IDWA arrives at least as often as standard DWA.",
          "IDWA stops in front of obstacles and never arrives on some starts: inside d_in of an obstacle the "
          "rotation weight eps_t is 0, every candidate is aligned with the A* path (E10 weight = alpha0), and the "
          "sum-normalised clearance term then pays more for standing still than the speed term pays for moving "
          "(pinned in tests/test_dwa_comparison.py::test_freeze_is_the_sum_normalised_clearance_term). Path length "
          "and flight time are therefore not comparable on those runs."),
    Claim("C3", "E3", "The target-distance correction (E8) removes the orbiting around a goal next to an obstacle: "
          "DWA+E8 arrives more often and turns less than standard DWA.",
          _all_of(_compare("E3", "success", "DWA+E8", "DWA", strict=True, higher=True),
                  _compare("E3", "total_turning", "DWA+E8", "DWA", strict=True, higher=False)),
          "DWA+E8 arrives more often and turns less.",
          "E8 only reshapes the heading term near the goal. The runs that do not arrive either circle the goal "
          "1.5-3.5 m away - about the radius of a full-speed turn, v_max / w_max = 2.9 m, as the speed term keeps "
          "rewarding full speed (path lengths over 30 m in 60 s) - or stop beside the obstacle (the freeze of C2), "
          "with or without E8. Braking near the goal does not cure it: DWA+E8+profile ((c1) approach_speed_profile, "
          "an [X] option) brakes only within about 2.5 m of the goal, inside the orbit, and where it does slow "
          "down next to the obstacle it freezes like C2 (see its row)."),
    Claim("C4", "E2", "The A* weight (E10) lets the planner escape traps that standard DWA falls into: DWA+E8+E10 "
          "and IDWA arrive more often than DWA in the U-trap and the dense fields.",
          _all_of(_compare("E2", "success", "DWA+E8+E10", "DWA", strict=True, higher=True),
                  _compare("E2", "success", "IDWA", "DWA", strict=True, higher=True)),
          "The E10 variants arrive more often than standard DWA.",
          "In the paper-faithful form (d6) the A* path only scales the weight of the heading term, and the heading "
          "term still points at the goal, i.e. into the trap, so no candidate leads out of it; a higher weight on "
          "a heading that points the wrong way does not help. IDWA+lookahead, which heads for the A* lookahead "
          "point instead (a deviation), shows whether the A* path itself leads out."),
    Claim("C5", "E1", "The rotation cost (E11) smooths the path: IDWA turns less per metre flown than DWA+E8+E10 "
          "on the classic maps and the dense fields.",
          _all_of(_compare("E1", "turning_per_metre", "IDWA", "DWA+E8+E10", strict=True, higher=False),
                  _compare("E2", "turning_per_metre", "IDWA", "DWA+E8+E10", strict=True, higher=False,
                           settings=("dense",))),
          "Adding the rotation cost lowers the turning per metre of path. Per metre, because the runs differ in "
          "how far they get (a run that stops early also turns less in total).",
          "Per metre flown, IDWA does not turn less: where it stops short of obstacles (the freeze of C2) its "
          "path ends in the turning it did while slowing down, and E11's weight is 0 within d_in of an obstacle, "
          "exactly where the turning happens."),
    Claim("C6", "E4", "The fused 3D controller passes obstacles that fixed-altitude 2D avoidance cannot: a single "
          "UAV (E4) and the five-UAV wedge in the same kind of world (E5 blocks) arrive more often, the single UAV "
          "with a similar (within 5 cm) or larger minimum clearance.",
          _all_of(_compare("E4", "success", "fusion", "IDWA-2D", strict=True, higher=True),
                  _compare("E4", "min_clearance", "fusion", "IDWA-2D", strict=False, higher=True, tol=0.05),
                  _compare("E5", "success", "fusion", "IDWA-2D", strict=True, higher=True, settings=("blocks",))),
          "The fusion climbs over the low blocks (altitude profile in the E4 figure). The fixed-altitude controller "
          "creeps up to the first block on its way and stops in front of it, although there is room to fly round "
          "it (E4 figure): its heading term points at the goal through the block and the A* path only weights that "
          "term, the mechanism of the U-trap (C4). So the difference is the climb and the planar controller's "
          "failure to detour together; the spec's 'shorter L' cannot be compared, as the fixed-altitude runs do "
          "not arrive.",
          "The fixed-altitude controller is not stopped more often, or the fusion passes closer to obstacles "
          "(see the evidence)."),
    Claim("C7", "E5", "Both formations fly collision-free through the block world and the corridor.",
          lambda s: _no_collisions(s, "E5"),
          "No run of either controller collided.",
          "Some runs collided (collision > 0 in the table)."),
    Claim("C8", "E5", "The fused formation keeps the formation better: lower formation-error RMS than the planar "
          "IDWA formation.",
          _compare("E5", "formation_error_rms", "fusion", "IDWA-2D", strict=True, higher=False,
                   settings=("blocks", "corridor")),
          "The fused formation's followers stay closer to their slots.",
          "Not in every world (see the evidence). The corridor's walls reach above z_max, so the third dimension "
          "offers nothing there. Both formations pass it in single file, but the fused followers also weigh "
          "3D VFH+'s climb proposals at the corridor's mouth and fall farther behind their slots (see the "
          "formation-error figure); within this experiment's 1200 steps the planar formation completes the "
          "corridor and the fused one is still closing up (the fused expert completes the full 3000-step "
          "mission on seeds 0-9: README, Status). In the blocks world the planar formation does not get "
          "through, and a formation that stops keeps its shape: lower error can mean less progress, so compare "
          "path length and success."),
    Claim("C9", "E5", "The fused formation re-forms after avoidance where the planar one does not: a larger share of "
          "runs closes up again (every follower within e_f = 0.5 m after the last break of more than 1 m) before "
          "the episode ends. The time it takes is in the table (defined only for runs that re-formed).",
          _compare("E5", "reformed", "fusion", "IDWA-2D", strict=True, higher=True, settings=("blocks", "corridor")),
          "The fused formation closes up again after passing the obstacles more often than the planar one.",
          "Not in every world (see the evidence). In the corridor the fused formation had not closed up again "
          "when this experiment's 1200-step episode ended (its followers were still leaving the corridor), while "
          "the planar formation had. In the blocks world it is the other way round: the planar formation does "
          "not get through."),
    Claim("C10", "E6", "With neighbour prediction (g6) the UAVs keep d_uu >= R_uu = 0.8 m in every conflict run.",
          _separation_kept("E6", "prediction", "no-prediction"),
          "Every run with prediction kept the safe separation (the evidence also counts the runs without it).",
          "Some runs with prediction came closer than R_uu."),
    Claim("C11", "E6", "Neighbour prediction keeps more separation than treating neighbours as standing "
          "obstacles: higher mean minimum separation with prediction.",
          _compare("E6", "min_separation", "prediction", "no-prediction", strict=True, higher=True),
          "Prediction keeps the UAVs farther apart.",
          "Not in every conflict (see the evidence): where prediction does not keep more separation, the "
          "neighbours, which without prediction are still DWA obstacles at their broadcast positions re-planned "
          "every 0.1 s, never came closer than the start spacing, so there was no conflict for prediction to "
          "improve on; prediction changes the manoeuvre (the UAVs pass where a neighbour is going, not where it "
          "is), which can mean a closer but still safe pass."),
)


def _no_collisions(summary: dict, exp: str):
    rows = [(s, v, r) for s, vs in summary.get(exp, {}).items() for v, r in vs.items()]
    if not rows:
        return None
    bad = [f"{s}/{v}" for s, v, r in rows if not r["collision"]["mean"] == 0.0]
    return not bad, "collisions in " + (", ".join(bad) if bad else "no run")


def check_claims(summary: dict) -> list[dict]:
    out = []
    for c in CLAIMS:
        result = c.check(summary)
        if result is None:
            out.append({"id": c.id, "experiment": c.experiment, "claim": c.text, "verdict": "not run",
                        "evidence": "", "why": ""})
            continue
        holds, evidence = result
        out.append({"id": c.id, "experiment": c.experiment, "claim": c.text,
                    "verdict": "holds" if holds else "does not hold", "evidence": evidence,
                    "why": c.why_holds if holds else c.why_not})
    return out


# ------------------------------------------------------------------------------------------------ figures
def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _save(fig, path: Path) -> None:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    _pyplot().close(fig)
    atomic_write_bytes(path, buf.getvalue())


STYLES = ("-", "--", "-.", ":", (0, (6, 2, 1, 2)))   # variants often coincide: dashes keep each visible


def _traces(records: list[dict], exp: str, setting: str) -> dict[str, dict]:
    return {r["variant"]: r["trace"] for r in records if r["experiment"] == exp and r["setting"] == setting
            and r["seed"] == FIGURE_SEED and r.get("trace")}


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


def _paths_figure(records, exp: str, settings: tuple[str, ...], path: Path, title: str) -> str | None:
    plt = _pyplot()
    panels = [(s, _traces(records, exp, s)) for s in settings]
    panels = [(s, t) for s, t in panels if t]
    if not panels:
        return None
    fig, axes = plt.subplots(1, len(panels), figsize=(6.5 * len(panels), 6), squeeze=False)
    for ax, (setting, traces) in zip(axes[0], panels):
        _top_view(ax, exp, setting, next(iter(traces)))
        for k, (variant, tr) in enumerate(traces.items()):
            pos = np.asarray(tr["pos"])
            ax.plot(pos[:, 0, 0], pos[:, 0, 1], lw=1.8, ls=STYLES[k % len(STYLES)], label=variant)
            ax.plot(pos[-1, 0, 0], pos[-1, 0, 1], "o", color=ax.lines[-1].get_color(), ms=5)
        ax.set_title(f"{exp} {setting} (seed {FIGURE_SEED})")
        ax.legend(fontsize=8, loc="upper left")
    fig.suptitle(title)
    _save(fig, path)
    return path.name


def _near_goal_figure(records, path: Path) -> str | None:
    """Heading and yaw rate against time for E3 and the E1 base map, the near-goal stretch shaded."""
    plt = _pyplot()
    panels = [(e, s, _traces(records, e, s)) for e, s in (("E3", "beside"), ("E1", "base"))]
    panels = [p for p in panels if p[2]]
    if not panels:
        return None
    fig, axes = plt.subplots(2, len(panels), figsize=(7 * len(panels), 6.5), squeeze=False, sharex="col")
    for col, (exp, setting, traces) in enumerate(panels):
        for k, (variant, tr) in enumerate(traces.items()):
            t, d = np.asarray(tr["t"]), np.asarray(tr["goal_distance"])
            ls = STYLES[k % len(STYLES)]
            axes[0, col].plot(t, np.degrees(np.unwrap(tr["yaw"])), lw=1.4, ls=ls, label=variant)
            axes[1, col].plot(t, np.degrees(tr["w"]), lw=1.2, ls=ls, label=variant)
            near = d < R_SW
            if near.any():
                axes[1, col].fill_between(t, -22, 22, where=near, color=axes[1, col].lines[-1].get_color(),
                                          alpha=0.08, step="mid")
        axes[0, col].set_title(f"{exp} {setting} (seed {FIGURE_SEED}): heading")
        axes[0, col].set_ylabel("yaw, unwrapped [deg]")
        axes[1, col].set_title(f"yaw rate (shaded: within R_sw = {R_SW:g} m of the goal)")
        axes[1, col].set_ylabel("w [deg/s]")
        axes[1, col].set_xlabel("time [s]")
        axes[0, col].legend(fontsize=8)
        for ax in axes[:, col]:
            ax.grid(True, lw=0.3)
    _save(fig, path)
    return path.name


def _series_figure(records, exp: str, key: str, ylabel: str, path: Path, title: str,
                   lines: tuple[tuple[float, str], ...] = ()) -> str | None:
    plt = _pyplot()
    settings = [s.name for e in EXPERIMENTS if e.id == exp for s in e.settings]
    panels = [(s, _traces(records, exp, s)) for s in settings]
    panels = [(s, t) for s, t in panels if t and np.isfinite(next(iter(t.values()))[key]).any()]
    if not panels:
        return None
    fig, axes = plt.subplots(1, len(panels), figsize=(5 * len(panels), 3.8), squeeze=False)
    for ax, (setting, traces) in zip(axes[0], panels):
        for k, (variant, tr) in enumerate(traces.items()):
            ax.plot(tr["t"], tr[key], lw=1.3, ls=STYLES[k % len(STYLES)], label=variant)
        for y, label in lines:
            ax.axhline(y, color="k", ls="--", lw=0.8)
            ax.text(0.99, y, label, transform=ax.get_yaxis_transform(), ha="right", va="bottom", fontsize=8)
        ax.set_title(f"{exp} {setting} (seed {FIGURE_SEED})")
        ax.set_xlabel("time [s]")
        ax.set_ylabel(ylabel)
        ax.grid(True, lw=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(title)
    _save(fig, path)
    return path.name


def _altitude_figure(records, path: Path) -> str | None:
    """E4: top view of the figure seed's paths and their altitude profiles."""
    plt = _pyplot()
    traces = _traces(records, "E4", "blocks")
    if not traces:
        return None
    fig, (top, alt) = plt.subplots(1, 2, figsize=(13, 5.5), gridspec_kw={"width_ratios": [1, 1.3]})
    _top_view(top, "E4", "blocks", next(iter(traces)))
    for k, (variant, tr) in enumerate(traces.items()):
        pos = np.asarray(tr["pos"])
        top.plot(pos[:, 0, 0], pos[:, 0, 1], lw=1.8, ls=STYLES[k % len(STYLES)], label=variant)
        alt.plot(tr["t"], pos[:, 0, 2], lw=1.5, ls=STYLES[k % len(STYLES)], label=variant)
    top.set_title(f"E4 blocks (seed {FIGURE_SEED}): paths over tall columns and low blocks (darker = taller)")
    top.legend(fontsize=8)
    alt.set_title("altitude profile")
    alt.set_xlabel("time [s]")
    alt.set_ylabel("z [m]")
    alt.grid(True, lw=0.3)
    alt.legend(fontsize=8)
    _save(fig, path)
    return path.name


def write_figures(records: list[dict], out: Path) -> dict[str, str]:
    """Every figure the report embeds; missing data (e.g. a quick run) leaves a figure out."""
    figures = {
        "E1": _paths_figure(records, "E1", ("base", "extended"), out / "e1-paths.png",
                            "Standard vs improved DWA on the classic map (single UAV, planar)"),
        "E2": _paths_figure(records, "E2", ("u-trap", "dense"), out / "e2-paths.png", "Traps"),
        "near-goal": _near_goal_figure(records, out / "near-goal-heading.png"),
        "E4": _altitude_figure(records, out / "e4-paths-altitude.png"),
        "E5": _series_figure(records, "E5", "formation_error_max", "worst follower slot error [m]",
                             out / "e5-formation-error.png", "Formation error over time",
                             ((1.0, "break (1 m)"), (0.5, "e_f"))),
        "E6": _series_figure(records, "E6", "separation_min", "min pairwise separation [m]",
                             out / "e6-separation.png", "Minimum separation over time",
                             ((R_UU, "R_uu"), (0.6, "collision (2 r_uav)"))),
    }
    return {k: v for k, v in figures.items() if v}


# ------------------------------------------------------------------------------------------------ markdown
def _label(metric: str) -> str:
    if metric == "separation_kept":
        return f"d_uu >= {R_UU} m (share)"
    if metric == "turning_per_metre":
        return "turning per metre (rad/m)"
    if metric == "reformed":
        return "re-formed (share)"
    return f"{metric} ({UNITS[metric]})" if metric in UNITS else metric


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


def _parameters() -> list[str]:
    """Every parameter of every run, from the config objects themselves (angles in radians)."""
    from uavform_env.config import EnvConfig

    from ..expert import ExpertConfig

    env = _flatten({k: v for k, v in EnvConfig().to_dict().items()
                    if k in ("uav", "sensor", "map", "formation", "episode")})
    expert = _flatten(ExpertConfig().to_dict())
    lines = ["", "## Parameters", "",
             "Generated from the config objects (SI units, angles in radians). Each run's episode length is the "
             "setting's (above); the mission (start, goal, formation, spacing) is the scenario's.", "",
             "Environment, `uavform_env.config.EnvConfig()` (every run):", "", "| field | value |", "|---|---|"]
    lines += [f"| `{k}` | {_value(v)} |" for k, v in env.items()]
    lines += ["", "Controller, `baselines.expert.ExpertConfig()` (the `fusion` and `prediction` variants; the others "
              "differ as listed below):", "", "| field | value |", "|---|---|"]
    lines += [f"| `{k}` | {_value(v)} |" for k, v in expert.items()]
    lines += ["", "Variants: the fields that differ from `ExpertConfig()`:", ""]
    seen = set()
    for e in EXPERIMENTS:
        for v in e.variants:
            if v.name in seen:
                continue
            seen.add(v.name)
            diff = {k: x for k, x in _flatten(v.config().to_dict()).items() if expert.get(k) != x}
            lines.append(f"- `{v.name}`: " + (", ".join(f"`{k}` = {_value(x)}" for k, x in diff.items()) or "none"))
    return lines


def _table(exp: str, rows: dict) -> list[str]:
    metrics = TABLE_METRICS[exp]
    lines = ["| setting | variant | runs | " + " | ".join(_label(m) for m in metrics) + " |",
             "|" + "---|" * (3 + len(metrics))]
    for setting, variants in rows.items():
        for variant, row in variants.items():
            runs = f"{row['runs']}" + (f" ({row['failed']} failed)" if row["failed"] else "")
            lines.append(f"| {setting} | {variant} | {runs} | " + " | ".join(ci_cell(row[m]) for m in metrics) + " |")
    return lines


def to_markdown(summary: dict, claims: list[dict], figures: dict[str, str], records: list[dict], command: str) -> str:
    ok = sum(r["status"] == "ok" for r in records)
    codes = sorted({r.get("code", "unknown") for r in records})
    lines = ["# Reproduction of the paper's claims (experiments E1-E6)", "",
             "Generated by `" + command + "` (`baselines/reproduce`); do not edit by hand. Paper: \"Multi-UAV "
             "Cooperative Obstacle Avoidance of 3D Vector Field Histogram Plus and Dynamic Window Approach\" "
             "(Drones 2023, 7(8), 504). Its equations, Sections 4-5 and result tables were not recovered (spec "
             "0.2), so no number of the paper is compared; each claim below is a direction test on our runs, "
             "and the verdict is computed from `runs.jsonl`.", "",
             f"{len(records)} runs ({ok} finished, {len(records) - ok} failed)"
             + (f", {sum(r['wall_time'] for r in records) / 60:.1f} min of episode wall time" if records else "")
             + f", code {', '.join(f'`{c}`' for c in codes)}"
             + (" (**mixed code**: rerun into a fresh folder)" if len(codes) > 1 else "") + ". "
             "Cells: mean [95% percentile-bootstrap interval over seeds] (`uavform_env.evaluation.table."
             "bootstrap_ci`, 2000 resamples, fixed seed); `n/a` where a metric does not apply (e.g. separation "
             "with one UAV). Every run is one episode of `baselines.expert.FusionExpert` in `FormationEnv`: each UAV "
             "maps the world with its own range sensor (unknown environment), and the metrics are "
             "`uavform_env.metrics.episode_metrics` (spec (h1)). Tags: [R] reference algorithm, [X] our "
             "reconstruction or choice, [D] suggested default (spec 0.1); every [X] field of the controller is "
             "listed in [docs/deviations.md](../deviations.md).", "",
             "## Verdicts", "", "| claim | experiment | verdict |", "|---|---|---|"]
    for c in claims:
        lines.append(f"| {c['id']}: {c['claim']} | {c['experiment']} | **{c['verdict']}** |")
    by_exp: dict[str, list[dict]] = {}
    for c in claims:
        by_exp.setdefault(c["experiment"], []).append(c)
    for e in EXPERIMENTS:
        lines += ["", f"## {e.id}: {e.title}", "", "**Setup.** " + e.setup, ""]
        lines += [f"- setting `{s.name}`: {s.description}" for s in e.settings]
        lines += [f"- variant `{v.name}`: {v.description}" for v in e.variants]
        if e.id in summary:
            lines += ["", "**Results.**", ""] + _table(e.id, summary[e.id])
        for key in (e.id, "near-goal" if e.id == "E3" else None):
            if key in figures:
                lines += ["", f"![{key}]({figures[key]})"]
        pictures = sorted({r["picture"] for r in records if r["experiment"] == e.id and r.get("picture")})
        if pictures:
            lines += ["", "Trajectory pictures (3D view, top view, formation snapshots, altitude profile):", ""]
            lines += [f"![{p}]({p})" for p in pictures]
        for c in by_exp.get(e.id, []):
            lines += ["", f"**{c['id']}: {c['claim']}** Verdict: **{c['verdict']}**."]
            if c["evidence"]:
                lines += ["", f"Evidence: {c['evidence']}.", "", f"Why: {c['why']}"]
    failed = [r for r in records if r["status"] != "ok"]
    if failed:
        lines += ["", "## Failed runs", ""]
        lines += [f"- `{r['key']}`: {r['error'].strip().splitlines()[-1]}" for r in failed]
    lines += _parameters()
    return "\n".join(lines) + "\n"


def write_report(records: list[dict], out, command: str) -> dict:
    """Write README.md, summary.json (tables and verdicts) and the figures into ``out``; return the summary."""
    out = Path(out)
    summary = summarize(records)
    claims = check_claims(summary)
    figures = write_figures(records, out)
    atomic_write_text(out / "README.md", to_markdown(summary, claims, figures, records, command))
    result = {"tables": summary, "claims": claims, "figures": figures}
    atomic_write_json(out / "summary.json", result)
    return result
