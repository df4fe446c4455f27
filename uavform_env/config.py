"""Frozen, self-validating configuration of the environment.

Defaults follow Appendix A of the algorithm spec. Every dataclass checks its fields on
construction and raises ``ValueError`` naming the field, the value and the allowed range, so a bad
configuration fails where it is written, not deep inside a numba kernel. The checks (``check_*``)
and the ``Config`` base with its declarative ``BOUNDS`` table are public: every package's configs
use them.
"""

from __future__ import annotations

import copy
import functools
import math
from dataclasses import dataclass, field, fields, replace
from types import MappingProxyType
from typing import Any, ClassVar

FORMATION_SHAPES = ("wedge", "diamond", "triangle", "line", "column")
# Where follower slots sit in altitude: at FormationConfig.z_ref (version-1 missions) or at the leader's altitude.
SLOT_ALTITUDES = ("z_ref", "leader")
PRIOR_MAPS = ("none", "heightmap")


def check_range(owner: str, name: str, value: Any, lo: float | None = None, hi: float | None = None,
                 lo_open: bool = False, hi_open: bool = False) -> None:
    """Raise a ValueError naming ``owner.name`` unless ``value`` is a finite number inside the range."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ValueError(f"{owner}.{name}={value!r}: expected a finite number")
    below = lo is not None and (value <= lo if lo_open else value < lo)
    above = hi is not None and (value >= hi if hi_open else value > hi)
    if below or above:
        left = "(" if lo_open else "["
        right = ")" if hi_open else "]"
        lo_s = "-inf" if lo is None else f"{lo:g}"
        hi_s = "inf" if hi is None else f"{hi:g}"
        raise ValueError(f"{owner}.{name}={value!r} is out of range; allowed {left}{lo_s}, {hi_s}{right}")


def check_order(owner: str, lo_name: str, lo: float, hi_name: str, hi: float) -> None:
    """Raise a ValueError naming both fields unless lo < hi."""
    if not lo < hi:
        raise ValueError(f"{owner}.{lo_name}={lo!r} must be smaller than {owner}.{hi_name}={hi!r}")


def check_int(owner: str, name: str, value: Any, lo: int, hi: int | None = None) -> None:
    """Raise a ValueError naming ``owner.name`` unless ``value`` is an integer in [lo, hi]."""
    if isinstance(value, bool) or not isinstance(value, int):
        raise ValueError(f"{owner}.{name}={value!r}: expected an integer")
    check_range(owner, name, value, lo, hi)


def check_choice(owner: str, name: str, value: Any, choices: tuple) -> None:
    """Raise a ValueError naming ``owner.name`` unless ``value`` is one of ``choices``."""
    if value not in choices:
        raise ValueError(f"{owner}.{name}={value!r}: expected one of {list(choices)}")


def check_bool(owner: str, name: str, value: Any) -> None:
    """Raise a ValueError naming ``owner.name`` unless ``value`` is a bool (not 0/1, not None)."""
    if not isinstance(value, bool):
        raise ValueError(f"{owner}.{name}={value!r}: expected a bool")


def check_type(owner: str, name: str, value: Any, cls: type) -> None:
    """Raise a ValueError naming ``owner.name`` unless ``value`` is a ``cls`` (a nested config)."""
    if not isinstance(value, cls):
        raise ValueError(f"{owner}.{name}: expected a {cls.__name__}")


# Entries of a ``Config.BOUNDS`` table: each binds one check_* function to a field's allowed values.
def in_range(lo: float | None = None, hi: float | None = None, lo_open: bool = False, hi_open: bool = False):
    """A finite number in the range (``check_range``)."""
    return functools.partial(check_range, lo=lo, hi=hi, lo_open=lo_open, hi_open=hi_open)


def integer(lo: int, hi: int | None = None):
    """An integer in [lo, hi] (``check_int``)."""
    return functools.partial(check_int, lo=lo, hi=hi)


def one_of(choices: tuple):
    """One of ``choices`` (``check_choice``)."""
    return functools.partial(check_choice, choices=choices)


def instance_of(cls: type):
    """A ``cls`` (``check_type``)."""
    return functools.partial(check_type, cls=cls)


def optional(check):
    """None (a default derived elsewhere) or a value that passes ``check``."""
    def check_optional(owner: str, name: str, value: Any) -> None:
        if value is not None:
            check(owner, name, value)
    return check_optional


boolean = check_bool


class Config:
    """Base of the config dataclasses: declared bounds, dict round-trip and validated copies.

    ``BOUNDS`` maps a field name to its allowed values (``in_range``, ``integer``, ``one_of``,
    ``boolean``, ``instance_of``, ``optional``), declared once per field; ``__post_init__`` checks them in table
    order. A subclass with checks across fields calls ``super().__post_init__()`` first.
    """

    BOUNDS: ClassVar[dict] = {}

    def __post_init__(self):
        owner = type(self).__name__
        for name, check in self.BOUNDS.items():
            check(owner, name, getattr(self, name))

    def to_dict(self) -> dict:
        out = {}
        for f in fields(self):
            v = getattr(self, f.name)
            out[f.name] = v.to_dict() if isinstance(v, Config) else (list(v) if isinstance(v, tuple) else v)
        return out

    @classmethod
    def from_dict(cls, data: dict):
        known = {f.name: f for f in fields(cls)}
        unknown = sorted(set(data) - set(known))
        if unknown:
            raise ValueError(f"{cls.__name__}: unknown field(s) {unknown}; allowed {sorted(known)}")
        kwargs = {}
        for name, value in data.items():
            default = getattr(cls(), name) if name in known else None
            if isinstance(default, Config):
                value = type(default).from_dict(value)
            elif isinstance(default, tuple):
                value = tuple(value)
            kwargs[name] = value
        return cls(**kwargs)

    def replace(self, **changes):
        return replace(self, **changes)

    def with_checked(self, **changes):
        """A copy with ``changes``, each checked against its declared bound alone.

        ``replace`` runs ``__post_init__``, i.e. every field's check (~50 us for the expert's config), which a
        per-step copy cannot afford; this copy skips the checks across fields, so it is only for fields that none
        of them reads.
        """
        owner = type(self).__name__
        for name, value in changes.items():
            self.BOUNDS[name](owner, name, value)
        new = copy.copy(self)
        for name, value in changes.items():
            object.__setattr__(new, name, value)
        return new


@dataclass(frozen=True)
class UAVLimits(Config):
    """Kinematic limits of one UAV (spec (a)); the planners' model uses exactly these.

    Against wind the commands are ground-velocity set-points of a multirotor autopilot that leans into the wind
    it has estimated (``dynamics.wind_drift``; README, "Disturbances"; docs/deviations.md): its estimate follows
    the true wind with time constant ``wind_rejection_tau`` (s, default 0.5) and is capped at
    ``wind_authority`` (m/s, default 3.0: the largest wind the airframe can lean against, per horizontal
    magnitude; the vertical component is capped at the same value). The UAV is carried by the wind minus the
    estimate. ``wind_authority = 0`` gives the unopposed model (the whole wind carries the UAV) [X].
    """

    dt: float = 0.1
    v_min: float = 0.0
    v_max: float = 1.0
    w_max: float = math.radians(20.0)
    a_max: float = 0.2
    dw_max: float = math.radians(50.0)
    vz_max: float = 0.5
    az_max: float = 0.5
    gamma_max: float = math.radians(45.0)
    r_uav: float = 0.3
    r_safe: float = 0.2
    z_min: float = 0.5
    z_max: float = 10.0
    wind_authority: float = 3.0
    wind_rejection_tau: float = 0.5

    def __post_init__(self):
        o = "UAVLimits"
        check_range(o, "dt", self.dt, 0.0, 1.0, lo_open=True)
        check_range(o, "v_min", self.v_min, 0.0, None)
        check_range(o, "v_max", self.v_max, 0.0, 50.0, lo_open=True)
        check_order(o, "v_min", self.v_min, "v_max", self.v_max)
        check_range(o, "w_max", self.w_max, 0.0, 2 * math.pi, lo_open=True)
        check_range(o, "a_max", self.a_max, 0.0, 100.0, lo_open=True)
        check_range(o, "dw_max", self.dw_max, 0.0, 100.0, lo_open=True)
        check_range(o, "vz_max", self.vz_max, 0.0, 20.0)
        check_range(o, "az_max", self.az_max, 0.0, 100.0)
        check_range(o, "gamma_max", self.gamma_max, 0.0, math.pi / 2)
        check_range(o, "r_uav", self.r_uav, 0.0, 10.0, lo_open=True)
        check_range(o, "r_safe", self.r_safe, 0.0, 10.0)
        check_range(o, "z_min", self.z_min, 0.0, None)
        check_range(o, "z_max", self.z_max, 0.0, None, lo_open=True)
        check_order(o, "z_min", self.z_min, "z_max", self.z_max)
        check_range(o, "wind_authority", self.wind_authority, 0.0, 50.0)
        check_range(o, "wind_rejection_tau", self.wind_rejection_tau, 0.0, 100.0)

    def climb_angle_limit(self, v: float) -> float:
        """e_max(v) = min(gamma_max, atan2(vz_max, max(v, 1e-3))) (spec (a))."""
        return min(self.gamma_max, math.atan2(self.vz_max, max(v, 1e-3)))


@dataclass(frozen=True)
class SensorConfig(Config):
    """Simulated range sensor: an azimuth x elevation grid of rays (spec (e2), simplified sensor).

    ``interleave`` rotates the azimuth pattern by a fraction of one ray spacing every step (golden
    ratio sequence), so a coarse, fast pattern still covers every direction within a few steps.
    Defaults [D]: 36 x 7 rays (10 deg x 14 deg, elevation +/-42 deg, odd so one row is level) and
    r_max = 6 m, which covers the planners' reach (DWA: v_max T_p + D_cap + margins = 5.7 m; 3D VFH+: R_w = 5 m). The spec's
    suggestion is r_max = 8 m; see docs/deviations.md.
    """

    n_azimuth: int = 36
    n_elevation: int = 7
    elevation_min: float = math.radians(-42.0)
    elevation_max: float = math.radians(42.0)
    r_max: float = 6.0
    interleave: bool = True

    def __post_init__(self):
        o = "SensorConfig"
        check_int(o, "n_azimuth", self.n_azimuth, 1, 3600)
        check_int(o, "n_elevation", self.n_elevation, 1, 1800)
        check_range(o, "elevation_min", self.elevation_min, -math.pi / 2, math.pi / 2)
        check_range(o, "elevation_max", self.elevation_max, -math.pi / 2, math.pi / 2)
        if self.elevation_max < self.elevation_min:
            raise ValueError(f"{o}.elevation_min={self.elevation_min!r} must not exceed "
                             f"{o}.elevation_max={self.elevation_max!r}")
        check_range(o, "r_max", self.r_max, 0.0, 100.0, lo_open=True)

    @property
    def n_rays(self) -> int:
        return self.n_azimuth * self.n_elevation


@dataclass(frozen=True)
class MapConfig(Config):
    """Onboard occupancy map with OctoMap's sensor model (spec (e1)).

    ``resolution``: the maps' voxel edge (m). None (default): the scenario's voxel grid (its ``resolution``, on which
    the ground truth is rasterised; ``scenarios.GRID_RESOLUTION`` for the registered generators). A number gives the
    maps a grid of their own over the world's bounds. ``FormationEnv`` replaces None by the resolution in use.
    """

    resolution: float | None = None
    p_hit: float = 0.7
    p_miss: float = 0.4
    p_min: float = 0.1192
    p_max: float = 0.971
    p_occ: float = 0.5

    def __post_init__(self):
        o = "MapConfig"
        if self.resolution is not None:
            check_range(o, "resolution", self.resolution, 0.01, 5.0)
        check_range(o, "p_hit", self.p_hit, 0.5, 1.0, lo_open=True, hi_open=True)
        check_range(o, "p_miss", self.p_miss, 0.0, 0.5, lo_open=True, hi_open=True)
        check_range(o, "p_min", self.p_min, 0.0, 0.5, lo_open=True, hi_open=True)
        check_range(o, "p_max", self.p_max, 0.5, 1.0, lo_open=True, hi_open=True)
        check_range(o, "p_occ", self.p_occ, 0.0, 1.0, lo_open=True, hi_open=True)
        check_order(o, "p_min", self.p_min, "p_occ", self.p_occ)
        check_order(o, "p_occ", self.p_occ, "p_max", self.p_max)

    @staticmethod
    def logodds(p: float) -> float:
        return math.log(p / (1.0 - p))


@dataclass(frozen=True)
class FormationConfig(Config):
    """Formation geometry (spec (g1)): shape, spacing, reference altitude and closing tolerance."""

    shape: str = "wedge"
    spacing: float = 2.0
    z_ref: float = 3.0
    e_f: float = 0.5

    def __post_init__(self):
        o = "FormationConfig"
        check_choice(o, "shape", self.shape, FORMATION_SHAPES)
        check_range(o, "spacing", self.spacing, 0.0, 100.0, lo_open=True)
        check_range(o, "z_ref", self.z_ref, 0.0, None)
        check_range(o, "e_f", self.e_f, 0.0, 100.0, lo_open=True)


@dataclass(frozen=True)
class RewardConfig(Config):
    """Weights of the per-agent reward terms (see README, "Rewards")."""

    progress: float = 1.0
    formation: float = 0.05
    collision: float = 10.0
    smoothness: float = 0.01
    success: float = 10.0
    time: float = 0.01

    def __post_init__(self):
        for f in fields(self):
            check_range("RewardConfig", f.name, getattr(self, f.name), 0.0, None)


@dataclass(frozen=True)
class ObservationConfig(Config):
    """What each agent's observation vector contains (see README, "Observations")."""

    k_neighbours: int = 4
    neighbour_range: float = 20.0
    target_clip: float = 50.0
    include_histogram: bool = True
    histogram_cell_deg: float = 15.0
    histogram_radius: float = 5.0
    include_crop: bool = False
    crop_level: int = 2
    crop_cells: int = 8
    crop_cells_z: int = 4

    def __post_init__(self):
        o = "ObservationConfig"
        check_int(o, "k_neighbours", self.k_neighbours, 0, 64)
        check_range(o, "neighbour_range", self.neighbour_range, 0.0, None, lo_open=True)
        check_range(o, "target_clip", self.target_clip, 0.0, None, lo_open=True)
        check_range(o, "histogram_cell_deg", self.histogram_cell_deg, 1.0, 90.0)
        if abs(360.0 / self.histogram_cell_deg - round(360.0 / self.histogram_cell_deg)) > 1e-9 or \
                abs(180.0 / self.histogram_cell_deg - round(180.0 / self.histogram_cell_deg)) > 1e-9:
            raise ValueError(f"ObservationConfig.histogram_cell_deg={self.histogram_cell_deg!r}: "
                             "expected a divisor of 180 degrees (e.g. 5, 10, 15, 30)")
        check_range(o, "histogram_radius", self.histogram_radius, 0.0, 50.0, lo_open=True)
        check_int(o, "crop_level", self.crop_level, 0, 8)
        check_int(o, "crop_cells", self.crop_cells, 1, 64)
        check_int(o, "crop_cells_z", self.crop_cells_z, 1, 64)


@dataclass(frozen=True)
class EpisodeConfig(Config):
    """Episode rules: length, goal radius, crash handling and prior knowledge."""

    max_cycles: int = 3000
    r_goal: float = 0.5
    remove_crashed: bool = False
    prior_map: str = "none"
    prior_resolution: float = 0.5

    def __post_init__(self):
        o = "EpisodeConfig"
        check_int(o, "max_cycles", self.max_cycles, 1)
        check_range(o, "r_goal", self.r_goal, 0.0, None, lo_open=True)
        check_bool(o, "remove_crashed", self.remove_crashed)
        check_choice(o, "prior_map", self.prior_map, PRIOR_MAPS)
        check_range(o, "prior_resolution", self.prior_resolution, 0.05, 10.0)


@dataclass(frozen=True)
class DisturbanceConfig(Config):
    """Wind on the airframe and faults of the range sensor (README, "Disturbances").

    Wind: a gust field (``wind.GustField``) of ``wind_std`` m/s per horizontal axis (vertical scaled by
    ``wind_vertical``), correlation time ``wind_tau`` s and correlation length ``wind_length`` m, plus the
    steady ``wind_mean`` (x, y) m/s, pushing every flying UAV's position, less what its autopilot compensates
    (``UAVLimits.wind_authority``; ``FormationEnv._apply_wind``). Sensor: every range that hit something gets Gaussian
    noise of ``range_noise_std`` m, and each ray is lost with probability ``ray_dropout`` (it then reads
    as no return: free space up to r_max, as a lidar's lost echo does) (``sensing.perturb_scan``).
    Named presets: ``DISTURBANCE_PRESETS``.
    """

    wind_std: float = 0.0
    wind_tau: float = 2.0
    wind_length: float = 20.0
    wind_vertical: float = 0.3
    wind_mean: tuple[float, float] = (0.0, 0.0)
    range_noise_std: float = 0.0
    ray_dropout: float = 0.0

    def __post_init__(self):
        o = "DisturbanceConfig"
        check_range(o, "wind_std", self.wind_std, 0.0, 10.0)
        check_range(o, "wind_tau", self.wind_tau, 0.0, None, lo_open=True)
        check_range(o, "wind_length", self.wind_length, 0.0, None, lo_open=True)
        check_range(o, "wind_vertical", self.wind_vertical, 0.0, 1.0)
        mean = self.wind_mean
        if not isinstance(mean, (tuple, list)) or len(mean) != 2:
            raise ValueError(f"{o}.wind_mean={mean!r}: expected two numbers (x, y) in m/s")
        for axis, value in zip("xy", mean):
            check_range(o, f"wind_mean.{axis}", value, -10.0, 10.0)
        object.__setattr__(self, "wind_mean", (float(mean[0]), float(mean[1])))
        check_range(o, "range_noise_std", self.range_noise_std, 0.0, 10.0)
        check_range(o, "ray_dropout", self.ray_dropout, 0.0, 1.0, hi_open=True)

    @property
    def windy(self) -> bool:
        return self.wind_std > 0.0 or self.wind_mean != (0.0, 0.0)


# Named disturbances (README, "Disturbances"); a suite, a scenario file and `uavform fly --wind` name them.
DISTURBANCE_PRESETS = MappingProxyType({
    "calm": DisturbanceConfig(),
    "breeze": DisturbanceConfig(wind_std=0.3),
    "gusty": DisturbanceConfig(wind_std=1.0, wind_mean=(0.3, 0.0)),
    "noisy": DisturbanceConfig(range_noise_std=0.05, ray_dropout=0.1),
})


def disturbance_preset(name) -> DisturbanceConfig:
    """The named preset; an unknown name raises a ValueError listing the known ones."""
    if not isinstance(name, str) or name not in DISTURBANCE_PRESETS:
        raise ValueError(f"unknown disturbance preset {name!r}; known presets: {', '.join(DISTURBANCE_PRESETS)}")
    return DISTURBANCE_PRESETS[name]


@dataclass(frozen=True)
class EnvConfig(Config):
    """Everything the environment needs besides the scenario."""

    uav: UAVLimits = field(default_factory=UAVLimits)
    sensor: SensorConfig = field(default_factory=SensorConfig)
    map: MapConfig = field(default_factory=MapConfig)
    formation: FormationConfig = field(default_factory=FormationConfig)
    reward: RewardConfig = field(default_factory=RewardConfig)
    observation: ObservationConfig = field(default_factory=ObservationConfig)
    episode: EpisodeConfig = field(default_factory=EpisodeConfig)
    disturbance: DisturbanceConfig = field(default_factory=DisturbanceConfig)

    def __post_init__(self):
        expected = {"uav": UAVLimits, "sensor": SensorConfig, "map": MapConfig,
                    "formation": FormationConfig, "reward": RewardConfig,
                    "observation": ObservationConfig, "episode": EpisodeConfig, "disturbance": DisturbanceConfig}
        for name, cls in expected.items():
            if not isinstance(getattr(self, name), cls):
                raise ValueError(f"EnvConfig.{name}: expected a {cls.__name__}, got {type(getattr(self, name)).__name__}")
        min_spacing = 2.0 * self.uav.r_uav
        if self.formation.spacing <= min_spacing:
            raise ValueError(f"FormationConfig.spacing={self.formation.spacing!r} must exceed two UAV radii "
                             f"(2 * UAVLimits.r_uav = {min_spacing:g})")
        if not self.uav.z_min <= self.formation.z_ref <= self.uav.z_max:
            raise ValueError(f"FormationConfig.z_ref={self.formation.z_ref!r} must lie in the altitude band "
                             f"[{self.uav.z_min:g}, {self.uav.z_max:g}] of UAVLimits")
