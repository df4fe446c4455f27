"""The fusion expert's numba geometry kernels on its own map's voxels and grid (serial, ``cache=True``)."""

from __future__ import annotations

import math

import numba
import numpy as np

from uavform_env.dynamics import V, VZ, W, integrate, window, wrap
from uavform_env.formation import slot_xy
from uavform_env.occupancy import MapArrays, voxel_logodds

TURN_SHRINK, TURN_RADII, TURN_STEP = 0.7, 6, 0.1   # ``clear_turn_radius``: radii r_pp x 0.7^k, k < 6; path steps (m)


def columns_without_gap(occ_map, centres: np.ndarray, z_min: float, z_max: float, gap: float,
                        seen: bool = True, misses: int = 0) -> np.ndarray:
    """x, y of the map columns holding an occupied voxel in [z_min, z_max] but no way through there: a run
    of non-occupied voxels of height >= ``gap`` of which at least one voxel is known free (``seen=False``:
    unknown voxels alone make a way too, the optimistic raster an explorer falls back on).

    A run of unknown voxels alone is not a way: a wall whose top the UAV has not seen is a wall (that
    optimism sent followers along a corridor's wall into the world's corners); one ray through the
    run (over a low wall, through a gap) is enough. ``misses`` > 0: a known-free voxel counts only when its
    log-odds holds ``misses`` of the map's miss updates (crossed by rays in that many scans, net of its hits), or
    sits at the clamp l_min: a lost ray reads as free space once, through whatever it would have hit. Only the
    columns of the occupied voxels ``centres`` are read, so the cost follows the obstacles, not the map.
    """
    res = occ_map.resolution
    origin = occ_map.origin
    k_lo = max(0, int(math.ceil((z_min - origin[2]) / res - 0.5)))
    k_hi = min(occ_map.shape[2], int(math.floor((z_max - origin[2]) / res - 0.5)) + 1)
    cfg = occ_map.cfg
    l_occ = np.float32(cfg.logodds(cfg.p_occ))                        # the map's float32 occupancy threshold
    # the free evidence a way needs: ``misses`` miss updates (half of one spared for float32 sums), or the clamp
    # l_min where that is nearer; 0: any known non-occupied voxel
    l_way = np.float32(max((misses - 0.5) * cfg.logodds(cfg.p_miss), cfg.logodds(cfg.p_min)) if misses > 0 else np.inf)
    out = np.empty((len(centres), 2))
    n = _gapless_columns_kernel(occ_map.arrays(), np.ascontiguousarray(centres, dtype=np.float64), origin, res,
                                z_min - res, z_max + res, k_lo, k_hi, l_occ, l_way, gap, seen, out)
    return out[:n]


@numba.njit(cache=True)
def _gapless_columns_kernel(leaves, centres, origin, res, z_lo, z_hi, k_lo, k_hi, l_occ, l_way, gap, need_seen, out):
    """Write into ``out`` the x, y of each column (once) of a voxel of ``centres`` within [z_lo, z_hi] whose
    layers k_lo..k_hi-1 hold no run of non-occupied voxels >= ``gap`` (with a known-free voxel, log-odds at most
    ``l_way``, if ``need_seen``); return the count."""
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
            seen = seen or value <= l_way or not need_seen     # NaN (unknown) compares False
            if seen and length * res >= gap - 1e-9:
                way = True
                break
        if not way:
            out[n, 0] = origin[0] + (i + 0.5) * res
            out[n, 1] = origin[1] + (j + 0.5) * res
            n += 1
    return n


@numba.njit(cache=True)
def open_level_way(window_open, cell, target_azimuth, window):
    """Whether an open cell of the two level rows of 3D VFH+'s open-window mask lies within ``window`` of the
    target azimuth (cells of ``cell`` rad, column 0 at azimuth 0)."""
    mid = window_open.shape[0] // 2
    for col in range(window_open.shape[1]):
        if window_open[mid - 1, col] or window_open[mid, col]:
            if abs(wrap((col + 0.5) * cell - target_azimuth)) <= window:
                return True
    return False


@numba.njit(cache=True)
def in_sphere(points, values, centre, radius):
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
        k = keep[m]
        inside[m, 0], inside[m, 1], inside[m, 2] = points[k, 0], points[k, 1], points[k, 2]
        inside_values[m] = values[k]
    return inside, inside_values


@numba.njit(cache=True)
def segment_clear(centres, a, b, clearance):
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


@numba.njit(cache=True)
def gap_altitude_kernel(parts, origin, res, pos, ux, uy, t_stop, z_pref, span, h_b, z_min, z_max, margin,
                        unseen_wall):
    """The known-gap altitude on the leaves (``parts``: the fields of a ``MapArrays`` as a plain tuple, which numba
    types from Python far faster than a new named tuple every call): the columns at ``pos + t * (ux, uy)`` for t in
    ``np.arange(res, t_stop, res)`` (its values: res + i res), the first blocking the band around ``z_pref``, and
    the runs known free through it and the next ``span - 1`` columns; NaN if none. A column blocks the band with an
    occupied voxel in it, or (``unseen_wall``) with the band all unknown and the first known voxel from the band
    toward the UAV's altitude ``pos[2]`` occupied: a wall seen down (or up) to there, unseen beyond."""
    leaves = MapArrays(*parts)
    nx, ny, nz = leaves.shape[0], leaves.shape[1], leaves.shape[2]
    n_t = max(0, math.ceil((t_stop - res) / res))
    cols = np.empty((n_t, 2), np.int64)
    k_cols = 0
    for i in range(n_t):
        t = res + i * res
        ci = int(math.floor((pos[0] + t * ux - origin[0]) / res))
        cj = int(math.floor((pos[1] + t * uy - origin[1]) / res))
        if 0 <= ci < nx and 0 <= cj < ny:
            cols[k_cols, 0], cols[k_cols, 1] = ci, cj
            k_cols += 1
    if k_cols == 0:
        return math.nan
    z = origin[2] + (np.arange(nz) + 0.5) * res
    first = -1
    for i in range(k_cols):
        known = False
        for k in range(nz):
            if abs(z[k] - z_pref) <= h_b + res / 2:
                value = voxel_logodds(leaves, cols[i, 0], cols[i, 1], k)
                known = known or not math.isnan(value)
                if value > 0.0:
                    first = i
                    break
        if first < 0 and unseen_wall and not known and _wall_beyond(leaves, cols[i, 0], cols[i, 1], z, z_pref,
                                                                    pos[2], h_b + res / 2):
            first = i
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
def _wall_beyond(leaves, i, j, z, z_pref, z_uav, half):
    """Whether the first known voxel of column (i, j) past the band ``z_pref`` +- ``half``, going toward ``z_uav``
    (up to the UAV's altitude), is occupied."""
    up = z_uav > z_pref
    for step in range(z.size):
        k = step if up else z.size - 1 - step
        if (z[k] <= z_pref + half) if up else (z[k] >= z_pref - half):
            continue                                            # inside the band, or on its far side
        if (z[k] > z_uav) if up else (z[k] < z_uav):
            return False                                        # past the UAV's altitude
        value = voxel_logodds(leaves, i, j, k)
        if not math.isnan(value):
            return value > 0.0
    return False


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


@numba.njit(cache=True)
def surface_clearance(pos, obstacles, radius, r_uav):
    """Distance from ``pos`` to the nearest voxel surface (balls of ``radius``) minus r_uav; inf without voxels."""
    if obstacles.shape[0] == 0:
        return math.inf
    best = math.inf
    for k in range(obstacles.shape[0]):
        dx, dy, dz = obstacles[k, 0] - pos[0], obstacles[k, 1] - pos[1], obstacles[k, 2] - pos[2]
        best = min(best, dx * dx + dy * dy + dz * dz)
    return math.sqrt(best) - radius - r_uav


@numba.njit(cache=True)
def braking_arc_clearance(state, w_c, dt, v_min, v_max, a_max, w_max, dw_max, obstacles, radii, r_uav):
    """The least clearance (distance to the obstacle balls of ``radii`` minus r_uav) along the arc a unicycle in
    ``state`` (x, y, z, psi, v, w, ...) flies at its altitude while it brakes at a_max to v_min, its turn rate
    moving to ``w_c`` at dw_max within +/- w_max: the env's dynamic window (``dynamics.window``); inf if it is
    at rest or no obstacle lies within its stopping distance plus the obstacle's radius and r_uav."""
    x, y, z, psi, v, w = state[0], state[1], state[2], state[3], state[V], state[W]
    if v <= v_min:
        return math.inf
    reach = (v * v - v_min * v_min) / (2.0 * a_max) + v * dt + r_uav
    near = np.empty(obstacles.shape[0], np.int64)
    n = 0
    for k in range(obstacles.shape[0]):
        dx, dy, dz = obstacles[k, 0] - x, obstacles[k, 1] - y, obstacles[k, 2] - z
        if dx * dx + dy * dy + dz * dz <= (reach + radii[k]) ** 2:
            near[n] = k
            n += 1
    best = math.inf
    while v > v_min and n > 0:
        v, w, _ = window(v_min, w_c, 0.0, v, w, 0.0, dt, v_min, v_max, w_max, a_max, dw_max, 0.0, 0.0)
        x, y, z, psi = integrate(x, y, z, psi, v, w, 0.0, dt)
        for j in range(n):
            k = near[j]
            dx, dy, dz = obstacles[k, 0] - x, obstacles[k, 1] - y, obstacles[k, 2] - z
            best = min(best, math.sqrt(dx * dx + dy * dy + dz * dz) - radii[k])
    return best - r_uav


@numba.njit(cache=True)
def closest_approach(pos, vel, movers_pos, movers_vel, n_steps, dt):
    """The least distance to the movers over steps 1..n_steps, everyone at constant velocity."""
    return closest_approach_of(pos, vel, movers_pos, movers_vel, np.ones(movers_pos.shape[0], np.bool_), n_steps, dt)


@numba.njit(cache=True)
def closest_approach_of(pos, vel, movers_pos, movers_vel, which, n_steps, dt):
    """``closest_approach`` to the movers selected by the mask ``which``; inf if none is."""
    best = math.inf
    for k in range(1, n_steps + 1):
        t = k * dt
        for m in range(movers_pos.shape[0]):
            if not which[m]:
                continue
            dx = (pos[0] - movers_pos[m, 0]) + t * (vel[0] - movers_vel[m, 0])
            dy = (pos[1] - movers_pos[m, 1]) + t * (vel[1] - movers_vel[m, 1])
            dz = (pos[2] - movers_pos[m, 2]) + t * (vel[2] - movers_vel[m, 2])
            best = min(best, math.sqrt(dx * dx + dy * dy + dz * dz))
    return best


@numba.njit(cache=True)
def nearest_live(pos, movers, alive):
    """Index (into ``movers``) and distance of the nearest live mover (``alive``) to ``pos``; (-1, inf) if none.
    The distance is ``np.linalg.norm``'s (x^2 + y^2 + z^2, summed in that order); the first of equals wins."""
    best, m = math.inf, -1
    for k in range(movers.shape[0]):
        if alive[k]:
            dx, dy, dz = movers[k, 0] - pos[0], movers[k, 1] - pos[1], movers[k, 2] - pos[2]
            d = math.sqrt(dx * dx + dy * dy + dz * dz)
            if d < best:
                best, m = d, k
    return m, best


@numba.njit(cache=True)
def live_within(pos, movers, alive, radius):
    """The live ``movers`` (M, 3) nearer than ``radius`` to ``pos`` (``np.linalg.norm``'s distance), in their order."""
    keep = np.empty(movers.shape[0], dtype=np.int64)
    n = 0
    for k in range(movers.shape[0]):
        dx, dy, dz = movers[k, 0] - pos[0], movers[k, 1] - pos[1], movers[k, 2] - pos[2]
        if alive[k] and math.sqrt(dx * dx + dy * dy + dz * dz) < radius:
            keep[n] = k
            n += 1
    out = np.empty((n, 3))
    for m in range(n):
        k = keep[m]
        out[m, 0], out[m, 1], out[m, 2] = movers[k, 0], movers[k, 1], movers[k, 2]
    return out


@numba.njit(cache=True)
def mark_cells(blocked, origin_x, origin_y, res, xy):
    """Set the cells of the 2D raster ``blocked`` (origin, cell size ``res``) that contain the points ``xy``
    (K, 2) to True; points outside the raster are ignored."""
    nx, ny = blocked.shape
    for k in range(xy.shape[0]):
        i = int(math.floor((xy[k, 0] - origin_x) / res))
        j = int(math.floor((xy[k, 1] - origin_y) / res))
        if 0 <= i < nx and 0 <= j < ny:
            blocked[i, j] = True


@numba.njit(cache=True)
def predicted_movers(states, cos_psi, sin_psi, dt, predict):
    """The neighbours as movers (g6) from their broadcast rows ``states`` (K, 7) and the cosines and sines of their
    headings: positions one cycle ahead (the broadcasts are one cycle old) and velocities (zero unless
    ``predict``)."""
    n = states.shape[0]
    pos, vel = np.empty((n, 3)), np.zeros((n, 3))
    for k in range(n):
        vx, vy, vz = states[k, V] * cos_psi[k], states[k, V] * sin_psi[k], states[k, VZ]
        pos[k, 0], pos[k, 1], pos[k, 2] = states[k, 0] + vx * dt, states[k, 1] + vy * dt, states[k, 2] + vz * dt
        if predict:
            vel[k, 0], vel[k, 1], vel[k, 2] = vx, vy, vz
    return pos, vel


@numba.njit(cache=True)
def trail_lags(trail, leader_xy, followers_xy, allowed):
    """[X] ``leader_pace="trail"``: each follower's lag along the leader's trail (points (M, 2), oldest first, the
    leader at ``leader_xy`` past the last): the least, over the trail's points, of its distance to the point plus
    how much farther than ``allowed`` (K,) the point lies behind the leader along the trail. A follower trailing
    through a door on the leader's own way lags by nothing while its slot, swung round the bend with the leader's
    heading, is metres off; one held behind an obstacle, off the trail or far back along it, still lags; where the
    leader turned back along its own trail, the newer points count."""
    m = trail.shape[0]
    behind = math.hypot(leader_xy[0] - trail[m - 1, 0], leader_xy[1] - trail[m - 1, 1])
    lags = np.full(followers_xy.shape[0], np.inf)
    for j in range(m - 1, -1, -1):                      # newest first, ``behind`` growing along the trail
        if j < m - 1:
            behind += math.hypot(trail[j + 1, 0] - trail[j, 0], trail[j + 1, 1] - trail[j, 1])
        for i in range(followers_xy.shape[0]):
            lag = math.hypot(followers_xy[i, 0] - trail[j, 0], followers_xy[i, 1] - trail[j, 1]) \
                + max(0.0, behind - allowed[i])
            if lag < lags[i]:
                lags[i] = lag
    return lags


@numba.njit(cache=True)
def trail_arc(trail, leader_xy, p, limit):
    """[X] ``column_shape="trail"``: where the point ``p`` lies along the leader's trail (points (M, 2), oldest first,
    the leader at ``leader_xy`` past the last): the arc length from the leader back to the trail's point nearest
    ``p``, of the part within ``limit`` m of the leader (the newest nearest where several tie)."""
    arc, best, best_arc = 0.0, np.inf, 0.0
    ax, ay = leader_xy[0], leader_xy[1]
    for j in range(trail.shape[0] - 1, -1, -1):         # segments newest first, from the leader back along the trail
        if arc > limit:
            break
        bx, by = trail[j, 0], trail[j, 1]
        dx, dy = bx - ax, by - ay
        length = math.hypot(dx, dy)
        if length > 0.0:
            u = min(1.0, max(0.0, ((p[0] - ax) * dx + (p[1] - ay) * dy) / (length * length)))
            d = math.hypot(p[0] - (ax + u * dx), p[1] - (ay + u * dy))
            if d < best:
                best, best_arc = d, arc + u * length
        arc += length
        ax, ay = bx, by
    return best_arc


@numba.njit(cache=True)
def trail_points(trail, leader_xy, arcs):
    """The points (K, 2) ``arcs`` (K,) m behind the leader along its trail (``trail_arc``'s frame); an arc beyond the
    trail's oldest point gives that point. Also returns whether the trail reaches the largest arc."""
    out = np.empty((arcs.shape[0], 2))
    done = np.zeros(arcs.shape[0], np.bool_)
    arc = 0.0
    ax, ay = leader_xy[0], leader_xy[1]
    for j in range(trail.shape[0] - 1, -1, -1):
        bx, by = trail[j, 0], trail[j, 1]
        dx, dy = bx - ax, by - ay
        length = math.hypot(dx, dy)
        if length > 0.0:
            for k in range(arcs.shape[0]):
                if not done[k] and arcs[k] <= arc + length:
                    f = max(0.0, arcs[k] - arc) / length
                    out[k, 0], out[k, 1] = ax + f * dx, ay + f * dy
                    done[k] = True
        arc += length
        ax, ay = bx, by
    for k in range(arcs.shape[0]):
        if not done[k]:
            out[k, 0], out[k, 1] = ax, ay
    return out, arc >= arcs.max()


@numba.njit(cache=True)
def slot_errors(x, y, cos_psi, sin_psi, offsets, ids, states, alive):
    """Horizontal distances of the live rows of ``states`` (K, 7; ``alive``) to their slots, the body-frame
    ``offsets`` rows ``ids`` turned by a heading with cosine and sine ``cos_psi``, ``sin_psi`` (numpy's, as
    ``formation.slot_positions`` takes them) about (x, y): ``formation.slot_xy`` about the origin plus (x, y), as
    ``slot_positions`` about the origin is, then ``np.linalg.norm`` of the differences."""
    n = 0
    for k in range(ids.shape[0]):
        n += alive[k]
    out = np.empty(n)
    m = 0
    for k in range(ids.shape[0]):
        if not alive[k]:
            continue
        o = ids[k]
        sx, sy = slot_xy(0.0, 0.0, cos_psi, sin_psi, offsets[o, 0], offsets[o, 1])
        dx, dy = states[k, 0] - (x + sx), states[k, 1] - (y + sy)
        out[m] = math.sqrt(dx * dx + dy * dy)
        m += 1
    return out


@numba.njit(cache=True)
def _turn_path_clear(x, y, z, psi, px, py, run, r, centres, c2, ds):
    """Whether the horizontal path at altitude z from (x, y) on heading ``psi``: ``run`` m straight on, then a turn on
    radius ``r`` (0: in place) toward (px, py) until the nose points at it, then straight to it, keeps every centre
    farther than sqrt(c2) and reaches the point (a turn too wide for it never does)."""
    max_steps = int((run + 2.0 * math.pi * r + 2.0 * r + math.hypot(px - x, py - y)) / ds) + 2
    travelled = 0.0
    for _ in range(max_steps):
        dx, dy = px - x, py - y
        if math.hypot(dx, dy) <= ds:
            return True
        if travelled >= run:
            err = wrap(math.atan2(dy, dx) - psi)
            turn = ds / r if r > 0.0 else abs(err)
            if abs(err) <= turn:                        # facing the point: the straight segment
                psi += err
            else:
                psi += turn if err > 0.0 else -turn
        x += ds * math.cos(psi)
        y += ds * math.sin(psi)
        travelled += ds
        for k in range(centres.shape[0]):
            ex, ey, ez = centres[k, 0] - x, centres[k, 1] - y, centres[k, 2] - z
            if ex * ex + ey * ey + ez * ez <= c2:
                return False
    return False


@numba.njit(cache=True)
def clear_turn_radius(x, y, z, psi, v, px, py, r_pp, centres, clearance, w_max, a_max):
    """The largest turning radius r of r_pp (the pure-pursuit radius onto (px, py)), r_pp x ``TURN_SHRINK``, ...
    (``TURN_RADII`` radii) and 0 (a turn in place) whose path toward (px, py) keeps the voxel ``centres`` farther than
    ``clearance`` (``_turn_path_clear``, in steps of ``TURN_STEP`` m): straight on while braking at ``a_max`` from the
    speed ``v`` to the turn's speed w_max r, the turn until the nose points at the point, then straight to it;
    r_pp when none does (the point is hidden: no turn helps). Only the centres within ``clearance`` of the path's
    altitude can come that near (the squared distance is at least the squared height difference, in floats too), so
    the paths are tested against that slab of them."""
    c2 = clearance * clearance
    near = np.empty(centres.shape[0], np.bool_)
    for k in range(centres.shape[0]):
        ez = centres[k, 2] - z
        near[k] = ez * ez <= c2
    centres = centres[near]
    r = r_pp
    for i in range(TURN_RADII + 1):
        if i == TURN_RADII:
            r = 0.0
        v_turn = w_max * r
        run = (v * v - v_turn * v_turn) / (2.0 * a_max) if v > v_turn else 0.0
        if _turn_path_clear(x, y, z, psi, px, py, run, r, centres, c2, TURN_STEP):
            return r
        r *= TURN_SHRINK
    return r_pp
