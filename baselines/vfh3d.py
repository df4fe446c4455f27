"""3D VFH+ (spec (f)): from occupied voxels to one free flight direction per planning cycle.

Stages: primary histogram (``uavform_env.polar_histogram``), turning and climbing limits (f3),
binary histogram with hysteresis (f4), masked histogram (f5), open-window detection and the
three-term cost (f6), plus the optional DP passage cost (f7). All histograms here are in the world
frame (column 0 starts at azimuth 0 = +x). Each function is pure except ``vfh3d_step``, which keeps the
per-UAV memory (binary histogram, previous selection) in a ``VFHState``.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, fields
from typing import ClassVar, NamedTuple

import numba
import numpy as np

from uavform_env.config import Config, UAVLimits, check_range, in_range, integer, one_of, optional
from uavform_env.dynamics import wrap
from uavform_env.polar_histogram import (ENLARGE_MODES, WEIGHT_RELATIONS, _primary_kernel, cell_geometry,
                                         cell_index, histogram_shape, weight_constants, width_steps)


@dataclass(frozen=True)
class VFHConfig(Config):
    """Parameters of 3D VFH+ (spec (f0)); ``None`` fields are derived per call.

    ``r_e`` None -> r_uav + r_safe + voxel size; ``b`` None -> ``weight_constants(a, R_w, r_e,
    weight_relation, voxel_size)`` (an explicit ``b`` overrides the relation);
    ``neighbour_r_extra`` None -> r_uav, the extra enlargement of neighbour pseudo-voxels (spec (g6)).
    ``enlarge_mode`` and ``weight_relation`` are the [X] switches of spec (f2); ``k4`` weighs the
    [X] DP passage cost of spec (f7) (0 = pure 3D VFH+).
    """

    alpha_h: float = math.radians(5.0)
    R_w: float = 5.0
    r_e: float | None = None
    a: float = 2.0
    b: float | None = None
    tau_low: float = 0.3
    tau_high: float = 0.9
    win: int = 2
    k1: float = 5.0
    k2: float = 2.0
    k3: float = 2.0
    k4: float = 0.0
    enlarge_mode: str = "ceil_2d"
    weight_relation: str = "edge_equals_one"
    neighbour_r_extra: float | None = None

    BOUNDS: ClassVar[dict] = {
        "alpha_h": in_range(0.0, math.pi / 2, lo_open=True),
        "R_w": in_range(0.0, 100.0, lo_open=True),
        "a": in_range(0.0, lo_open=True),
        "b": optional(in_range(0.0, lo_open=True)),
        "tau_low": in_range(0.0),
        "win": integer(0, 90),
        **{name: in_range(0.0) for name in ("k1", "k2", "k3", "k4")},
        "enlarge_mode": one_of(ENLARGE_MODES),
        "weight_relation": one_of(WEIGHT_RELATIONS),
        "neighbour_r_extra": optional(in_range(0.0)),
    }

    def __post_init__(self):
        super().__post_init__()
        o = "VFHConfig"
        try:
            histogram_shape(self.alpha_h)
        except ValueError as err:
            raise ValueError(f"{o}.alpha_h: {err}") from None
        if self.r_e is not None:
            check_range(o, "r_e", self.r_e, 0.0, self.R_w, lo_open=True, hi_open=True)    # bounded by R_w
        check_range(o, "tau_high", self.tau_high, self.tau_low, None)                     # bounded by tau_low

    @functools.lru_cache(maxsize=32)  # noqa: B019 - frozen, hashable config; called every cycle
    def resolve(self, limits: UAVLimits, voxel_size: float) -> tuple[float, float, float, float]:
        """(r_e, a, b, neighbour_r_extra) with the ``None`` defaults filled in; the edge weight must stay positive."""
        if not voxel_size > 0.0:
            raise ValueError(f"voxel_size={voxel_size!r}: expected a positive edge length")
        r_e = limits.r_uav + limits.r_safe + voxel_size if self.r_e is None else self.r_e
        if not r_e < self.R_w:
            raise ValueError(f"VFHConfig: enlargement radius r_e={r_e:g} must be smaller than R_w={self.R_w:g}")
        if self.b is None:
            a, b = weight_constants(self.a, self.R_w, r_e, self.weight_relation, voxel_size)
        else:
            a, b = self.a, self.b
            if not a - b * (self.R_w - r_e) > 0.0:
                raise ValueError(f"VFHConfig: a={a:g}, b={b:g} make voxels at the region edge weigh "
                                 f"{a - b * (self.R_w - r_e):g}; expected a positive weight")
        extra = limits.r_uav if self.neighbour_r_extra is None else self.neighbour_r_extra
        return r_e, a, b, extra


@dataclass
class VFHState:
    """Per-UAV memory between cycles: the binary histogram (hysteresis) and the last selected direction."""

    binary: np.ndarray | None = None
    previous_dir: np.ndarray | None = None

    def reset(self) -> None:
        self.binary = None
        self.previous_dir = None


@dataclass
class VFHResult:
    """One cycle's outcome. When ``blocked`` (no open window) azimuth, elevation and direction are NaN.

    ``window_open`` is ``open_cells(masked, win)``, the candidates the selection already computed.
    """

    blocked: bool
    azimuth: float
    elevation: float
    direction: np.ndarray
    emergency: bool
    primary: np.ndarray
    binary: np.ndarray
    masked: np.ndarray
    n_candidates: int
    window_open: np.ndarray | None = None


@numba.njit(cache=True)
def _turning_kernel(centres, probs, r_e, pos, psi, r_t, R_w):
    """(delta_R, delta_L): nearest blocked offsets from psi on each side among the active voxels (spec (f3)).

    Hovering (r_t < 1 mm) restricts nothing: a multirotor can yaw in place.
    """
    if r_t < 1e-3:
        return -math.pi, math.pi
    s = r_t * math.sin(psi)
    c = r_t * math.cos(psi)
    delta_r, delta_l = -math.pi, math.pi
    for i in range(centres.shape[0]):
        qx = centres[i, 0] - pos[0]
        qy = centres[i, 1] - pos[1]
        qz = centres[i, 2] - pos[2]
        if abs(qz) > r_e[i] or probs[i] <= 0.5 or qx * qx + qy * qy + qz * qz > R_w * R_w:
            continue
        reach = r_t + r_e[i]
        delta = wrap(math.atan2(qy, qx) - psi)
        if delta < 0.0:
            if delta > delta_r and math.hypot(qx - s, qy + c) < reach:
                delta_r = delta
        elif delta < delta_l and math.hypot(qx + s, qy - c) < reach:
            delta_l = delta
    return delta_r, delta_l


def turning_limits(centres, pos, psi: float, v: float, limits: UAVLimits, r_e) -> tuple[float, float]:
    """Right/left limit offsets (delta_R, delta_L) from the heading psi (spec (f3)).

    An active voxel within r_e of the flight level that overlaps the enlarged right (left) turning
    circle, centre r_t (sin psi, -cos psi) (resp. r_t (-sin psi, cos psi)), closes every azimuth beyond
    it on that side. Hovering (r_t < 1 mm) restricts nothing: a multirotor can yaw in place.
    ``centres`` are the active voxels; ``r_e`` is a scalar or one radius per voxel.
    """
    centres = np.ascontiguousarray(centres, dtype=np.float64)
    if centres.ndim != 2 or centres.shape[1] != 3:
        raise ValueError(f"centres: expected shape (M, 3), got {centres.shape}")
    radii = np.ascontiguousarray(np.broadcast_to(np.asarray(r_e, dtype=np.float64), centres.shape[:1]))
    return _turning_kernel(centres, np.ones(centres.shape[0]), radii, np.ascontiguousarray(pos, dtype=np.float64),
                           float(psi), _turn_radius(v, limits), math.inf)


def _turn_radius(v, limits: UAVLimits) -> float:
    """r_t = v / w_max, the radius of the tightest turn at forward speed v."""
    if not v >= 0.0:
        raise ValueError(f"v={v!r}: expected a non-negative forward speed")
    return float(v / limits.w_max)


@numba.njit(cache=True)
def _mask_kernel(binary, psi, delta_r, delta_l, e_max, z, R_w, z_min, z_max, cell, masked):
    n_e, n_z = binary.shape
    restrict = delta_r > -math.pi or delta_l < math.pi
    azimuth_closed = np.zeros(n_z, dtype=np.bool_)
    if restrict:
        for col in range(n_z):
            offset = wrap((col + 0.5) * cell - psi)
            azimuth_closed[col] = not (delta_r < offset < delta_l)
    for e in range(n_e):
        el = -0.5 * math.pi + (e + 0.5) * cell
        reach = z + R_w * math.sin(el)
        row_closed = (abs(el) > e_max + 1e-12 or (el < 0.0 and reach <= z_min)
                      or (el > 0.0 and reach >= z_max))
        for col in range(n_z):
            masked[e, col] = 1 if row_closed or azimuth_closed[col] or binary[e, col] != 0 else 0


def masked_histogram(binary, psi: float, delta_R: float, delta_L: float, e_max: float, z: float, R_w: float,
                     limits: UAVLimits, cell: float) -> np.ndarray:
    """Masked histogram H^m (uint8, 1 = closed) of spec (f5).

    A cell stays open only if it is free in ``binary``, its azimuth offset from psi lies strictly
    between the turning limits, |elevation| <= e_max, and its centre ray does not reach z_min
    (downward) or z_max (upward) within R_w of altitude ``z``.
    """
    shape = histogram_shape(cell)
    binary = np.ascontiguousarray(binary, dtype=np.uint8)
    if binary.shape != shape:
        raise ValueError(f"binary: expected shape {shape} for cell={cell!r}, got {binary.shape}")
    masked = np.empty(shape, dtype=np.uint8)
    _mask_kernel(binary, float(psi), float(delta_R), float(delta_L), float(e_max), float(z), float(R_w),
                 limits.z_min, limits.z_max, float(cell), masked)
    return masked


def update_binary(primary, previous_binary, tau_low: float, tau_high: float) -> np.ndarray:
    """Binary histogram with hysteresis (spec (f4), eq. 18): cells between the thresholds keep their last value."""
    if not 0.0 <= tau_low <= tau_high:
        raise ValueError(f"tau_low={tau_low!r}, tau_high={tau_high!r}: expected 0 <= tau_low <= tau_high")
    primary = np.ascontiguousarray(primary, dtype=np.float64)
    if previous_binary is None:
        previous = np.zeros(primary.shape, dtype=np.uint8)
    else:
        if np.shape(previous_binary) != primary.shape:
            raise ValueError(f"previous_binary: expected shape {primary.shape}, got {np.shape(previous_binary)}")
        previous = np.ascontiguousarray(previous_binary, dtype=np.uint8)
    binary = np.empty(primary.shape, dtype=np.uint8)
    _binary_kernel(primary.ravel(), previous.ravel(), float(tau_low), float(tau_high), binary.ravel())
    return binary


@numba.njit(cache=True)
def _binary_kernel(primary, previous, tau_low, tau_high, out):
    """Eq. 18 cell by cell on flat arrays: 1 above tau_high, 0 below tau_low, else ``previous``."""
    for i in range(primary.size):
        h = primary[i]
        out[i] = 1 if h > tau_high else (0 if h < tau_low else previous[i])


@numba.njit(cache=True)
def _select_kernel(masked, win, units, refs, weights, extra, cell, window_open):
    """Open-window test (spec (f6)) and the cheapest open cell; returns (n_open, row, column, cost).

    The rectangle test is separable: a circular pass along each row, then a pass down the rows where
    rows beyond the poles count as free; both slide a count of closed cells instead of rescanning.
    The row pass copies the row into a buffer padded with its wrapped ends, so the slide needs no
    index wrapping.
    The cost of an open cell is extra[cell] + sum_k weights[k] * angle(cell, refs[k]) / cell, with
    weights > 0 in decreasing order; an empty ``extra`` adds nothing (no 20 kB of zeros to fill and
    read). Cells whose first term alone exceeds the best cost so far are skipped with one dot product
    (extra >= 0, so every term is >= 0), which saves most arc cosines in open space.
    """
    n_e, n_z = masked.shape
    span = 2 * win + 1
    ring = np.empty(n_z + span - 1, dtype=np.int64)  # ring[win + col] = closed flag of column col
    row_closed = np.empty((n_e, n_z), dtype=np.uint8)  # a closed cell among columns col - win .. col + win
    for e in range(n_e):
        for col in range(n_z):
            ring[win + col] = masked[e, col] != 0
        for s in range(win):
            ring[s] = ring[win + (s - win) % n_z]
            ring[win + n_z + s] = ring[win + s % n_z]
        closed = 0
        for s in range(span - 1):
            closed += ring[s]
        for col in range(n_z):
            closed += ring[col + span - 1]
            row_closed[e, col] = closed != 0
            closed -= ring[col]
    window_closed = np.zeros(n_z, dtype=np.int64)  # rows with row_closed among rows e - win .. e + win
    for r in range(min(win, n_e - 1) + 1):
        for col in range(n_z):
            window_closed[col] += row_closed[r, col]
    n_open, best_e, best_z, best_cost = 0, -1, -1, np.inf
    prune_dot = -2.0  # cells with dot(unit, refs[0]) below this cannot beat best_cost
    for e in range(n_e):
        for col in range(n_z):
            free = window_closed[col] == 0
            window_open[e, col] = free
            if not free:
                continue
            n_open += 1
            cost = extra[e, col] if extra.size else 0.0
            for k in range(refs.shape[0]):
                dot = units[e, col, 0] * refs[k, 0] + units[e, col, 1] * refs[k, 1] + units[e, col, 2] * refs[k, 2]
                if k == 0 and dot < prune_dot:
                    cost = np.inf
                    break
                cost += weights[k] * math.acos(min(1.0, max(-1.0, dot))) / cell
            if cost < best_cost:
                best_e, best_z, best_cost = e, col, cost
                if refs.shape[0] > 0:
                    prune_dot = math.cos(min(best_cost * cell / weights[0], math.pi))
        if e + win + 1 < n_e:
            for col in range(n_z):
                window_closed[col] += row_closed[e + win + 1, col]
        if e - win >= 0:
            for col in range(n_z):
                window_closed[col] -= row_closed[e - win, col]
    return n_open, best_e, best_z, best_cost


_NO_NEIGHBOURS = np.zeros((0, 3))  # the neighbour positions of ``_cycle_kernel`` when there are none
_NONE = np.zeros((0, 0))  # no extra cost (``open_cells``), no primary (``select_direction`` when k4 = 0)


def open_cells(masked, win: int) -> np.ndarray:
    """Cells whose whole (2 win + 1)^2 window is free in ``masked`` (azimuth wraps; rows beyond the poles are free)."""
    masked = np.ascontiguousarray(masked, dtype=np.uint8)
    if masked.ndim != 2 or masked.shape[1] != 2 * masked.shape[0]:
        raise ValueError(f"masked: expected an (N_e, 2 N_e) histogram, got shape {masked.shape}")
    if isinstance(win, bool) or not isinstance(win, int) or win < 0:
        raise ValueError(f"win={win!r}: expected a non-negative integer")
    units = cell_geometry(math.pi / masked.shape[0])[2]
    window_open = np.empty(masked.shape, dtype=np.bool_)
    _select_kernel(masked, win, units, np.zeros((0, 3)), np.zeros(0), _NONE, 1.0, window_open)
    return window_open


@numba.njit(cache=True)
def _passage_kernel(weights, e0, z0, out):
    """Minimum monotone path sum from (e0, z0) to every cell, one DP per quadrant (spec (f7))."""
    n_e, n_z = weights.shape
    half = n_z // 2
    dp = np.empty((n_e, half + 1))
    out[:, :] = np.inf
    for se in (-1, 1):
        n_rows = n_e - e0 if se > 0 else e0 + 1
        for sz in (-1, 1):
            for i in range(n_rows):
                e = e0 + se * i
                for j in range(half + 1):
                    z = (z0 + sz * j) % n_z
                    best = 0.0 if i == 0 and j == 0 else np.inf
                    if i > 0:
                        best = dp[i - 1, j]
                    if j > 0 and dp[i, j - 1] < best:
                        best = dp[i, j - 1]
                    dp[i, j] = best + weights[e, z]
                    if dp[i, j] < out[e, z]:
                        out[e, z] = dp[i, j]


def passage_cost(primary, current_cell) -> np.ndarray:
    """P(c): the least obstacle mass summed along a monotone cell path from ``current_cell`` to c (spec (f7)).

    Paths step one row or one column at a time away from the current cell, the azimuth the shorter
    way round, and include both end cells (the grid minimum-path-sum recurrence).
    """
    weights = np.ascontiguousarray(primary, dtype=np.float64)
    if weights.ndim != 2:
        raise ValueError(f"primary: expected a 2D histogram, got shape {weights.shape}")
    e0, z0 = int(current_cell[0]), int(current_cell[1])
    if not (0 <= e0 < weights.shape[0] and 0 <= z0 < weights.shape[1]):
        raise ValueError(f"current_cell={tuple(current_cell)!r}: expected a cell inside {weights.shape}")
    out = np.empty_like(weights)
    _passage_kernel(weights, e0, z0, out)
    return out


def _direction(direction, name: str) -> tuple[float, float, float]:
    """``direction`` as three floats; rejects anything but a finite, non-zero 3-vector."""
    try:
        # A 1-D float array unpacks about three times faster through tolist() than element by element.
        fast = type(direction) is np.ndarray and direction.ndim == 1 and direction.dtype.kind == "f"
        dx, dy, dz = direction.tolist() if fast else direction
        dx, dy, dz = float(dx), float(dy), float(dz)
    except (TypeError, ValueError):
        raise ValueError(f"{name}={direction!r}: expected a 3-vector") from None
    if not (math.isfinite(dx) and math.isfinite(dy) and math.isfinite(dz)) or dx == dy == dz == 0.0:
        raise ValueError(f"{name}={direction!r}: expected a finite, non-zero 3-vector")
    return dx, dy, dz


def _references(target_dir, current_dir, previous_dir, cfg: VFHConfig):
    """(directions, gains) for ``_choose_kernel``: the checked target, current and previous directions, and k1..k3.

    ``previous_dir`` None means the first cycle: the target stands in.
    """
    target = _direction(target_dir, "target_dir")
    current = _direction(current_dir, "current_dir")
    previous = target if previous_dir is None else _direction(previous_dir, "previous_dir")
    return (target, current, previous), (float(cfg.k1), float(cfg.k2), float(cfg.k3))


@numba.njit(cache=True)
def _choose_kernel(masked, primary, directions, gains, k4, win, units, cell):
    """(n_open, row, column, cost, window_open): the cheapest open cell under the cost of spec (f6)-(f7).

    Each direction is binned to its cell and weighed by its gain; references that share a cell merge
    into one angle per distinct cell (steady flight has one), largest weight first since it prunes
    best (equal weights keep the target, current, previous order). The passage cost (k4 > 0) runs
    from the current cell over ``primary``.
    """
    n_e, n_z = masked.shape
    cells = np.empty((3, 2), dtype=np.int64)
    merged = np.zeros(3)
    n = 0
    for k in range(3):
        dx, dy, dz = directions[k]
        row, col = cell_index(dx, dy, dz, cell, n_e, n_z, 0.0)
        if k == 1:
            current_row, current_col = row, col
        if gains[k] == 0.0:
            continue
        j = 0
        while j < n and (cells[j, 0] != row or cells[j, 1] != col):
            j += 1
        if j == n:
            cells[n, 0], cells[n, 1] = row, col
            n += 1
        merged[j] += gains[k]
    for i in range(1, n):  # stable insertion sort, decreasing weight
        j = i
        while j > 0 and merged[j - 1] < merged[j]:
            merged[j - 1], merged[j] = merged[j], merged[j - 1]
            cells[j - 1, 0], cells[j, 0] = cells[j, 0], cells[j - 1, 0]
            cells[j - 1, 1], cells[j, 1] = cells[j, 1], cells[j - 1, 1]
            j -= 1
    refs = np.empty((n, 3))
    weights = np.empty(n)
    for j in range(n):
        for c in range(3):
            refs[j, c] = units[cells[j, 0], cells[j, 1], c]
        weights[j] = merged[j]
    if k4 != 0.0:
        extra = np.empty((n_e, n_z))
        _passage_kernel(primary, current_row, current_col, extra)
        scale = 1.0 + extra.max()
        for e in range(n_e):  # k4 P / (1 + max P) in place; a loop compiles seconds faster than the array expression
            for z in range(n_z):
                extra[e, z] = k4 * extra[e, z] / scale
    else:
        extra = np.zeros((0, 0))
    window_open = np.empty((n_e, n_z), dtype=np.bool_)
    n_open, row, col, cost = _select_kernel(masked, win, units, refs, weights, extra, cell, window_open)
    return n_open, row, col, cost, window_open


def select_direction(masked, target_dir, current_dir, previous_dir, cfg: VFHConfig, primary=None):
    """((row, column), cost) of the cheapest open cell, or (None, inf) when no window is open (spec (f6), (f7)).

    A cell is open when its whole (2 win + 1)^2 window is free in ``masked`` (azimuth wraps, rows
    beyond the poles count as free). Reference directions are world-frame 3-vectors converted to
    their cells; the angular distance is the true angle between cell-centre unit vectors, in cells.
    ``previous_dir`` None means the first cycle (the target stands in). ``primary`` is needed only
    when ``cfg.k4 > 0``.
    """
    masked = np.ascontiguousarray(masked, dtype=np.uint8)
    expected = histogram_shape(cfg.alpha_h)
    if masked.shape != expected:
        raise ValueError(f"masked: expected shape {expected} for alpha_h, got {masked.shape}")
    directions, gains = _references(target_dir, current_dir, previous_dir, cfg)
    if not cfg.k4:
        primary = _NONE
    elif primary is None:
        raise ValueError("primary: the primary histogram is needed when VFHConfig.k4 > 0")
    else:
        primary = np.ascontiguousarray(primary, dtype=np.float64)
        if primary.shape != expected:
            raise ValueError(f"primary: expected shape {expected} for alpha_h, got {primary.shape}")
    n_open, row, col, cost, _ = _choose_kernel(masked, primary, directions, gains, float(cfg.k4), cfg.win,
                                               cell_geometry(cfg.alpha_h)[2], float(cfg.alpha_h))
    return (None, math.inf) if n_open == 0 else ((row, col), cost)


class CycleSetup(NamedTuple):
    """The configuration's inputs of ``_cycle_kernel`` (from a VFHConfig, the UAV limits and the voxel size)."""

    units: np.ndarray          # (N_e, N_z, 3) cell-centre unit vectors
    r_e: float                 # voxel enlargement radius
    r_neighbour: float         # neighbour pseudo-voxel enlargement, r_e + neighbour_r_extra
    k4: float
    win: int
    cell: float                # alpha_h
    R_w: float
    a: float
    b: float
    paper_floor: bool          # enlarge_mode == "paper_floor"
    width_steps: np.ndarray    # polar_histogram.width_steps(cell, paper_floor)
    tau_low: float
    tau_high: float
    z_min: float
    z_max: float


@numba.njit(cache=True)
def _cycle_kernel(voxels, voxel_probs, neighbours, pos, previous, psi, r_t, e_max, directions, gains, setup):
    """Stages (f1)-(f7) in one call: (emergency, n_open, row, column, primary, binary, masked, window_open).

    ``setup``: the fields of a ``CycleSetup``, in order, as a plain tuple (numba types a named tuple passed
    from Python about 2.5 us slower), made a ``CycleSetup`` again here. Neighbours join the voxels as
    pseudo-voxels with o = 1 and radius ``setup.r_neighbour``. The stage kernels are called directly: ``vfh3d_step`` builds their inputs, so the
    wrappers' checks (primary_histogram, update_binary, masked_histogram) hold by construction. One dispatch,
    and no array built in Python, since each numpy call there costs microseconds on cold caches.
    """
    setup = CycleSetup(*setup)
    units, cell, R_w = setup.units, setup.cell, setup.R_w
    m, k = voxels.shape[0], neighbours.shape[0]
    centres = np.empty((m + k, 3))
    probs = np.ones(m + k)
    radii = np.full(m + k, setup.r_e)
    for i in range(m):  # element loops: slice assignments would add seconds of compile time
        for c in range(3):
            centres[i, c] = voxels[i, c]
        probs[i] = voxel_probs[i]
    for i in range(k):
        for c in range(3):
            centres[m + i, c] = neighbours[i, c]
        radii[m + i] = setup.r_neighbour
    n_e, n_z = units.shape[0], units.shape[1]
    primary = np.zeros((n_e, n_z))
    binary = np.empty((n_e, n_z), dtype=np.uint8)
    masked = np.empty((n_e, n_z), dtype=np.uint8)
    emergency = _primary_kernel(centres, probs, radii, pos, cell, n_e, n_z, R_w, setup.a, setup.b,
                                setup.paper_floor, setup.width_steps, 0.0, primary)
    _binary_kernel(primary.ravel(), previous.ravel(), setup.tau_low, setup.tau_high, binary.ravel())
    delta_r, delta_l = _turning_kernel(centres, probs, radii, pos, psi, r_t, R_w)
    _mask_kernel(binary, psi, delta_r, delta_l, e_max, pos[2], R_w, setup.z_min, setup.z_max, cell, masked)
    n_open, row, col, _, window_open = _choose_kernel(masked, primary, directions, gains, setup.k4, setup.win,
                                                      units, cell)
    return emergency, n_open, row, col, primary, binary, masked, window_open


def _cycle_setup(cfg: VFHConfig, limits: UAVLimits, voxel_size: float) -> tuple[np.ndarray, np.ndarray, CycleSetup]:
    """(elevation, azimuth, CycleSetup): the cell-centre angles and the kernel's configuration inputs."""
    r_e, a, b, extra = cfg.resolve(limits, voxel_size)
    elevation, azimuth, units = cell_geometry(cfg.alpha_h)
    paper_floor = cfg.enlarge_mode == "paper_floor"
    return elevation, azimuth, CycleSetup(
        units, float(r_e), float(r_e + extra), float(cfg.k4), cfg.win, float(cfg.alpha_h), float(cfg.R_w), float(a),
        float(b), paper_floor, width_steps(float(cfg.alpha_h), paper_floor), float(cfg.tau_low), float(cfg.tau_high),
        float(limits.z_min), float(limits.z_max))


_GAINS = ("k1", "k2", "k3")  # per-call inputs of the selection (the residual-RL weights), not part of the setup
_SETUP_FIELDS = tuple(f.name for f in fields(VFHConfig) if f.name not in _GAINS)


class VFHPlanner:
    """``vfh3d_step`` that keeps its configuration-derived setup (``_cycle_setup``) between calls.

    One per controller. The setup is reused while the configuration's fields other than the gains
    k1..k3, the limits and the voxel size stay the same, so per-UAV weights that change every call
    (residual RL: a new VFHConfig each time) still reuse it; the same objects as last time are
    recognised by identity first, which costs far less than comparing fields.
    """

    def __init__(self):
        self._last = None  # (cfg, limits, voxel_size, key, setup) of the last call

    def setup(self, cfg: VFHConfig, limits: UAVLimits, voxel_size: float) -> tuple:
        last = self._last
        if last is not None and last[0] is cfg and last[1] is limits and last[2] == voxel_size:
            return last[4]
        key = (tuple(getattr(cfg, name) for name in _SETUP_FIELDS), limits, voxel_size)
        setup = last[4] if last is not None and last[3] == key else _cycle_setup(cfg, limits, voxel_size)
        self._last = (cfg, limits, voxel_size, key, setup)
        return setup

    def __call__(self, state: VFHState, cfg: VFHConfig, limits: UAVLimits, pos, psi: float, v: float, vz: float,
                 target_dir, voxel_centres, voxel_probs, voxel_size: float, neighbour_positions=None) -> VFHResult:
        """One cycle, as ``vfh3d_step``."""
        return _step(self.setup(cfg, limits, voxel_size), state, cfg, limits, pos, psi, v, vz, target_dir,
                     voxel_centres, voxel_probs, neighbour_positions)


def vfh3d_step(state: VFHState, cfg: VFHConfig, limits: UAVLimits, pos, psi: float, v: float, vz: float,
               target_dir, voxel_centres, voxel_probs, voxel_size: float, neighbour_positions=None) -> VFHResult:
    """One 3D VFH+ cycle for one UAV; updates ``state`` (binary histogram, and the selection if not blocked).

    ``voxel_centres`` / ``voxel_probs`` are the occupied voxels around ``pos`` (e.g. from
    ``OccupancyMap.occupied_in_sphere(pos, cfg.R_w)``); neighbour UAVs (K, 3) become pseudo-voxels
    with o = 1 and enlargement r_e + neighbour_r_extra (spec (g6)). A planner calling it every cycle keeps
    the configuration's setup in a ``VFHPlanner`` instead.
    """
    return _step(_cycle_setup(cfg, limits, voxel_size), state, cfg, limits, pos, psi, v, vz, target_dir,
                 voxel_centres, voxel_probs, neighbour_positions)


def _step(setup: tuple, state: VFHState, cfg: VFHConfig, limits: UAVLimits, pos, psi, v, vz, target_dir,
          voxel_centres, voxel_probs, neighbour_positions) -> VFHResult:
    """``vfh3d_step`` with its setup (``_cycle_setup``) given."""
    elevation, azimuth, kernel_setup = setup
    units = kernel_setup.units
    pos = np.ascontiguousarray(pos, dtype=np.float64)
    centres = np.ascontiguousarray(voxel_centres, dtype=np.float64).reshape(-1, 3)
    probs = np.ascontiguousarray(voxel_probs, dtype=np.float64)
    if pos.shape != (3,) or probs.shape != centres.shape[:1]:
        raise ValueError(f"pos {pos.shape}, voxel_centres {centres.shape}, voxel_probs {probs.shape}: "
                         "expected (3,), (M, 3) and (M,)")
    if neighbour_positions is None or not len(neighbour_positions):
        neighbours = _NO_NEIGHBOURS
    else:
        neighbours = np.asarray(neighbour_positions, dtype=np.float64).reshape(-1, 3)
    n_e, n_z = units.shape[:2]
    if state.binary is None:  # all free; writable like a kept binary, so one compiled kernel serves both
        previous = np.zeros((n_e, n_z), dtype=np.uint8)
    else:
        previous = np.ascontiguousarray(state.binary, dtype=np.uint8)
        if previous.shape != (n_e, n_z):
            raise ValueError(f"previous_binary: expected shape {(n_e, n_z)}, got {previous.shape}")
    r_t = _turn_radius(v, limits)
    e_max = limits.climb_angle_limit(v)
    gamma = math.atan2(vz, max(v, 1e-3))
    current_dir = (math.cos(psi) * math.cos(gamma), math.sin(psi) * math.cos(gamma), math.sin(gamma))
    directions, gains = _references(target_dir, current_dir, state.previous_dir, cfg)
    emergency, n_candidates, row, col, primary, binary, masked, window_open = _cycle_kernel(
        centres, probs, neighbours, pos, previous, float(psi), r_t, float(e_max), directions, gains,
        tuple(kernel_setup))
    state.binary = binary
    if n_candidates == 0:
        nan = math.nan
        return VFHResult(True, nan, nan, np.full(3, nan), emergency, primary, binary, masked, 0, window_open)
    direction = units[row, col].copy()
    state.previous_dir = direction
    az = float(azimuth[col])
    return VFHResult(False, az - 2.0 * math.pi if az > math.pi else az, float(elevation[row]), direction, emergency,
                     primary, binary, masked, n_candidates, window_open)


def vertical_escape(result, lim) -> float:
    """The pure-vertical escape of spec (g4) after T_stuck: full climb (descent) if the straight-up (down) cells
    of ``result``'s binary histogram hold no obstacle, else 0."""
    if not result.binary[-1].any():
        return lim.vz_max
    if not result.binary[0].any():
        return -lim.vz_max
    return 0.0
