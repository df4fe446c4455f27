"""The simplest baselines: hover in place, random commands, and an artificial potential field (APF) formation.

APF is the method the paper's introduction compares against: an attractive pull toward the goal
(leader) or the own slot (followers), repulsion from occupied voxels of the own map and from
neighbours, turned into (v, w, vz) by a heading controller. It knows no dynamic window, which is
exactly its documented weakness.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from uavform_env.config import Config, in_range
from uavform_env.dynamics import PSI, wrap

from .policy import OnboardPolicy


class Hover(OnboardPolicy):
    """Stop and hold: zero speed, zero yaw rate, zero climb."""

    def command(self, view) -> np.ndarray:
        return np.zeros(3)


class Random(OnboardPolicy):
    """Uniform random commands within the limits (seeded by reset)."""

    def act(self, observations, env):
        base = getattr(env, "unwrapped", env)
        return {a: self.rng.uniform(-1, 1, 3).astype(np.float32) for a in base.agents}


@dataclass(frozen=True)
class APFConfig(Config):
    k_att: float = 1.0
    k_rep: float = 1.5
    d0: float = 2.5          # obstacle influence distance (m)
    k_uu: float = 2.0
    d0_uu: float = 1.5       # neighbour influence distance (m)
    k_psi: float = 1.5       # heading gain (1/s)
    k_z: float = 0.5         # altitude gain (1/s)

    BOUNDS: ClassVar[dict] = {name: in_range(0.0) for name in ("k_att", "k_rep", "d0", "k_uu", "d0_uu", "k_psi", "k_z")}


class APF(OnboardPolicy):
    """Artificial potential field formation (leader to the goal, followers to their slots)."""

    def __init__(self, config: APFConfig | None = None):
        self.config = config or APFConfig()

    def command(self, view) -> np.ndarray:
        c, lim = self.config, view.limits
        p = view.state[:3]
        target = view.goal if view.is_leader else view.slot
        to_t = target - p
        dist = float(np.linalg.norm(to_t))
        force = c.k_att * to_t / max(dist, 1.0)
        centres, _ = view.occupancy.occupied_in_sphere(p, c.d0 + lim.r_uav)
        force += _repulsion(p, centres, c.d0, c.k_rep, lim.r_uav)
        force += _repulsion(p, view.neighbour_states[:, :3], c.d0_uu, c.k_uu, 2 * lim.r_uav)
        heading = math.atan2(force[1], force[0])
        err = wrap(heading - view.state[PSI])
        horizontal = math.hypot(force[0], force[1])
        v = lim.v_max * min(1.0, horizontal) * max(0.0, math.cos(err))
        if view.is_leader and dist < 1.0:
            v *= dist
        w = float(np.clip(c.k_psi * err, -lim.w_max, lim.w_max))
        vz = float(np.clip(c.k_z * (view.z_ref - p[2]) + force[2], -lim.vz_max, lim.vz_max))
        return np.array([v, w, vz])


def _repulsion(p: np.ndarray, points: np.ndarray, d0: float, k: float, inflate: float) -> np.ndarray:
    """Khatib's repulsive force sum over ``points`` closer than d0 (distances measured from the inflated surface)."""
    if len(points) == 0:
        return np.zeros(3)
    diff = p - points
    d = np.linalg.norm(diff, axis=1)
    surf = np.maximum(d - inflate, 1e-2)
    near = surf < d0
    if not near.any():
        return np.zeros(3)
    mag = k * (1.0 / surf[near] - 1.0 / d0) / surf[near] ** 2
    return (mag[:, None] * diff[near] / d[near, None]).sum(axis=0) / max(1, near.sum()) ** 0.5
