"""The fusion expert of spec (g): A* + improved DWA in the plane, 3D VFH+ for the vertical, in a
distributed leader-follower formation controller.

Every UAV runs the same cycle (g3) on its own onboard view: target (leader: goal and A* lookahead;
follower: the slot predicted over the DWA horizon), 3D VFH+ on its own map, a debounced vertical
decision (g4), then DWA with a 3D-aware clearance (g5) and the neighbours as moving obstacles (g6).
All weights and thresholds live in one ``ExpertConfig``; ``act(..., weights=...)`` overrides the
evaluation weights per UAV and step (the residual-RL interface). The same class with
``use_vfh=False`` is the planar (2D, fixed-altitude) formation used by the DWA baselines.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numba
import numpy as np

from uavform_env.config import _check_choice, _check_int, _check_range, _Config
from uavform_env.dynamics import PSI, V, VZ, W, commands_to_actions, wrap
from uavform_env.occupancy import voxel_logodds
from uavform_env.world import grid_frame

from .astar import AStarConfig, GlobalPath, Raster, inflate, plan_path, replan_trigger
from .dwa import DWAConfig, dwa_plan
from .policy import OnboardPolicy
from .vfh3d import VFHConfig, VFHState, vfh3d_step

LEVEL, CLIMB, BLOCKED = "level", "climb", "blocked"
WEIGHT_NAMES = ("alpha0", "beta", "gamma", "eps0", "k1", "k2", "k3")
ASTAR_LAYERS = ("passable", "band")
REJOIN_MODES = ("astar", "trail")


@dataclass(frozen=True)
class ExpertConfig(_Config):
    """Every weight and threshold of the fusion controller (spec (g), Appendix A 'formation').

    use_vfh            3D fusion (True) or the planar formation of the 2D baselines (False)
    neighbour_prediction  neighbours move at their broadcast velocity in DWA (g6; E6 switches it off)
    shape_switching    a follower whose slot is blocked in its own map falls back to a column slot (g7) [X]
    astar_layer        "passable": a raster cell blocks only where no free vertical gap is left in the
                       altitude band (the fusion controller may climb); "band": any obstacle at the
                       formation altitude blocks (planar controllers) [X]
    dwa_map_level      octree level whose voxels form DWA's obstacle set (0 = the 0.2 m leaves; a coarser
                       level means fewer points but a pyramid refresh every step) [X]
    replan_check_period  how often (s) the leader rebuilds its raster and tests the (d5) triggers [X]
    leader_stopped_speed  below this leader speed a follower's speed reference uses its whole slot error, not
                       the along-track part of (g2), so it closes on a parked slot from the side too, scaled
                       by the cosine of its bearing error (0 beyond 90 degrees): a unicycle that keeps its
                       speed while its target is abeam orbits the target instead of reaching it; its target
                       point is then the slot itself, without the ``k_h`` lead along the leader's heading [X]
    dock_turn_angle    a follower of a parked leader that is itself below ``leader_stopped_speed`` turns in
                       place toward its target when that lies more than this far off its nose and at least
                       e_f / 2 away; DWA's rotation cost and sum-normalised heading term otherwise hold it at
                       rest there (w = 0 wins at v = 0) [X]
    pursuit_speed_cap  cap the speed at w_max / kappa, kappa = 2 sin(theta) / d the pure-pursuit curvature onto the
                       lookahead point (distance d, bearing theta off the nose; d / 2 beyond 90 degrees): the
                       turn-rate limit then lets the UAV steer onto the point instead of overshooting a corner
                       of its path (a leader passed a wall's opening 0.5 m/s too fast and followed the wall) [X]
    final_approach_free  closing on a fixed target (the leader on its goal, a follower on a parked slot) within
                       ``dock_radius`` along a straight segment clear by r_uav + r_safe, DWA drops its dist term
                       (beta = 0; admissibility still holds the clearance): at rest, the centimetres of clearance
                       a first step would cost outscored the goal terms, and a follower froze 0.5 m from its
                       slot beside a tree [X]
    reverse_turn_angle  a UAV steering by a path's lookahead point (the leader; a rejoining follower) turns in place
                       when that point lies more than this far off its nose: DWA turns through a wide circle
                       (a follower circled a whole wall's side to reach a point behind it) [X]
    dock_radius        the leader, within this distance of the goal with the goal more than ``dock_turn_angle`` off
                       its nose, brakes and turns in place toward it: DWA otherwise flies past a goal abeam at
                       0.5 m and parks against whatever lies beyond (the world's bound) [X]
    e0, e1, min_leader_scale  leader formation feedback of (g2): its speed cap scales from 1 at a mean follower
                       error e0 down to min_leader_scale at e1 [D: the spec's 1 m, 3 m, 0.3 held a forest
                       formation, which is always stretched, at 0.24 m/s]
    vfh_neighbour_radius  neighbours closer than this become 3D VFH+ pseudo-voxels (g6); farther ones are
                       left to DWA, so the formation's own members do not close the level gaps [X]
    level_line         LEVEL also when the straight segment to the target point keeps r_uav + r_safe + a voxel's
                       half-diagonal from every occupied voxel of the own map: 3D VFH+'s enlargement closes
                       passages DWA flies through (a 2.5 m corridor's mouth read as blocked, and the UAV climbed
                       the corridor wall) [X]
    level_window       LEVEL also when an open level cell lies within this angle of the target azimuth:
                       DWA detours horizontally rather than climbing over what it can fly around [X]
    geofence_spacing   the world's x/y bounds enter DWA as walls of points this far apart [X]
    rejoin_distance, rejoin  a follower farther than this from its slot rejoins along a path: ``"astar"``, an A*
                       path to the slot on its own map (the leader's raster and (d5) triggers, plus a replan when
                       the slot has moved ``astar.d_replan`` from the planned goal); ``"trail"``, the leader's
                       broadcast trail (points ``trail_spacing`` apart, progress searched ``trail_window`` points
                       ahead), in single file through clutter. A follower heading straight for a slot behind a
                       wall slides along it (3D VFH+ offers only the ways along the face) [X]
    rejoin_hidden      also rejoin when the straight segment to the slot passes within r_uav + a voxel's half-diagonal
                       of an occupied voxel of the own map (the slot is behind an obstacle, however near) [X]
    arrive_radius      the leader stops once this close to the goal (horizontally) and holds there for the rest
                       of the mission (the DWA stopping rule of (b10)); the default DWA's approach speed
                       profile brakes to rest 0.1 m from the goal (``dwa.r_goal``, inside ``arrive_radius``):
                       braking to rest at 0.5 m parks the leader on the rim of the env's success sphere,
                       never inside ``arrive_radius`` [X]
    stuck_window       the leader also reports ``stuck`` when its horizontal goal distance has not dropped by
                       ``trail_spacing`` for this long (s): DWA can hold it at rest with admissible samples [X]
    gap_lookahead, gap_depth, gap_margin, k_gap  the known-gap altitude rule of the vertical decision: when
                       no open level way lies within ``level_window`` of the target and the own map shows a
                       blocked level within ``gap_lookahead`` m ahead, fly to the altitude of the known-free
                       vertical run through the next ``gap_depth`` m of obstacle (3D VFH+'s 5x5 window cannot
                       resolve gaps of about 2 m) with altitude gain ``k_gap``, at most ``gap_speed`` m/s
                       and with leaf voxels as DWA obstacles while it passes [X]
    climb_target_limit in CLIMB, when 3D VFH+'s elevation points toward the target altitude, the climb rate is
                       at most ``k_z`` times the altitude error: the 5-degree elevation cells never give 0,
                       so a follower parked at its slot (target ~1 m away) otherwise oscillates +/- 1 m
                       around the slot altitude and never closes the formation [X]
    lateral_emergency_to_dwa  an emergency of (g5) (a voxel or neighbour inside 3D VFH+'s r_e) whose nearest voxel
                       lies more beside the UAV than above or below it, or which no voxel within r_e raised (a
                       neighbour did), is left to DWA, whose admissibility keeps the clearance and the separation:
                       the spec's stop-and-climb away never ends beside a floor-to-ceiling wall (a follower froze
                       at a corridor's mouth), nor beside a parked leader [X]
    park_turn          the parked leader turns in place (v = 0) to the heading nearest its own whose follower
                       slots are all free in its own map and inside the world bounds: parked at the goal, it
                       can otherwise leave a slot inside an obstacle, and the formation can never close [X]
    """

    dwa: DWAConfig = field(default_factory=lambda: DWAConfig.ablation("IDWA", approach_speed_profile=True,
                                                                                      r_goal=0.1, dist_cap=0.5))
    vfh: VFHConfig = field(default_factory=VFHConfig)
    astar: AStarConfig = field(default_factory=lambda: AStarConfig(prune=True, heading_target="visible_goal"))
    use_vfh: bool = True
    neighbour_prediction: bool = True
    shape_switching: bool = True
    astar_layer: str = "passable"
    dwa_map_level: int = 0
    replan_check_period: float = 0.5
    k_f: float = 0.5
    leader_stopped_speed: float = 0.05
    dock_turn_angle: float = math.radians(45.0)
    dock_radius: float = 1.5
    reverse_turn_angle: float = math.radians(100.0)
    final_approach_free: bool = True
    pursuit_speed_cap: bool = True
    k_h: float = 1.0
    k_z: float = 0.5
    leader_speed_cap: float = 0.8
    e0: float = 1.5
    e1: float = 5.0
    min_leader_scale: float = 0.5
    debounce: int = 3
    T_stuck: float = 5.0
    climb_lookahead: float = 3.0
    yield_factor: float = 0.5
    column_hold: float = 3.0
    vfh_neighbour_radius: float = 2.0
    level_window: float = math.radians(30.0)
    level_line: bool = True
    geofence_spacing: float = 0.4
    rejoin_distance: float = 4.0
    rejoin: str = "astar"
    rejoin_hidden: bool = True
    trail_spacing: float = 0.25
    trail_window: int = 400
    arrive_radius: float = 0.3
    stuck_window: float = 10.0
    gap_lookahead: float = 4.0
    gap_depth: float = 1.0
    gap_margin: float = 0.1
    k_gap: float = 1.0
    gap_speed: float = 0.3
    climb_target_limit: bool = True
    park_turn: bool = True
    lateral_emergency_to_dwa: bool = True

    def __post_init__(self):
        o = "ExpertConfig"
        for name, cls in (("dwa", DWAConfig), ("vfh", VFHConfig), ("astar", AStarConfig)):
            if not isinstance(getattr(self, name), cls):
                raise ValueError(f"{o}.{name}: expected a {cls.__name__}")
        for name in ("use_vfh", "neighbour_prediction", "shape_switching", "climb_target_limit", "park_turn",
                     "lateral_emergency_to_dwa", "level_line", "pursuit_speed_cap",
                     "rejoin_hidden", "final_approach_free"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"{o}.{name}={getattr(self, name)!r}: expected a bool")
        _check_choice(o, "astar_layer", self.astar_layer, ASTAR_LAYERS)
        _check_choice(o, "rejoin", self.rejoin, REJOIN_MODES)
        _check_int(o, "dwa_map_level", self.dwa_map_level, 0, 4)
        _check_int(o, "debounce", self.debounce, 1, 100)
        _check_int(o, "trail_window", self.trail_window, 1)
        for name in ("replan_check_period", "k_f", "k_h", "k_z", "T_stuck", "climb_lookahead", "column_hold",
                     "vfh_neighbour_radius", "rejoin_distance", "dock_radius", "trail_spacing", "arrive_radius",
                     "stuck_window",
                     "gap_lookahead", "gap_depth", "gap_margin",
                     "k_gap", "gap_speed", "leader_stopped_speed"):
            _check_range(o, name, getattr(self, name), 0.0, None)
        _check_range(o, "leader_speed_cap", self.leader_speed_cap, 0.0, 1.0, lo_open=True)
        _check_range(o, "yield_factor", self.yield_factor, 0.0, 1.0)
        _check_range(o, "min_leader_scale", self.min_leader_scale, 0.0, 1.0)
        _check_range(o, "level_window", self.level_window, 0.0, math.pi)
        _check_range(o, "dock_turn_angle", self.dock_turn_angle, 0.0, math.pi)
        _check_range(o, "reverse_turn_angle", self.reverse_turn_angle, 0.0, math.pi)
        _check_range(o, "geofence_spacing", self.geofence_spacing, 0.05, None)
        _check_range(o, "e0", self.e0, 0.0, None)
        _check_range(o, "e1", self.e1, self.e0, None, lo_open=True)

    @classmethod
    def planar(cls, ablation: str = "IDWA", **overrides) -> "ExpertConfig":
        """The 2D formation: fixed altitude, no 3D VFH+, the named DWA ablation, band raster for A*."""
        return cls(dwa=DWAConfig.ablation(ablation), use_vfh=False, astar_layer="band", **overrides)

    def weights(self) -> np.ndarray:
        """The evaluation weights in ``WEIGHT_NAMES`` order (DWA alpha0, beta, gamma, eps0; VFH k1, k2, k3)."""
        d, v = self.dwa, self.vfh
        return np.array([d.alpha0, d.beta, d.gamma, d.eps0, v.k1, v.k2, v.k3])

    def with_weights(self, w) -> "ExpertConfig":
        w = np.asarray(w, dtype=np.float64)
        if w.shape != (len(WEIGHT_NAMES),) or not np.all(np.isfinite(w)) or np.any(w < 0):
            raise ValueError(f"weights: expected {len(WEIGHT_NAMES)} finite values >= 0 in the order {WEIGHT_NAMES}, "
                             f"got {w.tolist() if w.size < 20 else w.shape}")
        dwa = replace(self.dwa, alpha0=w[0], alpha=w[0], beta=w[1], gamma=w[2], eps0=w[3])
        vfh = replace(self.vfh, k1=w[4], k2=w[5], k3=w[6])
        return replace(self, dwa=dwa, vfh=vfh)


@dataclass
class _UAVMemory:
    """What one UAV's controller remembers between cycles."""

    vfh: VFHState = field(default_factory=VFHState)
    mode: str = LEVEL
    pending: str = LEVEL
    pending_count: int = 0
    stuck_time: float = 0.0
    prev_alignment: float = 1.0
    column_until: float = -1.0
    path: GlobalPath | None = None
    path_found: bool = True
    plan_goal: np.ndarray | None = None
    goal_visible: bool = True
    on_path: bool = False
    last_plan_time: float = -1e9
    last_check_time: float = -1e9
    replans: int = 0
    trail: list = field(default_factory=list)
    trail_progress: int = 0
    arrived: bool = False
    park_psi: float | None = None
    best_goal_distance: float = math.inf
    last_progress_time: float = 0.0


class FusionExpert(OnboardPolicy):
    """The paper's fusion planner as a distributed formation controller (see the module docstring)."""

    def __init__(self, config: ExpertConfig | None = None):
        self.config = config if config is not None else ExpertConfig()
        if not isinstance(self.config, ExpertConfig):
            raise ValueError(f"config: expected an ExpertConfig, got {type(self.config).__name__}")

    def reset(self, env, seed: int | None = None) -> None:
        super().reset(env, seed)
        base = self.env
        self.memory = {a: _UAVMemory() for a in base.possible_agents}
        self._leader_prediction = (None, None)
        lead = base.onboard(base.possible_agents[0])
        self.raster = _raster_for(lead, self.config.astar.res_g)
        if lead.prior.kind != "none" and self._plan(lead, self.memory[lead.agent], 0.0, lead.goal[:2]) is None:
            raise ValueError(f"infeasible mission: the goal {lead.goal.tolist()} cannot be reached from the start "
                             f"{lead.state[:3].tolist()} on the prior map ({lead.prior.kind}) with the "
                             f"'{self.config.astar_layer}' raster of this controller")

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
        mem = self.memory[view.agent]
        lim = view.limits
        s = view.state
        t = view.step * lim.dt
        pos = s[:3]
        if view.crashed:
            return np.zeros(3)

        z_slot = view.z_ref + view.slot_offset[2]
        if view.is_leader and math.hypot(view.goal[0] - pos[0], view.goal[1] - pos[1]) < cfg.arrive_radius:
            mem.arrived = True
        if view.is_leader and mem.arrived:
            self.diagnostics[view.agent] = {"mode": mem.mode, "stuck": False, "arrived": True, "replans": mem.replans}
            w_c = 0.0
            if cfg.park_turn:
                psi_park = _park_heading(view, mem, cfg)
                w_c = _clamp(wrap(psi_park - s[PSI]), -lim.w_max, lim.w_max)
            return np.array([0.0, w_c, _clamp(cfg.k_z * (z_slot - pos[2]), -lim.vz_max, lim.vz_max)])
        level = cfg.dwa_map_level
        vox_size = view.occupancy.resolution * (2 ** level)
        reach = lim.v_max * cfg.dwa.T_p + cfg.dwa.D_cap + lim.r_uav + vox_size
        obstacles, obstacle_probs = view.occupancy.occupied_in_sphere(pos, reach, level=level)
        radius = vox_size * math.sqrt(3.0) / 2.0
        if view.is_leader:
            goal, lookahead, v_cap, v_ref = self._leader_target(view, mem, cfg, t)
            if goal is None:                                    # unreachable: hold position safely
                self.diagnostics[view.agent] = {"mode": mem.mode, "stuck": True, "unreachable": True,
                                                "replans": mem.replans}
                return np.array([0.0, 0.0, _clamp(cfg.k_z * (z_slot - pos[2]), -lim.vz_max, lim.vz_max)])
        else:
            slot_hidden = cfg.rejoin_hidden and not _segment_clear(obstacles, pos, view.slot, lim.r_uav + radius)
            goal, lookahead, v_cap, v_ref = self._follower_target(view, mem, cfg, t, slot_hidden)

        if cfg.pursuit_speed_cap:
            v_cap = _pursuit_cap(s, lookahead, lim.w_max, lim.v_max if v_cap is None else v_cap)
        movers_pos, movers_vel = self._neighbours(view, cfg)
        v_cap = self._yield(view, movers_pos, movers_vel, cfg, v_cap)

        fence = _geofence(pos, reach, view.bounds_lo, view.bounds_hi, cfg.geofence_spacing)

        vz_cmd = _clamp(cfg.k_z * (z_slot - pos[2]), -lim.vz_max, lim.vz_max)
        heading_goal = goal
        vfh_result = None
        emergency = False
        if cfg.use_vfh:
            if level == 0 and reach >= cfg.vfh.R_w:             # the same voxels, in the same order, as a query
                centres, probs = _in_sphere(obstacles, obstacle_probs, pos, cfg.vfh.R_w)
            else:
                centres, probs = view.occupancy.occupied_in_sphere(pos, cfg.vfh.R_w)
            gap_z = _gap_altitude(view, lookahead, z_slot, cfg)
            z_goal = z_slot if gap_z is None else gap_z
            target = np.array([lookahead[0], lookahead[1], z_goal])
            if math.dist(target, pos) < 1e-6:             # on the target: 3D VFH+ looks along the heading
                target = pos + np.array([math.cos(s[PSI]), math.sin(s[PSI]), 0.0])
            close = view.neighbour_alive & (np.linalg.norm(movers_pos - pos, axis=1) < cfg.vfh_neighbour_radius)
            vfh_result = vfh3d_step(mem.vfh, cfg.vfh, lim, pos, s[PSI], s[V], s[VZ], target - pos, centres, probs,
                                    view.occupancy.resolution, movers_pos[close])
            emergency = vfh_result.emergency
            level_way = _level_way(vfh_result, cfg, target - pos) or (
                cfg.level_line and _segment_clear(centres, pos, target, lim.r_uav + lim.r_safe
                                                  + view.occupancy.resolution * math.sqrt(3.0) / 2.0))
            mode = self._debounced_mode(mem, vfh_result, cfg, level_way, gap_z is not None)
            if mode == CLIMB and gap_z is not None:
                vz_cmd = _clamp(cfg.k_gap * (gap_z - pos[2]), -lim.vz_max, lim.vz_max)
                v_cap = cfg.gap_speed if v_cap is None else min(v_cap, cfg.gap_speed)
                if level > 0:                       # a gap leaves centimetres: use the leaf voxels
                    obstacles, _ = view.occupancy.occupied_in_sphere(pos, reach, level=0)
                    radius = view.occupancy.resolution * math.sqrt(3.0) / 2.0
            elif mode == CLIMB and not vfh_result.blocked:
                vz_cmd = _climb_rate(vfh_result.elevation, s[V], z_goal - pos[2], cfg, lim)
            elif mode == BLOCKED:
                vz_cmd = 0.0
            if not vfh_result.blocked and not level_way and gap_z is None:
                az = vfh_result.azimuth             # follow 3D VFH+ around what DWA cannot see past
                heading_goal = pos[:2] + cfg.climb_lookahead * np.array([math.cos(az), math.sin(az)])
        else:
            obstacles = _project_to_altitude(obstacles, pos[2], lim.r_uav + lim.r_safe + radius)
            mem.mode = LEVEL

        clearance_now = _clearance(pos, obstacles, radius, lim.r_uav)
        dwa_cfg = cfg.dwa
        if cfg.final_approach_free and self._final_approach(view, goal, obstacles, radius, cfg):
            dwa_cfg = replace(dwa_cfg, beta=0.0)
        radii = np.full(len(obstacles), radius)
        if len(fence):
            obstacles = np.concatenate([obstacles, fence])
            radii = np.concatenate([radii, np.zeros(len(fence))])
        alive_pos, alive_vel = movers_pos[view.neighbour_alive], movers_vel[view.neighbour_alive]
        def plan(vz):
            return dwa_plan(s, lim, dwa_cfg, heading_goal, obstacles, radii, vz_cmd=vz, lookahead=lookahead,
                            clearance_now=clearance_now, movers_pos=alive_pos, movers_vel=alive_vel, v_ref=v_ref,
                            v_cap=v_cap, prev_alignment=mem.prev_alignment)

        res = plan(vz_cmd)
        if not res.admissible and vz_cmd != 0.0:
            held = plan(0.0)                     # the climb itself may be what collides: try holding altitude
            if held.admissible:
                res, vz_cmd = held, 0.0
        mem.prev_alignment = res.alignment if math.isfinite(res.alignment) else 1.0
        v_c, w_c = res.v, res.w
        if not res.admissible:
            mem.stuck_time += lim.dt
            w_c = _turn_toward(s, heading_goal - pos[:2], lim.w_max)
            if cfg.use_vfh and mem.stuck_time >= cfg.T_stuck and vfh_result is not None:
                vz_cmd = _vertical_escape(vfh_result, lim)
        else:
            mem.stuck_time = 0.0
        to_goal = (view.goal[:2] if view.is_leader else goal) - pos[:2]
        if view.is_leader:
            docking = math.hypot(to_goal[0], to_goal[1]) < cfg.dock_radius
        else:
            docking = (_leader_parked(view, cfg) and s[V] < cfg.leader_stopped_speed
                       and math.hypot(to_goal[0], to_goal[1]) >= view.config.formation.e_f / 2)
        to_lookahead = lookahead - pos[:2]
        if docking and abs(_bearing_error(s, to_goal)) > cfg.dock_turn_angle:
            v_c, w_c = 0.0, _turn_toward(s, to_goal, lim.w_max)           # turn in place toward a parked slot
        elif mem.on_path and abs(_bearing_error(s, to_lookahead)) > cfg.reverse_turn_angle:
            v_c, w_c = 0.0, _turn_toward(s, to_lookahead, lim.w_max)      # the path doubles back: turn in place
        vz_away = None
        if emergency and vfh_result is not None:
            r_e = cfg.vfh.resolve(lim, view.occupancy.resolution)[0]
            vz_away = _away_vertically(pos, view.occupancy, r_e, lim, cfg.lateral_emergency_to_dwa)
        if vz_away is not None:
            v_c, vz_cmd = 0.0, vz_away
            alive = view.neighbour_alive
            if _closes_on_movers(pos, vz_cmd, movers_pos[alive], movers_vel[alive], cfg.dwa, lim):
                vz_cmd = 0.0                    # the escape would fly into a neighbour (above or below)
        self.diagnostics[view.agent] = {
            "mode": mem.mode, "stuck": not res.admissible or self._no_progress(view, mem, cfg, t),
            "n_admissible": res.n_admissible,
            "vfh_blocked": bool(vfh_result.blocked) if vfh_result is not None else False, "emergency": emergency,
            "replans": mem.replans, "path_found": mem.path_found, "column": t < mem.column_until,
            "clearance": clearance_now}
        return np.array([v_c, w_c, vz_cmd])

    @staticmethod
    def _final_approach(view, goal, obstacles, radius: float, cfg: ExpertConfig) -> bool:
        """Whether the UAV closes on a fixed target (the leader on its goal, a follower on a parked slot) within
        ``dock_radius`` along a straight segment clear of its own map's voxels by r_uav + r_safe."""
        pos = view.state[:3]
        if view.is_leader:
            target = view.goal
        elif _leader_parked(view, cfg):
            target = np.array([goal[0], goal[1], view.z_ref + view.slot_offset[2]])
        else:
            return False
        return bool(math.hypot(target[0] - pos[0], target[1] - pos[1]) < cfg.dock_radius
                    and _segment_clear(obstacles, pos, target, view.limits.r_uav + view.limits.r_safe + radius))

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
        lookahead = self._guidance(view, mem, cfg, t, view.goal[:2])
        if lookahead is None:
            return None, None, None, None
        mem.on_path = True
        heading_target = cfg.astar.heading_target
        to_lookahead = heading_target == "lookahead" or (heading_target == "visible_goal" and not mem.goal_visible)
        goal = lookahead if to_lookahead else view.goal[:2]
        errors = _follower_errors(view)
        scale = 1.0
        if errors.size:
            mean_err = float(errors.mean())
            scale = _clamp(1.0 - (mean_err - cfg.e0) / (cfg.e1 - cfg.e0), cfg.min_leader_scale, 1.0)
        return goal, lookahead, cfg.leader_speed_cap * lim.v_max * scale, None

    def _guidance(self, view, mem: _UAVMemory, cfg: ExpertConfig, t: float, goal_xy: np.ndarray):
        """A* lookahead point toward ``goal_xy`` on this UAV's own map, replanned on the (d5) triggers.

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
                    self._plan(view, mem, t, goal_xy, blocked)
                if view.is_leader and cfg.astar.heading_target == "visible_goal":
                    box = self._raster_box()
                    sight = GlobalPath(np.array([np.clip(pos_xy, *box), np.clip(goal_xy, *box)]))
                    mem.goal_visible = not sight.corridor_blocked(inflated, self.raster)
        if not mem.path_found:
            return None
        return mem.path.lookahead(pos_xy, cfg.astar.lookahead)

    def _plan(self, view, mem: _UAVMemory, t: float, goal_xy, blocked=None):
        cfg = self.config
        lim = view.limits
        if blocked is None:
            blocked = self._blocked_raster(view, cfg)
        path = plan_path(blocked, self.raster, np.clip(view.state[:2], *self._raster_box()),
                         np.clip(goal_xy, *self._raster_box()), lim.r_uav + lim.r_safe, cfg.astar)
        mem.path, mem.path_found, mem.plan_goal = path, path is not None, np.array(goal_xy, dtype=np.float64)
        mem.last_plan_time = t
        mem.replans += 1
        return path

    def _raster_box(self):
        lo = np.asarray(self.raster.origin) + 1e-6
        hi = lo + np.asarray(self.raster.shape) * self.raster.res - 2e-6
        return lo, hi

    def _blocked_raster(self, view, cfg: ExpertConfig) -> np.ndarray:
        """A UAV's 2D raster: its map's occupied voxels, the world bounds and the prior map (``astar_layer``)."""
        lim = view.limits
        h_b = lim.r_uav + lim.r_safe
        occ_map = view.occupancy
        res = occ_map.resolution
        extent = np.asarray(occ_map.shape) * res
        centres, _ = occ_map.occupied_in_sphere(occ_map.origin + extent / 2, float(np.linalg.norm(extent)) / 2 + res)
        if cfg.astar_layer == "band":
            columns = centres[np.abs(centres[:, 2] - view.z_ref) <= h_b + res / 2, :2]
        else:
            columns = _columns_without_gap(occ_map, centres, lim.z_min, lim.z_max, 2 * h_b + res)
        blocked = np.zeros(self.raster.shape, bool)
        blocked[[0, -1], :] = blocked[:, [0, -1]] = True       # the world's x/y bounds are walls (geofence)
        _mark(blocked, self.raster, columns)
        prior = view.prior
        if prior.kind != "none":
            limit = view.z_ref - h_b if cfg.astar_layer == "band" else lim.z_max - 2 * h_b
            cells = np.argwhere(prior.heights > limit)
            _mark(blocked, self.raster, prior.origin + (cells + 0.5) * prior.resolution)
        return blocked

    def _follower_target(self, view, mem: _UAVMemory, cfg: ExpertConfig, t: float, slot_hidden: bool):
        lim = view.limits
        lead = view.leader_state
        offset = view.slot_offset
        if cfg.shape_switching:
            column_offset = np.array([-view.index * view.config.formation.spacing, 0.0, offset[2]])
            if view.occupancy.occupied_within(view.slot, lim.r_uav + lim.r_safe + view.occupancy.resolution):
                mem.column_until = t + cfg.column_hold
            if t < mem.column_until:
                offset = column_offset
        key = (lead.tobytes(), cfg.dwa.T_p)              # every follower predicts the same broadcast: once a step
        if self._leader_prediction[0] != key:
            self._leader_prediction = key, _predict_unicycle(lead, cfg.dwa.T_p, lim.dt)
        pred_xy, pred_psi = self._leader_prediction[1]
        c, s_ = math.cos(pred_psi), math.sin(pred_psi)
        goal = pred_xy + np.array([c * offset[0] - s_ * offset[1], s_ * offset[0] + c * offset[1]])
        heading_l = np.array([math.cos(lead[PSI]), math.sin(lead[PSI])])
        lead_moving = not _leader_parked(view, cfg)
        a_j = goal - view.state[:2] + (cfg.k_h * heading_l if lead_moving else 0.0)   # a parked slot is the target
        lookahead = view.state[:2] + a_j
        cl, sl = heading_l
        slot_now = lead[:2] + np.array([cl * offset[0] - sl * offset[1], sl * offset[0] + cl * offset[1]])
        trail = mem.trail
        if cfg.rejoin == "trail" and (not trail or np.hypot(*(lead[:2] - trail[-1])) >= cfg.trail_spacing):
            trail.append(lead[:2].copy())
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
        e_par = float((slot_now - view.state[:2]) @ heading_l)
        if not lead_moving:                                     # closing on a parked slot, from any side
            to_slot = slot_now - view.state[:2]
            e_par = float(np.linalg.norm(to_slot)) * max(0.0, math.cos(_bearing_error(view.state, to_slot)))
        v_ref = _clamp(lead[V] + cfg.k_f * e_par, 0.0, lim.v_max)
        return goal, lookahead, None, v_ref

    # ------------------------------------------------------------------ neighbours (g6)
    def _neighbours(self, view, cfg: ExpertConfig):
        ns = view.neighbour_states
        vel = np.empty((len(ns), 3))
        vel[:, 0] = ns[:, V] * np.cos(ns[:, PSI])
        vel[:, 1] = ns[:, V] * np.sin(ns[:, PSI])
        vel[:, 2] = ns[:, VZ]
        pos = ns[:, :3] + vel * view.limits.dt                             # broadcasts are one cycle old
        if not cfg.neighbour_prediction:
            vel = np.zeros_like(vel)
        return pos, vel

    def _yield(self, view, movers_pos, movers_vel, cfg: ExpertConfig, v_cap):
        """Deadlock rule of (g6): a UAV predicting a conflict with a lower-index UAV caps its speed."""
        if view.is_leader or cfg.yield_factor >= 1.0:
            return v_cap
        lim = view.limits
        s = view.state
        own_vel = np.array([s[V] * math.cos(s[PSI]), s[V] * math.sin(s[PSI]), s[VZ]])
        lower = (view.neighbour_ids < view.index) & view.neighbour_alive
        if not lower.any():
            return v_cap
        n_steps = round(cfg.dwa.T_p / lim.dt)
        if _closest_approach(s[:3], own_vel, movers_pos[lower], movers_vel[lower], n_steps, lim.dt) < cfg.dwa.R_uu:
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
def _raster_for(view, res: float) -> Raster:
    origin, shape = grid_frame(view.bounds_lo[:2], view.bounds_hi[:2], res)
    return Raster(tuple(origin), res, shape)


def _mark(blocked: np.ndarray, raster: Raster, xy: np.ndarray) -> None:
    """Block the raster cells containing the points ``xy`` (K, 2); points outside the raster are ignored."""
    if len(xy) == 0:
        return
    cells = np.floor((xy - np.asarray(raster.origin)) / raster.res).astype(np.int64)
    ok = np.all((cells >= 0) & (cells < np.asarray(raster.shape)), axis=1)
    blocked[cells[ok, 0], cells[ok, 1]] = True


def _columns_without_gap(occ_map, centres: np.ndarray, z_min: float, z_max: float, gap: float) -> np.ndarray:
    """x, y of the map columns holding an occupied voxel in [z_min, z_max] but no way through there: a run
    of non-occupied voxels of height >= ``gap`` of which at least one voxel is known free.

    A run of unknown voxels alone is not a way: a wall whose top the UAV has not seen is a wall (that
    optimism sent followers along a corridor's wall into the world's corners); one ray through the
    run (over a low wall, through a gap) is enough. Only the columns of the occupied voxels
    ``centres`` are read, so the cost follows the obstacles, not the map.
    """
    res = occ_map.resolution
    origin = occ_map.origin
    k_lo = max(0, int(math.ceil((z_min - origin[2]) / res - 0.5)))
    k_hi = min(occ_map.shape[2], int(math.floor((z_max - origin[2]) / res - 0.5)) + 1)
    l_occ = np.float32(occ_map.cfg.logodds(occ_map.cfg.p_occ))        # the map's float32 occupancy threshold
    out = np.empty((len(centres), 2))
    n = _gapless_columns_kernel(occ_map.arrays(), np.ascontiguousarray(centres, dtype=np.float64), origin, res,
                                z_min - res, z_max + res, k_lo, k_hi, l_occ, gap, out)
    return out[:n]


@numba.njit(cache=True)
def _gapless_columns_kernel(leaves, centres, origin, res, z_lo, z_hi, k_lo, k_hi, l_occ, gap, out):
    """Write into ``out`` the x, y of each column (once) of a voxel of ``centres`` within [z_lo, z_hi] whose
    layers k_lo..k_hi-1 hold no run of non-occupied voxels >= ``gap`` with a known-free voxel; return the count."""
    visited = np.zeros((leaves.shape[0], leaves.shape[1]), dtype=np.bool_)
    n = 0
    for m in range(centres.shape[0]):
        if not z_lo <= centres[m, 2] <= z_hi:
            continue
        i = int(math.floor((centres[m, 0] - origin[0]) / res))
        j = int(math.floor((centres[m, 1] - origin[1]) / res))
        if visited[i, j]:
            continue
        visited[i, j] = True
        length, seen, way = 0, False, False
        for k in range(k_lo, k_hi):
            value = voxel_logodds(leaves, i, j, k)
            if value >= l_occ:                                  # NaN (unknown) compares False
                length, seen = 0, False
                continue
            length += 1
            seen = seen or value < l_occ
            if seen and length * res >= gap - 1e-9:
                way = True
                break
        if not way:
            out[n, 0] = origin[0] + (i + 0.5) * res
            out[n, 1] = origin[1] + (j + 0.5) * res
            n += 1
    return n


def _level_way(r, cfg: ExpertConfig, target_dir: np.ndarray) -> bool:
    """Whether an open cell of the two level rows lies within ``level_window`` of the target azimuth."""
    if cfg.level_window <= 0.0:
        return False
    return _level_way_kernel(r.window_open, cfg.vfh.alpha_h, math.atan2(target_dir[1], target_dir[0]), cfg.level_window)


@numba.njit(cache=True)
def _level_way_kernel(window_open, cell, target_azimuth, window):
    """_level_way on the open-window mask: the level rows' open columns within ``window`` of the target."""
    mid = window_open.shape[0] // 2
    for col in range(window_open.shape[1]):
        if window_open[mid - 1, col] or window_open[mid, col]:
            if abs(((col + 0.5) * cell - target_azimuth + math.pi) % (2 * math.pi) - math.pi) <= window:
                return True
    return False


@numba.njit(cache=True)
def _in_sphere(points, values, centre, radius):
    """The ``points`` (M, 3) within ``radius`` of ``centre`` and their ``values`` (M,), in their order."""
    r2 = radius * radius
    keep = np.empty(points.shape[0], dtype=np.int64)
    n = 0
    for k in range(points.shape[0]):
        dx, dy, dz = points[k, 0] - centre[0], points[k, 1] - centre[1], points[k, 2] - centre[2]
        if dx * dx + dy * dy + dz * dz <= r2:
            keep[n] = k
            n += 1
    inside, inside_values = np.empty((n, 3)), np.empty(n)
    for m in range(n):
        inside[m] = points[keep[m]]
        inside_values[m] = values[keep[m]]
    return inside, inside_values


@numba.njit(cache=True)
def _segment_clear(centres, a, b, clearance):
    """Whether every voxel centre lies farther than ``clearance`` from the segment a-b (3D)."""
    abx, aby, abz = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    ab2 = max(abx * abx + aby * aby + abz * abz, 1e-12)
    c2 = clearance * clearance
    for k in range(centres.shape[0]):
        px, py, pz = centres[k, 0] - a[0], centres[k, 1] - a[1], centres[k, 2] - a[2]
        t = min(1.0, max(0.0, (px * abx + py * aby + pz * abz) / ab2))
        dx, dy, dz = px - t * abx, py - t * aby, pz - t * abz
        if dx * dx + dy * dy + dz * dz <= c2:
            return False
    return True


def _gap_altitude(view, target_xy, z_pref: float, cfg: ExpertConfig) -> float | None:
    """The altitude to pass through a known vertical gap when the level way toward the target is blocked.

    The own map's columns along the line to the target (out to ``gap_lookahead``) are tested at the
    preferred altitude; if occupied voxels block that level, the known-free vertical runs of those
    columns (tall enough for the UAV and its margin, inside the altitude band) are intersected and
    the altitude nearest ``z_pref`` inside the common run is returned. Unknown voxels do not count as
    free here: a gap has to be seen before the UAV commits to it. None: the level is clear, or no gap.
    """
    lim = view.limits
    occ = view.occupancy
    res = occ.resolution
    pos = view.state[:3]
    d = np.asarray(target_xy, dtype=np.float64) - pos[:2]
    dist = math.hypot(d[0], d[1])
    if dist < 1e-6:
        return None
    ts = np.arange(res, min(cfg.gap_lookahead, dist + res), res)
    if ts.size == 0:
        return None
    best = _gap_kernel(occ.arrays(), occ.origin, res, pos, d / dist, ts, z_pref,
                       max(1, int(round(cfg.gap_depth / res))), lim.r_uav + lim.r_safe, lim.z_min, lim.z_max,
                       cfg.gap_margin)
    return None if math.isnan(best) else best


@numba.njit(cache=True)
def _gap_kernel(leaves, origin, res, pos, u, ts, z_pref, span, h_b, z_min, z_max, margin):
    """_gap_altitude on the leaves (a ``MapArrays``): the columns at ``pos + ts * u``, the first blocking the
    band around ``z_pref``, and the runs known free through it and the next ``span - 1`` columns; NaN if none."""
    nx, ny, nz = leaves.shape[0], leaves.shape[1], leaves.shape[2]
    cols = np.empty((ts.size, 2), np.int64)
    k_cols = 0
    for i in range(ts.size):
        ci = int(math.floor((pos[0] + ts[i] * u[0] - origin[0]) / res))
        cj = int(math.floor((pos[1] + ts[i] * u[1] - origin[1]) / res))
        if 0 <= ci < nx and 0 <= cj < ny:
            cols[k_cols, 0], cols[k_cols, 1] = ci, cj
            k_cols += 1
    if k_cols == 0:
        return math.nan
    z = origin[2] + (np.arange(nz) + 0.5) * res
    first = -1
    for i in range(k_cols):
        for k in range(nz):
            if abs(z[k] - z_pref) <= h_b + res / 2 and voxel_logodds(leaves, cols[i, 0], cols[i, 1], k) > 0.0:
                first = i
                break
        if first >= 0:
            break
    if first < 0:
        return math.nan
    free = np.empty(nz, np.bool_)
    for k in range(nz):
        ok = (z[k] - res / 2 >= z_min - h_b) and (z[k] + res / 2 <= z_max + h_b)
        for i in range(first, min(first + span, k_cols)):
            if not voxel_logodds(leaves, cols[i, 0], cols[i, 1], k) <= 0.0:  # occupied or unknown (NaN)
                ok = False
                break
        free[k] = ok
    return _nearest_free_run(free, z, res, h_b, z_min, z_max, z_pref, margin)


@numba.njit(cache=True)
def _nearest_free_run(free, z, res, h_b, z_min, z_max, z_pref, margin):
    """The altitude nearest ``z_pref`` that keeps ``h_b`` (+ ``margin``) inside a run of ``free`` cells; NaN if none."""
    best, best_cost = math.nan, math.inf
    k = 0
    n = free.size
    while k < n:
        if not free[k]:
            k += 1
            continue
        j = k
        while j < n and free[j]:
            j += 1
        lo, hi = z[k] - res / 2 + h_b, z[j - 1] + res / 2 - h_b   # centre range that keeps the margin
        lo, hi = max(lo, z_min), min(hi, z_max)
        if hi >= lo:
            alt = min(max(z_pref, lo + margin), hi - margin) if hi - lo > 2 * margin else 0.5 * (lo + hi)
            if abs(alt - z_pref) < best_cost:
                best, best_cost = alt, abs(alt - z_pref)
        k = j
    return best


def _geofence(pos, reach: float, lo, hi, spacing: float) -> np.ndarray:
    """Points on the world's vertical x/y bound planes within ``reach`` of ``pos``, at its altitude."""
    pts = []
    for axis in (0, 1):
        other = 1 - axis
        for bound in (lo[axis], hi[axis]):
            gap = abs(pos[axis] - bound)
            if gap >= reach:
                continue
            half = math.sqrt(reach ** 2 - gap ** 2)
            t = np.arange(pos[other] - half, pos[other] + half + spacing, spacing)
            p = np.empty((t.size, 3))
            p[:, axis] = bound
            p[:, other] = t
            p[:, 2] = pos[2]
            pts.append(p)
    return np.concatenate(pts) if pts else np.empty((0, 3))


def _project_to_altitude(obstacles: np.ndarray, z: float, band: float) -> np.ndarray:
    """Planar mode: keep the voxels within ``band`` of the flight altitude and put them at that altitude."""
    keep = np.abs(obstacles[:, 2] - z) <= band
    out = obstacles[keep].copy()
    out[:, 2] = z
    return out


@numba.njit(cache=True)
def _clearance(pos, obstacles, radius, r_uav):
    """Distance from ``pos`` to the nearest voxel surface (balls of ``radius``) minus r_uav; inf without voxels."""
    if obstacles.shape[0] == 0:
        return math.inf
    best = math.inf
    for k in range(obstacles.shape[0]):
        dx, dy, dz = obstacles[k, 0] - pos[0], obstacles[k, 1] - pos[1], obstacles[k, 2] - pos[2]
        best = min(best, dx * dx + dy * dy + dz * dz)
    return math.sqrt(best) - radius - r_uav


def _follower_errors(view) -> np.ndarray:
    """Horizontal slot errors of the followers, from their broadcasts and the leader's own pose."""
    s = view.state
    ids = view.neighbour_ids
    c, sn = math.cos(s[PSI]), math.sin(s[PSI])
    off = view.offsets[ids]
    slots = s[:2] + np.column_stack([c * off[:, 0] - sn * off[:, 1], sn * off[:, 0] + c * off[:, 1]])
    alive = view.neighbour_alive
    return np.linalg.norm(view.neighbour_states[alive, :2] - slots[alive], axis=1)


def _leader_parked(view, cfg: ExpertConfig) -> bool:
    """Whether the leader's broadcast speed is below ``leader_stopped_speed`` (its followers dock)."""
    return bool(view.leader_state[V] < cfg.leader_stopped_speed)


def _clamp(x: float, lo: float, hi: float) -> float:
    """``x`` limited to [lo, hi] (np.clip's result for one number, without its array overhead)."""
    return float(min(max(x, lo), hi))


def _bearing_error(state, direction) -> float:
    """Signed angle (rad) from the UAV's heading to the horizontal ``direction``."""
    return wrap(math.atan2(direction[1], direction[0]) - state[PSI])


def _turn_toward(state, direction, w_max: float) -> float:
    """The yaw rate toward the horizontal ``direction``: its bearing error, limited to +/- w_max."""
    return _clamp(_bearing_error(state, direction), -w_max, w_max)


def _pursuit_cap(state, point, w_max: float, v_cap: float) -> float:
    """``v_cap`` lowered to the speed at which the turn-rate limit still steers onto ``point`` (pure pursuit)."""
    d = point - state[:2]
    dist = math.hypot(d[0], d[1])
    theta = abs(_bearing_error(state, d)) if dist > 1e-9 else 0.0
    reach = dist / 2.0 if theta >= math.pi / 2 else dist / (2.0 * math.sin(theta)) if theta > 1e-9 else math.inf
    return min(v_cap, w_max * reach)


def _predict_unicycle(state, horizon: float, dt: float):
    """Pose (xy, psi) after ``horizon`` at constant (v, w) with the model of spec (a) (yaw first, closed form sum)."""
    n = max(1, round(horizon / dt))
    k = np.arange(1, n + 1)
    psi = state[PSI] + k * state[W] * dt
    x = state[0] + np.sum(state[V] * np.cos(psi) * dt)
    y = state[1] + np.sum(state[V] * np.sin(psi) * dt)
    return np.array([x, y]), float(psi[-1])


def _slots_free(view, psi: float, margin: float) -> bool:
    """Whether every follower slot of a leader at its position with heading ``psi`` is free in its own map."""
    c, sn = math.cos(psi), math.sin(psi)
    pos = view.state[:3]
    for off in view.offsets[1:]:
        slot = np.array([pos[0] + c * off[0] - sn * off[1], pos[1] + sn * off[0] + c * off[1], view.z_ref + off[2]])
        if np.any(slot[:2] < view.bounds_lo[:2] + margin) or np.any(slot[:2] > view.bounds_hi[:2] - margin):
            return False
        if view.occupancy.occupied_within(slot, margin):
            return False
    return True


def _park_heading(view, mem: _UAVMemory, cfg: ExpertConfig, n: int = 72) -> float:
    """The parked leader's heading: its own unless a slot is blocked, else the nearest heading with free slots."""
    lim = view.limits
    margin = lim.r_uav + lim.r_safe + view.occupancy.resolution
    if mem.park_psi is not None and _slots_free(view, mem.park_psi, margin):
        return mem.park_psi
    psi = float(view.state[PSI])
    if _slots_free(view, psi, margin):
        mem.park_psi = psi
        return psi
    for k in range(1, n // 2 + 1):
        for sign in (1.0, -1.0):
            cand = wrap(psi + sign * k * 2.0 * math.pi / n)
            if _slots_free(view, cand, margin):
                mem.park_psi = cand
                return cand
    mem.park_psi = psi                          # no heading frees every slot: stay as parked
    return psi


def _climb_rate(elevation: float, v: float, dz_goal: float, cfg: ExpertConfig, lim) -> float:
    """Vertical speed of CLIMB along 3D VFH+'s elevation; with ``climb_target_limit``, when that climb heads
    for the target altitude (error ``dz_goal``) it is at most ``k_z * |dz_goal|``, so it does not overshoot."""
    vz = _clamp(max(v, 0.3) * math.tan(elevation), -lim.vz_max, lim.vz_max)
    if cfg.climb_target_limit and vz * dz_goal > 0.0:
        vz = math.copysign(min(abs(vz), cfg.k_z * abs(dz_goal)), vz)
    return vz


def _vertical_escape(r, lim) -> float:
    """After T_stuck: climb (or descend) at full rate if the straight-up (down) cells hold no obstacle."""
    if not r.binary[-1].any():
        return lim.vz_max
    if not r.binary[0].any():
        return -lim.vz_max
    return 0.0


@numba.njit(cache=True)
def _closest_approach(pos, vel, movers_pos, movers_vel, n_steps, dt):
    """The least distance to the movers over steps 1..n_steps, everyone at constant velocity."""
    best = math.inf
    for k in range(1, n_steps + 1):
        t = k * dt
        for m in range(movers_pos.shape[0]):
            dx = (pos[0] - movers_pos[m, 0]) + t * (vel[0] - movers_vel[m, 0])
            dy = (pos[1] - movers_pos[m, 1]) + t * (vel[1] - movers_vel[m, 1])
            dz = (pos[2] - movers_pos[m, 2]) + t * (vel[2] - movers_vel[m, 2])
            best = min(best, math.sqrt(dx * dx + dy * dy + dz * dz))
    return best


def _closes_on_movers(pos, vz: float, movers_pos, movers_vel, dwa: DWAConfig, lim) -> bool:
    """Whether a vertical move at ``vz`` comes within ``dwa.R_uu`` of a neighbour over the DWA horizon (g6)."""
    if len(movers_pos) == 0 or vz == 0.0:
        return False
    n_steps = round(dwa.T_p / lim.dt)
    return _closest_approach(pos, np.array([0.0, 0.0, vz]), movers_pos, movers_vel, n_steps, lim.dt) < dwa.R_uu


def _away_vertically(pos, occ_map, radius, lim, lateral_to_dwa: bool) -> float | None:
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


__all__ = ["ExpertConfig", "FusionExpert", "StandardDWA", "WEIGHT_NAMES", "planar_formation"]
