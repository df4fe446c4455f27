"""World: raster, clearance and heightmap against hand-checked answers and a brute-force numpy reference."""

import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from uavform_env.world import Box, Cylinder, Sphere, World


# ---------------------------------------------------------------- independent numpy reference

def reference_distance(ob, p):
    """Signed distance from points p (P, 3) to one primitive via its nearest point (projection form)."""
    if isinstance(ob, Box):
        lo, hi = np.array(ob.lo), np.array(ob.hi)
        outside = np.linalg.norm(p - np.clip(p, lo, hi), axis=1)
        inside = np.all((p > lo) & (p < hi), axis=1)
        depth = np.minimum(p - lo, hi - p).min(axis=1)
        return np.where(inside, -depth, outside)
    if isinstance(ob, Cylinder):
        d = p[:, :2] - (ob.x, ob.y)
        rho = np.linalg.norm(d, axis=1)
        scale = np.where(rho > 0, np.minimum(rho, ob.radius) / np.maximum(rho, 1e-300), 0.0)
        nearest = np.column_stack([ob.x + d[:, 0] * scale, ob.y + d[:, 1] * scale, np.clip(p[:, 2], ob.z_lo, ob.z_hi)])
        outside = np.linalg.norm(p - nearest, axis=1)
        inside = (rho < ob.radius) & (p[:, 2] > ob.z_lo) & (p[:, 2] < ob.z_hi)
        depth = np.minimum.reduce([ob.radius - rho, p[:, 2] - ob.z_lo, ob.z_hi - p[:, 2]])
        return np.where(inside, -depth, outside)
    return np.linalg.norm(p - (ob.x, ob.y, ob.z), axis=1) - ob.radius


def reference_clearance(obstacles, p):
    return np.min([reference_distance(ob, p) for ob in obstacles], axis=0) if obstacles else np.full(len(p), np.inf)


def voxel_centres(w):
    axes = [w.origin[a] + (np.arange(w.shape[a]) + 0.5) * w.res for a in range(3)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)


def reference_occupied(w):
    """Boxes: the voxel cube overlaps the box with positive volume; others: centre distance < res/2.
    Ties count as free (a face on a voxel face, e.g. 1.2 = 6 * 0.2 up to rounding): a box face within
    1e-9 max(1, |q|) cells of a grid plane (q: its distance from the origin in cells) lies on that plane,
    and a curved surface within 1e-9 res of a voxel centre's res / 2 misses it."""
    c = voxel_centres(w)
    origin = np.asarray(w.origin)
    tie = 1e-9 * w.res
    occ = np.zeros(len(c), bool)
    for ob in w.obstacles:
        if isinstance(ob, Box):
            lo, hi = (np.where(np.abs(q - np.rint(q)) <= 1e-9 * np.maximum(1.0, np.abs(q)), np.rint(q), q)
                      for q in ((np.array(ob.lo) - origin) / w.res, (np.array(ob.hi) - origin) / w.res))
            cell = np.rint((c - origin) / w.res - 0.5)            # the voxel's index = its lower face, in cells
            occ |= np.all((cell < hi) & (cell + 1.0 > lo), axis=1)
        else:
            occ |= reference_distance(ob, c) < w.res / 2 - tie
    return occ.reshape(w.shape)


coord = st.floats(-1.0, 7.0, allow_nan=False)
size = st.floats(0.05, 3.0, allow_nan=False)
boxes = st.builds(lambda x, y, z, a, b, c: Box((x, y, z), (x + a, y + b, z + c)), coord, coord, coord, size, size, size)
cylinders = st.builds(lambda x, y, r, z, h: Cylinder(x, y, r, z, z + h), coord, coord, size, coord, size)
spheres = st.builds(Sphere, coord, coord, coord, size)
worlds = st.builds(lambda res, obs: World((0.0, 0.0, 0.0), (6.0, 5.0, 4.0), res, obs),
                   st.sampled_from([0.2, 0.25, 0.3, 0.5]), st.lists(st.one_of(boxes, cylinders, spheres), max_size=6))


@settings(max_examples=60, deadline=None)
@given(worlds)
@example(World((0, 0, 0), (6, 5, 4), 0.2, [Box((0, 0, 1.2), (1, 1, 2.2)), Cylinder(3, 3, 0.4, 0.6, 1.8)]))  # ties
@example(World((0, 0, 0), (6, 5, 4), 0.2, [Box((0, 0, 1e-9), (1, 1, 2.000000001))]))   # near-ties, 5e-9 cells off
def test_raster_matches_brute_force(w):
    assert w.occupied.dtype == np.uint8
    np.testing.assert_array_equal(w.occupied.astype(bool), reference_occupied(w))


@settings(max_examples=60, deadline=None)
@given(worlds, st.lists(st.tuples(coord, coord, coord), min_size=1, max_size=20))
def test_clearance_matches_brute_force(w, pts):
    p = np.array(pts, dtype=np.float64)
    np.testing.assert_allclose(w.clearance(p), reference_clearance(w.obstacles, p), rtol=0, atol=1e-9)


def test_clearance_agrees_with_sampled_surface():
    """Distance to a densely sampled cylinder surface (side and caps) bounds the exact clearance."""
    cyl = Cylinder(1.0, 2.0, 0.7, 0.5, 3.0)
    t, z = np.meshgrid(np.linspace(0, 2 * np.pi, 361), np.linspace(0.5, 3.0, 126))
    side = np.column_stack([1 + 0.7 * np.cos(t.ravel()), 2 + 0.7 * np.sin(t.ravel()), z.ravel()])
    rr, tt = np.meshgrid(np.linspace(0, 0.7, 36), np.linspace(0, 2 * np.pi, 361))
    cap = np.column_stack([1 + (rr * np.cos(tt)).ravel(), 2 + (rr * np.sin(tt)).ravel(), np.zeros(rr.size)])
    surface = np.vstack([side, cap + (0, 0, 0.5), cap + (0, 0, 3.0)])
    pts = np.random.default_rng(0).uniform((-2, -1, -1), (4, 5, 5), (40, 3))
    w = World((0, 0, 0), (1, 1, 1), 0.5, [cyl])
    sampled = np.min(np.linalg.norm(pts[:, None] - surface[None], axis=2), axis=1)
    inside = (np.hypot(pts[:, 0] - 1, pts[:, 1] - 2) < 0.7) & (pts[:, 2] > 0.5) & (pts[:, 2] < 3.0)
    exact = w.clearance(pts)
    np.testing.assert_array_less(np.abs(exact) - 1e-12, sampled)  # no surface point is nearer than |clearance|
    assert np.all(sampled - np.abs(exact) < 0.02)  # ... and the sampled distance is within the sampling step
    assert np.array_equal(exact < 0, inside)


def test_clearance_known_answers():
    w = World((0, 0, 0), (10, 10, 10), 0.2, [Box((1, 2, 0), (3, 4, 8)), Cylinder(5, 5, 0.5, 0, 9)])
    pts = [(0, 3, 4),  # 1 m west of the box face x = 1
           (0, 0, 9),  # to the box corner (1, 2, 8): sqrt(1 + 4 + 1)
           (2, 3, 4),  # inside the box, 1 m from four faces
           (7, 5, 4),  # 2 m from the cylinder axis, radius 0.5
           (5, 5, 10),  # 1 m above the cylinder's top cap
           (6, 5, 11),  # to the cap rim: hypot(0.5, 2)
           (5, 5, 4),  # on the axis: 0.5 deep
           (4, 3, 8.5)]  # nearer the box edge (3, y, 8) than the cylinder: hypot(1, 0.5)
    np.testing.assert_allclose(w.clearance(pts), [1, math.sqrt(6), -1, 1.5, 1, math.hypot(0.5, 2), -0.5,
                                                  math.hypot(1, 0.5)], atol=1e-12)
    assert World((0, 0, 0), (1, 1, 1), 0.2, []).clearance([(0.5, 0.5, 0.5)])[0] == np.inf
    assert World((0, 0, 0), (1, 1, 1), 0.2, [Sphere(0, 0, 0, 1)]).clearance([(0, 3, 4)])[0] == pytest.approx(4.0)


def test_raster_known_answers():
    # A box on voxel faces fills exactly its 10 x 10 x 40 voxels, nothing around it.
    w = World((0, 0, 0), (10, 10, 10), 0.2, [Box((1, 2, 0), (3, 4, 8))])
    assert w.occupied[5:15, 10:20, 0:40].all() and w.occupied.sum() == 4000
    # Off-grid faces: every voxel the box reaches into counts, 1.05..2.95 -> voxels 5..14.
    w = World((0, 0, 0), (10, 10, 10), 0.2, [Box((1.05, 2.0, 0.0), (2.95, 2.2, 0.2))])
    assert np.flatnonzero(w.occupied.any(axis=(1, 2))).tolist() == list(range(5, 15)) and w.occupied.sum() == 10
    # Cylinder r 0.5 on voxel faces: the voxel centres at (+-0.1, +-0.3, +-0.5) offsets nearer than 0.6 to the
    # axis are 32 columns; its top at z = 9 is a voxel face, so 45 layers (the tie at 9.1 stays free).
    w = World((0, 0, 0), (10, 10, 10), 0.2, [Cylinder(5, 5, 0.5, 0, 9)])
    assert w.occupied.sum() == 32 * 45 and w.occupied[:, :, 45:].sum() == 0
    # Sphere r 0.2 centred on a voxel centre: the centre, 6 face and 12 edge neighbours (0.283 < 0.3), no corners.
    w = World((0, 0, 0), (2, 2, 2), 0.2, [Sphere(1.1, 1.1, 1.1, 0.2)])
    assert w.occupied.sum() == 19 and w.occupied[4:7, 4:7, 4:7].sum() == 19


def test_grid_frame_and_clipping():
    w = World((-3.1, 0.3, 0.0), (1.0, 1.0, 1.0), 0.2, [Box((-10, -10, -1), (10, 10, 0.5))])
    np.testing.assert_allclose(w.origin, (-3.2, 0.2, 0.0))
    assert w.shape == (21, 4, 5)
    assert w.occupied[:, :, :3].all() and not w.occupied[:, :, 3:].any()  # clipped to the grid
    assert World((0, 0, 0), (0.6, 0.6, 0.6), 0.2, []).shape == (3, 3, 3)  # 0.6 / 0.2 snaps to 3


def test_arrays_are_read_only_float64():
    w = World((0, 0, 0), (4, 4, 4), 0.2, [Box((1, 1, 0), (2, 2, 1)), Cylinder(3, 3, 0.4, 0, 2), Sphere(1, 3, 2, 0.5)])
    assert w.boxes.shape == (1, 6) and w.cylinders.shape == (1, 5) and w.spheres.shape == (1, 4)
    np.testing.assert_array_equal(w.boxes[0], [1, 1, 0, 2, 2, 1])
    np.testing.assert_array_equal(w.cylinders[0], [3, 3, 0.4, 0, 2])
    for a in (w.occupied, w.boxes, w.cylinders, w.spheres, w.origin):
        with pytest.raises(ValueError):
            a[(0,) * a.ndim] = 1
    assert w.boxes.dtype == w.cylinders.dtype == w.spheres.dtype == np.float64
    empty = World((0, 0, 0), (1, 1, 1), 0.5, [])
    assert empty.boxes.shape == (0, 6) and empty.spheres.shape == (0, 4) and not empty.occupied.any()


def test_heightmap_known_answers():
    w = World((0, 0, 0), (10, 10, 10), 0.2,
              [Box((1, 2, 0), (3, 4, 8)), Cylinder(5, 8, 0.5, 0, 6), Sphere(7, 7, 3, 1)])
    origin, res, h = w.heightmap(0.5)
    assert h.dtype == np.float32 and h.shape == (20, 20) and res == 0.5
    np.testing.assert_array_equal(origin, (0, 0))
    assert h[2:6, 4:8].min() == 8.0 and h[:2].max() == 0 and h[6, 4] == 0  # box edge x = 3 only touches cell 6
    assert h[9, 15] == h[10, 16] == 6.0 and h[9, 14] == 0.0  # disc at (5, 8) r 0.5; cell y 7..7.5 only touched
    assert h[13, 13] == 4.0  # the sphere's top over the cell whose corner is its centre
    assert h[15, 14] == pytest.approx(3 + math.sqrt(0.75), abs=1e-6)  # nearest point 0.5 m from the centre
    assert h[16, 14] == 0.0  # nearest point 1.0 m away: only touches


def test_heightmap_of_aligned_boxes_matches_raster():
    obs = [Box((0.4, 0.6, 0.0), (2.0, 1.4, 3.2)), Box((1.0, 1.0, 1.0), (3.0, 2.0, 4.6)),
           Box((3.2, 0.2, 0.0), (3.6, 3.0, 0.4))]
    w = World((0, 0, 0), (4, 4, 6), 0.2, obs)
    _, _, h = w.heightmap(0.2)
    top = np.where(w.occupied.any(axis=2), (w.shape[2] - np.argmax(w.occupied[:, :, ::-1], axis=2)) * 0.2, 0.0)
    np.testing.assert_allclose(h, top, atol=1e-6)


@pytest.mark.parametrize("kwargs, match", [
    (dict(bounds_lo=(0, 0, 1)), "bounds_lo.*z = 0"),
    (dict(bounds_hi=(10, 0, 10)), "below World.bounds_hi.*fails on y"),
    (dict(bounds_lo=(0, 0)), "bounds_lo.*expected 3 finite numbers"),
    (dict(bounds_hi=(10, np.nan, 10)), "bounds_hi.*finite"),
    (dict(resolution=0.0), "resolution.*positive"),
    (dict(resolution="0.2"), "resolution.*finite number"),
    (dict(resolution=1e-4), "voxels"),
    (dict(obstacles=[(1, 2, 3)]), r"obstacles\[0\].*Box, Cylinder or Sphere"),
])
def test_world_rejects_bad_input(kwargs, match):
    args = dict(bounds_lo=(0, 0, 0), bounds_hi=(10, 10, 10), resolution=0.2, obstacles=[])
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        World(**args)


@pytest.mark.parametrize("make, match", [
    (lambda: Box((0, 0, 0), (1, 0, 1)), "fails on y"),
    (lambda: Box((0, 0), (1, 1, 1)), "Box.lo"),
    (lambda: Cylinder(0, 0, -1, 0, 1), "Cylinder.radius.*positive"),
    (lambda: Cylinder(0, 0, 1, 2, 1), "Cylinder.z_lo"),
    (lambda: Sphere(0, 0, math.inf, 1), "Sphere.z.*finite"),
    (lambda: Sphere(0, 0, 0, 0), "Sphere.radius"),
])
def test_primitives_reject_bad_input(make, match):
    with pytest.raises(ValueError, match=match):
        make()


def test_primitives_store_floats():
    b = Box([0, 0, 0], np.array([1, 2, 3]))
    assert b == Box((0.0, 0.0, 0.0), (1.0, 2.0, 3.0)) and type(b.lo) is tuple
    assert hash(b) == hash(Box((0, 0, 0), (1, 2, 3)))
    assert type(Cylinder(np.int64(1), 0, 1, 0, 1).x) is float


def test_clearance_and_heightmap_reject_bad_input():
    w = World((0, 0, 0), (1, 1, 1), 0.2, [])
    with pytest.raises(ValueError, match=r"points.*\(P, 3\)"):
        w.clearance([1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match="resolution"):
        w.heightmap(-1)
