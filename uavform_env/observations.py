"""The observation vector: a fixed layout of named, bounded float32 fields.

Every field is scaled into a documented range, so the Box bounds are honest and a user can pick
``obs[layout.slice("obstacle_histogram")]`` without counting offsets. The README's table is
generated from ``ObservationLayout.table()``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from gymnasium import spaces

from .config import EnvConfig
from .dynamics import PSI, VZ, W, V, Z
from .occupancy import MapArrays, MapStore, occupied_cells, voxel_logodds
from .polar_histogram import _primary_kernel, histogram_shape, weight_constants, width_steps


@dataclass(frozen=True)
class Field:
    name: str
    size: int
    low: float
    high: float
    meaning: str


class ObservationLayout:
    """The ordered fields of one agent's observation, derived from the config."""

    def __init__(self, cfg: EnvConfig):
        oc = cfg.observation
        k = oc.k_neighbours
        fields = [
            Field("ego", 6, -1.0, 1.0, "v/v_max, w/w_max, vz/vz_max, sin(psi), cos(psi), altitude scaled to [-1, 1] over [z_min, z_max]"),
            Field("target", 4, -1.0, 1.0, "goal (leader) or own slot (follower) in the body frame: dx, dy, dz, distance; each / target_clip, clipped"),
            Field("role", 3, -1.0, 1.0, "is_leader (0/1), sin and cos of the leader's yaw relative to own yaw"),
        ]
        if k:
            fields.append(Field("neighbours", 7 * k, -1.0, 1.0,
                                f"{k} nearest UAVs (broadcast states), each: dx, dy, dz / neighbour_range, "
                                "dvx, dvy, dvz / (2 v_max) in the body frame, mask (1 = present); nearest first, zero-padded"))
        if oc.include_histogram:
            n_e, n_z = histogram_shape(math.radians(oc.histogram_cell_deg))
            fields.append(Field("obstacle_histogram", n_e * n_z, 0.0, 1.0,
                                f"1 - exp(-H) of the 3D VFH+ primary polar histogram of the own map ({n_e} elevation x "
                                f"{n_z} azimuth cells of {oc.histogram_cell_deg:g} deg, azimuth from the own heading, "
                                f"radius {oc.histogram_radius:g} m), row-major from -90 deg elevation"))
        if oc.include_crop:
            n = oc.crop_cells * oc.crop_cells * oc.crop_cells_z
            fields.append(Field("map_crop", n, 0.0, 1.0,
                                f"occupancy probability (unknown = 0.5) of octree level {oc.crop_level}: a world-aligned "
                                f"{oc.crop_cells}x{oc.crop_cells}x{oc.crop_cells_z} block of cells centred on the UAV, x-major"))
        self.fields = tuple(fields)
        self._slices = {}
        start = 0
        for f in self.fields:
            self._slices[f.name] = slice(start, start + f.size)
            start += f.size
        self.size = start
        self.low = np.concatenate([np.full(f.size, f.low, np.float32) for f in self.fields])
        self.high = np.concatenate([np.full(f.size, f.high, np.float32) for f in self.fields])
        # what build_observations needs of the config on every step, worked out once
        self._own_columns = tuple(self._slices[name].start if name in self._slices else -1
                                  for name in ("ego", "target", "role", "neighbours"))
        self._histogram = None
        if oc.include_histogram:
            u = cfg.uav
            cell = math.radians(oc.histogram_cell_deg)
            r_e = u.r_uav + u.r_safe + cfg.map.resolution
            self._histogram = (float(oc.histogram_radius), float(r_e), cell, *histogram_shape(cell),
                               *weight_constants(2.0, oc.histogram_radius, r_e), width_steps(cell, False))

    def slice(self, name: str) -> slice:
        if name not in self._slices:
            raise KeyError(f"observation field {name!r} is not in this layout; fields: {list(self._slices)}")
        return self._slices[name]

    def space(self) -> spaces.Box:
        return spaces.Box(self.low.copy(), self.high.copy(), dtype=np.float32)

    def table(self) -> str:
        rows = ["| field | slice | range | meaning |", "|---|---|---|---|"]
        for f in self.fields:
            s = self._slices[f.name]
            rows.append(f"| `{f.name}` | {s.start}:{s.stop} | [{f.low:g}, {f.high:g}] | {f.meaning} |")
        return "\n".join(rows)


def build_observations(layout: ObservationLayout, cfg: EnvConfig, states: np.ndarray, targets: np.ndarray,
                       leader_index: int, broadcast: np.ndarray, maps: MapStore,
                       neighbour_ok: np.ndarray) -> np.ndarray:
    """Observations (N, size) float32 of all UAVs.

    ``states`` are the true own states, ``broadcast`` the neighbours' broadcast states (one cycle
    old), ``targets`` (N, 3) each UAV's goal or slot, ``maps`` the store of the onboard maps (map i
    is UAV i's), ``neighbour_ok`` (N,) which UAVs still broadcast (a removed UAV does not). The map
    features of all UAVs come from one numba call each. ``layout`` is ``ObservationLayout(cfg)``: the
    histogram's constants come from it.
    """
    u, oc = cfg.uav, cfg.observation
    n = states.shape[0]
    out = np.zeros((n, layout.size), np.float32)
    states = np.ascontiguousarray(states, dtype=np.float64)
    _own_features(out, *layout._own_columns, states, np.ascontiguousarray(targets, dtype=np.float64), leader_index,
                  np.ascontiguousarray(broadcast, dtype=np.float64), np.ascontiguousarray(neighbour_ok, dtype=np.bool_),
                  oc.k_neighbours, float(oc.neighbour_range), float(u.v_max), float(u.w_max), float(u.vz_max),
                  float(u.z_min), float(u.z_max), float(oc.target_clip))
    if layout._histogram is not None:
        radius, r_e, cell, n_e, n_z, a, b, steps = layout._histogram
        h = np.zeros((n, n_e, n_z))
        leaves = maps.levels[0]
        _histograms(leaves.tables, leaves.values, leaves.bits, leaves.counts, leaves.key0, leaves.shape, maps.res,
                    np.ascontiguousarray(states[:, :3]), np.ascontiguousarray(states[:, PSI]), radius, r_e, cell, n_e,
                    n_z, a, b, steps, h)
        out[:, layout.slice("obstacle_histogram")] = -np.expm1(-h.reshape(n, -1))
    if oc.include_crop:
        out[:, layout.slice("map_crop")] = map_crops(maps, states[:, :3], oc.crop_level, oc.crop_cells,
                                                     oc.crop_cells_z).reshape(n, -1)
    np.minimum(np.maximum(out, layout.low, out=out), layout.high, out=out)  # np.clip without its wrapper's cost
    return out


@numba.njit(cache=True, inline="always")
def _body_x(dx, dy, c, s):
    """x of a world-frame horizontal vector in a body frame whose yaw has cosine c and sine s."""
    return c * dx + s * dy


@numba.njit(cache=True, inline="always")
def _body_y(dx, dy, c, s):
    """y of a world-frame horizontal vector in a body frame whose yaw has cosine c and sine s."""
    return -s * dx + c * dy


@numba.njit(cache=True)
def _own_features(out, ego, tgt, role, nbr, states, targets, leader, broadcast, neighbour_ok, k, rng_max, v_max, w_max,
                  vz_max, z_min, z_max, target_clip):
    """The ego, target, role and neighbour fields of every UAV (starting at columns ``ego``, ``tgt``,
    ``role`` and ``nbr``; nbr < 0: no neighbour field); see ``ObservationLayout`` for their meaning."""
    n = states.shape[0]
    near = np.empty(max(k, 1), np.int64)
    near_d = np.empty(max(k, 1))
    for i in range(n):
        psi = states[i, PSI]
        c, s = math.cos(psi), math.sin(psi)
        out[i, ego] = states[i, V] / v_max
        out[i, ego + 1] = states[i, W] / w_max
        out[i, ego + 2] = states[i, VZ] / vz_max if vz_max > 0 else 0.0
        out[i, ego + 3] = s
        out[i, ego + 4] = c
        out[i, ego + 5] = 2.0 * (states[i, Z] - z_min) / (z_max - z_min) - 1.0
        dx, dy, dz = targets[i, 0] - states[i, 0], targets[i, 1] - states[i, 1], targets[i, 2] - states[i, 2]
        out[i, tgt] = _body_x(dx, dy, c, s) / target_clip
        out[i, tgt + 1] = _body_y(dx, dy, c, s) / target_clip
        out[i, tgt + 2] = dz / target_clip
        out[i, tgt + 3] = math.sqrt(dx * dx + dy * dy + dz * dz) / target_clip
        dpsi = broadcast[leader, PSI] - psi
        out[i, role] = 1.0 if i == leader else 0.0
        out[i, role + 1] = math.sin(dpsi)
        out[i, role + 2] = math.cos(dpsi)
        if nbr < 0:
            continue
        # the k nearest broadcasting UAVs within rng_max, nearest first (ties: lower index first)
        m = 0
        for j in range(n):
            if j == i or not neighbour_ok[j]:
                continue
            rx, ry, rz = broadcast[j, 0] - states[i, 0], broadcast[j, 1] - states[i, 1], broadcast[j, 2] - states[i, 2]
            d = math.sqrt(rx * rx + ry * ry + rz * rz)
            if d > rng_max:
                continue
            slot = min(m, k)
            while slot > 0 and near_d[slot - 1] > d:
                slot -= 1
            if slot < k:
                for q in range(min(m, k - 1), slot, -1):
                    near[q], near_d[q] = near[q - 1], near_d[q - 1]
                near[slot], near_d[slot] = j, d
                m += 1
        vx, vy = states[i, V] * math.cos(psi), states[i, V] * math.sin(psi)
        for slot in range(min(m, k)):
            j = near[slot]
            col = nbr + 7 * slot
            rx, ry, rz = broadcast[j, 0] - states[i, 0], broadcast[j, 1] - states[i, 1], broadcast[j, 2] - states[i, 2]
            ux = broadcast[j, V] * math.cos(broadcast[j, PSI]) - vx
            uy = broadcast[j, V] * math.sin(broadcast[j, PSI]) - vy
            uz = broadcast[j, VZ] - states[i, VZ]
            out[i, col] = _body_x(rx, ry, c, s) / rng_max
            out[i, col + 1] = _body_y(rx, ry, c, s) / rng_max
            out[i, col + 2] = rz / rng_max
            out[i, col + 3] = _body_x(ux, uy, c, s) / (2.0 * v_max)
            out[i, col + 4] = _body_y(ux, uy, c, s) / (2.0 * v_max)
            out[i, col + 5] = uz / (2.0 * v_max)
            out[i, col + 6] = 1.0

@numba.njit(cache=True)
def _histograms(tables, values, bits, counts, key0, shape, res, positions, psi, radius, r_e, cell, n_e, n_z, a, b,
                steps, out):
    """out[m] += the body-frame primary polar histogram (``ceil_2d``, ``steps`` its ``width_steps``) of map m's
    occupied voxels within ``radius``."""
    for m in range(positions.shape[0]):
        centres, probs = occupied_cells(tables, values, bits, counts, m, key0, shape, res, positions[m], radius, False)
        _primary_kernel(centres, probs, np.full(probs.shape[0], r_e), positions[m], cell, n_e, n_z, radius, a, b,
                        False, steps, psi[m], out[m])


def map_crops(maps: MapStore, centers: np.ndarray, level: int, cells: int, cells_z: int) -> np.ndarray:
    """Occupancy probabilities (N, cells, cells, cells_z) of a world-aligned block of octree-level cells
    around each map i's ``centers[i]``.

    Unknown cells read 0.5; cells outside the map read 0.5 as well (nothing is known there).
    """
    n = centers.shape[0]
    lv = maps.level_blocks(level, np.arange(n))
    lvl_res = maps.res * 2 ** level
    idx = np.floor((np.asarray(centers) - lv.key0 * lvl_res) / lvl_res).astype(np.int64)
    lo = idx - np.array([cells // 2, cells // 2, cells_z // 2])
    out = np.empty((n, cells, cells, cells_z), np.float32)
    _gather(lv.tables, lv.values, lv.key0, lv.shape, lo, out)
    prob = 1.0 / (1.0 + np.exp(-out))
    return np.where(np.isnan(out), 0.5, prob).astype(np.float32)


@numba.njit(cache=True)
def _gather(tables, values, key0, shape, lo, out):
    """out[m] = map m's log-odds of the cells lo[m] + (0..) (NaN where unknown or outside)."""
    for m in range(out.shape[0]):
        arrays = MapArrays(key0, shape, tables[0][m], tables[1], values)
        for i in range(out.shape[1]):
            for j in range(out.shape[2]):
                for k in range(out.shape[3]):
                    out[m, i, j, k] = voxel_logodds(arrays, lo[m, 0] + i, lo[m, 1] + j, lo[m, 2] + k)
