"""Per-agent reward, a documented sum of configurable terms (README, "Rewards").

r_i = progress * (d_i,prev - d_i)          progress toward the own target (goal or slot)
    - formation * e_i                      formation error of a follower (0 for the leader)
    - collision * [crashed this step]
    - smoothness * |a_i - a_i,prev|^2      change of the normalised action
    - time                                 per step
    + success * [mission accomplished this step]
A UAV that crashed earlier gets 0.
"""

from __future__ import annotations

import numpy as np

from .config import RewardConfig


def compute_rewards(cfg: RewardConfig, prev_target_dist: np.ndarray, target_dist: np.ndarray,
                    formation_err: np.ndarray, is_follower: np.ndarray, crashed_now: np.ndarray,
                    was_active: np.ndarray, actions: np.ndarray, prev_actions: np.ndarray, success: bool) -> np.ndarray:
    """Rewards (N,) for one step; all inputs are arrays over UAVs."""
    r = cfg.progress * (prev_target_dist - target_dist)
    r -= cfg.formation * formation_err * is_follower
    r -= cfg.smoothness * np.sum((actions - prev_actions) ** 2, axis=1)
    r -= cfg.time
    r -= cfg.collision * crashed_now
    if success:
        r += cfg.success
    return np.where(was_active, r, 0.0)
