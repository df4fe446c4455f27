"""The fusion expert of spec (g): A* + improved DWA in the plane, 3D VFH+ for the vertical, in a
distributed leader-follower formation controller.

Every UAV runs the same cycle (g3) on its own onboard view, in four stages: the target (leader: goal
and A* lookahead; follower: the slot predicted over the DWA horizon), the vertical decision (3D VFH+
on its own map, debounced (g4)), DWA with a 3D-aware clearance (g5) and the neighbours as moving
obstacles (g6), then the ordered command rules of ``rules.RULES``. All weights and thresholds live in
one ``ExpertConfig``; ``act(..., weights=...)`` overrides the evaluation weights per UAV and step (the
residual-RL interface). The same class with ``use_vfh=False`` is the planar (2D, fixed-altitude)
formation used by the DWA baselines. DWA and 3D VFH+ are constructor arguments (the planners of
``baselines.dwa`` and ``baselines.vfh3d`` by default), so they can be timed or replaced.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from uavform_env.dynamics import PSI, V, VZ, W, commands_to_actions, wrap
from uavform_env.formation import formation_slots, slot_positions
from uavform_env.world import grid_frame

from ..astar import GlobalPath, Raster, inflate, plan_path, replan_trigger
from ..dwa import dwa_plan, geofence_points, project_to_altitude
from ..policy import OnboardPolicy
from ..vertical import BLOCKED, CLIMB, LEVEL, PlannerMemory
from ..vfh3d import VFHPlanner
from .config import ExpertConfig
from .kernels import (clear_turn_radius, closest_approach_of, columns_without_gap, gap_altitude_kernel, in_sphere,
                      live_within, mark_cells, open_level_way, predicted_movers, segment_clear, slot_errors,
                      surface_clearance, trail_arc, trail_lags, trail_points)
from .rules import (RULES, Command, Cycle, WindMemory, bearing_error, braking_share, clamp, drift_persistence,
                    fence_clearance, gust_radii, gust_speed, gust_standoff, leader_parked, rest_standoff, station_keep,
                    wind_estimate, wind_margin)


@dataclass
class _UAVMemory(PlannerMemory, WindMemory):
    """What one UAV's controller remembers between cycles: the shared (g4) state, the wind rules' and the expert's
    own."""

    column_until: float = -1.0
    plan_goal: np.ndarray | None = None
    goal_visible: bool = True
    on_path: bool = False
    last_plan_time: float = -1e9
    last_check_time: float = -1e9
    trail: np.ndarray = field(default_factory=lambda: np.empty((0, 2)))   # the leader's broadcast positions
    trail_progress: int = 0
    pace_trail: np.ndarray = field(default_factory=lambda: np.empty((0, 2)))
    pace_allowed: tuple = (None, None)          # (live-follower mask bytes, their slot ranges) of ``_pace_errors``
    arrived: bool = False
    park_psi: float | None = None
    park_marks: np.ndarray = field(default_factory=lambda: np.empty((0, 2)))
    park_watch: tuple | None = None
    best_goal_distance: float = math.inf
    last_progress_time: float = 0.0
    hold_xy: np.ndarray | None = None
    hold_margin: float = 0.0
    cruise_z: float | None = None


class _Local(NamedTuple):
    """The UAV's surroundings this cycle: occupied voxels within DWA's reach on the ``level`` of its own map
    (centres, probabilities, ball radius), that reach, and the neighbours as movers (g6)."""

    obstacles: np.ndarray
    probs: np.ndarray
    radius: float
    reach: float
    level: int
    movers_pos: np.ndarray
    movers_vel: np.ndarray


class _Target(NamedTuple):
    """The target stage: DWA's goal, the lookahead point (E10), the speed cap, the speed reference and E8's rho_D
    (``dwa_plan(goal_distance=...)``; None: the distance to DWA's goal)."""

    goal: np.ndarray
    lookahead: np.ndarray
    v_cap: float | None
    v_ref: float | None
    stop_distance: float | None = None


class _Vertical(NamedTuple):
    """The vertical decision: climb rate, speed cap, DWA's heading goal and obstacle set, 3D VFH+'s result."""

    vz: float
    v_cap: float | None
    heading_goal: np.ndarray
    obstacles: np.ndarray
    radius: float
    vfh: object
    gap: bool = False


class FusionExpert(OnboardPolicy):
    """The paper's fusion planner as a distributed formation controller (see the module docstring).

    ``dwa``: the DWA planner, called like ``baselines.dwa.dwa_plan``; ``vfh``: the 3D VFH+ planner, called
    like ``baselines.vfh3d.vfh3d_step`` (None: a ``VFHPlanner`` of this controller's own, which keeps its
    configuration-derived setup).
    """

    def __init__(self, config: ExpertConfig | None = None, *, dwa: Callable = dwa_plan, vfh: Callable | None = None):
        self.config = config if config is not None else ExpertConfig()
        if not isinstance(self.config, ExpertConfig):
            raise ValueError(f"config: expected an ExpertConfig, got {type(self.config).__name__}")
        for name, planner in (("dwa", dwa), ("vfh", vfh)):
            if planner is not None and not callable(planner):
                raise ValueError(f"{name}: expected a callable planner, got {type(planner).__name__}")
        self.dwa = dwa
        self.vfh = vfh if vfh is not None else VFHPlanner()
        self._free_approach = (None, None)          # (DWA config, its copy with beta = 0) of the last final approach

    def reset(self, env, seed: int | None = None) -> None:
        super().reset(env, seed)
        base = self.env
        self.memory = {a: _UAVMemory() for a in base.possible_agents}
        self._leader_prediction = (None, None)
        lead = base.onboard(base.possible_agents[0])
        self.raster = _raster_for(lead, self.config.astar.res_g)

    def act(self, observations: dict, env, weights: dict | None = None) -> dict:
        base = getattr(env, "unwrapped", env)
        if getattr(self, "env", None) is not base:
            raise ValueError("policy: act() called with an env this policy was not reset() on; call reset(env, seed)")
        agents = list(base.agents)
        if not agents:
            return {}
        commands = np.array([self._cycle(base.onboard(agent), self.config if weights is None or agent not in weights
                                         else self.config.with_weights(weights[agent])) for agent in agents])
        return dict(zip(agents, commands_to_actions(commands, base.config.uav)))

    # ------------------------------------------------------------------ one UAV's cycle (g3)
    def _cycle(self, view, cfg: ExpertConfig) -> np.ndarray:
        """Target -> vertical decision -> DWA -> the command rules (``RULES``, in order)."""
        if view.crashed:
            return np.zeros(3)
        mem = self.memory[view.agent]
        wind_estimate(view, mem, cfg)
        t = view.step * view.limits.dt
        z_slot = _altitude_target(view, mem, cfg)
        if view.is_leader and self._arrived(view, mem, cfg):
            return self._park(view, mem, cfg, z_slot)
        local = self._local(view, cfg)
        target = self._target(view, mem, cfg, t, local)
        if target is None:                                      # unreachable: hold position safely
            self.diagnostics[view.agent] = {"mode": mem.mode, "stuck": True, "unreachable": True,
                                            "replans": mem.replans}
            margin = self._hold_margin(view, mem, cfg)
            if mem.hold_xy is None or margin > mem.hold_margin + view.limits.r_safe:   # first, or the wind rose
                mem.hold_xy, mem.hold_margin = self._hold_point(view, cfg, margin), margin
            cmd = station_keep(view, mem, cfg, mem.hold_xy, float(view.state[PSI]),
                               self._rest_clearance(view, mem, cfg))
            return np.array([cmd.v, cmd.w, self._hold_altitude(view, cfg, z_slot)])
        mem.hold_xy = None
        vertical = self._vertical_decision(view, mem, cfg, target, local, z_slot)
        cmd, res, clearance_now, obstacles, radii, docking = self._dwa(view, mem, cfg, target, vertical, local)
        cycle = Cycle(view, mem, cfg, target.goal, target.lookahead, vertical.heading_goal, res, vertical.vfh,
                      local.movers_pos, local.movers_vel, obstacles, radii, docking, vertical.gap)
        for rule in RULES:
            rule(cmd, cycle)
        self.diagnostics[view.agent] = {
            "mode": mem.mode, "stuck": not res.admissible or self._no_progress(view, mem, cfg, t),
            "n_admissible": res.n_admissible,
            "vfh_blocked": bool(vertical.vfh.blocked) if vertical.vfh is not None else False,
            "emergency": bool(vertical.vfh is not None and vertical.vfh.emergency),
            "replans": mem.replans, "path_found": mem.path_found, "column": t < mem.column_until,
            "clearance": clearance_now}
        return cmd.array()

    @staticmethod
    def _hold_margin(view, mem: _UAVMemory, cfg: ExpertConfig) -> float:
        """[X] ``hold_drift_time``: the horizontal clearance a UAV holding a point needs: r_safe plus the drift the
        estimated wind causes in ``hold_drift_time`` (the time to turn the nose into a gust from abeam)."""
        return view.limits.r_safe + cfg.hold_drift_time * gust_speed(mem)

    @staticmethod
    def _hold_point(view, cfg: ExpertConfig, margin: float) -> np.ndarray:
        """Where a UAV with no way to its goal holds: the nearest point (on a grid of ``geofence_spacing`` within
        ``hold_search`` m) whose horizontal clearance to the own map's voxels near the flight altitude and to the
        world's bounds is at least ``margin``, reached along a straight segment clear by r_uav + r_safe; none: the
        clearest such point (its own position if no other is reachable). It moves again only when the wind
        has risen by r_safe / ``hold_drift_time`` since."""
        lim = view.limits
        pos = view.state[:3]
        points = _hold_obstacles(view, cfg, cfg.hold_search + margin + lim.r_uav)
        if len(points) == 0:
            return pos[:2].copy()
        step = cfg.geofence_spacing
        axis = np.arange(-cfg.hold_search, cfg.hold_search + step / 2, step)
        gx, gy = np.meshgrid(axis, axis, indexing="ij")
        inside = gx ** 2 + gy ** 2 <= cfg.hold_search ** 2
        cand = np.column_stack([pos[0] + gx[inside], pos[1] + gy[inside], np.full(int(inside.sum()), pos[2])])
        cand = np.vstack([pos, cand])                                      # its own position first
        clear = np.sqrt(((cand[:, None, :2] - points[None, :, :2]) ** 2).sum(axis=2)).min(axis=1) - lim.r_uav
        dist = np.hypot(cand[:, 0] - pos[0], cand[:, 1] - pos[1])
        order = np.lexsort((dist, -np.minimum(clear, margin)))           # enough clearance first, then nearest
        for k in order:
            if k == 0 or segment_clear(points, pos, cand[k], lim.r_uav + lim.r_safe):
                return cand[k, :2].copy()
        return pos[:2].copy()

    @staticmethod
    def _rest_clearance(view, mem: _UAVMemory, cfg: ExpertConfig) -> float:
        """A holding UAV's horizontal clearance (``rules.station_keep``) to ``_hold_obstacles``, exact up to the
        standoff a rest needs (``rules.rest_standoff``), inf beyond it."""
        lim = view.limits
        points = _hold_obstacles(view, cfg, lim.r_uav + rest_standoff(mem, cfg, lim.r_safe))
        return surface_clearance(view.state[:3], points, 0.0, lim.r_uav)   # the points lie at the UAV's altitude

    @staticmethod
    def _hold_altitude(view, cfg: ExpertConfig, z_slot: float) -> float:
        """The climb rate back to the slot altitude, gain ``k_z``."""
        lim = view.limits
        return clamp(cfg.k_z * (z_slot - view.state[2]), -lim.vz_max, lim.vz_max)

    @staticmethod
    def _arrived(view, mem: _UAVMemory, cfg: ExpertConfig) -> bool:
        """Whether the leader has come within ``arrive_radius`` of a goal in reach (horizontally), now or before."""
        pos = view.state
        if math.hypot(view.goal[0] - pos[0], view.goal[1] - pos[1]) < cfg.arrive_radius and _goal_in_band(view):
            mem.arrived = True
        return mem.arrived

    def _park(self, view, mem: _UAVMemory, cfg: ExpertConfig, z_slot: float) -> np.ndarray:
        """The arrived leader holds the goal against the wind (``rules.station_keep``), turning in place to a heading
        with free slots (``park_turn``)."""
        self.diagnostics[view.agent] = {"mode": mem.mode, "stuck": False, "arrived": True, "replans": mem.replans,
                                        "repark_marks": len(mem.park_marks)}
        if cfg.park_turn and cfg.repark_time > 0.0 and mem.park_psi is not None:
            _mark_unreached_slots(view, mem, cfg, view.step * view.limits.dt)
        heading = _park_heading(view, mem, cfg) if cfg.park_turn else float(view.state[PSI])
        cmd = station_keep(view, mem, cfg, view.goal[:2], heading, self._rest_clearance(view, mem, cfg))
        return np.array([cmd.v, cmd.w, self._hold_altitude(view, cfg, z_slot)])

    def _local(self, view, cfg: ExpertConfig) -> _Local:
        """The occupied voxels within DWA's reach (octree level ``dwa_map_level``) and the neighbours (g6)."""
        lim = view.limits
        level = cfg.dwa_map_level
        vox_size = view.occupancy.resolution * (2 ** level)
        reach = lim.v_max * cfg.dwa.T_p + cfg.dwa.D_cap + lim.r_uav + vox_size
        obstacles, probs = view.occupancy.occupied_in_sphere(view.state[:3], reach, level=level)
        return _Local(obstacles, probs, vox_size * math.sqrt(3.0) / 2.0, reach, level, *self._neighbours(view, cfg))

    # ------------------------------------------------------------------ stage 1: target
    def _target(self, view, mem: _UAVMemory, cfg: ExpertConfig, t: float, local: _Local) -> _Target | None:
        """Goal, lookahead and speed limits of the leader (A*) or a follower (its slot); None if unreachable."""
        lim = view.limits
        s = view.state
        if view.is_leader:
            goal, lookahead, v_cap, v_ref = self._leader_target(view, mem, cfg, t)
            if goal is None:
                return None
        else:
            slot_hidden = cfg.rejoin_hidden and not segment_clear(local.obstacles, s[:3], view.slot,
                                                                  lim.r_uav + local.radius)
            goal, lookahead, v_cap, v_ref = self._follower_target(view, mem, cfg, t, slot_hidden, local)
        if cfg.pursuit_speed_cap:
            clear = (local.obstacles, lim.r_uav + lim.r_safe + local.radius) if cfg.pursuit_clear else None
            v_cap = _pursuit_cap(s, lookahead, lim, lim.v_max if v_cap is None else v_cap, clear)
        v_cap = self._yield(view, local.movers_pos, local.movers_vel, cfg, v_cap)
        # E8's rho_D (spec (c1): G is the follower's target slot): a follower rejoining along a path stops at its
        # slot, not at the path's lookahead point (docs/deviations.md, "E8's rho_D of a rejoining follower")
        rejoining = not view.is_leader and mem.on_path
        stop_distance = math.hypot(float(view.slot[0]) - float(s[0]), float(view.slot[1]) - float(s[1])) \
            if rejoining else None
        return _Target(goal, lookahead, v_cap, v_ref, stop_distance)

    # ------------------------------------------------------------------ stage 2: vertical decision (g4)
    def _vertical_decision(self, view, mem: _UAVMemory, cfg: ExpertConfig, target: _Target, local: _Local,
                           z_slot: float) -> _Vertical:
        """Climb rate and DWA's heading goal and obstacles: 3D VFH+, the known-gap rule and the debounced mode;
        planar mode flies level with the voxels near the flight altitude projected onto it."""
        lim = view.limits
        s = view.state
        pos = s[:3]
        vz = self._hold_altitude(view, cfg, z_slot)
        obstacles, radius, v_cap = local.obstacles, local.radius, target.v_cap
        if not cfg.use_vfh:
            mem.mode = LEVEL
            obstacles = project_to_altitude(obstacles, pos[2], lim.r_uav + lim.r_safe + radius)
            return _Vertical(vz, v_cap, target.goal, obstacles, radius, None)
        heading_goal = target.goal
        if local.level == 0 and local.reach >= cfg.vfh.R_w:   # the same voxels, in the same order, as a query
            centres, probs = in_sphere(local.obstacles, local.probs, pos, cfg.vfh.R_w)
        else:
            centres, probs = view.occupancy.occupied_in_sphere(pos, cfg.vfh.R_w)
        gap_z = _gap_altitude(view, mem, target.lookahead, z_slot, cfg)
        z_goal = z_slot if gap_z is None else gap_z
        aim = np.array([target.lookahead[0], target.lookahead[1], z_goal])
        if math.dist(aim.tolist(), pos.tolist()) < 1e-6:       # on the target: 3D VFH+ looks along the heading
            aim = pos + np.array([math.cos(s[PSI]), math.sin(s[PSI]), 0.0])
        to_aim = aim - pos
        close = live_within(pos, local.movers_pos, view.neighbour_alive, cfg.vfh_neighbour_radius)
        r = self.vfh(mem.vfh, cfg.vfh, lim, pos, s[PSI], s[V], s[VZ], to_aim, centres, probs,
                     view.occupancy.resolution, close)
        level_way = _level_way(r, cfg, to_aim) or (
            cfg.level_line and segment_clear(centres, pos, aim, lim.r_uav + lim.r_safe
                                             + view.occupancy.resolution * math.sqrt(3.0) / 2.0))
        mode = self._debounced_mode(mem, r, cfg, level_way, gap_z is not None)
        if mode == CLIMB and gap_z is not None:
            vz = clamp(cfg.k_gap * (gap_z - pos[2]), -lim.vz_max, lim.vz_max)
            v_cap = cfg.gap_speed if v_cap is None else min(v_cap, cfg.gap_speed)
            if local.level > 0:                     # a gap leaves centimetres: use the leaf voxels
                obstacles, _ = view.occupancy.occupied_in_sphere(pos, local.reach, level=0)
                radius = view.occupancy.resolution * math.sqrt(3.0) / 2.0
        elif mode == CLIMB and not r.blocked:
            vz = _climb_rate(r.elevation, s[V], z_goal - pos[2], cfg, lim)
        elif mode == BLOCKED:
            vz = 0.0
        elif mode == LEVEL and gap_z is not None and cfg.gap_hold:
            vz = self._hold_altitude(view, cfg, gap_z)
        if not r.blocked and not level_way and gap_z is None:
            az = r.azimuth                          # follow 3D VFH+ around what DWA cannot see past
            heading_goal = pos[:2] + cfg.climb_lookahead * np.array([math.cos(az), math.sin(az)])
        return _Vertical(vz, v_cap, heading_goal, obstacles, radius, r, gap_z is not None)

    # ------------------------------------------------------------------ stage 3: DWA
    def _dwa(self, view, mem: _UAVMemory, cfg: ExpertConfig, target: _Target, vertical: _Vertical, local: _Local):
        """(command, DWA result, current clearance, DWA's obstacle points and radii, whether on the final approach):
        DWA toward the heading goal at the vertical decision's climb
        rate, with the world's bounds as walls and the estimated wind carrying the rollouts (``wind_drift``); if
        nothing is admissible while climbing, holding altitude is tried."""
        lim = view.limits
        s = view.state
        pos = s[:3]
        obstacles, radius = vertical.obstacles, vertical.radius
        clearance_now = surface_clearance(pos, obstacles, radius, lim.r_uav)   # (without the wind margin)
        dwa_cfg = cfg.dwa
        if cfg.final_approach_free and self._final_approach(view, target.goal, obstacles, radius, cfg,
                                                            cfg.dock_radius):
            dwa_cfg = self._without_clearance_weight(dwa_cfg)
        docking = view.is_leader and self._final_approach(view, target.goal, obstacles, radius, cfg,
                                                          cfg.approach_radius)
        fence = geofence_points(pos, local.reach, view.bounds_lo, view.bounds_hi, cfg.geofence_spacing)
        cap = clearance_now                     # with ``fence_margin`` the cap counts the world's bounds too
        if cfg.fence_margin:
            cap = min(cap, fence_clearance(pos, view.bounds_lo, view.bounds_hi, lim.r_uav))
        margin = wind_margin(mem, cfg, cap, lim.r_safe)
        margin_z = wind_margin(mem, cfg, cap, lim.r_safe, vertical=True) if cfg.vertical_margin else margin
        fence_radius = margin if cfg.fence_margin else 0.0      # the fence points have radius 0, plus the margin
        n_voxels = len(obstacles)
        if len(fence):
            obstacles = np.concatenate([obstacles, fence])

        def obstacle_radii(vz):
            radii = np.empty(len(obstacles))
            radii[:n_voxels] = gust_radii(pos[2], vz * dwa_cfg.T_p, obstacles[:n_voxels], radius, margin, margin_z,
                                          lim.r_uav)
            radii[n_voxels:] = fence_radius
            return radii
        alive = view.neighbour_alive
        alive_pos, alive_vel = (local.movers_pos, local.movers_vel) if all(alive.tolist()) else \
            (local.movers_pos[alive], local.movers_vel[alive])
        still = mem.wind[0] == 0.0 and mem.wind[1] == 0.0
        drift = mem.wind * drift_persistence(lim, dwa_cfg.T_p) if cfg.wind_drift and not still else None
        share = braking_share(mem, cfg)
        mover_dist = not (cfg.leader_right_of_way and view.is_leader)     # (g6): the leader never yields

        def plan(vz):
            radii = obstacle_radii(vz)
            return self.dwa(s, lim, dwa_cfg, vertical.heading_goal, obstacles, radii, vz_cmd=vz,
                            lookahead=target.lookahead, clearance_now=clearance_now, movers_pos=alive_pos,
                            movers_vel=alive_vel, v_ref=target.v_ref, v_cap=vertical.v_cap,
                            prev_alignment=mem.prev_alignment, drift=drift, brake_share=share,
                            mover_dist=mover_dist, goal_distance=target.stop_distance), radii

        vz = vertical.vz
        res, radii = plan(vz)
        if not res.admissible and vz != 0.0:
            held, held_radii = plan(0.0)         # the climb itself may be what collides: try holding altitude
            if held.admissible:
                res, vz, radii = held, 0.0, held_radii
        mem.prev_alignment = res.alignment if math.isfinite(res.alignment) else 1.0
        return Command(res.v, res.w, vz), res, clearance_now, obstacles, radii, docking

    # ------------------------------------------------------------------ helpers of the stages
    def _without_clearance_weight(self, dwa_cfg):
        """``dwa_cfg`` with beta = 0 (``final_approach_free``), made once per configuration, not every cycle (with
        residual weights every cycle has its own configuration: ``with_checked``, as ``with_weights`` sets beta)."""
        last = self._free_approach
        if last[0] is not dwa_cfg:
            last = self._free_approach = (dwa_cfg, dwa_cfg.with_checked(beta=0.0))
        return last[1]

    @staticmethod
    def _final_approach(view, goal, obstacles, radius: float, cfg: ExpertConfig, within: float) -> bool:
        """Whether the UAV closes on a fixed target (the leader on its goal, a follower on a parked slot) within
        ``within`` along a straight segment clear of its own map's voxels by r_uav + r_safe."""
        pos = view.state[:3]
        if view.is_leader:
            target = view.goal
        elif leader_parked(view, cfg):
            target = np.array([goal[0], goal[1], view.slot[2]])
        else:
            return False
        return bool(math.hypot(float(target[0]) - float(pos[0]), float(target[1]) - float(pos[1])) < within
                    and segment_clear(obstacles, pos, target, view.limits.r_uav + view.limits.r_safe + radius))

    def _no_progress(self, view, mem: _UAVMemory, cfg: ExpertConfig, t: float) -> bool:
        """Whether the leader has gained less than ``trail_spacing`` on the goal in the last ``stuck_window`` s."""
        if not view.is_leader:
            return False
        dist = math.hypot(view.goal[0] - view.state[0], view.goal[1] - view.state[1])
        if dist < mem.best_goal_distance - cfg.trail_spacing:
            mem.best_goal_distance, mem.last_progress_time = dist, t
        return t - mem.last_progress_time >= cfg.stuck_window

    # ------------------------------------------------------------------ targets
    def _leader_target(self, view, mem: _UAVMemory, cfg: ExpertConfig, t: float):
        lim = view.limits
        if not _goal_in_band(view):                     # no altitude of the band comes within r_goal of the goal
            return None, None, None, None
        lookahead = self._guidance(view, mem, cfg, t, view.goal[:2])
        if lookahead is None:
            return None, None, None, None
        mem.on_path = True
        heading_target = cfg.astar.heading_target
        to_lookahead = heading_target == "lookahead" or (heading_target == "visible_goal" and not mem.goal_visible)
        goal = lookahead if to_lookahead else view.goal[:2]
        errors = self._pace_errors(view, mem, cfg)
        scale = 1.0
        if errors.size:
            mean_err = float(np.add.reduce(errors) / errors.size)           # np.mean's sum and division
            scale = clamp(1.0 - (mean_err - cfg.e0) / (cfg.e1 - cfg.e0), cfg.min_leader_scale, 1.0)
        share = cfg.leader_speed_cap if errors.size or not cfg.solo_full_speed else 1.0    # margin for followers
        return goal, lookahead, share * lim.v_max * scale, None

    @staticmethod
    def _pace_errors(view, mem: _UAVMemory, cfg: ExpertConfig) -> np.ndarray:
        """The followers' lags that pace the leader (``leader_pace``): their slot errors (``"slot"``), or each the
        smaller of its slot error and its lag along the leader's own trail beyond its slot's range (``"trail"``,
        ``trail_lags``; the trail kept as points ``trail_spacing`` apart, the last ``trail_window`` of them)."""
        errors = _follower_errors(view)
        if cfg.leader_pace != "trail":
            return errors
        pos = view.state[:2]
        trail = mem.pace_trail
        if not len(trail) or math.hypot(pos[0] - trail[-1, 0], pos[1] - trail[-1, 1]) >= cfg.trail_spacing:
            mem.pace_trail = trail = np.concatenate([trail[max(0, len(trail) + 1 - cfg.trail_window):], pos[None]])
        if not errors.size:
            return errors
        alive = view.neighbour_alive
        key = alive.tobytes()                           # the slot ranges change only when a follower is lost
        if mem.pace_allowed[0] != key:
            ids = view.neighbour_ids[alive]
            allowed = np.linalg.norm(view.offsets[ids, :2], axis=1)
            if _files(cfg):                             # a follower may file along the trail, index x spacing back
                allowed = np.maximum(allowed, ids * view.config.formation.spacing)
            mem.pace_allowed = key, allowed
        allowed = mem.pace_allowed[1]
        lags = trail_lags(trail, pos, view.neighbour_states[alive, :2], allowed)
        return np.minimum(errors, lags)

    def _guidance(self, view, mem: _UAVMemory, cfg: ExpertConfig, t: float, goal_xy: np.ndarray):
        """A* lookahead point toward ``goal_xy`` on this UAV's own map, replanned on the (d5) triggers; at the end
        of a path that ends in the goal's raster cell, the goal itself (``path_to_goal``).

        None when no path exists (the goal is unreachable on what this UAV knows).
        """
        lim = view.limits
        pos_xy = view.state[:2]
        if mem.replans == 0 or t - mem.last_check_time >= cfg.replan_check_period:
            mem.last_check_time = t
            blocked = self._blocked_raster(view, cfg)
            if mem.replans == 0 or mem.path is None or math.dist(goal_xy, mem.plan_goal) > cfg.astar.d_replan:
                self._plan(view, mem, t, goal_xy, blocked)
            else:
                inflated = inflate(blocked, lim.r_uav + lim.r_safe, self.raster.res)
                trigger = replan_trigger(mem.path, pos_xy, inflated, self.raster, max(0.0, t - mem.last_plan_time),
                                         True, cfg.astar)
                if trigger is not None:
                    self._plan(view, mem, t, goal_xy, blocked, inflated)
                if view.is_leader and cfg.astar.heading_target == "visible_goal":
                    box = self._raster_box()
                    sight = GlobalPath(np.array([np.clip(pos_xy, *box), np.clip(goal_xy, *box)]))
                    mem.goal_visible = not sight.corridor_blocked(inflated, self.raster)
        if not mem.path_found:
            return None
        point = mem.path.lookahead(pos_xy, cfg.astar.lookahead)
        if cfg.path_to_goal and self._same_cell(point, mem.path.points[-1], goal_xy):
            return np.array(goal_xy[:2], dtype=np.float64)      # the path's end stands for the goal in its cell
        return point

    def _same_cell(self, point, end, goal_xy) -> bool:
        """Whether ``point`` is the path's ``end`` and that lies in the raster cell of ``goal_xy`` (not snapped)."""
        if float(point[0]) != float(end[0]) or float(point[1]) != float(end[1]):
            return False
        origin, res = self.raster.origin, self.raster.res
        return all(math.floor((float(end[k]) - origin[k]) / res) == math.floor((float(goal_xy[k]) - origin[k]) / res)
                   for k in (0, 1))

    def _plan(self, view, mem: _UAVMemory, t: float, goal_xy, blocked=None, inflated=None):
        """A* from the UAV to ``goal_xy`` on ``blocked`` (its raster; None: made here); ``inflated``: ``blocked``
        already inflated by r_uav + r_safe, if the caller has it (``route_turn_cost`` reuses it)."""
        cfg = self.config
        lim = view.limits
        if blocked is None:
            blocked = self._blocked_raster(view, cfg)
        start, goal = np.clip(view.state[:2], *self._raster_box()), np.clip(goal_xy, *self._raster_box())
        margin = cfg.path_margin if view.is_leader else 0.0       # the leader's route keeps off walls
        path = self._search(blocked, start, goal, lim, margin, cfg.margin_detour)
        exploring = t - mem.last_progress_time < cfg.stuck_window       # not yet stuck: look at the unseen
        if path is None and exploring and cfg.explore_unknown and cfg.astar_layer == "passable":
            # the unseen ways, on the own map alone: a 2.5D prior shows tops, not the openings below them
            path = self._search(self._blocked_raster(view, cfg, seen=False, prior=False), start, goal, lim, margin,
                                cfg.margin_detour)
        if path is not None and view.is_leader and cfg.route_turn_cost:
            path = self._heading_route(view, blocked, goal, path, margin, inflated)
        mem.path, mem.path_found, mem.plan_goal = path, path is not None, np.array(goal_xy, dtype=np.float64)
        mem.last_plan_time = t
        mem.replans += 1
        return path

    def _heading_route(self, view, blocked, goal, path: GlobalPath, margin: float, inflated=None) -> GlobalPath:
        """``route_turn_cost``: ``path``, or the route that first flies the lookahead L_a straight on along the heading
        (when that leg is free) and then A*'s path from there, whichever costs less by ``route_cost``; not searched when
        ``path`` leaves within a raster cell of the nose at L_a (the two are the same route there). ``inflated``:
        ``blocked`` inflated by r_uav + r_safe (None: inflated here, when the leg is tested)."""
        cfg, lim = self.config, view.limits
        L, psi, pos = cfg.astar.lookahead, float(view.state[PSI]), view.state[:2]
        metres_per_rad = cfg.leader_speed_cap * lim.v_max / lim.w_max
        cost = route_cost(path.points, psi, L, metres_per_rad)
        if cost - path.length <= metres_per_rad * self.raster.res / L:     # on the nose within a raster cell at L_a
            return path
        ahead = pos + L * np.array([math.cos(psi), math.sin(psi)])
        lo, hi = self._raster_box()
        if np.any(ahead < lo) or np.any(ahead > hi):
            return path
        leg = GlobalPath(np.array([pos, ahead]))
        if inflated is None:
            inflated = inflate(blocked, lim.r_uav + lim.r_safe, self.raster.res)
        if leg.corridor_blocked(inflated, self.raster):
            return path
        onward = self._search(blocked, ahead, goal, lim, margin, cfg.margin_detour)
        if onward is None:
            return path
        if L + route_cost(onward.points, psi, L, metres_per_rad) < cost + cfg.route_keep_margin:   # heading psi ahead
            return GlobalPath(np.vstack([pos, onward.points]), cfg.astar.window, cfg.astar.allow_corner_cut)
        return path

    def _search(self, blocked, start, goal, lim, margin: float, detour: float) -> GlobalPath | None:
        """A* on ``blocked`` inflated by r_uav + r_safe (d1); the path on the raster inflated by ``margin`` more (it
        keeps off walls, along which DWA crawls) instead when one exists at most ``detour`` m longer and ends in the
        same cell (a goal near a wall is not moved away by the wider inflation's snapping)."""
        h_b = lim.r_uav + lim.r_safe
        path = plan_path(blocked, self.raster, start, goal, h_b, self.config.astar)
        if path is None or margin <= 0.0:
            return path
        wide = plan_path(blocked, self.raster, start, goal, h_b + margin, self.config.astar)
        if wide is None or wide.length > path.length + detour or not np.array_equal(wide.points[-1], path.points[-1]):
            return path
        return wide

    def _raster_box(self):
        lo = np.asarray(self.raster.origin) + 1e-6
        hi = lo + np.asarray(self.raster.shape) * self.raster.res - 2e-6
        return lo, hi

    def _blocked_raster(self, view, cfg: ExpertConfig, seen: bool = True, prior: bool = True) -> np.ndarray:
        """A UAV's 2D raster: its map's occupied voxels, the world bounds and (``prior``) the prior map
        (``astar_layer``); ``seen=False``: a column with a tall enough run of unknown voxels is a way too
        (``explore_unknown``). A way's free evidence is ``way_misses`` scans, or as many as the UAV has made (step k:
        k + 1). With the ``passable`` layer a cell in which the own map has seen a way (``_seen_ways``) stays open
        where the prior is taller than the band: a 2.5D prior shows an obstacle's top, not the openings below it."""
        lim = view.limits
        h_b = lim.r_uav + lim.r_safe
        occ_map = view.occupancy
        res = occ_map.resolution
        extent = np.asarray(occ_map.shape) * res
        centres, _ = occ_map.occupied_in_sphere(occ_map.origin + extent / 2, float(np.linalg.norm(extent)) / 2 + res)
        z_flight = _altitude_target(view, self.memory[view.agent], cfg)
        if cfg.astar_layer == "band":
            columns = centres[np.abs(centres[:, 2] - z_flight) <= h_b + res / 2, :2]
        else:
            misses = min(cfg.way_misses, view.step + 1)           # the scans so far can give no more evidence
            columns = columns_without_gap(occ_map, centres, lim.z_min, lim.z_max, 2 * h_b + res, seen, misses)
        blocked = np.zeros(self.raster.shape, bool)
        blocked[0, :] = blocked[-1, :] = blocked[:, 0] = blocked[:, -1] = True    # the x/y bounds are walls (geofence)
        _mark(blocked, self.raster, columns)
        known = view.prior
        if prior and known.kind != "none":
            limit = z_flight - h_b if cfg.astar_layer == "band" else lim.z_max - 2 * h_b
            cells = np.argwhere(known.heights > limit)
            tall = np.zeros(self.raster.shape, bool)
            _mark(tall, self.raster, known.origin + (cells + 0.5) * known.resolution)
            if cfg.astar_layer == "passable":
                tall &= ~self._seen_ways(occ_map, tall, lim, 2 * h_b + res, misses)
            blocked |= tall
        return blocked

    def _seen_ways(self, occ_map, cells: np.ndarray, lim, gap: float, misses: int) -> np.ndarray:
        """The raster cells of ``cells`` (bool raster) with a map column in which the own map shows a way: a run of
        non-occupied voxels of height ``gap`` with free evidence (``columns_without_gap``, seen), in the band."""
        res, raster = occ_map.resolution, self.raster
        sub = max(1, math.ceil(raster.res / res))              # map columns across a raster cell
        offsets = (np.arange(sub) + 0.5) * (raster.res / sub)
        corners = raster.origin + np.argwhere(cells) * raster.res
        xy = (corners[:, None, None, :] + np.stack(np.meshgrid(offsets, offsets, indexing="ij"), -1)).reshape(-1, 2)
        points = np.column_stack([xy, np.full(len(xy), 0.5 * (lim.z_min + lim.z_max))])
        closed = columns_without_gap(occ_map, points, lim.z_min, lim.z_max, gap, True, misses)
        column = np.array([1 << 32, 1])                         # a map column's (i, j) as one integer
        keys = [np.floor((p - occ_map.origin[:2]) / res).astype(np.int64) @ column for p in (xy, closed)]
        open_points = xy[~np.isin(*keys)]
        ways = np.zeros(raster.shape, bool)
        _mark(ways, raster, open_points)
        return ways

    def _follower_target(self, view, mem: _UAVMemory, cfg: ExpertConfig, t: float, slot_hidden: bool, local: _Local):
        lim = view.limits
        lead = view.leader_state
        column = False
        if cfg.shape_switching and (cfg.column_at_goal or not _leader_at_goal(view, cfg)):
            if _occupied_within(view, local, view.slot, lim.r_uav + lim.r_safe + view.occupancy.resolution):
                mem.column_until = t + cfg.column_hold
            column = t < mem.column_until
        key = (lead.tobytes(), cfg.dwa.T_p)              # every follower predicts the same broadcast: once a step
        if self._leader_prediction[0] != key:
            pred_xy, pred_psi = _predict_unicycle(lead, cfg.dwa.T_p, lim.dt)
            self._leader_prediction = key, {"xy": pred_xy, "psi": pred_psi}
        pred = self._leader_prediction[1]
        kind = "column" if column else "formation"
        if kind not in pred:                            # every UAV's slot offset, rotated (once a step)
            offsets = _column_offsets(view.offsets, view.config.formation.spacing) if column else view.offsets
            pred[kind] = _rotated(pred["psi"], offsets), _rotated(lead[PSI], offsets)
        pred_xy, (turned_pred, turned_now) = pred["xy"], pred[kind]
        row = view.index
        goal = pred_xy + turned_pred[row]
        heading_l = np.array([math.cos(lead[PSI]), math.sin(lead[PSI])])
        lead_moving = not leader_parked(view, cfg)
        x, y = float(view.state[0]), float(view.state[1])            # floats: the array arithmetic's values, faster
        k_hx, k_hy = (cfg.k_h * float(heading_l[0]), cfg.k_h * float(heading_l[1])) if lead_moving else (0.0, 0.0)
        lookahead = np.array([x + ((float(goal[0]) - x) + k_hx), y + ((float(goal[1]) - y) + k_hy)])  # a_j = goal - p
        slot_now = lead[:2] + turned_now[row]
        trail = mem.trail
        if (cfg.rejoin == "trail" or _files(cfg)) and (
                not len(trail) or math.hypot(lead[0] - trail[-1, 0], lead[1] - trail[-1, 1]) >= cfg.trail_spacing):
            mem.trail = trail = np.concatenate([trail, lead[None, :2]])
        e_file = None
        if column and _files(cfg) and len(trail):
            filed = self._file_place(view, mem, cfg, lead, lead_moving)
            if filed is not None:
                goal, lookahead, slot_now, e_file = filed
                slot_hidden = False
        far = slot_hidden or math.hypot(slot_now[0] - view.state[0], slot_now[1] - view.state[1]) > cfg.rejoin_distance
        mem.on_path = False
        if far and cfg.rejoin == "astar":
            guide = self._guidance(view, mem, cfg, t, slot_now)
            if guide is not None:
                mem.on_path = True
                return guide, guide, None, None
        elif not far:
            mem.last_check_time = -math.inf                     # re-entering the rejoin checks the path at once
        if far and cfg.rejoin == "trail" and len(trail) > 1:
            # Far from the slot: rejoin along the leader's broadcast trail, which the leader has flown.
            path = GlobalPath(np.asarray(trail), window=cfg.trail_window)
            path.progress = min(mem.trail_progress, len(trail) - 1)
            guide = path.lookahead(view.state[:2], cfg.astar.lookahead)
            mem.trail_progress = path.progress
            if path.length - path._arc[path.progress] > cfg.astar.lookahead:   # not yet at the trail's end
                mem.on_path = True
                return guide, guide, None, None
        e_par = float((slot_now - view.state[:2]) @ heading_l) if e_file is None else e_file
        if not lead_moving:                                     # closing on a parked slot, from any side
            to_slot = slot_now - view.state[:2]
            e_par = float(np.linalg.norm(to_slot)) * max(0.0, math.cos(bearing_error(view.state, to_slot)))
        v_ref = clamp(lead[V] + cfg.k_f * e_par, 0.0, lim.v_max)
        arriving = math.hypot(view.goal[0] - lead[0], view.goal[1] - lead[1]) < cfg.dock_radius
        v_cap = _slot_brake_cap(lead[V], math.hypot(slot_now[0] - view.state[0], slot_now[1] - view.state[1]),
                                lim.a_max) if cfg.slot_brake and arriving else None
        return goal, lookahead, v_cap, v_ref

    @staticmethod
    def _file_place(view, mem: _UAVMemory, cfg: ExpertConfig, lead: np.ndarray, lead_moving: bool):
        """[X] ``column_shape="trail"``: the column slot (g7) as a place in single file on the leader's broadcast
        trail, ``index`` x spacing behind the leader along it: (goal, lookahead, place now, e_par), or None while
        the trail is shorter than that. The goal is the trail's point ``astar.lookahead`` ahead of the follower's
        own nearest point on it (path following: round a door's corner, not across it), but no nearer the leader
        than where its place will be in T_p (``k_h`` before that while the leader flies); e_par, its lag behind its
        place along the trail, sets the (g2) speed reference."""
        back = view.index * view.config.formation.spacing
        ahead = float(lead[V]) * cfg.dwa.T_p
        own = trail_arc(mem.trail, lead[:2], view.state[:2], back + cfg.rejoin_distance + ahead)
        aim = max(own - cfg.astar.lookahead, back - ahead - (cfg.k_h if lead_moving else 0.0), 0.0)
        points, reached = trail_points(mem.trail, lead[:2], np.array([back, aim, max(0.0, aim - cfg.k_h)]))
        if not reached:
            return None
        return points[1], points[2], points[0], own - back

    # ------------------------------------------------------------------ neighbours (g6)
    def _neighbours(self, view, cfg: ExpertConfig):
        ns = view.neighbour_states
        return predicted_movers(ns, np.cos(ns[:, PSI]), np.sin(ns[:, PSI]), view.limits.dt, cfg.neighbour_prediction)

    def _yield(self, view, movers_pos, movers_vel, cfg: ExpertConfig, v_cap):
        """Deadlock rule of (g6): a UAV predicting a conflict with a lower-index UAV caps its speed."""
        if view.is_leader or cfg.yield_factor >= 1.0:
            return v_cap
        lim = view.limits
        s = view.state
        own_vel = np.array([s[V] * math.cos(s[PSI]), s[V] * math.sin(s[PSI]), s[VZ]])
        lower = (view.neighbour_ids < view.index) & view.neighbour_alive     # none: the approach is inf
        n_steps = round(cfg.dwa.T_p / lim.dt)
        if closest_approach_of(s[:3], own_vel, movers_pos, movers_vel, lower, n_steps, lim.dt) < cfg.dwa.R_uu:
            base = lim.v_max if v_cap is None else v_cap
            return cfg.yield_factor * base
        return v_cap

    # ------------------------------------------------------------------ vertical decision (g4)
    def _debounced_mode(self, mem: _UAVMemory, r, cfg: ExpertConfig, level_way: bool, gap: bool) -> str:
        """The vertical mode of (g4), changed only after ``debounce`` consecutive cycles agree."""
        if level_way:
            proposal = LEVEL
        elif gap:
            proposal = CLIMB
        elif r.blocked:
            proposal = BLOCKED
        elif abs(r.elevation) <= cfg.vfh.alpha_h / 2 + 1e-9:
            proposal = LEVEL
        else:
            proposal = CLIMB
        if proposal == mem.mode:
            mem.pending, mem.pending_count = proposal, 0
        elif proposal == mem.pending:
            mem.pending_count += 1
            if mem.pending_count >= cfg.debounce:
                mem.mode, mem.pending_count = proposal, 0
        else:
            mem.pending, mem.pending_count = proposal, 1
            if cfg.debounce <= 1:
                mem.mode = proposal
        return mem.mode


# ---------------------------------------------------------------------- helpers
def route_cost(points: np.ndarray, psi: float, lookahead: float, metres_per_rad: float) -> float:
    """A route's length plus the distance the leader forgoes while it turns from heading ``psi`` onto the route: the
    bearing of the route's point ``lookahead`` m along it (or its end), times ``metres_per_rad`` (speed over turn
    rate: a unicycle turns in place at w_max), spec [X] ``route_turn_cost``."""
    arc = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(points, axis=0).T))))
    d = points[min(int(np.searchsorted(arc, lookahead)), len(points) - 1)] - points[0]
    turn = abs(wrap(math.atan2(d[1], d[0]) - psi)) if d[0] or d[1] else 0.0
    return float(arc[-1]) + metres_per_rad * turn


def _altitude_target(view, mem: _UAVMemory, cfg: ExpertConfig) -> float:
    """The altitude a UAV flies to. A follower: its slot's (``view.slot``, placed by ``formation.formation_slots``:
    z_ref + dz for version-1 missions, the leader's altitude + dz otherwise). The leader: its cruise altitude
    (where it started) until the goal is near, then a glide path of slope ``glide_slope`` (altitude change per
    horizontal metre) down or up to the goal's altitude (kept inside the altitude band), reached at ``dock_radius``
    from the goal."""
    if not view.is_leader:
        return float(view.slot[2])
    if mem.cruise_z is None:
        mem.cruise_z = float(view.state[2])
    z_goal = clamp(float(view.goal[2]), view.limits.z_min, view.limits.z_max)
    rise = mem.cruise_z - z_goal
    if rise == 0.0:
        return z_goal
    d = math.hypot(view.goal[0] - view.state[0], view.goal[1] - view.state[1])
    return z_goal + math.copysign(min(abs(rise), cfg.glide_slope * max(0.0, d - cfg.dock_radius)), rise)


def _leader_at_goal(view, cfg: ExpertConfig) -> bool:
    """Whether the leader's broadcast shows it parked (``rules.leader_parked``) within ``arrive_radius`` of the goal."""
    lead = view.leader_state
    return leader_parked(view, cfg) and math.hypot(view.goal[0] - lead[0], view.goal[1] - lead[1]) < cfg.arrive_radius


def _hold_obstacles(view, cfg: ExpertConfig, reach: float) -> np.ndarray:
    """What a holding UAV keeps clear of, within ``reach`` horizontally: its own map's voxels near its altitude
    (within r_uav + r_safe + one voxel), projected onto it, and the world's bounds (``geofence_spacing`` apart)."""
    lim = view.limits
    pos = view.state[:3]
    band = lim.r_uav + lim.r_safe + view.occupancy.resolution
    voxels, _ = view.occupancy.occupied_in_sphere(pos, reach + band)
    near = project_to_altitude(voxels, pos[2], band)
    return np.concatenate([near, geofence_points(pos, reach, view.bounds_lo, view.bounds_hi, cfg.geofence_spacing)])


def _goal_in_band(view) -> bool:
    """Whether a UAV inside the altitude band [z_min, z_max] can come within the env's r_goal of the goal: a goal
    further above or below is unreachable (the leader reports ``stuck`` and holds, issue 13)."""
    lim, r_goal, z = view.limits, view.config.episode.r_goal, float(view.goal[2])
    return lim.z_min - r_goal < z < lim.z_max + r_goal


def _occupied_within(view, local: _Local, point: np.ndarray, radius: float) -> bool:
    """``view.occupancy.occupied_within(point, radius)``, answered from the cycle's local voxels when they hold every
    voxel that query could find (leaf level, the ball around ``point`` inside the local sphere with a voxel to
    spare): any leaf centre at squared distance <= radius^2, the map kernel's test in its arithmetic."""
    near = math.dist(point.tolist(), view.state[:3].tolist()) + radius + view.occupancy.resolution
    if local.level == 0 and near <= local.reach:
        return not segment_clear(local.obstacles, point, point, radius)    # a point segment: the ball's test
    return view.occupancy.occupied_within(point, radius)


def _raster_for(view, res: float) -> Raster:
    origin, shape = grid_frame(view.bounds_lo[:2], view.bounds_hi[:2], res)
    return Raster(tuple(origin), res, shape)


def _mark(blocked: np.ndarray, raster: Raster, xy: np.ndarray) -> None:
    """Block the raster cells containing the points ``xy`` (K, 2); points outside the raster are ignored."""
    mark_cells(blocked, float(raster.origin[0]), float(raster.origin[1]), float(raster.res),
               np.ascontiguousarray(xy, dtype=np.float64))


def _level_way(r, cfg: ExpertConfig, target_dir: np.ndarray) -> bool:
    """Whether an open cell of the two level rows lies within ``level_window`` of the target azimuth."""
    if cfg.level_window <= 0.0:
        return False
    return open_level_way(r.window_open, cfg.vfh.alpha_h, math.atan2(target_dir[1], target_dir[0]), cfg.level_window)


def _gap_altitude(view, mem, target_xy, z_pref: float, cfg: ExpertConfig) -> float | None:
    """The altitude to pass through a known vertical gap when the level way toward the target is blocked.

    The own map's columns along the line to the target (out to ``gap_lookahead``) are tested at the
    preferred altitude; if occupied voxels block that level, the known-free vertical runs of those
    columns (tall enough for the UAV and its margin, inside the altitude band) are intersected and
    the altitude nearest ``z_pref`` inside the common run, ``gap_margin`` (plus the vertical gust standoff,
    ``vertical_margin``) off its edges, is returned. Unknown voxels do not count as free here: a gap has to be
    seen before the UAV commits to it. None: the level is clear, or no gap.
    """
    lim = view.limits
    occ = view.occupancy
    res = occ.resolution
    pos = view.state[:3]
    dx, dy = float(target_xy[0]) - float(pos[0]), float(target_xy[1]) - float(pos[1])   # floats: no array glue
    dist = math.hypot(dx, dy)
    if dist < 1e-6:
        return None
    span = max(1, int(round(cfg.gap_depth / res)))
    gap_margin = cfg.gap_margin + (gust_standoff(mem, cfg, cfg.wind_margin, lim.r_safe, vertical=True)
                                   if cfg.vertical_margin else 0.0)
    best = gap_altitude_kernel(tuple(occ.arrays()), occ.origin, res, pos, dx / dist, dy / dist,
                               float(min(cfg.gap_lookahead, dist + res)), z_pref, span, lim.r_uav + lim.r_safe,
                               lim.z_min, lim.z_max, gap_margin, cfg.gap_unseen_wall)
    return None if math.isnan(best) else best


_ORIGIN = np.zeros(2)
_ORIGIN.flags.writeable = False


def _rotated(psi: float, offsets: np.ndarray) -> np.ndarray:
    """Body-frame ``offsets`` (K, 3) turned by the heading ``psi`` into world-frame x, y (K, 2): the slots of
    ``slot_positions`` about the origin, to which the caller adds the (predicted) leader position."""
    return slot_positions(_ORIGIN, psi, offsets, 0.0)[:, :2]


def _files(cfg: ExpertConfig) -> bool:
    """Whether the column fallback of (g7) files along the leader's trail (``column_shape="trail"``)."""
    return cfg.shape_switching and cfg.column_shape == "trail"


def _column_offsets(offsets: np.ndarray, spacing: float) -> np.ndarray:
    """(g7) ``shape_switching``: the slot offsets (K, 3) of the column (single file) behind the leader, ``spacing``
    apart, each UAV at its own formation slot's height offset."""
    column = np.zeros_like(offsets)
    column[:, 0] = -np.arange(offsets.shape[0]) * spacing
    column[:, 2] = offsets[:, 2]
    return column


def _follower_errors(view) -> np.ndarray:
    """Horizontal slot errors of the followers, from their broadcasts and the leader's own pose."""
    s = view.state
    return slot_errors(float(s[0]), float(s[1]), float(np.cos(s[PSI])), float(np.sin(s[PSI])), view.offsets,
                       view.neighbour_ids, view.neighbour_states, view.neighbour_alive)


def _slot_brake_cap(v_leader: float, distance: float, a_max: float) -> float:
    """[X] ``slot_brake``: the highest speed from which a follower ``distance`` m from its slot stops, braking at
    ``a_max``, no farther than the slot will have moved when a leader at ``v_leader`` brakes as hard."""
    return math.sqrt(v_leader * v_leader + 2.0 * a_max * distance)


def _pursuit_cap(state, point, lim, v_cap: float, clear=None) -> float:
    """``v_cap`` lowered to the speed at which the turn-rate limit still steers onto ``point`` (pure pursuit); with
    ``clear`` = (voxel centres, clearance), on the largest turn of ``clear_turn_radius`` that clears them
    (``pursuit_clear``)."""
    d = (float(point[0]) - float(state[0]), float(point[1]) - float(state[1]))   # floats: no array glue
    dist = math.hypot(d[0], d[1])
    theta = abs(bearing_error(state, d)) if dist > 1e-9 else 0.0
    reach = dist / 2.0 if theta >= math.pi / 2 else dist / (2.0 * math.sin(theta)) if theta > 1e-9 else math.inf
    if clear is not None and len(clear[0]) and math.isfinite(reach):
        x, y, z, psi, v = (float(state[i]) for i in (0, 1, 2, PSI, V))
        reach = clear_turn_radius(x, y, z, psi, v, float(point[0]), float(point[1]), reach, clear[0], clear[1],
                                  lim.w_max, lim.a_max)
    return min(v_cap, lim.w_max * reach)


def _predict_unicycle(state, horizon: float, dt: float):
    """Pose (xy, psi) after ``horizon`` at constant (v, w) with the model of spec (a) (yaw first, closed form sum)."""
    n = max(1, round(horizon / dt))
    k = np.arange(1, n + 1)
    psi = state[PSI] + k * state[W] * dt
    x = state[0] + np.sum(state[V] * np.cos(psi) * dt)
    y = state[1] + np.sum(state[V] * np.sin(psi) * dt)
    return np.array([x, y]), float(psi[-1])


def _park_slots(view, psi: float) -> np.ndarray:
    """The followers' slots (K, 3; UAVs 1..K, the leader's ``neighbour_ids`` order) of a leader parked at its position
    with heading ``psi`` (at the goal's altitude)."""
    at_goal = np.array([view.state[0], view.state[1], view.goal[2]])
    return formation_slots(at_goal, psi, view.offsets[1:], view.z_ref, view.slot_altitude)


def _slots_free(view, slots: np.ndarray, margin: float) -> bool:
    """Whether every follower slot (``_park_slots``) is free in the leader's own map."""
    for slot in slots:
        if np.any(slot[:2] < view.bounds_lo[:2] + margin) or np.any(slot[:2] > view.bounds_hi[:2] - margin):
            return False
        if view.occupancy.occupied_within(slot, margin):
            return False
    return True


def _slots_unmarked(slots: np.ndarray, marks: np.ndarray, radius: float) -> bool:
    """Whether no follower slot (``_park_slots``) lies within ``radius`` (horizontally) of a marked point (``marks``,
    (K, 2): slots a follower did not reach, ``repark_time``)."""
    if len(marks) == 0:
        return True
    xy = slots[:, :2]
    return bool(np.all(((xy[:, None, :] - marks[None, :, :]) ** 2).sum(axis=2) >= radius * radius))


def _mark_unreached_slots(view, mem: _UAVMemory, cfg: ExpertConfig, t: float) -> None:
    """[X] ``repark_time``: the parked leader's watch over its followers (broadcasts) on the park heading
    ``mem.park_psi``. A live follower at least e_f from its slot whose 3D slot distance has not dropped by
    ``trail_spacing`` for ``repark_time`` s gets that slot point (x, y) added to ``mem.park_marks``, which
    ``_park_heading`` keeps every slot ``repark_radius`` away from. A new park heading restarts the watch."""
    slots = _park_slots(view, mem.park_psi)
    err = np.linalg.norm(view.neighbour_states[:, :3] - slots, axis=1)
    if mem.park_watch is None or mem.park_watch[0] != mem.park_psi:
        mem.park_watch = (mem.park_psi, err, np.full(err.shape, t))
        return
    _, best, since = mem.park_watch
    gained = err <= best - cfg.trail_spacing
    best[gained], since[gained] = err[gained], t
    unreached = view.neighbour_alive & (err >= view.config.formation.e_f) & (t - since >= cfg.repark_time)
    if unreached.any():
        mem.park_marks = np.vstack([mem.park_marks, slots[unreached, :2]])
        mem.park_watch = None


def _park_heading(view, mem: _UAVMemory, cfg: ExpertConfig, n: int = 72) -> float:
    """The parked leader's heading: the one it parked on while those slots stay free (and unmarked), else one of the
    headings (its own, then turned outward in steps of 2 pi / ``n``) with free slots, chosen by ``cfg.park_heading``,
    among those whose slots keep ``repark_radius`` from the slots followers did not reach (``repark_time``) when any
    does; none frees every slot: its own."""
    lim = view.limits
    margin = lim.r_uav + lim.r_safe + view.occupancy.resolution
    marks, radius = mem.park_marks, cfg.repark_radius
    if mem.park_psi is not None:
        slots = _park_slots(view, mem.park_psi)
        if _slots_free(view, slots, margin) and _slots_unmarked(slots, marks, radius):
            return mem.park_psi
    psi = float(view.state[PSI])
    turns = [psi] + [wrap(psi + sign * k * 2.0 * math.pi / n) for k in range(1, n // 2 + 1) for sign in (1.0, -1.0)]
    candidates = [(cand, _park_slots(view, cand)) for cand in turns]     # each heading's slots, built once
    free = [(cand, slots) for cand, slots in candidates if _slots_free(view, slots, margin)]
    unmarked = [cand for cand, slots in free if _slots_unmarked(slots, marks, radius)]
    free = unmarked or [cand for cand, _ in free]
    if cfg.park_heading == "nearest":
        mem.park_psi = free[0] if free else psi
    else:
        mem.park_psi = _heading_nearest_followers(view, free, psi)
    return mem.park_psi


def _heading_nearest_followers(view, headings: list, default: float) -> float:
    """Of ``headings``, the one whose slots lie nearest the live followers' broadcast positions (the sum of the
    horizontal distances; the first on a tie); ``default`` when ``headings`` is empty."""
    if not headings:
        return default
    alive = view.neighbour_alive
    if not alive.any():
        return headings[0]
    followers = view.neighbour_states[alive, :2]
    offsets = view.offsets[view.neighbour_ids[alive]]
    cost = [float(np.hypot(*(view.state[:2] + _rotated(h, offsets) - followers).T).sum()) for h in headings]
    return headings[int(np.argmin(cost))]


def _climb_rate(elevation: float, v: float, dz_goal: float, cfg: ExpertConfig, lim) -> float:
    """Vertical speed of CLIMB along 3D VFH+'s elevation; with ``climb_target_limit``, when that climb heads
    for the target altitude (error ``dz_goal``) it is at most ``k_z * |dz_goal|``, so it does not overshoot."""
    vz = clamp(max(v, 0.3) * math.tan(elevation), -lim.vz_max, lim.vz_max)
    if cfg.climb_target_limit and vz * dz_goal > 0.0:
        vz = math.copysign(min(abs(vz), cfg.k_z * abs(dz_goal)), vz)
    return vz


class StandardDWA(FusionExpert):
    """Planar formation with the standard DWA of spec (b): fixed altitude, no 3D VFH+."""

    def __init__(self, config: ExpertConfig | None = None):
        super().__init__(config or ExpertConfig.planar("DWA"))


def planar_formation(ablation: str):
    """A factory for the planar formation with one DWA ablation (``DWA+E8``, ``DWA+E8+E10``, ``IDWA``)."""
    def make():
        return FusionExpert(ExpertConfig.planar(ablation))
    make.__name__ = f"planar_{ablation}"
    return make

