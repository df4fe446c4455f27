"""What one UAV can know on board: the read-only view that policies (the expert included) act on.

It holds the UAV's own state, its goal and formation slot, its own occupancy map, the neighbours'
broadcast states (one cycle old, as over a radio link) and the prior 2.5D map; never the ground
truth. Arrays are read-only and the map view refuses updates.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .config import EnvConfig, UAVLimits


@dataclass(frozen=True)
class PriorMap:
    """Prior 2.5D knowledge: top height of obstacles per cell (``kind="none"``: all zero, unknown world)."""

    origin: np.ndarray
    resolution: float
    heights: np.ndarray
    kind: str


@dataclass(frozen=True)
class OnboardView:
    agent: str
    index: int
    is_leader: bool
    state: np.ndarray            # own (x, y, z, psi, v, w, vz)
    goal: np.ndarray             # mission goal (the leader broadcasts it)
    slot: np.ndarray             # own slot from the leader's broadcast pose (the goal for the leader)
    slot_offset: np.ndarray      # own offset in the leader's body frame
    offsets: np.ndarray          # all offsets (N, 3)
    z_ref: float
    slot_altitude: str           # slots at z_ref + dz ("z_ref") or at the leader's altitude + dz ("leader")
    leader_state: np.ndarray     # leader's broadcast state (its true state for the leader itself)
    neighbour_ids: np.ndarray    # indices of the other UAVs
    neighbour_states: np.ndarray  # their broadcast states (K, 7)
    neighbour_alive: np.ndarray  # whether each still flies
    occupancy: object            # own OccupancyMap, read-only
    prior: PriorMap
    limits: UAVLimits
    config: EnvConfig
    step: int
    bounds_lo: np.ndarray
    bounds_hi: np.ndarray
    crashed: bool
