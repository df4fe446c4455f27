"""Primary polar histogram of spec (f1)-(f2): hand-checked cases and a slow independent reference."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from uavform_env.polar_histogram import (cell_index, half_width, histogram_shape, primary_histogram, weight_constants,
                                         width_steps)

CELL = math.radians(5.0)
P_MAX = 0.971
A = 2.0
B = 1.0 / 4.3  # weight_constants(2, 5, 0.7): edge weight 1


def reference_histogram(centres, probs, r_e, pos, cell, R_w, a, b, enlarge_mode="ceil_2d", azimuth_ref=0.0):
    """Spec (f2) cell by cell, from degrees, with no shared code: which voxel windows contain each cell.

    Widths use the module's documented rounding tolerance (1e-9 cell), so asin(1) = 90 deg is exactly 6
    cells of 15 deg even though the float quotient is 6.000000000000001.
    """
    n_e, n_z = int(round(180 / math.degrees(cell))), int(round(360 / math.degrees(cell)))
    deg = math.degrees(cell)
    hist = np.zeros((n_e, n_z))
    for c, o, re in zip(centres, probs, r_e):
        dx, dy, dz = np.asarray(c) - pos
        d, ph = math.dist(c, pos), math.hypot(dx, dy)
        if o <= 0.5 or d > R_w:
            continue
        az_deg = math.degrees(math.atan2(dy, dx) - azimuth_ref) % 360.0
        bz = int(az_deg // deg)
        be = min(max(int((math.degrees(math.atan2(dz, ph)) + 90.0) // deg), 0), n_e - 1)
        if enlarge_mode == "ceil_2d":
            lam_e = math.ceil(math.degrees(math.asin(min(1.0, re / d))) / deg - 1e-9)
            lam_z = math.ceil(math.degrees(math.asin(min(1.0, re / max(ph, re)))) / deg - 1e-9)
        else:
            lam_e = lam_z = math.floor(math.degrees(math.asin(min(1.0, re / d))) / deg + 1e-9)
        weight = o * o * (a - b * max(0.0, d - re))
        for e in range(n_e):
            for z in range(n_z):
                gap = abs(z - bz)
                if abs(e - be) <= lam_e and min(gap, n_z - gap) <= lam_z:
                    hist[e, z] += weight
    return hist


def test_histogram_shape():
    assert histogram_shape(CELL) == (36, 72)
    assert histogram_shape(math.radians(15.0)) == (12, 24)
    assert histogram_shape(math.pi / 2) == (2, 4)
    for bad in (math.radians(7.0), 0.0, -CELL, math.pi, "5"):
        with pytest.raises(ValueError, match="cell"):
            histogram_shape(bad)


def test_weight_constants_edge_equals_one():
    a, b = weight_constants(2.0, 5.0, 0.7)
    assert b == pytest.approx(1.0 / 4.3)
    assert a - b * (5.0 - 0.7) == pytest.approx(1.0)  # weight 1 at the edge, 2 at contact


def test_weight_constants_paper_literal():
    # a - b ((w_s - 1)/2)^2 = 1 with a half-window of 5 m / 0.2 m = 25 voxels.
    a, b = weight_constants(2.0, 5.0, 0.7, relation="paper_literal", voxel_size=0.2)
    assert b == pytest.approx(1.0 / 625.0)
    with pytest.raises(ValueError, match="voxel_size"):
        weight_constants(2.0, 5.0, 0.7, relation="paper_literal")


@pytest.mark.parametrize("kwargs, match", [
    (dict(a=0.5, R_w=5.0, r_e=0.7), "b > 0"),  # the open implementation's a < 1: weights grow with distance
    (dict(a=1.0, R_w=5.0, r_e=0.7), "b > 0"),
    (dict(a=0.5, R_w=5.0, r_e=0.7, relation="paper_literal", voxel_size=0.2), "b > 0"),
    (dict(a=2.0, R_w=5.0, r_e=5.0), "r_e"),
    (dict(a=2.0, R_w=5.0, r_e=0.7, relation="quadratic"), "relation"),
    (dict(a=float("nan"), R_w=5.0, r_e=0.7), "a="),
    (dict(a=3.0, R_w=5.0, r_e=0.7, relation="paper_literal", voxel_size=5.0), "positive weight"),
])
def test_weight_constants_rejects(kwargs, match):
    with pytest.raises(ValueError, match=match):
        weight_constants(**kwargs)


def test_single_saturated_voxel_blocks_plus_minus_five_cells():
    """Appendix B 6: p = 0.971 straight ahead at 2 m, r_e = 0.7 -> +/-ceil(asin(0.35)/5 deg) = +/-5 cells."""
    assert math.ceil(math.degrees(math.asin(0.35)) / 5.0) == 5
    a, b = weight_constants(2.0, 5.0, 0.7)
    assert b > 0
    pos = np.array([1.0, -2.0, 3.0])
    hist, emergency = primary_histogram(pos + [[2.0, 0.0, 0.0]], [P_MAX], 0.7, pos, CELL, 5.0, a, b)
    assert not emergency
    rows = np.arange(13, 24)  # level row 18 = [0, 5) deg, +/-5
    cols = np.r_[67:72, 0:6]  # azimuth column 0 = [0, 5) deg, +/-5 around the wrap
    expected = np.zeros((36, 72))
    expected[np.ix_(rows, cols)] = P_MAX ** 2 * (a - b * 1.3)
    np.testing.assert_allclose(hist, expected, rtol=0, atol=1e-12)
    assert expected.max() > 0.9  # above tau_high: all 11 x 11 cells are blocked


def test_azimuth_is_x_referenced():
    """Appendix B 6: the azimuth bin of (dx, dy) = (0, 1) is 90 deg, i.e. column 18 (spec convention, not PX4's)."""
    assert cell_index(0.0, 1.0, 0.0, CELL, 36, 72, 0.0) == (18, 18)
    assert cell_index(0.0, -1.0, 0.0, CELL, 36, 72, 0.0) == (18, 54)
    assert cell_index(-1.0, 0.0, -1e-3, CELL, 36, 72, 0.0) == (17, 36)
    hist, _ = primary_histogram([[0.0, 2.0, 0.0]], [P_MAX], 0.7, np.zeros(3), CELL, 5.0, A, B)
    occupied_cols = np.flatnonzero(hist[18] > 0)
    np.testing.assert_array_equal(occupied_cols, np.arange(13, 24))


def test_body_frame_rotates_columns():
    """azimuth_ref = yaw makes column 0 start at the heading: a voxel dead ahead of a UAV facing +y."""
    pos = np.zeros(3)
    hist, _ = primary_histogram([[0.0, 2.0, 0.0]], [P_MAX], 0.7, pos, CELL, 5.0, A, B, azimuth_ref=math.pi / 2)
    assert set(np.flatnonzero(hist[18] > 0)) == set(range(67, 72)) | set(range(0, 6))


def test_exact_width_multiples_do_not_round_up():
    """r_e/d = 0.5 gives asin = 30 deg = exactly 6 cells: the window is +/-6, not +/-7."""
    hist, _ = primary_histogram([[1.4, 0.0, 0.0]], [P_MAX], 0.7, np.zeros(3), CELL, 5.0, A, B)
    assert np.count_nonzero(hist[:, 0]) == 13 and np.count_nonzero(hist[18]) == 13


def test_paper_floor_uses_one_floored_width():
    hist, _ = primary_histogram([[2.0, 0.0, 0.0]], [P_MAX], 0.7, np.zeros(3), CELL, 5.0, A, B,
                                enlarge_mode="paper_floor")
    assert np.count_nonzero(hist[:, 0]) == 9 and np.count_nonzero(hist[18]) == 9  # floor(4.1) = 4


def test_pole_rows_dropped_and_azimuth_widened():
    """A voxel almost overhead: rows past the pole are dropped, azimuth spans +/-18 cells (asin(1)/5 deg)."""
    pos = np.zeros(3)
    hist, _ = primary_histogram([[0.05, 0.0, 2.0]], [P_MAX], 0.7, pos, CELL, 5.0, A, B)
    d = math.hypot(0.05, 2.0)
    lam_e = math.ceil(math.degrees(math.asin(0.7 / d)) / 5.0)
    assert np.flatnonzero(hist.any(axis=1)).tolist() == list(range(35 - lam_e, 36))
    assert np.count_nonzero(hist[35]) == 37
    weight = P_MAX ** 2 * (A - B * (d - 0.7))
    assert hist.sum() == pytest.approx(weight * (lam_e + 1) * 37)


def test_far_voxels_free_voxels_and_emergency():
    pos = np.array([0.0, 0.0, 2.0])
    far = pos + [[5.01, 0.0, 0.0], [0.0, 0.0, -6.0]]
    hist, emergency = primary_histogram(far, [P_MAX, P_MAX], 0.7, pos, CELL, 5.0, A, B)
    assert not hist.any() and not emergency
    hist, emergency = primary_histogram(pos + [[1.0, 0.0, 0.0]], [0.5], 0.7, pos, CELL, 5.0, A, B)
    assert not hist.any() and not emergency  # p = 0.5 is not occupied
    _, emergency = primary_histogram(pos + [[0.7, 0.0, 0.0]], [0.6], 0.7, pos, CELL, 5.0, A, B)
    assert emergency  # d <= r_e
    _, emergency = primary_histogram(pos + [[0.9, 0.0, 0.0]], [1.0], [1.0], pos, CELL, 5.0, A, B)
    assert emergency  # per-point radius, as for a neighbour pseudo-voxel
    hist, emergency = primary_histogram(pos[None, :], [1.0], 0.7, pos, CELL, 5.0, A, B)
    assert emergency and np.isfinite(hist).all() and hist.max() == pytest.approx(A)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(0, 25), mode=st.sampled_from(["ceil_2d", "paper_floor"]),
       cell_deg=st.sampled_from([5.0, 10.0, 15.0, 30.0]))
def test_matches_reference(seed, n, mode, cell_deg):
    rng = np.random.default_rng(seed)
    pos = rng.uniform(-1, 1, 3)
    centres = pos + rng.uniform(-4.0, 4.0, (n, 3))
    probs = rng.uniform(0.3, 1.0, n)
    r_e = rng.uniform(0.3, 1.5, n)
    cell = math.radians(cell_deg)
    azimuth_ref = rng.uniform(-4.0, 4.0)
    got, emergency = primary_histogram(centres, probs, r_e, pos, cell, 5.0, A, B, mode, azimuth_ref)
    want = reference_histogram(centres, probs, r_e, pos, cell, 5.0, A, B, mode, azimuth_ref)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)
    d = np.linalg.norm(centres - pos, axis=1)
    assert emergency == bool(np.any((d <= r_e) & (probs > 0.5)))


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), shift=st.integers(-80, 80))
def test_azimuth_ref_is_a_column_roll(seed, shift):
    rng = np.random.default_rng(seed)
    centres = rng.uniform(-4.0, 4.0, (12, 3))
    world, _ = primary_histogram(centres, np.full(12, 0.9), 0.7, np.zeros(3), CELL, 5.0, A, B)
    body, _ = primary_histogram(centres, np.full(12, 0.9), 0.7, np.zeros(3), CELL, 5.0, A, B,
                                azimuth_ref=shift * CELL)
    np.testing.assert_allclose(body, np.roll(world, -shift, axis=1), atol=1e-12)


@pytest.mark.parametrize("kwargs, match", [
    (dict(centres=np.zeros((2, 2))), "centres"),
    (dict(probs=[0.9]), "probs"),
    (dict(r_e=-0.7), "r_e"),
    (dict(r_e=[0.7]), "r_e"),
    (dict(pos=[0.0, 0.0]), "pos"),
    (dict(enlarge_mode="paper"), "enlarge_mode"),
    (dict(R_w=0.0), "R_w"),
    (dict(cell=math.radians(7.0)), "cell"),
])
def test_bad_input_is_rejected(kwargs, match):
    args = dict(centres=np.ones((2, 3)), probs=[0.9, 0.9], r_e=0.7, pos=np.zeros(3), cell=CELL, R_w=5.0, a=A, b=B)
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        primary_histogram(**args)


@pytest.mark.parametrize("cell_deg", [5.0, 10.0, 15.0, 30.0])
@pytest.mark.parametrize("paper_floor", [False, True])
def test_width_steps_count_the_arcsine_half_width_exactly(cell_deg, paper_floor):
    """The kernel counts steps instead of taking asin: the same half-width for every x, also next to each step."""
    cell = math.radians(cell_deg)
    steps = width_steps(cell, paper_floor)
    assert np.all(np.diff(steps) > 0) and steps.size == half_width(1.0, cell, paper_floor)
    rng = np.random.default_rng(0)
    xs = np.concatenate([rng.uniform(0.0, 1.0, 20000), [0.0, 1.0], steps, np.nextafter(steps, 0.0),
                         np.nextafter(steps, 2.0), np.sin(np.arange(1, steps.size + 1) * cell)])
    xs = np.clip(xs, 0.0, 1.0)
    expected = np.array([half_width(x, cell, paper_floor) for x in xs])
    assert np.array_equal(np.searchsorted(steps, xs, side="right"), expected)
    # the half-widths themselves: asin(0.5) / 5 deg = 6 exactly (within _SNAP), so x = 0.5 gives 6 in both modes
    if cell_deg == 5.0:
        assert half_width(0.5, cell, paper_floor) == 6
