"""RangeSensor: ray pattern, known-answer hits, and a comparison with an independent slab-method caster."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from uavform_env.config import SensorConfig
from uavform_env.sensing import NOTHING, STATIC, UAV, RangeSensor, perturb_scan

RES = 0.2
LEVEL = SensorConfig(n_azimuth=4, n_elevation=1, r_max=8.0, interleave=False)  # rays +x, +y, -x, -y


def voxel_of(points, origin=(0.0, 0.0, 0.0)):
    return np.floor((np.asarray(points) - np.asarray(origin)) / RES + 1e-9).astype(int)


def test_directions_pattern_and_interleave():
    cfg = SensorConfig(n_azimuth=8, n_elevation=3, elevation_min=-0.5, elevation_max=0.5, interleave=True)
    sensor = RangeSensor(cfg)
    d0 = sensor.directions(0)
    assert d0.shape == (24, 3)
    np.testing.assert_allclose(np.linalg.norm(d0, axis=1), 1.0)
    az = np.arctan2(d0[:, 1], d0[:, 0]) % (2 * math.pi)
    el = np.arcsin(d0[:, 2])
    # ray r = i_az * n_el + i_el
    np.testing.assert_allclose(az.reshape(8, 3), np.repeat(np.arange(8)[:, None] * math.pi / 4, 3, axis=1), atol=1e-12)
    np.testing.assert_allclose(el.reshape(8, 3), np.tile([-0.5, 0.0, 0.5], (8, 1)), atol=1e-12)
    shift = np.arctan2(sensor.directions(3)[0, 1], sensor.directions(3)[0, 0])
    assert shift == pytest.approx(((3 * 0.6180339887) % 1.0) * math.pi / 4)
    plain = RangeSensor(cfg.replace(interleave=False))
    np.testing.assert_array_equal(plain.directions(3), d0)
    single = RangeSensor(SensorConfig(n_azimuth=5, n_elevation=1, elevation_min=-0.7, elevation_max=-0.2))
    np.testing.assert_array_equal(single.directions(0)[:, 2], 0.0)


def test_wall_ground_and_nothing_known_answers():
    occ = np.zeros((30, 20, 10), np.uint8)
    occ[15, :, :] = 1  # wall x in [3.0, 3.2)
    sensor = RangeSensor(LEVEL)
    pos = np.array([[1.1, 2.1, 1.1]])
    scan = sensor.scan(occ, (0, 0, 0), RES, pos, np.zeros(1), 0, 0.3)
    assert scan.kind.tolist() == [[STATIC, NOTHING, NOTHING, NOTHING]]
    assert scan.ranges[0, 0] == pytest.approx(1.9, abs=1e-12)
    assert voxel_of(scan.endpoints[0, 0]).tolist() == [15, 10, 5]
    np.testing.assert_allclose(scan.ranges[0, 1:], 8.0)
    np.testing.assert_allclose(scan.endpoints[0, 1:], pos + 8.0 * scan.directions[0, 1:])
    # the same wall seen from the far side, from outside the grid (outside is free space)
    back = sensor.scan(occ, (0, 0, 0), RES, np.array([[7.5, 2.1, 1.1]]), np.array([math.pi]), 0, 0.3)
    assert back.kind[0, 0] == STATIC and back.ranges[0, 0] == pytest.approx(7.5 - 3.2, abs=1e-12)
    assert voxel_of(back.endpoints[0, 0]).tolist() == [15, 10, 5]
    # straight-ish down at 45 degrees: the ground (z < 0 is solid) at 2 / sin(45 deg)
    down = RangeSensor(SensorConfig(n_azimuth=1, n_elevation=2, elevation_min=-math.pi / 4,
                                    elevation_max=math.pi / 4, interleave=False))
    g = down.scan(np.zeros((5, 5, 5), np.uint8), (0, 0, 0), RES, np.array([[0.5, 0.5, 2.0]]), np.zeros(1), 0, 0.3)
    assert g.kind.tolist() == [[STATIC, NOTHING]]
    assert g.ranges[0, 0] == pytest.approx(2.0 * math.sqrt(2.0), abs=1e-12)
    assert -RES < g.endpoints[0, 0, 2] < 0.0
    assert g.endpoints[0, 0, 0] == pytest.approx(2.5, abs=1e-3)


def test_other_uavs_are_spheres_and_a_uav_never_sees_itself():
    occ = np.zeros((4, 4, 4), np.uint8)
    sensor = RangeSensor(LEVEL)
    pos = np.array([[0.0, 0.0, 3.0], [3.0, 0.0, 3.0]])
    scan = sensor.scan(occ, (0, 0, 0), RES, pos, np.zeros(2), 0, 0.5)
    assert scan.kind[0].tolist() == [UAV, NOTHING, NOTHING, NOTHING]
    assert scan.ranges[0, 0] == pytest.approx(2.5)
    assert scan.kind[1].tolist() == [NOTHING, NOTHING, UAV, NOTHING]
    np.testing.assert_allclose(scan.endpoints[0, 0], [2.5, 0.0, 3.0])
    alone = sensor.scan(occ, (0, 0, 0), RES, pos[:1], np.zeros(1), 0, 5.0)
    assert (alone.kind == NOTHING).all()
    # a static obstacle in front of a UAV hides it
    occ2 = np.zeros((10, 5, 20), np.uint8)
    occ2[5, :, :] = 1  # x in [1.0, 1.2)
    hidden = sensor.scan(occ2, (0, 0, 0), RES, pos, np.zeros(2), 0, 0.5)
    assert hidden.kind[0, 0] == STATIC and hidden.ranges[0, 0] == pytest.approx(1.0)


def test_noise_only_on_hits_and_from_the_given_generator():
    occ = np.zeros((30, 20, 10), np.uint8)
    occ[15, :, :] = 1
    pos = np.array([[1.1, 2.1, 1.1], [1.1, 0.5, 1.1]])
    clean = RangeSensor(LEVEL).scan(occ, (0, 0, 0), RES, pos, np.zeros(2), 0, 0.3)
    before = clean.ranges.copy()
    a = perturb_scan(clean, pos, LEVEL.r_max, 0.05, 0.0, np.random.default_rng(7), None)
    b = perturb_scan(clean, pos, LEVEL.r_max, 0.05, 0.0, np.random.default_rng(7), None)
    np.testing.assert_array_equal(clean.ranges, before)  # the input scan is untouched
    np.testing.assert_array_equal(a.ranges, b.ranges)
    np.testing.assert_array_equal(a.kind, clean.kind)
    hits = clean.kind != NOTHING
    assert np.all(a.ranges[hits] != clean.ranges[hits])
    np.testing.assert_array_equal(a.ranges[~hits], clean.ranges[~hits])
    moved = (a.ranges - clean.ranges)[..., None] * a.directions
    np.testing.assert_allclose(a.endpoints, clean.endpoints + moved, atol=1e-12)
    with pytest.raises(ValueError, match="noise_rng"):
        perturb_scan(clean, pos, LEVEL.r_max, 0.05, 0.0, None, None)


def test_dropped_rays_read_as_no_return_from_their_own_generator():
    occ = np.zeros((30, 20, 10), np.uint8)
    occ[15, :, :] = 1
    pos = np.array([[1.1, 2.1, 1.1], [1.1, 0.5, 1.1]])
    clean = RangeSensor(LEVEL).scan(occ, (0, 0, 0), RES, pos, np.zeros(2), 0, 0.3)
    dropped = perturb_scan(clean, pos, LEVEL.r_max, 0.0, 0.5, None, np.random.default_rng(1))
    lost = np.random.default_rng(1).random(clean.ranges.shape) < 0.5
    assert 0 < lost.sum() < lost.size
    assert np.all(dropped.kind[lost] == NOTHING) and np.all(dropped.ranges[lost] == LEVEL.r_max)
    np.testing.assert_allclose(dropped.endpoints[lost], (pos[:, None, :] + clean.directions * LEVEL.r_max)[lost])
    np.testing.assert_array_equal(dropped.ranges[~lost], clean.ranges[~lost])
    # both faults: the dropout pattern does not depend on whether noise is on (separate generators)
    both = perturb_scan(clean, pos, LEVEL.r_max, 0.05, 0.5, np.random.default_rng(2), np.random.default_rng(1))
    np.testing.assert_array_equal(both.kind, dropped.kind)
    with pytest.raises(ValueError, match="dropout_rng"):
        perturb_scan(clean, pos, LEVEL.r_max, 0.0, 0.5, None, None)


def test_batch_equals_one_uav_at_a_time():
    rng = np.random.default_rng(3)
    occ = (rng.random((20, 20, 8)) < 0.05).astype(np.uint8)
    sensor = RangeSensor(SensorConfig(n_azimuth=12, n_elevation=3))
    pos = rng.uniform([0.5, 0.5, 0.3], [3.5, 3.5, 1.5], size=(3, 3))
    yaws = rng.uniform(-3, 3, 3)
    batch = sensor.scan(occ, (0, 0, 0), RES, pos, yaws, 5, 0.0)
    for i in range(3):
        one = sensor.scan(occ, (0, 0, 0), RES, pos[i:i + 1], yaws[i:i + 1], 5, 0.0)
        np.testing.assert_array_equal(one.ranges[0], batch.ranges[i])
        np.testing.assert_array_equal(one.endpoints[0], batch.endpoints[i])


def slab_ranges(occ, origin, pos, dirs, r_max, others, radius):
    """Independent reference: exact entry distance into every occupied voxel box (slab method),
    the ground plane and the other UAVs' spheres, then the nearest within r_max."""
    lo = np.argwhere(occ) * RES + origin
    best = np.full(len(dirs), np.inf)
    kind = np.zeros(len(dirs), np.int8)
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (lo[None] - pos) / dirs[:, None]
        t2 = (lo[None] + RES - pos) / dirs[:, None]
        t_ground = np.where(dirs[:, 2] < 0, -pos[2] / dirs[:, 2], np.inf)
    t_in = np.maximum(np.minimum(t1, t2).max(axis=2), 0.0)
    t_out = np.maximum(t1, t2).min(axis=2)
    t_box = np.where(t_out >= t_in, t_in, np.inf).min(axis=1, initial=np.inf)
    t_static = np.minimum(t_box, t_ground)
    for c in others:
        rel = c - pos
        proj = dirs @ rel
        disc = proj ** 2 - (rel @ rel - radius ** 2)
        t = np.where((proj > 0) & (disc >= 0), proj - np.sqrt(np.maximum(disc, 0)), np.inf)
        if rel @ rel <= radius ** 2:  # inside the other UAV's sphere: every ray ends at once
            t[:] = 0.0
        closer = t < best
        best[closer] = t[closer]
    kind[best <= r_max] = UAV
    static = (t_static <= best) & (t_static <= r_max)
    best[static] = t_static[static]
    kind[static] = STATIC
    return np.where(kind == NOTHING, r_max, best), kind


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), density=st.sampled_from([0.02, 0.08, 0.2]))
def test_matches_independent_slab_caster(seed, density):
    rng = np.random.default_rng(seed)
    origin = np.array([-1.0, 0.4, 0.0])
    occ = (rng.random((16, 14, 8)) < density).astype(np.uint8)
    sensor = RangeSensor(SensorConfig(n_azimuth=16, n_elevation=5, r_max=3.0))
    pos = origin + rng.uniform([0.2, 0.2, 0.2], [3.0, 2.6, 1.4], size=(3, 3))
    yaws = rng.uniform(-math.pi, math.pi, 3)
    step = int(rng.integers(0, 100))
    scan = sensor.scan(occ, origin, RES, pos, yaws, step, 0.25)
    for i in range(3):
        others = np.delete(pos, i, axis=0)
        ranges, kind = slab_ranges(occ, origin, pos[i], scan.directions[i], 3.0, others, 0.25)
        np.testing.assert_array_equal(scan.kind[i], kind)
        np.testing.assert_allclose(scan.ranges[i], ranges, atol=1e-9)
        static = scan.kind[i] == STATIC
        # a static endpoint lies inside an occupied voxel or below ground, next to the true hit point
        ends = scan.endpoints[i][static]
        true = pos[i] + scan.directions[i][static] * ranges[static, None]
        assert np.all(np.linalg.norm(ends - true, axis=1) < 0.01 * RES)
        v = np.floor((ends - origin) / RES).astype(int)
        in_grid = np.all((v >= 0) & (v < occ.shape), axis=1)
        assert np.all(occ[tuple(v[in_grid].T)] == 1)
        assert np.all(ends[~in_grid, 2] < 0)


def test_bad_input_raises_value_error():
    sensor = RangeSensor(LEVEL)
    occ = np.zeros((4, 4, 4), np.uint8)
    ok = dict(occupied=occ, origin=(0, 0, 0), res=RES, positions=np.zeros((1, 3)), yaws=np.zeros(1), step=0,
              uav_radius=0.3)
    for name, bad in [("occupied", occ.astype(bool)), ("origin", (0.05, 0, 0)), ("positions", np.zeros((1, 2))),
                      ("yaws", np.zeros(2)), ("uav_radius", -1.0), ("step", 1.5), ("res", 0.0)]:
        with pytest.raises(ValueError, match=name):
            sensor.scan(**{**ok, name: bad})
    with pytest.raises(ValueError, match="cfg"):
        RangeSensor({"n_azimuth": 4})
