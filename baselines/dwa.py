"""Dynamic Window Approach: standard DWA (spec (b)) and improved DWA (spec (c)) in one planner.

The improvements E8 (target-distance correction), E10 (A*-aligned heading weight) and E11
(rotation cost) are switches of ``DWAConfig``. The ablation of spec (h) therefore compares
planners that share every other line of code. Rollouts use the environment's own integrator, so a
sample the planner calls safe is exactly the motion the simulator produces.

Horizontal terms (heading, goal distances, alignment) use x, y only: DWA chooses the horizontal
motion, and altitude comes from the caller's ``vz_cmd``. Clearance is 3D, with the rollout
altitude ``z_k = z + vz_cmd * k * dt`` (spec (g5)).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import ClassVar, NamedTuple

import numba
import numpy as np

from uavform_env.config import Config, UAVLimits, boolean, check_range, in_range, one_of, optional
from uavform_env.dynamics import wrap

NORM_MODES = ("sum", "minmax")
HEADING_REFS = ("endpoint", "current")
ASTAR_WEIGHT_MODES = ("per_candidate", "per_step")
ROTATION_MODES = ("abs", "delta")
ROT_WEIGHT_MODES = ("proximity", "alignment")
IMPROVEMENT_FLAGS = ("use_goal_dist_correction", "use_astar_weight", "use_rotation_cost")
# Ablation names of spec (c5) -> values of IMPROVEMENT_FLAGS (E8, E10, E11).
ABLATIONS = {
    "DWA": (False, False, False),
    "DWA+E8": (True, False, False),
    "DWA+E8+E10": (True, True, False),
    "IDWA": (True, True, True),
}
_FLOAT_MAX = np.finfo(np.float64).max
_TIE_TOL = 1e-12  # relative: scores (and |w|) this close count as equal, so the tie rule decides


@dataclass(frozen=True)
class DWAConfig(Config):
    """Weights, horizon and the E8/E10/E11 switches of the DWA planner (spec (b), (c), Appendix A).

    Fields tagged [X] in the spec are reconstructions and stay configurable:
    ``heading_ref``, ``approach_speed_profile``, ``astar_weight_mode``, ``rotation_mode``,
    ``rot_weight_mode``, and ``alpha0``, ``kappa``, ``R_sw``, ``eps0``, ``d_in``, ``d_out``.
    ``R_sw=None`` means one horizon of travel at full speed, ``UAVLimits.v_max * T_p``.
    ``R_uu`` is the separation to moving neighbours below which a sample is inadmissible (g6).
    ``dist_cap`` [X]: the clearance at which the dist term saturates (None: ``D_cap``, as in (b5)).
    ``brake_share`` [X]: the braking test of (b6) asks for a clearance of at least ``brake_share`` x d_brake(v). 1 (the
    default) is the clearance form of (b6), which counts a wall beside the path as one ahead: flying 1 m beside a
    wall holds v at sqrt(2 a_max x 1 m). Below 1 the free arc also counts, Fox's form v <= sqrt(2 dist a_max) with
    dist the free arc length along the sample's curvature: every rollout runs on at (v, w) past T_p for the stopping
    time of the window's top speed, v_hi / (2 a_max), and that longer arc must be collision-free (c > 0), so a UAV
    can still stop where the horizon ends (the sample's clearance, in the dist term too, is that arc's). Share 0 then
    slows a UAV only for obstacles on its path.
    ``dwa_plan(brake_share=...)`` overrides it for one cycle.
    Sum normalisation over the admissible samples turns centimetre clearance differences among the
    slow samples of a small window into the largest term, so with an obstacle inside ``D_cap`` the
    planner prefers standing still; a lower cap lets only genuinely close obstacles rank samples.
    Admissibility (c >= d_brake, c > 0) is unaffected.
    """

    T_p: float = 3.0
    alpha: float = 0.1
    beta: float = 0.2
    gamma: float = 0.1
    D_cap: float = 2.0
    norm: str = "sum"
    r_goal: float = 0.5
    v_res: float = 0.01
    w_res: float = math.radians(1.0)
    use_goal_dist_correction: bool = False
    use_astar_weight: bool = False
    use_rotation_cost: bool = False
    alpha0: float = 0.1
    kappa: float = 0.2
    R_sw: float | None = None
    heading_ref: str = "endpoint"
    approach_speed_profile: bool = False
    astar_weight_mode: str = "per_candidate"
    eps0: float = 0.05
    d_in: float = 0.3
    d_out: float = 2.0
    rotation_mode: str = "abs"
    rot_weight_mode: str = "proximity"
    R_uu: float = 0.8
    dist_cap: float | None = None
    brake_share: float = 1.0

    BOUNDS: ClassVar[dict] = {
        "T_p": in_range(0.0, 60.0, lo_open=True),
        **{name: in_range(0.0) for name in ("alpha", "beta", "gamma", "alpha0", "eps0", "d_in", "d_out")},
        **{name: in_range(0.0, lo_open=True) for name in ("D_cap", "r_goal", "v_res", "w_res", "R_uu")},
        "norm": one_of(NORM_MODES),
        **{name: boolean for name in IMPROVEMENT_FLAGS + ("approach_speed_profile",)},
        "kappa": in_range(0.0, 1.0, hi_open=True),
        "brake_share": in_range(0.0, 1.0),
        "R_sw": optional(in_range(0.0, lo_open=True)),
        "heading_ref": one_of(HEADING_REFS),
        "astar_weight_mode": one_of(ASTAR_WEIGHT_MODES),
        "rotation_mode": one_of(ROTATION_MODES),
        "rot_weight_mode": one_of(ROT_WEIGHT_MODES),
    }

    def __post_init__(self):
        super().__post_init__()
        o = "DWAConfig"
        if self.dist_cap is not None:
            check_range(o, "dist_cap", self.dist_cap, 0.0, self.D_cap, lo_open=True)   # bounded by D_cap
        if not self.d_in < self.d_out:
            raise ValueError(f"{o}.d_out={self.d_out!r} must exceed d_in={self.d_in!r} (the rotation weight "
                             "ramps from 0 at d_in to eps0 at d_out)")
        if self.approach_speed_profile and not self.use_goal_dist_correction:
            raise ValueError(f"{o}.approach_speed_profile=True needs use_goal_dist_correction=True "
                             "(it is part of E8 and acts where the E8 blend lambda < 1)")

    @classmethod
    def ablation(cls, name: str, **overrides) -> DWAConfig:
        """The named ablation of spec (c5): ``DWA``, ``DWA+E8``, ``DWA+E8+E10`` or ``IDWA`` (E8+E10+E11)."""
        if name not in ABLATIONS:
            raise ValueError(f"DWAConfig.ablation name={name!r}: expected one of {list(ABLATIONS)}")
        fixed = sorted(set(overrides) & set(IMPROVEMENT_FLAGS))
        if fixed:
            raise ValueError(f"DWAConfig.ablation: {fixed} are set by the name {name!r}; do not override them")
        unknown = sorted(set(overrides) - {f.name for f in fields(cls)})
        if unknown:
            raise ValueError(f"DWAConfig.ablation: unknown field(s) {unknown}")
        return cls(**dict(zip(IMPROVEMENT_FLAGS, ABLATIONS[name])), **overrides)


@dataclass(frozen=True)
class DWACandidates:
    """Every sample of one planning cycle, for diagnostics and plots (inadmissible score = -inf).

    ``clearance`` is exact below max(D_cap, the braking test's clearance) and capped there; for an inadmissible
    sample it is only some value below the admissibility bound (evaluation stops early).
    """

    v: np.ndarray
    w: np.ndarray
    admissible: np.ndarray
    clearance: np.ndarray
    score: np.ndarray
    endpoint: np.ndarray


@dataclass(frozen=True)
class DWAResult:
    """The chosen command; ``admissible=False`` is the braking fallback of spec (b10) (a 'stuck' step).

    ``endpoint`` (x, y, z) and ``clearance`` belong to the chosen rollout (for the fallback: the
    braking rollout); the clearance is capped at max(D_cap, the braking test's clearance). ``alignment`` is the E10
    cosine c of that endpoint against the lookahead direction; feed it back as ``prev_alignment``
    for the per-step and alignment modes.
    """

    v: float
    w: float
    admissible: bool
    n_admissible: int
    score: float
    endpoint: np.ndarray
    clearance: float
    alignment: float
    candidates: DWACandidates


def _finite(name: str, value) -> float:
    if type(value) is not float and (isinstance(value, bool) or
                                     not isinstance(value, (int, float, np.integer, np.floating))) \
            or not math.isfinite(value):
        raise ValueError(f"{name}={value!r}: expected a finite number")
    return float(value)


def _array(name: str, value, shape_text: str, ndim: int, last: tuple | None = None,
           finite: bool = True) -> np.ndarray:
    """A contiguous float64 array with ``ndim`` dims whose last dim is in ``last``; finite values only if ``finite``."""
    arr = np.ascontiguousarray(value, dtype=np.float64)
    if arr.ndim != ndim or (last is not None and arr.shape[-1] not in last):
        raise ValueError(f"{name}: expected shape {shape_text}, got {arr.shape}")
    if finite and not np.isfinite(arr).all():
        raise ValueError(f"{name}: expected finite values")
    return arr


def _window_bounds(v0, w0, limits: UAVLimits, v_cap) -> tuple[float, float, float, float]:
    """(v_lo, v_hi, w_lo, w_hi) of V_s ∩ V_d; a v_cap below one step of braking collapses v onto v_lo."""
    v0 = _finite("v0", v0)
    w0 = _finite("w0", w0)
    tol = 1e-9
    if not limits.v_min - tol <= v0 <= limits.v_max + tol:
        raise ValueError(f"v0={v0!r}: expected a speed inside UAVLimits [v_min, v_max] = "
                         f"[{limits.v_min:g}, {limits.v_max:g}]")
    if not abs(w0) <= limits.w_max + tol:
        raise ValueError(f"w0={w0!r}: expected a yaw rate inside UAVLimits [-w_max, w_max] = "
                         f"[{-limits.w_max:g}, {limits.w_max:g}]")
    v_lo = max(limits.v_min, v0 - limits.a_max * limits.dt)
    v_hi = max(v_lo, min(limits.v_max, v0 + limits.a_max * limits.dt))
    if v_cap is not None:
        v_cap = _finite("v_cap", v_cap)
        if v_cap < 0.0:
            raise ValueError(f"v_cap={v_cap!r}: expected a speed >= 0")
        v_hi = max(v_lo, min(v_hi, v_cap))
    w_lo = max(-limits.w_max, w0 - limits.dw_max * limits.dt)
    w_hi = min(limits.w_max, w0 + limits.dw_max * limits.dt)
    return v_lo, v_hi, w_lo, w_hi


def window_samples(v0: float, w0: float, limits: UAVLimits, cfg: DWAConfig,
                   v_cap: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Flat samples (vs, ws) of the dynamic window V_s ∩ V_d (spec (b1)-(b3)).

    Both end points of each axis are included, and w = 0 whenever it is inside the window, so
    flying straight and the extreme manoeuvres are always candidates. ``v_cap`` lowers the top
    speed (leader cap, deadlock yield); a cap below what one step of braking reaches collapses the
    speed axis onto the hardest braking speed.
    """
    return _window_grid(*_window_bounds(v0, w0, limits, v_cap), cfg.v_res, cfg.w_res)


# ----------------------------------------------------------------------------------- kernels


@numba.njit(cache=True)
def _axis(lo, hi, res):
    """lo, lo + res, ... and hi itself, plus 0 when lo <= 0 <= hi (sorted).

    Grid points within 1e-9 * res of hi or 0 are moved onto them (never lo or hi themselves), so
    rounding does not add a near-duplicate sample. (0 can only matter for w: v_lo >= v_min >= 0.)
    """
    tol = 1e-9 * res
    n = int(math.floor((hi - lo) / res + 1e-9)) + 1
    grid = np.empty(n + 2)  # room for hi and 0
    for i in range(n):
        grid[i] = lo + i * res
    if n > 1 and hi - grid[n - 1] <= tol:
        grid[n - 1] = hi
    elif hi > grid[n - 1]:
        grid[n] = hi
        n += 1
    if lo <= 0.0 <= hi:
        p = 0
        while grid[p] < 0.0:  # first point >= 0; exists because hi >= 0
            p += 1
        if grid[p] != 0.0:
            if p < n - 1 and grid[p] <= tol:
                grid[p] = 0.0
            elif p > 1 and grid[p - 1] >= -tol:
                grid[p - 1] = 0.0
            else:
                for i in range(n, p, -1):
                    grid[i] = grid[i - 1]
                grid[p] = 0.0
                n += 1
    return grid[:n]


@numba.njit(cache=True)
def _window_grid(v_lo, v_hi, w_lo, w_hi, v_res, w_res):
    """All (v, w) pairs of the two axes, flattened v-major."""
    v_axis = _axis(v_lo, v_hi, v_res)
    w_axis = _axis(w_lo, w_hi, w_res)
    vs = np.empty(v_axis.size * w_axis.size)
    ws = np.empty(v_axis.size * w_axis.size)
    for i in range(v_axis.size):
        for j in range(w_axis.size):
            vs[i * w_axis.size + j] = v_axis[i]
            ws[i * w_axis.size + j] = w_axis[j]
    return vs, ws


_SKIP_MARGIN = 1e-9  # m: the geometric skip tests below keep this much slack over float rounding


@numba.njit(cache=True, inline="always")
def _rollout_table(x, y, z, v, vz, dt, yaw, path):
    """Fill ``path`` (n, 3) with the positions after 1..n steps of constant input.

    The arithmetic of ``integrate``, with its yaw sequence precomputed per w (it does not depend on
    v): yaw[k] = (psi_k, cos psi_k, sin psi_k).
    """
    for k in range(path.shape[0]):
        x, y, z = x + v * yaw[k, 1] * dt, y + v * yaw[k, 2] * dt, z + vz * dt
        path[k, 0] = x
        path[k, 1] = y
        path[k, 2] = z


_NEAR_BIN = 0.05  # m: bucket width of the nearest-first order of _nearby


@numba.njit(cache=True)
def _nearby(obstacles, radii, x0, y0, z0, reach, r_uav):
    """The obstacles whose surface is closer than ``reach`` to (x0, y0, z0), copied out once per cycle.

    Returns their centres, their radii plus ``r_uav``, and ``lows``: the obstacles come in buckets of
    ``_NEAR_BIN`` by their clearance at the start point, |o - start| - R_o - r_uav (a counting sort,
    nearest bucket first), and ``lows`` is the lower edge of each one's bucket (-inf for the first),
    so it is non-decreasing and never above that clearance.
    """
    keep = np.empty(obstacles.shape[0], dtype=np.int64)
    bins = np.empty(obstacles.shape[0], dtype=np.int64)
    m = 0
    n_bins = 1
    for o in range(obstacles.shape[0]):
        dx, dy, dz = obstacles[o, 0] - x0, obstacles[o, 1] - y0, obstacles[o, 2] - z0
        lim = reach + radii[o]
        d2 = dx * dx + dy * dy + dz * dz
        if d2 < lim * lim:
            low = math.sqrt(d2) - (radii[o] + r_uav)
            j = int(low / _NEAR_BIN) if low >= _NEAR_BIN else 0
            keep[m] = o
            bins[m] = j
            n_bins = max(n_bins, j + 1)
            m += 1
    start = np.zeros(n_bins + 1, dtype=np.int64)
    for i in range(m):
        start[bins[i] + 1] += 1
    for j in range(n_bins):
        start[j + 1] += start[j]
    near = np.empty((m, 3))
    near_rads = np.empty(m)
    near_lows = np.empty(m)
    for i in range(m):
        j = bins[i]
        at = start[j]
        start[j] += 1
        o = keep[i]
        near[at, 0], near[at, 1], near[at, 2] = obstacles[o, 0], obstacles[o, 1], obstacles[o, 2]
        near_rads[at] = radii[o] + r_uav
        near_lows[at] = j * _NEAR_BIN if j > 0 else -math.inf
    return near, near_rads, near_lows


_BLOCK = 5  # rollout steps per bounding sphere of _static_clearance


@numba.njit(cache=True, inline="always")
def _bounding_sphere(path, k0, k1):
    """The middle point of path[k0:k1] and the farthest distance of those points from it (one pass)."""
    m = (k0 + k1 - 1) // 2
    cx, cy, cz = path[m, 0], path[m, 1], path[m, 2]
    r2 = 0.0
    for k in range(k0, k1):
        dx, dy, dz = path[k, 0] - cx, path[k, 1] - cy, path[k, 2] - cz
        r2 = max(r2, dx * dx + dy * dy + dz * dz)
    return cx, cy, cz, math.sqrt(r2)


@numba.njit(cache=True, inline="always")
def _enclose(spheres, out):
    """Write into ``out`` (4,) a sphere (centre, radius) around all ``spheres`` (n, 4), with _SKIP_MARGIN.

    Centred on their bounding box; the radius reaches the farthest sphere surface.
    """
    lo_x = lo_y = lo_z = math.inf
    hi_x = hi_y = hi_z = -math.inf
    for i in range(spheres.shape[0]):
        bx, by, bz, r = spheres[i, 0], spheres[i, 1], spheres[i, 2], spheres[i, 3]
        lo_x, hi_x = min(lo_x, bx - r), max(hi_x, bx + r)
        lo_y, hi_y = min(lo_y, by - r), max(hi_y, by + r)
        lo_z, hi_z = min(lo_z, bz - r), max(hi_z, bz + r)
    cx, cy, cz = 0.5 * (lo_x + hi_x), 0.5 * (lo_y + hi_y), 0.5 * (lo_z + hi_z)
    r = 0.0
    for i in range(spheres.shape[0]):
        dx, dy, dz = spheres[i, 0] - cx, spheres[i, 1] - cy, spheres[i, 2] - cz
        r = max(r, math.sqrt(dx * dx + dy * dy + dz * dz) + spheres[i, 3])
    out[0], out[1], out[2], out[3] = cx, cy, cz, r + _SKIP_MARGIN


@numba.njit(cache=True, inline="always")
def _path_spheres(path, x0, y0, z0, spheres):
    """Bounding spheres of one rollout; returns a bound on its points' distance from (x0, y0, z0).

    ``spheres`` (n_blocks + 1, 4) gets one sphere per block of ``_BLOCK`` steps, then one around
    those. All keep _SKIP_MARGIN of slack over float rounding.
    """
    n = path.shape[0]
    n_blocks = spheres.shape[0] - 1
    r_start = 0.0
    for b in range(n_blocks):
        bx, by, bz, r = _bounding_sphere(path, b * _BLOCK, min(n, (b + 1) * _BLOCK))
        spheres[b, 0], spheres[b, 1], spheres[b, 2], spheres[b, 3] = bx, by, bz, r + _SKIP_MARGIN
        dx, dy, dz = bx - x0, by - y0, bz - z0
        r_start = max(r_start, math.sqrt(dx * dx + dy * dy + dz * dz) + r)
    _enclose(spheres[:n_blocks], spheres[n_blocks])
    return r_start + 2.0 * _SKIP_MARGIN


@numba.njit(cache=True, inline="always")
def _within(sphere, x, y, z, gap):
    """Whether (x, y, z) is closer than ``gap`` to the sphere (centre, radius) ``sphere``."""
    lim = sphere[3] + gap
    dx, dy, dz = x - sphere[0], y - sphere[1], z - sphere[2]
    return dx * dx + dy * dy + dz * dz < lim * lim


@numba.njit(cache=True)
def _candidates(obstacles, rads, lows, spheres, r_start, bar):
    """The obstacles (in order) that may come closer than ``bar`` to some rollout, and where, once per cycle.

    ``spheres`` (n_samples, n_blocks + 1, 4) and ``r_start`` (the largest reach) come from
    ``_path_spheres``; ``obstacles``, ``rads``, ``lows`` from ``_nearby``. Returns the indices and a
    (n, n_blocks) mask of the blocks that may come that close, tested against spheres around that
    block of every rollout: what is left out is at ``bar`` or beyond for every rollout, with
    _SKIP_MARGIN of slack.
    """
    n_blocks = spheres.shape[1] - 1
    fan = np.empty((n_blocks + 1, 4))
    for b in range(n_blocks + 1):
        _enclose(spheres[:, b], fan[b])
    keep = np.empty(obstacles.shape[0], dtype=np.int64)
    mask = np.empty((obstacles.shape[0], n_blocks), dtype=np.bool_)
    n = 0
    for o in range(obstacles.shape[0]):
        if lows[o] >= r_start + bar:
            break
        ox, oy, oz, gap = obstacles[o, 0], obstacles[o, 1], obstacles[o, 2], bar + rads[o]
        if not _within(fan[n_blocks], ox, oy, oz, gap):
            continue
        close = False
        for b in range(n_blocks):
            mask[n, b] = _within(fan[b], ox, oy, oz, gap)
            close |= mask[n, b]
        if close:
            keep[n] = o
            n += 1
    return keep[:n], mask[:n]


@numba.njit(cache=True, inline="always")
def _obstacle_clearance(path, k0, k1, ox, oy, oz, rad):
    """min |p_k - o| - rad over path[k0:k1] with one square root: sqrt and - are monotone in floating point."""
    d2_min = math.inf
    for k in range(k0, k1):
        dx, dy, dz = path[k, 0] - ox, path[k, 1] - oy, path[k, 2] - oz
        d2 = dx * dx + dy * dy + dz * dz
        if d2 < d2_min:
            d2_min = d2
    return math.sqrt(d2_min) - rad


@numba.njit(cache=True)
def _search_starts(paths, spheres, obstacles, rads, caps, stop_below):
    """Where each sample's clearance search starts: its cap, or an attained value below it.

    The attained value is the clearance of the obstacle nearest the centre of the middle rollout,
    which is likely near all of them; it is raised to ``stop_below`` where it is below (there the
    first value below ``stop_below`` in the visiting order is searched for instead).
    """
    mid = spheres[paths.shape[0] // 2, spheres.shape[1] - 1]
    seed, near = -1, math.inf
    for o in range(obstacles.shape[0]):
        dx, dy, dz = obstacles[o, 0] - mid[0], obstacles[o, 1] - mid[1], obstacles[o, 2] - mid[2]
        c = math.sqrt(dx * dx + dy * dy + dz * dz) - rads[o]
        if c < near:
            seed, near = o, c
    start = caps.copy()
    if seed >= 0:
        for i in range(paths.shape[0]):
            c = _obstacle_clearance(paths[i], 0, paths.shape[1], obstacles[seed, 0], obstacles[seed, 1],
                                    obstacles[seed, 2], rads[seed])
            if c < caps[i]:
                start[i] = max(c, stop_below[i])
    return start


@numba.njit(cache=True, inline="always")
def _static_clearance(path, spheres, r_start, obstacles, rads, lows, keep, mask, best, stop_below):
    """min_k min_o |p_k - o| - R_o - r_uav over the rollout, exact below the start ``best`` (spec (b5)).

    ``best`` is the cap or an attained value (``_search_starts``). ``spheres`` and ``r_start`` come
    from ``_path_spheres``; ``obstacles``, ``rads`` (R_o + r_uav) and ``lows`` (non-decreasing lower
    bounds of |o - start| - rads) from ``_nearby``; ``keep`` and ``mask`` from ``_candidates`` with a
    bar of at least ``best``: the only obstacles, and their blocks, that may come closer.
    Returns early once the value drops below ``stop_below`` (d_brake: the sample is inadmissible
    whatever the exact value), with the first such block value in the visiting order (obstacles
    as ``_nearby`` lists them, blocks along the rollout). Otherwise the minimum does not depend on
    the order in which obstacles and points are visited; nearest first finds a small minimum early.
    Only obstacles that cannot lower the current minimum are passed over, each bound with
    ``_SKIP_MARGIN`` of slack over float rounding: those whose surface is farther than the minimum
    from the sphere around the start through the rollout's farthest point end the loop (by bucket,
    nearest first); those farther from the bounding sphere of the whole rollout, or of a block of
    ``_BLOCK`` steps, are skipped. A block that may come closer is evaluated whole
    (``_obstacle_clearance``): its exact minimum.
    """
    n = path.shape[0]
    n_blocks = spheres.shape[0] - 1
    for q in range(keep.shape[0]):
        o = keep[q]
        if lows[o] >= r_start + best:
            break
        ox, oy, oz = obstacles[o, 0], obstacles[o, 1], obstacles[o, 2]
        rad = rads[o]
        if not _within(spheres[n_blocks], ox, oy, oz, best + rad):
            continue
        for b in range(n_blocks):
            if not mask[q, b] or not _within(spheres[b], ox, oy, oz, best + rad):
                continue
            c = _obstacle_clearance(path, b * _BLOCK, min(n, (b + 1) * _BLOCK), ox, oy, oz, rad)
            if c < best:
                best = c
                if best < stop_below:
                    return best
    return best


@numba.njit(cache=True)
def _mover_track(dt, n_steps, movers_pos, movers_vel):
    """(K, n_steps, 3): the movers at t_k = (k + 1) dt, predicted at constant velocity (spec (g6))."""
    track = np.empty((movers_pos.shape[0], n_steps, 3))
    for m in range(movers_pos.shape[0]):
        for k in range(n_steps):
            t = (k + 1) * dt
            for j in range(3):
                track[m, k, j] = movers_pos[m, j] + movers_vel[m, j] * t
    return track


@numba.njit(cache=True, inline="always")
def _mover_clearance(path, track, R_uu):
    """min_k min_m |p_k - m(t_k)| - R_uu for the predicted mover positions ``track`` (``_mover_track``).

    Returns the first value below 0 (in mover-major order) as soon as one turns up. The square
    root is taken only for a new smallest squared distance: sqrt and the subtraction are monotone
    in floating point, so this is the same minimum.
    """
    best = math.inf
    best_d2 = math.inf
    for m in range(track.shape[0]):
        for k in range(path.shape[0]):
            dx = path[k, 0] - track[m, k, 0]
            dy = path[k, 1] - track[m, k, 1]
            dz = path[k, 2] - track[m, k, 2]
            d2 = dx * dx + dy * dy + dz * dz
            if d2 < best_d2:
                best_d2 = d2
                best = math.sqrt(d2) - R_uu
                if best < 0.0:
                    return best
    return best


@numba.njit(cache=True)
def _heading(bearing, psi_end):
    """Standard azimuth term (pi - |theta|)/pi with theta = wrap(bearing - psi_end) (eq. 5)."""
    return (math.pi - abs(wrap(bearing - psi_end))) / math.pi


@numba.njit(cache=True)
def _alignment(ax, ay, bx, by, psi_end):
    """Cosine c between the global direction a and the endpoint direction b (spec (c3)).

    A vanishing a (lookahead at the UAV) gives c = 1, i.e. the full weight alpha0.
    """
    a_norm = math.hypot(ax, ay)
    if a_norm < 1e-9:
        return 1.0
    b_norm = math.hypot(bx, by)
    if b_norm < 1e-3:
        bx, by, b_norm = math.cos(psi_end), math.sin(psi_end), 1.0
    return min(1.0, max(-1.0, (ax * bx + ay * by) / (a_norm * b_norm)))


@numba.njit(cache=True)
def _heading_weight(alignment, alpha0, kappa):
    """alpha = alpha0 * (kappa + (1 - kappa) * (1 + c) / 2) (eq. 10): alpha0 aligned, kappa*alpha0 opposite."""
    return alpha0 * (kappa + (1.0 - kappa) * 0.5 * (1.0 + alignment))


@numba.njit(cache=True)
def _normalise(term, admissible, minmax):
    """The term over the admissible set divided by its sum (b8) or mapped min-max to [0, 1].

    A term whose sum is 0 (or which is constant, for min-max) cannot rank samples and becomes 0.
    """
    out = np.zeros(term.shape[0])
    total, lo, hi = 0.0, math.inf, -math.inf
    for i in range(term.shape[0]):
        if admissible[i]:
            total += term[i]
            lo = min(lo, term[i])
            hi = max(hi, term[i])
    if minmax:
        span = hi - lo
        if span <= _TIE_TOL * max(1.0, abs(hi)):
            return out
        for i in range(term.shape[0]):
            if admissible[i]:
                out[i] = (term[i] - lo) / span
    elif total != 0.0:
        for i in range(term.shape[0]):
            if admissible[i]:
                out[i] = term[i] / total
    return out


@numba.njit(cache=True)
def _select(score, vs, ws):
    """Index of the best score; ties go to the smaller |w|, then the larger v (spec (c5)); -1 if none."""
    best = -math.inf
    for i in range(score.shape[0]):
        best = max(best, score[i])
    if best == -math.inf:
        return -1
    tol = _TIE_TOL * max(1.0, abs(best))
    pick = -1
    for i in range(score.shape[0]):
        if score[i] < best - tol:
            continue
        if pick < 0:
            pick = i
            continue
        dw = abs(ws[i]) - abs(ws[pick])
        if dw < -_TIE_TOL or (dw <= _TIE_TOL and vs[i] > vs[pick]):
            pick = i
    return pick


@numba.njit(cache=True)
def _yaw_table(psi0, w_axis, dt, n_steps):
    """(n_w, n_steps, 3): psi_k, cos psi_k, sin psi_k of the rollout of each w, stepped as ``integrate`` does.

    The yaw sequence does not depend on v. The wrap chains of all w advance step by step together:
    they are independent, so the CPU overlaps them.
    """
    yaw = np.empty((w_axis.size, n_steps, 3))
    for j in range(w_axis.size):
        yaw[j, 0, 0] = wrap(psi0 + w_axis[j] * dt)
    for k in range(1, n_steps):
        for j in range(w_axis.size):
            yaw[j, k, 0] = wrap(yaw[j, k - 1, 0] + w_axis[j] * dt)
    for j in range(w_axis.size):
        for k in range(n_steps):
            yaw[j, k, 1] = math.cos(yaw[j, k, 0])
            yaw[j, k, 2] = math.sin(yaw[j, k, 0])
    return yaw


class _Params(NamedTuple):
    """Everything of one planning cycle that ``_plan_kernel`` reads besides the state, the window's bounds and
    the obstacles: the sample spacing, the rollout model and UAV limits, the clearance caps, the neighbour
    separation and every input of the eq. 12 score.

    ``lam`` < 1 blends the heading with distance progress (E8); ``vel_target`` < 0 means the plain
    v / v_max term, otherwise 1 - |v - vel_target| / v_max; ``rot_ref`` is 0 (|w|) or w0 (|w - w0|);
    ``mover_dist``: the movers' clearance counts in the dist term (else only in admissibility).
    """

    v_res: float
    w_res: float
    vz: float
    dt: float
    n_steps: int
    r_uav: float
    a_max: float
    v_max: float
    w_max: float
    D_cap: float
    dist_cap: float
    R_uu: float
    goal_x: float
    goal_y: float
    la_x: float
    la_y: float
    heading_from_current: bool
    lam: float
    progress_reach: float
    vel_target: float
    rot_ref: float
    alpha: float
    kappa: float
    alpha_per_candidate: bool
    beta: float
    gamma: float
    eps: float
    minmax: bool
    drift_x: float
    drift_y: float
    brake_share: float
    mover_dist: bool


@numba.njit(cache=True)
def _plan_kernel(state, v_lo, v_hi, w_lo, w_hi, obstacles, radii, movers_pos, movers_vel, params, exact_clearance):
    """Window sampling, rollout, clearance, admissibility and the eq. 12 score of every sample.

    The window is [v_lo, v_hi] x [w_lo, w_hi]; ``params``: the fields of a ``_Params``, in order, as a plain
    tuple, made a ``_Params`` again here (as ``vfh3d._cycle_kernel`` does with its setup: numba types a new named
    tuple passed from Python on its slow path, about 5 us a call more). ``exact_clearance`` evaluates
    inadmissible samples to the end instead of stopping early.
    """
    p = _Params(*params)
    dt, n_steps, vz, drift_x, drift_y = p.dt, p.n_steps, p.vz, p.drift_x, p.drift_y
    w_axis = _axis(w_lo, w_hi, p.w_res)
    n_w = w_axis.size
    vs, ws = _window_grid(v_lo, v_hi, w_lo, w_hi, p.v_res, p.w_res)
    n_samples = vs.shape[0]
    x0, y0, z0, psi0 = state[0], state[1], state[2], state[3]
    # brake_share < 1: each rollout runs on for the stopping time of the window's top speed (its free arc)
    n_roll = n_steps + (int(math.ceil(v_hi / (2.0 * p.a_max) / dt - 1e-9)) if p.brake_share < 1.0 else 0)
    yaw = _yaw_table(psi0, w_axis, dt, n_roll)
    track = _mover_track(dt, n_steps, movers_pos, movers_vel)
    n_blocks = (n_roll + _BLOCK - 1) // _BLOCK
    paths = np.empty((n_samples, n_roll, 3))
    spheres = np.empty((n_samples, n_blocks + 1, 4))
    reach = np.empty(n_samples)
    drifting = drift_x != 0.0 or drift_y != 0.0
    for i in range(n_samples):
        _rollout_table(x0, y0, z0, vs[i], vz, dt, yaw[i % n_w], paths[i])
        if drifting:                                    # the wind carries every rollout along
            for k in range(n_roll):
                paths[i, k, 0] += drift_x * (k + 1) * dt
                paths[i, k, 1] += drift_y * (k + 1) * dt
        reach[i] = _path_spheres(paths[i], x0, y0, z0, spheres[i])
    clearance = np.empty(n_samples)
    admissible = np.zeros(n_samples, dtype=np.bool_)
    endpoint = np.empty((n_samples, 3))
    alignment = np.empty(n_samples)
    heading = np.empty(n_samples)
    dist = np.empty(n_samples)
    vel = np.empty(n_samples)
    rot = np.empty(n_samples)
    rho_d = math.hypot(p.goal_x - x0, p.goal_y - y0)
    bearing_now = math.atan2(p.goal_y - y0, p.goal_x - x0)
    # no rollout gets farther than the fastest one; beyond its reach plus the clearance cap nothing counts
    far = (dt * n_roll * (math.sqrt(v_hi * v_hi + vz * vz) + math.hypot(drift_x, drift_y))
           + max(p.D_cap, v_hi * v_hi / (2.0 * p.a_max)) + p.r_uav)
    obstacles, rads, lows = _nearby(obstacles, radii, x0, y0, z0, far, p.r_uav)
    d_brake = p.brake_share * (vs * vs / (2.0 * p.a_max))   # share 1: exactly v^2 / (2 a_max)
    caps = np.maximum(p.D_cap, d_brake)
    stop_below = np.full(n_samples, -math.inf) if exact_clearance else d_brake
    # every search starts at its cap or an attained value; one candidate list serves all rollouts
    start = _search_starts(paths, spheres, obstacles, rads, caps, stop_below)
    keep, mask = _candidates(obstacles, rads, lows, spheres, reach.max(), start.max())
    for i in range(n_samples):
        v, w, path = vs[i], ws[i], paths[i]
        c = _static_clearance(path, spheres[i], reach[i], obstacles, rads, lows, keep, mask, start[i], stop_below[i])
        ok = c > 0.0 and c >= d_brake[i]
        d = c
        if (ok or exact_clearance) and movers_pos.shape[0] > 0:
            c_mover = _mover_clearance(path[:n_steps], track, p.R_uu)
            ok = ok and c_mover >= 0.0
            c = min(c, c_mover)
            if p.mover_dist:
                d = c
        clearance[i] = c
        dist[i] = min(d, p.dist_cap)
        admissible[i] = ok
        ex, ey, psi_end = path[n_steps - 1, 0], path[n_steps - 1, 1], yaw[i % n_w, n_steps - 1, 0]
        endpoint[i, :] = path[n_steps - 1]
        alignment[i] = _alignment(p.la_x - x0, p.la_y - y0, ex - x0, ey - y0, psi_end)
        bearing = bearing_now if p.heading_from_current else math.atan2(p.goal_y - ey, p.goal_x - ex)
        h = _heading(bearing, psi_end)
        if p.lam < 1.0:  # E8 (eq. 8): blend with the distance progress Dg
            progress = 1.0 - math.hypot(p.goal_x - ex, p.goal_y - ey) / (rho_d + p.progress_reach)
            h = p.lam * h + (1.0 - p.lam) * progress
        heading[i] = h
        vel[i] = v / p.v_max if p.vel_target < 0.0 else 1.0 - abs(v - p.vel_target) / p.v_max
        rot[i] = 1.0 - abs(w - p.rot_ref) / p.w_max
    h_hat = _normalise(heading, admissible, p.minmax)
    d_hat = _normalise(dist, admissible, p.minmax)
    v_hat = _normalise(vel, admissible, p.minmax)
    r_hat = _normalise(rot, admissible, p.minmax)
    score = np.empty(n_samples)
    for i in range(n_samples):
        score[i] = -math.inf
        if admissible[i]:
            a = _heading_weight(alignment[i], p.alpha, p.kappa) if p.alpha_per_candidate else p.alpha
            score[i] = a * h_hat[i] + p.beta * d_hat[i] + p.gamma * v_hat[i] + p.eps * r_hat[i]
    return _select(score, vs, ws), vs, ws, score, clearance, admissible, endpoint, alignment


# ----------------------------------------------------------------------------------- planner


def _plan_arrays(state, goal, lookahead, obstacles, obstacle_radius, movers_pos, movers_vel, finite: bool):
    """dwa_plan's array arguments as contiguous float64 of checked shapes; values checked too if ``finite``.

    ``finite=False`` leaves the values to one ``_valid_values`` call, the cheap common case.
    """
    state = _array("state", state, "(7,) [x, y, z, psi, v, w, vz]", 1, (7,), finite)
    goal_xy = _array("goal", goal, "(2,) or (3,)", 1, (2, 3), finite)
    la_xy = goal_xy if lookahead is None else _array("lookahead", lookahead, "(2,) or (3,)", 1, (2, 3), finite)
    obstacles = np.empty((0, 3)) if np.size(obstacles) == 0 else \
        _array("obstacles", obstacles, "(M, 3)", 2, (3,), finite)
    radii = np.full(obstacles.shape[0], _finite("obstacle_radius", np.asarray(obstacle_radius).item())) \
        if np.ndim(obstacle_radius) == 0 else _array("obstacle_radius", obstacle_radius, "(M,)", 1, None, finite)
    if radii.shape != (obstacles.shape[0],) or (finite and not (radii >= 0).all()):
        raise ValueError(f"obstacle_radius: expected one radius >= 0 per obstacle ({obstacles.shape[0]}) or a "
                         f"single number, got shape {radii.shape}")
    if (movers_pos is None) != (movers_vel is None):
        raise ValueError("movers_pos, movers_vel: pass both (K, 3) arrays or neither")
    if movers_pos is None:
        movers_pos = movers_vel = np.empty((0, 3))
    else:
        movers_pos = _array("movers_pos", movers_pos, "(K, 3)", 2, (3,), finite)
        movers_vel = _array("movers_vel", movers_vel, "(K, 3)", 2, (3,), finite)
        if movers_pos.shape != movers_vel.shape:
            raise ValueError(f"movers_pos {movers_pos.shape} and movers_vel {movers_vel.shape}: expected equal shapes")
    return state, goal_xy, la_xy, obstacles, radii, movers_pos, movers_vel


@numba.njit(cache=True, inline="always")
def _all_finite(arr):
    """Whether every value of a contiguous array is finite; branch-free, so the loop vectorises."""
    flat = arr.ravel()
    ok = True
    for i in range(flat.size):
        ok &= abs(flat[i]) <= _FLOAT_MAX
    return ok


@numba.njit(cache=True)
def _valid_values(state, goal, lookahead, obstacles, radii, movers_pos, movers_vel):
    """Whether every value is finite and every radius >= 0 (``_plan_arrays``' value checks in one call)."""
    ok = True
    for r in radii:
        ok &= r >= 0.0  # False for nan too
    return (ok and _all_finite(state) and _all_finite(goal) and _all_finite(lookahead) and _all_finite(obstacles)
            and _all_finite(movers_pos) and _all_finite(movers_vel))


def _rotation_weight(cfg: DWAConfig, clearance_now: float, prev_alignment: float) -> float:
    """eps_t of eq. 11: eps0 in open space fading to 0 near obstacles, or eps0 * (1 + c_prev) / 2."""
    if not cfg.use_rotation_cost:
        return 0.0
    if cfg.rot_weight_mode == "alignment":
        return cfg.eps0 * 0.5 * (1.0 + prev_alignment)
    return cfg.eps0 * min(1.0, max(0.0, (clearance_now - cfg.d_in) / (cfg.d_out - cfg.d_in)))


def dwa_plan(state, limits: UAVLimits, cfg: DWAConfig, goal, obstacles, obstacle_radius, *,
             vz_cmd: float = 0.0, lookahead=None, clearance_now: float = math.inf, movers_pos=None,
             movers_vel=None, v_ref: float | None = None, v_cap: float | None = None,
             prev_alignment: float | None = None, drift=None, brake_share: float | None = None,
             mover_dist: bool = True, goal_distance: float | None = None) -> DWAResult:
    """One DWA planning cycle: the best admissible (v, w) of the dynamic window (spec (b), (c)).

    state: (7,) row (x, y, z, psi, v, w, vz). goal, lookahead: (2,) or (3,); only x, y are used;
    lookahead is P_LA of E10 (None -> goal). obstacles: (M, 3) centres with radius R_o
    (``obstacle_radius`` (M,) or one number); the clearance is |p_k - o| - R_o - r_uav.
    clearance_now: the UAV's current clearance d_min (E11 proximity weight).
    movers_pos, movers_vel: (K, 3) neighbours, predicted at constant velocity and compared at the
    same time step; a sample closer than R_uu to one is inadmissible and, with ``mover_dist`` (False: a
    leader given right of way, ``ExpertConfig.leader_right_of_way``), the gap minus R_uu counts in the dist
    term. The braking test (``brake_share``) applies to static obstacles only: braking does not open the
    gap to a moving neighbour, and it would forbid formation speed at 2 m spacing.
    v_ref: follower speed matching of spec (g2), vel = 1 - |v - v_ref| / v_max (overrides the
    approach speed profile). v_cap: speed cap (leader cap, deadlock yield).
    prev_alignment: c of the previous cycle's choice (E10 per_step, E11 alignment; None -> 1).
    drift: (2,) horizontal velocity (m/s) added to every rollout, e.g. a wind estimate (None: still air).
    brake_share: this cycle's ``DWAConfig.brake_share`` (None: the config's).
    goal_distance: rho_D of E8's blend and of the approach speed profile: the distance to where the UAV has to
    stop (None: the distance to ``goal``; inf: it only steers toward ``goal``, e.g. a path's lookahead point).
    If no sample is admissible, brakes: v = v_lo (= max(0, v0 - a_max dt) for v_min = 0), w = w0.
    """
    try:
        arrays = _plan_arrays(state, goal, lookahead, obstacles, obstacle_radius, movers_pos, movers_vel, False)
        checked = _valid_values(*arrays)
    except ValueError:
        checked = False
    if not checked:  # the full checks raise for the first bad argument, in argument order
        arrays = _plan_arrays(state, goal, lookahead, obstacles, obstacle_radius, movers_pos, movers_vel, True)
    state, goal_xy, la_xy, obstacles, radii, movers_pos, movers_vel = arrays
    x, y, _, _, v0, w0, _ = state.tolist()  # Python floats: cheaper than numpy scalars in the glue below
    goal_x, goal_y = goal_xy.tolist()[:2]
    la_x, la_y = la_xy.tolist()[:2]
    vz_cmd = _finite("vz_cmd", vz_cmd)
    if math.isnan(clearance_now):
        raise ValueError("clearance_now=nan: expected a number (inf in open space)")
    if prev_alignment is None:
        prev_alignment = 1.0
    elif not -1.0 <= _finite("prev_alignment", prev_alignment) <= 1.0:
        raise ValueError(f"prev_alignment={prev_alignment!r}: expected a cosine in [-1, 1]")
    if v_ref is not None and not 0.0 <= _finite("v_ref", v_ref) <= limits.v_max:
        raise ValueError(f"v_ref={v_ref!r}: expected a speed in [0, UAVLimits.v_max={limits.v_max:g}]")
    drift_x = drift_y = 0.0
    if drift is not None:
        d = np.asarray(drift, dtype=np.float64)
        if d.shape != (2,) or not np.all(np.isfinite(d)):
            raise ValueError(f"drift={drift!r}: expected a finite (2,) horizontal velocity in m/s")
        drift_x, drift_y = float(d[0]), float(d[1])
    if brake_share is None:
        brake_share = cfg.brake_share
    elif not 0.0 <= _finite("brake_share", brake_share) <= 1.0:
        raise ValueError(f"brake_share={brake_share!r}: expected a share in [0, 1]")
    if not isinstance(mover_dist, bool):
        raise ValueError(f"mover_dist={mover_dist!r}: expected True or False")
    if goal_distance is not None and (isinstance(goal_distance, bool) or not isinstance(goal_distance, (int, float))
                                      or not goal_distance >= 0.0):
        raise ValueError(f"goal_distance={goal_distance!r}: expected a distance >= 0 (inf: no stop ahead) or None")
    n_steps = round(cfg.T_p / limits.dt)
    if n_steps < 1:
        raise ValueError(f"DWAConfig.T_p={cfg.T_p!r} is shorter than one step (UAVLimits.dt={limits.dt!r})")

    v_lo, v_hi, w_lo, w_hi = _window_bounds(v0, w0, limits, v_cap)
    reach = limits.v_max * cfg.T_p
    rho_d = math.hypot(goal_x - x, goal_y - y) if goal_distance is None else float(goal_distance)
    lam = min(1.0, rho_d / (reach if cfg.R_sw is None else cfg.R_sw)) if cfg.use_goal_dist_correction else 1.0
    if v_ref is not None:
        vel_target = v_ref
    elif cfg.approach_speed_profile and lam < 1.0:
        vel_target = min(limits.v_max, math.sqrt(2.0 * limits.a_max * max(rho_d - cfg.r_goal, 0.0)))
    else:
        vel_target = -1.0
    per_candidate = cfg.use_astar_weight and cfg.astar_weight_mode == "per_candidate"
    if not cfg.use_astar_weight:
        alpha = cfg.alpha
    elif per_candidate:
        alpha = cfg.alpha0
    else:
        alpha = _heading_weight(prev_alignment, cfg.alpha0, cfg.kappa)

    params = _Params(float(cfg.v_res), float(cfg.w_res), float(vz_cmd), float(limits.dt), int(n_steps),
                     float(limits.r_uav), float(limits.a_max), float(limits.v_max), float(limits.w_max),
                     float(cfg.D_cap), float(cfg.D_cap if cfg.dist_cap is None else cfg.dist_cap), float(cfg.R_uu),
                     goal_x, goal_y, la_x, la_y, cfg.heading_ref == "current", float(lam), float(reach),
                     float(vel_target), float(w0 if cfg.rotation_mode == "delta" else 0.0), float(alpha),
                     float(cfg.kappa), per_candidate, float(cfg.beta), float(cfg.gamma),
                     float(_rotation_weight(cfg, clearance_now, prev_alignment)), cfg.norm == "minmax",
                     drift_x, drift_y, float(brake_share), mover_dist)
    params = tuple(params)             # plain: see _plan_kernel

    def run(v_lo_, v_hi_, w_lo_, w_hi_, exact_clearance):
        return _plan_kernel(state, v_lo_, v_hi_, w_lo_, w_hi_, obstacles, radii, movers_pos, movers_vel, params,
                            exact_clearance)

    pick, vs, ws, score, clearance, admissible, endpoint, alignment = run(v_lo, v_hi, w_lo, w_hi, False)
    candidates = DWACandidates(vs, ws, admissible, clearance, score, endpoint)
    if pick >= 0:
        return DWAResult(vs.item(pick), ws.item(pick), True, int(np.count_nonzero(admissible)), score.item(pick),
                         endpoint[pick].copy(), clearance.item(pick), alignment.item(pick), candidates)
    brake_w = min(max(w0, w_lo), w_hi)
    _, _, _, _, brake_clearance, _, brake_end, brake_alignment = run(v_lo, v_lo, brake_w, brake_w, True)
    return DWAResult(v_lo, brake_w, False, 0, math.nan, brake_end[0].copy(), brake_clearance.item(0),
                     brake_alignment.item(0), candidates)


def geofence_points(pos, reach: float, lo, hi, spacing: float) -> np.ndarray:
    """Points on the world's vertical x/y bound planes within ``reach`` of ``pos``, at its altitude: the bounds
    (a crash in the env) as DWA obstacles, ``spacing`` apart."""
    pts = []
    pos = (float(pos[0]), float(pos[1]), float(pos[2]))    # Python floats: cheaper than numpy scalars here
    for axis in (0, 1):
        other = 1 - axis
        for bound in (float(lo[axis]), float(hi[axis])):
            gap = abs(pos[axis] - bound)
            if gap >= reach:
                continue
            half = math.sqrt(reach ** 2 - gap ** 2)
            t = np.arange(pos[other] - half, pos[other] + half + spacing, spacing)
            p = np.empty((t.size, 3))
            p[:, axis] = bound
            p[:, other] = t
            p[:, 2] = pos[2]
            pts.append(p)
    return np.concatenate(pts) if pts else np.empty((0, 3))


def project_to_altitude(obstacles: np.ndarray, z: float, band: float) -> np.ndarray:
    """Planar DWA (spec (g5), the 2D baseline): the voxels within ``band`` of the flight altitude, put at it."""
    keep = np.abs(obstacles[:, 2] - z) <= band
    out = obstacles[keep].copy()
    out[:, 2] = z
    return out
