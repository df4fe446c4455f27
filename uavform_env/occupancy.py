"""Onboard occupancy maps: sparse voxel blocks of log-odds updated with OctoMap's rules.

Every map allocates fixed-size blocks of 8^3 float32 log-odds (NaN = never observed) on first
touch, the voxblox way, so its memory follows what its UAV has seen rather than the world's size
(spec (e3) allows any store with OctoMap's semantics). The maps of one environment share one
``MapStore``: one pool of blocks and a two-level index, a dense table per map with one int32 per
64^3 voxels (a chunk; -1 = never touched) pointing into a pool of chunks, each holding its 8^3
blocks' pool indices. Two dense levels keep a lookup O(1) and branch-light inside numba kernels, and
the per-map table costs 1/262144 of a dense grid (a one-level table, 1/512, grew as N x world: 0.75
GB at 200 UAVs); a hash table would add probing for no gain here. ``OccupancyMap`` is one map's view
of the store and carries the public API.

Scans are integrated like ``OccupancyOcTreeBase::insertPointCloud`` (``computeUpdate`` +
``updateNode``): the rays' voxels come from the ported ``computeRayKeys``, every voxel is updated
at most once per scan and a hit beats a miss, log-odds add in float32 and are clamped. Labels
therefore match ``octomap-python`` voxel by voxel (tests/test_octomap_parity.py). ``MapStore``
integrates the scans of many maps in one numba call.

Each block carries its occupied count and per-row occupied bits (8 voxels along z per byte), kept
by the integrate kernel, so a sphere query skips empty blocks and reads a block's 64 row bytes
instead of its 512 voxels. Pyramid level d (OctoMap's inner nodes d levels up, a max-pool of the
known children) is stored the same way, built lazily and refreshed over the region changed since.

Kernels of other modules read a map through ``OccupancyMap.arrays()`` (a ``MapArrays``) and the
``voxel_logodds`` accessor, never through a dense array.
"""

from __future__ import annotations

import math
import os
import tempfile
from typing import NamedTuple

import numba
import numpy as np

from .config import MapConfig
from .dda import coord_key, grid_origin_key, ray_key_bound, ray_select, ray_setup, ray_step

BLOCK_SHIFT = 3  # blocks of 2**3 = 8 voxels per axis
BLOCK_VOXELS = 1 << (3 * BLOCK_SHIFT)
_MASK = (1 << BLOCK_SHIFT) - 1
# Bytes per pooled block: log-odds, scan stamps, row bits, occupied count.
BLOCK_BYTES = BLOCK_VOXELS * 4 + BLOCK_VOXELS + BLOCK_VOXELS // 8 + 4
CHUNK_SHIFT = 2 * BLOCK_SHIFT  # log2 of a chunk's edge in voxels
BLOCK_EDGE, CHUNK_EDGE = 1 << BLOCK_SHIFT, 1 << CHUNK_SHIFT  # edges in voxels
CHUNK_BYTES = BLOCK_VOXELS * 4 + 8  # block entries and the owner entry
# Deepest pyramid level: OctoMap's depth-1 nodes (tree depth 16; keys align up to 2**15, the root
# straddles the origin and is not a level).
MAX_LEVEL = 15
_LAST_STAMP = 254  # scan stamps (uint8) run 1.._LAST_STAMP, then every stamp is zeroed and they restart
_SETTLED = 255  # the stamp of a voxel at the clamping minimum l_min, which a miss leaves as it is (kept on wraps)
_FIRST_CAPACITY = 1024  # pool blocks per map reserved up front (untouched pages cost no RSS); grows by half


class MapArrays(NamedTuple):
    """One map's (one pyramid level's) arrays as numba kernels read them, through ``voxel_logodds``.

    Valid until the map is next updated (the pools may grow and move). Cell (i, j, k) counts from the
    map's lower corner ``key0`` (the local index of the former dense grid).
    """

    key0: np.ndarray    # (3,) int64 key of cell (0, 0, 0)
    shape: np.ndarray   # (3,) int64 cells per axis
    top: np.ndarray     # (cx, cy, cz) int32 chunk of each 64^3 voxels, -1 = never observed
    chunks: np.ndarray  # (C, 512) int32 pool block of each 8^3 block of a chunk, -1 = never observed
    values: np.ndarray  # (P, 512) float32 log-odds of the pool's blocks, NaN = unknown


@numba.njit(cache=True, inline="always")
def voxel_logodds(arrays, i, j, k):
    """float32 log-odds of cell (i, j, k) of ``arrays`` (a ``MapArrays``); NaN if unknown or outside."""
    if i < 0 or j < 0 or k < 0 or i >= arrays.shape[0] or j >= arrays.shape[1] or k >= arrays.shape[2]:
        return np.float32(np.nan)
    c = arrays.top[i >> CHUNK_SHIFT, j >> CHUNK_SHIFT, k >> CHUNK_SHIFT]
    if c < 0:
        return np.float32(np.nan)
    b = arrays.chunks[c, _offset(i >> BLOCK_SHIFT, j >> BLOCK_SHIFT, k >> BLOCK_SHIFT)]
    if b < 0:
        return np.float32(np.nan)
    return arrays.values[b, _offset(i, j, k)]


class _Blocks:
    """One pyramid level of every map of a store: per-map chunk tables into a chunk pool into a block pool.

    ``tables`` = (top (n_maps, cx, cy, cz) int32, chunks (C, 512) int32), the block index the kernels
    take; ``owner[c]`` is chunk c's entry in ``top`` (flat); ``used`` = (blocks, chunks) in use;
    ``stamps`` (P, 512) uint8 the leaves' scan stamps (see ``_integrate_one``).
    """

    def __init__(self, key0: np.ndarray, shape: tuple, n_maps: int, capacity: int):
        self.key0 = key0
        self.shape = np.asarray(shape, np.int64)
        self.top = np.full((n_maps,) + tuple(-(-n >> CHUNK_SHIFT) for n in shape), -1, np.int32)
        self.used = np.zeros(2, np.int64)
        self.values = self.stamps = self.bits = self.counts = self.chunks = self.owner = None
        self.grow(capacity)

    @property
    def tables(self) -> tuple:
        return self.top, self.chunks

    def grow(self, at_least: int = 0) -> None:
        """Grow the block pool by half (or to ``at_least`` blocks) and the chunk pool with it; indices stay."""
        blocks = 0 if self.values is None else self.values.shape[0]
        blocks = max(at_least, blocks + max(16, blocks // 2))
        grown = (np.empty((blocks, BLOCK_VOXELS), np.float32), np.zeros((blocks, BLOCK_VOXELS), np.uint8),
                 np.empty((blocks, BLOCK_VOXELS >> BLOCK_SHIFT), np.uint8), np.empty(blocks, np.int32),
                 np.empty((max(16, blocks >> 3), BLOCK_VOXELS), np.int32), np.empty(max(16, blocks >> 3), np.int64))
        if self.values is not None:
            old = (self.values, self.stamps, self.bits, self.counts, self.chunks, self.owner)
            for new, prev, n in zip(grown, old, [self.used[0]] * 4 + [self.used[1]] * 2):
                new[:n] = prev[:n]
        self.values, self.stamps, self.bits, self.counts, self.chunks, self.owner = grown

    def adopt_pool(self, other: _Blocks) -> None:
        """Take over the (emptied) pools of ``other``."""
        self.values, self.stamps, self.bits, self.counts, self.chunks, self.owner = (
            other.values, other.stamps, other.bits, other.counts, other.chunks, other.owner)

    def pool(self) -> tuple:
        """The arguments every block kernel takes, in order."""
        return self.tables, self.values, self.bits, self.counts, self.owner, self.used

    def clear(self) -> None:
        """Forget every block (the pools are kept and reused)."""
        _clear(self.top, self.owner, self.used)

    def arrays(self, index: int) -> MapArrays:
        return MapArrays(self.key0, self.shape, self.top[index], self.chunks, self.values)

    def n_blocks(self, index: int) -> int:
        """Blocks allocated to map ``index``."""
        own = self.top[index][self.top[index] >= 0]
        return int(np.count_nonzero(self.chunks[own] >= 0))

    @property
    def nbytes(self) -> int:
        return sum(a.nbytes for a in (self.top, self.values, self.stamps, self.bits, self.counts, self.chunks,
                                      self.owner))


class MapStore:
    """The occupancy maps of ``n_maps`` UAVs over one grid (lower corner ``origin``, ``shape`` cells).

    ``maps[i]`` is map i's ``OccupancyMap``; ``integrate`` inserts one scan into many maps in one
    numba call; ``clear`` forgets everything without reallocating. ``cfg`` supplies the sensor model
    (p_hit, p_miss, clamping, p_occ); ``cfg.resolution`` is not consulted.
    """

    def __init__(self, origin, shape, resolution: float, cfg: MapConfig = MapConfig(), n_maps: int = 1):
        if not isinstance(cfg, MapConfig):
            raise ValueError(f"cfg: expected a MapConfig, got {type(cfg).__name__}")
        if isinstance(n_maps, bool) or not isinstance(n_maps, (int, np.integer)) or n_maps < 1:
            raise ValueError(f"n_maps={n_maps!r}: expected an integer >= 1")
        grid_origin_key(origin, resolution)                      # checks the resolution first
        self.res = float(resolution)
        self.cfg = cfg
        self.n_maps = int(n_maps)
        f32 = np.float32
        self.l_hit, self.l_miss = f32(cfg.logodds(cfg.p_hit)), f32(cfg.logodds(cfg.p_miss))
        self.l_min, self.l_max = f32(cfg.logodds(cfg.p_min)), f32(cfg.logodds(cfg.p_max))
        self.l_occ = f32(cfg.logodds(cfg.p_occ))
        self.levels = []
        self.dirty = np.empty((self.n_maps, 6), np.int64)  # per map: leaves changed since its pyramid refresh
        self._scan = np.zeros(1, np.int64)  # the stamp of the last scan integrated (see _integrate_maps)
        self.clear(origin, shape)
        self.maps = [OccupancyMap._view(self, i) for i in range(self.n_maps)]

    def clear(self, origin=None, shape=None) -> None:
        """Forget every observation of every map, keeping the block pool for reuse; with ``origin`` and
        ``shape``, the maps cover that grid from now on (new chunk tables, the same pools)."""
        same = self.levels and (origin is None or (np.array_equal(grid_origin_key(origin, self.res), self.key0)
                                                   and _check_shape(shape) == self.shape))
        if same:
            self.levels[0].clear()                               # unlinks the used blocks only
        else:
            self.key0 = grid_origin_key(origin, self.res)
            self.shape = _check_shape(shape)
            self.n_levels = 1
            while self.n_levels <= MAX_LEVEL and max(_level_shape(self.key0, self.shape, self.n_levels - 1)) > 1:
                self.n_levels += 1
            leaves = _Blocks(self.key0, self.shape, self.n_maps, 16)
            if self.levels:
                leaves.adopt_pool(self.levels[0])
            else:
                leaves.grow(_FIRST_CAPACITY * self.n_maps)
            self.levels = [leaves]
        del self.levels[1:]
        self.dirty[:] = _empty_region()

    def integrate(self, indices, sensor_origins, endpoints, hit) -> None:
        """Insert one scan into each map ``indices[q]``: rays from ``sensor_origins[q]`` to ``endpoints[q]``
        (R, 3), ``hit[q]`` (R,) as in ``OccupancyMap.integrate``. One numba call for all maps."""
        idx = np.ascontiguousarray(indices, dtype=np.int64)
        if idx.ndim != 1 or ((idx < 0) | (idx >= self.n_maps)).any() or np.bincount(idx).max(initial=0) > 1:
            raise ValueError(f"indices: expected distinct map indices in [0, {self.n_maps - 1}], got {indices!r}")
        o = np.ascontiguousarray(sensor_origins, dtype=np.float64)
        if o.shape != (idx.size, 3) or not np.isfinite(o).all():
            raise ValueError(f"sensor_origins: expected finite ({idx.size}, 3) coordinates, got shape {o.shape}")
        ends = np.ascontiguousarray(endpoints, dtype=np.float64)
        if ends.ndim != 3 or ends.shape[0] != idx.size or ends.shape[2] != 3 or not np.isfinite(ends).all():
            raise ValueError(f"endpoints: expected finite ({idx.size}, R, 3) coordinates, got shape {ends.shape}")
        hit = np.ascontiguousarray(hit)
        if hit.dtype != np.bool_ or hit.shape != ends.shape[:2]:
            raise ValueError(f"hit: expected a bool array of shape {ends.shape[:2]}, got {hit.dtype} {hit.shape}")
        leaves = self.levels[0]
        done = 0
        while done < idx.size:  # the kernel stops before a map that might not fit in the pool
            done = _integrate_maps(*leaves.pool(), leaves.stamps, self._scan, self.dirty, self.key0, leaves.shape,
                                   self.res, idx, o, ends, hit, self.l_hit, self.l_miss, self.l_min, self.l_max,
                                   self.l_occ, done)
            if done < idx.size:
                leaves.grow()

    def level_blocks(self, depth: int, indices) -> _Blocks:
        """Pyramid level ``depth``, brought up to date for the maps ``indices``."""
        if isinstance(depth, bool) or not isinstance(depth, (int, np.integer)) or not 0 <= depth < self.n_levels:
            raise ValueError(f"level={depth!r}: expected an integer in [0, {self.n_levels - 1}]")
        if depth == 0:
            return self.levels[0]
        idx = np.ascontiguousarray(indices, dtype=np.int64)
        stale = idx[self.dirty[idx, 0] <= self.dirty[idx, 3]]
        if stale.size and len(self.levels) > 1:  # bring the built levels up to date
            regions = self.dirty[stale].copy()
            for d in range(1, len(self.levels)):
                regions = self._pool(d, stale, regions)
        self.dirty[stale] = _empty_region()
        while len(self.levels) <= depth:  # build the missing levels for every map
            d = len(self.levels)
            self.levels.append(_Blocks(self.key0 >> d, _level_shape(self.key0, self.shape, d), self.n_maps,
                                       max(16, self.levels[d - 1].values.shape[0] >> 2)))
            every = np.arange(self.n_maps)
            full = np.tile(np.concatenate([np.zeros(3, np.int64), self.levels[d - 1].shape - 1]), (self.n_maps, 1))
            self._pool(d, every, full)
        return self.levels[depth]

    def _pool(self, d: int, indices: np.ndarray, regions: np.ndarray) -> np.ndarray:
        """Refresh level d above the child regions (one row per map); returns the refreshed regions."""
        child, parent = self.levels[d - 1], self.levels[d]
        out = np.empty_like(regions)
        while not _pool_maps(child.tables, child.values, child.shape, child.key0, *parent.pool(), parent.key0,
                             indices, regions, self.l_occ, out):
            parent.grow()  # pooling is idempotent: redo it with room
        return out

    @property
    def nbytes(self) -> int:
        """Bytes held by the tables and pools of every level."""
        return sum(lv.nbytes for lv in self.levels) + self.dirty.nbytes


class OccupancyMap:
    """One UAV's own map: sparse float32 log-odds voxels (NaN = unknown) updated with OctoMap's rules.

    ``OccupancyMap(origin, shape, resolution, cfg)`` makes a standalone map (a store of one map);
    an environment's maps are the ``maps`` of its ``MapStore``. The grid's lower corner is
    ``origin``, its extent ``shape`` voxels of size ``resolution``; ``cfg`` supplies the sensor
    model. A voxel is occupied when its log-odds is >= logit(p_occ), as OctoMap's ``isNodeOccupied``.
    """

    def __init__(self, origin, shape, resolution: float, cfg: MapConfig = MapConfig()):
        store = MapStore(origin, shape, resolution, cfg, 1)
        self.__dict__ = store.maps[0].__dict__

    @classmethod
    def _view(cls, store: MapStore, index: int) -> OccupancyMap:
        view = object.__new__(cls)
        view._store, view._index = store, index
        return view

    # ------------------------------------------------------------------ properties
    @property
    def origin(self) -> np.ndarray:
        return self._store.key0 * self._store.res

    @property
    def shape(self) -> tuple:
        return self._store.shape

    @property
    def resolution(self) -> float:
        return self._store.res

    @property
    def cfg(self) -> MapConfig:
        return self._store.cfg

    @property
    def n_levels(self) -> int:
        """Number of pyramid levels: up to the first single-cell level, at most MAX_LEVEL + 1."""
        return self._store.n_levels

    @property
    def n_blocks(self) -> int:
        """Leaf blocks (8^3 voxels) allocated so far: what this map has touched."""
        return self._store.levels[0].n_blocks(self._index)

    def arrays(self) -> MapArrays:
        """The leaves as numba kernels read them (with ``voxel_logodds``); valid until the next update."""
        return self._store.levels[0].arrays(self._index)

    @property
    def logodds(self) -> np.ndarray:
        """A dense read-only float32 copy of the leaf log-odds (NaN = unknown), as large as the grid:
        for tests and small maps; kernels read ``arrays()`` instead."""
        return self.level(0)[2]

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
        ends = np.asarray(endpoints, dtype=np.float64)
        if ends.ndim != 2 or ends.shape[1] != 3 or not np.all(np.isfinite(ends)):
            raise ValueError(f"endpoints: expected finite (R, 3) coordinates, got shape {ends.shape}")
        hit = np.asarray(hit)
        if hit.dtype != np.bool_ or hit.shape != (ends.shape[0],):
            raise ValueError(f"hit: expected a bool array of shape ({ends.shape[0]},), got {hit.dtype} {hit.shape}")
        self._store.integrate([self._index], o[None], ends[None], hit[None])

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
        idx = np.floor(p.reshape(-1, 3) * (1.0 / self._store.res)).astype(np.int64) - self._store.key0
        return _lookup(self.arrays(), idx).reshape(p.shape[:-1])

    def label(self, points) -> np.ndarray:
        """int8 per point: -1 unknown (also outside the grid), 0 free, 1 occupied."""
        v = self._values(points)
        return np.where(np.isnan(v), -1, v >= self._store.l_occ).astype(np.int8)

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
        lv = self._store.level_blocks(level, [self._index])
        return occupied_cells(lv.tables, lv.values, lv.bits, lv.counts, self._index, lv.key0, lv.shape,
                                   self._store.res * 2 ** level, c, r, False)

    def occupied_within(self, center, radius: float) -> bool:
        """True if any occupied voxel centre lies within ``radius`` of ``center``."""
        c, r = self._sphere_args(center, radius)
        lv = self._store.levels[0]
        return occupied_cells(lv.tables, lv.values, lv.bits, lv.counts, self._index, lv.key0, lv.shape,
                                   self._store.res, c, r, True)[1].size > 0

    def level(self, depth: int) -> tuple[np.ndarray, float, np.ndarray]:
        """Octree level ``depth``: (origin, res * 2**depth, read-only dense float32 log-odds grid).

        A cell holds the max of its known children (NaN if all are unknown), as an OctoMap inner
        node. Cells align with OctoMap's nodes at that depth, so the level's origin can lie below
        the map's. The level is kept sparse and refreshed lazily over the region changed by
        ``integrate``; the dense grid returned is a copy (kernels read ``level_arrays``).
        """
        lv = self._store.level_blocks(depth, [self._index])
        grid = np.full(tuple(lv.shape), np.nan, np.float32)
        _densify(lv.tables, self._index, lv.values, grid)
        grid.flags.writeable = False
        return lv.key0 * (self._store.res * 2 ** depth), self._store.res * 2 ** depth, grid

    def level_arrays(self, depth: int) -> MapArrays:
        """Pyramid level ``depth`` as a ``MapArrays`` (cell size res * 2**depth), brought up to date."""
        return self._store.level_blocks(depth, [self._index]).arrays(self._index)

    # ------------------------------------------------------------------ export
    def to_octomap(self):
        """An ``octomap.OcTree`` with the same leaves, sensor model and inner nodes (needs octomap-python)."""
        try:
            import octomap
        except ImportError as exc:
            raise ImportError("OccupancyMap.to_octomap needs the optional dependency octomap-python "
                              "(pip install 'uavform[octomap]')") from exc
        cfg = self.cfg
        tree = octomap.OcTree(self.resolution)
        tree.setProbHit(cfg.p_hit)
        tree.setProbMiss(cfg.p_miss)
        tree.setClampingThresMin(cfg.p_min)
        tree.setClampingThresMax(cfg.p_max)
        tree.setOccupancyThres(cfg.p_occ)
        leaves = self._store.levels[0]
        idx, values = _known(leaves.tables, self._index, leaves.values, leaves.shape)
        centres = (self._store.key0 + idx + 0.5) * self.resolution
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


# ---------------------------------------------------------------------- memory estimate
def map_memory_estimate(shape, n_maps: int, seen_blocks: int, seen_chunks: int) -> int:
    """Bytes of ``n_maps`` leaf maps over a grid of ``shape`` voxels when each touches at most
    ``seen_blocks`` blocks in ``seen_chunks`` chunks (capped at the grid's): tables, chunks, blocks."""
    grid_blocks = math.prod(-(-int(n) >> BLOCK_SHIFT) for n in shape)
    grid_chunks = math.prod(-(-int(n) >> CHUNK_SHIFT) for n in shape)
    return n_maps * (4 * grid_chunks + min(seen_chunks, grid_chunks) * CHUNK_BYTES
                     + min(seen_blocks, grid_blocks) * BLOCK_BYTES)


def seen_blocks_bound(r_max: float, path_length: float, res: float, edge_voxels: int = BLOCK_EDGE) -> int:
    """Cubes of ``edge_voxels`` voxels (default: blocks) a sensor of range ``r_max`` can touch along a
    path of ``path_length`` m: those of a box as long as the path plus 2 r_max and 2 r_max wide and
    high, one spare cube per side."""
    edge = res * edge_voxels
    across = math.ceil(2.0 * r_max / edge) + 2
    return int((math.ceil((path_length + 2.0 * r_max) / edge) + 2) * across * across)


def available_memory() -> int:
    """Bytes of memory available to a new allocation: /proc/meminfo's MemAvailable, else free physical pages."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")


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


def _level_shape(key0: np.ndarray, shape, depth: int) -> tuple:
    """Shape of pyramid level ``depth``: the octree nodes covering the grid's keys."""
    hi = key0 + np.asarray(shape, np.int64) - 1
    return tuple(int(n) for n in (hi >> depth) - (key0 >> depth) + 1)


# ---------------------------------------------------------------------- kernels
@numba.njit(cache=True)
def _clear(top, owner, used):
    """Unlink every pooled chunk from its map's table and empty both pools."""
    flat = top.reshape(top.size)
    for c in range(used[1]):
        flat[owner[c]] = -1
    used[0] = used[1] = 0


@numba.njit(cache=True, inline="always")
def _block_at(tables, m, bi, bj, bk):
    """Pool index of block (bi, bj, bk) of map m (int64), -1 if never observed; ``tables`` = (top, chunks)."""
    c = tables[0][m, bi >> BLOCK_SHIFT, bj >> BLOCK_SHIFT, bk >> BLOCK_SHIFT]
    if c < 0:
        return np.int64(-1)
    return np.int64(tables[1][c, _offset(bi, bj, bk)])


@numba.njit(cache=True)
def _new_block(top, chunks, values, bits, counts, owner, used, m, bi, bj, bk):
    """Allocate block (bi, bj, bk) of map m (all unknown) from the pool, and its chunk if it has none;
    -1 if a pool is full. Callers look the block up first and call this only on a miss."""
    ci, cj, ck = bi >> BLOCK_SHIFT, bj >> BLOCK_SHIFT, bk >> BLOCK_SHIFT
    c = np.int64(top[m, ci, cj, ck])
    if used[0] >= values.shape[0] or (c < 0 and used[1] >= chunks.shape[0]):
        return np.int64(-1)
    if c < 0:
        c = used[1]
        used[1] = c + 1
        top[m, ci, cj, ck] = c
        for e in range(BLOCK_VOXELS):
            chunks[c, e] = -1
        owner[c] = ((m * top.shape[1] + ci) * top.shape[2] + cj) * top.shape[3] + ck
    b = used[0]
    used[0] = b + 1
    chunks[c, _offset(bi, bj, bk)] = b
    for v in range(BLOCK_VOXELS):
        values[b, v] = np.nan
    for row in range(bits.shape[1]):
        bits[b, row] = 0
    counts[b] = 0
    return b


@numba.njit(cache=True, inline="always")
def _offset(i, j, k):
    """Voxel (i, j, k)'s index inside its block."""
    return (((i & _MASK) << BLOCK_SHIFT | (j & _MASK)) << BLOCK_SHIFT) | (k & _MASK)


@numba.njit(cache=True, inline="always")
def _added(old, update, l_min, l_max):
    """A voxel's log-odds ``old`` (NaN = unknown, counted as 0) plus one update, in float32, clamped."""
    return min(max((np.float32(0.0) if np.isnan(old) else old) + update, l_min), l_max)


@numba.njit(cache=True, inline="always")
def _flip(bits, counts, f, old, new, l_occ):
    """Keep the block summaries of pooled voxel f (flat: block * 512 + offset; ``bits`` a flat view of the pool)
    when its log-odds goes from ``old`` to ``new``: its row bit and the block's occupied count."""
    if (new >= l_occ) != (old >= l_occ):
        counts[f >> (3 * BLOCK_SHIFT)] += 1 if new >= l_occ else -1
        bits[f >> BLOCK_SHIFT] ^= np.uint8(1 << (f & _MASK))


@numba.njit(cache=True)
def _integrate_maps(tables, values, bits, counts, owner, used, stamps, scan, dirty, key0, shape, res, indices, origins,
                    endpoints, hit, l_hit, l_miss, l_min, l_max, l_occ, start):
    """Integrate scan q into map indices[q] for q = start, ...; return the first q not done because the
    pools might run out during it (grow them and call again from there), or len(indices).

    Each scan gets the next stamp ``scan[0]`` (1.._LAST_STAMP); when the stamps wrap, every voxel's is zeroed
    but _SETTLED ones (see ``_integrate_one``)."""
    inv_res = 1.0 / res
    n_rays = endpoints.shape[1]
    ends = np.empty((n_rays, 3))
    for q in range(start, indices.shape[0]):
        # OctoMap's point3d is float32: round the origin and the endpoints first. A ray of K keys enters
        # at most K / 8 + 4 blocks (a block change needs 8 steps along one axis), and at most K / 64 + 4 chunks.
        o = origins[q]
        ox, oy, oz = np.float64(np.float32(o[0])), np.float64(np.float32(o[1])), np.float64(np.float32(o[2]))
        need, need_chunks = 0, 0
        for r in range(n_rays):
            for a in range(3):
                ends[r, a] = np.float32(endpoints[q, r, a])
            bound = ray_key_bound(ox, oy, oz, ends[r, 0], ends[r, 1], ends[r, 2], inv_res)
            need += bound // (1 << BLOCK_SHIFT) + 5
            need_chunks += bound // (1 << CHUNK_SHIFT) + 5
        if used[0] + need > values.shape[0] or used[1] + need_chunks > tables[1].shape[0]:
            return q
        scan[0] += 1
        if scan[0] > _LAST_STAMP:
            flat = stamps.reshape(stamps.size)
            for f in range(used[0] << (3 * BLOCK_SHIFT)):  # blocks allocated later get theirs zeroed
                if flat[f] != _SETTLED:
                    flat[f] = 0
            scan[0] = 1
        _integrate_one(tables, values, bits, counts, owner, used, stamps, np.uint8(scan[0]), dirty[indices[q]], key0,
                       shape, res, indices[q], ox, oy, oz, ends, hit[q], l_hit, l_miss, l_min, l_max, l_occ)
    return indices.shape[0]


@numba.njit(cache=True)
def _integrate_one(tables, values, bits, counts, owner, used, stamps, stamp, dirty, key0, shape, res, m, ox, oy, oz,
                   ends, hit, l_hit, l_miss, l_min, l_max, l_occ):
    """OctoMap's computeUpdate + updateNode for one map (see ``OccupancyMap.integrate``), from the float32
    origin (ox, oy, oz) to the float32 ``ends``; the pool has room.

    A voxel is updated at most once per scan: only if its stamp is not yet this scan's ``stamp``, which
    the update sets. The hit voxels go first (a hit beats a miss), then each ray walks its
    ``computeRayKeys`` voxels (``ray_setup``, ``ray_select``, ``ray_step``) and applies misses. A miss on a voxel
    clamped at l_min changes nothing, so such voxels (free space missed in several earlier scans) carry
    the stamp _SETTLED, set by the miss that clamped them and replaced by the next hit, and the walk leaves
    them as they are on that one byte. The walk does not branch on the stamp (most voxels it visits are
    settled or done in this scan, a condition hard to foresee): it works the miss out for every voxel and
    stores it, or writes the voxel back unchanged (faster than the branch: docs/speed.md, session 13). The
    walk keeps the last block looked up and resolves a block only when it enters one (the lookup is written
    out here: an inlined helper that may call ``_new_block``, or one that takes arrays and returns a value,
    costs refcounting on every voxel).
    """
    nx, ny, nz = shape[0], shape[1], shape[2]
    top, chunks = tables
    flat_values = values.reshape(values.size)
    flat_stamps = stamps.reshape(stamps.size)
    flat_bits = bits.reshape(bits.size)
    inv_res = 1.0 / res
    n_rays = ends.shape[0]
    kx0, ky0, kz0 = key0[0], key0[1], key0[2]
    okx, oky, okz = coord_key(ox, inv_res), coord_key(oy, inv_res), coord_key(oz, inv_res)
    lo0, lo1, lo2 = okx - kx0, oky - ky0, okz - kz0
    hi0, hi1, hi2 = lo0, lo1, lo2
    changed = False
    for r in range(n_rays):  # the hit voxels, and the box of the end keys
        i = coord_key(ends[r, 0], inv_res) - kx0
        j = coord_key(ends[r, 1], inv_res) - ky0
        k = coord_key(ends[r, 2], inv_res) - kz0
        lo0, lo1, lo2, hi0, hi1, hi2 = min(lo0, i), min(lo1, j), min(lo2, k), max(hi0, i), max(hi1, j), max(hi2, k)
        if hit[r] and (i | j | k) >= 0 and i < nx and j < ny and k < nz:
            bi, bj, bk = i >> BLOCK_SHIFT, j >> BLOCK_SHIFT, k >> BLOCK_SHIFT
            c = top[m, bi >> BLOCK_SHIFT, bj >> BLOCK_SHIFT, bk >> BLOCK_SHIFT]
            b = np.int64(chunks[c, _offset(bi, bj, bk)] if c >= 0 else -1)
            if b < 0:
                b = _new_block(top, chunks, values, bits, counts, owner, used, m, bi, bj, bk)
                stamps[b, :] = 0  # a reused block's may be _SETTLED
            f = (b << (3 * BLOCK_SHIFT)) | _offset(i, j, k)
            changed = True
            if flat_stamps[f] != stamp:
                flat_stamps[f] = stamp
                old = flat_values[f]
                flat_values[f] = _added(old, l_hit, l_min, l_max)
                _flip(flat_bits, counts, f, old, flat_values[f], l_occ)
    cbi, cbj, cbk, base = np.int64(-1), np.int64(-1), np.int64(-1), np.int64(0)  # the last block looked up
    for r in range(n_rays):  # the misses
        ex, ey, ez = ends[r, 0], ends[r, 1], ends[r, 2]
        ekx, eky, ekz = coord_key(ex, inv_res), coord_key(ey, inv_res), coord_key(ez, inv_res)
        if okx == ekx and oky == eky and okz == ekz:
            continue
        sx, sy, sz, tx, ty, tz, ddx, ddy, ddz, length = ray_setup(ox, oy, oz, ex, ey, ez, okx, oky, okz, res)
        i, j, k = okx - kx0, oky - ky0, okz - kz0
        ei, ej, ek = ekx - kx0, eky - ky0, ekz - kz0
        # a walk stays within one voxel of its end keys' box (DDA drift): inside the grid, skip the checks
        on_x, on_y, on_z, _ = ray_select(tx, ty, tz)
        inside = (min(i, ei) >= 2 and min(j, ej) >= 2 and min(k, ek) >= 2 and max(i, ei) < nx - 2
                  and max(j, ej) < ny - 2 and max(k, ek) < nz - 2)
        while True:
            if inside or ((i | j | k) >= 0 and i < nx and j < ny and k < nz):
                bi, bj, bk = i >> BLOCK_SHIFT, j >> BLOCK_SHIFT, k >> BLOCK_SHIFT
                if bi != cbi or bj != cbj or bk != cbk:
                    c = top[m, bi >> BLOCK_SHIFT, bj >> BLOCK_SHIFT, bk >> BLOCK_SHIFT]
                    b = np.int64(chunks[c, _offset(bi, bj, bk)] if c >= 0 else -1)
                    if b < 0:
                        b = _new_block(top, chunks, values, bits, counts, owner, used, m, bi, bj, bk)
                        stamps[b, :] = 0
                    cbi, cbj, cbk, base = bi, bj, bk, b << (3 * BLOCK_SHIFT)
                f = np.uint64(base | _offset(i, j, k))  # unsigned: no negative-index wrap in the loads
                changed = True
                # branch-free (see the docstring): the miss is worked out always, then stored or the voxel rewritten
                mark = flat_stamps[f]
                apply = (mark != stamp) & (mark != _SETTLED)
                old = flat_values[f]
                new = _added(old, l_miss, l_min, l_max)
                flat_values[f] = new if apply else old
                flat_stamps[f] = (_SETTLED if new == l_min else stamp) if apply else mark
                if apply:
                    _flip(flat_bits, counts, f, old, new, l_occ)
            i, j, k, tx, ty, tz = ray_step(i, j, k, sx, sy, sz, tx, ty, tz, ddx, ddy, ddz, on_x, on_y, on_z)
            on_x, on_y, on_z, t = ray_select(tx, ty, tz)  # t = min(tx, ty, tz)
            if ((i == ei) & (j == ej) & (k == ek)) | (t > length):
                break
    if changed:  # segments stay in the box of their end keys (+1 voxel of DDA drift): the changed region
        dirty[0], dirty[1], dirty[2] = min(dirty[0], max(lo0 - 1, 0)), min(dirty[1], max(lo1 - 1, 0)), \
            min(dirty[2], max(lo2 - 1, 0))
        dirty[3], dirty[4], dirty[5] = max(dirty[3], min(hi0 + 1, nx - 1)), max(dirty[4], min(hi1 + 1, ny - 1)), \
            max(dirty[5], min(hi2 + 1, nz - 1))


@numba.njit(cache=True)
def _pool_maps(child_tables, child_values, child_shape, child_key0, tables, values, bits, counts, owner, used, key0,
               indices, regions, l_occ, out):
    """For each map indices[q]: max-pool the 2x2x2 children of every parent cell above the child region
    regions[q] (NaN = unknown), redo the summaries of the parent blocks touched and write the parent
    region to out[q]. Returns False if the parent pool ran out of blocks (redo it after growing)."""
    for q in range(indices.shape[0]):
        m = indices[q]
        region, o = regions[q], out[q]
        for a in range(3):
            o[a] = ((child_key0[a] + region[a]) >> 1) - key0[a]
            o[a + 3] = ((child_key0[a] + region[a + 3]) >> 1) - key0[a]
        if o[0] > o[3]:
            continue
        for pbi in range(o[0] >> BLOCK_SHIFT, (o[3] >> BLOCK_SHIFT) + 1):
            for pbj in range(o[1] >> BLOCK_SHIFT, (o[4] >> BLOCK_SHIFT) + 1):
                for pbk in range(o[2] >> BLOCK_SHIFT, (o[5] >> BLOCK_SHIFT) + 1):
                    pb = _block_at(tables, m, pbi, pbj, pbk)
                    if pb < 0 and not _children_known(child_tables, child_shape, child_key0, key0, m, pbi, pbj, pbk):
                        continue
                    if pb < 0:
                        pb = _new_block(tables[0], tables[1], values, bits, counts, owner, used, m, pbi, pbj, pbk)
                        if pb < 0:
                            return False
                    for pi in range(max(o[0], pbi << BLOCK_SHIFT), min(o[3], ((pbi + 1) << BLOCK_SHIFT) - 1) + 1):
                        for pj in range(max(o[1], pbj << BLOCK_SHIFT), min(o[4], ((pbj + 1) << BLOCK_SHIFT) - 1) + 1):
                            for pk in range(max(o[2], pbk << BLOCK_SHIFT),
                                            min(o[5], ((pbk + 1) << BLOCK_SHIFT) - 1) + 1):
                                best = np.float32(np.nan)
                                for bi in range(2):
                                    ci = 2 * (key0[0] + pi) + bi - child_key0[0]
                                    for bj in range(2):
                                        cj = 2 * (key0[1] + pj) + bj - child_key0[1]
                                        for bk in range(2):
                                            ck = 2 * (key0[2] + pk) + bk - child_key0[2]
                                            v = _child(child_tables, child_values, child_shape, m, ci, cj, ck)
                                            if not np.isnan(v) and (np.isnan(best) or v > best):
                                                best = v
                                values[pb, _offset(pi, pj, pk)] = best
                    c = 0
                    for row in range(BLOCK_VOXELS >> BLOCK_SHIFT):
                        byte = 0
                        for bit in range(1 << BLOCK_SHIFT):
                            if values[pb, (row << BLOCK_SHIFT) | bit] >= l_occ:
                                byte |= 1 << bit
                                c += 1
                        bits[pb, row] = byte
                    counts[pb] = c
    return True


@numba.njit(cache=True, inline="always")
def _child(tables, values, shape, m, i, j, k):
    """Log-odds of cell (i, j, k) of map m of a level (NaN if unknown or outside)."""
    if i < 0 or j < 0 or k < 0 or i >= shape[0] or j >= shape[1] or k >= shape[2]:
        return np.float32(np.nan)
    b = _block_at(tables, m, i >> BLOCK_SHIFT, j >> BLOCK_SHIFT, k >> BLOCK_SHIFT)
    if b < 0:
        return np.float32(np.nan)
    return values[b, _offset(i, j, k)]


@numba.njit(cache=True)
def _children_known(child_tables, child_shape, child_key0, key0, m, pbi, pbj, pbk):
    """Whether any child block under parent block (pbi, pbj, pbk) of map m is allocated."""
    lo = np.empty(3, np.int64)
    hi = np.empty(3, np.int64)
    pb = (pbi, pbj, pbk)
    for a in range(3):
        lo[a] = max(0, 2 * (key0[a] + (pb[a] << BLOCK_SHIFT)) - child_key0[a]) >> BLOCK_SHIFT
        hi[a] = min(child_shape[a] - 1, 2 * (key0[a] + ((pb[a] + 1) << BLOCK_SHIFT)) - 1 - child_key0[a]) >> BLOCK_SHIFT
    for bi in range(lo[0], hi[0] + 1):
        for bj in range(lo[1], hi[1] + 1):
            for bk in range(lo[2], hi[2] + 1):
                if _block_at(child_tables, m, bi, bj, bk) >= 0:
                    return True
    return False


@numba.njit(cache=True)
def _densify(tables, m, values, grid):
    """Copy the allocated blocks of map m into the dense NaN-filled ``grid``."""
    nx, ny, nz = grid.shape
    for bi in range(-(-nx >> BLOCK_SHIFT)):
        for bj in range(-(-ny >> BLOCK_SHIFT)):
            for bk in range(-(-nz >> BLOCK_SHIFT)):
                b = _block_at(tables, m, bi, bj, bk)
                if b < 0:
                    continue
                for i in range(bi << BLOCK_SHIFT, min(nx, (bi + 1) << BLOCK_SHIFT)):
                    for j in range(bj << BLOCK_SHIFT, min(ny, (bj + 1) << BLOCK_SHIFT)):
                        for k in range(bk << BLOCK_SHIFT, min(nz, (bk + 1) << BLOCK_SHIFT)):
                            grid[i, j, k] = values[b, _offset(i, j, k)]


@numba.njit(cache=True)
def _known(tables, m, values, shape):
    """Local indices (M, 3) and log-odds (M,) of map m's known voxels, block by block."""
    nb = np.empty(3, np.int64)
    for a in range(3):
        nb[a] = -(-shape[a] >> BLOCK_SHIFT)
    n = 0
    for bi in range(nb[0]):
        for bj in range(nb[1]):
            for bk in range(nb[2]):
                b = _block_at(tables, m, bi, bj, bk)
                if b >= 0:
                    for v in range(BLOCK_VOXELS):
                        n += not np.isnan(values[b, v])
    idx = np.empty((n, 3), np.int64)
    out = np.empty(n, np.float32)
    n = 0
    for bi in range(nb[0]):
        for bj in range(nb[1]):
            for bk in range(nb[2]):
                b = _block_at(tables, m, bi, bj, bk)
                if b < 0:
                    continue
                for v in range(BLOCK_VOXELS):
                    if not np.isnan(values[b, v]):
                        idx[n, 0] = (bi << BLOCK_SHIFT) | (v >> (2 * BLOCK_SHIFT))
                        idx[n, 1] = (bj << BLOCK_SHIFT) | ((v >> BLOCK_SHIFT) & _MASK)
                        idx[n, 2] = (bk << BLOCK_SHIFT) | (v & _MASK)
                        out[n] = values[b, v]
                        n += 1
    return idx, out


@numba.njit(cache=True)
def _lookup(arrays, idx):
    """Log-odds at the local indices idx (M, 3) (NaN where unknown or outside)."""
    out = np.empty(idx.shape[0], np.float32)
    for p in range(idx.shape[0]):
        out[p] = voxel_logodds(arrays, idx[p, 0], idx[p, 1], idx[p, 2])
    return out


@numba.njit(cache=True, inline="always")
def _gap(c, lo_centre, hi_centre):
    """Distance along one axis from c to the interval [lo_centre, hi_centre]."""
    return max(lo_centre - c, c - hi_centre, 0.0)


@numba.njit(cache=True)
def occupied_cells(tables, values, bits, counts, m, key0, n, res, center, radius, first_only):
    """The kernel of ``OccupancyMap.occupied_in_sphere`` over one level of a store (its ``tables``, block
    pool arrays, map m, the level's key0, shape and cell size): centres and probabilities of the occupied
    cells of map m whose centres lie within ``radius``. Visits the non-empty blocks within reach only,
    and in them only the set bits of their rows; with ``first_only`` stops at the first one.

    Order: blocks x-major, then cells x-major inside a block (the order every caller sums in)."""
    lo = np.empty(3, np.int64)
    hi = np.empty(3, np.int64)
    for a in range(3):  # cells whose centre may lie within the radius (one spare cell per side)
        lo[a] = max(0, np.int64(math.floor((center[a] - radius) / res - 0.5)) - key0[a])
        hi[a] = min(n[a] - 1, np.int64(math.ceil((center[a] + radius) / res - 0.5)) - key0[a])
    if lo[0] > hi[0] or lo[1] > hi[1] or lo[2] > hi[2]:
        return np.empty((0, 3)), np.empty(0)
    r2 = radius * radius
    capacity = 0
    for bi in range(lo[0] >> BLOCK_SHIFT, (hi[0] >> BLOCK_SHIFT) + 1):
        for bj in range(lo[1] >> BLOCK_SHIFT, (hi[1] >> BLOCK_SHIFT) + 1):
            for bk in range(lo[2] >> BLOCK_SHIFT, (hi[2] >> BLOCK_SHIFT) + 1):
                b = _block_at(tables, m, bi, bj, bk)
                if b >= 0:
                    capacity += counts[b]
    centres = np.empty((capacity, 3))
    probs = np.empty(capacity)
    if capacity == 0:
        return centres, probs
    c = 0
    for bi in range(lo[0] >> BLOCK_SHIFT, (hi[0] >> BLOCK_SHIFT) + 1):
        i0, i1 = max(lo[0], bi << BLOCK_SHIFT), min(hi[0], ((bi + 1) << BLOCK_SHIFT) - 1)
        gi = _gap(center[0], (key0[0] + i0 + 0.5) * res, (key0[0] + i1 + 0.5) * res)
        for bj in range(lo[1] >> BLOCK_SHIFT, (hi[1] >> BLOCK_SHIFT) + 1):
            j0, j1 = max(lo[1], bj << BLOCK_SHIFT), min(hi[1], ((bj + 1) << BLOCK_SHIFT) - 1)
            gj = _gap(center[1], (key0[1] + j0 + 0.5) * res, (key0[1] + j1 + 0.5) * res)
            for bk in range(lo[2] >> BLOCK_SHIFT, (hi[2] >> BLOCK_SHIFT) + 1):
                b = _block_at(tables, m, bi, bj, bk)
                if b < 0 or counts[b] == 0:
                    continue
                k0, k1 = max(lo[2], bk << BLOCK_SHIFT), min(hi[2], ((bk + 1) << BLOCK_SHIFT) - 1)
                gk = _gap(center[2], (key0[2] + k0 + 0.5) * res, (key0[2] + k1 + 0.5) * res)
                if gi * gi + gj * gj + gk * gk > r2:
                    continue
                in_range = ((1 << (k1 - (bk << BLOCK_SHIFT) + 1)) - 1) & ~((1 << (k0 - (bk << BLOCK_SHIFT))) - 1)
                for i in range(i0, i1 + 1):
                    x = (key0[0] + i + 0.5) * res
                    for j in range(j0, j1 + 1):
                        row = bits[b, ((i & _MASK) << BLOCK_SHIFT) | (j & _MASK)] & in_range
                        if row == 0:
                            continue
                        y = (key0[1] + j + 0.5) * res
                        for bit in range(1 << BLOCK_SHIFT):
                            if not (row >> bit) & 1:
                                continue
                            k = (bk << BLOCK_SHIFT) + bit
                            z = (key0[2] + k + 0.5) * res
                            if (x - center[0]) ** 2 + (y - center[1]) ** 2 + (z - center[2]) ** 2 <= r2:
                                centres[c, 0], centres[c, 1], centres[c, 2] = x, y, z
                                probs[c] = 1.0 / (1.0 + math.exp(-np.float64(values[b, _offset(i, j, k)])))
                                c += 1
                                if first_only:
                                    return centres[:c], probs[:c]
    return centres[:c], probs[:c]
