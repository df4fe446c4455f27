"""Is a change of the expert more than noise? Two sets of flights compared pair by pair (issue 13, tuning on v1-dev).

    python benchmarks/compare_flights.py BASE.jsonl [BASE2.jsonl ...] --against NEW.jsonl [NEW2.jsonl ...]

The files are the flight records of ``benchmarks/gust_seeds.py --out`` (one JSON line per flight: episode, wind,
outcome, steps, formation_error_rms), e.g. one file per disturbance preset on each side. A flight of one side is
paired with the flight of the other side that flew the same episode under the same wind seed; flights without a
partner are counted and left out. A change of the controller changes most flights somewhere (session 22: a 0.5 ->
0.3 m cap of one DWA term changed the steps of 62 of 77 calm flights), and a flight near the margin of its step
limit or of a gust's reach flips either way, so a count that moved by 2 out of 77 says little by itself.

Printed, per disturbance preset (the key's last field; calm keys have none) and in total:
- successes and flights with a collision on each side;
- the discordant pairs of each (b: the base side's only, c: the new side's only) and the exact two-sided McNemar
  p-value, min(1, 2 P(Binomial(b + c, 1/2) <= min(b, c))): the chance of a split at least this uneven if the
  change did nothing to these flights' outcomes (under 0.05: unlikely to be noise);
- the median over pairs of the change of the formation error's RMS, and the mean change of the steps of the
  flights both sides flew to success;
then each family's successes on both sides, and the flights whose outcome changed.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

from uavform_env.config import DISTURBANCE_PRESETS
from uavform_env.files import read_jsonl

REQUIRED = frozenset({"episode", "wind", "outcome", "steps", "formation_error_rms"})


def mcnemar_p(b: int, c: int) -> float:
    """Exact two-sided McNemar p-value of b against c discordant pairs (1 when there are none)."""
    n = b + c
    if n == 0:
        return 1.0
    tail = sum(math.comb(n, k) for k in range(min(b, c) + 1)) / 2.0 ** n
    return min(1.0, 2.0 * tail)


def preset_of(key: str) -> str:
    """The disturbance preset an episode key names in its last field ("calm" when it names none): read for records
    written before gust_seeds.py recorded ``Episode.wind`` as "preset" (session 23)."""
    last = key.rsplit("/", 1)[-1]
    return last if last in DISTURBANCE_PRESETS else "calm"


def load(paths: list[str]) -> dict:
    """The flights of ``paths`` by (episode, wind); a flight flown twice on one side raises ValueError."""
    flights = {}
    for path in paths:
        if not Path(path).is_file():
            raise ValueError(f"{path}: no such file")
        for r in read_jsonl(path, "flight record", REQUIRED):
            pair = (r["episode"], int(r["wind"]))
            if pair in flights:
                raise ValueError(f"{path}: episode {pair[0]} wind {pair[1]} appears twice on one side")
            r.setdefault("preset", preset_of(r["episode"]))
            r.setdefault("scenario", r["episode"].split("/", 1)[0])
            flights[pair] = r
    return flights


def compare(base: dict, new: dict) -> list[dict]:
    """One row per disturbance preset and a total row over the flights both sides flew."""
    groups = defaultdict(list)
    for pair in sorted(base.keys() & new.keys()):
        groups[base[pair]["preset"]].append(pair)
    order = [p for p in DISTURBANCE_PRESETS if p in groups]
    rows = []
    for name, pairs in [(p, groups[p]) for p in order] + [("all", [q for p in order for q in groups[p]])]:
        row = {"preset": name, "flights": len(pairs)}
        for what, test in (("success", lambda r: r["outcome"] == "success"),
                           ("collision", lambda r: r["outcome"].startswith("crash"))):
            a = np.array([test(base[q]) for q in pairs], dtype=bool)
            c = np.array([test(new[q]) for q in pairs], dtype=bool)
            only_base, only_new = int(np.sum(a & ~c)), int(np.sum(~a & c))
            row[what] = (int(a.sum()), int(c.sum()), only_base, only_new, mcnemar_p(only_base, only_new))
        rms = [new[q]["formation_error_rms"] - base[q]["formation_error_rms"] for q in pairs]
        rms = [d for d in rms if not math.isnan(d)]
        row["rms_change"] = float(np.median(rms)) if rms else math.nan
        both = [new[q]["steps"] - base[q]["steps"] for q in pairs
                if base[q]["outcome"] == new[q]["outcome"] == "success"]
        row["steps_change"] = float(np.mean(both)) if both else math.nan
        row["both_succeed"] = len(both)
        rows.append(row)
    return rows


def families(base: dict, new: dict) -> dict:
    """Successes per family (the episode's scenario) on each side: {family: [base, new, flights]}."""
    out = defaultdict(lambda: [0, 0, 0])
    for pair in base.keys() & new.keys():
        f = out[base[pair]["scenario"]]
        f[0] += base[pair]["outcome"] == "success"
        f[1] += new[pair]["outcome"] == "success"
        f[2] += 1
    return dict(sorted(out.items()))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("base", nargs="+", help="flight records of the base side (gust_seeds.py --out)")
    parser.add_argument("--against", nargs="+", required=True, help="flight records of the changed side")
    args = parser.parse_args(argv)
    try:
        base, new = load(args.base), load(args.against)
    except (OSError, ValueError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    common = base.keys() & new.keys()
    if not common:
        print("error: --against: no flight of these files flew the episode and wind of a base flight", file=sys.stderr)
        return 2
    unpaired = len(base.keys() ^ new.keys())
    print(f"{len(common)} paired flights" + (f" ({unpaired} without a partner, left out)" if unpaired else ""))
    print("| preset | flights | successes base -> new | base only / new only | p | collisions base -> new | "
          "base only / new only | p | formation RMS change, median (m) | steps change, both succeed (mean, n) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in compare(base, new):
        s, c = r["success"], r["collision"]
        print(f"| {r['preset']} | {r['flights']} | {s[0]} -> {s[1]} | {s[2]} / {s[3]} | {s[4]:.3f} | {c[0]} -> {c[1]} "
              f"| {c[2]} / {c[3]} | {c[4]:.3f} | {r['rms_change']:+.2f} | {r['steps_change']:+.1f} "
              f"({r['both_succeed']}) |")
    print("\n| family | successes base -> new (of flights) |\n|---|---|")
    for name, (b, n, total) in families(base, new).items():
        print(f"| {name} | {b} -> {n} ({total}) |")
    flips = sorted(q for q in common if base[q]["outcome"] != new[q]["outcome"])
    if flips:
        print("\noutcomes changed:")
        for q in flips:
            print(f"  {q[0]} wind {q[1]}: {base[q]['outcome']} -> {new[q]['outcome']}  {new[q].get('detail', '')[:90]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
