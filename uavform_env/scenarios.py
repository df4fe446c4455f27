"""Named, versioned, seeded scenarios (an obstacle field plus a formation mission) and their TOML files.

A scenario is plain data: frozen, hashable, and it survives a TOML round trip exactly, so a result can
always name the world it came from. ``"forest"`` is the newest generator of that name, ``"forest@1"``
pins version 1; a generator whose output changes gets a new version and the old one stays.

Every generator is deterministic in its seed and feasible by construction: obstacle footprints,
inflated by the default UAV's r_uav + r_safe, never touch each other, and streets, the corridor and
the wall's gap stay open, so one UAV can always get from start to goal; start and goal keep every
slot of the requested formation clear.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Callable

import numba
import numpy as np
import tomli_w

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

from .config import (FORMATION_SHAPES, SLOT_ALTITUDES, DisturbanceConfig, FormationConfig, UAVLimits,
                     disturbance_preset)
from .files import atomic_write_bytes
from .formation import MAX_UAVS, formation_slots, slot_offsets, slot_positions
from .world import Box, Cylinder, Sphere, World, as_finite, as_finite_vector, as_positive, check_world_bounds

# Generators design for the default vehicle and formation altitude (the config is the one source of truth).
_LIMITS = UAVLimits()
_Z_REF = FormationConfig().z_ref
GRID_RESOLUTION = 0.2  # m: voxel grid of every generated world (the ground truth; the onboard maps' by default)
_DEFAULT_N_UAVS = 5  # spec Appendix A: N = 5, wedge, s = 2.0 (shape and spacing come from FormationConfig)
_R_CLEAR = _LIMITS.r_uav + _LIMITS.r_safe  # the clearance validate_scenario demands
_ZONE_RADIUS = _R_CLEAR + 1.0  # obstacle footprints keep this far from every start and goal slot
_CEILING = _LIMITS.z_max + 2.0  # world top; "tall" obstacles reach it, so nothing flies over them in the band
_FLYOVER_TOP = _LIMITS.z_max - (2.0 * _R_CLEAR + 1.0)  # highest "low" top: passable above with 1 m to spare
_FIELD = (40.0, 30.0)  # nominal x, y extent of the generated fields; bounds grow to hold wide formations
_START_X, _GOAL_X, _Y_JITTER = 3.0, 37.0, 3.0


class ScenarioFileError(ValueError):
    """A scenario file that cannot be read; the message names the file, the entry and the problem."""


@dataclass(frozen=True)
class Mission:
    """Fly the leader (UAV 0) from ``start`` to ``goal``; followers start on their formation slots.

    ``slot_altitude`` places the followers' slots at FormationConfig.z_ref ("z_ref", version-1
    missions and files without the key) or at the leader's altitude ("leader", missions whose start
    and goal lie at other altitudes); see ``formation.formation_slots``.
    """

    start: tuple[float, float, float]
    goal: tuple[float, float, float]
    start_heading: float
    formation: str
    spacing: float
    n_uavs: int
    slot_altitude: str = "z_ref"

    def __post_init__(self):
        object.__setattr__(self, "start", as_finite_vector("Mission", "start", self.start, 3))
        object.__setattr__(self, "goal", as_finite_vector("Mission", "goal", self.goal, 3))
        object.__setattr__(self, "start_heading", as_finite("Mission", "start_heading", self.start_heading))
        if self.formation not in FORMATION_SHAPES:
            raise ValueError(f"Mission.formation={self.formation!r}: expected one of {list(FORMATION_SHAPES)}")
        object.__setattr__(self, "spacing", as_positive("Mission", "spacing", self.spacing))
        if isinstance(self.n_uavs, bool) or not isinstance(self.n_uavs, (int, np.integer)) or self.n_uavs < 1:
            raise ValueError(f"Mission.n_uavs={self.n_uavs!r}: expected an integer >= 1")
        object.__setattr__(self, "n_uavs", int(self.n_uavs))
        if self.slot_altitude not in SLOT_ALTITUDES:
            raise ValueError(f"Mission.slot_altitude={self.slot_altitude!r}: expected one of {list(SLOT_ALTITUDES)}")


@dataclass(frozen=True)
class Scenario:
    """A world (bounds, voxel resolution, obstacles) and a mission; ``seed`` records the generator's seed.

    ``disturbance`` is the wind and sensor faults a scenario file asks for (its ``[disturbance]``
    table); None leaves the env's own (``EnvConfig.disturbance``).
    """

    name: str
    version: int
    seed: int | None
    bounds_lo: tuple[float, float, float]
    bounds_hi: tuple[float, float, float]
    resolution: float
    obstacles: tuple
    mission: Mission
    disturbance: DisturbanceConfig | None = None

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name.strip():
            raise ValueError(f"Scenario.name={self.name!r}: expected a non-empty string")
        if isinstance(self.version, bool) or not isinstance(self.version, (int, np.integer)) or self.version < 1:
            raise ValueError(f"Scenario.version={self.version!r}: expected an integer >= 1")
        object.__setattr__(self, "version", int(self.version))
        if self.seed is not None:
            if isinstance(self.seed, bool) or not isinstance(self.seed, (int, np.integer)) or self.seed < 0:
                raise ValueError(f"Scenario.seed={self.seed!r}: expected None or an integer >= 0")
            object.__setattr__(self, "seed", int(self.seed))
        lo, hi, res = check_world_bounds(self.bounds_lo, self.bounds_hi, self.resolution)
        object.__setattr__(self, "bounds_lo", lo)
        object.__setattr__(self, "bounds_hi", hi)
        object.__setattr__(self, "resolution", res)
        object.__setattr__(self, "obstacles", tuple(self.obstacles))
        for i, ob in enumerate(self.obstacles):
            if not isinstance(ob, (Box, Cylinder, Sphere)):
                raise ValueError(f"Scenario.obstacles[{i}]={ob!r}: expected a Box, Cylinder or Sphere")
        if not isinstance(self.mission, Mission):
            raise ValueError(f"Scenario.mission: expected a Mission, got {type(self.mission).__name__}")
        if self.disturbance is not None and not isinstance(self.disturbance, DisturbanceConfig):
            raise ValueError(f"Scenario.disturbance: expected None or a DisturbanceConfig, "
                             f"got {type(self.disturbance).__name__}")

    def build_world(self) -> World:
        return World(self.bounds_lo, self.bounds_hi, self.resolution, self.obstacles)

    def with_mission(self, **changes) -> Scenario:
        """The same world with mission fields replaced, e.g. ``with_mission(n_uavs=3, formation="triangle")``."""
        known = [f.name for f in fields(Mission)]
        unknown = sorted(set(changes) - set(known))
        if unknown:
            raise ValueError(f"Scenario.with_mission: unknown field(s) {unknown}; allowed {known}")
        return replace(self, mission=replace(self.mission, **changes))

    def to_toml(self, path) -> None:
        """Write the scenario as commented TOML (temporary file + rename, so readers never see half a file)."""
        atomic_write_bytes(path, commented_toml(self).encode("utf-8"))

    @classmethod
    def from_toml(cls, path) -> Scenario:
        """Read a scenario file; a malformed one raises ``ScenarioFileError``."""
        path = Path(path)
        try:
            with open(path, "rb") as f:
                document = tomllib.load(f)
        except tomllib.TOMLDecodeError as exc:
            raise ScenarioFileError(f"{path}: TOML syntax error: {exc}") from None
        except UnicodeDecodeError as exc:
            raise ScenarioFileError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
        return _from_document(document, path)


# ---------------------------------------------------------------------------------------------- TOML

_OBSTACLE_KEYS = {"box": ("lo", "hi"), "cylinder": ("center", "radius", "z_lo", "z_hi"), "sphere": ("center", "radius")}
_MISSION_KEYS = tuple(f.name for f in fields(Mission) if f.name != "slot_altitude")
_DISTURBANCE_KEYS = tuple(f.name for f in fields(DisturbanceConfig))


def _obstacle_entry(ob) -> dict:
    if isinstance(ob, Box):
        return {"type": "box", "lo": list(ob.lo), "hi": list(ob.hi)}
    if isinstance(ob, Cylinder):
        return {"type": "cylinder", "center": [ob.x, ob.y], "radius": ob.radius, "z_lo": ob.z_lo, "z_hi": ob.z_hi}
    return {"type": "sphere", "center": [ob.x, ob.y, ob.z], "radius": ob.radius}


def _to_document(scn: Scenario) -> dict:
    m = scn.mission
    head = {"name": scn.name, "version": scn.version, **({} if scn.seed is None else {"seed": scn.seed})}
    mission = {"start": list(m.start), "goal": list(m.goal), "start_heading": m.start_heading,
               "formation": m.formation, "spacing": m.spacing, "n_uavs": m.n_uavs}
    if m.slot_altitude != "z_ref":  # files without the key keep version 1's slots at z_ref
        mission["slot_altitude"] = m.slot_altitude
    doc = {"scenario": head,
           "world": {"bounds_lo": list(scn.bounds_lo), "bounds_hi": list(scn.bounds_hi), "resolution": scn.resolution},
           "obstacles": [_obstacle_entry(ob) for ob in scn.obstacles], "mission": mission}
    if scn.disturbance is not None:
        doc["disturbance"] = scn.disturbance.to_dict()
    return doc


# What each table and key of a scenario file means, written as comments by ``commented_toml``.
_FILE_HEADER = """\
# uavform scenario file: one fixed world and one mission.
# Fly it with `uavform fly --scenario THIS.toml`, or in Python `parallel_env(scenario="THIS.toml")`.
# Units: lengths and positions in metres, angles in radians; x, y horizontal, z up from the ground (z = 0).
"""
_TABLE_NOTES = {
    "scenario": "Where this file came from: informational when loading (the file is always this one world).",
    "world": "The box the UAVs fly in and the voxel size of its occupancy grid.",
    "mission": "The leader (uav_0) flies from start to goal; followers start on their formation slots.",
    "disturbance": "Wind and range-sensor faults (optional): a `preset` name and/or any field below.",
    "obstacles": "Solid obstacles, one [[obstacles]] table each, of three types:\n"
                 "  box:      lo = [x, y, z] and hi = [x, y, z], opposite corners (m)\n"
                 "  cylinder: center = [x, y], radius, from z_lo up to z_hi (m), vertical\n"
                 "  sphere:   center = [x, y, z], radius (m)",
}
_KEY_NOTES = {
    "scenario": {"name": "generator name", "version": "generator version (name@version)",
                 "seed": "generator seed that made this layout"},
    "world": {"bounds_lo": "lowest corner [x, y, z] (m); z starts at the ground, 0",
              "bounds_hi": "highest corner [x, y, z] (m); leaving the x/y bounds is a crash",
              "resolution": "voxel edge (m) of the ground-truth grid, and of the UAVs' maps unless "
                            "MapConfig.resolution is set"},
    "mission": {"start": "leader's start [x, y, z] (m); followers start on their slots (see slot_altitude)",
                "goal": "leader's goal [x, y, z] (m)", "start_heading": "initial yaw of every UAV (rad, 0 = +x)",
                "formation": f"formation shape: {' | '.join(FORMATION_SHAPES)}",
                "spacing": "distance between neighbouring formation slots (m)",
                "n_uavs": "number of UAVs, uav_0 (the leader) .. uav_{N-1}",
                "slot_altitude": "followers' slot altitude: z_ref (fixed) | leader (the leader's altitude)"},
    "disturbance": {"wind_std": "gust strength, std per axis (m/s)", "wind_tau": "gust correlation time (s)",
                    "wind_length": "gust correlation length (m)", "wind_vertical": "vertical gusts / horizontal",
                    "wind_mean": "steady wind [x, y] (m/s)", "range_noise_std": "range noise, std (m)",
                    "ray_dropout": "probability that a ray returns nothing"},
}


def _toml_value(value) -> str:
    """One TOML value on one line (tomli_w's exact number format; its arrays would span several lines)."""
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    return tomli_w.dumps({"v": value})[len("v = "):].rstrip("\n")


def commented_toml(scn: Scenario) -> str:
    """The scenario file text: the same document ``from_toml`` reads, each table and key with a comment."""
    doc = _to_document(scn)
    lines = _FILE_HEADER.splitlines()
    for table in ("scenario", "world", "mission", "disturbance"):
        if table not in doc:
            continue
        lines += ["", *(f"# {line}" for line in _TABLE_NOTES[table].splitlines()), f"[{table}]"]
        width = max(len(f"{k} = {_toml_value(v)}") for k, v in doc[table].items())
        lines += [f"{f'{k} = {_toml_value(v)}':<{width}}  # {_KEY_NOTES[table][k]}" for k, v in doc[table].items()]
    lines += ["", *(f"# {line}" for line in _TABLE_NOTES["obstacles"].splitlines())]
    if not doc["obstacles"]:
        lines.append("# (none: an empty world)")
    for ob in doc["obstacles"]:
        lines += ["[[obstacles]]", *(f"{k} = {_toml_value(v)}" for k, v in ob.items()), ""]
    return "\n".join(lines).rstrip("\n") + "\n"


class _Reader:
    """Typed access to a parsed TOML document; every error names the file and the entry."""

    def __init__(self, path: Path):
        self.path = path

    def fail(self, entry: str, problem: str):
        raise ScenarioFileError(f"{self.path}: {entry}: {problem}")

    def keys(self, table, entry: str, required: tuple[str, ...], optional: tuple[str, ...] = ()) -> dict:
        if not isinstance(table, dict):
            self.fail(entry, f"expected a table, got {type(table).__name__}")
        for key in required:
            if key not in table:
                self.fail(entry, f"missing key {key!r}")
        unknown = sorted(set(table) - set(required) - set(optional))
        if unknown:
            self.fail(entry, f"unknown key(s) {unknown}; allowed: {', '.join(required + optional)}")
        return table

    def number(self, value, entry: str) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            self.fail(entry, f"expected a number, got {type(value).__name__} {value!r}")
        return float(value)

    def integer(self, value, entry: str) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            self.fail(entry, f"expected an integer, got {type(value).__name__} {value!r}")
        return value

    def string(self, value, entry: str) -> str:
        if not isinstance(value, str):
            self.fail(entry, f"expected a string, got {type(value).__name__} {value!r}")
        return value

    def vector(self, value, n: int, entry: str) -> tuple[float, ...]:
        if not isinstance(value, list):
            self.fail(entry, f"expected a list of {n} numbers, got {type(value).__name__} {value!r}")
        if len(value) != n:
            self.fail(entry, f"expected a list of {n} numbers, got {len(value)}")
        return tuple(self.number(v, f"{entry}[{i}]") for i, v in enumerate(value))

    def build(self, entry: str, make: Callable, *args, **kwargs):
        """Construct a validated object; its ValueError (range, ordering) is re-raised naming the entry."""
        try:
            return make(*args, **kwargs)
        except ValueError as exc:
            self.fail(entry, str(exc))

    def obstacle(self, table, i: int):
        entry = f"obstacles[{i}]"
        if not isinstance(table, dict):
            self.fail(entry, f"expected a table, got {type(table).__name__}")
        if "type" not in table:
            self.fail(entry, "missing key 'type'")
        kind = self.string(table["type"], f"{entry}.type")
        if kind not in _OBSTACLE_KEYS:
            self.fail(f"{entry}.type", f"unknown obstacle type {kind!r}; expected one of {', '.join(_OBSTACLE_KEYS)}")
        self.keys(table, entry, ("type",) + _OBSTACLE_KEYS[kind])
        if kind == "box":
            return self.build(entry, Box, self.vector(table["lo"], 3, f"{entry}.lo"),
                              self.vector(table["hi"], 3, f"{entry}.hi"))
        radius = self.number(table["radius"], f"{entry}.radius")
        if kind == "cylinder":
            x, y = self.vector(table["center"], 2, f"{entry}.center")
            return self.build(entry, Cylinder, x, y, radius, self.number(table["z_lo"], f"{entry}.z_lo"),
                              self.number(table["z_hi"], f"{entry}.z_hi"))
        return self.build(entry, Sphere, *self.vector(table["center"], 3, f"{entry}.center"), radius)


def _from_document(doc: dict, path: Path) -> Scenario:
    r = _Reader(path)
    r.keys(doc, "top level", ("scenario", "world", "mission"), ("obstacles", "disturbance"))
    head = r.keys(doc["scenario"], "[scenario]", ("name", "version"), ("seed",))
    world = r.keys(doc["world"], "[world]", ("bounds_lo", "bounds_hi", "resolution"))
    mission = r.keys(doc["mission"], "[mission]", _MISSION_KEYS, ("slot_altitude",))
    obstacles = doc.get("obstacles", [])
    if not isinstance(obstacles, list):
        r.fail("obstacles", f"expected an array of tables ([[obstacles]]), got {type(obstacles).__name__}")
    bounds = r.build("[world]", check_world_bounds, r.vector(world["bounds_lo"], 3, "[world].bounds_lo"),
                     r.vector(world["bounds_hi"], 3, "[world].bounds_hi"),
                     r.number(world["resolution"], "[world].resolution"))
    m = r.build("[mission]", Mission, start=r.vector(mission["start"], 3, "[mission].start"),
                goal=r.vector(mission["goal"], 3, "[mission].goal"),
                start_heading=r.number(mission["start_heading"], "[mission].start_heading"),
                formation=r.string(mission["formation"], "[mission].formation"),
                spacing=r.number(mission["spacing"], "[mission].spacing"),
                n_uavs=r.integer(mission["n_uavs"], "[mission].n_uavs"),
                slot_altitude=r.string(mission.get("slot_altitude", "z_ref"), "[mission].slot_altitude"))
    disturbance = _disturbance(r, doc["disturbance"]) if "disturbance" in doc else None
    seed = r.integer(head["seed"], "[scenario].seed") if "seed" in head else None
    return r.build("[scenario]", Scenario, name=r.string(head["name"], "[scenario].name"),
                   version=r.integer(head["version"], "[scenario].version"), seed=seed, bounds_lo=bounds[0],
                   bounds_hi=bounds[1], resolution=bounds[2],
                   obstacles=tuple(r.obstacle(t, i) for i, t in enumerate(obstacles)), mission=m,
                   disturbance=disturbance)


def _disturbance(r: _Reader, table) -> DisturbanceConfig:
    """``[disturbance]``: an optional ``preset`` name, then any DisturbanceConfig field overriding it."""
    r.keys(table, "[disturbance]", (), ("preset",) + _DISTURBANCE_KEYS)
    base = r.build("[disturbance].preset", disturbance_preset,
                   r.string(table["preset"], "[disturbance].preset")) if "preset" in table else DisturbanceConfig()
    changes = {}
    for key in _DISTURBANCE_KEYS:
        if key in table:
            where = f"[disturbance].{key}"
            changes[key] = (r.vector(table[key], 2, where) if key == "wind_mean" else r.number(table[key], where))
    return r.build("[disturbance]", base.replace, **changes)


# ---------------------------------------------------------------------------------------------- generators

@dataclass(frozen=True)
class _Layout:
    """Start, goal and bounds of a generated field, and the room the formation needs at both ends."""

    mission: Mission
    bounds_lo: tuple[float, float, float]
    bounds_hi: tuple[float, float, float]
    keep_out: np.ndarray  # (m, 2) start and goal slots; obstacle footprints stay _ZONE_RADIUS away
    field: tuple[float, float]  # x-range between the start and goal zones, free for structures (layouts along +x)


def _layout(rng, n_uavs: int, formation: str, spacing: float, min_field: float = 0.0, goal_x: float = _GOAL_X,
            z: tuple[float, float] = (_Z_REF, _Z_REF), slot_altitude: str = "z_ref") -> _Layout:
    """Start near x = 3 and goal near x = ``goal_x`` (y jittered), the formation facing the goal at both ends;
    the goal moves further out when the field between the two zones would be shorter than ``min_field``.
    ``z`` holds the start's and the goal's altitude."""
    offsets = slot_offsets(formation, n_uavs, spacing)
    reach = float(np.hypot(offsets[:, 0], offsets[:, 1]).max())
    start = np.array([_START_X, _FIELD[1] / 2 + rng.uniform(-_Y_JITTER, _Y_JITTER)])
    goal_y = _FIELD[1] / 2 + rng.uniform(-_Y_JITTER, _Y_JITTER)
    start_zone_front = start[0] + reach + _ZONE_RADIUS  # whatever the heading
    goal = np.array([max(goal_x, start_zone_front + min_field + reach + _ZONE_RADIUS), goal_y])
    heading = math.atan2(goal[1] - start[1], goal[0] - start[0])
    start_slots = slot_positions(start, heading, offsets, _Z_REF)[:, :2]
    goal_slots = slot_positions(goal, heading, offsets, _Z_REF)[:, :2]
    keep_out = np.vstack([start_slots, goal_slots])
    lo = np.floor(np.minimum(0.0, keep_out.min(axis=0) - _ZONE_RADIUS))
    hi = np.ceil(np.maximum(_FIELD, keep_out.max(axis=0) + _ZONE_RADIUS))
    mission = Mission(start=(start[0], start[1], z[0]), goal=(goal[0], goal[1], z[1]), start_heading=heading,
                      formation=formation, spacing=spacing, n_uavs=n_uavs, slot_altitude=slot_altitude)
    return _Layout(mission, (lo[0], lo[1], 0.0), (hi[0], hi[1], _CEILING), keep_out,
                   (start_slots[:, 0].max() + _ZONE_RADIUS, goal_slots[:, 0].min() - _ZONE_RADIUS))


def _disc_distance(centres: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Distance (n,) from each centre (n, 2) to the nearest point (m, 2)."""
    return np.hypot(centres[:, None, 0] - points[None, :, 0], centres[:, None, 1] - points[None, :, 1]).min(axis=1)


def _scatter(rng, layout: _Layout, count: int, radius_range: tuple[float, float], gap: float):
    """Centres (k, 2) and footprint radii (k,) of up to ``count`` random discs (dart throwing).

    Any two discs stay 2 (r_uav + r_safe) + ``gap`` apart, so their inflated footprints are disjoint and
    the free space at flight altitude stays connected: one UAV can always pass between them.
    """
    tries = 30 * count
    centres = rng.uniform(layout.bounds_lo[:2], layout.bounds_hi[:2], (tries, 2))
    radii = rng.uniform(*radius_range, tries)
    clear_of_zones = _disc_distance(centres, layout.keep_out) - radii >= _ZONE_RADIUS
    kept_c, kept_r = np.empty((count, 2)), np.empty(count)
    k = 0
    for c, r in zip(centres[clear_of_zones], radii[clear_of_zones]):
        if k == count:
            break
        if np.all(np.hypot(kept_c[:k, 0] - c[0], kept_c[:k, 1] - c[1]) - kept_r[:k] - r >= 2 * _R_CLEAR + gap):
            kept_c[k], kept_r[k] = c, r
            k += 1
    return kept_c[:k], kept_r[:k]


def _middle(rng, field: tuple[float, float], length: float) -> float:
    """Random start x of a structure of this length in the middle half of the field (inside the field)."""
    lo, hi = field[0], field[1] - length
    return rng.uniform(lo + 0.25 * (hi - lo), hi - 0.25 * (hi - lo))


def _tops(rng, n: int, tall_fraction: float) -> np.ndarray:
    """Obstacle tops: tall ones reach the world top, the others are low enough to fly over."""
    low_tops = rng.uniform(1.5, _FLYOVER_TOP, n)
    return np.where(rng.random(n) < tall_fraction, _CEILING, low_tops)


# The classic MATLAB DWA map (spec (h2) E1): disc obstacles of radius 0.5 m, start (0, 0) heading pi/2, goal (10, 10).
_CLASSIC_DISCS = ((0, 2), (4, 2), (4, 4), (5, 4), (5, 5), (5, 6), (5, 9), (8, 8), (8, 9), (7, 9))
_CLASSIC_EXTRA_DISCS = ((6, 5), (6, 3), (6, 8), (6, 7), (7, 4), (9, 8), (9, 11), (9, 6))
_CLASSIC_DISC_RADIUS = 0.5


def _classic_2d(rng, n_uavs, formation, spacing, difficulty):
    """The discs as columns through the whole world; the bounds hold the map plus the start slots."""
    start, goal, heading = np.array([0.0, 0.0]), (10.0, 10.0, _Z_REF), math.pi / 2
    slots = slot_positions(start, heading, slot_offsets(formation, n_uavs, spacing), _Z_REF)[:, :2]
    lo = np.floor(np.minimum(-2.0, slots.min(axis=0) - _ZONE_RADIUS))
    hi = np.ceil(np.maximum(12.0, slots.max(axis=0) + _ZONE_RADIUS))
    discs = _CLASSIC_DISCS + (_CLASSIC_EXTRA_DISCS if difficulty == "extended" else ())
    obstacles = [Cylinder(x, y, _CLASSIC_DISC_RADIUS, 0.0, _CEILING) for x, y in discs]
    mission = Mission(start=(0.0, 0.0, _Z_REF), goal=goal, start_heading=heading, formation=formation,
                      spacing=spacing, n_uavs=n_uavs)
    return (lo[0], lo[1], 0.0), (hi[0], hi[1], _CEILING), obstacles, mission


def _forest(rng, n_uavs, formation, spacing, difficulty):
    """Trees of radius 0.3-0.8 m at least 2 m apart (surface to surface); about 30 % can be flown over."""
    layout = _layout(rng, n_uavs, formation, spacing)
    centres, radii = _scatter(rng, layout, count=60, radius_range=(0.3, 0.8), gap=1.0)
    tops = _tops(rng, len(radii), tall_fraction=0.7)
    obstacles = [Cylinder(x, y, r, 0.0, top) for (x, y), r, top in zip(centres, radii, tops)]
    return layout.bounds_lo, layout.bounds_hi, obstacles, layout.mission


_STREET_WIDTH = 3.5  # >= 2 (r_uav + r_safe) + 2 m: every street is a passage


def _urban(rng, n_uavs, formation, spacing, difficulty):
    """Buildings on a block grid with 3.5 m streets; heights vary, about 40 % can be flown over."""
    return _blocks(rng, _layout(rng, n_uavs, formation, spacing))


def _blocks(rng, layout: _Layout):
    """Buildings on a block grid over the layout's bounds, clear of its start and goal zones."""
    lo, hi = np.array(layout.bounds_lo[:2]), np.array(layout.bounds_hi[:2])
    block = rng.uniform(4.0, 6.0)
    pitch = block + _STREET_WIDTH
    first = lo - rng.uniform(0.0, pitch, 2)
    ix, iy = np.meshgrid(*(np.arange(math.ceil((h - f) / pitch)) for f, h in zip(first, hi)), indexing="ij")
    corners = first + pitch * np.stack([ix.ravel(), iy.ravel()], axis=1)
    n = len(corners)
    setbacks = rng.uniform(0.0, 1.0, (n, 4))  # west, south, east, north
    foot_lo = corners + setbacks[:, :2]
    foot_hi = corners + block - setbacks[:, 2:]
    present = rng.random(n) < 0.8
    tops = _tops(rng, n, tall_fraction=0.6)
    outside = np.maximum(0.0, np.maximum(foot_lo[:, None] - layout.keep_out[None],
                                         layout.keep_out[None] - foot_hi[:, None]))
    zone_gap = np.hypot(outside[..., 0], outside[..., 1]).min(axis=1)  # footprint to the nearest start/goal slot
    keep = present & (zone_gap >= _ZONE_RADIUS) & np.all(foot_hi > lo, axis=1) & np.all(foot_lo < hi, axis=1)
    obstacles = [Box((a[0], a[1], 0.0), (b[0], b[1], top))
                 for a, b, top in zip(foot_lo[keep], foot_hi[keep], tops[keep])]
    return layout.bounds_lo, layout.bounds_hi, obstacles, layout.mission


_GAP_MIN_HEIGHT = 2.0  # the wall's gap is at least this tall ...
_GAP_OFFSET = 0.5  # ... and its near edge lies at least this far beyond z_ref, so level flight hits the wall


def _wall_gap(rng, n_uavs, formation, spacing, difficulty):
    """A wall across the whole width, from the ground to the world top except one horizontal gap above or
    below z_ref (the seed picks which): 2D avoidance at z_ref cannot pass, climbing or descending can."""
    return _gap_wall(rng, _layout(rng, n_uavs, formation, spacing, min_field=3.0), _Z_REF)


def _gap_wall(rng, layout: _Layout, z_level: float):
    """The wall across the layout's field with one gap above or below ``z_level`` (the seed picks which)."""
    thickness, heights, rise = rng.uniform(0.3, 1.0), rng.uniform(_GAP_MIN_HEIGHT, 3.0, 2), rng.uniform(0.0, 1.0)
    above_lo = z_level + _GAP_OFFSET + rise
    above = (above_lo, min(above_lo + heights[0], _LIMITS.z_max))
    below_hi = z_level - _GAP_OFFSET
    below = (max(_LIMITS.z_min, below_hi - heights[1]), below_hi)
    options = [g for g in (above, below) if g[1] - g[0] >= _GAP_MIN_HEIGHT]
    if not options:
        raise ValueError(f"wall-gap: no gap of {_GAP_MIN_HEIGHT} m fits above or below z={z_level} "
                         f"inside the altitude band [{_LIMITS.z_min}, {_LIMITS.z_max}]")
    gap_lo, gap_hi = options[int(rng.integers(len(options)))]
    x = _middle(rng, layout.field, thickness)
    y_lo, y_hi = layout.bounds_lo[1] - 1.0, layout.bounds_hi[1] + 1.0
    obstacles = [Box((x, y_lo, 0.0), (x + thickness, y_hi, gap_lo)),
                 Box((x, y_lo, gap_hi), (x + thickness, y_hi, _CEILING))]
    return layout.bounds_lo, layout.bounds_hi, obstacles, layout.mission


_CORRIDOR_WIDTH = (2.5, 3.5)  # narrower than the 8 m default wedge, wide enough for one UAV (>= 2 * 0.5 m)
_CORRIDOR_LENGTH = (10.0, 14.0)


def _corridor(rng, n_uavs, formation, spacing, difficulty):
    """Two walls through the whole world height that fill the width except a straight corridor."""
    return _corridor_walls(rng, _layout(rng, n_uavs, formation, spacing, min_field=_CORRIDOR_LENGTH[1] + 2.0))


def _corridor_walls(rng, layout: _Layout):
    """The two walls of a straight corridor across the layout's field."""
    width, length = rng.uniform(*_CORRIDOR_WIDTH), rng.uniform(*_CORRIDOR_LENGTH)
    x = _middle(rng, layout.field, length)
    y = _FIELD[1] / 2 + rng.uniform(-2.0, 2.0)
    y_lo, y_hi = layout.bounds_lo[1] - 1.0, layout.bounds_hi[1] + 1.0
    obstacles = [Box((x, y_lo, 0.0), (x + length, y - width / 2, _CEILING)),
                 Box((x, y + width / 2, 0.0), (x + length, y_hi, _CEILING))]
    return layout.bounds_lo, layout.bounds_hi, obstacles, layout.mission


@dataclass(frozen=True)
class _Density:
    count: int  # obstacles tried for (fewer fit when the field is full)
    radius: tuple[float, float]  # footprint radius range
    gap: float  # free width between inflated footprints
    tall_fraction: float


_RANDOM_3D = {"easy": _Density(20, (0.4, 1.2), 2.5, 0.3),
              "medium": _Density(35, (0.5, 1.6), 1.5, 0.5),
              "hard": _Density(60, (0.6, 2.0), 0.8, 0.6)}


def _random_3d(rng, n_uavs, formation, spacing, difficulty):
    """A mix of boxes, cylinders (both standing on the ground) and floating spheres; ``difficulty`` sets
    how many, how large and how tightly packed they are."""
    d = _RANDOM_3D[difficulty]
    layout = _layout(rng, n_uavs, formation, spacing)
    centres, radii = _scatter(rng, layout, d.count, d.radius, d.gap)
    return layout.bounds_lo, layout.bounds_hi, _mixed(rng, centres, radii, d), layout.mission


def _mixed(rng, centres: np.ndarray, radii: np.ndarray, d: _Density) -> list:
    """A box, cylinder or floating sphere on each disc (a box's footprint is inscribed in its disc)."""
    n = len(radii)
    kinds, tops = rng.integers(0, 3, n), _tops(rng, n, d.tall_fraction)
    angles = rng.uniform(math.pi / 8, 3 * math.pi / 8, n)  # box footprint inscribed in its disc
    sphere_z = rng.uniform(_LIMITS.z_min + 1.0, _LIMITS.z_max - 1.0, n)
    obstacles = []
    for (x, y), r, kind, top, a, z in zip(centres, radii, kinds, tops, angles, sphere_z):
        if kind == 0:
            hx, hy = r * math.cos(a), r * math.sin(a)
            obstacles.append(Box((x - hx, y - hy, 0.0), (x + hx, y + hy, top)))
        elif kind == 1:
            obstacles.append(Cylinder(x, y, r, 0.0, top))
        else:
            obstacles.append(Sphere(x, y, z, r))
    return obstacles


# ---------------------------------------------------------------------------------------------- version 2
# Missions in every direction and at every altitude: start and goal altitudes drawn from _MISSION_Z, the
# followers' slots at the leader's altitude, formation size, shape and spacing from the family's _Team.
_MISSION_Z = (1.5, 7.5)  # inside the band [z_min, z_max] with room for the low tops and the world top
_OPEN_FIELD = 30.0  # square field of the open families (forest, urban, random-3d) ...
_OPEN_DISTANCE = (18.0, 24.0)  # ... crossed from start to goal on a bearing over the full circle
_STRUCTURE_GOAL_X = 27.0  # corridor, wall-gap and dog-leg: the goal near x = 27 before the quarter turn


@dataclass(frozen=True)
class _Team:
    """The formations a family draws when the caller does not override them."""

    n_uavs: tuple[int, int]  # inclusive range
    spacing: tuple[float, float]


def _draw_team(rng, team: _Team, n_uavs, formation, spacing) -> tuple[int, str, float]:
    """Size, shape and spacing: the overrides where given, else drawn. Always three draws, so an override
    never shifts the rest of the seed's stream."""
    drawn_n, u_shape, drawn_spacing = (int(rng.integers(team.n_uavs[0], team.n_uavs[1] + 1)), rng.random(),
                                       round(rng.uniform(*team.spacing) * 20.0) / 20.0)  # 5 cm steps
    if n_uavs is None:  # a drawn size fits an overridden shape
        cap = MAX_UAVS.get(formation) if isinstance(formation, str) else None
        n_uavs = drawn_n if cap is None else min(drawn_n, cap)
    if formation is None:  # a drawn shape holds the size (Mission reports a malformed size)
        fits = [f for f in FORMATION_SHAPES if MAX_UAVS[f] is None
                or (isinstance(n_uavs, (int, np.integer)) and n_uavs <= MAX_UAVS[f])]
        formation = fits[int(u_shape * len(fits))]
    return n_uavs, formation, drawn_spacing if spacing is None else spacing


def _altitudes(rng) -> tuple[float, float]:
    return tuple(float(z) for z in rng.uniform(*_MISSION_Z, 2))


def _open_layout(rng, n_uavs: int, formation: str, spacing: float) -> _Layout:
    """Start and goal on a random bearing (full circle) through the centre of a square field, at random
    altitudes; the formation faces the goal at both ends and the bounds grow to hold it."""
    bearing, distance = rng.uniform(-math.pi, math.pi), rng.uniform(*_OPEN_DISTANCE)
    z_start, z_goal = _altitudes(rng)
    centre = np.full(2, _OPEN_FIELD / 2)
    half = 0.5 * distance * np.array([math.cos(bearing), math.sin(bearing)])
    start, goal = centre - half, centre + half
    offsets = slot_offsets(formation, n_uavs, spacing)
    keep_out = np.vstack([slot_positions(p, bearing, offsets, 0.0)[:, :2] for p in (start, goal)])
    lo = np.floor(np.minimum(0.0, keep_out.min(axis=0) - _ZONE_RADIUS))
    hi = np.ceil(np.maximum(_OPEN_FIELD, keep_out.max(axis=0) + _ZONE_RADIUS))
    mission = Mission(start=(start[0], start[1], z_start), goal=(goal[0], goal[1], z_goal), start_heading=bearing,
                      formation=formation, spacing=spacing, n_uavs=n_uavs, slot_altitude="leader")
    return _Layout(mission, (lo[0], lo[1], 0.0), (hi[0], hi[1], _CEILING), keep_out, (lo[0], hi[0]))


def _hard_core(rng, layout: _Layout, count: int, radius_range: tuple[float, float], gap: float, rounds: int = 4):
    """Centres (k, 2) and radii (k,) of up to ``count`` discs clear of the zones, any two 2 (r_uav + r_safe)
    + ``gap`` apart (as ``_scatter``), without a per-disc Python loop: each round throws a batch of candidates
    and keeps those that clash with no disc kept before and no earlier valid candidate of the batch (Matern
    type-II thinning, ``_thin``), so the kept discs never clash."""
    sep = 2 * _R_CLEAR + gap
    kept_c, kept_r = np.empty((0, 2)), np.empty(0)
    for _ in range(rounds):
        c = rng.uniform(layout.bounds_lo[:2], layout.bounds_hi[:2], (3 * count, 2))
        r = rng.uniform(*radius_range, 3 * count)
        ok = _thin(c, r, np.ascontiguousarray(layout.keep_out, dtype=np.float64), kept_c, kept_r, _ZONE_RADIUS, sep)
        take = np.flatnonzero(ok)[:count - kept_r.size]
        kept_c, kept_r = np.vstack([kept_c, c[take]]), np.concatenate([kept_r, r[take]])
    return kept_c, kept_r


@numba.njit(cache=True)
def _thin(c, r, keep_out, kept_c, kept_r, zone, sep):
    """One round of ``_hard_core``: which candidate discs (centres c (n, 2), radii r) to keep. A candidate is
    valid if its edge is ``zone`` from every keep-out point and ``sep`` from every kept disc; it is kept if
    valid and ``sep`` from every earlier valid candidate. Distances are ``hypot(dx, dy) - r_i - r_j`` in
    that order (the float64 results of the numpy formulation this kernel replaced)."""
    n = r.shape[0]
    valid = np.empty(n, np.bool_)
    for i in range(n):
        near = np.inf
        for p in range(keep_out.shape[0]):
            near = min(near, math.hypot(c[i, 0] - keep_out[p, 0], c[i, 1] - keep_out[p, 1]))
        ok = near - r[i] >= zone
        for j in range(kept_r.shape[0]):
            if not ok:
                break
            ok = math.hypot(c[i, 0] - kept_c[j, 0], c[i, 1] - kept_c[j, 1]) - r[i] - kept_r[j] >= sep
        valid[i] = ok
    keep = valid.copy()
    for i in range(n):
        if not valid[i]:
            continue
        for j in range(i):
            if valid[j] and math.hypot(c[i, 0] - c[j, 0], c[i, 1] - c[j, 1]) - r[i] - r[j] < sep:
                keep[i] = False
                break
    return keep


def _forest_2(rng, n_uavs, formation, spacing, difficulty):
    """forest@1's trees, crossed on any bearing between any two altitudes."""
    layout = _open_layout(rng, n_uavs, formation, spacing)
    centres, radii = _hard_core(rng, layout, count=50, radius_range=(0.3, 0.8), gap=1.0)
    tops = _tops(rng, len(radii), tall_fraction=0.7)
    obstacles = [Cylinder(x, y, r, 0.0, top) for (x, y), r, top in zip(centres, radii, tops)]
    return layout.bounds_lo, layout.bounds_hi, obstacles, layout.mission


def _urban_2(rng, n_uavs, formation, spacing, difficulty):
    """urban@1's blocks, crossed on any bearing: the goal often lies behind a building (a dog-leg)."""
    layout = _open_layout(rng, n_uavs, formation, spacing)
    return _blocks(rng, layout)


def _random_3d_2(rng, n_uavs, formation, spacing, difficulty):
    """random-3d@1's mix, crossed on any bearing between any two altitudes."""
    d = _RANDOM_3D[difficulty]
    layout = _open_layout(rng, n_uavs, formation, spacing)
    centres, radii = _hard_core(rng, layout, d.count, d.radius, d.gap)
    return layout.bounds_lo, layout.bounds_hi, _mixed(rng, centres, radii, d), layout.mission


def _quarter_turn(k: int, bounds_lo, bounds_hi, obstacles, mission: Mission):
    """World and mission turned by k quarter turns about the z axis (exact: coordinate swaps and signs)."""
    def turn(p):  # (m, 2+) -> the same points turned
        p = np.array(p, dtype=float).reshape(-1, np.shape(p)[-1])
        for _ in range(k % 4):
            p[:, 0], p[:, 1] = -p[:, 1], p[:, 0].copy()
        return p

    def box(lo, hi):
        corners = turn([lo, hi])
        return corners.min(axis=0), corners.max(axis=0)

    lo, hi = box(bounds_lo, bounds_hi)
    out = []
    for ob in obstacles:
        if isinstance(ob, Box):
            out.append(Box(*box(ob.lo, ob.hi)))
        elif isinstance(ob, Cylinder):
            (x, y), = turn([ob.x, ob.y])
            out.append(Cylinder(x, y, ob.radius, ob.z_lo, ob.z_hi))
        else:
            (x, y, z), = turn([ob.x, ob.y, ob.z])
            out.append(Sphere(x, y, z, ob.radius))
    start, goal = turn([mission.start, mission.goal])
    heading = math.remainder(mission.start_heading + k * math.pi / 2, 2 * math.pi)
    return tuple(lo), tuple(hi), out, replace(mission, start=tuple(start), goal=tuple(goal), start_heading=heading)


def _structure_layout(rng, n_uavs, formation, spacing, min_field: float) -> _Layout:
    """The version-1 layout along +x (shorter, at random altitudes, slots at the leader's altitude)."""
    return _layout(rng, n_uavs, formation, spacing, min_field=min_field, goal_x=_STRUCTURE_GOAL_X,
                   z=_altitudes(rng), slot_altitude="leader")


def _corridor_2(rng, n_uavs, formation, spacing, difficulty):
    """corridor@1 at random altitudes, along x or y in either direction (a random quarter turn)."""
    layout = _structure_layout(rng, n_uavs, formation, spacing, _CORRIDOR_LENGTH[1] + 2.0)
    bounds_lo, bounds_hi, obstacles, mission = _corridor_walls(rng, layout)
    return _quarter_turn(int(rng.integers(4)), bounds_lo, bounds_hi, obstacles, mission)


def _wall_gap_2(rng, n_uavs, formation, spacing, difficulty):
    """wall-gap@1 with its gap above or below the start's (random) altitude, the goal at another random
    altitude, along x or y in either direction."""
    layout = _structure_layout(rng, n_uavs, formation, spacing, 3.0)
    bounds_lo, bounds_hi, obstacles, mission = _gap_wall(rng, layout, layout.mission.start[2])
    return _quarter_turn(int(rng.integers(4)), bounds_lo, bounds_hi, obstacles, mission)


_DOOR_WIDTH = (3.5, 5.0)  # wide enough for one UAV with margin; narrower than most formations
_DOOR_SIDE = (4.5, 8.0)  # door centre this far from the field's edge: off the straight start-goal line
_WALL_THICKNESS = (0.3, 0.6)
_DOG_LEG_WALLS = {"easy": 1, "hard": 2}


def _dog_leg(rng, n_uavs, formation, spacing, difficulty):
    """Walls through the whole height across the field, each with one door near an edge, alternate sides:
    the goal is hidden from the start and the way to it bends (one bend per wall), along x or y in
    either direction. Start and goal lie within 3 m of the middle, so the straight line hits a wall."""
    layout = _structure_layout(rng, n_uavs, formation, spacing, 12.0)
    n_walls = _DOG_LEG_WALLS[difficulty]
    f0, f1 = layout.field
    xs = f0 + (f1 - f0) * np.arange(1, n_walls + 1) / (n_walls + 1)
    thickness = rng.uniform(*_WALL_THICKNESS, n_walls)
    widths = rng.uniform(*_DOOR_WIDTH, n_walls)
    sides = (int(rng.integers(2)) + np.arange(n_walls)) % 2  # 0: door near y = 0, 1: near y = _FIELD[1]
    inset = rng.uniform(*_DOOR_SIDE, n_walls)
    centres = np.where(sides == 0, inset, _FIELD[1] - inset)
    y_lo, y_hi = layout.bounds_lo[1] - 1.0, layout.bounds_hi[1] + 1.0
    obstacles = []
    for x, t, c, w in zip(xs - thickness / 2, thickness, centres, widths):
        obstacles += [Box((x, y_lo, 0.0), (x + t, c - w / 2, _CEILING)), Box((x, c + w / 2, 0.0), (x + t, y_hi, _CEILING))]
    return _quarter_turn(int(rng.integers(4)), layout.bounds_lo, layout.bounds_hi, obstacles, layout.mission)


_CLASSIC_START = ((-1.5, -1.5), (1.0, 0.5))  # the start's x, y range: clear of the disc at (0, 2) by >= 1 m


def _classic_2d_2(rng, n_uavs, formation, spacing, difficulty):
    """classic-2d@1 with the start position and heading drawn from the seed."""
    start, heading = rng.uniform(*_CLASSIC_START), rng.uniform(-math.pi, math.pi)
    bounds_lo, bounds_hi, obstacles, mission = _classic_2d(rng, n_uavs, formation, spacing, difficulty)
    slots = slot_positions(start, heading, slot_offsets(formation, n_uavs, spacing), _Z_REF)[:, :2]
    lo = np.minimum(bounds_lo[:2], np.floor(slots.min(axis=0) - _ZONE_RADIUS))
    hi = np.maximum(bounds_hi[:2], np.ceil(slots.max(axis=0) + _ZONE_RADIUS))
    mission = replace(mission, start=(start[0], start[1], _Z_REF), start_heading=heading, slot_altitude="leader")
    return (lo[0], lo[1], 0.0), (hi[0], hi[1], _CEILING), obstacles, mission


@dataclass(frozen=True)
class _Generator:
    build: Callable  # (rng, n_uavs, formation, spacing, difficulty) -> (bounds_lo, bounds_hi, obstacles, mission)
    n_uavs: int = _DEFAULT_N_UAVS
    difficulties: tuple[str, ...] = ()
    default_difficulty: str | None = None
    team: _Team | None = None  # draw the formation from this range when not overridden (version 2)


# name -> version -> generator. Never change a published version's output: add a new version.
_OPEN_TEAM, _NARROW_TEAM = _Team((2, 10), (1.5, 3.0)), _Team((2, 6), (1.5, 2.5))
_REGISTRY: dict[str, dict[int, _Generator]] = {
    "classic-2d": {1: _Generator(_classic_2d, n_uavs=1, difficulties=("base", "extended"), default_difficulty="base"),
                   2: _Generator(_classic_2d_2, n_uavs=1, difficulties=("base", "extended"), default_difficulty="base")},
    "forest": {1: _Generator(_forest), 2: _Generator(_forest_2, team=_OPEN_TEAM)},
    "urban": {1: _Generator(_urban), 2: _Generator(_urban_2, team=_OPEN_TEAM)},
    "wall-gap": {1: _Generator(_wall_gap), 2: _Generator(_wall_gap_2, team=_Team((2, 8), (1.5, 3.0)))},
    "corridor": {1: _Generator(_corridor), 2: _Generator(_corridor_2, team=_NARROW_TEAM)},
    "random-3d": {1: _Generator(_random_3d, difficulties=tuple(_RANDOM_3D), default_difficulty="medium"),
                  2: _Generator(_random_3d_2, difficulties=tuple(_RANDOM_3D), default_difficulty="medium",
                                team=_OPEN_TEAM)},
    "dog-leg": {1: _Generator(_dog_leg, difficulties=tuple(_DOG_LEG_WALLS), default_difficulty="easy",
                              team=_NARROW_TEAM)},
}


def list_scenarios() -> list[str]:
    """Registered scenario names (each resolves to its newest version; ``name@k`` pins version k)."""
    return sorted(_REGISTRY)


def scenario_options(name: str) -> dict:
    """What ``make_scenario`` lets a caller choose for a registered scenario: ``difficulties`` (its levels, empty if
    it has none) and ``n_uavs``, its default team size (None: drawn from the family's range; 1 for the single-UAV
    classic-2d maps)."""
    _, _, gen = _lookup(name)
    return {"difficulties": tuple(gen.difficulties), "n_uavs": None if gen.team is not None else gen.n_uavs}


def _lookup(name) -> tuple[str, int, _Generator]:
    if not isinstance(name, str):
        raise ValueError(f"scenario name {name!r}: expected a string such as 'forest' or 'forest@1'")
    base, sep, version_text = name.partition("@")
    versions = _REGISTRY.get(base)
    if versions is None:
        raise ValueError(f"unknown scenario {name!r}; known scenarios: {', '.join(list_scenarios())} "
                         "(add '@<version>' to pin a version)")
    if not sep:
        version = max(versions)
    else:
        version = int(version_text) if version_text.isdigit() else None
        if version not in versions:
            raise ValueError(f"scenario {base!r} has no version {version_text!r}; known versions: {sorted(versions)}")
    return base, version, versions[version]


def make_scenario(name: str, seed: int = 0, *, n_uavs: int | None = None, formation: str | None = None,
                  spacing: float | None = None, difficulty: str | None = None) -> Scenario:
    """Generate a registered scenario; the same (name, version, seed, overrides) always gives the same scenario.

    Defaults: version 1 flies 1 UAV in classic-2d, 5 in a wedge at 2 m spacing elsewhere; version 2 draws
    the size, shape and spacing the caller leaves out from the family's range (``_Team``; classic-2d
    flies 1 UAV). ``difficulty`` is "base" | "extended" for classic-2d, "easy" | "medium" | "hard" for
    random-3d (default "medium"), "easy" (one wall) | "hard" (two) for dog-leg.
    """
    base, version, gen = _lookup(name)
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed={seed!r}: expected an integer >= 0")
    if difficulty is None:
        difficulty = gen.default_difficulty
    elif difficulty not in gen.difficulties:
        allowed = f"one of {list(gen.difficulties)}" if gen.difficulties else "None (it has no difficulty levels)"
        raise ValueError(f"difficulty={difficulty!r} for scenario {base!r}: expected {allowed}")
    rng = np.random.default_rng(int(seed))
    if gen.team is not None:
        n_uavs, formation, spacing = _draw_team(rng, gen.team, n_uavs, formation, spacing)
    formation_defaults = FormationConfig()
    n_uavs = gen.n_uavs if n_uavs is None else n_uavs
    formation = formation_defaults.shape if formation is None else formation
    spacing = formation_defaults.spacing if spacing is None else spacing
    mission = Mission(start=(0.0, 0.0, 0.0), goal=(0.0, 0.0, 0.0), start_heading=0.0, formation=formation,
                      spacing=spacing, n_uavs=n_uavs)  # validates the overrides before they shape the layout
    bounds_lo, bounds_hi, obstacles, mission = gen.build(rng, mission.n_uavs,
                                                         mission.formation, mission.spacing, difficulty)
    return Scenario(name=base, version=version, seed=int(seed), bounds_lo=bounds_lo, bounds_hi=bounds_hi,
                    resolution=GRID_RESOLUTION, obstacles=tuple(obstacles), mission=mission)


def load_scenario(name_or_path, seed: int = 0, *, n_uavs: int | None = None, formation: str | None = None,
                  spacing: float | None = None, difficulty: str | None = None) -> Scenario:
    """A registered name (generated with ``seed``) or a ``.toml`` file (one fixed world; ``seed`` unused)."""
    if isinstance(name_or_path, Path) or (isinstance(name_or_path, str) and name_or_path.endswith(".toml")):
        if difficulty is not None:
            raise ValueError(f"difficulty={difficulty!r}: a scenario file is one fixed world; "
                             "difficulty only applies to registered generators")
        scn = Scenario.from_toml(name_or_path)
        changes = {k: v for k, v in (("n_uavs", n_uavs), ("formation", formation), ("spacing", spacing))
                   if v is not None}
        return scn.with_mission(**changes) if changes else scn
    return make_scenario(name_or_path, seed, n_uavs=n_uavs, formation=formation, spacing=spacing,
                         difficulty=difficulty)


_GOAL_HEADINGS = 36  # goal slots are checked at the start-to-goal bearing, the start heading and 36 more headings


def validate_scenario(scn: Scenario, limits: UAVLimits, z_ref: float, world: World | None = None, *,
                      source: str | None = None) -> None:
    """Raise ValueError listing every reason the mission cannot be flown with UAVs of these limits.

    ``source`` names the scenario in the message (e.g. ``"scenario file my.toml"``); by default its name,
    version and seed.

    Checked: the leader's start and every follower's start slot lie inside the bounds and the altitude band
    with clearance >= r_uav + r_safe; the goal passes the same test except the altitude band, and so do the
    formation's goal slots at some heading of the leader (the start-to-goal bearing, the start heading or one of
    36 evenly spaced ones: the arrival heading is the policy's choice); the formation holds n_uavs; the
    spacing exceeds two UAV radii. Slot altitudes follow the mission's ``slot_altitude``. A goal outside the
    altitude band is a mission no UAV can complete, not malformed input: it is flown until the step limit, and a
    policy is expected to see that and hold (issue 13: the expert reports it ``stuck``).
    """
    if not isinstance(scn, Scenario):
        raise ValueError(f"scn: expected a Scenario, got {type(scn).__name__}")
    if not isinstance(limits, UAVLimits):
        raise ValueError(f"limits: expected a UAVLimits, got {type(limits).__name__}")
    z_ref = as_finite("validate_scenario", "z_ref", z_ref)
    m = scn.mission
    problems = []
    if m.spacing <= 2.0 * limits.r_uav:
        problems.append(f"spacing {m.spacing:g} m does not exceed two UAV radii (2 * r_uav = {2 * limits.r_uav:g} m)")
    world = world if world is not None else scn.build_world()
    names, points = ["leader start", "goal"], [m.start, m.goal]
    goal_slots = None
    try:
        offsets = slot_offsets(m.formation, m.n_uavs, m.spacing)
        slots = formation_slots(np.array(m.start), m.start_heading, offsets, z_ref, m.slot_altitude)
        names += [f"follower {j} start slot" for j in range(1, m.n_uavs)]
        points += [tuple(p) for p in slots[1:]]
        if m.n_uavs > 1:
            bearing = math.atan2(m.goal[1] - m.start[1], m.goal[0] - m.start[0])
            headings = np.concatenate([[bearing, m.start_heading],
                                       np.linspace(-math.pi, math.pi, _GOAL_HEADINGS, endpoint=False)])
            goal_slots = np.stack([formation_slots(np.array(m.goal), h, offsets, z_ref, m.slot_altitude)[1:]
                                   for h in headings])  # (H, n - 1, 3)
    except ValueError as exc:
        problems.append(str(exc))
    pts = np.array(points)
    bad, describe = cannot_stand(scn, limits, world, pts, band=np.array([name != "goal" for name in names]))
    problems += [f"{names[k]} {describe(k)}" for k in np.flatnonzero(bad)]
    if goal_slots is not None:
        blocked, describe = cannot_stand(scn, limits, world, goal_slots.reshape(-1, 3), band=False)
        blocked = blocked.reshape(goal_slots.shape[:2])
        if blocked.any(axis=1).all():
            j = int(np.flatnonzero(blocked[0])[0])
            problems.append("the goal slots are blocked at every heading of the leader; at the start-to-goal "
                            f"bearing follower {j + 1} goal slot {describe(j)}")
    if problems:
        who = source if source is not None else f"scenario {scn.name!r} (version {scn.version}, seed {scn.seed})"
        raise ValueError(f"{who} cannot be flown: "
                         + "; ".join(problems))


def cannot_stand(scn: Scenario, limits: UAVLimits, world: World, pts: np.ndarray, band=True):
    """Which points (m, 3) a UAV cannot stand on (outside the bounds, or the altitude band where ``band`` (a
    bool, or one per point) says so, or too close to an obstacle), and ``describe(k)``: point k and why, for
    the error message."""
    lo, hi = np.array(scn.bounds_lo), np.array(scn.bounds_hi)
    r_clear = limits.r_uav + limits.r_safe
    clearance = world.clearance(pts)
    outside = np.any((pts < lo) | (pts > hi), axis=1)
    off_band = ((pts[:, 2] < limits.z_min) | (pts[:, 2] > limits.z_max)) & band
    close = clearance < r_clear

    def describe(k: int) -> str:
        p = pts[k]
        issue = ([f"lies outside the world bounds {scn.bounds_lo} .. {scn.bounds_hi}"] * bool(outside[k])
                 + [f"lies outside the altitude band [{limits.z_min:g}, {limits.z_max:g}]"] * bool(off_band[k])
                 + [f"has clearance {clearance[k]:.3f} m < r_uav + r_safe = {r_clear:g} m"] * bool(close[k]))
        return f"({p[0]:.2f}, {p[1]:.2f}, {p[2]:.2f}) " + "; ".join(issue)

    return outside | off_band | close, describe
