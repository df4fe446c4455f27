"""The vertical decision of spec (g4) that both fusion planners (``baselines.paper``, ``baselines.fusion``) make:
its three modes and the per-UAV state it and the A* path keep between cycles."""

from __future__ import annotations

from dataclasses import dataclass, field

from .astar import GlobalPath
from .vfh3d import VFHState

LEVEL, CLIMB, BLOCKED = "level", "climb", "blocked"


@dataclass
class PlannerMemory:
    """What one UAV's fusion planner keeps between cycles: 3D VFH+'s hysteresis, the debounced mode (g4), the
    time without an admissible DWA sample, the last alignment and the A* path with its replan count."""

    vfh: VFHState = field(default_factory=VFHState)
    mode: str = LEVEL
    pending: str = LEVEL
    pending_count: int = 0
    stuck_time: float = 0.0
    prev_alignment: float = 1.0
    path: GlobalPath | None = None
    path_found: bool = True
    replans: int = 0
