"""Episode metrics of spec (h1), computed from an env's recorded history.

One function, ``episode_metrics``, used by ``uavform fly``, the leaderboard and the experiments, so
every number in every table is computed the same way. All values are plain floats (NaN where a
metric does not apply), so results serialise to JSON without special cases.
"""

from __future__ import annotations

import math

import numpy as np

from .dynamics import wrap_all
from .env import CRASH_CAUSES, END_REASONS
from .scenarios import cannot_stand

METRIC_NAMES = (
    "success", "collision", "timeout", "flight_time", "path_length_leader", "path_length_mean", "min_clearance",
    "min_separation", "formation_error_rms", "formation_error_max", "time_to_reform", "total_turning",
    "total_turning_mean", "direction_sign_changes", "altitude_deviation_max", "planning_ms_median", "planning_ms_p95",
)


def _path_lengths(positions: np.ndarray) -> np.ndarray:
    """How far each UAV flew (N,): the summed step lengths of its track in ``positions`` (T+1, N, 3)."""
    return np.linalg.norm(np.diff(positions, axis=0), axis=2).sum(axis=0)


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

    path = _path_lengths(pos)
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


# A time-out is "stuck" when the leader moved less than STUCK_DISTANCE (m) in the last STUCK_SECONDS (s).
STUCK_SECONDS = 30.0
STUCK_DISTANCE = 1.0
# A follower left off its slot "stood still" when it stayed within STILL_DISTANCE (m) of where it ended for at
# least STILL_SECONDS (s) before the end.
STILL_SECONDS = 5.0
STILL_DISTANCE = 0.3
_CRASHED_INTO = {"obstacle": "an obstacle", "geofence": "the edge of the world (left its x/y bounds)"}


def _slot_standing(env, k: int) -> str:
    """Whether UAV k's slot at the leader's final state is a place a UAV can stand (``scenarios.cannot_stand``:
    inside the bounds and the altitude band, r_uav + r_safe from every obstacle), said from the true world."""
    slot = env.true_slots()[k:k + 1]
    bad, describe = cannot_stand(env.scenario, env.config.uav, env.world, slot)
    if bad[0]:
        return f"its slot {describe(0)}"
    clearance = float(env.world.clearance(slot)[0])
    return "its slot is clear" + (f" ({clearance:.1f} m from the nearest obstacle)" if math.isfinite(clearance) else "")


def _still_for(track: np.ndarray, dt: float) -> float:
    """How long (s) before the end of ``track`` (T, 3) its UAV had stayed within STILL_DISTANCE of where it ended."""
    moved = np.flatnonzero(np.linalg.norm(track - track[-1], axis=1) >= STILL_DISTANCE)
    return (len(track) - 1 - (int(moved[-1]) if moved.size else 0)) * dt


def episode_outcome(env) -> tuple[str, str]:
    """Why the episode ended: (one of ``END_REASONS``, a sentence saying why).

    A crash names the first UAV to crash, what it hit and when; a time-out says whether the leader
    reached the goal but a follower did not reach its slot (whether that slot, at the leader's final state, is
    clear or why a UAV cannot stand there, and whether the follower stood still at the end: within STILL_DISTANCE
    of where it ended for STILL_SECONDS or more), whether the leader reached the goal (came within
    r_goal) but ended outside it (carried off, or it rested beside it), whether the leader was stuck (moved less
    than STUCK_DISTANCE in the last STUCK_SECONDS), or that the step limit simply ran out (and how far the leader
    flew, at what mean speed). An episode still running (or cut short by the caller) is "running".
    """
    reason = END_REASONS[env.end_reason]
    dt = env.config.uav.dt
    names = [f"uav_{i} ({'leader' if i == 0 else f'follower {i}'})" for i in range(env.n_uavs)]
    if reason.startswith("crash"):
        crashed = np.asarray(env.history["crashed"])  # (T+1, N)
        step = int(np.flatnonzero(crashed.any(axis=1))[0])
        first = np.flatnonzero(crashed[step])
        pos = np.asarray(env.history["positions"][step])

        def into(i):
            cause = CRASH_CAUSES[env.crash_cause[i]]
            if cause != "uav":
                return _CRASHED_INTO[cause]
            gaps = np.linalg.norm(pos - pos[i], axis=1)
            gaps[i] = np.inf
            return names[int(np.argmin(gaps))]

        what = ", ".join(f"{names[i]} crashed into {into(i)}" for i in first)
        later = int(crashed[-1].sum()) - len(first)
        return reason, (f"{what} at step {step} (t = {step * dt:.1f} s)"
                        + (f"; {later} more crashed later" if later else ""))
    if reason == "timeout":
        track = np.asarray(env.history["positions"])
        pos = track[:, 0]  # the leader's
        window = max(1, round(STUCK_SECONDS / dt))
        moved = float(np.linalg.norm(pos[-1] - pos[-1 - window])) if len(pos) > window else math.inf
        ferr = np.asarray(env.history["formation_error"][-1], dtype=np.float64)
        r_goal = env.config.episode.r_goal
        to_goal = np.linalg.norm(pos - env.goal, axis=1)
        if to_goal[-1] < r_goal and len(ferr) > 1:
            k = int(np.argmax(ferr[1:])) + 1
            still = _still_for(track[:, k], dt)
            motion = (f"it had stood within {STILL_DISTANCE:g} m of there for the last {still:.0f} s"
                      if still >= STILL_SECONDS else "it was still moving")
            return reason, (f"the leader reached the goal but {names[k]} ended {ferr[k]:.1f} m from its slot "
                            f"(e_f = {env.config.formation.e_f:g} m): {_slot_standing(env, k)}; {motion}")
        reached = np.flatnonzero(to_goal < r_goal)
        if to_goal[-1] >= r_goal and reached.size:
            return reason, (f"the leader reached the goal at t = {reached[0] * dt:.1f} s but ended {to_goal[-1]:.1f} m "
                            f"from it (r_goal = {r_goal:g} m)")
        if moved < STUCK_DISTANCE:
            return reason, f"stuck: the leader moved {moved:.2f} m in the last {STUCK_SECONDS:g} s"
        flown = float(_path_lengths(track)[0])
        return reason, (f"the step limit ({env.max_cycles} steps) ran out; the leader flew {flown:.1f} m, "
                        f"{flown / max(len(pos) - 1, 1) / dt:.2f} m/s on average")
    return reason, ""
