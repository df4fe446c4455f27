"""2D A* on an occupancy raster and the global-path interface that couples it to DWA (spec (d)).

Everything here is a pure function of arrays, independent of the environment. The search is one
numba kernel (binary heap keyed (f, h), lazy deletion, closed set, 8-connected). Segment checks
for line-of-sight pruning and for the corridor replanning trigger share one exact integer grid
walk that applies the same corner rule as the search, so a path the search accepts is never
reported as blocked by the corridor check.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import ClassVar

import numba
import numpy as np

from uavform_env.config import (Config, boolean, check_bool, check_choice, check_int, check_range, in_range, integer,
                                one_of)

HEURISTICS = ("octile", "euclidean")
HEADING_TARGETS = ("goal", "lookahead", "visible_goal")
SQRT2 = math.sqrt(2.0)


def _as_point(name: str, xy) -> np.ndarray:
    p = np.asarray(xy, dtype=np.float64)
    if p.shape != (2,) or not (math.isfinite(p[0]) and math.isfinite(p[1])):
        raise ValueError(f"{name}={xy!r}: expected 2 finite coordinates (x, y)")
    return p


def _as_grid(name: str, blocked, shape: tuple | None = None) -> np.ndarray:
    """Validate a boolean raster and return it C-contiguous (one numba specialisation)."""
    b = np.asarray(blocked)
    if b.ndim != 2 or b.dtype != np.bool_ or 0 in b.shape:
        raise ValueError(f"{name}: expected a non-empty 2D bool array, got dtype {b.dtype} shape {b.shape}")
    if shape is not None and b.shape != tuple(shape):
        raise ValueError(f"{name}: expected shape {tuple(shape)} (the raster's), got {b.shape}")
    return np.ascontiguousarray(b)


def _as_cell(name: str, cell, shape: tuple) -> tuple[int, int]:
    c = np.asarray(cell)
    if c.shape != (2,) or not np.issubdtype(c.dtype, np.integer):
        raise ValueError(f"{name}={cell!r}: expected an integer cell index (i, j)")
    i, j = int(c[0]), int(c[1])
    if not (0 <= i < shape[0] and 0 <= j < shape[1]):
        raise ValueError(f"{name}={cell!r}: outside the raster of shape {tuple(shape)}")
    return i, j


# ----------------------------------------------------------------------------------------------
# Raster geometry and configuration
# ----------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Raster:
    """Cell (i, j) covers ``[origin + (i, j) * res, origin + (i + 1, j + 1) * res)`` (CONVENTIONS.md)."""

    origin: tuple[float, float]
    res: float
    shape: tuple[int, int]

    def __post_init__(self):
        o = "Raster"
        origin = tuple(float(v) for v in np.asarray(self.origin, dtype=np.float64).ravel())
        if len(origin) != 2 or not all(math.isfinite(v) for v in origin):
            raise ValueError(f"{o}.origin={self.origin!r}: expected 2 finite coordinates")
        check_range(o, "res", self.res, 0.0, None, lo_open=True)
        shape = tuple(self.shape)
        if len(shape) != 2:
            raise ValueError(f"{o}.shape={self.shape!r}: expected (nx, ny)")
        for name, n in zip(("shape[0]", "shape[1]"), shape):
            check_int(o, name, int(n) if isinstance(n, np.integer) else n, 1)
        object.__setattr__(self, "origin", origin)
        object.__setattr__(self, "shape", (int(shape[0]), int(shape[1])))

    def to_cell(self, xy):
        """Cell index of a point (2,) -> (i, j) ints, or of points (K, 2) -> (K, 2) int64.

        Points outside the raster raise: silently clipping them would plan from the wrong place.
        """
        p = np.asarray(xy, dtype=np.float64)
        if p.ndim not in (1, 2) or p.shape[-1] != 2 or not np.all(np.isfinite(p)):
            raise ValueError(f"xy={xy!r}: expected finite point(s) of shape (2,) or (K, 2)")
        cells = np.floor((p - np.asarray(self.origin)) / self.res).astype(np.int64)
        outside = np.any((cells < 0) | (cells >= np.asarray(self.shape)), axis=-1)
        if np.any(outside):
            bad = p if p.ndim == 1 else p[outside][0]
            hi = np.asarray(self.origin) + np.asarray(self.shape) * self.res
            raise ValueError(f"xy: point {bad.tolist()} lies outside the raster [{self.origin}, {tuple(hi)})")
        return (int(cells[0]), int(cells[1])) if p.ndim == 1 else cells

    def to_world(self, cells) -> np.ndarray:
        """Metric centres (K, 2) of cells (K, 2)."""
        c = np.asarray(cells)
        if c.ndim != 2 or c.shape[1] != 2 or not np.issubdtype(c.dtype, np.integer):
            raise ValueError(f"cells: expected an integer array of shape (K, 2), got {c.dtype} {c.shape}")
        return np.asarray(self.origin) + (c.astype(np.float64) + 0.5) * self.res


@dataclass(frozen=True)
class AStarConfig(Config):
    """Options of spec (d); every [X] choice is a field.

    res_g          raster resolution the caller must build the Raster with [D]
    heuristic      "octile" (exact on an empty 8-connected grid) or "euclidean" [R]
    weight         heuristic weight w; w > 1 trades optimality for fewer expansions [R]
    allow_corner_cut  permit diagonal moves past a blocked axial neighbour (PythonRobotics) [R]
    prune          line-of-sight pruning of the cell path (d3) [X]
    lookahead      L_a, arc length from the progress node to P_LA, metres (d4) [X]
    window         progress search covers the progress node and the next `window` nodes (d4) [X]
    d_replan       replan when the UAV is farther than this from the path, metres (d5) [X]
    replan_period  replan at most this often (s) while new map data arrives (d5) [X]
    heading_target DWA heads for the true goal ("goal", paper), for P_LA ("lookahead"), or for the goal while the
                   straight segment to it is free in the inflated raster and for P_LA otherwise
                   ("visible_goal": the paper in the open, no U-trap behind a known wall) (d6) [X]
    """

    res_g: float = 0.5
    heuristic: str = "octile"
    weight: float = 1.0
    allow_corner_cut: bool = False
    prune: bool = False
    lookahead: float = 3.0
    window: int = 20
    d_replan: float = 2.0
    replan_period: float = 2.0
    heading_target: str = "goal"

    BOUNDS: ClassVar[dict] = {
        "res_g": in_range(0.0, lo_open=True), "heuristic": one_of(HEURISTICS), "weight": in_range(0.0),
        "allow_corner_cut": boolean, "prune": boolean, "lookahead": in_range(0.0), "window": integer(1),
        "d_replan": in_range(0.0, lo_open=True), "replan_period": in_range(0.0),
        "heading_target": one_of(HEADING_TARGETS),
    }


# ----------------------------------------------------------------------------------------------
# Inflation and snapping (d1), (d2)
# ----------------------------------------------------------------------------------------------

def inflate(blocked, radius: float, res: float) -> np.ndarray:
    """Block every cell whose centre lies within ``radius`` (m) of an occupied cell's centre (d1).

    A dilation by the disc of cell offsets within ``radius``: the cost follows the occupied cells,
    not the raster. Offsets are kept by the distance formula of scipy's exact Euclidean distance
    transform, so both give the same cells (a test compares them).
    """
    b = _as_grid("blocked", blocked)
    check_range("inflate", "radius", radius, 0.0, None)
    check_range("inflate", "res", res, 0.0, None, lo_open=True)
    out = np.zeros_like(b)
    _dilate_kernel(b, _disc_offsets(float(radius), float(res)), out)
    return out


@functools.lru_cache(maxsize=16)
def _disc_offsets(radius: float, res: float) -> np.ndarray:
    """(K, 2) cell offsets (di, dj) with sqrt((di res)^2 + (dj res)^2) <= radius (1 + 1e-12)."""
    reach = int(math.floor(radius / res)) + 1
    di, dj = np.meshgrid(np.arange(-reach, reach + 1), np.arange(-reach, reach + 1), indexing="ij")
    inside = np.sqrt((di * res) ** 2 + (dj * res) ** 2) <= radius * (1.0 + 1e-12)
    offsets = np.column_stack([di[inside], dj[inside]])
    offsets.flags.writeable = False
    return offsets


@numba.njit(cache=True)
def _dilate_kernel(blocked, offsets, out):
    """Mark in ``out`` every in-bounds cell at one of ``offsets`` from a blocked cell."""
    n_i, n_j = blocked.shape
    for i in range(n_i):
        for j in range(n_j):
            if not blocked[i, j]:
                continue
            for k in range(offsets.shape[0]):
                a = i + offsets[k, 0]
                c = j + offsets[k, 1]
                if 0 <= a < n_i and 0 <= c < n_j:
                    out[a, c] = True


def snap_to_free(blocked, cell) -> tuple[int, int] | None:
    """Nearest free cell (Euclidean, in cells) to ``cell``; the cell itself if free; None if all blocked.

    Equivalent to a breadth-first ring search run until no closer free cell can appear; done as
    one vectorised distance over the free cells. Ties go to the first cell in row-major order.
    """
    b = _as_grid("blocked", blocked)
    i, j = _as_cell("cell", cell, b.shape)
    if not b[i, j]:
        return i, j
    free = np.argwhere(~b)
    if len(free) == 0:
        return None
    k = int(np.argmin((free[:, 0] - i) ** 2 + (free[:, 1] - j) ** 2))
    return int(free[k, 0]), int(free[k, 1])


# ----------------------------------------------------------------------------------------------
# Search (d2)
# ----------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class AStarResult:
    """found; path (K, 2) int64 cells start..goal (empty if not found); cost in cells; expanded nodes."""

    found: bool
    path: np.ndarray
    cost: float
    expanded: int


@numba.njit(cache=True)
def _astar_kernel(blocked, si, sj, gi, gj, euclidean, weight, corner_cut):
    """Textbook A* with a binary heap of (f, h, node) entries, lazy deletion and a closed set.

    The grid is copied into a flat free-mask with a blocked border, so neighbours are plain index
    offsets without bounds checks. g is kept as integer counts of axial and diagonal steps:
    g = n_ax + n_dg * sqrt(2) and the octile f = (n_ax + w * c) + (n_dg + w * d) * sqrt(2) round the
    same way on every path, so equal-cost nodes tie exactly and the (f, h) order really prefers
    the node nearer the goal.
    """
    nx, ny = blocked.shape
    W = ny + 2
    n = (nx + 2) * W
    free = np.zeros(n, dtype=np.bool_)
    for i in range(nx):
        for j in range(ny):
            free[(i + 1) * W + j + 1] = not blocked[i, j]
    # 4 axial then 4 diagonal moves; a diagonal's two axial side cells are node + side_i / side_j
    offset = np.array([W, -W, 1, -1, W + 1, W - 1, -W + 1, -W - 1], dtype=np.int64)
    side_i = np.array([0, 0, 0, 0, W, W, -W, -W], dtype=np.int64)
    side_j = np.array([0, 0, 0, 0, 1, -1, 1, -1], dtype=np.int64)
    n_ax = np.zeros(n, dtype=np.int64)
    n_dg = np.zeros(n, dtype=np.int64)
    g = np.full(n, np.inf)
    parent = np.full(n, -1, dtype=np.int64)
    closed = np.zeros(n, dtype=np.bool_)
    cap = 1024
    hf = np.empty(cap)
    hh = np.empty(cap)
    hn = np.empty(cap, dtype=np.int64)
    start = (si + 1) * W + sj + 1
    goal = (gi + 1) * W + gj + 1
    g[start] = 0.0
    hf[0] = 0.0
    hh[0] = 0.0
    hn[0] = start
    size = 1
    expanded = 0
    found = False
    while size > 0:
        node = hn[0]
        # pop: sift the last entry down from the root
        size -= 1
        lf = hf[size]
        lh = hh[size]
        ln = hn[size]
        k = 0
        while True:
            c = 2 * k + 1
            if c >= size:
                break
            if c + 1 < size and (hf[c + 1] < hf[c] or (hf[c + 1] == hf[c] and hh[c + 1] < hh[c])):
                c += 1
            if not (hf[c] < lf or (hf[c] == lf and hh[c] < lh)):
                break
            hf[k] = hf[c]
            hh[k] = hh[c]
            hn[k] = hn[c]
            k = c
        hf[k] = lf
        hh[k] = lh
        hn[k] = ln
        if closed[node]:
            continue  # stale entry (lazy deletion)
        closed[node] = True
        expanded += 1
        if node == goal:
            found = True
            break
        for m in range(8):
            nb = node + offset[m]
            if not free[nb] or closed[nb]:
                continue
            diagonal = m >= 4
            if diagonal and not corner_cut and not (free[node + side_i[m]] and free[node + side_j[m]]):
                continue
            ax = n_ax[node] + (0 if diagonal else 1)
            dg = n_dg[node] + (1 if diagonal else 0)
            g_new = ax + dg * SQRT2
            if g_new >= g[nb]:
                continue
            g[nb] = g_new
            n_ax[nb] = ax
            n_dg[nb] = dg
            parent[nb] = node
            a = nb // W
            dx = abs(a - 1 - gi)
            dy = abs(nb - a * W - 1 - gj)
            if euclidean:
                h = weight * math.sqrt(dx * dx + dy * dy)
                f = g_new + h
            else:
                lo = min(dx, dy)
                h = weight * ((max(dx, dy) - lo) + lo * SQRT2)
                f = (ax + weight * (max(dx, dy) - lo)) + (dg + weight * lo) * SQRT2
            if size == cap:
                cap *= 2
                hf2 = np.empty(cap)
                hh2 = np.empty(cap)
                hn2 = np.empty(cap, dtype=np.int64)
                hf2[:size] = hf[:size]
                hh2[:size] = hh[:size]
                hn2[:size] = hn[:size]
                hf, hh, hn = hf2, hh2, hn2
            # push: sift the new entry up from the end
            k = size
            size += 1
            while k > 0:
                p = (k - 1) // 2
                if not (f < hf[p] or (f == hf[p] and h < hh[p])):
                    break
                hf[k] = hf[p]
                hh[k] = hh[p]
                hn[k] = hn[p]
                k = p
            hf[k] = f
            hh[k] = h
            hn[k] = nb
    if not found:
        return False, np.empty((0, 2), dtype=np.int64), np.inf, expanded
    length = 1
    node = goal
    while node != start:
        node = parent[node]
        length += 1
    path = np.empty((length, 2), dtype=np.int64)
    node = goal
    for k in range(length - 1, -1, -1):
        path[k, 0] = node // W - 1
        path[k, 1] = node % W - 1
        node = parent[node]
    return True, path, g[goal], expanded


def astar(blocked, start, goal, heuristic: str = "octile", weight: float = 1.0,
          allow_corner_cut: bool = False) -> AStarResult:
    """Shortest 8-connected path between two cells (axial step 1, diagonal sqrt(2)), spec (d2).

    Blocked cells are not nodes, so a blocked start or goal gives ``found=False``
    (``plan_path`` snaps them first).
    """
    b = _as_grid("blocked", blocked)
    si, sj = _as_cell("start", start, b.shape)
    gi, gj = _as_cell("goal", goal, b.shape)
    check_choice("astar", "heuristic", heuristic, HEURISTICS)
    check_range("astar", "weight", weight, 0.0, None)
    check_bool("astar", "allow_corner_cut", allow_corner_cut)
    if b[si, sj] or b[gi, gj]:
        return AStarResult(False, np.empty((0, 2), dtype=np.int64), math.inf, 0)
    found, path, cost, expanded = _astar_kernel(b, si, sj, gi, gj, heuristic == "euclidean",
                                                float(weight), bool(allow_corner_cut))
    return AStarResult(bool(found), path, float(cost), int(expanded))


# ----------------------------------------------------------------------------------------------
# Segment checks: pruning (d3) and the corridor trigger (d5)
# ----------------------------------------------------------------------------------------------

@numba.njit(cache=True)
def _segment_free(blocked, i0, j0, i1, j1, corner_cut):
    """Exact walk over the cells the segment between two cell centres passes through.

    Integer arithmetic: ``decision`` compares the next x and y cell-boundary crossings. A crossing
    exactly through a cell corner is a diagonal step, which checks both side cells unless corner
    cutting is allowed (the same rule as the search).
    """
    nx_, ny_ = abs(i1 - i0), abs(j1 - j0)
    si = 1 if i1 > i0 else -1
    sj = 1 if j1 > j0 else -1
    i, j, ix, iy = i0, j0, 0, 0
    if blocked[i, j]:
        return False
    while ix < nx_ or iy < ny_:
        decision = (1 + 2 * ix) * ny_ - (1 + 2 * iy) * nx_
        if decision == 0:
            if not corner_cut and (blocked[i + si, j] or blocked[i, j + sj]):
                return False
            i += si
            j += sj
            ix += 1
            iy += 1
        elif decision < 0:
            i += si
            ix += 1
        else:
            j += sj
            iy += 1
        if blocked[i, j]:
            return False
    return True


@numba.njit(cache=True)
def _prune_kernel(blocked, path, corner_cut):
    """Greedy pruning: keep a node only when the anchor cannot see the node after it."""
    k = path.shape[0]
    keep = np.zeros(k, dtype=np.bool_)
    keep[0] = True
    keep[k - 1] = True
    anchor = 0
    for m in range(1, k - 1):
        if not _segment_free(blocked, path[anchor, 0], path[anchor, 1], path[m + 1, 0], path[m + 1, 1],
                             corner_cut):
            keep[m] = True
            anchor = m
    return keep


@numba.njit(cache=True)
def _polyline_free(blocked, cells, corner_cut):
    """True when every segment of a cell polyline (K >= 1) passes free cells only."""
    if blocked[cells[0, 0], cells[0, 1]]:
        return False
    for m in range(cells.shape[0] - 1):
        if not _segment_free(blocked, cells[m, 0], cells[m, 1], cells[m + 1, 0], cells[m + 1, 1], corner_cut):
            return False
    return True


def _as_cell_path(name: str, path, shape: tuple) -> np.ndarray:
    p = np.asarray(path)
    if p.ndim != 2 or p.shape[1] != 2 or not np.issubdtype(p.dtype, np.integer):
        raise ValueError(f"{name}: expected an integer array of shape (K, 2), got {p.dtype} {p.shape}")
    if len(p) and (np.any(p < 0) or np.any(p >= np.asarray(shape))):
        raise ValueError(f"{name}: cell indices outside the raster of shape {tuple(shape)}")
    return np.ascontiguousarray(p, dtype=np.int64)


def prune_line_of_sight(path, blocked, allow_corner_cut: bool = False) -> np.ndarray:
    """Drop path nodes the previous kept node can see past (d3); endpoints are always kept."""
    b = _as_grid("blocked", blocked)
    p = _as_cell_path("path", path, b.shape)
    if len(p) <= 2:
        return p.copy()
    return p[_prune_kernel(b, p, bool(allow_corner_cut))]


# ----------------------------------------------------------------------------------------------
# The global path and its coupling to DWA (d4), (d5)
# ----------------------------------------------------------------------------------------------

class GlobalPath:
    """A metric polyline with a monotone progress index (spec (d4)).

    The progress index only moves forward, so where the path doubles back the lookahead point
    cannot jump to the other leg (which would flip the sign of the eq. 10 cosine).
    """

    def __init__(self, points, window: int = 20, allow_corner_cut: bool = False):
        p = np.array(points, dtype=np.float64)
        if p.ndim != 2 or p.shape[1] != 2 or len(p) == 0 or not np.all(np.isfinite(p)):
            raise ValueError(f"points: expected finite coordinates of shape (K>=1, 2), got shape {p.shape}")
        check_int("GlobalPath", "window", window, 1)
        check_bool("GlobalPath", "allow_corner_cut", allow_corner_cut)
        p.setflags(write=False)
        self.points = p
        self.window = window
        self.allow_corner_cut = bool(allow_corner_cut)
        self.progress = 0
        self._arc = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(p, axis=0).T))))

    @property
    def length(self) -> float:
        return float(self._arc[-1])

    def update_progress(self, pos_xy) -> int:
        """Move the progress index to the node nearest ``pos_xy`` among itself and the next `window` nodes."""
        pos = _as_point("pos_xy", pos_xy)
        self.progress = _nearest_ahead(self.points, self.progress, self.window, pos[0], pos[1])
        return self.progress

    def lookahead(self, pos_xy, L_a: float) -> np.ndarray:
        """P_LA: advance the progress, then the first node at arc length >= L_a beyond it, else the end."""
        check_range("lookahead", "L_a", L_a, 0.0, None)
        i = self.update_progress(pos_xy)
        j = i + int(np.searchsorted(self._arc[i:], self._arc[i] + L_a, side="left"))
        return self.points[min(j, len(self.points) - 1)].copy()

    def distance(self, pos_xy) -> float:
        """Distance to the path still ahead (from the segment entering the progress node)."""
        pos = _as_point("pos_xy", pos_xy)
        pts = self.points[max(self.progress - 1, 0):]
        if len(pts) == 1:
            return float(np.hypot(*(pos - pts[0])))
        a, seg = pts[:-1], np.diff(pts, axis=0)
        seg_len2 = np.sum(seg ** 2, axis=1)
        t = np.clip(np.sum((pos - a) * seg, axis=1) / np.where(seg_len2 > 0, seg_len2, 1.0), 0.0, 1.0)
        return float(np.min(np.hypot(*(a + t[:, None] * seg - pos).T)))

    def corridor_blocked(self, blocked_inflated, raster: Raster) -> bool:
        """True when a cell the path passes through is blocked in the inflated raster (trigger (i))."""
        b = _as_grid("blocked_inflated", blocked_inflated, raster.shape)
        cells = raster.to_cell(self.points)
        return not _polyline_free(b, cells, self.allow_corner_cut)


@numba.njit(cache=True)
def _nearest_ahead(points, progress, window, x, y):
    """Index of the node nearest (x, y) among ``points[progress]`` and the next ``window`` nodes (first on ties)."""
    best, best_d2 = progress, math.inf
    for k in range(progress, min(points.shape[0], progress + window + 1)):
        dx, dy = points[k, 0] - x, points[k, 1] - y
        d2 = dx * dx + dy * dy
        if d2 < best_d2:
            best, best_d2 = k, d2
    return best


def plan_path(blocked_world, raster: Raster, start_xy, goal_xy, inflate_radius: float,
              cfg: AStarConfig = AStarConfig()) -> GlobalPath | None:
    """Inflate, snap a blocked start/goal to the nearest free cell, search, optionally prune (and resample).

    Returns the path through metric cell centres, or None when no path exists (the leader then
    uses the goal itself as P_LA, spec (d2)).
    """
    if not isinstance(cfg, AStarConfig):
        raise ValueError(f"cfg: expected an AStarConfig, got {type(cfg).__name__}")
    if not isinstance(raster, Raster):
        raise ValueError(f"raster: expected a Raster, got {type(raster).__name__}")
    if not math.isclose(raster.res, cfg.res_g, rel_tol=1e-9):
        raise ValueError(f"raster.res={raster.res!r} differs from AStarConfig.res_g={cfg.res_g!r}; "
                         "build the raster with the configured resolution")
    b = _as_grid("blocked_world", blocked_world, raster.shape)
    inflated = inflate(b, inflate_radius, raster.res)
    start = snap_to_free(inflated, raster.to_cell(_as_point("start_xy", start_xy)))
    goal = snap_to_free(inflated, raster.to_cell(_as_point("goal_xy", goal_xy)))
    if start is None or goal is None:
        return None
    result = astar(inflated, start, goal, cfg.heuristic, cfg.weight, cfg.allow_corner_cut)
    if not result.found:
        return None
    if not cfg.prune:
        points = raster.to_world(result.path)
    else:
        points = resample(raster.to_world(prune_line_of_sight(result.path, inflated, cfg.allow_corner_cut)), raster.res)
    return GlobalPath(points, cfg.window, cfg.allow_corner_cut)


def resample(points, spacing: float) -> np.ndarray:
    """The polyline through ``points`` with nodes at most ``spacing`` apart (every corner kept).

    A pruned path has nodes only at its corners, many metres apart; the node-based progress index and
    lookahead of (d4) need them evenly spaced, or the progress jumps to a far corner and the lookahead
    aims through the obstacle the corner goes around.
    """
    p = np.asarray(points, dtype=np.float64)
    check_range("resample", "spacing", spacing, 0.0, None, lo_open=True)
    if len(p) < 2:
        return p.copy()
    seg = np.diff(p, axis=0)
    n = np.maximum(1, np.ceil(np.hypot(seg[:, 0], seg[:, 1]) / spacing - 1e-9).astype(np.int64))
    which = np.repeat(np.arange(len(seg)), n)
    frac = (np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)) / np.repeat(n, n)
    return np.vstack([p[which] + frac[:, None] * seg[which], p[-1:]])


def replan_trigger(path: GlobalPath | None, pos_xy, blocked_inflated, raster: Raster, t_since_plan: float,
                   new_data: bool, cfg: AStarConfig) -> str | None:
    """Which replanning trigger of (d5) fires: "corridor", "off_path", "periodic" or None.

    Without a path only the periodic trigger applies: new map data is what can open a way.
    """
    check_range("replan_trigger", "t_since_plan", t_since_plan, 0.0, None)
    check_bool("replan_trigger", "new_data", new_data)
    periodic = new_data and t_since_plan >= cfg.replan_period
    if path is None:
        return "periodic" if periodic else None
    if path.corridor_blocked(blocked_inflated, raster):
        return "corridor"
    if path.distance(pos_xy) > cfg.d_replan:
        return "off_path"
    return "periodic" if periodic else None


def needs_replan(path: GlobalPath | None, pos_xy, blocked_inflated, raster: Raster, t_since_plan: float,
                 new_data: bool, cfg: AStarConfig) -> bool:
    """True when any replanning trigger of (d5) fires (see ``replan_trigger``)."""
    return replan_trigger(path, pos_xy, blocked_inflated, raster, t_since_plan, new_data, cfg) is not None
