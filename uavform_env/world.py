"""Ground truth of one episode: analytic obstacle primitives, their voxel raster, exact clearance, a DSM.

The primitives stay analytic so clearance (collision checks, rewards) is exact rather than limited by
the raster; the raster is the occupancy ground truth that onboard maps are scored against, on the
voxel grid of the conventions (origin a multiple of ``res``, same keys as OctoMap up to a shift).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

# Grid coordinates closer than this (relative) to an integer count as that integer, so 0.6 / 0.2 =
# 2.9999999999999996 is cell boundary 3 and a box face on a voxel face does not spill into the next voxel.
# Also the tie tolerance of the raster: a voxel whose centre is res / 2 from a flat face only touches it.
_SNAP = 1e-9
# Refuse grids larger than this instead of failing later with a MemoryError (2 Gi voxels = 2 GiB of raster;
# the env also checks its whole estimate against the memory available).
MAX_VOXELS = 2**31


def as_finite(owner: str, name: str, value) -> float:
    """``value`` as a float, or a ValueError naming ``owner.name`` (shared by the frozen data classes)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not math.isfinite(value):
        raise ValueError(f"{owner}.{name}={value!r}: expected a finite number")
    return float(value)


def as_finite_vector(owner: str, name: str, value, n: int) -> tuple[float, ...]:
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        arr = None
    if arr is None or arr.shape != (n,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{owner}.{name}={value!r}: expected {n} finite numbers")
    return tuple(float(v) for v in arr)


def as_positive(owner: str, name: str, value) -> float:
    value = as_finite(owner, name, value)
    if value <= 0.0:
        raise ValueError(f"{owner}.{name}={value!r}: expected a positive number")
    return value


@dataclass(frozen=True)
class Box:
    """Axis-aligned box [lo, hi] (closed); ``lo`` must be below ``hi`` on every axis."""

    lo: tuple[float, float, float]
    hi: tuple[float, float, float]

    def __post_init__(self):
        lo = as_finite_vector("Box", "lo", self.lo, 3)
        hi = as_finite_vector("Box", "hi", self.hi, 3)
        bad = [axis for axis, a, b in zip("xyz", lo, hi) if not a < b]
        if bad:
            raise ValueError(f"Box.lo={lo} must be below Box.hi={hi} on every axis (fails on {', '.join(bad)})")
        object.__setattr__(self, "lo", lo)
        object.__setattr__(self, "hi", hi)


@dataclass(frozen=True)
class Cylinder:
    """Vertical cylinder with axis at (x, y), spanning z_lo <= z <= z_hi."""

    x: float
    y: float
    radius: float
    z_lo: float
    z_hi: float

    def __post_init__(self):
        for name in ("x", "y", "z_lo", "z_hi"):
            object.__setattr__(self, name, as_finite("Cylinder", name, getattr(self, name)))
        object.__setattr__(self, "radius", as_positive("Cylinder", "radius", self.radius))
        if not self.z_lo < self.z_hi:
            raise ValueError(f"Cylinder.z_lo={self.z_lo!r} must be below Cylinder.z_hi={self.z_hi!r}")


@dataclass(frozen=True)
class Sphere:
    x: float
    y: float
    z: float
    radius: float

    def __post_init__(self):
        for name in ("x", "y", "z"):
            object.__setattr__(self, name, as_finite("Sphere", name, getattr(self, name)))
        object.__setattr__(self, "radius", as_positive("Sphere", "radius", self.radius))


Obstacle = Box | Cylinder | Sphere


def check_world_bounds(bounds_lo, bounds_hi, resolution) -> tuple[tuple[float, ...], tuple[float, ...], float]:
    """Validated (bounds_lo, bounds_hi, resolution) as floats; the world starts at the ground, z = 0."""
    lo = as_finite_vector("World", "bounds_lo", bounds_lo, 3)
    hi = as_finite_vector("World", "bounds_hi", bounds_hi, 3)
    res = as_positive("World", "resolution", resolution)
    if lo[2] != 0.0:
        raise ValueError(f"World.bounds_lo={lo}: expected z = 0 (the ground), got z = {lo[2]!r}")
    bad = [axis for axis, a, b in zip("xyz", lo, hi) if not a < b]
    if bad:
        raise ValueError(f"World.bounds_lo={lo} must be below World.bounds_hi={hi} on every axis "
                         f"(fails on {', '.join(bad)})")
    return lo, hi, res


def _snap(q: np.ndarray) -> np.ndarray:
    r = np.rint(q)
    return np.where(np.abs(q - r) <= _SNAP * np.maximum(1.0, np.abs(q)), r, q)


def _cell_span(lo: np.ndarray, hi: np.ndarray, origin: np.ndarray, res: float, n: np.ndarray) -> np.ndarray:
    """Index ranges [start, stop) (int64) of the cells [origin + i res, origin + (i+1) res) that overlap
    the intervals [lo, hi] with positive length, clipped to 0..n; vectorised over rows."""
    start = np.floor(_snap((lo - origin) / res))
    stop = np.ceil(_snap((hi - origin) / res))
    return np.concatenate([np.clip(start, 0, n), np.clip(stop, 0, n)], axis=-1).astype(np.int64)


def grid_frame(bounds_lo, bounds_hi, res: float) -> tuple[np.ndarray, tuple[int, ...]]:
    """Origin (a multiple of ``res``) and cell counts of the grid that covers [bounds_lo, bounds_hi]."""
    lo = np.asarray(bounds_lo, dtype=np.float64)
    origin = np.floor(_snap(lo / res)) * res
    n = np.ceil(_snap((np.asarray(bounds_hi, dtype=np.float64) - origin) / res)).astype(np.int64)
    return origin, tuple(int(v) for v in n)


@numba.njit(cache=True, inline="always")
def _box_sdf(boxes, b, px, py, pz):
    qx = max(boxes[b, 0] - px, px - boxes[b, 3])
    qy = max(boxes[b, 1] - py, py - boxes[b, 4])
    qz = max(boxes[b, 2] - pz, pz - boxes[b, 5])
    outside = math.sqrt(max(qx, 0.0) ** 2 + max(qy, 0.0) ** 2 + max(qz, 0.0) ** 2)
    return outside + min(max(qx, qy, qz), 0.0)


@numba.njit(cache=True, inline="always")
def _cylinder_sdf(dr, cylinders, c, pz):
    """Signed distance to cylinder c from a point at height pz whose radial offset from the surface is dr."""
    dz = max(cylinders[c, 3] - pz, pz - cylinders[c, 4])
    return min(max(dr, dz), 0.0) + math.sqrt(max(dr, 0.0) ** 2 + max(dz, 0.0) ** 2)


@numba.njit(cache=True)
def _clearance_kernel(points, boxes, cylinders, spheres):
    """Minimum signed distance over all primitives. A primitive is skipped, without square roots, when a
    lower bound of its signed distance (largest per-axis gap; horizontal or centre distance minus the
    radius) cannot beat the best so far."""
    out = np.empty(points.shape[0])
    for p in range(points.shape[0]):
        px, py, pz = points[p, 0], points[p, 1], points[p, 2]
        best = np.inf
        for b in range(boxes.shape[0]):
            if max(boxes[b, 0] - px, px - boxes[b, 3], boxes[b, 1] - py, py - boxes[b, 4],
                   boxes[b, 2] - pz, pz - boxes[b, 5]) < best:
                best = min(best, _box_sdf(boxes, b, px, py, pz))
        for c in range(cylinders.shape[0]):
            reach = best + cylinders[c, 2]
            d2 = (px - cylinders[c, 0]) ** 2 + (py - cylinders[c, 1]) ** 2
            if reach > 0.0 and d2 < reach * reach:
                best = min(best, _cylinder_sdf(math.sqrt(d2) - cylinders[c, 2], cylinders, c, pz))
        for s in range(spheres.shape[0]):
            reach = best + spheres[s, 3]
            d2 = (px - spheres[s, 0]) ** 2 + (py - spheres[s, 1]) ** 2 + (pz - spheres[s, 2]) ** 2
            if reach > 0.0 and d2 < reach * reach:
                best = min(best, math.sqrt(d2) - spheres[s, 3])
        out[p] = best
    return out


@numba.njit(cache=True, inline="always")
def _centre_span(lo, hi, o, res, n):
    """Index range [start, stop) that contains every cell whose centre lies in [lo, hi] (with a spare cell)."""
    start = max(0.0, min(float(n), math.floor((lo - o) / res) - 1.0))
    stop = max(0.0, min(float(n), math.floor((hi - o) / res) + 2.0))
    return int(start), int(stop)


@numba.njit(cache=True, inline="always")
def _fill_centres(occupied, i, j, z_lo, z_hi, oz, res):
    """Mark the voxels of column (i, j) whose centres lie in [z_lo, z_hi]."""
    k0 = max(0.0, math.ceil((z_lo - oz) / res - 0.5))
    k1 = min(float(occupied.shape[2]), math.floor((z_hi - oz) / res - 0.5) + 1.0)
    if k0 < k1:
        occupied[i, j, int(k0):int(k1)] = 1


@numba.njit(cache=True)
def _rasterise(occupied, origin, res, box_spans, cylinders, spheres):
    """Boxes by their exact index spans; cylinders and spheres column by column: the centres nearer
    than res / 2 to the surface (or inside) form one z-interval per column, found in closed form."""
    nx, ny, _ = occupied.shape
    half = 0.5 * res * (1.0 - _SNAP)  # a tie (a face on a voxel face) leaves the outer voxel free
    for b in range(box_spans.shape[0]):
        occupied[box_spans[b, 0]:box_spans[b, 3], box_spans[b, 1]:box_spans[b, 4], box_spans[b, 2]:box_spans[b, 5]] = 1
    for c in range(cylinders.shape[0]):
        x, y, r = cylinders[c, 0], cylinders[c, 1], cylinders[c, 2]
        i0, i1 = _centre_span(x - r - half, x + r + half, origin[0], res, nx)
        j0, j1 = _centre_span(y - r - half, y + r + half, origin[1], res, ny)
        for i in range(i0, i1):
            dx = origin[0] + (i + 0.5) * res - x
            for j in range(j0, j1):
                dr = math.hypot(dx, origin[1] + (j + 0.5) * res - y) - r
                if dr <= half:
                    e = math.sqrt(half * half - max(dr, 0.0) ** 2)
                    _fill_centres(occupied, i, j, cylinders[c, 3] - e, cylinders[c, 4] + e, origin[2], res)
    for s in range(spheres.shape[0]):
        x, y, z, reach = spheres[s, 0], spheres[s, 1], spheres[s, 2], spheres[s, 3] + half
        i0, i1 = _centre_span(x - reach, x + reach, origin[0], res, nx)
        j0, j1 = _centre_span(y - reach, y + reach, origin[1], res, ny)
        for i in range(i0, i1):
            dx = origin[0] + (i + 0.5) * res - x
            for j in range(j0, j1):
                d2 = reach * reach - dx * dx - (origin[1] + (j + 0.5) * res - y) ** 2
                if d2 >= 0.0:
                    e = math.sqrt(d2)
                    _fill_centres(occupied, i, j, z - e, z + e, origin[2], res)


@numba.njit(cache=True)
def _heightmap_kernel(heights, origin, res, box_spans, box_tops, discs):
    """Tops over each cell; ``discs`` rows (x, y, r, z, dome): top z, plus the dome height if dome = 1 (spheres)."""
    mx, my = heights.shape
    for b in range(box_spans.shape[0]):
        for i in range(box_spans[b, 0], box_spans[b, 2]):
            for j in range(box_spans[b, 1], box_spans[b, 3]):
                heights[i, j] = max(heights[i, j], box_tops[b])
    for c in range(discs.shape[0]):  # a disc reaches a cell iff the disc centre is nearer than r to the cell
        x, y, r, z, dome = discs[c, 0], discs[c, 1], discs[c, 2], discs[c, 3], discs[c, 4]
        r_tie = r - _SNAP * res  # a disc tangent to a cell edge does not cover the cell
        i0, i1 = _centre_span(x - r, x + r, origin[0], res, mx)
        j0, j1 = _centre_span(y - r, y + r, origin[1], res, my)
        for i in range(i0, i1):
            dx = max(origin[0] + i * res - x, 0.0, x - origin[0] - (i + 1) * res)
            for j in range(j0, j1):
                dy = max(origin[1] + j * res - y, 0.0, y - origin[1] - (j + 1) * res)
                d2 = dx * dx + dy * dy
                if d2 < r_tie * r_tie:  # a sphere's highest point over the cell is above its nearest point
                    heights[i, j] = max(heights[i, j], z + dome * math.sqrt(r * r - d2))


def _read_only(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


class World:
    """Ground truth, built once per reset; never shown to policies.

    ``occupied[i, j, k]`` is 1 iff voxel (i, j, k) overlaps an obstacle: exactly (positive volume) for
    boxes; for cylinders and spheres iff the signed distance at the voxel centre is < res / 2 (a tie
    counts as free, so a flat face on a voxel face rasterises exactly, as for boxes). That marks every
    voxel a curved surface cuts with a flat face's worth of depth, and misses slivers it only clips at
    a corner (clearance stays exact, so collisions do not depend on the raster).
    Obstacles may reach beyond the bounds (they are clipped to the grid). All arrays are read-only; the
    primitive arrays (float64) are the inputs of numba kernels elsewhere (ray casting, clearance).
    """

    def __init__(self, bounds_lo, bounds_hi, resolution, obstacles):
        self.bounds_lo, self.bounds_hi, self.res = check_world_bounds(bounds_lo, bounds_hi, resolution)
        self.obstacles = tuple(obstacles)
        for i, ob in enumerate(self.obstacles):
            if not isinstance(ob, (Box, Cylinder, Sphere)):
                raise ValueError(f"World.obstacles[{i}]={ob!r}: expected a Box, Cylinder or Sphere")
        origin, shape = grid_frame(self.bounds_lo, self.bounds_hi, self.res)    # z from 0: bounds_lo z is the ground
        n_voxels = math.prod(shape)
        if n_voxels > MAX_VOXELS:
            raise ValueError(f"World.resolution={self.res!r}: the grid {shape} would have {n_voxels} voxels, "
                             f"more than the {MAX_VOXELS} allowed; use a coarser resolution")
        self.origin = _read_only(origin)
        self.shape = shape
        self.boxes = _read_only(np.array([[*o.lo, *o.hi] for o in self.obstacles if isinstance(o, Box)],
                                         dtype=np.float64).reshape(-1, 6))
        self.cylinders = _read_only(np.array([[o.x, o.y, o.radius, o.z_lo, o.z_hi] for o in self.obstacles
                                              if isinstance(o, Cylinder)], dtype=np.float64).reshape(-1, 5))
        self.spheres = _read_only(np.array([[o.x, o.y, o.z, o.radius] for o in self.obstacles
                                            if isinstance(o, Sphere)], dtype=np.float64).reshape(-1, 4))
        occupied = np.zeros(shape, dtype=np.uint8)
        box_spans = _cell_span(self.boxes[:, :3], self.boxes[:, 3:], self.origin, self.res, np.array(shape))
        _rasterise(occupied, self.origin, self.res, box_spans, self.cylinders, self.spheres)
        self.occupied = _read_only(occupied)

    def clearance(self, points) -> np.ndarray:
        """Euclidean distance (P,) from each point (P, 3) to the nearest obstacle surface, negative inside.

        Exact outside the obstacles; inside, the depth in the deepest single primitive (a bound on the
        depth in a union of overlapping primitives). +inf when the world has no obstacles.
        """
        pts = np.asarray(points, dtype=np.float64)
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise ValueError(f"points: expected an array of shape (P, 3), got shape {pts.shape}")
        return _clearance_kernel(np.ascontiguousarray(pts), self.boxes, self.cylinders, self.spheres)

    def heightmap(self, resolution) -> tuple[np.ndarray, float, np.ndarray]:
        """2.5D prior map (a DSM, as from a survey): (origin_xy (2,), res, heights (mx, my) float32).

        ``heights[i, j]`` is the top of the tallest obstacle over cell [origin + (i, j) res, + res) (the
        highest point of a sphere above that cell), 0 where no obstacle covers the cell with positive area.
        """
        res = as_positive("World.heightmap", "resolution", resolution)
        origin, shape = grid_frame(self.bounds_lo[:2], self.bounds_hi[:2], res)
        heights = np.zeros(shape, dtype=np.float64)
        box_spans = _cell_span(self.boxes[:, :2], self.boxes[:, 3:5], origin, res, np.array(shape))
        c, sp = self.cylinders, self.spheres
        discs = np.concatenate([np.column_stack([c[:, :3], c[:, 4], np.zeros(len(c))]),
                                np.column_stack([sp[:, :2], sp[:, 3], sp[:, 2], np.ones(len(sp))])]).reshape(-1, 5)
        _heightmap_kernel(heights, origin, res, box_spans, np.ascontiguousarray(self.boxes[:, 5]), discs)
        return origin, res, heights.astype(np.float32)
