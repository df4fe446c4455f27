"""The paper's claims as data (``claims.toml``) and the verdict logic that tests them on the run records.

A claim is tested once per reading of the spec (``readings``); under a reading it holds when every check
holds. A check compares a metric's mean over a setting's runs between two variants, or with a threshold
(the tests are listed in ``TESTS``). ``evaluate`` returns, per claim, every check with its figures and a
sentence generated from them, the verdict per reading, and the readings under which the claim holds.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from uavform_env.evaluation.table import bootstrap_ci
from uavform_env.metrics import METRIC_NAMES

from .experiments import EXPERIMENTS, METRICS

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

CLAIMS_FILE = Path(__file__).with_name("claims.toml")
TESTS = {"lower": "<", "higher": ">", "not_higher": "<=", "not_lower": ">=", "at_most": "<=", "at_least": ">="}
COMPARISONS = ("lower", "higher", "not_higher", "not_lower")
HOLDS, FAILS, NOT_RUN = "holds", "does not hold", "undecided"


@dataclass(frozen=True)
class Check:
    what: str
    experiment: str
    setting: str
    metric: str
    variant: str
    test: str
    baseline: str | None = None
    threshold: float | None = None
    paired: bool = False
    tol: float = 0.0


@dataclass(frozen=True)
class Claim:
    id: str
    source: str
    statement: str
    conditions: str
    reading_field: str
    readings: tuple[str, ...]
    checks: tuple[Check, ...]
    aliases: tuple[tuple[str, str], ...] = ()

    def name(self, template: str | None, reading: str) -> str | None:
        """A variant name with ``{reading}`` filled in and the claim's aliases applied."""
        if template is None:
            return None
        name = template.replace("{reading}", reading)
        return dict(self.aliases).get(name, name)


def _check(claim_id: str, raw: dict) -> Check:
    where = f"claims.toml {claim_id}"
    unknown = sorted(set(raw) - set(Check.__dataclass_fields__))
    if unknown:
        raise ValueError(f"{where}: unknown check field(s) {unknown}")
    c = Check(**raw)
    if c.test not in TESTS:
        raise ValueError(f"{where}: test={c.test!r}; expected one of {list(TESTS)}")
    if (c.test in COMPARISONS) != (c.baseline is not None) or (c.test in COMPARISONS) == (c.threshold is not None):
        raise ValueError(f"{where}: test {c.test!r} needs " + ("a baseline and no threshold" if c.test in COMPARISONS
                                                                else "a threshold and no baseline"))
    if c.paired and c.test not in COMPARISONS:
        raise ValueError(f"{where}: paired=true needs a comparison test, not {c.test!r}")
    if c.metric not in METRIC_NAMES and c.metric not in METRICS:
        raise ValueError(f"{where}: metric={c.metric!r} is neither in uavform_env.metrics nor in {METRICS}")
    exp = next((e for e in EXPERIMENTS if e.id == c.experiment), None)
    if exp is None or c.setting not in {s.name for s in exp.settings}:
        raise ValueError(f"{where}: no setting {c.setting!r} in experiment {c.experiment!r}")
    return c


def load_claims(path=CLAIMS_FILE) -> tuple[Claim, ...]:
    """The claims of ``path``; every variant a check names must be one of its experiment's variants."""
    with open(path, "rb") as f:
        data = tomllib.load(f)
    claims = []
    for raw in data.get("claim", []):
        raw = dict(raw)
        checks = tuple(_check(raw.get("id", "?"), c) for c in raw.pop("checks"))
        claim = Claim(**{**raw, "readings": tuple(raw["readings"]), "checks": checks,
                         "aliases": tuple(sorted(raw.get("aliases", {}).items()))})
        for c in checks:
            names = {v.name for e in EXPERIMENTS if e.id == c.experiment for v in e.variants}
            for reading in claim.readings:
                for name in (claim.name(c.variant, reading), claim.name(c.baseline, reading)):
                    if name is not None and name not in names:
                        raise ValueError(f"claims.toml {claim.id}: variant {name!r} (reading {reading!r}) is not a "
                                         f"variant of {c.experiment}; expected one of {sorted(names)}")
        claims.append(claim)
    return tuple(claims)


def seed_values(records: list[dict], experiment: str, setting: str, variant: str, metric: str) -> dict[int, float]:
    """{seed: value} of the finished main runs (not the horizon checks) of one variant."""
    return {r["seed"]: float(r["metrics"][metric]) for r in records
            if r["experiment"] == experiment and r["setting"] == setting and r["variant"] == variant
            and r["status"] == "ok" and not r.get("horizon_check")}


def _stats(values: list[float]) -> dict:
    mean, lo, hi = bootstrap_ci(np.asarray(values, dtype=np.float64))
    return {"mean": mean, "ci_low": lo, "ci_high": hi, "n": int(np.isfinite(values).sum()) if values else 0}


def _fmt(s: dict) -> str:
    if s["n"] == 0 or not math.isfinite(s["mean"]):
        return "n/a (no finite value)"
    return f"{s['mean']:.3g} [{s['ci_low']:.3g}, {s['ci_high']:.3g}] (n = {s['n']})"


def evaluate_check(claim: Claim, check: Check, reading: str, records: list[dict]) -> dict:
    """One check under one reading: its figures, ``holds`` (None when the runs are missing) and a sentence."""
    variant, baseline = claim.name(check.variant, reading), claim.name(check.baseline, reading)
    a = seed_values(records, check.experiment, check.setting, variant, check.metric)
    out = {"what": check.what, "experiment": check.experiment, "setting": check.setting, "metric": check.metric,
           "test": check.test, "variant": variant, "baseline": baseline, "threshold": check.threshold,
           "paired": check.paired}
    if baseline is None:
        sa = _stats([a[k] for k in sorted(a)])
        out["value"] = sa
        holds = None
        if sa["n"] and math.isfinite(sa["mean"]):
            holds = sa["mean"] <= check.threshold if check.test == "at_most" else sa["mean"] >= check.threshold
        out["holds"] = holds
        out["text"] = (f"{check.what}: {variant} {check.metric} = {_fmt(sa)}, test {TESTS[check.test]} "
                       f"{check.threshold:g}: " + _word(holds))
        return out
    b = seed_values(records, check.experiment, check.setting, baseline, check.metric)
    seeds = sorted(set(a) & set(b))
    if check.paired:
        sa_ok = seed_values(records, check.experiment, check.setting, variant, "success")
        sb_ok = seed_values(records, check.experiment, check.setting, baseline, "success")
        seeds = [k for k in seeds if sa_ok.get(k) == 1.0 and sb_ok.get(k) == 1.0]
    sa, sb = _stats([a[k] for k in seeds]), _stats([b[k] for k in seeds])
    out.update(value=sa, baseline_value=sb, seeds=len(seeds))
    holds = None
    if seeds and sa["n"] and sb["n"] and math.isfinite(sa["mean"]) and math.isfinite(sb["mean"]):
        x, y, tol = sa["mean"], sb["mean"], check.tol
        holds = {"lower": x < y, "higher": x > y, "not_higher": x <= y + tol, "not_lower": x >= y - tol}[check.test]
    out["holds"] = holds
    scope = f"on the {len(seeds)} seeds both arrived on" if check.paired else f"over {len(seeds)} seeds"
    out["text"] = (f"{check.what}: {variant} {check.metric} = {_fmt(sa)} {TESTS[check.test]} {baseline} {_fmt(sb)} "
                   f"({scope}): " + _word(holds))
    return out


def _word(holds: bool | None) -> str:
    return "no runs to decide" if holds is None else "holds" if holds else "fails"


def outcome(records: list[dict], experiment: str, setting: str, variant: str) -> str:
    """A sentence of counts for one variant's main runs: arrived, collided, timed out, failed to run."""
    rs = [r for r in records if r["experiment"] == experiment and r["setting"] == setting
          and r["variant"] == variant and not r.get("horizon_check")]
    ok = [r for r in rs if r["status"] == "ok"]
    count = {k: sum(bool(r["metrics"][k]) for r in ok) for k in ("success", "collision", "timeout")}
    return (f"{variant} in {experiment} {setting}: {len(rs)} runs, arrived {count['success']}, collided "
            f"{count['collision']}, timed out {count['timeout']}" + (f", {len(rs) - len(ok)} failed to run"
                                                                     if len(ok) < len(rs) else ""))


def evaluate_claim(claim: Claim, records: list[dict]) -> dict:
    """Every check under every reading, the verdict per reading and the claim's verdict."""
    readings = []
    for reading in claim.readings:
        checks = [evaluate_check(claim, c, reading, records) for c in claim.checks]
        results = [c["holds"] for c in checks]
        verdict = FAILS if False in results else NOT_RUN if None in results else HOLDS
        failed = [c["what"] for c in checks if c["holds"] is False]
        variants = sorted({(c["experiment"], c["setting"], v) for c in checks for v in (c["variant"], c["baseline"])
                           if v is not None})
        why = (f"under {claim.reading_field} = {reading!r} every check holds" if verdict == HOLDS else
               f"under {claim.reading_field} = {reading!r} " + (
                   f"{len(failed)} of {len(checks)} checks fail: " + "; ".join(failed) if failed
                   else "some checks have no runs"))
        readings.append({"reading": reading, "verdict": verdict, "checks": checks, "why": why,
                         "outcomes": [outcome(records, *v) for v in variants]})
    holding = [r["reading"] for r in readings if r["verdict"] == HOLDS]
    if holding:
        verdict = HOLDS
    elif all(r["verdict"] == NOT_RUN for r in readings):
        verdict = NOT_RUN
    else:
        verdict = FAILS
    return {"id": claim.id, "source": claim.source, "statement": claim.statement, "conditions": claim.conditions,
            "reading_field": claim.reading_field, "readings": readings, "verdict": verdict,
            "reproduced_by": holding}


def evaluate(records: list[dict], claims: tuple[Claim, ...] | None = None) -> list[dict]:
    return [evaluate_claim(c, records) for c in (load_claims() if claims is None else claims)]
