"""FormationEnv: the PettingZoo ParallelEnv of N UAVs flying a formation through a 3D obstacle field.

The class is glue: every stage of a step (dynamics, collisions, sensing, maps, observations,
rewards) is an array function of its own module, called here in this order: validate -> commands ->
dynamics (and wind) -> collisions -> sensing (and its faults) -> maps (one batched call) -> observations ->
rewards, endings and infos. The README's "Using the environment" is this env's documentation page.
"""

from __future__ import annotations

import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from . import dynamics
from .actions import action_rows
from .collisions import CRASH_CAUSES, NONE, contacts, separations
from .config import DisturbanceConfig, EnvConfig, disturbance_preset
from .dynamics import PSI, STATE_DIM, V, VZ, W
from .formation import formation_slots, slot_distances, slot_offsets
from .kernels import compile_notice
from .observations import ObservationLayout, build_observations
from .occupancy import (BLOCK_EDGE, CHUNK_EDGE, MapStore, available_memory, map_memory_estimate,
                        seen_blocks_bound)
from .onboard import OnboardView, PriorMap
from .rewards import compute_rewards
from .scenarios import Scenario, ScenarioFileError, load_scenario, make_scenario, validate_scenario
from .sensing import STATIC, RangeSensor, perturb_scan
from .wind import GUST_MODES, GustField
from .world import World, _read_only, grid_frame

_LAYOUTS_KEPT = 2  # layouts (scenario, raster, prior) an env keeps for its next resets
_DETOUR = 2.0      # the memory estimate's flight length over the straight start-goal line

INFO_KEYS = ("clearance", "separation", "formation_error", "target_distance", "goal_distance", "speed",
             "altitude", "crashed", "crash_cause", "success", "end_reason", "step", "TimeLimit.truncated")
INFO_INTEGERS = ("crashed", "crash_cause", "success", "end_reason", "step")   # the counts and codes among them
# Integer codes of the infos "crash_cause" (per UAV, collisions.CRASH_CAUSES) and "end_reason" (the episode's, 0
# while it runs).
# Success needs every UAV flying: once one crashed, the episode's end reason is that (first) crash.
END_REASONS = ("running", "success", "timeout", "crash-obstacle", "crash-uav", "crash-geofence")


class FormationEnv(ParallelEnv):
    """N UAVs (``uav_0`` is the leader) fly from the scenario's start to its goal in formation.

    Args:
        scenario: a registered scenario name (``uavform_env.scenarios.list_scenarios()``), a path to a
            scenario TOML file, or a ``Scenario``.
        n_uavs, formation, spacing, difficulty: override the scenario's mission. The team (size, shape,
            spacing) stays fixed for the env's life: what is not overridden comes from the scenario
            generated with seed 0 (version-2 generators draw it from the seed).
        max_cycles: episode length in steps (overrides ``config.episode.max_cycles``).
        render_mode: ``None``, ``"rgb_array"`` (headless) or ``"human"``.
        remove_crashed: remove crashed UAVs from ``agents`` instead of freezing them.
        config: an ``EnvConfig``; its fields are documented in ``uavform_env.config``.
        layout_seed: fix the obstacle layout of a generated scenario (default: the reset seed).
        top_down: render the top view instead of the 3D view.
        disturbance: wind and sensor faults, a preset name (``config.DISTURBANCE_PRESETS``) or a
            ``DisturbanceConfig``; default: the scenario file's ``[disturbance]`` if it has one, else
            ``config.disturbance``.
    """

    metadata = {"name": "formation_v0", "render_modes": ["human", "rgb_array"], "render_fps": 10,
                "is_parallelizable": True}

    def __init__(self, scenario: str | Path | Scenario = "forest", n_uavs: int | None = None,
                 formation: str | None = None, spacing: float | None = None, difficulty: str | None = None,
                 max_cycles: int | None = None, render_mode: str | None = None, remove_crashed: bool | None = None,
                 config: EnvConfig | None = None, layout_seed: int | None = None, top_down: bool = False,
                 disturbance: str | DisturbanceConfig | None = None):
        cfg = config if config is not None else EnvConfig()
        if not isinstance(cfg, EnvConfig):
            raise ValueError(f"config: expected an EnvConfig, got {type(cfg).__name__}")
        if max_cycles is not None or remove_crashed is not None:
            cfg = cfg.replace(episode=cfg.episode.replace(
                **({"max_cycles": max_cycles} if max_cycles is not None else {}),
                **({"remove_crashed": remove_crashed} if remove_crashed is not None else {})))
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode={render_mode!r}: expected None or one of {self.metadata['render_modes']}")
        self.render_mode = render_mode
        self.top_down = bool(top_down)
        self.layout_seed = layout_seed
        self._overrides = {k: v for k, v in (("n_uavs", n_uavs), ("formation", formation), ("spacing", spacing))
                           if v is not None}
        self._difficulty = difficulty
        self._fixed_scenario, self._scenario_name = self._resolve_scenario(scenario)
        # how errors name the scenario: a loaded file by its path, otherwise by name, version and seed
        self._source = f"scenario file {scenario}" if isinstance(scenario, (str, Path)) and \
            str(scenario).endswith(".toml") else None
        first = self._scenario_for(0)
        mission = first.mission
        if self._fixed_scenario is None:  # the team is fixed for the env's life: version-2 generators draw it
            self._overrides = {"n_uavs": mission.n_uavs, "formation": mission.formation, "spacing": mission.spacing}
        cfg = cfg.replace(formation=cfg.formation.replace(shape=mission.formation, spacing=mission.spacing))
        if isinstance(disturbance, str):
            disturbance = disturbance_preset(disturbance)
        elif disturbance is None:
            disturbance = first.disturbance
        elif not isinstance(disturbance, DisturbanceConfig):
            raise ValueError(f"disturbance: expected a preset name or a DisturbanceConfig, "
                             f"got {type(disturbance).__name__}")
        if disturbance is not None:
            cfg = cfg.replace(disturbance=disturbance)
        if cfg.map.resolution is None:                  # the maps on the scenario's grid (fixed for the env's life)
            cfg = cfg.replace(map=cfg.map.replace(resolution=first.resolution))
        if self._source is not None:
            try:  # a file's mistakes are reported now, naming the file
                validate_scenario(first, cfg.uav, cfg.formation.z_ref, source=self._source)
            except ValueError as e:
                raise ScenarioFileError(str(e)) from None
        self.config = cfg
        self.max_cycles = cfg.episode.max_cycles
        self.n_uavs = mission.n_uavs
        _check_memory(first, cfg, self.n_uavs)
        self.offsets = slot_offsets(mission.formation, mission.n_uavs, mission.spacing)

        self.possible_agents = [f"uav_{i}" for i in range(self.n_uavs)]
        self.agent_name_mapping = {a: i for i, a in enumerate(self.possible_agents)}
        self._is_follower = np.arange(self.n_uavs) > 0
        self.layout = ObservationLayout(cfg)
        obs_space = self.layout.space()
        act_space = spaces.Box(-1.0, 1.0, (3,), np.float32)
        self.observation_spaces = {a: obs_space for a in self.possible_agents}
        self.action_spaces = {a: act_space for a in self.possible_agents}
        self.state_space = spaces.Box(-1.0, 1.0, (9 * self.n_uavs + 3,), np.float32)
        self.sensor = RangeSensor(cfg.sensor)
        self.agents: list[str] = []
        self._episode_seeds: np.random.Generator | None = None
        self.scenario: Scenario | None = None
        self._snapshot: SimpleNamespace | None = None            # see _onboard_snapshot
        n = self.n_uavs                                          # row i: the UAVs other than i (onboard views)
        others = np.tile(np.arange(n, dtype=np.int64), (n, 1))[~np.eye(n, dtype=bool)].reshape(n, n - 1)
        self._others = _read_only(others)
        self._map_store: MapStore | None = None                  # the onboard maps, cleared by every reset
        self._layouts: dict = {}                                 # see _layout
        self.world = None
        self._renderer = None
        self._compile_checked = False                          # the first reset tells a cold numba cache

    # ------------------------------------------------------------------ spaces
    def observation_space(self, agent):
        return self.observation_spaces[agent]

    def action_space(self, agent):
        return self.action_spaces[agent]

    # ------------------------------------------------------------------ scenario handling
    def _resolve_scenario(self, scenario):
        if isinstance(scenario, Scenario):
            return scenario, scenario.name
        if isinstance(scenario, Path) or (isinstance(scenario, str) and scenario.endswith(".toml")):
            return load_scenario(scenario), str(scenario)
        if not isinstance(scenario, str):
            raise ValueError(f"scenario: expected a name, a .toml path or a Scenario, got {type(scenario).__name__}")
        make_scenario(scenario, seed=0, difficulty=self._difficulty, **self._overrides)  # fail fast on bad names
        return None, scenario

    def _scenario_for(self, seed: int) -> Scenario:
        if self._fixed_scenario is not None:
            scn = self._fixed_scenario
            return scn.with_mission(**self._overrides) if self._overrides else scn
        return make_scenario(self._scenario_name, seed=seed, difficulty=self._difficulty, **self._overrides)

    # ------------------------------------------------------------------ reset
    def reset(self, seed: int | None = None, options: dict | None = None):
        if not self._compile_checked:         # one stderr line at the first reset if numba's cache is cold
            self._compile_checked = True
            compile_notice()
        if seed is not None:
            self._episode_seeds = np.random.default_rng(seed)
        elif self._episode_seeds is not None:   # Gymnasium's convention: unseeded resets continue the seeded stream
            seed = int(self._episode_seeds.integers(2**63))
        root = np.random.SeedSequence(seed)
        noise_ss, wind_ss, dropout_ss = root.spawn(3)  # one stream per disturbance: each leaves the others as they are
        self._noise_rng = np.random.default_rng(noise_ss)
        self._wind_rng = np.random.default_rng(wind_ss)
        self._dropout_rng = np.random.default_rng(dropout_ss)
        layout_seed = self.layout_seed if self.layout_seed is not None else (
            seed if seed is not None else int(root.generate_state(1)[0]))
        scn, world, prior = self._layout(layout_seed)
        cfg = self.config
        validate_scenario(scn, cfg.uav, cfg.formation.z_ref, world, source=self._source)
        self.scenario, self.world, self._prior = scn, world, prior
        m = scn.mission
        self.goal = np.asarray(m.goal, dtype=np.float64)
        self._bounds = np.asarray(scn.bounds_lo, dtype=np.float64), np.asarray(scn.bounds_hi, dtype=np.float64)
        self.slot_altitude = m.slot_altitude

        n = self.n_uavs
        self.states = np.zeros((n, STATE_DIM))
        self.states[:, :3] = formation_slots(np.asarray(m.start), m.start_heading, self.offsets, cfg.formation.z_ref,
                                             m.slot_altitude)
        self.states[0, 2] = m.start[2]
        self.states[:, PSI] = m.start_heading
        self.broadcast = self.states.copy()
        self.active = np.ones(n, bool)
        self.present = np.ones(n, bool)
        self.crashed = np.zeros(n, bool)
        self.crash_cause = np.zeros(n, np.int64)  # index into CRASH_CAUSES
        self.end_reason = self._first_crash = 0  # indices into END_REASONS
        self.prev_actions = np.zeros((n, 3), np.float32)
        self.air = np.zeros((n, 3))   # the wind (m/s) where each UAV was at the last step: gust plus mean
        self.lean = np.zeros((n, 3))  # the wind each UAV's autopilot compensates (dynamics.wind_drift)
        self.drift = np.zeros((n, 3))  # the velocity the wind carried each UAV by at the last step: air - lean
        d = cfg.disturbance
        self._gusts = (GustField(self._wind_rng, d.wind_std, d.wind_tau, d.wind_length, GUST_MODES, d.wind_vertical)
                       if d.wind_std > 0 else None)
        self.step_count = 0
        self.success = False
        origin, shape = grid_frame(scn.bounds_lo, scn.bounds_hi, cfg.map.resolution)   # the maps' own grid
        store = self._map_store
        if store is not None and (store.cfg, store.n_maps) == (cfg.map, n):
            store.clear(origin, shape)                           # a new layout's grid, the same block pool
        else:
            self._map_store = MapStore(origin, shape, cfg.map.resolution, cfg.map, n)
            self._map_views = [m.read_only() for m in self._map_store.maps]
        self.maps = self._map_store.maps
        self._sense()
        self.agents = list(self.possible_agents)
        ferr, self._target_dist = slot_distances(self.states, self.true_slots(), self.goal)
        clearance = self._clearance()
        self.history = {"positions": [self.states[:, :3].copy()], "yaw": [self.states[:, PSI].copy()],
                        "w": [self.states[:, W].copy()], "formation_error": [ferr],
                        "clearance": [clearance], "crashed": [self.crashed.copy()]}
        obs = self._observe()
        infos = self._infos(clearance, separations(self.states), ferr, self._target_dist, self.goal_distance(),
                            truncated=False)
        return obs, infos

    def _layout(self, seed: int) -> tuple[Scenario, World, PriorMap]:
        """Scenario, ground truth and prior map of a layout seed; the two most recent layouts are kept, so
        resetting to a layout seen last (or the one before) builds nothing."""
        key = None if self._fixed_scenario is not None else seed
        cache = self._layouts
        if key in cache:
            cache[key] = cache.pop(key)                          # most recently used last
        else:
            scn = self._scenario_for(seed)
            world = scn.build_world()
            cache[key] = (scn, world, self._build_prior(scn, world))
            while len(cache) > _LAYOUTS_KEPT:
                del cache[next(iter(cache))]
        return cache[key]

    def _build_prior(self, scn: Scenario, world: World) -> PriorMap:
        ep = self.config.episode
        if ep.prior_map == "heightmap":
            origin_xy, res, heights = world.heightmap(ep.prior_resolution)
        else:
            res = ep.prior_resolution
            origin_xy, shape = grid_frame(scn.bounds_lo[:2], scn.bounds_hi[:2], res)
            heights = np.zeros(shape, np.float32)
        heights = _read_only(np.array(heights, np.float32))
        return PriorMap(np.asarray(origin_xy, float), float(res), heights, ep.prior_map)

    # ------------------------------------------------------------------ step
    def step(self, actions):
        if not self.agents:
            raise ValueError("step() called after the episode ended (no live agents); call reset() first")
        acts = self._validate_actions(actions)
        cfg = self.config
        was_active = self.active.copy()
        self.broadcast = self.states.copy()
        dynamics.step_actions(self.states, acts, self.active, cfg.uav)
        self._apply_wind()
        self.step_count += 1

        clearance = self._clearance()
        separation, cause, any_crash = contacts(self.states, clearance, *self._bounds, 2.0 * cfg.uav.r_uav,
                                                self.active)
        crashed_now = cause != NONE
        first_crash = any_crash and not self.crashed.any()
        if any_crash:
            self.crash_cause[crashed_now] = cause[crashed_now]
            self.crashed |= crashed_now
            self.active &= ~crashed_now
            self.states[crashed_now, V] = self.states[crashed_now, W] = self.states[crashed_now, VZ] = 0.0

        self._sense()
        ferr, target_dist = slot_distances(self.states, self.true_slots(), self.goal)
        goal_dist = self.goal_distance()
        leader_ok = self.active[0] and goal_dist < cfg.episode.r_goal
        followers_ok = (ferr[1:][self.active[1:]] < cfg.formation.e_f).all()
        self.success = bool(leader_ok and followers_ok and not self.crashed.any())

        rew = compute_rewards(cfg.reward, self._target_dist, target_dist, ferr, self._is_follower,
                              crashed_now.astype(float), was_active, acts, self.prev_actions, self.success)
        self._target_dist = target_dist
        self.prev_actions = acts

        ended = self.success or not self.active[0] or not self.active.any()
        truncated = (not ended) and self.step_count >= self.max_cycles
        if first_crash:
            cause = CRASH_CAUSES[self.crash_cause[np.flatnonzero(crashed_now)[0]]]
            self._first_crash = END_REASONS.index(f"crash-{cause}")
        if ended or truncated:
            self.end_reason = self._first_crash if self.crashed.any() else \
                END_REASONS.index("success" if self.success else "timeout")
        live = list(self.agents)
        obs = self._observe()
        infos = self._infos(clearance, separation, ferr, target_dist, goal_dist, truncated=truncated)
        index = self.agent_name_mapping
        rew = rew.tolist()
        rewards = {a: rew[index[a]] for a in live}
        terminations = dict.fromkeys(live, bool(ended))
        truncations = dict.fromkeys(live, bool(truncated))
        if cfg.episode.remove_crashed:
            for a in live:
                if self.crashed[index[a]]:
                    terminations[a] = True
        self._record(ferr, clearance)
        self.agents = [] if (ended or truncated) else [a for a in live if not terminations[a]]
        if self.agents and len(self.agents) < len(live):
            self.present = np.isin(self.possible_agents, self.agents)
        if len(live) < self.n_uavs:
            obs = {a: obs[a] for a in live}
            infos = {a: infos[a] for a in live}
        return obs, rewards, terminations, truncations, infos

    def _validate_actions(self, actions) -> np.ndarray:
        rows = action_rows(actions, self.possible_agents, self.agents, 3, "forward speed, yaw rate, climb rate")
        if len(actions) == self.n_uavs and list(actions) == self.possible_agents:  # every agent, in order
            return rows.astype(np.float32)
        acts = np.zeros((self.n_uavs, 3), np.float32)
        acts[[self.agent_name_mapping[a] for a in actions]] = rows
        return acts

    def _apply_wind(self):
        d, dt = self.config.disturbance, self.config.uav.dt
        if not d.windy:
            return
        # The gust field where each UAV is, plus the steady mean wind; the autopilot leans into its estimate of
        # it, and what it does not compensate carries the UAV.
        air = self.air
        air[:] = 0.0
        air[:, :2] = d.wind_mean
        if self._gusts is not None:
            self._gusts.advance(dt)
            air += self._gusts.at(self.states[:, :3])
        u = self.config.uav
        self.drift[:] = dynamics.wind_drift(air, self.lean, self.active, u)
        self.states[self.active, :3] += self.drift[self.active] * dt
        np.clip(self.states[:, 2], u.z_min, u.z_max, out=self.states[:, 2])

    # ------------------------------------------------------------------ stages
    def _sense(self):
        scan = self.sensor.scan(self.world.occupied, self.world.origin, self.world.res, self.states[:, :3],
                                self.states[:, PSI], self.step_count, self.config.uav.r_uav)
        d = self.config.disturbance
        if d.range_noise_std > 0 or d.ray_dropout > 0:
            scan = perturb_scan(scan, self.states[:, :3], self.config.sensor.r_max, d.range_noise_std, d.ray_dropout,
                                self._noise_rng, self._dropout_rng)
        live = np.flatnonzero(self.active)
        rows = slice(None) if live.size == self.n_uavs else live  # views, not copies, while every UAV flies
        self._map_store.integrate(live, self.states[rows, :3], scan.endpoints[rows], scan.kind[rows] == STATIC)
        self.last_scan = scan

    def _clearance(self) -> np.ndarray:
        return self.world.clearance(self.states[:, :3]) - self.config.uav.r_uav

    def goal_distance(self) -> float:
        """The leader's 3D distance to the goal (the infos' ``goal_distance``)."""
        return float(np.linalg.norm(self.states[0, :3] - self.goal))

    def true_slots(self) -> np.ndarray:
        """World positions (N, 3) of the formation's slots at the leader's true state (row 0: the leader's)."""
        lead = self.states[0]
        return formation_slots(lead[:3], lead[PSI], self.offsets, self.config.formation.z_ref, self.slot_altitude)

    def _broadcast_slots(self) -> np.ndarray:
        lead = self.broadcast[0]
        return formation_slots(lead[:3], lead[PSI], self.offsets, self.config.formation.z_ref, self.slot_altitude)

    def _observe(self) -> dict:
        targets = self._broadcast_slots()
        targets[0] = self.goal
        obs = build_observations(self.layout, self.config, self.states, targets, 0, self.broadcast,
                                 self._map_store, self.present)
        return {a: obs[i] for i, a in enumerate(self.possible_agents)}

    def _infos(self, clearance, separation, ferr, target_dist, goal_dist: float, truncated: bool) -> dict:
        success, end, step, truncated = int(self.success), int(self.end_reason), int(self.step_count), bool(truncated)
        per_uav = zip(self.possible_agents, clearance.tolist(), separation.tolist(), ferr.tolist(),
                      target_dist.tolist(), self.states[:, V].tolist(), self.states[:, 2].tolist(),
                      self.crashed.astype(np.int64).tolist(), self.crash_cause.tolist())
        return {a: {"clearance": c, "separation": s, "formation_error": f, "target_distance": t,
                    "goal_distance": goal_dist, "speed": v, "altitude": z, "crashed": crashed, "crash_cause": cause,
                    "success": success, "end_reason": end, "step": step, "TimeLimit.truncated": truncated}
                for a, c, s, f, t, v, z, crashed, cause in per_uav}

    def _record(self, ferr, clearance):
        h = self.history
        h["positions"].append(self.states[:, :3].copy())
        h["yaw"].append(self.states[:, PSI].copy())
        h["w"].append(self.states[:, W].copy())
        h["formation_error"].append(ferr)
        h["clearance"].append(clearance)
        h["crashed"].append(self.crashed.copy())

    # ------------------------------------------------------------------ views for policies and critics
    def onboard(self, agent: str) -> OnboardView:
        """What ``agent`` can know on board: never the ground truth (see ``OnboardView``)."""
        if agent not in self.agent_name_mapping:
            raise ValueError(f"onboard: unknown agent {agent!r}; agents are {self.possible_agents}")
        if self.scenario is None:
            raise ValueError("onboard: call reset() first")
        i = self.agent_name_mapping[agent]
        snap = self._onboard_snapshot()
        return OnboardView(
            agent=agent, index=i, is_leader=(i == 0), state=snap.states[i], goal=snap.goal, slot=snap.slots[i],
            slot_offset=snap.offsets[i], offsets=snap.offsets, z_ref=self.config.formation.z_ref,
            slot_altitude=self.slot_altitude,
            leader_state=snap.broadcast[0] if i else snap.states[0], neighbour_ids=snap.others[i],
            neighbour_states=snap.neighbour_states[i], neighbour_alive=snap.neighbour_alive[i],
            occupancy=snap.maps[i], prior=self._prior, limits=self.config.uav, config=self.config,
            step=self.step_count, bounds_lo=snap.bounds_lo, bounds_hi=snap.bounds_hi, crashed=bool(self.crashed[i]))

    def _onboard_snapshot(self) -> SimpleNamespace:
        """Read-only copies shared by every agent's view of this step, made once per step (``step`` and
        ``reset`` replace ``self.broadcast``, which keys the snapshot). Each UAV's true state is a copy of its
        own, so no view reaches the others' true states (through ``.base``)."""
        snap = self._snapshot
        if snap is None or snap.key is not self.broadcast:
            others = self._others
            copy = _read_only_copy          # fresh arrays (the slots, fancy-indexed rows) need no copy
            snap = SimpleNamespace(
                key=self.broadcast, states=[copy(row) for row in self.states], broadcast=copy(self.broadcast),
                slots=_read_only(self._broadcast_slots()), goal=copy(self.goal), offsets=copy(self.offsets),
                others=others, neighbour_states=_read_only(self.broadcast[others]),
                neighbour_alive=_read_only((self.active & self.present)[others]), maps=self._map_views,
                bounds_lo=copy(self.scenario.bounds_lo), bounds_hi=copy(self.scenario.bounds_hi))
            self._snapshot = snap
        return snap

    def state(self) -> np.ndarray:
        lo, hi = np.asarray(self.scenario.bounds_lo), np.asarray(self.scenario.bounds_hi)
        span = np.maximum(hi - lo, 1e-9)
        u = self.config.uav
        s = self.states
        per = np.column_stack([2 * (s[:, :3] - lo) / span - 1, np.sin(s[:, PSI]), np.cos(s[:, PSI]),
                               s[:, V] / u.v_max, s[:, W] / u.w_max, s[:, VZ] / max(u.vz_max, 1e-9),
                               self.active.astype(float)])
        g = 2 * (self.goal - lo) / span - 1
        return np.clip(np.concatenate([per.ravel(), g]), -1, 1).astype(np.float32)

    # ------------------------------------------------------------------ rendering
    def render(self):
        if self.render_mode is None:
            import gymnasium
            gymnasium.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' or 'human'")
            return None
        if self.scenario is None:
            raise ValueError("render: call reset() first")
        from .render import Renderer
        if self._renderer is None:
            self._renderer = Renderer(self.render_mode, top_down=self.top_down)
        return self._renderer.draw(self)

    def close(self):
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None


def _check_memory(scn: Scenario, cfg: EnvConfig, n: int) -> None:
    """ValueError if the ground-truth raster and n onboard maps will not fit in the memory available.

    Each map is expected to hold the blocks within r_max of a flight _DETOUR times as long as the
    straight line from start to goal (or of the whole episode at v_max, if that is shorter), as
    ``seen_blocks_bound`` counts them; maps that see more grow their pools as they go."""
    res = cfg.map.resolution
    _, truth = grid_frame(scn.bounds_lo, scn.bounds_hi, scn.resolution)
    _, shape = grid_frame(scn.bounds_lo, scn.bounds_hi, res)
    u, m = cfg.uav, scn.mission
    path = min(u.v_max * u.dt * cfg.episode.max_cycles, _DETOUR * math.dist(m.start, m.goal))
    seen = [seen_blocks_bound(cfg.sensor.r_max, path, res, edge) for edge in (BLOCK_EDGE, CHUNK_EDGE)]
    need = math.prod(truth) + map_memory_estimate(shape, n, *seen)
    have = available_memory()
    if need > have:
        raise ValueError(f"n_uavs={n} at map resolution {res:g} m over a {shape[0]}x{shape[1]}x{shape[2]} "
                         f"voxel world needs an estimated {need / 2**30:.2f} GiB, but only {have / 2**30:.2f} GiB is "
                         "available; use fewer UAVs, a coarser resolution, a shorter sensor.r_max or free memory")


def _read_only_copy(a) -> np.ndarray:
    """A read-only copy: views handed to policies must not alias the env's state."""
    return _read_only(np.array(a))
