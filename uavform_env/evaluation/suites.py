"""Benchmark suites: frozen, versioned lists of episodes with a content hash.

A suite is a TOML file (``suites/<name>.toml`` in this package, or any path) listing episodes as
``[[episode]]`` tables with ``scenario`` (a pinned ``name@version``), ``n_uavs``, ``formation``,
``seed``, ``max_cycles`` and optional ``difficulty``, ``spacing`` (m; default: the generator's) and
``disturbance`` (a preset name of ``config.DISTURBANCE_PRESETS``; default: calm). The hash covers exactly what decides an
episode's outcome (the episode list), so two result tables are comparable only if their hashes match;
the name and description are labels and stay out of it.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass
from functools import cached_property
from importlib import resources
from pathlib import Path

from ..config import EnvConfig, disturbance_preset
from ..scenarios import make_scenario, validate_scenario

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

_EPISODE_KEYS = ("scenario", "difficulty", "n_uavs", "formation", "spacing", "seed", "max_cycles", "disturbance")
_OPTIONAL_KEYS = ("spacing", "disturbance")  # absent (None) keys stay out of the hash and the key: v0 keeps both
_REQUIRED_KEYS = ("scenario", "n_uavs", "formation", "seed", "max_cycles")


@dataclass(frozen=True)
class Episode:
    """One benchmark episode: the scenario generator (pinned version), its mission overrides and the seed."""

    scenario: str
    n_uavs: int
    formation: str
    seed: int
    max_cycles: int
    difficulty: str | None = None
    spacing: float | None = None
    disturbance: str | None = None

    @property
    def key(self) -> str:
        """A stable identifier; results are matched to episodes by it on resume."""
        extra = (f"/sp{self.spacing:g}" if self.spacing is not None else "") + \
            (f"/{self.disturbance}" if self.disturbance is not None else "")
        return (f"{self.scenario}/{self.difficulty or '-'}/n{self.n_uavs}/{self.formation}"
                f"/s{self.seed}/c{self.max_cycles}{extra}")

    @property
    def family(self) -> str:
        """The scenario family without version or difficulty."""
        return self.scenario.partition("@")[0]

    @property
    def wind(self) -> str:
        """The disturbance preset's name (calm when the episode names none)."""
        return self.disturbance or "calm"

    @property
    def task(self) -> str:
        """The scenario family and difficulty tier without the version (a 'task' in marl-eval's terms)."""
        base = self.scenario.partition("@")[0]
        return f"{base}-{self.difficulty}" if self.difficulty else base

    def env_kwargs(self) -> dict:
        """Keyword arguments of ``formation_v0.parallel_env`` that build this episode's env."""
        kwargs = dict(scenario=self.scenario, n_uavs=self.n_uavs, formation=self.formation,
                      max_cycles=self.max_cycles)
        for name in ("difficulty", "spacing", "disturbance"):
            if getattr(self, name) is not None:
                kwargs[name] = getattr(self, name)
        return kwargs

    def to_dict(self) -> dict:
        return {k: v for k, v in asdict(self).items() if not (k in _OPTIONAL_KEYS and v is None)}


@dataclass(frozen=True)
class Suite:
    name: str
    description: str
    episodes: tuple[Episode, ...]

    @cached_property
    def hash(self) -> str:
        """SHA-256 (first 16 hex digits) of the canonical JSON of the episode list (worked out once: the suite is
        frozen)."""
        doc = json.dumps([e.to_dict() for e in self.episodes], sort_keys=True, separators=(",", ":"))
        return hashlib.sha256(doc.encode("utf-8")).hexdigest()[:16]

    def manifest(self) -> dict:
        return {"suite": self.name, "suite_hash": self.hash, "description": self.description,
                "episodes": [e.to_dict() for e in self.episodes]}


def list_suites() -> list[str]:
    """Names of the suites shipped with the package."""
    folder = resources.files(__package__) / "suites"
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".toml"))


def load_suite(name_or_path: str | Path) -> Suite:
    """A shipped suite by name (``list_suites()``) or a suite TOML file by path; every episode is validated."""
    if isinstance(name_or_path, Path) or str(name_or_path).endswith(".toml"):
        path = Path(name_or_path)
        if not path.is_file():
            raise ValueError(f"suite file {str(path)!r} not found")
        text, where = path.read_text(encoding="utf-8"), str(path)
    elif name_or_path in list_suites():
        text = (resources.files(__package__) / "suites" / f"{name_or_path}.toml").read_text(encoding="utf-8")
        where = f"suite {name_or_path!r}"
    else:
        raise ValueError(f"unknown suite {name_or_path!r}; known suites: {list_suites()} (or give a .toml path)")
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ValueError(f"{where}: not valid TOML ({e})") from e
    return _parse(doc, where)


def _parse(doc: dict, where: str) -> Suite:
    name = doc.get("name")
    if not isinstance(name, str) or not name:
        raise ValueError(f"{where}: expected a top-level 'name' string")
    entries = doc.get("episode")
    if not isinstance(entries, list) or not entries:
        raise ValueError(f"{where}: expected at least one [[episode]] table")
    env_cfg = EnvConfig()
    episodes = []
    for i, entry in enumerate(entries):
        here = f"{where}: episode {i}"
        unknown = sorted(set(entry) - set(_EPISODE_KEYS))
        missing = [k for k in _REQUIRED_KEYS if k not in entry]
        if unknown or missing:
            raise ValueError(f"{here}: unknown keys {unknown}, missing keys {missing}; allowed {list(_EPISODE_KEYS)}")
        if "@" not in str(entry["scenario"]):
            raise ValueError(f"{here}: scenario {entry['scenario']!r} must pin a generator version ('name@k'), "
                             "so the suite keeps meaning the same worlds")
        for key, lowest in (("n_uavs", 1), ("seed", 0), ("max_cycles", 1)):
            value = entry[key]
            if isinstance(value, bool) or not isinstance(value, int) or value < lowest:
                raise ValueError(f"{here}: {key}={value!r}: expected an integer >= {lowest}")
        spacing = entry.get("spacing")
        if spacing is not None and (isinstance(spacing, bool) or not isinstance(spacing, (int, float))):
            raise ValueError(f"{here}: spacing={spacing!r}: expected a number of metres")
        episode = Episode(**entry)
        try:
            if episode.disturbance is not None:
                disturbance_preset(episode.disturbance)
            scn = make_scenario(episode.scenario, episode.seed, n_uavs=episode.n_uavs, formation=episode.formation,
                                spacing=episode.spacing, difficulty=episode.difficulty)
            validate_scenario(scn, env_cfg.uav, env_cfg.formation.z_ref)
        except ValueError as e:
            raise ValueError(f"{here} ({episode.key}): {e}") from e
        episodes.append(episode)
    keys = [e.key for e in episodes]
    duplicates = sorted({k for k in keys if keys.count(k) > 1})
    if duplicates:
        raise ValueError(f"{where}: duplicate episodes {duplicates}")
    return Suite(name=name, description=str(doc.get("description", "")), episodes=tuple(episodes))


def suite_from_manifest(manifest: dict, where: str = "suite manifest") -> Suite:
    """The suite a results folder's ``suite.json`` records, checked against its stored hash."""
    try:
        suite = Suite(name=manifest["suite"], description=manifest.get("description", ""),
                      episodes=tuple(Episode(**e) for e in manifest["episodes"]))
    except (KeyError, TypeError) as e:
        raise ValueError(f"{where}: not a suite manifest ({e!r})") from e
    if suite.hash != manifest.get("suite_hash"):
        raise ValueError(f"{where}: its episodes hash to {suite.hash}, but it records {manifest.get('suite_hash')}; "
                         "the file was edited")
    return suite
