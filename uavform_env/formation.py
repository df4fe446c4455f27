"""Formation geometry of spec (g1): slot offsets in the leader's body frame and formation error.

wedge, line and column extend to any N (one more pair per rank); diamond holds at most 4 UAVs and
triangle at most 3, as in the spec's table.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from .config import FORMATION_SHAPES, SLOT_ALTITUDES

MAX_UAVS = {"wedge": None, "diamond": 4, "triangle": 3, "line": None, "column": None}


def slot_offsets(shape: str, n_uavs: int, spacing: float) -> np.ndarray:
    """Offsets (n, 3) of every UAV's slot in the leader's body frame (x fwd, y left, z up); row 0 is the leader."""
    if shape not in FORMATION_SHAPES:
        raise ValueError(f"formation shape {shape!r}: expected one of {list(FORMATION_SHAPES)}")
    if isinstance(n_uavs, bool) or not isinstance(n_uavs, (int, np.integer)) or n_uavs < 1:
        raise ValueError(f"n_uavs={n_uavs!r}: expected an integer >= 1")
    cap = MAX_UAVS[shape]
    if cap is not None and n_uavs > cap:
        raise ValueError(f"n_uavs={n_uavs} is too many for formation {shape!r}, which holds at most {cap} UAVs")
    if not spacing > 0:
        raise ValueError(f"spacing={spacing!r}: expected a positive number")
    s = float(spacing)
    out = np.zeros((n_uavs, 3))
    for j in range(1, n_uavs):
        rank, side = (j + 1) // 2, (1.0 if j % 2 else -1.0)
        if shape == "wedge":
            out[j, :2] = (-rank * s, side * rank * s)
        elif shape == "line":
            out[j, :2] = (0.0, side * rank * s)
        elif shape == "column":
            out[j, :2] = (-j * s, 0.0)
        elif shape == "triangle":
            out[j, :2] = (-s, side * s)
        else:  # diamond: two flanks, then the tail
            out[j, :2] = (-s, side * s) if j < 3 else (-2 * s, 0.0)
    return out


def slot_positions(leader_xy: np.ndarray, leader_yaw: float, offsets: np.ndarray, z_ref: float) -> np.ndarray:
    """World positions (n, 3) of the slots: p_L + R_z(psi_L) [dx, dy], at altitude z_ref + dz."""
    c, s = np.cos(leader_yaw), np.sin(leader_yaw)
    out = np.empty((offsets.shape[0], 3))
    _slot_rows(float(leader_xy[0]), float(leader_xy[1]), float(z_ref), float(c), float(s),
               np.ascontiguousarray(offsets, dtype=np.float64), out)
    return out


@numba.njit(cache=True)
def slot_xy(x, y, c, s, dx, dy):
    """The slot rotation, written once: (x, y) + R_z(psi) [dx, dy] for a heading of cosine ``c`` and sine ``s``
    (numba kernels that need one slot call it in their loops)."""
    return x + c * dx - s * dy, y + s * dx + c * dy


@numba.njit(cache=True)
def _slot_rows(x, y, z, c, s, offsets, out):
    for i in range(offsets.shape[0]):
        out[i, 0], out[i, 1] = slot_xy(x, y, c, s, offsets[i, 0], offsets[i, 1])
        out[i, 2] = z + offsets[i, 2]


def formation_slots(leader_position, leader_yaw: float, offsets: np.ndarray, z_ref: float,
                    slot_altitude: str = "z_ref") -> np.ndarray:
    """World positions (n, 3) of the slots of a leader at ``leader_position`` (x, y, z) with yaw ``leader_yaw``.

    The one place that decides slot altitudes (env, onboard view, observations): ``slot_altitude``
    "z_ref" puts every slot at z_ref + dz (version-1 missions), "leader" at the leader's altitude + dz.
    """
    if slot_altitude not in SLOT_ALTITUDES:
        raise ValueError(f"slot_altitude={slot_altitude!r}: expected one of {list(SLOT_ALTITUDES)}")
    z = leader_position[2] if slot_altitude == "leader" else z_ref
    return slot_positions(leader_position[:2], leader_yaw, offsets, z)


def slot_distances(positions: np.ndarray, slots: np.ndarray, goal) -> tuple[np.ndarray, np.ndarray]:
    """(formation errors (n,), target distances (n,)) of UAVs at ``positions`` (n, 3), or state rows (n, >= 3)
    whose first three columns are the position: each UAV's 3D distance to its slot, and to its target (its slot
    for a follower, ``goal`` for the leader, row 0)."""
    n = slots.shape[0]
    ferr, target = np.empty(n), np.empty(n)
    _slot_distances(np.ascontiguousarray(positions, dtype=np.float64), np.ascontiguousarray(slots, dtype=np.float64),
                    np.ascontiguousarray(goal, dtype=np.float64), ferr, target)
    return ferr, target


@numba.njit(cache=True)
def _slot_distances(positions, slots, goal, ferr, target):
    for i in range(slots.shape[0]):
        dx, dy, dz = positions[i, 0] - slots[i, 0], positions[i, 1] - slots[i, 1], positions[i, 2] - slots[i, 2]
        ferr[i] = math.sqrt(dx * dx + dy * dy + dz * dz)
        if i == 0:
            dx, dy, dz = positions[0, 0] - goal[0], positions[0, 1] - goal[1], positions[0, 2] - goal[2]
        target[i] = math.sqrt(dx * dx + dy * dy + dz * dz)
