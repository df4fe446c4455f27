"""MapStore: sparse blocks follow what a map has seen, clearing reuses the pool, the batched kernels
equal a simple dense reference and the per-map path, and the env refuses what will not fit in memory."""

import importlib
import math

import numpy as np
import pytest

from uavform_env import occupancy
from uavform_env.config import MapConfig
from uavform_env.dda import coord_key, ray_key_bound, ray_keys
from uavform_env.env import FormationEnv
from uavform_env.observations import _histograms
from uavform_env.occupancy import BLOCK_BYTES, MapStore, OccupancyMap
from uavform_env.polar_histogram import histogram_shape, primary_histogram, width_steps

RES = 0.2
CFG = MapConfig()


class DenseReference:
    """OctoMap's update rules on a dense float32 grid, one voxel at a time in Python (the test's oracle)."""

    def __init__(self, origin, shape):
        self.key0 = np.round(np.asarray(origin) / RES).astype(np.int64)
        self.grid = np.full(shape, np.nan, np.float32)
        f32 = np.float32
        self.l_hit, self.l_miss = f32(CFG.logodds(CFG.p_hit)), f32(CFG.logodds(CFG.p_miss))
        self.l_min, self.l_max = f32(CFG.logodds(CFG.p_min)), f32(CFG.logodds(CFG.p_max))

    def integrate(self, origin, ends, hit):
        o = np.float32(origin).astype(np.float64)
        ends = np.float32(ends).astype(np.float64)
        hits, misses = set(), set()
        for e, h in zip(ends, hit):
            if h:
                hits.add(tuple(coord_key(x, 1.0 / RES) for x in e))
        for e in ends:
            keys = np.empty((ray_key_bound(*o, *e, 1.0 / RES), 3), np.int64)
            misses.update(map(tuple, keys[:ray_keys(*o, *e, RES, keys)]))
        for key, update in [(k, self.l_hit) for k in hits] + [(k, self.l_miss) for k in misses - hits]:
            i, j, k = np.asarray(key) - self.key0
            if 0 <= i < self.grid.shape[0] and 0 <= j < self.grid.shape[1] and 0 <= k < self.grid.shape[2]:
                old = self.grid[i, j, k]
                self.grid[i, j, k] = np.clip((np.float32(0) if np.isnan(old) else old) + update, self.l_min, self.l_max)


def random_scan(rng, lo, hi, n_rays=60, reach=3.0):
    o = rng.uniform(lo, hi)
    d = rng.normal(size=(n_rays, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return o, o + d * rng.uniform(0.2, reach, size=(n_rays, 1)), rng.random(n_rays) < 0.6


def test_batched_integrate_equals_the_dense_reference_also_when_the_pool_grows(monkeypatch):
    monkeypatch.setattr(occupancy, "_FIRST_CAPACITY", 1)     # the pool runs out inside the batch, many times
    rng = np.random.default_rng(3)
    origin, shape = (-1.0, -1.0, 0.0), (30, 25, 15)
    store = MapStore(origin, shape, RES, CFG, 3)
    store._scan[0] = 250                                     # the scan stamps wrap inside the batch too
    refs = [DenseReference(origin, shape) for _ in range(3)]
    lo, hi = np.array(origin) - 0.5, np.array(origin) + np.array(shape) * RES + 0.5   # some rays leave the grid
    for step in range(4):
        live = np.array([0, 2]) if step == 2 else np.arange(3)
        scans = [random_scan(rng, lo, hi) for _ in live]
        store.integrate(live, [s[0] for s in scans], [s[1] for s in scans], np.array([s[2] for s in scans]))
        for i, (o, ends, hit) in zip(live, scans):
            refs[i].integrate(o, ends, hit)
    assert store.levels[0].values.shape[0] > 3 and store._scan[0] < 250   # it grew, the stamps wrapped
    for m, ref in zip(store.maps, refs):
        np.testing.assert_array_equal(m.logodds, ref.grid)


def test_repeated_scans_of_one_region_equal_the_dense_reference_and_keep_the_block_summaries():
    """Voxels hit and missed again and again (occupied ones freed, free ones clamped at l_min and settled, settled
    ones hit again) end as the reference's, scan after scan, and every block's occupied count and row bits match
    its log-odds: the oracle for any faster walk of the misses."""
    rng = np.random.default_rng(11)
    origin, shape = (0.0, 0.0, 0.0), (20, 20, 12)
    store = MapStore(origin, shape, RES, CFG, 2)
    refs = [DenseReference(origin, shape) for _ in range(2)]
    lo, hi = np.array([1.5, 1.5, 1.0]), np.array([2.5, 2.5, 1.4])      # a small box: the rays overlap a lot
    flips = 0
    for _ in range(25):
        scans = [random_scan(rng, lo, hi, n_rays=80, reach=1.8) for _ in range(2)]
        before = [m.logodds >= store.l_occ for m in store.maps]
        store.integrate(np.arange(2), [s[0] for s in scans], [s[1] for s in scans], np.array([s[2] for s in scans]))
        for m, ref, (o, ends, hit), was in zip(store.maps, refs, scans, before):
            ref.integrate(o, ends, hit)
            np.testing.assert_array_equal(m.logodds, ref.grid)
            flips += int(np.count_nonzero(was & ~(m.logodds >= store.l_occ)))
        leaves = store.levels[0]
        occupied = leaves.values[:leaves.used[0]] >= store.l_occ
        np.testing.assert_array_equal(leaves.counts[:leaves.used[0]], occupied.sum(axis=1))
        rows = occupied.reshape(-1, occupied.shape[1] >> 3, 8)
        row_bits = np.packbits(rows, axis=2, bitorder="little")[..., 0]
        np.testing.assert_array_equal(leaves.bits[:leaves.used[0]], row_bits)
    assert flips > 0 and (store.levels[0].stamps == occupancy._SETTLED).any()   # both cases were exercised


def test_batched_histograms_equal_the_per_map_path():
    rng = np.random.default_rng(8)
    store = MapStore((0.0, 0.0, 0.0), (40, 40, 20), RES, CFG, 4)
    lo, hi = np.array([0.5, 0.5, 0.5]), np.array([7.5, 7.5, 3.5])
    for _ in range(6):
        scans = [random_scan(rng, lo, hi, reach=4.0) for _ in range(4)]
        store.integrate(np.arange(4), [s[0] for s in scans], [s[1] for s in scans], np.array([s[2] for s in scans]))
    pos, psi = rng.uniform(lo, hi, (4, 3)), rng.uniform(-math.pi, math.pi, 4)
    cell, radius, r_e, a, b = math.radians(10.0), 3.0, 0.7, 2.0, 0.4
    n_e, n_z = histogram_shape(cell)
    got = np.zeros((4, n_e, n_z))
    leaves = store.levels[0]
    _histograms(leaves.tables, leaves.values, leaves.bits, leaves.counts, leaves.key0, leaves.shape, RES, pos, psi,
                radius, r_e, cell, n_e, n_z, a, b, width_steps(cell, False), got)
    assert got.sum() > 0
    for i, m in enumerate(store.maps):
        centres, probs = m.occupied_in_sphere(pos[i], radius)
        want, _ = primary_histogram(centres, probs, np.full(len(probs), r_e), pos[i], cell, radius, a, b,
                                    azimuth_ref=psi[i])
        np.testing.assert_array_equal(got[i], want)


def test_memory_follows_the_seen_volume():
    shape = (1000, 1000, 100)                                  # 10^8 voxels: 400 MB as a dense float32 grid
    m = OccupancyMap((0.0, 0.0, 0.0), shape, RES)
    o = np.array([100.0, 100.0, 10.0])
    ends = o + np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]])
    m.integrate(o, ends, np.array([True, True, True]))
    assert 1 <= m.n_blocks <= 4                                # three 1 m rays touch at most a few 8^3 blocks
    assert m.label(ends).tolist() == [1, 1, 1]
    store = m._store
    assert store.nbytes < 0.02 * math.prod(shape) * 4         # a table (1/262144 of the voxels), small pools
    far = OccupancyMap((0.0, 0.0, 0.0), shape, RES)
    far.integrate(o, o + np.array([[0.0, 30.0, 0.0]]), np.array([True]))
    assert m.n_blocks < far.n_blocks <= 2 * 30 / (8 * RES) + 4  # a 30 m ray: about one block per 1.6 m


def test_clear_reuses_the_pool_and_forgets_everything():
    rng = np.random.default_rng(1)
    store = MapStore((0.0, 0.0, 0.0), (30, 30, 15), RES, CFG, 2)
    scans = [random_scan(rng, np.full(3, 0.5), np.array([5.5, 5.5, 2.5])) for _ in range(2)]

    def fill():
        store.integrate([0, 1], [s[0] for s in scans], [s[1] for s in scans], np.array([s[2] for s in scans]))
        store.maps[1].level(2)                                 # builds the pyramid
        return [m.logodds for m in store.maps], store.maps[1].level(2)[2]

    first, first_level = fill()
    pool = store.levels[0].values
    store.clear()
    assert store.levels[0].values is pool and store.levels[0].used[0] == 0
    assert all(m.n_blocks == 0 and np.isnan(m.logodds).all() for m in store.maps)
    assert not store.maps[0].occupied_within((3.0, 3.0, 1.5), 10.0)
    again, again_level = fill()
    assert store.levels[0].values is pool
    for a, b in zip(first, again):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(first_level, again_level)
    store.clear((-2.0, 0.0, 0.0), (40, 20, 15))               # another layout's grid: new tables, the same pool
    assert store.levels[0].values is pool and store.maps[0].shape == (40, 20, 15)
    assert store.maps[1].n_blocks == 0 and np.allclose(store.maps[1].origin, (-2.0, 0.0, 0.0))
    o, ends, hit = scans[0]
    store.maps[1].integrate(o, ends, hit)
    fresh = OccupancyMap((-2.0, 0.0, 0.0), (40, 20, 15), RES)
    fresh.integrate(o, ends, hit)
    np.testing.assert_array_equal(store.maps[1].logodds, fresh.logodds)


def test_lazy_pyramid_of_one_map_equals_a_fresh_one():
    rng = np.random.default_rng(4)
    store = MapStore((0.0, 0.0, 0.0), (40, 30, 20), RES, CFG, 2)
    lo, hi = np.full(3, 0.5), np.array([7.5, 5.5, 3.5])
    scans = [random_scan(rng, lo, hi) for _ in range(6)]
    for k, (o, ends, hit) in enumerate(scans):
        store.integrate([0], [o], [ends], hit[None])
        if k % 2:
            store.maps[0].level(3)                            # refreshed lazily between scans
    fresh = OccupancyMap((0.0, 0.0, 0.0), (40, 30, 20), RES)
    for o, ends, hit in scans:
        fresh.integrate(o, ends, hit)
    for d in range(fresh.n_levels):
        np.testing.assert_array_equal(store.maps[0].level(d)[2], fresh.level(d)[2])
        got = store.maps[0].occupied_in_sphere((4.0, 3.0, 2.0), 3.0, level=min(d, 2))
        want = fresh.occupied_in_sphere((4.0, 3.0, 2.0), 3.0, level=min(d, 2))
        np.testing.assert_array_equal(got[0], want[0])
    assert store.maps[1].n_blocks == 0 and np.isnan(store.maps[1].level(2)[2]).all()


def test_env_reset_clears_the_maps_without_reallocating():
    env = FormationEnv("forest", n_uavs=3, max_cycles=50)
    env.reset(seed=0)
    first = [m.logodds for m in env.maps]
    for _ in range(5):
        env.step({a: np.array([0.0, 0.5, 0.0], np.float32) for a in env.agents})
    store, pool = env._map_store, env._map_store.levels[0].values
    world = env.world
    env.reset(seed=0)
    assert env._map_store is store and store.levels[0].values is pool and env.world is world
    for a, b in zip(first, env.maps):
        np.testing.assert_array_equal(a, b.logodds)


def test_env_refuses_a_swarm_that_will_not_fit_in_memory(monkeypatch):
    env_module = importlib.import_module("uavform_env.env")   # the package's `env` attribute is a function
    monkeypatch.setattr(env_module, "available_memory", lambda: 10 * 2**20)
    with pytest.raises(ValueError, match=r"n_uavs=5 at map resolution 0.2 m .* needs an estimated [0-9.]+ GiB, "
                                         r"but only 0.01 GiB is available; use fewer UAVs, a coarser resolution"):
        FormationEnv("forest", n_uavs=5)
    monkeypatch.setattr(env_module, "available_memory", lambda: 64 * 2**30)
    FormationEnv("forest", n_uavs=5)


def test_memory_estimate_is_linear_in_the_maps_and_capped_by_the_grid():
    shape = (400, 200, 60)
    grid_blocks, grid_chunks = 50 * 25 * 8, 7 * 4 * 1
    one = occupancy.map_memory_estimate(shape, 1, 100, 3)
    assert one == 4 * grid_chunks + 3 * occupancy.CHUNK_BYTES + 100 * BLOCK_BYTES
    assert occupancy.map_memory_estimate(shape, 7, 100, 3) == 7 * one
    assert occupancy.map_memory_estimate(shape, 1, 10**9, 10**9) == grid_chunks * (4 + occupancy.CHUNK_BYTES) \
        + grid_blocks * BLOCK_BYTES
    assert occupancy.seen_blocks_bound(6.0, 0.0, RES) == (math.ceil(12.0 / 1.6) + 2) ** 3
    assert occupancy.seen_blocks_bound(6.0, 0.0, RES, 64) == (math.ceil(12.0 / 12.8) + 2) ** 3


def test_maps_follow_the_map_resolution_and_default_to_the_scenarios_grid():
    from uavform_env.config import EnvConfig
    from uavform_env.scenarios import GRID_RESOLUTION

    default = FormationEnv("forest", n_uavs=2)
    default.reset(seed=0)
    assert default.config.map.resolution == GRID_RESOLUTION == default.world.res
    assert default.onboard("uav_0").occupancy.resolution == GRID_RESOLUTION
    for res in (0.1, 0.4):
        env = FormationEnv("forest", n_uavs=2, config=EnvConfig(map=MapConfig(resolution=res)))
        env.reset(seed=0)
        assert env.config.map.resolution == res and env.world.res == GRID_RESOLUTION   # the ground truth stays
        occ = env.onboard("uav_1").occupancy
        assert occ.resolution == res
        assert np.allclose(np.asarray(occ.origin) / res, np.round(np.asarray(occ.origin) / res))
        for _ in range(3):
            env.step({a: np.array([0.0, 0.0, 0.0], np.float32) for a in env.agents})
        centres, _ = occ.occupied_in_sphere(env.states[1, :3], 6.0)
        assert len(centres) and np.allclose(centres / res - 0.5, np.round(centres / res - 0.5))  # voxel centres
        # each holds a hit on the ground truth, whose voxels (world.res) hold a piece of obstacle
        assert env.world.clearance(centres).max() <= (res + env.world.res) * math.sqrt(3) / 2
    with pytest.raises(ValueError, match=r"MapConfig.resolution=0.001"):
        MapConfig(resolution=0.001)
