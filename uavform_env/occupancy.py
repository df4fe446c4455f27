"""One UAV's onboard occupancy map: a dense log-odds voxel grid updated with OctoMap's rules.

A dense float32 grid (NaN = never observed) replaces OctoMap's octree (spec (e3) allows any store
with the same semantics). Scans are integrated like ``OccupancyOcTreeBase::insertPointCloud``
(``computeUpdate`` + ``updateNode``): the rays' voxels come from the ported ``computeRayKeys``,
every voxel is updated at most once per scan and a hit beats a miss, log-odds add in float32 and
are clamped. Labels therefore match ``octomap-python`` voxel by voxel (tests/test_octomap_parity.py).

Three structures keep the queries cheap: per-block occupied counts (8^3 voxels per block) and
per-row occupied bits (8 voxels along z per byte), both updated inside the integrate kernel, so a
sphere query skips empty blocks and reads a block's 64 row bytes instead of its 512 voxels; and a
lazily refreshed max-pooled pyramid whose level d holds OctoMap's inner nodes d levels up.
"""

from __future__ import annotations

import math
import os
import tempfile
from typing import NamedTuple

import numba
import numpy as np

from .config import MapConfig
from .dda import coord_key, grid_origin_key, ray_key_bound, ray_keys

BLOCK_SHIFT = 3  # blocks of 2**3 = 8 voxels per axis carry occupied counts
# Deepest pyramid level: OctoMap's depth-1 nodes (tree depth 16; keys align up to 2**15, the root
# straddles the origin and is not a level).
MAX_LEVEL = 15
_UNTOUCHED, _MISS, _HIT = 0, 1, 2  # stamp values during one integrate call (the stamp is all-zero between calls)


class _Level(NamedTuple):
    """One pyramid level: key of its lower corner, log-odds grid and the occupancy summaries."""

    key0: np.ndarray    # (3,) int64
    grid: np.ndarray    # (nx, ny, nz) float32, NaN = unknown
    counts: np.ndarray  # (bx, by, bz) int32 occupied cells per 8^3 block
    bits: np.ndarray    # (nx, ny, bz) uint8, bit b of [i, j, kb] = cell (i, j, 8 kb + b) occupied


class OccupancyMap:
    """One UAV's own map: a dense float32 log-odds grid (NaN = unknown) updated with OctoMap's rules.

    ``resolution`` is the grid's voxel size; ``cfg`` supplies the sensor model (p_hit, p_miss,
    clamping, p_occ); ``cfg.resolution`` is not consulted. ``stamp`` is an optional int32 scratch
    grid of the same shape that several maps may share (it is all-zero between calls).
    A voxel is occupied when its log-odds is >= logit(p_occ), as OctoMap's ``isNodeOccupied``.
    """

    def __init__(self, origin, shape, resolution: float, cfg: MapConfig = MapConfig(), stamp: np.ndarray | None = None):
        if not isinstance(cfg, MapConfig):
            raise ValueError(f"cfg: expected a MapConfig, got {type(cfg).__name__}")
        self._key0 = grid_origin_key(origin, resolution)
        self._shape = _check_shape(shape)
        self._res = float(resolution)
        self._origin = self._key0 * self._res
        self._cfg = cfg
        if stamp is None:
            stamp = np.zeros(self._shape, np.int32)
        elif not (isinstance(stamp, np.ndarray) and stamp.dtype == np.int32 and stamp.shape == self._shape
                  and stamp.flags.c_contiguous and stamp.flags.writeable):
            raise ValueError(f"stamp: expected a writeable C-contiguous int32 array of shape {self._shape}")
        elif stamp.any():
            raise ValueError("stamp: expected an all-zero scratch grid (it is cleared after every integrate call)")
        self._stamp = stamp
        f32 = np.float32
        self._l_hit, self._l_miss = f32(cfg.logodds(cfg.p_hit)), f32(cfg.logodds(cfg.p_miss))
        self._l_min, self._l_max = f32(cfg.logodds(cfg.p_min)), f32(cfg.logodds(cfg.p_max))
        self._l_occ = f32(cfg.logodds(cfg.p_occ))
        self._levels = [_empty_level(self._key0, self._shape)]
        self._dirty = _empty_region()  # voxels changed since the pyramid was last refreshed
        self._n_levels = 1
        while self._n_levels <= MAX_LEVEL and max(_level_shape(self._key0, self._shape, self._n_levels - 1)) > 1:
            self._n_levels += 1

    # ------------------------------------------------------------------ properties
    @property
    def origin(self) -> np.ndarray:
        return self._origin.copy()

    @property
    def shape(self) -> tuple:
        return self._shape

    @property
    def resolution(self) -> float:
        return self._res

    @property
    def cfg(self) -> MapConfig:
        return self._cfg

    @property
    def logodds(self) -> np.ndarray:
        """Read-only float32 view of the leaf log-odds (NaN = unknown)."""
        view = self._levels[0].grid.view()
        view.flags.writeable = False
        return view

    @property
    def n_levels(self) -> int:
        """Number of pyramid levels: up to the first single-cell level, at most MAX_LEVEL + 1."""
        return self._n_levels

    # ------------------------------------------------------------------ updates
    def integrate(self, sensor_origin, endpoints, hit) -> None:
        """Insert one scan taken from ``sensor_origin``.

        ``hit[r]`` True: the endpoint voxel is a hit and the voxels the ray crosses before it are
        misses. False: misses only along origin -> endpoint, endpoint voxel excluded (max-range rays
        truncated at r_max; rays that ended on another UAV, which never enters the map).
        Voxels outside the grid are skipped.
        """
        o = np.asarray(sensor_origin, dtype=np.float64)
        if o.shape != (3,) or not np.all(np.isfinite(o)):
            raise ValueError(f"sensor_origin={sensor_origin!r}: expected 3 finite coordinates")
        ends = np.ascontiguousarray(endpoints, dtype=np.float64)
        if ends.ndim != 2 or ends.shape[1] != 3 or not np.all(np.isfinite(ends)):
            raise ValueError(f"endpoints: expected finite (R, 3) coordinates, got shape {ends.shape}")
        hit = np.asarray(hit)
        if hit.dtype != np.bool_ or hit.shape != (ends.shape[0],):
            raise ValueError(f"hit: expected a bool array of shape ({ends.shape[0]},), got {hit.dtype} {hit.shape}")
        leaves = self._levels[0]
        _integrate(leaves.grid, self._stamp, leaves.counts, leaves.bits, self._dirty, leaves.key0, self._res, o, ends,
                   hit, self._l_hit, self._l_miss, self._l_min, self._l_max, self._l_occ)

    def integrate_scan(self, sensor_origin, scan_row_endpoints, scan_row_kind) -> None:
        """Insert one UAV's row of a ``sensing.Scan``: static hits (kind 1) are hits, the rest misses."""
        kind = np.asarray(scan_row_kind)
        self.integrate(sensor_origin, scan_row_endpoints, kind == 1)

    # ------------------------------------------------------------------ point queries
    def _values(self, points) -> np.ndarray:
        """Leaf log-odds at ``points`` (..., 3); NaN where unknown or outside the grid."""
        p = np.asarray(points, dtype=np.float64)
        if p.ndim == 0 or p.shape[-1] != 3 or not np.all(np.isfinite(p)):
            raise ValueError(f"points: expected finite (..., 3) coordinates, got shape {p.shape}")
        idx = np.floor(p.reshape(-1, 3) * (1.0 / self._res)).astype(np.int64) - self._key0
        inside = np.all((idx >= 0) & (idx < np.asarray(self._shape)), axis=1)
        out = np.full(idx.shape[0], np.nan, np.float32)
        i = idx[inside]
        out[inside] = self._levels[0].grid[i[:, 0], i[:, 1], i[:, 2]]
        return out.reshape(p.shape[:-1])

    def label(self, points) -> np.ndarray:
        """int8 per point: -1 unknown (also outside the grid), 0 free, 1 occupied."""
        v = self._values(points)
        return np.where(np.isnan(v), -1, v >= self._l_occ).astype(np.int8)

    def probability(self, points) -> np.ndarray:
        """Occupancy probability per point (float64), NaN where unknown."""
        v = self._values(points).astype(np.float64)
        return 1.0 / (1.0 + np.exp(-v))

    def is_known(self, points) -> np.ndarray:
        return ~np.isnan(self._values(points))

    # ------------------------------------------------------------------ region queries
    def _sphere_args(self, center, radius):
        c = np.asarray(center, dtype=np.float64)
        if c.shape != (3,) or not (math.isfinite(c[0]) and math.isfinite(c[1]) and math.isfinite(c[2])):
            raise ValueError(f"center={center!r}: expected 3 finite coordinates")
        if isinstance(radius, bool) or not np.isfinite(radius) or radius < 0:
            raise ValueError(f"radius={radius!r}: expected a finite radius >= 0")
        return c, float(radius)

    def occupied_in_sphere(self, center, radius: float, level: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """Centres (M, 3) and probabilities (M,) of the occupied cells of pyramid ``level`` whose
        centres lie within ``radius`` of ``center`` (block by block). Visits non-empty blocks only."""
        c, r = self._sphere_args(center, radius)
        lv = self._level_state(level)
        return _occupied_in_sphere(lv.grid, lv.counts, lv.bits, lv.key0, self._res * 2 ** level, c, r, False)

    def occupied_within(self, center, radius: float) -> bool:
        """True if any occupied voxel centre lies within ``radius`` of ``center``."""
        c, r = self._sphere_args(center, radius)
        lv = self._level_state(0)
        return _occupied_in_sphere(lv.grid, lv.counts, lv.bits, lv.key0, self._res, c, r, True)[1].size > 0

    def level(self, depth: int) -> tuple[np.ndarray, float, np.ndarray]:
        """Octree level ``depth``: (origin, res * 2**depth, read-only float32 log-odds grid).

        A cell holds the max of its known children (NaN if all are unknown), as an OctoMap inner
        node. Cells align with OctoMap's nodes at that depth, so the level's origin can lie below
        the map's. Cached; refreshed lazily over the region changed by ``integrate``.
        """
        lv = self._level_state(depth)
        view = lv.grid.view()
        view.flags.writeable = False
        return lv.key0 * (self._res * 2 ** depth), self._res * 2 ** depth, view

    def _level_state(self, depth) -> _Level:
        if isinstance(depth, bool) or not isinstance(depth, (int, np.integer)) or not 0 <= depth < self._n_levels:
            raise ValueError(f"level={depth!r}: expected an integer in [0, {self._n_levels - 1}]")
        if depth == 0:
            return self._levels[0]
        if self._dirty[0] <= self._dirty[3]:  # bring the built levels up to date
            region = self._dirty.copy()
            for d in range(1, len(self._levels)):
                region = _pool_level(self._levels[d - 1], self._levels[d], region, self._l_occ)
            self._dirty[:] = _empty_region()
        while len(self._levels) <= depth:
            d = len(self._levels)
            child = self._levels[d - 1]
            parent = _empty_level(self._key0 >> d, _level_shape(self._key0, self._shape, d))
            full = np.concatenate([np.zeros(3, np.int64), np.asarray(child.grid.shape, np.int64) - 1])
            _pool_level(child, parent, full, self._l_occ)
            self._levels.append(parent)
        return self._levels[depth]

    # ------------------------------------------------------------------ export
    def to_octomap(self):
        """An ``octomap.OcTree`` with the same leaves, sensor model and inner nodes (needs octomap-python)."""
        try:
            import octomap
        except ImportError as exc:
            raise ImportError("OccupancyMap.to_octomap needs the optional dependency octomap-python "
                              "(pip install 'uavform[octomap]')") from exc
        cfg = self._cfg
        tree = octomap.OcTree(self._res)
        tree.setProbHit(cfg.p_hit)
        tree.setProbMiss(cfg.p_miss)
        tree.setClampingThresMin(cfg.p_min)
        tree.setClampingThresMax(cfg.p_max)
        tree.setOccupancyThres(cfg.p_occ)
        grid = self._levels[0].grid
        idx = np.argwhere(~np.isnan(grid))
        values = grid[idx[:, 0], idx[:, 1], idx[:, 2]]
        centres = (self._key0 + idx + 0.5) * self._res
        # A new node starts at log-odds 0, so adding the value sets it exactly; one call per distinct value.
        order = np.argsort(values, kind="stable")
        distinct, starts = np.unique(values[order], return_index=True)
        for value, group in zip(distinct, np.split(centres[order], starts[1:])):
            tree.updateNodes(group, float(value), lazy_eval=True)
        tree.updateInnerOccupancy()
        return tree

    def write_bt(self, path) -> None:
        """Write a real OctoMap binary ``.bt`` file (atomically: temporary file + os.replace)."""
        tree = self.to_octomap()
        path = os.fspath(path)
        fd, tmp = tempfile.mkstemp(suffix=".bt.tmp", dir=os.path.dirname(os.path.abspath(path)))
        os.close(fd)
        try:
            if not tree.writeBinary(tmp):
                raise OSError(f"octomap could not write {tmp!r}")
            os.replace(tmp, path)
        except BaseException:
            if os.path.exists(tmp):
                os.remove(tmp)
            raise

    def read_only(self) -> OccupancyMap:
        """A view sharing this map's state whose queries work and whose mutators raise TypeError."""
        view = object.__new__(_ReadOnlyOccupancyMap)
        view.__dict__ = self.__dict__  # the same state object, so the view follows later updates
        return view


class _ReadOnlyOccupancyMap(OccupancyMap):
    """Read-only view of an ``OccupancyMap`` (built by ``read_only``)."""

    def integrate(self, sensor_origin, endpoints, hit) -> None:
        raise TypeError("this OccupancyMap is a read-only view: integrate() is not allowed")

    def integrate_scan(self, sensor_origin, scan_row_endpoints, scan_row_kind) -> None:
        raise TypeError("this OccupancyMap is a read-only view: integrate_scan() is not allowed")

    def read_only(self) -> OccupancyMap:
        return self


# ---------------------------------------------------------------------- helpers
def _check_shape(shape) -> tuple:
    try:
        dims = tuple(shape)
    except TypeError:
        dims = ()
    if len(dims) != 3 or not all(isinstance(n, (int, np.integer)) and not isinstance(n, bool) and n > 0 for n in dims):
        raise ValueError(f"shape={shape!r}: expected 3 positive integers (nx, ny, nz)")
    return tuple(int(n) for n in dims)


def _empty_region() -> np.ndarray:
    """A region (lo xyz, hi xyz) of local indices that contains nothing."""
    return np.array([1 << 62] * 3 + [-1] * 3, np.int64)


def _empty_level(key0: np.ndarray, shape) -> _Level:
    """A level with every cell unknown."""
    blocks = tuple(-(-n >> BLOCK_SHIFT) for n in shape)
    return _Level(key0, np.full(shape, np.nan, np.float32), np.zeros(blocks, np.int32),
                  np.zeros(shape[:2] + blocks[2:], np.uint8))


def _level_shape(key0: np.ndarray, shape, depth: int) -> tuple:
    """Shape of pyramid level ``depth``: the octree nodes covering the grid's keys."""
    hi = key0 + np.asarray(shape, np.int64) - 1
    return tuple(int(n) for n in (hi >> depth) - (key0 >> depth) + 1)


def _pool_level(child, parent, region: np.ndarray, l_occ) -> np.ndarray:
    """Refresh the parent cells above the child's ``region``; returns the refreshed parent region."""
    out = np.empty(6, np.int64)
    _pool(child.grid, child.key0, parent.grid, parent.key0, parent.counts, parent.bits, region, l_occ, out)
    return out


# ---------------------------------------------------------------------- kernels
@numba.njit(cache=True, inline="always")
def _update_voxel(flat, counts, bits, v, update, l_min, l_max, l_occ, ny, nz):
    """Add one log-odds update to voxel ``v`` (flat index) in float32, clamp, keep the summaries."""
    old = flat[v]
    was_occupied = old >= l_occ
    if np.isnan(old):
        old = np.float32(0.0)
    new = old + update
    if new < l_min:
        new = l_min
    elif new > l_max:
        new = l_max
    flat[v] = new
    is_occupied = new >= l_occ
    if is_occupied != was_occupied:
        k = v % nz
        j = (v // nz) % ny
        i = v // (nz * ny)
        counts[i >> BLOCK_SHIFT, j >> BLOCK_SHIFT, k >> BLOCK_SHIFT] += 1 if is_occupied else -1
        bits[i, j, k >> BLOCK_SHIFT] ^= np.uint8(1 << (k & 7))


@numba.njit(cache=True)
def _integrate(grid, stamp, counts, bits, dirty, key0, res, origin, endpoints, hit, l_hit, l_miss, l_min, l_max, l_occ):
    """OctoMap's computeUpdate + updateNode over a dense grid (see ``OccupancyMap.integrate``).

    Hit voxels are marked first; each ray then applies a miss to every unmarked voxel it crosses
    and marks it; finally the hits are applied and all marks cleared (the stamp is shared).
    """
    nx, ny, nz = grid.shape
    flat = grid.reshape(nx * ny * nz)
    marks = stamp.reshape(nx * ny * nz)
    inv_res = 1.0 / res
    n_rays = endpoints.shape[0]
    # OctoMap's point3d is float32: round the origin and the endpoints first.
    ox, oy, oz = np.float64(np.float32(origin[0])), np.float64(np.float32(origin[1])), np.float64(np.float32(origin[2]))
    ends = np.empty((n_rays, 3))
    capacity, longest = 0, 0
    lo = np.array([coord_key(ox, inv_res), coord_key(oy, inv_res), coord_key(oz, inv_res)]) - key0
    hi = lo.copy()
    for r in range(n_rays):
        for a in range(3):
            ends[r, a] = np.float32(endpoints[r, a])
            e = coord_key(ends[r, a], inv_res) - key0[a]
            lo[a], hi[a] = min(lo[a], e), max(hi[a], e)
        bound = ray_key_bound(ox, oy, oz, ends[r, 0], ends[r, 1], ends[r, 2], inv_res)
        capacity += bound + 1
        longest = max(longest, bound)
    touched = np.empty(capacity, np.int64)
    keys = np.empty((longest, 3), np.int64)
    n = 0
    for r in range(n_rays):  # occupied endpoints first: a hit beats a miss of the same scan
        if hit[r]:
            i = coord_key(ends[r, 0], inv_res) - key0[0]
            j = coord_key(ends[r, 1], inv_res) - key0[1]
            k = coord_key(ends[r, 2], inv_res) - key0[2]
            if 0 <= i < nx and 0 <= j < ny and 0 <= k < nz:
                v = (i * ny + j) * nz + k
                if marks[v] == _UNTOUCHED:
                    marks[v] = _HIT
                    touched[n] = v
                    n += 1
    kx0, ky0, kz0 = key0[0], key0[1], key0[2]
    for r in range(n_rays):  # misses, one per voxel and scan
        m = ray_keys(ox, oy, oz, ends[r, 0], ends[r, 1], ends[r, 2], res, keys)
        for q in range(m):
            i, j, k = keys[q, 0] - kx0, keys[q, 1] - ky0, keys[q, 2] - kz0
            if (i | j | k) >= 0 and i < nx and j < ny and k < nz:
                v = (i * ny + j) * nz + k
                if marks[v] == _UNTOUCHED:
                    marks[v] = _MISS
                    touched[n] = v
                    n += 1
                    _update_voxel(flat, counts, bits, v, l_miss, l_min, l_max, l_occ, ny, nz)
    for q in range(n):
        v = touched[q]
        if marks[v] == _HIT:
            _update_voxel(flat, counts, bits, v, l_hit, l_min, l_max, l_occ, ny, nz)
        marks[v] = _UNTOUCHED
    if n > 0:  # segments stay in the box of their end keys (+1 voxel of DDA drift): the changed region
        shape = (nx, ny, nz)
        for a in range(3):
            dirty[a] = min(dirty[a], max(lo[a] - 1, 0))
            dirty[a + 3] = max(dirty[a + 3], min(hi[a] + 1, shape[a] - 1))


@numba.njit(cache=True)
def _pool(child, child_key0, parent, parent_key0, parent_counts, parent_bits, region, l_occ, out):
    """Max-pool the 2x2x2 children of every parent cell above the child region (NaN = unknown),
    then redo the summaries of every parent block touched; write the parent region to out."""
    cn = child.shape
    pn = parent.shape
    for a in range(3):
        out[a] = ((child_key0[a] + region[a]) >> 1) - parent_key0[a]
        out[a + 3] = ((child_key0[a] + region[a + 3]) >> 1) - parent_key0[a]
    for pi in range(out[0], out[3] + 1):
        for pj in range(out[1], out[4] + 1):
            for pk in range(out[2], out[5] + 1):
                best = np.float32(np.nan)
                for bi in range(2):
                    ci = 2 * (parent_key0[0] + pi) + bi - child_key0[0]
                    if ci < 0 or ci >= cn[0]:
                        continue
                    for bj in range(2):
                        cj = 2 * (parent_key0[1] + pj) + bj - child_key0[1]
                        if cj < 0 or cj >= cn[1]:
                            continue
                        for bk in range(2):
                            ck = 2 * (parent_key0[2] + pk) + bk - child_key0[2]
                            if ck < 0 or ck >= cn[2]:
                                continue
                            v = child[ci, cj, ck]
                            if not np.isnan(v) and (np.isnan(best) or v > best):
                                best = v
                parent[pi, pj, pk] = best
    for bi in range(out[0] >> BLOCK_SHIFT, (out[3] >> BLOCK_SHIFT) + 1):
        for bj in range(out[1] >> BLOCK_SHIFT, (out[4] >> BLOCK_SHIFT) + 1):
            for bk in range(out[2] >> BLOCK_SHIFT, (out[5] >> BLOCK_SHIFT) + 1):
                c = 0
                for pi in range(bi << BLOCK_SHIFT, min((bi + 1) << BLOCK_SHIFT, pn[0])):
                    for pj in range(bj << BLOCK_SHIFT, min((bj + 1) << BLOCK_SHIFT, pn[1])):
                        row = 0
                        for pk in range(bk << BLOCK_SHIFT, min((bk + 1) << BLOCK_SHIFT, pn[2])):
                            if parent[pi, pj, pk] >= l_occ:
                                row |= 1 << (pk & 7)
                                c += 1
                        parent_bits[pi, pj, bk] = row
                parent_counts[bi, bj, bk] = c


@numba.njit(cache=True, inline="always")
def _gap(c, lo_centre, hi_centre):
    """Distance along one axis from c to the interval [lo_centre, hi_centre]."""
    return max(lo_centre - c, c - hi_centre, 0.0)


@numba.njit(cache=True)
def _candidate_blocks(counts, key0, res, center, radius, n):
    """Non-empty blocks within reach: rows (i0, i1, j0, j1, k0, k1, count) of the cell index box
    (inclusive) of the block clipped to the sphere's bounding box."""
    lo = np.empty(3, np.int64)
    hi = np.empty(3, np.int64)
    for a in range(3):  # cells whose centre may lie within the radius (one spare cell per side)
        lo[a] = max(0, np.int64(math.floor((center[a] - radius) / res - 0.5)) - key0[a])
        hi[a] = min(n[a] - 1, np.int64(math.ceil((center[a] + radius) / res - 0.5)) - key0[a])
    rows = np.empty((max(0, ((hi[0] >> BLOCK_SHIFT) - (lo[0] >> BLOCK_SHIFT) + 1)
                         * ((hi[1] >> BLOCK_SHIFT) - (lo[1] >> BLOCK_SHIFT) + 1)
                         * ((hi[2] >> BLOCK_SHIFT) - (lo[2] >> BLOCK_SHIFT) + 1)), 7), np.int64)
    m = 0
    if lo[0] > hi[0] or lo[1] > hi[1] or lo[2] > hi[2]:
        return rows[:0]
    r2 = radius * radius
    for bi in range(lo[0] >> BLOCK_SHIFT, (hi[0] >> BLOCK_SHIFT) + 1):
        i0, i1 = max(lo[0], bi << BLOCK_SHIFT), min(hi[0], ((bi + 1) << BLOCK_SHIFT) - 1)
        gi = _gap(center[0], (key0[0] + i0 + 0.5) * res, (key0[0] + i1 + 0.5) * res)
        for bj in range(lo[1] >> BLOCK_SHIFT, (hi[1] >> BLOCK_SHIFT) + 1):
            j0, j1 = max(lo[1], bj << BLOCK_SHIFT), min(hi[1], ((bj + 1) << BLOCK_SHIFT) - 1)
            gj = _gap(center[1], (key0[1] + j0 + 0.5) * res, (key0[1] + j1 + 0.5) * res)
            for bk in range(lo[2] >> BLOCK_SHIFT, (hi[2] >> BLOCK_SHIFT) + 1):
                if counts[bi, bj, bk] == 0:
                    continue
                k0, k1 = max(lo[2], bk << BLOCK_SHIFT), min(hi[2], ((bk + 1) << BLOCK_SHIFT) - 1)
                gk = _gap(center[2], (key0[2] + k0 + 0.5) * res, (key0[2] + k1 + 0.5) * res)
                if gi * gi + gj * gj + gk * gk > r2:
                    continue
                rows[m, 0], rows[m, 1], rows[m, 2], rows[m, 3] = i0, i1, j0, j1
                rows[m, 4], rows[m, 5], rows[m, 6] = k0, k1, counts[bi, bj, bk]
                m += 1
    return rows[:m]


@numba.njit(cache=True)
def _occupied_in_sphere(grid, counts, bits, key0, res, center, radius, first_only):
    """Occupied cells whose centres lie within ``radius``: candidate blocks only, and in them only
    the set bits of their rows; with ``first_only`` stop at the first one."""
    blocks = _candidate_blocks(counts, key0, res, center, radius, grid.shape)
    capacity = 0
    for b in range(blocks.shape[0]):
        capacity += blocks[b, 6]
    centres = np.empty((capacity, 3))
    probs = np.empty(capacity)
    r2 = radius * radius
    m = 0
    for b in range(blocks.shape[0]):
        k0, k1 = blocks[b, 4], blocks[b, 5]
        kb = k0 >> BLOCK_SHIFT
        in_range = ((1 << (k1 - (kb << BLOCK_SHIFT) + 1)) - 1) & ~((1 << (k0 - (kb << BLOCK_SHIFT))) - 1)
        for i in range(blocks[b, 0], blocks[b, 1] + 1):
            x = (key0[0] + i + 0.5) * res
            for j in range(blocks[b, 2], blocks[b, 3] + 1):
                row = bits[i, j, kb] & in_range
                if row == 0:
                    continue
                y = (key0[1] + j + 0.5) * res
                for bit in range(1 << BLOCK_SHIFT):
                    if not (row >> bit) & 1:
                        continue
                    k = (kb << BLOCK_SHIFT) + bit
                    z = (key0[2] + k + 0.5) * res
                    if (x - center[0]) ** 2 + (y - center[1]) ** 2 + (z - center[2]) ** 2 <= r2:
                        centres[m, 0], centres[m, 1], centres[m, 2] = x, y, z
                        probs[m] = 1.0 / (1.0 + math.exp(-np.float64(grid[i, j, k])))
                        m += 1
                        if first_only:
                            return centres[:m], probs[:m]
    return centres[:m], probs[:m]
