"""The paper's planners as the paper describes them, and nothing more (Drones 2023, 7(8), 504; spec (b)-(g)).

Every UAV runs the same cycle on its own onboard view (its own map, the broadcasts of the others):

* the leader flies DWA (spec (b)) toward the mission goal G, with the improvements E8, E10, E11 of
  spec (c) switched by ``DWAConfig`` and the readings the spec leaves open (``heading_ref``,
  ``rotation_mode``) selectable there; E10's A* path (spec (d)) on the UAV's own map only modulates
  the heading weight: the heading term always aims at G (spec (d6), ``heading_target = "goal"``);
  once within ``DWAConfig.r_goal`` of G it stops (spec (b10));
* a follower flies the same DWA toward its slot predicted over the DWA horizon, with the speed
  matching term of spec (g2) and the neighbours as moving obstacles (g6);
* with ``use_vfh`` the fusion rule of spec (g3)-(g5): planar DWA unless 3D VFH+ (spec (f)) demands
  vertical motion (its chosen elevation leaves the level rows), then climb or descend along that
  elevation with DWA's clearance taken in 3D. Without it the planar (2D) controller holds z_ref.

None of the engineered expert's [X] rules is here (no visible-goal switch to the A* lookahead, no
turn-in-place, no pursuit or leader speed cap, no gap rule, no rejoin path, no parking turn). The
choices the spec still leaves to us are the fields of ``PaperConfig`` (docs/deviations.md,
"Paper-faithful planners").
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from uavform_env.config import Config, boolean, in_range, instance_of, integer, optional
from uavform_env.dynamics import PSI, V, VZ, W
from uavform_env.world import grid_frame

from .astar import AStarConfig, Raster, inflate, plan_path, replan_trigger
from .dwa import DWAConfig, dwa_plan, geofence_points, project_to_altitude
from .policy import OnboardPolicy
from .vertical import BLOCKED, CLIMB, LEVEL, PlannerMemory
from .vfh3d import VFHConfig, vertical_escape, vfh3d_step



@dataclass(frozen=True)
class PaperConfig(Config):
    """The paper's planner: DWA ablation and readings (``dwa``), A* (``astar``), 3D VFH+ (``vfh``), fusion switch.

    Spec values [R]/[D] (spec (g2)-(g6), Appendix A):
    k_f, k_h, k_z      follower speed gain (1/s), follower lead along the leader's heading (m), altitude gain (1/s)
    debounce           cycles a new vertical mode must be proposed in a row before it is taken (g4)
    T_stuck            seconds without an admissible DWA sample before the pure-vertical escape (g4)
    climb_lookahead    in CLIMB, DWA heads for the point this far along 3D VFH+'s azimuth (g3)
    yield_factor       the (g6) deadlock rule: a follower predicting a conflict with a lower-index UAV within
                       T_p caps its speed at this fraction of v_max (1 = off)
    Choices the spec leaves open [X], each a field:
    replan_check_period  how often (s) the leader rebuilds its A* raster and tests the (d5) triggers
    geofence_spacing   the world's x/y bounds (a crash in the env) enter DWA as walls of points this far apart
                       (None: the bounds are invisible to DWA, as in the paper's unbounded plane)
    delay_compensation a neighbour's one-cycle-old broadcast is moved one step along its velocity (g1, g6)
    stop_at_goal       the leader stops within ``dwa.r_goal`` of G (the stopping condition of (b10)); False:
                       DWA keeps flying (the raw loop, for the C1 oscillation test)
    """

    dwa: DWAConfig = field(default_factory=lambda: DWAConfig.ablation("IDWA"))
    astar: AStarConfig = field(default_factory=AStarConfig)
    vfh: VFHConfig = field(default_factory=VFHConfig)
    use_vfh: bool = False
    k_f: float = 0.5
    k_h: float = 1.0
    k_z: float = 0.5
    debounce: int = 3
    T_stuck: float = 5.0
    climb_lookahead: float = 3.0
    yield_factor: float = 0.5
    replan_check_period: float = 0.5
    geofence_spacing: float | None = 0.4
    delay_compensation: bool = True
    stop_at_goal: bool = True

    BOUNDS: ClassVar[dict] = {
        "dwa": instance_of(DWAConfig), "astar": instance_of(AStarConfig), "vfh": instance_of(VFHConfig),
        **{name: boolean for name in ("use_vfh", "delay_compensation", "stop_at_goal")},
        **{name: in_range(0.0) for name in ("k_f", "k_h", "k_z", "T_stuck", "climb_lookahead", "replan_check_period")},
        "yield_factor": in_range(0.0, 1.0),
        "debounce": integer(1, 100),
        "geofence_spacing": optional(in_range(0.05)),
    }

    def __post_init__(self):
        super().__post_init__()
        if self.astar.heading_target != "goal":
            raise ValueError(f"PaperConfig.astar.heading_target={self.astar.heading_target!r}: the paper's DWA heads "
                             "for the goal (spec (d6)); other targets are the engineered expert's (baselines.expert)")

    @classmethod
    def named(cls, ablation: str, use_vfh: bool = False, **overrides) -> "PaperConfig":
        """The planar (or with ``use_vfh`` fused) planner with ``DWAConfig.ablation(ablation)`` (spec (c5) names).

        ``overrides`` may hold DWAConfig fields (``heading_ref``, ``rotation_mode``, ``r_goal``...) and PaperConfig
        fields; they are told apart by name.
        """
        dwa_names = set(DWAConfig.__dataclass_fields__)
        dwa_over = {k: v for k, v in overrides.items() if k in dwa_names}
        own = {k: v for k, v in overrides.items() if k not in dwa_names}
        return cls(dwa=DWAConfig.ablation(ablation, **dwa_over), use_vfh=use_vfh, **own)


@dataclass
class _Memory(PlannerMemory):
    """What one UAV's planner keeps between cycles: the shared (g4) state and its replanning clock."""

    last_plan_time: float = -math.inf
    last_check_time: float = -math.inf


class PaperPlanner(OnboardPolicy):
    """The paper's leader-follower planner (see the module docstring); works for one UAV or a formation."""

    def __init__(self, config: PaperConfig | None = None):
        self.config = config if config is not None else PaperConfig()
        if not isinstance(self.config, PaperConfig):
            raise ValueError(f"config: expected a PaperConfig, got {type(self.config).__name__}")

    def reset(self, env, seed: int | None = None) -> None:
        super().reset(env, seed)
        self.memory = {a: _Memory() for a in self.env.possible_agents}
        lead = self.env.onboard(self.env.possible_agents[0])
        origin, shape = grid_frame(lead.bounds_lo[:2], lead.bounds_hi[:2], self.config.astar.res_g)
        self.raster = Raster(tuple(origin), self.config.astar.res_g, shape)

    # ------------------------------------------------------------------ one UAV's cycle
    def command(self, view) -> np.ndarray:
        cfg, lim, s = self.config, view.limits, view.state
        mem = self.memory[view.agent]
        pos = s[:3]
        t = view.step * lim.dt
        if view.crashed:
            return np.zeros(3)
        z_slot = view.z_ref + view.slot_offset[2]
        vz_hold = _clamp(cfg.k_z * (z_slot - pos[2]), lim.vz_max)
        if view.is_leader:
            goal = view.goal[:2]
            if cfg.stop_at_goal and math.hypot(goal[0] - pos[0], goal[1] - pos[1]) < cfg.dwa.r_goal:
                self.diagnostics[view.agent] = {"mode": mem.mode, "stuck": False, "arrived": True}
                return np.array([0.0, 0.0, vz_hold])                        # (b10): stopped at the goal
            lookahead = self._lookahead(view, mem, t) if (cfg.dwa.use_astar_weight or cfg.use_vfh) else goal
            v_ref = None
        else:
            goal, lookahead, v_ref = self._follower_target(view)
        movers_pos, movers_vel = self._neighbours(view)
        v_cap = self._yield(view, movers_pos, movers_vel)

        res_vox = view.occupancy.resolution
        radius = res_vox * math.sqrt(3.0) / 2.0
        reach = lim.v_max * cfg.dwa.T_p + cfg.dwa.D_cap + lim.r_uav + res_vox
        obstacles, _ = view.occupancy.occupied_in_sphere(pos, reach)
        heading_goal, vz_cmd, vfh_result = goal, vz_hold, None
        if cfg.use_vfh:
            centres, probs = view.occupancy.occupied_in_sphere(pos, cfg.vfh.R_w)
            aim = lookahead if view.is_leader else goal         # (g3): T = P_LA (leader) or G_j (follower)
            target = np.array([aim[0], aim[1], z_slot]) - pos
            if float(np.linalg.norm(target)) < 1e-6:            # on the target: look along the heading
                target = np.array([math.cos(s[PSI]), math.sin(s[PSI]), 0.0])
            near = view.neighbour_alive & (np.linalg.norm(movers_pos - pos, axis=1) < cfg.vfh.R_w)
            vfh_result = vfh3d_step(mem.vfh, cfg.vfh, lim, pos, s[PSI], s[V], s[VZ], target, centres, probs, res_vox,
                                    movers_pos[near])
            mode = self._debounced_mode(mem, vfh_result)
            if mode == CLIMB and not vfh_result.blocked:
                vz_cmd = _clamp(max(s[V], 0.3) * math.tan(vfh_result.elevation), lim.vz_max)
                az = vfh_result.azimuth
                heading_goal = pos[:2] + cfg.climb_lookahead * np.array([math.cos(az), math.sin(az)])
            elif mode == BLOCKED:
                vz_cmd = 0.0
        else:
            obstacles = project_to_altitude(obstacles, pos[2], lim.r_uav + lim.r_safe + radius)

        clearance_now = _clearance(pos, obstacles, radius, lim.r_uav)
        radii = np.full(len(obstacles), radius)
        if cfg.geofence_spacing is not None:
            fence = geofence_points(pos, reach, view.bounds_lo, view.bounds_hi, cfg.geofence_spacing)
            obstacles = np.concatenate([obstacles, fence])
            radii = np.concatenate([radii, np.zeros(len(fence))])
        alive = view.neighbour_alive
        res = dwa_plan(s, lim, cfg.dwa, heading_goal, obstacles, radii, vz_cmd=vz_cmd, lookahead=lookahead,
                       clearance_now=clearance_now, movers_pos=movers_pos[alive], movers_vel=movers_vel[alive],
                       v_ref=v_ref, v_cap=v_cap, prev_alignment=mem.prev_alignment)
        mem.prev_alignment = res.alignment if math.isfinite(res.alignment) else 1.0
        v_c, w_c = res.v, res.w
        if res.admissible:
            mem.stuck_time = 0.0
        else:
            mem.stuck_time += lim.dt
            if vfh_result is not None:                          # (g4): decelerate and yaw toward the target
                err = math.atan2(heading_goal[1] - pos[1], heading_goal[0] - pos[0]) - s[PSI]
                w_c = _clamp(math.remainder(err, 2 * math.pi), lim.w_max)
                if mem.stuck_time >= cfg.T_stuck:
                    vz_cmd = vertical_escape(vfh_result, lim)
        if vfh_result is not None and vfh_result.emergency:    # (g5): stop, move vertically away for a cycle
            away = _away_vertically(pos, view.occupancy, cfg.vfh.resolve(lim, res_vox)[0], lim)
            if away is not None:
                v_c, vz_cmd = 0.0, away
        self.diagnostics[view.agent] = {"mode": mem.mode, "stuck": not res.admissible,
                                        "n_admissible": res.n_admissible, "replans": mem.replans,
                                        "clearance": clearance_now}
        return np.array([v_c, w_c, vz_cmd])

    # ------------------------------------------------------------------ targets
    def _lookahead(self, view, mem: _Memory, t: float) -> np.ndarray:
        """P_LA of (d4) on the leader's own A* path, replanned on the (d5) triggers; G when no path exists (d2)."""
        cfg, lim = self.config, view.limits
        goal = view.goal[:2]
        pos_xy = view.state[:2]
        if t - mem.last_check_time >= cfg.replan_check_period:
            mem.last_check_time = t
            blocked = self._blocked_raster(view)
            lo, hi = self._raster_box()
            if mem.replans == 0:
                replan = True
            else:
                inflated = inflate(blocked, lim.r_uav + lim.r_safe, self.raster.res)
                replan = replan_trigger(mem.path, pos_xy, inflated, self.raster, t - mem.last_plan_time, True,
                                        cfg.astar) is not None
            if replan:
                mem.path = plan_path(blocked, self.raster, np.clip(pos_xy, lo, hi), np.clip(goal, lo, hi),
                                     lim.r_uav + lim.r_safe, cfg.astar)
                mem.path_found = mem.path is not None
                mem.last_plan_time = t
                mem.replans += 1
        if mem.path is None:
            return goal.copy()
        return mem.path.lookahead(pos_xy, cfg.astar.lookahead)

    def _raster_box(self):
        lo = np.asarray(self.raster.origin) + 1e-6
        return lo, lo + np.asarray(self.raster.shape) * self.raster.res - 2e-6

    def _blocked_raster(self, view) -> np.ndarray:
        """The 2D raster of (d1): the own map's occupied voxels in the flight band, and the world's x/y bounds."""
        lim = view.limits
        occ = view.occupancy
        extent = np.asarray(occ.shape) * occ.resolution
        centres, _ = occ.occupied_in_sphere(occ.origin + extent / 2, float(np.linalg.norm(extent)) / 2 + occ.resolution)
        band = lim.r_uav + lim.r_safe + occ.resolution / 2
        xy = centres[np.abs(centres[:, 2] - view.z_ref) <= band, :2]
        blocked = np.zeros(self.raster.shape, bool)
        blocked[[0, -1], :] = blocked[:, [0, -1]] = True
        cells = np.floor((xy - np.asarray(self.raster.origin)) / self.raster.res).astype(np.int64)
        ok = np.all((cells >= 0) & (cells < np.asarray(self.raster.shape)), axis=1)
        blocked[cells[ok, 0], cells[ok, 1]] = True
        return blocked

    def _follower_target(self, view):
        """(g2): the slot predicted over T_p as the goal, its direction plus k_h along the leader's heading for
        eq. 10, and the speed reference v_L + k_f * (along-track slot error)."""
        cfg, lim = self.config, view.limits
        lead = view.leader_state
        off = view.slot_offset
        n = max(1, round(cfg.dwa.T_p / lim.dt))
        psi = lead[PSI] + np.arange(1, n + 1) * lead[W] * lim.dt
        pred = lead[:2] + lead[V] * lim.dt * np.array([np.cos(psi).sum(), np.sin(psi).sum()])
        c, sn = math.cos(psi[-1]), math.sin(psi[-1])
        goal = pred + np.array([c * off[0] - sn * off[1], sn * off[0] + c * off[1]])
        head = np.array([math.cos(lead[PSI]), math.sin(lead[PSI])])
        lookahead = goal + cfg.k_h * head            # D + a_j with a_j = G_j - D + k_h * heading_L
        slot_now = view.slot[:2]
        e_par = float((slot_now - view.state[:2]) @ head)
        v_ref = min(max(lead[V] + cfg.k_f * e_par, 0.0), lim.v_max)
        return goal, lookahead, v_ref

    # ------------------------------------------------------------------ neighbours (g6)
    def _neighbours(self, view):
        ns = view.neighbour_states
        vel = np.column_stack([ns[:, V] * np.cos(ns[:, PSI]), ns[:, V] * np.sin(ns[:, PSI]), ns[:, VZ]])
        pos = ns[:, :3] + (vel * view.limits.dt if self.config.delay_compensation else 0.0)
        return pos, vel

    def _yield(self, view, movers_pos, movers_vel):
        """(g6) deadlock rule: a follower closing within R_uu of a lower-index UAV inside T_p slows to yield_factor."""
        cfg, lim, s = self.config, view.limits, view.state
        lower = (view.neighbour_ids < view.index) & view.neighbour_alive
        if view.is_leader or cfg.yield_factor >= 1.0 or not lower.any():
            return None
        own = np.array([s[V] * math.cos(s[PSI]), s[V] * math.sin(s[PSI]), s[VZ]])
        t = np.arange(1, round(cfg.dwa.T_p / lim.dt) + 1)[:, None, None] * lim.dt
        gap = (s[:3] - movers_pos[lower])[None] + t * (own - movers_vel[lower])[None]
        if float(np.sqrt((gap ** 2).sum(axis=2)).min()) < cfg.dwa.R_uu:
            return cfg.yield_factor * lim.v_max
        return None

    # ------------------------------------------------------------------ vertical decision (g4)
    def _debounced_mode(self, mem: _Memory, r) -> str:
        """LEVEL when 3D VFH+'s choice lies in the level rows, CLIMB otherwise, BLOCKED without a candidate;
        a new mode is taken after ``debounce`` consecutive proposals."""
        if r.blocked:
            proposal = BLOCKED
        elif abs(r.elevation) <= self.config.vfh.alpha_h / 2 + 1e-9:
            proposal = LEVEL
        else:
            proposal = CLIMB
        if proposal == mem.mode:
            mem.pending, mem.pending_count = proposal, 0
        else:
            mem.pending_count = mem.pending_count + 1 if proposal == mem.pending else 1
            mem.pending = proposal
            if mem.pending_count >= self.config.debounce:
                mem.mode, mem.pending_count = proposal, 0
        return mem.mode


# ---------------------------------------------------------------------- helpers
def _clamp(x: float, limit: float) -> float:
    return float(min(max(x, -limit), limit))


def _clearance(pos, obstacles: np.ndarray, radius: float, r_uav: float) -> float:
    """d_min of eq. 11: distance to the nearest voxel surface minus r_uav (inf without voxels)."""
    if len(obstacles) == 0:
        return math.inf
    return float(np.sqrt(((obstacles - pos) ** 2).sum(axis=1).min())) - radius - r_uav


def _away_vertically(pos, occ_map, r_e: float, lim) -> float | None:
    """(g5) emergency: full vertical speed away from the nearest voxel within r_e (None: a neighbour raised it)."""
    centres, _ = occ_map.occupied_in_sphere(pos, r_e)
    if len(centres) == 0:
        return None
    nearest = centres[np.argmin(((centres - pos) ** 2).sum(axis=1))]
    return -lim.vz_max if nearest[2] > pos[2] else lim.vz_max


def paper_planner(ablation: str, use_vfh: bool = False):
    """A registry factory: ``PaperPlanner(PaperConfig.named(ablation, use_vfh))``."""
    def make():
        return PaperPlanner(PaperConfig.named(ablation, use_vfh))
    make.__name__ = f"paper_{ablation.lower().replace('+', '_')}{'_fusion' if use_vfh else ''}"
    return make


__all__ = ["PaperConfig", "PaperPlanner", "paper_planner"]
