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

import numba
import numpy as np

from .config import RewardConfig


def compute_rewards(cfg: RewardConfig, prev_target_dist: np.ndarray, target_dist: np.ndarray,
                    formation_err: np.ndarray, is_follower: np.ndarray, crashed_now: np.ndarray,
                    was_active: np.ndarray, actions: np.ndarray, prev_actions: np.ndarray, success: bool) -> np.ndarray:
    """Rewards (N,) for one step; all inputs are arrays over UAVs, one numba call.

    The action change is summed in the actions' dtype (float32 in the env) and weighted by ``smoothness`` as
    numpy weighs an array of that dtype (a Python float keeps float32)."""
    dtype = np.result_type(actions, prev_actions, np.float32)  # float32 or float64, as numpy would subtract them
    actions, prev = np.ascontiguousarray(actions, dtype=dtype), np.ascontiguousarray(prev_actions, dtype=dtype)
    out = np.empty(actions.shape[0])
    _rewards(float(cfg.progress), float(cfg.formation), float(cfg.collision), cfg.smoothness * dtype.type(1),
             float(cfg.time), float(cfg.success), bool(success), _f64(prev_target_dist), _f64(target_dist),
             _f64(formation_err), np.ascontiguousarray(is_follower, np.bool_), _f64(crashed_now),
             np.ascontiguousarray(was_active, np.bool_), actions, prev, out)
    return out


def _f64(a) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64)


@numba.njit(cache=True)
def _rewards(progress, formation, collision, smoothness, time, bonus, success, prev_dist, dist, ferr, is_follower,
             crashed_now, was_active, actions, prev_actions, out):
    for i in range(out.shape[0]):
        if not was_active[i]:
            out[i] = 0.0
            continue
        d = actions[i, 0] - prev_actions[i, 0]
        change = d * d  # in the actions' dtype, summed left to right as numpy sums a short row
        for k in range(1, actions.shape[1]):
            d = actions[i, k] - prev_actions[i, k]
            change += d * d
        r = progress * (prev_dist[i] - dist[i])
        r -= formation * ferr[i] * (1.0 if is_follower[i] else 0.0)
        r -= smoothness * change
        r -= time
        r -= collision * crashed_now[i]
        if success:
            r += bonus
        out[i] = r
