"""Primary polar obstacle histogram of 3D VFH+ (spec (f1)-(f2)).

The histogram turns a sphere of occupied voxels around a UAV into an elevation x azimuth grid of
obstacle mass. The environment uses it for the agents' observations (in the body frame) and the 3D
VFH+ planner for its binary and masked histograms (in the world frame), so both see the same
obstacles. Everything here is a pure function of arrays; the occupancy map stays outside.

Grid layout: row ``e`` covers elevations ``[-pi/2 + e*cell, -pi/2 + (e+1)*cell)``, column ``z`` covers
azimuths ``[azimuth_ref + z*cell, azimuth_ref + (z+1)*cell)`` measured from +x, counter-clockwise.
"""

from __future__ import annotations

import functools
import math

import numba
import numpy as np

ENLARGE_MODES = ("ceil_2d", "paper_floor")
WEIGHT_RELATIONS = ("edge_equals_one", "paper_literal")

# Tolerance, in cells, of every angle-to-index rounding: an angle this close below a cell boundary
# counts as on it. Axis-aligned directions (a voxel straight ahead, a wall along y) would otherwise
# fall into a neighbouring cell through float rounding, and widths such as asin(0.5)/5deg = 6
# would round up to 7.
_SNAP = 1e-9


def histogram_shape(cell: float) -> tuple[int, int]:
    """(N_e, N_z) = (round(pi/cell), round(2pi/cell)); ``cell`` must divide 180 degrees."""
    if isinstance(cell, bool) or not isinstance(cell, (int, float, np.floating)) or not 0.0 < cell <= math.pi / 2:
        raise ValueError(f"cell={cell!r}: expected an angle in (0, pi/2] radians")
    n_e = round(math.pi / cell)
    if abs(math.pi / cell - n_e) > _SNAP:
        raise ValueError(f"cell={cell!r} rad ({math.degrees(cell):g} deg): expected a divisor of 180 degrees")
    return n_e, 2 * n_e


def weight_constants(a: float, R_w: float, r_e: float, relation: str = "edge_equals_one",
                     voxel_size: float | None = None) -> tuple[float, float]:
    """Constants (a, b) of the voxel weight o^2 (a - b l) (spec (f2)).

    ``edge_equals_one`` makes a voxel at the edge of the active region (l = R_w - r_e) weigh 1, so a
    saturated voxel blocks its cells anywhere in the region. ``paper_literal`` is the source's eq. 7,
    a - b ((w_s - 1)/2)^2 = 1, with the half-window (w_s - 1)/2 = R_w / voxel_size in voxels.
    Both need a > 1; a weight that grows with distance (b <= 0) or turns negative inside the
    region is rejected.
    """
    for name, value in (("a", a), ("R_w", R_w), ("r_e", r_e)):
        if isinstance(value, bool) or not isinstance(value, (int, float, np.floating)) or not math.isfinite(value):
            raise ValueError(f"{name}={value!r}: expected a finite number")
    if not 0.0 < r_e < R_w:
        raise ValueError(f"r_e={r_e!r}: expected 0 < r_e < R_w={R_w!r}")
    if relation == "edge_equals_one":
        b = (a - 1.0) / (R_w - r_e)
    elif relation == "paper_literal":
        if voxel_size is None or not voxel_size > 0.0:
            raise ValueError(f"voxel_size={voxel_size!r}: relation 'paper_literal' needs a positive voxel size")
        b = (a - 1.0) / (R_w / voxel_size) ** 2
    else:
        raise ValueError(f"relation={relation!r}: expected one of {list(WEIGHT_RELATIONS)}")
    if not b > 0.0:
        raise ValueError(f"a={a!r} gives b={b:g} with relation {relation!r}; expected b > 0 (needs a > 1), "
                         "otherwise far obstacles would weigh more than near ones")
    if not a - b * (R_w - r_e) > 0.0:
        raise ValueError(f"a={a!r}, b={b:g}: voxels at the edge of R_w={R_w!r} would weigh "
                         f"{a - b * (R_w - r_e):g}; expected a positive weight")
    return float(a), float(b)


@numba.njit(cache=True)
def cell_index(dx, dy, dz, cell, n_e, n_z, azimuth_ref):
    """(row, column) of the cell holding direction (dx, dy, dz); the one binning rule of spec (f2)."""
    az = math.atan2(dy, dx) - azimuth_ref
    az -= 2.0 * math.pi * math.floor(az / (2.0 * math.pi))
    column = int(math.floor(az / cell + _SNAP)) % n_z
    el = math.atan2(dz, math.sqrt(dx * dx + dy * dy))
    row = min(max(int(math.floor((el + 0.5 * math.pi) / cell + _SNAP)), 0), n_e - 1)
    return row, column


@numba.njit(cache=True)
def half_width(x, cell, paper_floor):
    """Half-width in cells of the window of a voxel seen under the half-angle asin(x), x = r_e / distance in
    [0, 1]: ceil(asin(x) / cell) (``ceil_2d``) or the paper's floor (``paper_floor``), both within _SNAP."""
    w = math.asin(x) / cell
    return int(math.floor(w + _SNAP)) if paper_floor else int(math.ceil(w - _SNAP))


@functools.lru_cache(maxsize=8)
def width_steps(cell: float, paper_floor: bool) -> np.ndarray:
    """The smallest x in [0, 1] at which ``half_width(x, cell, paper_floor)`` reaches 1, 2, ...

    ``half_width`` never decreases with x (asin, the division, the rounding and the floor or ceil all keep
    the order), so ``half_width(x)`` is exactly the number of these steps <= x: the histogram kernel counts
    them instead of taking an arcsine per voxel. Found by bisection over the floats' bit patterns."""
    histogram_shape(cell)
    steps = np.empty(half_width(1.0, cell, paper_floor))
    lo_all = np.float64(0.0).view(np.int64)
    for n in range(1, steps.size + 1):
        lo, hi = lo_all, np.float64(1.0).view(np.int64)  # half_width(lo) < n <= half_width(hi)
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if half_width(np.int64(mid).view(np.float64), cell, paper_floor) >= n:
                hi = mid
            else:
                lo = mid
        steps[n - 1] = np.int64(hi).view(np.float64)
        lo_all = lo
    steps.flags.writeable = False
    return steps


@numba.njit(cache=True, inline="always")
def _count_steps(steps, x):
    """``half_width(x)`` from its ``width_steps``."""
    n = 0
    while n < steps.shape[0] and x >= steps[n]:
        n += 1
    return n


@functools.lru_cache(maxsize=8)
def cell_geometry(cell: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cell-centre elevations (N_e,), azimuths (N_z,) from column 0, and unit vectors (N_e, N_z, 3)."""
    n_e, n_z = histogram_shape(cell)
    elevation = -0.5 * math.pi + (np.arange(n_e) + 0.5) * cell
    azimuth = (np.arange(n_z) + 0.5) * cell
    ce = np.cos(elevation)[:, None]
    units = np.stack([ce * np.cos(azimuth)[None, :], ce * np.sin(azimuth)[None, :],
                      np.broadcast_to(np.sin(elevation)[:, None], (n_e, n_z))], axis=-1)
    for array in (elevation, azimuth, units):
        array.flags.writeable = False
    return elevation, azimuth, units


@numba.njit(cache=True)
def _primary_kernel(centres, probs, r_e, pos, cell, n_e, n_z, R_w, a, b, paper_floor, steps, azimuth_ref, hist):
    """Accumulate every active voxel's weight over its enlarged cell window; return the emergency flag.
    ``steps`` = ``width_steps(cell, paper_floor)``."""
    emergency = False
    flat = hist.reshape(-1)  # flat row-major indexing is about twice as fast in the inner loop
    n_z_u = np.uint64(n_z)
    for i in range(centres.shape[0]):
        o = probs[i]
        if o <= 0.5:
            continue
        dx = centres[i, 0] - pos[0]
        dy = centres[i, 1] - pos[1]
        dz = centres[i, 2] - pos[2]
        d = math.sqrt(dx * dx + dy * dy + dz * dz)
        if d > R_w:
            continue
        re = r_e[i]
        if d <= re:
            emergency = True
        ph = math.sqrt(dx * dx + dy * dy)
        be, bz = cell_index(dx, dy, dz, cell, n_e, n_z, azimuth_ref)
        lam_e = _count_steps(steps, min(1.0, re / d) if d > 0.0 else 1.0)  # asin(1) = pi / 2 exactly
        lam_z = lam_e if paper_floor else _count_steps(steps, min(1.0, re / max(ph, re)))
        h = o * o * (a - b * max(0.0, d - re))
        # Columns bz - lam_z .. bz + lam_z as up to two unwrapped runs; lam_z <= N_e/2 = N_z/4,
        # so the run never covers a column twice. The indices are unsigned: numba then skips its
        # negative-index wrap check, which more than halves the time of these loops.
        first = bz - lam_z
        last = bz + lam_z
        if first < 0:
            first += n_z
            last += n_z
        first_u = np.uint64(first)
        end_1 = np.uint64(min(last, n_z - 1) + 1)
        end_2 = np.uint64(max(last - n_z + 1, 0))
        for e in range(max(be - lam_e, 0), min(be + lam_e, n_e - 1) + 1):
            base = np.uint64(e) * n_z_u
            for k in range(base + first_u, base + end_1):
                flat[k] += h
            for k in range(base, base + end_2):
                flat[k] += h
    return emergency


def primary_histogram(centres, probs, r_e, pos, cell: float, R_w: float, a: float, b: float,
                      enlarge_mode: str = "ceil_2d", azimuth_ref: float = 0.0) -> tuple[np.ndarray, bool]:
    """Primary polar histogram H^p (N_e, N_z) and the emergency flag (spec (f1)-(f2)).

    ``centres`` (M, 3) and ``probs`` (M,) are occupied voxels (probabilities <= 0.5 are skipped);
    ``r_e`` is the enlargement radius, a scalar or one per voxel (neighbour pseudo-voxels use a
    larger one). Voxels farther than ``R_w`` are ignored. Each voxel adds o^2 (a - b l) to the cells
    within lambda_e rows (rows beyond the poles are dropped) and lambda_z columns (circular) of its
    own cell: ``ceil_2d`` uses ceil and a separate, pole-widened azimuth half-width, ``paper_floor``
    the paper's floor with one width. ``azimuth_ref`` rotates column 0 to that azimuth (pass the yaw
    for a body-frame histogram). ``emergency`` is True if any voxel lies within its r_e of ``pos``.
    """
    n_e, n_z = histogram_shape(cell)
    if enlarge_mode not in ENLARGE_MODES:
        raise ValueError(f"enlarge_mode={enlarge_mode!r}: expected one of {list(ENLARGE_MODES)}")
    centres = np.ascontiguousarray(centres, dtype=np.float64)
    if centres.ndim != 2 or centres.shape[1] != 3:
        raise ValueError(f"centres: expected shape (M, 3), got {centres.shape}")
    m = centres.shape[0]
    probs = np.ascontiguousarray(probs, dtype=np.float64)
    if probs.shape != (m,):
        raise ValueError(f"probs: expected shape ({m},) to match centres, got {probs.shape}")
    r_e_arr = np.asarray(r_e, dtype=np.float64)
    if r_e_arr.ndim == 0:
        r_e_arr = np.full(m, float(r_e_arr))
    if r_e_arr.shape != (m,) or not np.all(r_e_arr > 0.0):
        got = f"shape {r_e_arr.shape}" if r_e_arr.ndim else repr(r_e)
        raise ValueError(f"r_e: expected a positive scalar or shape ({m},) of positive radii, got {got}")
    pos = np.ascontiguousarray(pos, dtype=np.float64)
    if pos.shape != (3,):
        raise ValueError(f"pos: expected shape (3,), got {pos.shape}")
    if not R_w > 0.0:
        raise ValueError(f"R_w={R_w!r}: expected a positive radius")
    hist = np.zeros((n_e, n_z))
    paper_floor = enlarge_mode == "paper_floor"
    emergency = _primary_kernel(centres, probs, np.ascontiguousarray(r_e_arr), pos, float(cell), n_e, n_z,
                                float(R_w), float(a), float(b), paper_floor, width_steps(float(cell), paper_floor),
                                float(azimuth_ref), hist)
    return hist, bool(emergency)
