"""Voxel keys and the 3D-DDA ray traversal (Amanatides-Woo) shared by the range sensor and the map.

Keys follow OctoMap exactly, so our grids compare voxel by voxel with ``octomap-python``:

* ``key = floor(coordinate * (1 / res))``: OctoMap multiplies by the cached reciprocal
  (``coordToKey``); dividing by ``res`` instead puts points that lie on a voxel border on the other
  side (``1.2 / 0.1`` floors to 11, ``1.2 * (1 / 0.1)`` to 12).
* A grid whose lower corner is ``origin = key0 * res`` stores key ``k`` at index ``k - key0``
  (docs/CONVENTIONS.md), i.e. OctoMap's key grid shifted by its constant ``tree_max_val``.
* The traversal set-up and its tie-breaking copy ``OcTreeBaseImpl::computeRayKeys`` (ties go to
  the later axis); ``ray_keys`` also keeps its float32 quirks, the sensor uses exact borders.
"""

from __future__ import annotations

import math

import numba
import numpy as np

# Relative tolerance for "origin is a multiple of res" (absorbs decimal round-off such as 0.1 * 3).
_ORIGIN_TOL = 1e-6


def grid_origin_key(origin, res: float) -> np.ndarray:
    """The key (int64 (3,)) of a grid's lower corner; ValueError unless it is a multiple of ``res``."""
    if isinstance(res, bool) or not isinstance(res, (int, float, np.floating)) or not math.isfinite(res) or res <= 0:
        raise ValueError(f"res={res!r}: expected a finite voxel size > 0")
    o = np.asarray(origin, dtype=np.float64)
    if o.shape != (3,) or not np.all(np.isfinite(o)):
        raise ValueError(f"origin={origin!r}: expected 3 finite coordinates (x, y, z)")
    key = np.round(o / res)
    if np.any(np.abs(o / res - key) > _ORIGIN_TOL):
        raise ValueError(f"origin={o.tolist()}: expected a multiple of the voxel size {res!r} "
                         "(voxel centres must coincide with OctoMap's)")
    return key.astype(np.int64)


@numba.njit(cache=True, inline="always")
def coord_key(x, inv_res):
    """OctoMap's coordToKey along one axis (without the tree offset)."""
    return np.int64(math.floor(x * inv_res))


@numba.njit(cache=True, inline="always")
def axis_setup(o, d, key, res, half):
    """Along one axis: step (-1, 0, 1), ray length to the first voxel border, border spacing.

    The border is the voxel centre plus ``step * half``: half = res / 2 gives exact borders;
    OctoMap uses ``(float)(res / 2)`` (see ``ray_keys``).
    """
    if d > 0.0:
        step = 1
    elif d < 0.0:
        step = -1
    else:
        return 0, np.inf, np.inf
    border = (key + 0.5) * res + step * half
    return step, (border - o) / d, res / abs(d)


@numba.njit(cache=True, inline="always")
def next_axis(tx, ty, tz):
    """The axis whose border the ray crosses next (OctoMap's comparison order for ties)."""
    if tx < ty:
        return 0 if tx < tz else 2
    return 1 if ty < tz else 2


@numba.njit(cache=True, inline="always")
def ray_key_bound(ox, oy, oz, ex, ey, ez, inv_res):
    """Upper bound on the number of keys ``ray_keys`` returns for one segment (buffer sizing)."""
    return (abs(coord_key(ex, inv_res) - coord_key(ox, inv_res)) + abs(coord_key(ey, inv_res) - coord_key(oy, inv_res))
            + abs(coord_key(ez, inv_res) - coord_key(oz, inv_res)) + 4)


@numba.njit(cache=True, inline="always")
def ray_setup(ox, oy, oz, ex, ey, ez, kx, ky, kz, res):
    """``computeRayKeys``' set-up for the segment from (ox, oy, oz) (in voxel (kx, ky, kz)) to (ex, ey, ez):
    (sx, sy, sz, tx, ty, tz, ddx, ddy, ddz, length) for ``ray_select`` and ``ray_step``; see ``ray_keys`` for the
    float32 rules."""
    dx = np.float32(ex) - np.float32(ox)
    dy = np.float32(ey) - np.float32(oy)
    dz = np.float32(ez) - np.float32(oz)
    length = np.float32(math.sqrt(np.float64(dx * dx + dy * dy + dz * dz)))
    dx, dy, dz = dx / length, dy / length, dz / length
    half = np.float64(np.float32(res * 0.5))
    sx, tx, ddx = axis_setup(ox, np.float64(dx), kx, res, half)
    sy, ty, ddy = axis_setup(oy, np.float64(dy), ky, res, half)
    sz, tz, ddz = axis_setup(oz, np.float64(dz), kz, res, half)
    return sx, sy, sz, tx, ty, tz, ddx, ddy, ddz, np.float64(length)


@numba.njit(cache=True, inline="always")
def ray_select(tx, ty, tz):
    """The axis the traversal steps along next, as three flags (``next_axis``' choice), and the distance
    of the border it crosses there, which is min(tx, ty, tz).

    Selects instead of jumps (the axis sequence of a ray defeats branch prediction), which makes the
    map's walk faster (the sensor's loop measured faster with ``next_axis``' branches)."""
    x_first = tx < ty
    on_x = x_first & (tx < tz)
    on_y = (not x_first) & (ty < tz)
    on_z = not (on_x | on_y)
    return on_x, on_y, on_z, tx if on_x else (ty if on_y else tz)


@numba.njit(cache=True, inline="always")
def ray_step(kx, ky, kz, sx, sy, sz, tx, ty, tz, ddx, ddy, ddz, on_x, on_y, on_z):
    """One step of the traversal set up by ``ray_setup`` along the axis ``ray_select`` chose: the next
    voxel and the new border distances."""
    return (kx + sx * on_x, ky + sy * on_y, kz + sz * on_z, tx + ddx if on_x else tx, ty + ddy if on_y else ty,
            tz + ddz if on_z else tz)


@numba.njit(cache=True)
def ray_keys(ox, oy, oz, ex, ey, ez, res, out):
    """Port of OctoMap's ``computeRayKeys(origin, end)``: the keys of the voxels the segment crosses.

    The coordinates must already be float32 values (OctoMap's ``point3d`` is float); the direction
    and length are formed in float32 as in OctoMap. The origin voxel comes first; the end voxel is
    never included; a ray stops early once it is longer than the segment (OctoMap's guard against
    drift). Writes the keys to ``out`` (K, 3) int64 and returns K. (The map's integrate kernel walks
    the same ``ray_setup`` / ``ray_select`` / ``ray_step`` steps without storing the keys.)
    """
    inv_res = 1.0 / res
    kx, ky, kz = coord_key(ox, inv_res), coord_key(oy, inv_res), coord_key(oz, inv_res)
    ekx, eky, ekz = coord_key(ex, inv_res), coord_key(ey, inv_res), coord_key(ez, inv_res)
    if kx == ekx and ky == eky and kz == ekz:
        return 0
    out[0, 0], out[0, 1], out[0, 2] = kx, ky, kz
    n = 1
    sx, sy, sz, tx, ty, tz, ddx, ddy, ddz, length = ray_setup(ox, oy, oz, ex, ey, ez, kx, ky, kz, res)
    on_x, on_y, on_z, _ = ray_select(tx, ty, tz)
    while True:
        kx, ky, kz, tx, ty, tz = ray_step(kx, ky, kz, sx, sy, sz, tx, ty, tz, ddx, ddy, ddz, on_x, on_y, on_z)
        if kx == ekx and ky == eky and kz == ekz:
            return n
        on_x, on_y, on_z, t = ray_select(tx, ty, tz)  # t = min(tx, ty, tz)
        if t > length:
            return n
        out[n, 0], out[n, 1], out[n, 2] = kx, ky, kz
        n += 1
