"""Episode metrics of spec (h1), computed from an env's recorded history.

One function, ``episode_metrics``, used by ``uavform fly``, the leaderboard and the experiments, so
every number in every table is computed the same way. All values are plain floats (NaN where a
metric does not apply), so results serialise to JSON without special cases.
"""

from __future__ import annotations

import math

import numpy as np

from .dynamics import wrap_all

METRIC_NAMES = (
    "success", "collision", "timeout", "flight_time", "path_length_leader", "path_length_mean", "min_clearance",
    "min_separation", "formation_error_rms", "formation_error_max", "time_to_reform", "total_turning",
    "total_turning_mean", "direction_sign_changes", "altitude_deviation_max", "planning_ms_median", "planning_ms_p95",
)


def episode_metrics(env, planning_seconds: np.ndarray | None = None, break_threshold: float = 1.0,
                    near_goal_radius: float | None = None) -> dict:
    """Metrics of the episode the env just played.

    Args:
        env: the unwrapped ``FormationEnv`` after the episode (its ``history`` is read).
        planning_seconds: the policy's compute time per UAV-step (one entry per step), if measured.
        break_threshold: a formation counts as broken while some follower is farther than this from its slot;
            ``time_to_reform`` is the time from the last break until every follower is within ``e_f`` again.
        near_goal_radius: where direction sign changes are counted (default v_max * T_p = 3 m, spec R_sw).
    """
    h = env.history
    cfg = env.config
    dt = cfg.uav.dt
    pos = np.asarray(h["positions"])            # (T+1, N, 3)
    yaw = np.asarray(h["yaw"])
    w = np.asarray(h["w"])
    ferr = np.asarray(h["formation_error"])     # (T+1, N)
    clear = np.asarray(h["clearance"])
    crashed = np.asarray(h["crashed"])
    steps = pos.shape[0] - 1
    n = pos.shape[1]

    seg = np.linalg.norm(np.diff(pos, axis=0), axis=2)          # (T, N)
    path = seg.sum(axis=0)
    turning = np.abs(wrap_all(np.diff(yaw, axis=0))).sum(axis=0)
    if n > 1:
        d = np.linalg.norm(pos[:, :, None, :] - pos[:, None, :, :], axis=3)
        iu = np.triu_indices(n, 1)
        min_sep = float(d[:, iu[0], iu[1]].min())
    else:
        min_sep = math.nan

    followers = ferr[:, 1:]
    if n > 1:
        rms = float(np.sqrt(np.mean(followers ** 2)))
        fmax = float(followers.max())
        broken = followers.max(axis=1) > break_threshold
        if broken.any():
            last_break = int(np.flatnonzero(broken)[-1])
            closed = np.flatnonzero(followers[last_break:].max(axis=1) < cfg.formation.e_f)
            reform = float(closed[0] * dt) if closed.size else math.nan
        else:
            reform = 0.0
    else:
        rms = fmax = reform = math.nan

    r_near = near_goal_radius if near_goal_radius is not None else cfg.uav.v_max * 3.0
    goal = np.asarray(env.goal)
    near = np.linalg.norm(pos[1:, 0, :2] - goal[:2], axis=1) < r_near
    w_lead = w[1:, 0]
    sig = np.sign(np.where(np.abs(w_lead) > math.radians(1.0), w_lead, 0.0))
    sig_near = sig[near & (sig != 0)]
    sign_changes = int(np.count_nonzero(np.diff(sig_near) != 0)) if sig_near.size > 1 else 0

    success = bool(env.success)
    collision = bool(crashed[-1].any())
    plan = np.asarray(planning_seconds if planning_seconds is not None else [], dtype=float) * 1e3
    return {
        "success": float(success),
        "collision": float(collision),
        "timeout": float(not success and not collision and steps >= env.max_cycles),
        "flight_time": steps * dt,
        "path_length_leader": float(path[0]),
        "path_length_mean": float(path.mean()),
        "min_clearance": float(clear.min()),
        "min_separation": min_sep,
        "formation_error_rms": rms,
        "formation_error_max": fmax,
        "time_to_reform": reform,
        "total_turning": float(turning[0]),
        "total_turning_mean": float(turning.mean()),
        "direction_sign_changes": float(sign_changes),
        "altitude_deviation_max": float(np.abs(pos[:, :, 2] - cfg.formation.z_ref).max()),
        "planning_ms_median": float(np.median(plan)) if plan.size else math.nan,
        "planning_ms_p95": float(np.percentile(plan, 95)) if plan.size else math.nan,
    }
