"""Simulated range sensor: an azimuth x elevation fan of rays cast from every UAV at once.

Rays are traced through the world's voxel grid with the 3D-DDA of ``dda`` (the same key grid and
traversal as the onboard OctoMap), against the ground (z < 0 is solid) and against the other UAVs
(spheres). One numba call covers all UAVs and all rays.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from .config import SensorConfig
from .dda import axis_setup, coord_key, grid_origin_key, next_axis

# Hit kinds of a ray.
NOTHING, STATIC, UAV = 0, 1, 2
# Golden-ratio step of the interleaved azimuth offset (in units of one azimuth spacing).
_GOLDEN = 0.6180339887
# A static-hit endpoint is pulled this fraction of a voxel inside the hit voxel, so looking it up
# (also after OctoMap's float32 rounding) always returns the hit voxel.
_ENDPOINT_INSET = 1e-3


@dataclass(frozen=True)
class Scan:
    """One scan of N UAVs with R rays each (world frame).

    ``kind``: 0 nothing within r_max (range = r_max), 1 static obstacle or ground, 2 another UAV.
    ``endpoints`` = origin + direction * range; for kind 1 the endpoint lies just inside the hit
    voxel (for ground hits: just below z = 0), so voxel lookups of hits are robust.
    """

    directions: np.ndarray  # (N, R, 3) float64 unit vectors
    ranges: np.ndarray      # (N, R) float64
    kind: np.ndarray        # (N, R) int8
    endpoints: np.ndarray   # (N, R, 3) float64


class RangeSensor:
    """Ray-casting range sensor with ``cfg.n_azimuth x cfg.n_elevation`` rays per UAV.

    Ray r = i_az * n_elevation + i_el points at azimuth ``i_az * 2 pi / n_az`` (+ yaw, + the
    interleave offset) and elevation ``i_el``-th of n_el values evenly spaced over
    [elevation_min, elevation_max] (a single row looks level).
    """

    def __init__(self, cfg: SensorConfig):
        if not isinstance(cfg, SensorConfig):
            raise ValueError(f"cfg: expected a SensorConfig, got {type(cfg).__name__}")
        self.cfg = cfg
        if cfg.n_elevation == 1:
            elevations = np.zeros(1)
        else:
            elevations = np.linspace(cfg.elevation_min, cfg.elevation_max, cfg.n_elevation)
        azimuths = np.repeat(np.arange(cfg.n_azimuth) * (2.0 * math.pi / cfg.n_azimuth), cfg.n_elevation)
        elevations = np.tile(elevations, cfg.n_azimuth)
        # the fan at azimuth offset 0; a step's fan is this one rotated about z
        self._fan = np.ascontiguousarray(np.column_stack([np.cos(elevations) * np.cos(azimuths),
                                                          np.cos(elevations) * np.sin(azimuths), np.sin(elevations)]))
        self._grid = (None, None, None)  # (origin, res, key) of the last grid scanned: see _origin_key

    @property
    def n_rays(self) -> int:
        return self.cfg.n_rays

    def _origin_key(self, origin, res) -> np.ndarray:
        """``dda.grid_origin_key(origin, res)``, worked out once for a read-only origin array (a ``World``'s),
        which every scan of an episode passes again."""
        last, last_res, key = self._grid
        if origin is last and res == last_res and not origin.flags.writeable:
            return key
        key = grid_origin_key(origin, res)
        if isinstance(origin, np.ndarray) and not origin.flags.writeable:
            self._grid = (origin, res, key)
        return key

    def _azimuth_offset(self, step: int) -> float:
        """Interleave: rotate the fan by frac(step * golden) of one azimuth spacing."""
        if not self.cfg.interleave:
            return 0.0
        return math.modf(step * _GOLDEN)[0] * (2.0 * math.pi / self.cfg.n_azimuth)

    def directions(self, step: int) -> np.ndarray:
        """Body-frame unit ray directions (R, 3) used at simulation step ``step``."""
        out = np.empty((1,) + self._fan.shape)
        _rotate_fan(self._fan, np.array([self._azimuth_offset(_check_step(step))]), out)
        return out[0]

    def scan(self, occupied: np.ndarray, origin, res: float, positions: np.ndarray, yaws: np.ndarray,
             step: int, uav_radius: float) -> Scan:
        """Cast every UAV's rays through ``occupied`` (uint8 (nx, ny, nz), lower corner ``origin``).

        Outside the grid is free space except z < 0 (ground). Every UAV is a sphere of
        ``uav_radius`` seen by the others. Sensor faults are a separate step: ``perturb_scan``.
        """
        occupied = np.asarray(occupied)
        if occupied.ndim != 3 or occupied.dtype != np.uint8:
            raise ValueError(f"occupied: expected a 3D uint8 grid, got {occupied.dtype} with shape {occupied.shape}")
        key0 = self._origin_key(origin, res)
        positions = np.ascontiguousarray(positions, dtype=np.float64)
        if positions.ndim != 2 or positions.shape[1] != 3 or not np.isfinite(positions).all():
            raise ValueError(f"positions: expected finite (N, 3) coordinates, got shape {positions.shape}")
        yaws = np.asarray(yaws, dtype=np.float64)
        if yaws.shape != (positions.shape[0],) or not np.isfinite(yaws).all():
            raise ValueError(f"yaws: expected {positions.shape[0]} finite angles (one per position), "
                             f"got shape {yaws.shape}")
        if isinstance(uav_radius, bool) or not np.isfinite(uav_radius) or uav_radius < 0:
            raise ValueError(f"uav_radius={uav_radius!r}: expected a finite radius >= 0")
        step = _check_step(step)

        n, r = positions.shape[0], self._fan.shape[0]
        dirs = np.empty((n, r, 3))
        _rotate_fan(self._fan, yaws + self._azimuth_offset(step), dirs)
        ranges = np.empty((n, r))
        kind = np.empty((n, r), np.int8)
        endpoints = np.empty((n, r, 3))
        _cast_rays(np.ascontiguousarray(occupied), key0, float(res), positions, dirs, float(self.cfg.r_max),
                   float(uav_radius), ranges, kind, endpoints)
        return Scan(directions=dirs, ranges=ranges, kind=kind, endpoints=endpoints)


def perturb_scan(scan: Scan, positions: np.ndarray, r_max: float, noise_std: float, dropout: float,
                 noise_rng: np.random.Generator | None, dropout_rng: np.random.Generator | None) -> Scan:
    """The scan as a faulty sensor reports it (``DisturbanceConfig``): a new ``Scan``, the input untouched.

    Every range that hit something (kind 1 or 2) gets Gaussian noise of ``noise_std`` m from
    ``noise_rng`` (never below 0; its endpoint moves along the ray). Then each ray is lost with
    probability ``dropout``, drawn from ``dropout_rng``: it reads as no return (kind 0, range r_max).
    Each fault draws one full (N, R) array from its own generator, so enabling one never shifts the other.
    """
    for name, rate, rng in (("noise_rng", noise_std, noise_rng), ("dropout_rng", dropout, dropout_rng)):
        if rate > 0.0 and not isinstance(rng, np.random.Generator):
            raise ValueError(f"{name}: expected a numpy Generator, got {type(rng).__name__}")
    ranges, kind, endpoints = scan.ranges.copy(), scan.kind.copy(), scan.endpoints.copy()
    if noise_std > 0.0:
        noise = noise_rng.normal(0.0, noise_std, size=ranges.shape)
        noise[kind == NOTHING] = 0.0
        noise = np.maximum(noise, -ranges)  # a range never turns negative
        ranges += noise
        endpoints += scan.directions * noise[..., None]
    if dropout > 0.0:
        lost = dropout_rng.random(ranges.shape) < dropout
        ranges[lost] = r_max
        kind[lost] = NOTHING
        origins = np.broadcast_to(np.asarray(positions, dtype=np.float64)[:, None, :], endpoints.shape)
        endpoints[lost] = origins[lost] + scan.directions[lost] * r_max
    return Scan(directions=scan.directions, ranges=ranges, kind=kind, endpoints=endpoints)


def _check_step(step) -> int:
    if isinstance(step, bool) or not isinstance(step, (int, np.integer)):
        raise ValueError(f"step={step!r}: expected an integer simulation step")
    return int(step)


@numba.njit(cache=True)
def _rotate_fan(fan, angles, out):
    """out[n] = the fan (R, 3) rotated about z by angles[n]."""
    for n in range(angles.shape[0]):
        c, s = math.cos(angles[n]), math.sin(angles[n])
        for r in range(fan.shape[0]):
            out[n, r, 0] = c * fan[r, 0] - s * fan[r, 1]
            out[n, r, 1] = s * fan[r, 0] + c * fan[r, 1]
            out[n, r, 2] = fan[r, 2]


@numba.njit(cache=True, inline="always")
def _inset(x, key, res):
    """Clamp a coordinate into voxel ``key`` along one axis, a small margin inside its faces."""
    margin = _ENDPOINT_INSET * res
    return min(max(x, key * res + margin), (key + 1) * res - margin)


@numba.njit(cache=True)
def _cast_rays(occupied, key0, res, positions, dirs, r_max, uav_radius, ranges, kind, endpoints):
    """Fill ranges, kind and endpoints for every (UAV, ray); see ``RangeSensor.scan``."""
    nx, ny, nz = occupied.shape
    cells = occupied.reshape(nx * ny * nz)
    inv_res = 1.0 / res
    n_uav, n_ray = dirs.shape[0], dirs.shape[1]
    # The other UAVs a ray of UAV a can reach within r_max (1 m spare against rounding), in index order so
    # that ties go to the lower index: (offset from a, squared distance minus radius squared).
    near = np.empty((n_uav, 4))
    reach = (r_max + uav_radius + 1.0) ** 2
    for a in range(n_uav):
        ox, oy, oz = positions[a, 0], positions[a, 1], positions[a, 2]
        okx, oky, okz = coord_key(ox, inv_res), coord_key(oy, inv_res), coord_key(oz, inv_res)
        n_near = 0
        if uav_radius > 0.0:
            for b in range(n_uav):
                cx, cy, cz = positions[b, 0] - ox, positions[b, 1] - oy, positions[b, 2] - oz
                if b != a and cx * cx + cy * cy + cz * cz <= reach:
                    near[n_near, 0], near[n_near, 1], near[n_near, 2] = cx, cy, cz
                    near[n_near, 3] = cx * cx + cy * cy + cz * cz - uav_radius * uav_radius
                    n_near += 1
        for r in range(n_ray):
            dx, dy, dz = dirs[a, r, 0], dirs[a, r, 1], dirs[a, r, 2]
            # Nearest non-grid obstacle within r_max: another UAV, then the ground (which wins ties).
            t_lim = r_max
            lim_kind = NOTHING
            if uav_radius > 0.0:
                for b in range(n_near):
                    cx, cy, cz, c = near[b, 0], near[b, 1], near[b, 2], near[b, 3]
                    proj = cx * dx + cy * dy + cz * dz
                    if c <= 0.0:
                        t = 0.0  # inside the other UAV's sphere
                    else:
                        disc = proj * proj - c
                        if proj <= 0.0 or disc < 0.0:
                            continue
                        t = proj - math.sqrt(disc)
                    if t < t_lim:
                        t_lim = t
                        lim_kind = UAV
            ground = False
            if oz < 0.0 or dz < 0.0:
                t_ground = 0.0 if oz < 0.0 else -oz / dz
                if t_ground <= t_lim:
                    t_lim = t_ground
                    ground = True
            # First occupied grid voxel entered at a distance <= t_lim.
            kx, ky, kz = okx, oky, okz
            t_hit = -1.0
            i, j, k = kx - key0[0], ky - key0[1], kz - key0[2]
            if 0 <= i < nx and 0 <= j < ny and 0 <= k < nz and occupied[i, j, k]:
                t_hit = 0.0
            else:
                sx, tx, ddx = axis_setup(ox, dx, kx, res, 0.5 * res)
                sy, ty, ddy = axis_setup(oy, dy, ky, res, 0.5 * res)
                sz, tz, ddz = axis_setup(oz, dz, kz, res, 0.5 * res)
                while True:
                    axis = next_axis(tx, ty, tz)
                    if axis == 0:
                        t = tx
                        i += sx
                        tx += ddx
                    elif axis == 1:
                        t = ty
                        j += sy
                        ty += ddy
                    else:
                        t = tz
                        k += sz
                        tz += ddz
                    if t > t_lim:
                        break
                    if (i | j | k) >= 0 and i < nx and j < ny and k < nz and cells[(i * ny + j) * nz + k]:
                        t_hit = t
                        kx, ky, kz = i + key0[0], j + key0[1], k + key0[2]
                        break
            if t_hit >= 0.0 or ground:
                t = t_hit if t_hit >= 0.0 else t_lim
                px, py, pz = ox + dx * t, oy + dy * t, oz + dz * t
                if t_hit < 0.0:  # the ground voxel below the hit point
                    kx, ky, kz = coord_key(px, inv_res), coord_key(py, inv_res), -1
                ranges[a, r] = t
                kind[a, r] = STATIC
                endpoints[a, r, 0] = _inset(px, kx, res)
                endpoints[a, r, 1] = _inset(py, ky, res)
                endpoints[a, r, 2] = _inset(pz, kz, res)
            else:
                t = t_lim if lim_kind == UAV else r_max
                ranges[a, r] = t
                kind[a, r] = lim_kind
                endpoints[a, r, 0] = ox + dx * t
                endpoints[a, r, 1] = oy + dy * t
                endpoints[a, r, 2] = oz + dz * t
