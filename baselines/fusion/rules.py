"""The fusion expert's command rules: what overrides DWA's choice, in the order ``RULES`` applies them.

After DWA each UAV's command is a ``Command`` record; every rule reads the cycle's facts (``Cycle``)
and may change the record. The order is the control law: a later rule overrides an earlier one
(the emergency escape of (g5) has the last word). Each rule names the spec item or [X] field it
implements; the fields are documented in ``ExpertConfig``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from uavform_env.dynamics import PSI, V, VZ, W, integrate, wrap

from ..vfh3d import vertical_escape
from .kernels import braking_arc_clearance, closest_approach, nearest_live


@dataclass
class Command:
    """One UAV's command (v, w, vz) while the rules act on it; ``turning``: a turn-in-place rule has fired."""

    v: float
    w: float
    vz: float
    turning: bool = False

    def array(self) -> np.ndarray:
        return np.array([self.v, self.w, self.vz])


class Cycle(NamedTuple):
    """What the rules read of one UAV's cycle: its view, memory and config, the target stage's goal
    (DWA's goal) and lookahead point, the heading goal DWA steered for, DWA's and 3D VFH+'s results
    (``vfh`` None in planar mode), the neighbours as predicted movers (g6) and DWA's obstacle points
    (own-map voxels and the world's bounds) with their radii, and whether the UAV is on its final approach to
    a fixed target (``docking``), and whether the vertical decision steers through a known gap in a wall
    ahead (``gap``: the gap rule found the preferred altitude blocked and returned another)."""

    view: object
    mem: object
    cfg: object
    goal: np.ndarray
    lookahead: np.ndarray
    heading_goal: np.ndarray
    dwa: object
    vfh: object
    movers_pos: np.ndarray
    movers_vel: np.ndarray
    obstacles: np.ndarray = np.empty((0, 3))
    radii: np.ndarray = np.empty(0)
    docking: bool = False
    gap: bool = False


# ---------------------------------------------------------------------- the rules, in order
def braking_fallback(cmd: Command, c: Cycle) -> None:
    """(b10) and the stuck escape of (g4): with no admissible DWA sample, DWA brakes and the UAV turns toward
    its heading goal [X]; after ``T_stuck`` s of this, 3D VFH+'s straight-up (down) cells pick a vertical escape."""
    mem, lim = c.mem, c.view.limits
    if c.dwa.admissible:
        mem.stuck_time = 0.0
        return
    mem.stuck_time += lim.dt
    s = c.view.state
    cmd.w = turn_toward(s, c.heading_goal - s[:2], lim.w_max)
    if c.cfg.use_vfh and mem.stuck_time >= c.cfg.T_stuck and c.vfh is not None:
        cmd.vz = vertical_escape(c.vfh, lim)


def dock_turn(cmd: Command, c: Cycle) -> None:
    """[X] ``dock_turn_angle``, ``dock_radius``, ``dock_turn_speed``, ``dock_turn_toward``: a UAV closing on a fixed
    target (the leader within ``dock_radius`` of the goal; a slow follower of a parked leader, at least e_f / 2 from
    its slot) that lies more than ``dock_turn_angle`` off its nose turns in place toward it; a follower, with
    ``dock_turn_toward="heading_goal"``, toward the point DWA steers for, which is 3D VFH+'s detour when it takes one
    (turned toward its target behind a tree instead, a follower at rest against the tree turned to and fro with DWA
    for 250 s: drawn forest mission, seed 12 draw 33). A follower is slow below ``leader_stopped_speed``
    (``dock_turn_speed="stopped"``) or when it stops within e_f / 2 at a_max (``"stop"``: v^2 < a_max e_f)."""
    view, cfg = c.view, c.cfg
    s = view.state
    if not view.is_leader and not (leader_parked(view, cfg) and _docking_slow(s[V], view, cfg)):
        return
    to_goal = (view.goal[:2] if view.is_leader else c.goal) - s[:2]
    if view.is_leader:
        docking = math.hypot(to_goal[0], to_goal[1]) < cfg.dock_radius
    else:
        docking = math.hypot(to_goal[0], to_goal[1]) >= view.config.formation.e_f / 2
        if cfg.dock_turn_toward == "heading_goal":
            to_goal = c.heading_goal - s[:2]
    if docking and abs(bearing_error(s, to_goal)) > cfg.dock_turn_angle:
        cmd.v, cmd.w, cmd.turning = 0.0, turn_toward(s, to_goal, view.limits.w_max), True


def dock_approach(cmd: Command, c: Cycle) -> None:
    """[X] ``dock_approach``, ``approach_radius``: the leader on its final approach (``Cycle.docking``: within
    ``approach_radius`` of its goal along a segment clear of its own map by r_uav + r_safe), in an estimated wind
    stronger than ``vane_wind``, flies the approach law of ``home_in`` instead of DWA's choice: DWA's speed
    profile and heading weight, blind to the wind, flew past the goal and orbited it 1-2 m away. In still air
    DWA's approach stands (it parks the leader on headings that leave the followers' slots free more often:
    with this rule in still air too, 3 of 7 still-air episodes of the dev subset closed the formation, without 6)."""
    if not (c.docking and c.cfg.dock_approach and math.hypot(c.mem.wind[0], c.mem.wind[1]) > c.cfg.vane_wind):
        return
    home = home_in(c.view, c.mem, c.cfg, c.view.goal[:2])
    cmd.v, cmd.w, cmd.turning = home.v, home.w, cmd.turning or home.turning


def reverse_turn(cmd: Command, c: Cycle) -> None:
    """[X] ``reverse_turn_angle``: a UAV steering by a path's lookahead point (the leader; a rejoining follower)
    turns in place when that point lies more than ``reverse_turn_angle`` off its nose (unless it docks)."""
    if cmd.turning or not c.mem.on_path:
        return
    s = c.view.state
    to_lookahead = c.lookahead - s[:2]
    if abs(bearing_error(s, to_lookahead)) > c.cfg.reverse_turn_angle:
        cmd.v, cmd.w, cmd.turning = 0.0, turn_toward(s, to_lookahead, c.view.limits.w_max), True


def gap_turn(cmd: Command, c: Cycle) -> None:
    """[X] ``gap_turn_angle``: a UAV steering through a known gap in a wall ahead (``Cycle.gap``) turns in place
    when its heading goal lies more than ``gap_turn_angle`` off its nose (unless another turn fired). Arrived
    along the wall, DWA's clearance term kept the nose parallel to it, and the UAV slid along the wall beside
    the gap instead of turning into it (wall-gap v1-dev s200120 breeze: a follower to time-out)."""
    if cmd.turning or not c.gap:
        return
    s = c.view.state
    to_goal = c.heading_goal - s[:2]
    if abs(bearing_error(s, to_goal)) > c.cfg.gap_turn_angle:
        cmd.v, cmd.w, cmd.turning = 0.0, turn_toward(s, to_goal, c.view.limits.w_max), True


def braking_turn(cmd: Command, c: Cycle) -> None:
    """[X] ``braking_turn``: a UAV that a rule set braking while it turns (``braking_fallback``, a turn in place)
    coasts along its nose until it stops; when the arc of the commanded turn would touch DWA's obstacle points
    (their radii, less r_uav), the UAV flies the turn among the commanded one, none and w_max either way whose
    braking arc keeps the most clearance (``kernels.braking_arc_clearance``; the first of equals)."""
    s, lim = c.view.state, c.view.limits
    if not c.cfg.braking_turn or len(c.obstacles) == 0 or cmd.v >= s[V] or (c.dwa.admissible and not cmd.turning):
        return

    def arc(w: float) -> float:
        return braking_arc_clearance(s, w, lim.dt, lim.v_min, lim.v_max, lim.a_max, lim.w_max, lim.dw_max,
                                     c.obstacles, c.radii, lim.r_uav)

    best = arc(cmd.w)
    if best >= 0.0:
        return
    for w in (0.0, lim.w_max, -lim.w_max):          # the commanded turn's arc is not worked out twice
        clearance = arc(w)
        if clearance > best:
            best, cmd.w = clearance, w


def drift_guard(cmd: Command, c: Cycle) -> None:
    """[X] ``guard_clearance``, ``guard_speed``: with no admissible DWA sample, a UAV whose clearance to the nearest
    obstacle point (own-map voxel or world bound) beside it is below ``guard_clearance`` does not brake to a
    hover, which the wind pushes on into the obstacle, but turns its nose away from that point and flies
    off at ``guard_speed`` plus the estimated wind toward the point (``mem.wind``), times the cosine of its
    bearing error (0 beyond 90 degrees). A point more above or
    below than beside is the emergency escape's case (g5).
    [X] ``guard_gust_time``, ``guard_hover_speed``: in gusts the guard's clearance grows by ``guard_gust_time`` x the
    RMS drift (``gust_speed``), less what r_safe covers (``gust_standoff``); a UAV slower than ``guard_hover_speed``
    within that gust standoff alone is guarded even when DWA has admissible samples (a UAV DWA turns in place at
    v = 0 cannot dodge the next gust).
    [X] ``guard_dwa_exit``: such a hovering UAV whose nose points more than 90 degrees from the way away (the guard
    would first turn it in place) is left to the command so far when DWA accelerates it (v above its speed now)
    along a rollout whose clearance is at least its clearance now: turning in place toward the way away from a
    nearest point whose bearing changed with every gust excursion held a rejoining follower at v = 0 for 30 s while
    DWA asked for more speed each cycle (forest s200071 gusty)."""
    cfg, view = c.cfg, c.view
    s, lim = view.state, view.limits
    standoff = gust_standoff(c.mem, cfg, cfg.guard_gust_time, lim.r_safe)
    if not c.dwa.admissible:
        reach = cfg.guard_clearance + standoff
    else:                                       # DWA found a way: only a hovering UAV within the gust standoff
        reach = standoff if s[V] < cfg.guard_hover_speed else 0.0
    if len(c.obstacles) == 0 or reach <= 0.0:
        return
    gaps = np.linalg.norm(c.obstacles - s[:3], axis=1) - c.radii
    m = int(np.argmin(gaps))
    clearance = gaps[m] - lim.r_uav
    if clearance >= reach:
        return
    away = s[:2] - c.obstacles[m, :2]
    if math.hypot(away[0], away[1]) <= abs(s[2] - c.obstacles[m, 2]):
        return
    err = bearing_error(s, away)
    if (cfg.guard_dwa_exit and c.dwa.admissible and math.cos(err) <= 0.0 and c.dwa.v > s[V]
            and c.dwa.clearance >= clearance):
        return                                  # DWA's way out: it accelerates along a rollout no nearer
    toward = -float(c.mem.wind @ away) / math.hypot(away[0], away[1])      # wind component toward the point
    speed = min(lim.v_max, cfg.guard_speed + max(0.0, toward))
    cmd.v, cmd.w = speed * max(0.0, math.cos(err)), turn_toward(s, away, lim.w_max)


def vertical_separation(cmd: Command, c: Cycle) -> None:
    """[X] ``separation_margin``, ``separation_tie``: a live neighbour within R_uu + ``separation_margin`` (3D) is left
    vertically, at full climb rate away from it (the higher UAV climbs, the lower descends; within
    ``separation_tie`` of one altitude the higher index climbs: each UAV compares its own altitude with the
    neighbour's broadcast, predicted one cycle on at its vz, which misses the cycle's vertical acceleration (up to
    az_max dt^2 = 5 mm); two UAVs climbing together saw each other 1-9 mm below themselves and both climbed into
    a collision, forest v1-dev s200068 breeze),
    unless the altitude band or a voxel of the own map within r_uav + r_safe of the point r_uav + r_safe along
    the way closes that direction (then the other way; neither: DWA's command stands).
    DWA's admissibility cannot help a UAV already inside R_uu (every sample is inadmissible, it brakes) and
    the horizontal dynamic window (0.2 m/s^2) is too slow against gusts that push two UAVs together; the
    vertical one (0.5 m/s^2, 0.5 m/s) is the fastest way apart."""
    view, cfg = c.view, c.cfg
    if c.cfg.separation_margin <= 0.0:
        return
    pos = view.state[:3]
    m, dist = nearest_live(pos, c.movers_pos, view.neighbour_alive)
    if m < 0 or dist >= cfg.dwa.R_uu + cfg.separation_margin:
        return
    lim = view.limits
    dz = pos[2] - c.movers_pos[m, 2]
    up = dz > 0.0 if abs(dz) > max(cfg.separation_tie, 1e-6) else view.index > int(view.neighbour_ids[m])
    margin = lim.r_uav + lim.r_safe
    for sign in ((1.0, -1.0) if up else (-1.0, 1.0)):
        z_next = pos[2] + sign * margin                    # checked every cycle: the next r_uav + r_safe of the way
        if not lim.z_min <= z_next <= lim.z_max:
            continue
        if view.occupancy.occupied_within(np.array([pos[0], pos[1], z_next]), margin):
            continue
        cmd.vz = sign * lim.vz_max
        return


def emergency_escape(cmd: Command, c: Cycle) -> None:
    """(g5) emergency, with [X] ``lateral_emergency_to_dwa``: a voxel or neighbour inside 3D VFH+'s r_e stops the
    UAV and moves it vertically away from the nearest voxel, unless that move closes on a neighbour (g6)."""
    if c.vfh is None or not c.vfh.emergency:
        return
    view, cfg = c.view, c.cfg
    lim = view.limits
    pos = view.state[:3]
    r_e = cfg.vfh.resolve(lim, view.occupancy.resolution)[0]
    vz_away = away_vertically(pos, view.occupancy, r_e, lim, cfg.lateral_emergency_to_dwa)
    if vz_away is None:
        return
    cmd.v, cmd.vz = 0.0, vz_away
    alive = view.neighbour_alive
    if closes_on_movers(pos, cmd.vz, c.movers_pos[alive], c.movers_vel[alive], cfg.dwa, lim):
        cmd.vz = 0.0                    # the escape would fly into a neighbour (above or below)


RULES = (braking_fallback, dock_turn, dock_approach, reverse_turn, gap_turn, braking_turn, drift_guard,
         vertical_separation, emergency_escape)
"""The rules after DWA, in the order they act on the command (later ones override earlier ones)."""


# ---------------------------------------------------------------------- the hold stage (no DWA)
def station_keep(view, mem, cfg, hold_xy, heading: float, clearance: float) -> Command:
    """[X] ``hold_radius``, ``k_hold``, ``vane_wind``: a UAV holding a point (the arrived leader at its goal; a UAV
    with no way to its goal, where it stopped) keeps it against the wind. The air velocity it needs is
    u = k_hold (p_hold - p) - w (return to the point and cancel the wind ``mem.wind`` its own drift estimates);
    of the drift only what persists over 1 / k_hold s (``drift_persistence``: the autopilot cancels the rest);
    a unicycle with v >= 0 has no lateral control, so it turns its nose toward u and flies at |u| times the
    cosine of the bearing error (0 beyond 90 degrees). Within ``hold_radius`` of the point with |u| below
    ``vane_wind`` (still air) it stops and turns to ``heading``, and stays stopped (``mem.held``) until the wind
    has carried it ``hold_release`` from the point: every return turns the nose, and with it a leader's follower
    slots. [X] ``hold_gust_time``: in gusts (RMS drift, ``gust_speed``, above ``vane_wind``) both radii grow by
    ``hold_gust_time`` x the RMS drift and the still-air condition goes, on an airframe that leans into the wind
    (with the unopposed model a resting UAV drifts with the whole wind): an autopilot-held UAV is carried by the
    gusts' changes only (``UAVLimits.wind_authority``: tau x the change of its lean), about that far and back, so
    chasing each excursion only turns the nose round. [X] ``rest_gust_time``: it rests only while its ``clearance``
    (horizontal, to its own map near its altitude and the world's bounds) is at least r_safe plus the gust standoff
    of that time (``gust_standoff``); closer, it flies back to the point, which it reached clear. The returned
    ``vz`` is 0 (the caller holds altitude)."""
    s, lim = view.state, view.limits
    to_hold = np.asarray(hold_xy, dtype=np.float64) - s[:2]
    u = cfg.k_hold * to_hold - mem.wind * drift_persistence(lim, 1.0 / cfg.k_hold if cfg.k_hold > 0.0 else math.inf)
    speed, dist = math.hypot(u[0], u[1]), math.hypot(to_hold[0], to_hold[1])
    gusts = gust_speed(mem)
    slack = cfg.hold_gust_time * gusts if gusts > cfg.vane_wind and lim.wind_authority > 0.0 else 0.0
    radius = (cfg.hold_release if mem.held else cfg.hold_radius) + slack
    mem.held = clearance >= rest_standoff(mem, cfg, lim.r_safe) and dist <= radius and (
        mem.held or slack > 0.0 or speed <= cfg.vane_wind)
    if mem.held:
        return Command(0.0, clamp(wrap(heading - s[PSI]), -lim.w_max, lim.w_max), 0.0)
    err = bearing_error(s, u)
    return Command(clamp(speed * math.cos(err), 0.0, lim.v_max), clamp(err, -lim.w_max, lim.w_max), 0.0)


def rest_standoff(mem, cfg, r_safe: float) -> float:
    """[X] ``rest_gust_time``: the horizontal clearance (m) a holding UAV needs to rest (``station_keep``): r_safe plus
    the gust standoff of ``rest_gust_time`` (``gust_standoff``); r_safe in still air."""
    return r_safe + gust_standoff(mem, cfg, cfg.rest_gust_time, r_safe)


def home_in(view, mem, cfg, point_xy) -> Command:
    """Fly to a fixed point without orbiting it: turn toward it (in place while it lies more than
    ``dock_turn_angle`` off the nose) and fly at ``k_hold`` times the distance plus the headwind the UAV's own
    drift estimates (``mem.wind``), scaled by the cosine of the bearing error and capped at the pure-pursuit
    speed that still steers onto the point (so the turn-rate limit never carries it round the point)."""
    s, lim = view.state, view.limits
    to_point = np.asarray(point_xy, dtype=np.float64) - s[:2]
    dist = math.hypot(to_point[0], to_point[1])
    if dist < 1e-9:
        return Command(0.0, 0.0, 0.0)
    err = bearing_error(s, to_point)
    w = clamp(err, -lim.w_max, lim.w_max)
    if abs(err) > cfg.dock_turn_angle:
        return Command(0.0, w, 0.0, turning=True)
    headwind = max(0.0, -float(mem.wind @ to_point) / dist)
    v = (cfg.k_hold * dist + headwind) * math.cos(err)
    sin_err = abs(math.sin(err))
    if sin_err > 1e-9:
        v = min(v, lim.w_max * dist / (2.0 * sin_err))          # pure pursuit onto the point (no orbit)
    return Command(clamp(v, 0.0, lim.v_max), w, 0.0)


@dataclass
class WindMemory:
    """What the wind rules keep of one UAV between cycles: the wind estimate and the mean squares of the horizontal
    and vertical drift (``wind_estimate``), the pose it predicts from, and whether a holding UAV rests
    (``station_keep``). The expert's per-UAV memory extends it; a script that holds a UAV with these rules alone
    (benchmarks/wind_authority.py) starts from it."""

    wind: np.ndarray = field(default_factory=lambda: np.zeros(2))
    drift_ms: float = 0.0
    drift_z_ms: float = 0.0
    prev_pose: tuple | None = None
    held: bool = False


def wind_estimate(view, mem, cfg) -> None:
    """[X] ``wind_tau``, ``gust_tau``: the horizontal wind from the UAV's own drift. The last cycle's pose moved by
    the commands now in its state (the kinematic model of spec (a)) predicts this pose; what is left over per
    second is the drift (the wind its autopilot has not compensated), low-pass filtered with time constant
    ``wind_tau`` into ``mem.wind``, and its squared speed with ``gust_tau`` into ``mem.drift_ms`` (both zero in
    still air). [X] ``vertical_margin``: the climb the state's vz does not explain is the vertical drift, its square
    filtered the same way into ``mem.drift_z_ms``."""
    dt = view.limits.dt
    s = view.state.tolist()                     # floats: the numpy scalars' values, without their glue
    x_now, y_now, z_now, psi_now, v, w, vz = s[0], s[1], s[2], s[PSI], s[V], s[W], s[VZ]
    prev = mem.prev_pose
    if prev is not None:
        x, y, z, _ = integrate(prev[0], prev[1], prev[2], prev[3], v, w, vz, dt)
        drift_x, drift_y, drift_z = (x_now - x) / dt, (y_now - y) / dt, (z_now - z) / dt
        gain, wind_x, wind_y = min(1.0, dt / cfg.wind_tau), float(mem.wind[0]), float(mem.wind[1])
        mem.wind = np.array([wind_x + gain * (drift_x - wind_x), wind_y + gain * (drift_y - wind_y)])
        gust_gain = min(1.0, dt / cfg.gust_tau)
        mem.drift_ms += gust_gain * (drift_x * drift_x + drift_y * drift_y - mem.drift_ms)
        mem.drift_z_ms += gust_gain * (drift_z * drift_z - mem.drift_z_ms)
    mem.prev_pose = (x_now, y_now, z_now, psi_now)


def gust_speed(mem, vertical: bool = False) -> float:
    """The UAV's typical drift speed (m/s): the root mean square of its horizontal (``vertical``: vertical) drift over
    ``gust_tau`` (``wind_estimate``). Under gusts the drift changes faster than ``mem.wind`` follows; this is what a
    wind margin must cover."""
    return math.sqrt(mem.drift_z_ms if vertical else mem.drift_ms)


def gust_standoff(mem, cfg, time: float, r_safe: float, vertical: bool = False) -> float:
    """[X] ``gust_allowance`` (issue 13, breeze): the distance (m) a gust margin adds to a UAV's clearance: ``time`` (s)
    x the RMS drift (``gust_speed``; ``vertical``: the vertical drift's), less the share ``gust_allowance`` of the
    safety radius ``r_safe`` that every clearance already keeps (never below 0). A breeze's drift (RMS ~0.16 m/s) then
    adds nothing where r_safe covers it, while a gusty drift (~0.6 m/s) keeps nearly all of its margin."""
    return max(0.0, time * gust_speed(mem, vertical) - cfg.gust_allowance * r_safe)


def braking_share(mem, cfg) -> float:
    """[X] ``gust_braking``: this cycle's share of DWA's braking test (``DWAConfig.brake_share``): the config's,
    raised with the RMS drift (``gust_speed``) to 1 at ``gust_braking`` m/s. In still air only obstacles on a
    rollout's path slow the UAV (Fox's free-arc form); in gusts the clearance form's speed-dependent standoff
    leaves room to turn away from a gust that the rollouts did not foresee."""
    return max(cfg.dwa.brake_share, min(1.0, gust_speed(mem) / cfg.gust_braking))


def wind_margin(mem, cfg, clearance_now: float, r_safe: float, vertical: bool = False) -> float:
    """[X] ``wind_margin``, ``wind_margin_share``: how far DWA's obstacle points grow in gusts (m): ``wind_margin``
    s x the RMS drift less what r_safe covers (``gust_standoff``), at most ``wind_margin_share`` of the UAV's
    current clearance (a UAV the gusts carried inside the margin can still hold or leave: a margin as large as the
    clearance makes every sample inadmissible). A share of 1/2 lets a UAV close in to half its clearance every
    cycle, so the margin never stops an approach; a larger share keeps it nearer the clearance it has."""
    return min(gust_standoff(mem, cfg, cfg.wind_margin, r_safe, vertical),
               cfg.wind_margin_share * max(0.0, clearance_now))


def gust_radii(z: float, climb: float, voxels: np.ndarray, radius: float, margin: float, margin_z: float,
               r_uav: float) -> np.ndarray:
    """DWA's voxel radii in the wind: ``radius`` plus the horizontal ``margin`` for a voxel a horizontal drift can
    reach (its centre within ``margin_z`` + radius + r_uav of the altitudes the rollouts fly, from ``z`` to ``z`` +
    ``climb``), plus the vertical ``margin_z`` for one above or below those; equal margins: every voxel alike."""
    if margin == margin_z:
        radii = np.empty(len(voxels))
        radii.fill(radius + margin)                 # np.full's result, without its wrapper
        return radii
    reach = margin_z + radius + r_uav
    lo, hi = min(z, z + climb) - reach, max(z, z + climb) + reach
    beside = (voxels[:, 2] > lo) & (voxels[:, 2] < hi)
    return np.where(beside, radius + margin, radius + margin_z)


def fence_clearance(pos, bounds_lo, bounds_hi, r_uav: float) -> float:
    """The UAV's horizontal clearance (m) to the world's x/y bounds: the nearest bound's distance minus r_uav."""
    x, y = float(pos[0]), float(pos[1])                  # floats: the numpy scalars' values, without their glue
    nearest = min(x - float(bounds_lo[0]), y - float(bounds_lo[1]), float(bounds_hi[0]) - x, float(bounds_hi[1]) - y)
    return nearest - r_uav


# ---------------------------------------------------------------------- helpers (the controller uses them too)
def drift_persistence(lim, horizon: float) -> float:
    """The share of a drift d felt now that carries on over ``horizon`` s, as a constant velocity with the same
    displacement: the airframe's autopilot cancels it with time constant tau = ``wind_rejection_tau``, so the UAV
    moves d tau (1 - exp(-horizon / tau)) (``uavform_env.dynamics.wind_drift``); with no wind authority the wind
    carries it whole (1)."""
    tau = lim.wind_rejection_tau
    if lim.wind_authority == 0.0:
        return 1.0
    if tau == 0.0 or horizon == math.inf:
        return 0.0
    return tau / horizon * -math.expm1(-horizon / tau)


def _docking_slow(v: float, view, cfg) -> bool:
    """``dock_turn``'s test of a follower's speed ``v`` (``dock_turn_speed``)."""
    if cfg.dock_turn_speed == "stopped":
        return v < cfg.leader_stopped_speed
    return v * v < view.limits.a_max * view.config.formation.e_f


def clamp(x: float, lo: float, hi: float) -> float:
    """``x`` limited to [lo, hi] (np.clip's result for one number, without its array overhead)."""
    return float(min(max(x, lo), hi))


def bearing_error(state, direction) -> float:
    """Signed angle (rad) from the UAV's heading to the horizontal ``direction``."""
    return wrap(math.atan2(direction[1], direction[0]) - state[PSI])


def turn_toward(state, direction, w_max: float) -> float:
    """The yaw rate toward the horizontal ``direction``: its bearing error, limited to +/- w_max."""
    return clamp(bearing_error(state, direction), -w_max, w_max)


def leader_parked(view, cfg) -> bool:
    """Whether the leader's broadcast speed is below ``leader_stopped_speed`` (its followers dock)."""
    return bool(view.leader_state[V] < cfg.leader_stopped_speed)


def closes_on_movers(pos, vz: float, movers_pos, movers_vel, dwa, lim) -> bool:
    """Whether a vertical move at ``vz`` comes within ``dwa.R_uu`` of a neighbour over the DWA horizon (g6)."""
    if len(movers_pos) == 0 or vz == 0.0:
        return False
    n_steps = round(dwa.T_p / lim.dt)
    return closest_approach(pos, np.array([0.0, 0.0, vz]), movers_pos, movers_vel, n_steps, lim.dt) < dwa.R_uu


def away_vertically(pos, occ_map, radius, lim, lateral_to_dwa: bool) -> float | None:
    """The emergency escape of (g5): full vertical speed away from the nearest voxel within ``radius`` (r_e).

    None (no escape, DWA acts) when ``lateral_to_dwa`` and that voxel lies more beside the UAV than above
    or below it, or when no voxel is that near (a neighbour inside r_e raised the emergency: DWA's moving
    obstacles handle it).
    """
    centres, _ = occ_map.occupied_in_sphere(pos, radius)
    if len(centres) == 0:
        return None if lateral_to_dwa else 0.0
    nearest = centres[np.argmin(np.sum((centres - pos) ** 2, axis=1))]
    if lateral_to_dwa and abs(nearest[2] - pos[2]) < math.hypot(*(nearest[:2] - pos[:2])):
        return None
    return -lim.vz_max if nearest[2] > pos[2] else lim.vz_max
