"""Which UAVs touched an obstacle, another UAV or the geofence in a step: one numba call for all UAVs.

A crash cause is an index into ``CRASH_CAUSES`` (the env's info "crash_cause"): an obstacle (clearance < 0) wins
over the geofence (outside the x/y bounds), which wins over another UAV (centres too close).
"""

from __future__ import annotations

import math

import numba
import numpy as np

CRASH_CAUSES = ("none", "obstacle", "uav", "geofence")
NONE, OBSTACLE, UAV, GEOFENCE = range(len(CRASH_CAUSES))


@numba.njit(cache=True)
def _separations(positions, out):
    """out[i] = distance from UAV i to its nearest other UAV (+inf alone)."""
    n = positions.shape[0]
    for i in range(n):
        best = np.inf
        for j in range(n):
            if j != i:
                dx = positions[i, 0] - positions[j, 0]
                dy = positions[i, 1] - positions[j, 1]
                dz = positions[i, 2] - positions[j, 2]
                best = min(best, math.sqrt(dx * dx + dy * dy + dz * dz))
        out[i] = best


def separations(positions: np.ndarray) -> np.ndarray:
    """Distance (N,) from every UAV (positions (N, 3), or state rows as in ``contacts``) to its nearest other UAV;
    +inf for a lone UAV."""
    out = np.empty(positions.shape[0])
    _separations(np.ascontiguousarray(positions, dtype=np.float64), out)
    return out


@numba.njit(cache=True)
def _contacts(positions, clearance, lo, hi, min_separation, active, separation, cause):
    _separations(positions, separation)
    hit = False
    for i in range(positions.shape[0]):
        cause[i] = NONE
        if not active[i]:
            continue
        x, y = positions[i, 0], positions[i, 1]
        if clearance[i] < 0.0:
            cause[i] = OBSTACLE
        elif x < lo[0] or y < lo[1] or x > hi[0] or y > hi[1]:
            cause[i] = GEOFENCE
        elif separation[i] < min_separation:
            cause[i] = UAV
        hit |= cause[i] != NONE
    return hit


def contacts(positions: np.ndarray, clearance: np.ndarray, lo: np.ndarray, hi: np.ndarray, min_separation: float,
             active: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool]:
    """(separation (N,), cause (N,) int64, whether any active UAV crashed) for UAVs at ``positions`` (N, 3), or
    state rows (N, >= 3) whose first three columns are the position.

    ``clearance`` (N,) is each UAV's distance to the nearest obstacle surface minus its radius; ``lo``, ``hi``
    are the world's bounds (only x and y are a geofence); UAVs closer than ``min_separation`` collide. The cause
    of an inactive UAV is NONE (it crashed earlier, or was never flying)."""
    n = positions.shape[0]
    separation, cause = np.empty(n), np.empty(n, np.int64)
    hit = _contacts(np.ascontiguousarray(positions, dtype=np.float64), np.ascontiguousarray(clearance, np.float64),
                    np.ascontiguousarray(lo, np.float64), np.ascontiguousarray(hi, np.float64), float(min_separation),
                    np.ascontiguousarray(active, np.bool_), separation, cause)
    return separation, cause, bool(hit)
