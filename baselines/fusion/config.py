"""``ExpertConfig``: every weight and threshold of the fusion controller, and the residual-RL weight vector."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from uavform_env.config import Config, boolean, check_range, in_range, instance_of, integer, one_of

from ..astar import AStarConfig
from ..dwa import DWAConfig
from ..vfh3d import VFHConfig

WEIGHT_NAMES = ("alpha0", "beta", "gamma", "eps0", "k1", "k2", "k3")
ASTAR_LAYERS = ("passable", "band")
REJOIN_MODES = ("astar", "trail")
PARK_HEADINGS = ("nearest", "followers")
LEADER_PACES = ("slot", "trail")
COLUMN_SHAPES = ("rigid", "trail")
DOCK_TURN_SPEEDS = ("stopped", "stop")
DOCK_TURN_TOWARD = ("heading_goal", "target")


@dataclass(frozen=True)
class ExpertConfig(Config):
    """Every weight and threshold of the fusion controller (spec (g), Appendix A 'formation').

    use_vfh            3D fusion (True) or the planar formation of the 2D baselines (False)
    neighbour_prediction  neighbours move at their broadcast velocity in DWA (g6; E6 switches it off)
    shape_switching    a follower whose slot is blocked in its own map falls back to a column slot (g7) [X]
    column_at_goal     the column fallback also once the leader is parked at its goal (broadcast speed below
                       ``leader_stopped_speed`` within ``arrive_radius`` of the goal); False: the follower then
                       closes on its own slot, which is what the env judges (DWA keeps its clearance): a follower
                       whose map showed a voxel within r_uav + r_safe + a voxel of a slot 0.76 m from a tree flew
                       to the column slot 11 m away and stayed there [X]
    leader_right_of_way  (g6)'s "the leader never yields" in DWA's dist term: the leader's dist term counts no
                       neighbour (each still makes a sample closer than R_uu inadmissible); followers count every
                       neighbour. Off by default: it lifted v1-dev (a dog-leg leader turned back at a wall's closed
                       end had crawled 8 s behind its follower) but not v1, where it added obstacle crashes; figures
                       in docs/deviations.md [X]
    column_shape       the column of ``shape_switching``: ``"rigid"``, slots ``index`` x spacing behind the leader along
                       its heading; ``"trail"``, places that far behind it along its broadcast trail, followed as a
                       path (``FusionExpert._file_place``), and the leader's pace (``leader_pace="trail"``) lets each
                       follower lag that far along the trail. At a dog-leg's door the leader turns a quarter turn just
                       past it, and the rigid column swung with its heading into the wall beside the door [X]
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
    dock_turn_angle    a slow follower of a parked leader (``dock_turn_speed``) turns in
                       place toward its target when that lies more than this far off its nose and at least
                       e_f / 2 away; DWA's rotation cost and sum-normalised heading term otherwise hold it at
                       rest there (w = 0 wins at v = 0) [X]
    dock_turn_toward   where such a follower turns: ``"heading_goal"``, the point DWA steers for, which is 3D VFH+'s
                       detour when it takes one; ``"target"``, its target whatever 3D VFH+ says (before session 31):
                       a follower at rest against a tree with its target behind it turned to and fro with DWA [X]
    dock_turn_speed    which followers ``dock_turn_angle`` turns in place: ``"stopped"``, below
                       ``leader_stopped_speed``; ``"stop"``, those that stop within e_f / 2 at a_max (v^2 < a_max e_f,
                       0.32 m/s): a follower creeping at 0.06-0.1 m/s with its slot 0.7 m away and 80 degrees off
                       its nose circled it for 25 s, DWA's rotation cost holding its turn rate at a quarter of w_max
                       (forest seed 0) [X]
    slot_brake         while the leader is within ``dock_radius`` of its goal (where it will stop), a follower in
                       formation (not on a rejoin path) flies no faster than it can stop, at the
                       airframe's a_max, within its horizontal distance to the slot plus the leader's own braking
                       distance: v <= sqrt(v_leader^2 + 2 a_max d). Catching up at 0.9 m/s behind a leader that
                       parked, a follower overshot its slot by 1 m and spent the rest of the episode turning back
                       (wall-gap v1-dev s200120 breeze) [X]
    pursuit_speed_cap  cap the speed at w_max / kappa, kappa = 2 sin(theta) / d the pure-pursuit curvature onto the
                       lookahead point (distance d, bearing theta off the nose; d / 2 beyond 90 degrees): the
                       turn-rate limit then lets the UAV steer onto the point instead of overshooting a corner
                       of its path (a leader passed a wall's opening 0.5 m/s too fast and followed the wall) [X]
    pursuit_clear      with ``pursuit_speed_cap``, the turn onto the point must also clear the UAV's own map: the cap is
                       w_max x the largest radius, of the pure-pursuit radius and smaller ones down to a turn in place
                       (``kernels.clear_turn_radius``), whose path (straight on while braking at a_max to the
                       turn's speed, the turn toward the point, then straight to it) keeps r_uav + r_safe from its
                       voxels near DWA's reach. A follower flying along a wall at 1 m/s toward a
                       slot through a door 90 degrees off its nose took the pure-pursuit arc's speed, which runs into
                       the wall, passed the door and was pinned beyond it (dog-leg v1-dev s200255) [X]
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
                       0.5 m and parks against whatever lies beyond (the world's bound). 4 m, not 1.5 m: after a
                       dog-leg's last door the goal came up 3-5 m abeam and DWA (its rotation cost keeps the
                       turn gentle) circled it at 0.6 m/s on a 7 m arc until the time-out [X]
    e0, e1, min_leader_scale  leader formation feedback of (g2): its speed cap scales from 1 at a mean follower
                       error e0 down to min_leader_scale at e1 [D: the spec's 1 m, 3 m, 0.3 held a forest
                       formation, which is always stretched, at 0.24 m/s]
    solo_full_speed    a leader with no live follower flies up to v_max: ``leader_speed_cap`` is the followers'
                       speed margin (g2), and a UAV flying alone needs none [X]
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
    path_to_goal       the A* lookahead at the path's end is the goal itself when the path ends in the goal's raster
                       cell: the path runs through cell centres, and a leader at the end of the path sat 0.35 m from
                       its goal (outside ``arrive_radius``), its pursuit cap toward a lookahead under itself at 0, and
                       turned to and fro for the last 40 s; the followers' predicted slots swung with it (wall-gap
                       v1-dev s200118) [X]
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
    gap_unseen_wall    the gap rule's level test also finds the band around the target altitude blocked where it is
                       all unknown and the first known voxel from it toward the UAV's altitude is occupied: a wall
                       seen down to there is taken to go on. A follower in a wall's gap 5 m above its slot's
                       altitude (the leader had descended to its goal) saw the band there as unknown, lost the gap
                       and slid down along the wall for 20 s (wall-gap v1-dev s200118) [X]
    gap_hold           with a known gap ahead (the gap rule finds the slot's or cruise altitude blocked within
                       ``gap_lookahead`` and returns another), LEVEL mode holds the gap's altitude, not the slot's:
                       3D VFH+ sees a level way at the UAV's own altitude inside the gap while the altitude hold
                       pulled a follower back to its slot's, too near the gap's edge for DWA, and it slid along the
                       wall behind it to time-out (wall-gap v1-dev s200120 breeze, s200118). Off by default: on
                       the calm slice (expert-dev/calm-suite.toml) it cost two random-3d episodes, where the rule
                       lifted followers off their slots' altitude over obstacles they could pass level, and gained
                       none (20/34 with it, 22/34 without, 21/34 before all of gap_hold, gap_turn, slot_brake) [X]
    gap_turn_angle     a UAV steering through a known gap in a wall ahead (the gap rule active) turns in place
                       when its heading goal lies more than this far off its nose: DWA's clearance term kept a
                       follower that arrived along the wall parallel to it, sliding past the gap (rule
                       ``gap_turn``; pi disables it) [X]
    climb_target_limit in CLIMB, when 3D VFH+'s elevation points toward the target altitude, the climb rate is
                       at most ``k_z`` times the altitude error: the 5-degree elevation cells never give 0,
                       so a follower parked at its slot (target ~1 m away) otherwise oscillates +/- 1 m
                       around the slot altitude and never closes the formation [X]
    lateral_emergency_to_dwa  an emergency of (g5) (a voxel or neighbour inside 3D VFH+'s r_e) whose nearest voxel
                       lies more beside the UAV than above or below it, or which no voxel within r_e raised (a
                       neighbour did), is left to DWA, whose admissibility keeps the clearance and the separation:
                       the spec's stop-and-climb away never ends beside a floor-to-ceiling wall (a follower froze
                       at a corridor's mouth), nor beside a parked leader [X]
    dock_approach, approach_radius  the leader within ``approach_radius`` of its goal, along a segment clear of its
                       own map by r_uav + r_safe, flies ``rules.home_in`` (turn toward the goal, speed k_hold x
                       distance + headwind, pure-pursuit cap) instead of DWA's choice: in gusts DWA flew past the
                       goal and orbited it 1-2 m away. Followers dock with DWA, which keeps them apart [X]
    hold_radius, k_hold, vane_wind  station keeping (``rules.station_keep``): a holding UAV (the arrived leader at
                       its goal, a UAV with no way to its goal) flies the air velocity k_hold (p_hold - p) - wind
                       (nose toward it, speed |.| cos(bearing error)); within ``hold_radius`` with that below
                       ``vane_wind`` it stops and turns to its park heading, and flies back only once the wind
                       has carried it ``hold_release`` m off: a leader that turned toward every gust swept its
                       followers' slots round the goal (under ``breeze`` a follower chased its slot until time-out,
                       session 7). A UAV hovering at v = 0 otherwise drifts with the wind into whatever is downwind
                       (under the unopposed wind model; with the autopilot of ``UAVLimits.wind_authority`` only the
                       gusts' changes carry it) [X]
    hold_gust_time     in gusts (the RMS drift above ``vane_wind``) the hold and release radii grow by this times
                       the RMS drift, and on an airframe that leans into the wind (``UAVLimits.wind_authority``
                       > 0) the holding UAV rests in any wind: the gusts carry an autopilot-held UAV
                       about that far and back, and a parked leader that flew back after each excursion turned
                       its nose, and its followers' slots, round the goal until the time-out (session 14) [X]
    rest_gust_time     a holding UAV rests only while its horizontal clearance to its own map near its altitude
                       (and to the world's bounds) is at least r_safe plus this times the RMS drift, less what
                       r_safe covers (``rules.gust_standoff``); closer, it flies back to its hold point. r_safe
                       in still air. Why and figures: docs/deviations.md (``rest_gust_time``) [X]
    hold_drift_time, hold_search  a UAV with no way to its goal holds the nearest point within ``hold_search`` m
                       (reached along a clear straight segment) whose horizontal clearance to its own map near the
                       flight altitude and to the world's bounds is at least r_safe plus the drift the estimated wind
                       causes in ``hold_drift_time`` s (default: a quarter turn at 20 deg/s, the time to bring the
                       nose into a gust from abeam); none: the clearest such point. It moves on when the wind rises
                       past what the point's clearance covers. In still air it holds where it stopped [X]
    wind_tau           time constant (s) of the low-pass filter that estimates the wind from the UAV's own drift
                       (``rules.wind_estimate``: observed minus commanded motion) [X]
    gust_tau           time constant (s) of the mean square of the UAV's drift (``rules.gust_speed``, its root: the
                       drift speed gusts cause, which the wind margins scale with) [X]
    wind_margin, wind_margin_share  DWA's obstacle voxels grow by ``wind_margin`` (s) x the RMS drift
                       (less ``gust_allowance``), at most ``wind_margin_share`` of the UAV's current clearance (a UAV
                       the gusts carried inside its margin can still hold or leave; ``rules.wind_margin``). A share of
                       1/2 lets DWA close in to half the clearance every cycle, so the margin never stops an approach;
                       a larger share holds the UAV near the clearance it has once inside the margin [X]
    fence_margin       the world's bounds (``geofence_spacing``) grow by the wind margin too; False: they keep radius 0
                       (a gusty leader in ``classic-2d`` kept its margin from the discs and was carried out of the
                       world beside them) [X]
    wind_drift         DWA's rollouts drift with the estimated wind (``dwa_plan(drift=...)``) times the share of it
                       the autopilot leaves over the horizon (``rules.drift_persistence``). Off by default since
                       session 12: the drift left by the leaning autopilot is the gusts' high-pass part, and this
                       forecast of it points the wrong way (slope -0.99 against the drift realised over T_p;
                       docs/deviations.md); rollouts without drift crash less [X]
    path_margin, margin_detour  the leader's A* route is the path on its raster
                       inflated by r_uav + r_safe plus ``path_margin`` when that path is at most ``margin_detour`` m
                       longer than the one inflated by r_uav + r_safe alone (d1): a path one cell off a wall held
                       the leader 0.2 m from it, where DWA's braking-distance admissibility let it crawl along
                       the wall at 0.1-0.3 m/s; without the detour bound a follower preferred an unseen way round
                       a wall's far end to the known 2.6 m opening in it. Followers' rejoin paths keep (d1) alone:
                       with the margin, followers of 10-UAV forest formations lost their way to their slots [X]
    route_turn_cost    the leader's A* route is also planned from the point L_a (``astar.lookahead``) straight on
                       along its heading (when that leg is free), and of the two it flies the one whose length
                       plus its turn (the bearing of its point L_a along it off the heading) times
                       leader_speed_cap * v_max / w_max (the metres forgone while turning at w_max) is smaller
                       (``controller.route_cost``): with the E11 cost on the change of the turn rate the leader
                       turned at once onto a route only as long as one straight on, and in the unknown
                       ``classic-2d`` "extended" maze that route led into a pocket seen closed only on arrival [X]
    route_keep_margin  (with ``route_turn_cost``) the route straight on is flown unless the direct route costs at least
                       this many metres less (0: the cheaper of the two): the two costs are estimates through unseen
                       space, and a near tie (0.1-0.3 m of 18 m in the ``classic-2d`` "extended" maze) was decided
                       by a few degrees of heading at the first replan after the maze came into view, turning the
                       leader into a pocket whose exit reads closed only on arrival [X]
    way_misses         the ``passable`` raster's way through a map column (a run of non-occupied voxels tall enough
                       for the UAV) needs a voxel holding ``way_misses`` of the map's miss updates net of its hits
                       (crossed by rays in that many scans, or in as many as the UAV has made; or at the clamp p_min),
                       not one ray's (0: any known non-occupied voxel, as before): under ``noisy`` a lost ray reads as
                       free space once, through the obstacle it would have hit, and its miss with the unseen voxels
                       between the sensor's elevation rows opened ways through the columns of ``classic-2d``; the
                       leader's route ran through discs, before which it climbed and turned until time-out
                       (``kernels.columns_without_gap``) [X]
    leader_pace        what slows the leader by the (g2) feedback (``e0``, ``e1``): ``"slot"``, the followers' slot
                       errors; ``"trail"``, each follower's smaller of its slot error and its lag along the leader's own
                       trail (``kernels.trail_lags``: the least, over the trail's points, of its distance to the point
                       plus how much farther than its formation slot's range the point lies behind). At a dog-leg's door
                       bend the slots swing with the leader's heading: followers trailing through the door read 5-14 m
                       slot errors and held the leader at ``min_leader_scale`` for 50 s and more; a follower held behind
                       an obstacle is still waited for (pacing only followers farther than their slots' range lost calm
                       episodes that way) [X]
    guard_gust_time    ``rules.drift_guard``'s clearance (``guard_clearance``) grows by ``guard_gust_time`` (s) x
                       the RMS drift (``rules.gust_speed``): gust bursts of 2-3 times the RMS drift carried UAVs braking
                       0.5-1 m from a tree or wall into it before a 20 deg/s turn could point them away [X]
    gust_allowance     the gust margins (``wind_margin`` in DWA's obstacle radii, ``guard_gust_time`` in
                       ``rules.drift_guard``'s standoff) leave out this share of r_safe, which every clearance keeps
                       already (``rules.gust_standoff``: time x RMS drift - gust_allowance x r_safe, at least 0): a
                       breeze's RMS drift (~0.16 m/s) added 0.16 m to every voxel and a 0.48 m hover standoff on top
                       of r_safe, and the guard flew a leader turning into a wall's gap off the wall 425 times until
                       time-out (wall-gap v1-dev s200119 breeze); gusty drifts (~0.6 m/s) keep most of theirs [X]
    gust_braking       DWA's braking test (``DWAConfig.brake_share``) in the wind: the share is ``dwa.brake_share``
                       (the expert's 0: Fox's free-arc form, each rollout run on for its stopping time) raised to the
                       RMS drift (``rules.gust_speed``) over ``gust_braking`` m/s, at most 1 (the clearance form of
                       spec (b6)), by ``rules.braking_share``. Why: with the clearance form a UAV 1 m beside a wall
                       flies at most sqrt(2 a_max x 1 m) = 0.63 m/s; gusts make the rollouts a poor forecast, and there
                       the clearance form's speed-dependent standoff stays. At 0.3 m/s a breeze (RMS drift ~0.16 m/s)
                       asks about half of it and gusts (~0.6 m/s) all of it (0.1 until session 27: a breeze asked all
                       of it too). Figures and the variants tried: docs/deviations.md (``dwa.brake_share``,
                       ``gust_braking``) [X]
    guard_hover_speed  a UAV slower than this, within ``guard_gust_time`` x the RMS drift of an obstacle point beside
                       it, flies away from it (``rules.drift_guard``) even when DWA has admissible samples: DWA
                       chose to turn in place at v = 0, and the gusts carried the stopped UAV into the obstacle
                       (0 switches it off) [X]
    guard_dwa_exit     such a hovering UAV whose nose points away from the way off the obstacle keeps the command
                       when DWA accelerates it along a rollout at least as clear as it is now (``rules.drift_guard``);
                       False: the guard turns it in place first, as before session 22 [X]
    braking_turn       a UAV that a rule set braking while it turns (the braking fallback, a turn in place) flies on
                       along its nose until it stops, v^2 / (2 a_max) (1.7 m from 0.83 m/s), on the arc its turn
                       sweeps; when that arc would touch DWA's obstacle points (their radii, less r_uav), the turn
                       (the rule's, none, left or right at w_max) whose arc keeps the most clearance is flown
                       (``rules.braking_turn``): a follower at 0.83 m/s beside a building, its path's lookahead
                       behind it, turned in place the short way round, toward the wall, and coasted into it in still
                       air (urban, 12 UAVs) [X]
    vertical_margin    the gust margins per axis: ``rules.wind_estimate`` keeps the vertical drift apart, and DWA's
                       voxels grow by the horizontal margin (``wind_margin``) only where a horizontal drift can reach
                       them, within the vertical margin + voxel radius + r_uav of the altitudes the rollouts fly; above
                       or below those by the vertical one (``wind_margin`` s x the vertical RMS drift;
                       ``rules.gust_radii``); the gap rule keeps that vertical standoff more off a gap's edges. False:
                       every voxel grows by the horizontal margin (before session 23), which closed a wall's 2-3 m gap
                       to gusty flights [X]
    dwa                the IDWA of spec (c) with the approach speed profile, r_goal 0.1 m, ``dist_cap`` 0.5 m and
                       E11's rotation cost on the change of the turn rate (``rotation_mode="delta"``): the cost on
                       the turn rate itself kept a leader in open space from turning toward a goal off its nose [X]
    park_turn          the parked leader turns in place (v = 0) to the heading nearest its own whose follower
                       slots are all free in its own map and inside the world bounds: parked at the goal, it
                       can otherwise leave a slot inside an obstacle, and the formation can never close [X]
    park_heading       which heading with free slots the arriving leader parks on: "nearest" its own (turned
                       outward in ``2 pi / 72`` steps); "followers" the one whose slots lie nearest the followers'
                       broadcast positions (the sum of their horizontal distances), kept while its slots stay free.
                       Parked on its own heading after a docking turn, a leader swung the slots of a column's tail
                       12 m away from the followers trailing it [X]
    repark_time, repark_radius  (no frozen followers) the parked leader watches each live follower's 3D distance to its
                       slot of the park heading (from the broadcasts); a follower at least e_f off whose distance has
                       not dropped by ``trail_spacing`` for ``repark_time`` s marks that slot point as unreachable,
                       and the leader parks again on a heading (chosen by ``park_heading``) none of whose slots lies
                       within ``repark_radius`` of a marked point. The leader's map, which treats unknown as free, held
                       slots 0.06-0.17 m from trees it had not seen, and followers froze 0.5-1.3 m off them for the
                       rest of the episode (forest@1 seeds 1, 2). 0 switches it off [X]
    """

    dwa: DWAConfig = field(default_factory=lambda: DWAConfig.ablation("IDWA", approach_speed_profile=True,
                                                                                      r_goal=0.1, dist_cap=0.5,
                                                                                      rotation_mode="delta",
                                                                                      brake_share=0.0))
    vfh: VFHConfig = field(default_factory=VFHConfig)
    astar: AStarConfig = field(default_factory=lambda: AStarConfig(prune=True, heading_target="visible_goal"))
    use_vfh: bool = True
    neighbour_prediction: bool = True
    shape_switching: bool = True
    column_at_goal: bool = False
    leader_right_of_way: bool = False
    column_shape: str = "trail"
    astar_layer: str = "passable"
    dwa_map_level: int = 0
    replan_check_period: float = 0.5
    k_f: float = 0.5
    leader_stopped_speed: float = 0.05
    dock_turn_angle: float = math.radians(45.0)
    dock_turn_speed: str = "stop"
    dock_turn_toward: str = "heading_goal"
    dock_radius: float = 4.0
    reverse_turn_angle: float = math.radians(100.0)
    final_approach_free: bool = True
    pursuit_speed_cap: bool = True
    pursuit_clear: bool = True
    k_h: float = 1.0
    k_z: float = 0.5
    leader_speed_cap: float = 0.8
    solo_full_speed: bool = True
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
    path_to_goal: bool = True
    stuck_window: float = 10.0
    gap_lookahead: float = 4.0
    gap_depth: float = 1.0
    gap_margin: float = 0.1
    k_gap: float = 1.0
    gap_speed: float = 0.3
    climb_target_limit: bool = True
    gap_hold: bool = False
    gap_unseen_wall: bool = True
    slot_brake: bool = True
    gap_turn_angle: float = math.radians(45.0)
    hold_radius: float = 0.25
    hold_release: float = 0.4
    hold_gust_time: float = 3.0
    k_hold: float = 0.5
    wind_tau: float = 1.0
    gust_tau: float = 5.0
    hold_drift_time: float = 4.5
    hold_search: float = 4.0
    wind_drift: bool = False
    explore_unknown: bool = True
    route_turn_cost: bool = True
    path_margin: float = 0.5
    margin_detour: float = 2.0
    dock_approach: bool = True
    vane_wind: float = 0.1
    approach_radius: float = 3.0
    glide_slope: float = 0.5
    wind_margin: float = 1.5
    separation_margin: float = 0.3
    separation_tie: float = 0.1
    guard_clearance: float = 0.4
    guard_speed: float = 0.3
    guard_gust_time: float = 3.0
    guard_hover_speed: float = 0.1
    guard_dwa_exit: bool = True
    braking_turn: bool = True
    vertical_margin: bool = True
    park_turn: bool = True
    park_heading: str = "followers"
    # -- no frozen followers (issue 13, session 8 "s8slots")
    repark_time: float = 15.0
    repark_radius: float = 1.0
    lateral_emergency_to_dwa: bool = True
    # the passable raster: free evidence of a way (s8maze: classic-2d "extended" under noisy, issue 13)
    way_misses: int = 4
    # -- breeze (issue 13, session 9 "s9breeze"): gust margins count only what r_safe does not already cover
    gust_allowance: float = 1.0
    # -- speed beside walls (issue 13, session 16): Fox's free-arc braking in still air
    gust_braking: float = 0.3
    # -- the leader's pace at bends (issue 13, session 9 "s9dogleg")
    leader_pace: str = "trail"
    # -- gusts (issue 13, session 9 "s9gusty")
    wind_margin_share: float = 0.8
    fence_margin: bool = True
    # -- route choice in an unknown maze (issue 13, session 10 "s10maze")
    route_keep_margin: float = 1.0
    # -- a holding UAV rests only where it is clear (issue 13, session 18: parked leaders carried into trees)
    rest_gust_time: float = 1.5

    BOUNDS: ClassVar[dict] = {
        "dwa": instance_of(DWAConfig), "vfh": instance_of(VFHConfig), "astar": instance_of(AStarConfig),
        **{name: boolean for name in ("use_vfh", "neighbour_prediction", "shape_switching", "column_at_goal",
                                      "leader_right_of_way", "climb_target_limit", "gap_hold", "gap_unseen_wall",
                                      "path_to_goal", "slot_brake",
                                      "park_turn", "lateral_emergency_to_dwa", "level_line", "pursuit_speed_cap",
                                      "pursuit_clear", "rejoin_hidden", "final_approach_free", "wind_drift",
                                      "dock_approach", "explore_unknown", "route_turn_cost", "fence_margin",
                                      "solo_full_speed", "guard_dwa_exit", "vertical_margin", "braking_turn")},
        "astar_layer": one_of(ASTAR_LAYERS),
        "rejoin": one_of(REJOIN_MODES),
        "park_heading": one_of(PARK_HEADINGS),
        "leader_pace": one_of(LEADER_PACES),
        "column_shape": one_of(COLUMN_SHAPES),
        "dock_turn_speed": one_of(DOCK_TURN_SPEEDS),
        "dock_turn_toward": one_of(DOCK_TURN_TOWARD),
        "dwa_map_level": integer(0, 4),
        "debounce": integer(1, 100),
        "trail_window": integer(1),
        "way_misses": integer(0, 100),
        **{name: in_range(0.0) for name in ("replan_check_period", "k_f", "k_h", "k_z", "T_stuck", "climb_lookahead",
                                            "column_hold", "vfh_neighbour_radius", "rejoin_distance", "dock_radius",
                                            "trail_spacing", "arrive_radius", "stuck_window", "gap_lookahead",
                                            "gap_depth", "gap_margin", "k_gap", "gap_speed", "leader_stopped_speed",
                                            "hold_radius", "hold_release", "hold_gust_time", "k_hold",
                                            "separation_margin", "separation_tie", "hold_drift_time", "hold_search",
                                            "glide_slope",
                                            "wind_margin", "vane_wind",
                                            "approach_radius", "guard_clearance", "guard_speed", "guard_gust_time",
                                            "guard_hover_speed", "path_margin",
                                            "margin_detour", "repark_time", "repark_radius",
                                            "gust_allowance", "route_keep_margin", "rest_gust_time")},
        **{name: in_range(0.0, lo_open=True) for name in ("wind_tau", "gust_tau", "gust_braking")},
        "leader_speed_cap": in_range(0.0, 1.0, lo_open=True),
        "yield_factor": in_range(0.0, 1.0),
        "wind_margin_share": in_range(0.0, 1.0),
        "min_leader_scale": in_range(0.0, 1.0),
        "level_window": in_range(0.0, math.pi),
        "dock_turn_angle": in_range(0.0, math.pi),
        "reverse_turn_angle": in_range(0.0, math.pi),
        "gap_turn_angle": in_range(0.0, math.pi),
        "geofence_spacing": in_range(0.05),
        "e0": in_range(0.0),
    }

    def __post_init__(self):
        super().__post_init__()
        check_range("ExpertConfig", "e1", self.e1, self.e0, None, lo_open=True)   # bounded by e0

    @classmethod
    def planar(cls, ablation: str = "IDWA", **overrides) -> "ExpertConfig":
        """The 2D formation: fixed altitude, no 3D VFH+, the named DWA ablation, band raster for A*."""
        return cls(dwa=DWAConfig.ablation(ablation), use_vfh=False, astar_layer="band", **overrides)

    def weights(self) -> np.ndarray:
        """The evaluation weights in ``WEIGHT_NAMES`` order (DWA alpha0, beta, gamma, eps0; VFH k1, k2, k3)."""
        d, v = self.dwa, self.vfh
        return np.array([d.alpha0, d.beta, d.gamma, d.eps0, v.k1, v.k2, v.k3])

    def with_weights(self, w) -> "ExpertConfig":
        """A copy with the evaluation weights ``w`` (``WEIGHT_NAMES`` order), each checked against its field's
        declared bound (``Config.with_checked``: no check across fields reads a weight); called every step with
        residual weights."""
        w = np.asarray(w, dtype=np.float64)
        try:
            if w.shape != (len(WEIGHT_NAMES),):
                raise ValueError
            dwa = self.dwa.with_checked(alpha0=w[0], alpha=w[0], beta=w[1], gamma=w[2], eps0=w[3])
            vfh = self.vfh.with_checked(k1=w[4], k2=w[5], k3=w[6])
        except ValueError:
            raise ValueError(f"weights: expected {len(WEIGHT_NAMES)} finite values >= 0 in the order {WEIGHT_NAMES}, "
                             f"got {w.tolist() if w.size < 20 else w.shape}") from None
        return self.with_checked(dwa=dwa, vfh=vfh)

