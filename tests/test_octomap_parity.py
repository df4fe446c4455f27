"""Parity with the real OctoMap (octomap-python): same scans in, same labels out, voxel by voxel."""

import numpy as np
import pytest

from uavform_env.config import MapConfig, SensorConfig
from uavform_env.occupancy import OccupancyMap
from uavform_env.sensing import STATIC, RangeSensor

octomap = pytest.importorskip("octomap")

RES = 0.2
R_MAX = 4.0
WORLD_ORIGIN = np.array([-1.0, -0.6, 0.0])
SENSOR = SensorConfig(n_azimuth=60, n_elevation=21, elevation_min=-1.3, elevation_max=1.3, r_max=R_MAX)


def random_boxes(rng, shape=(40, 36, 20), n=14):
    occ = np.zeros(shape, np.uint8)
    for _ in range(n):
        lo = rng.integers(0, np.array(shape) - 2)
        size = rng.integers(1, [8, 8, 12])
        occ[lo[0]:lo[0] + size[0], lo[1]:lo[1] + size[1], lo[2]:lo[2] + size[2]] = 1
    return occ


def search_logodds(tree, point, depth=0):
    """Log-odds of the node at ``point`` (at tree depth ``depth``, 0 = leaves), None if not found."""
    try:
        return tree.search(point, depth=depth).getLogOdds()
    except octomap.NullPointerException:
        return None


@pytest.fixture(scope="module")
def scanned():
    """Several scans from random free origins inserted into both maps."""
    rng = np.random.default_rng(11)
    occ = random_boxes(rng)
    sensor = RangeSensor(SENSOR)
    ours = OccupancyMap((-6.0, -6.0, -5.0), (90, 90, 70), RES)  # covers every ray
    tree = octomap.OcTree(RES)
    origins = []
    while len(origins) < 5:
        p = WORLD_ORIGIN + rng.uniform([0.5, 0.5, 0.3], [7.5, 6.7, 3.7])
        if not occ[tuple(np.floor((p - WORLD_ORIGIN) / RES).astype(int))]:
            origins.append(p)
    for step, o in enumerate(origins):
        scan = sensor.scan(occ, WORLD_ORIGIN, RES, o[None], rng.uniform(-3, 3, 1), step, 0.3)
        ends, kind, dirs = scan.endpoints[0], scan.kind[0], scan.directions[0]
        assert (kind == STATIC).sum() > 100 and (kind != STATIC).sum() > 100
        # max-range rays reach OctoMap as far points that insertPointCloud truncates at maxrange
        cloud = np.where((kind == STATIC)[:, None], ends, o + dirs * (3.0 * R_MAX))
        tree.insertPointCloud(cloud, o, maxrange=R_MAX, lazy_eval=False, discretize=False)
        ours.integrate_scan(o, ends, kind)
    lo = np.floor((np.min(origins, axis=0) - R_MAX) / RES).astype(int) - 1
    hi = np.floor((np.max(origins, axis=0) + R_MAX) / RES).astype(int) + 1
    keys = np.stack(np.meshgrid(*[np.arange(a, b + 1) for a, b in zip(lo, hi)], indexing="ij"), -1).reshape(-1, 3)
    return ours, tree, (keys + 0.5) * RES


def test_labels_match_on_every_voxel_of_the_scanned_region(scanned):
    ours, tree, centres = scanned
    theirs = tree.getLabels(centres)
    mine = ours.label(centres)
    counts = np.bincount(mine + 1, minlength=3)
    assert counts.min() > 1000, counts  # unknown, free and occupied voxels all take part
    mismatch = np.flatnonzero(theirs != mine)
    assert mismatch.size == 0, (mismatch.size, centres[mismatch[:5]], theirs[mismatch[:5]], mine[mismatch[:5]])


def test_search_agrees_and_log_odds_are_bit_identical(scanned):
    ours, tree, centres = scanned
    rng = np.random.default_rng(0)
    labels = ours.label(centres)
    sample = np.concatenate([rng.choice(np.flatnonzero(labels == v), 150, replace=False) for v in (-1, 0, 1)])
    index = np.floor(centres[sample] / RES).astype(int) - np.round(ours.origin / RES).astype(int)
    for p, i in zip(centres[sample], index):
        got, mine = search_logodds(tree, p), ours.logodds[tuple(i)]
        if np.isnan(mine):
            assert got is None
        else:
            assert got is not None and np.float32(got) == mine, (p, got, mine)


def test_pyramid_levels_equal_octomap_inner_nodes(scanned):
    ours, tree, _ = scanned
    rng = np.random.default_rng(1)
    for depth in (1, 2, 3):
        origin, res, grid = ours.level(depth)
        idx = np.argwhere(np.ones(grid.shape, bool))
        idx = idx[rng.choice(len(idx), 400, replace=False)]
        for cell in idx:
            got = search_logodds(tree, origin + (cell + 0.5) * res, depth=16 - depth)
            want = grid[tuple(cell)]
            if np.isnan(want):
                assert got is None
            else:
                assert got is not None and np.float32(got) == want, (depth, cell, got, want)


def test_to_octomap_copies_leaves_and_sensor_model(scanned):
    ours, tree, centres = scanned
    copy = ours.to_octomap()
    np.testing.assert_array_equal(copy.getLabels(centres), tree.getLabels(centres))
    known = np.flatnonzero(ours.is_known(centres))
    for p in centres[np.random.default_rng(2).choice(known, 300, replace=False)]:
        assert search_logodds(copy, p) == search_logodds(tree, p)
    cfg = MapConfig()
    assert copy.getProbHit() == pytest.approx(cfg.p_hit) and copy.getProbMiss() == pytest.approx(cfg.p_miss)
    assert copy.getClampingThresMinLog() == tree.getClampingThresMinLog()
    assert copy.getClampingThresMaxLog() == tree.getClampingThresMaxLog()


def test_write_bt_round_trip(scanned, tmp_path):
    ours, _, centres = scanned
    path = tmp_path / "map.bt"
    ours.write_bt(path)
    assert [f.name for f in tmp_path.iterdir()] == ["map.bt"]  # no temporary file left behind
    back = octomap.OcTree(str(path))
    assert back.getResolution() == pytest.approx(RES)
    np.testing.assert_array_equal(back.getLabels(centres), ours.label(centres))
