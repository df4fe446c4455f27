"""The verdict logic of reproduction v2 on constructed figures: every claim of claims.toml holds when all of its
checks hold, and fails when any single one of them fails, so each condition the statement names is tested."""

import pytest

from baselines.reproduce.claims import FAILS, HOLDS, NOT_RUN, Check, Claim, evaluate_claim, load_claims

CLAIMS = load_claims()
SEEDS = (0, 1, 2)
SHARES = ("success", "collision", "timeout", "reformed")


def _records(values: dict) -> list[dict]:
    """Records of three seeds with the constant figures ``values[(experiment, setting, variant)][metric]``."""
    out = []
    for (exp, setting, variant), metrics in values.items():
        for seed in SEEDS:
            out.append({"key": f"{exp}/{setting}/{variant}/{seed}", "experiment": exp, "setting": setting,
                        "variant": variant, "seed": seed, "status": "ok", "metrics": {"success": 1.0, "collision": 0.0, "timeout": 0.0, **metrics}})
    return out


def _nodes(claim: Claim, check: Check, reading: str):
    a = (check.experiment, check.setting, claim.name(check.variant, reading))
    b = None if check.baseline is None else (check.experiment, check.setting, claim.name(check.baseline, reading))
    return a, b


def _satisfy(claim: Claim, check: Check, reading: str, values: dict) -> None:
    """Change the figures so that ``check`` holds (the variant moves, the baseline stays unless a share forces it)."""
    a, b = _nodes(claim, check, reading)
    m = check.metric
    va = values.setdefault(a, {})
    vb = values.setdefault(b, {}) if b else None
    share = m in SHARES
    if check.test == "at_least":
        va[m] = 1.0 if share else check.threshold + 1.0
    elif check.test == "at_most":
        va[m] = check.threshold
    elif check.test in ("not_lower", "not_higher"):
        va[m] = vb.setdefault(m, 1.0 if share else 5.0)
    elif check.test == "higher":
        if share:
            va[m], vb[m] = 1.0, 0.0
        else:
            va[m] = vb.setdefault(m, 5.0) + 1.0
    else:  # lower
        if share:
            va[m], vb[m] = 0.0, 1.0
        else:
            va[m] = vb.setdefault(m, 5.0) - 1.0


def _holding_figures(claim: Claim, reading: str) -> dict:
    values: dict = {}
    for _ in range(10):                                    # a few sweeps settle checks that share a variant
        for check in claim.checks:
            _satisfy(claim, check, reading, values)
    return values


def _break(claim: Claim, check: Check, reading: str, values: dict) -> None:
    a, b = _nodes(claim, check, reading)
    m = check.metric
    if check.test in ("at_least", "at_most"):
        values[a][m] = check.threshold + (-1.0 if check.test == "at_least" else 1.0)
    elif check.test in ("lower", "not_higher"):
        values[a][m] = values[b][m] + 1.0
    else:
        values[a][m] = values[b][m] - 1.0


@pytest.mark.parametrize("claim", CLAIMS, ids=[c.id for c in CLAIMS])
def test_a_claim_holds_when_all_its_checks_hold_and_fails_with_any_one(claim):
    for reading in claim.readings:
        values = _holding_figures(claim, reading)
        result = evaluate_claim(claim, _records(values))
        per = {r["reading"]: r for r in result["readings"]}
        assert per[reading]["verdict"] == HOLDS, [c["text"] for c in per[reading]["checks"]]
        assert reading in result["reproduced_by"] and result["verdict"] == HOLDS
        for k, check in enumerate(claim.checks):
            broken = {node: dict(metrics) for node, metrics in values.items()}
            _break(claim, check, reading, broken)
            r = {x["reading"]: x for x in evaluate_claim(claim, _records(broken))["readings"]}[reading]
            assert r["checks"][k]["holds"] is False, (check.what, r["checks"][k]["text"])
            assert r["verdict"] == FAILS and check.what in r["why"]


def test_every_condition_the_statements_name_has_a_check():
    """The conditions the statements name, by claim: the metric (and comparison) each must test."""
    need = {
        "C1": {("near_goal_loops", "at_least"), ("near_goal_loops", "lower"), ("near_goal_dwell", "lower")},
        "C2": {("success", "not_lower"), ("path_length_leader", "lower"), ("flight_time", "lower"),
               ("iterations", "lower")},
        "C3": {("near_goal_loops", "at_least"), ("near_goal_loops", "at_most"), ("success", "higher")},
        "C5": {("yaw_jitter_per_metre", "lower"), ("success", "not_lower")},
        "C6": {("success", "higher"), ("collision", "at_most")},
        "C7": {("collision", "at_most"), ("success", "at_least"), ("reformed", "at_least")},
    }
    have = {c.id: {(k.metric, k.test) for k in c.checks} for c in CLAIMS}
    assert set(need) == set(have)
    for cid, conditions in need.items():
        assert conditions <= have[cid], (cid, conditions - have[cid])


def test_paired_comparisons_use_only_missions_both_arrived_on():
    claim = Claim("CX", "s", "x", "c", "r", ("a",), (Check("shorter", "E2", "dense", "path_length_leader",
                                                        "DWA+E8+E10/endpoint", "lower", "DWA+E8/endpoint",
                                                        paired=True),))
    fast, slow = ("E2", "dense", "DWA+E8+E10/endpoint"), ("E2", "dense", "DWA+E8/endpoint")
    records = _records({fast: {"path_length_leader": 10.0}, slow: {"path_length_leader": 12.0}})
    for r in records:                                     # seed 2: only the baseline arrives, on a short path
        if r["seed"] == 2 and r["variant"] == fast[2]:
            r["metrics"].update(success=0.0, path_length_leader=50.0)
        if r["seed"] == 2 and r["variant"] == slow[2]:
            r["metrics"]["path_length_leader"] = 1.0
    (check,) = evaluate_claim(claim, records)["readings"][0]["checks"]
    assert check["holds"] is True and check["seeds"] == 2
    assert check["value"]["mean"] == 10.0 and check["baseline_value"]["mean"] == 12.0


def test_missing_runs_leave_a_claim_undecided_not_held():
    claim = CLAIMS[0]
    result = evaluate_claim(claim, [])
    assert result["verdict"] == NOT_RUN and not result["reproduced_by"]


@pytest.mark.parametrize("text, match", [
    ('[[claim]]\nid="C9"\nsource="s"\nstatement="x"\nconditions="c"\nreading_field="r"\nreadings=["a"]\n'
     'checks=[{what="w", experiment="E1", setting="classic", metric="success", variant="nope", test="at_least", '
     'threshold=1.0}]\n', "variant 'nope'"),
    ('[[claim]]\nid="C9"\nsource="s"\nstatement="x"\nconditions="c"\nreading_field="r"\nreadings=["a"]\n'
     'checks=[{what="w", experiment="E1", setting="classic", metric="success", variant="DWA/endpoint", '
     'test="at_least"}]\n', "threshold"),
    ('[[claim]]\nid="C9"\nsource="s"\nstatement="x"\nconditions="c"\nreading_field="r"\nreadings=["a"]\n'
     'checks=[{what="w", experiment="E1", setting="classic", metric="speed", variant="DWA/endpoint", '
     'test="at_least", threshold=1.0}]\n', "metric='speed'"),
])
def test_a_broken_claims_file_is_refused_with_its_claim_named(tmp_path, text, match):
    path = tmp_path / "claims.toml"
    path.write_text(text)
    with pytest.raises(ValueError, match=match):
        load_claims(path)
