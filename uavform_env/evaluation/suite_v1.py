"""The recipe of suites v1 (the test split) and v1-dev (tuning and training): ``python -m uavform_env.evaluation.suite_v1``.

Both splits cross every task (scenario family and difficulty tier, newest generator versions) with
every disturbance preset, ``SEEDS_PER_CELL`` episodes each; the team (size, shape, spacing) of an
episode is what the generator draws for its seed, written out so the file states it. The splits
differ only in their seeds (``SPLITS``), which are disjoint from each other and from the seeds v0
and the expert's tuning used (below 100). The shipped TOML files are the frozen truth: this recipe
regenerates them exactly (a test checks it), and a changed recipe means new suite names.
"""

from __future__ import annotations

import argparse
from importlib import resources
from pathlib import Path

import tomli_w

from ..config import DISTURBANCE_PRESETS
from ..files import atomic_write_bytes
from ..scenarios import make_scenario

# (scenario, difficulty, max_cycles): the episode lengths leave a policy flying at half speed time to arrive
TASKS = (("classic-2d@2", "base", 600), ("classic-2d@2", "extended", 600), ("forest@2", None, 900),
         ("urban@2", None, 900), ("wall-gap@2", None, 900), ("corridor@2", None, 900),
         ("random-3d@2", "easy", 900), ("random-3d@2", "medium", 900), ("random-3d@2", "hard", 900),
         ("dog-leg@1", "easy", 900), ("dog-leg@1", "hard", 900))
SEEDS_PER_CELL = 7
SPLITS = {"v1": 100_000, "v1-dev": 200_000}  # first seed of each split
DESCRIPTIONS = {
    "v1": "Leaderboard suite v1, the test split: every task (family and difficulty, newest generator versions) "
          "under every disturbance preset, teams of 1 to 10 UAVs. Run once to report; never tune or train on it.",
    "v1-dev": "Development split of suite v1: the same recipe with disjoint seeds. Tune and train on this one.",
}


def episodes(split: str) -> list[dict]:
    """The split's episodes, in a fixed order: task, then disturbance preset, then seed."""
    seed = SPLITS[split]
    out = []
    for scenario, difficulty, max_cycles in TASKS:
        for disturbance in DISTURBANCE_PRESETS:
            for _ in range(SEEDS_PER_CELL):
                m = make_scenario(scenario, seed, difficulty=difficulty).mission
                entry = {"scenario": scenario, **({"difficulty": difficulty} if difficulty else {}),
                         "n_uavs": m.n_uavs, "formation": m.formation, "spacing": m.spacing, "seed": seed,
                         "max_cycles": max_cycles}
                if disturbance != "calm":
                    entry["disturbance"] = disturbance
                out.append(entry)
                seed += 1
    return out


def suite_toml(split: str) -> str:
    return tomli_w.dumps({"name": split, "description": DESCRIPTIONS[split], "episode": episodes(split)})


def shipped_path(split: str) -> Path:
    return Path(str(resources.files(__package__) / "suites" / f"{split}.toml"))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=None, help="folder to write v1.toml and v1-dev.toml (default: the package's)")
    args = parser.parse_args(argv)
    for split in SPLITS:
        path = shipped_path(split) if args.out is None else Path(args.out) / f"{split}.toml"
        atomic_write_bytes(path, suite_toml(split).encode("utf-8"))
        print(f"wrote {path} ({len(episodes(split))} episodes)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
