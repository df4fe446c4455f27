"""Pictures of a formation flight: live frames, the episode picture and videos.

Matplotlib only. A ``Renderer`` keeps one figure: axes and obstacles are drawn once per world into a
cached background and each frame only blits the UAV artists over it. Only ``"human"`` mode touches
pyplot, so headless rendering never opens a window nor changes pyplot's global state.
"""

from __future__ import annotations

import io
import math
from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.cm import ScalarMappable
from matplotlib.collections import LineCollection, PolyCollection
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Circle, Patch
from mpl_toolkits.mplot3d.art3d import Line3D, Line3DCollection, Poly3DCollection

from .files import atomic_write_bytes, atomic_write_figure
from .formation import formation_slots

RENDER_MODES = ("rgb_array", "human")
DPI = 100
CYLINDER_SEGMENTS = 16
SPHERE_SEGMENTS = (12, 6)            # longitude x latitude quads per sphere
# Obstacles are coloured by their top height; light = low (flyable over), dark = tall.
OBSTACLE_CMAP = "YlOrBr"
OBSTACLE_ALPHA_3D = 0.35
LEADER_COLOUR = "black"
# No red (crashes), no orange/brown (obstacles), no light green (goal).
FOLLOWER_COLOURS = ("tab:blue", "tab:green", "tab:purple", "tab:cyan", "tab:pink", "navy", "tab:gray", "teal",
                    "darkviolet")
CRASH_COLOUR = "red"
GOAL_COLOUR = "limegreen"
# The 3D box is at least this tall relative to its longer side, so altitude changes stay visible in
# flat worlds (the vertical scale is stretched; the top view and altitude strip stay true to scale).
MIN_BOX_HEIGHT_RATIO = 0.35
CAMERA_ELEVATION_DEG = 28.0
# Camera azimuth relative to the start->goal direction: behind the start and to the right of the path.
CAMERA_AZIMUTH_OFFSET_DEG = -135.0
SNAPSHOT_PERIOD_S = 10.0             # formation snapshots in the episode picture
FAR_OFF_SLOT_M = 5.0                 # the formation-error strip marks and counts followers this far off their slot
DEFAULT_FPS = 10
VIDEO_SUFFIXES = (".gif", ".mp4")


# ---------------------------------------------------------------------------------------------- geometry
def _rows(world, name: str, width: int) -> np.ndarray:
    arr = np.asarray(getattr(world, name), dtype=np.float64)
    if arr.size == 0:
        return np.zeros((0, width))
    if arr.ndim != 2 or arr.shape[1] != width:
        raise ValueError(f"world.{name}: expected an array of shape (n, {width}), got shape {arr.shape}")
    return arr


_BOX_FACE_CORNERS = np.array([[0, 1, 3, 2], [4, 5, 7, 6], [0, 1, 5, 4], [2, 3, 7, 6], [0, 2, 6, 4], [1, 3, 7, 5]])


def box_faces(boxes: np.ndarray) -> np.ndarray:
    """The 6 quads (nb*6, 4, 3) of boxes given as rows [xlo, ylo, zlo, xhi, yhi, zhi]."""
    b = np.asarray(boxes, dtype=np.float64).reshape(-1, 6)
    bits = (np.arange(8)[:, None] >> np.arange(3)) & 1            # corner c has coordinate axis a at bit a
    corners = np.where(bits[None], b[:, None, 3:], b[:, None, :3])  # (nb, 8, 3)
    return corners[:, _BOX_FACE_CORNERS].reshape(-1, 4, 3)


def _ring(centres: np.ndarray, radii: np.ndarray, segments: int) -> np.ndarray:
    theta = np.linspace(0.0, 2.0 * np.pi, segments, endpoint=False)
    return centres[:, None, :2] + radii[:, None, None] * np.stack([np.cos(theta), np.sin(theta)], axis=1)


def cylinder_faces(cylinders: np.ndarray, segments: int = CYLINDER_SEGMENTS) -> tuple[np.ndarray, np.ndarray]:
    """Side quads (nc*segments, 4, 3) and top caps (nc, segments, 3) of rows [x, y, r, zlo, zhi]."""
    c = np.asarray(cylinders, dtype=np.float64).reshape(-1, 5)
    ring = _ring(c[:, :2], c[:, 2], segments)                       # (nc, s, 2)
    nxt = np.roll(ring, -1, axis=1)
    zlo = np.broadcast_to(c[:, 3, None, None], ring.shape[:2] + (1,))
    zhi = np.broadcast_to(c[:, 4, None, None], ring.shape[:2] + (1,))
    sides = np.stack([np.concatenate([ring, zlo], 2), np.concatenate([nxt, zlo], 2),
                      np.concatenate([nxt, zhi], 2), np.concatenate([ring, zhi], 2)], axis=2)
    return sides.reshape(-1, 4, 3), np.concatenate([ring, zhi], 2)


def sphere_faces(spheres: np.ndarray, segments: tuple[int, int] = SPHERE_SEGMENTS) -> np.ndarray:
    """Longitude-latitude quads (ns*n_lon*n_lat, 4, 3) of rows [x, y, z, r]."""
    s = np.asarray(spheres, dtype=np.float64).reshape(-1, 4)
    n_lon, n_lat = segments
    lon = np.linspace(0.0, 2.0 * np.pi, n_lon + 1)
    lat = np.linspace(-0.5 * np.pi, 0.5 * np.pi, n_lat + 1)
    unit = np.stack(np.broadcast_arrays(np.cos(lat)[:, None] * np.cos(lon), np.cos(lat)[:, None] * np.sin(lon),
                                        np.sin(lat)[:, None]), axis=-1)          # (n_lat+1, n_lon+1, 3)
    pts = s[:, None, None, :3] + s[:, 3, None, None, None] * unit
    quads = np.stack([pts[:, :-1, :-1], pts[:, :-1, 1:], pts[:, 1:, 1:], pts[:, 1:, :-1]], axis=3)
    return quads.reshape(-1, 4, 3)


def obstacle_footprints(world) -> tuple[list[np.ndarray], np.ndarray]:
    """Top-view outlines of every obstacle and its top height, lowest first (so taller ones are drawn on top)."""
    boxes, cyl, sph = _rows(world, "boxes", 6), _rows(world, "cylinders", 5), _rows(world, "spheres", 4)
    rects = box_faces(boxes)[0::6, :, :2]                            # the bottom face of each box
    outlines = list(rects) + list(_ring(cyl[:, :2], cyl[:, 2], CYLINDER_SEGMENTS)) + \
        list(_ring(sph[:, :2], sph[:, 3], CYLINDER_SEGMENTS))
    tops = np.concatenate([boxes[:, 5], cyl[:, 4], sph[:, 2] + sph[:, 3]])
    order = np.argsort(tops, kind="stable")
    return [outlines[i] for i in order], tops[order]


def _height_norm(scenario, world) -> Normalize:
    tops = obstacle_footprints(world)[1]
    top = max(float(np.asarray(scenario.bounds_hi, float)[-1]), float(tops.max()) if tops.size else 0.0)
    return Normalize(0.0, top if top > 0 else 1.0)


# ---------------------------------------------------------------------------------------------- drawing helpers
def _add_obstacles_3d(ax, world, norm: Normalize) -> None:
    boxes, cyl, sph = _rows(world, "boxes", 6), _rows(world, "cylinders", 5), _rows(world, "spheres", 4)
    sides, caps = cylinder_faces(cyl)
    quads = np.concatenate([box_faces(boxes), sides, sphere_faces(sph)])
    quad_tops = np.concatenate([np.repeat(boxes[:, 5], 6), np.repeat(cyl[:, 4], CYLINDER_SEGMENTS),
                                np.repeat(sph[:, 2] + sph[:, 3], np.prod(SPHERE_SEGMENTS))])
    cmap = colormaps[OBSTACLE_CMAP]
    for polys, tops in ((quads, quad_tops), (caps, cyl[:, 4])):
        if len(polys) == 0:
            continue
        faces = cmap(norm(tops))
        faces[:, 3] = OBSTACLE_ALPHA_3D
        edges = faces.copy()
        edges[:, :3] *= 0.6
        edges[:, 3] = 0.5
        ax.add_collection3d(Poly3DCollection(polys, facecolors=faces, edgecolors=edges, linewidths=0.3, zorder=1),
                            autolim=False)


def _add_obstacles_top(ax, world, norm: Normalize) -> None:
    outlines, tops = obstacle_footprints(world)
    if outlines:
        ax.add_collection(PolyCollection(outlines, array=tops, cmap=OBSTACLE_CMAP, norm=norm, edgecolors="0.35",
                                         linewidths=0.5, zorder=1), autolim=False)


def _height_colorbar(fig, norm: Normalize, z_ref: float, **where):
    """Colour key of obstacle heights with z_ref marked: obstacles below the mark can be flown over."""
    bar = fig.colorbar(ScalarMappable(norm=norm, cmap=OBSTACLE_CMAP), **where)
    bar.set_label("obstacle top [m]")
    bar.ax.axhline(z_ref, color="k", lw=1.5, ls="--")
    bar.ax.text(1.05, z_ref, " z_ref", transform=bar.ax.get_yaxis_transform(), va="center", fontsize=8)
    return bar


def _set_limits(ax, scenario, three_d: bool, zoom: float = 1.0) -> None:
    lo, hi = np.asarray(scenario.bounds_lo, float), np.asarray(scenario.bounds_hi, float)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    if three_d:
        ax.set_zlim(lo[2], hi[2])
        ax.set_zlabel("z [m]")
        span = hi - lo
        ax.set_box_aspect((span[0], span[1], max(span[2], MIN_BOX_HEIGHT_RATIO * span[:2].max())), zoom=zoom)
        course = np.asarray(scenario.mission.goal, float) - np.asarray(scenario.mission.start, float)
        heading_deg = math.degrees(math.atan2(course[1], course[0]))
        ax.view_init(elev=CAMERA_ELEVATION_DEG, azim=heading_deg + CAMERA_AZIMUTH_OFFSET_DEG)
        ax.computed_zorder = False                                    # UAVs stay visible through obstacles
    else:
        ax.set_aspect("equal")
        ax.grid(True, lw=0.3, alpha=0.5)


def uav_colours(n: int) -> list[str]:
    """The leader is black, followers cycle through distinct non-red colours (red marks crashes)."""
    return [LEADER_COLOUR] + [FOLLOWER_COLOURS[(i - 1) % len(FOLLOWER_COLOURS)] for i in range(1, n)]


def _dims(ax) -> int:
    return 3 if ax.name == "3d" else 2


def _empty_line(ax, **style):
    return ax.plot(*([[]] * _dims(ax)), **style)[0]


def _set_points(line, pts: np.ndarray) -> None:
    pts = np.asarray(pts, dtype=np.float64).reshape(-1, 3)
    if isinstance(line, Line3D):
        line.set_data_3d(pts[:, 0], pts[:, 1], pts[:, 2])
    else:
        line.set_data(pts[:, 0], pts[:, 1])


def _segments(ax, **style):
    col = Line3DCollection([], **style) if _dims(ax) == 3 else LineCollection([], **style)
    if _dims(ax) == 3:
        ax.add_collection3d(col, autolim=False)
    else:
        ax.add_collection(col, autolim=False)
    return col


def _set_segments(col, starts: np.ndarray, ends: np.ndarray) -> None:
    d = 3 if isinstance(col, Line3DCollection) else 2
    col.set_segments(np.stack([starts[:, :d], ends[:, :d]], axis=1))


def _check_env(env, who: str) -> None:
    if getattr(env, "scenario", None) is None or getattr(env, "world", None) is None:
        raise ValueError(f"{who}: env has no scenario yet (env.scenario is None); call env.reset() first")


def _legend_handles(names: tuple[str, ...]) -> list:
    """Legend entries by name, in the given order."""
    handles = {
        "leader": Line2D([], [], color=LEADER_COLOUR, marker="D", lw=2, label="leader"),
        "followers": Line2D([], [], color=FOLLOWER_COLOURS[0], marker="o", lw=1, label="followers"),
        "slots": Line2D([], [], color="0.4", marker="o", mfc="none", ls="none", label="formation slots"),
        "snapshots": Line2D([], [], color="0.25", ls="--", marker="o", ms=3.5,
                            label=f"formation every {SNAPSHOT_PERIOD_S:g} s"),
        "start": Line2D([], [], color="k", marker="s", mfc="white", ms=9, ls="none", label="start"),
        "goal": Line2D([], [], color=GOAL_COLOUR, marker="*", ms=12, mec="k", ls="none", label="goal"),
        "crashed": Line2D([], [], color=CRASH_COLOUR, marker="X", ms=9, ls="none", label="crashed"),
        "obstacles": Patch(facecolor=colormaps[OBSTACLE_CMAP](0.6), edgecolor="0.35", label="obstacles"),
    }
    return [handles[name] for name in names]


# ---------------------------------------------------------------------------------------------- live frames
class _Scene:
    """The artists of one world: static obstacles drawn once, UAV artists moved by ``update``."""

    def __init__(self, fig, env, top_down: bool):
        self.world = env.world
        self.n = env.n_uavs
        # Fixed placement (no layout engine per frame): the view on the left, legend and colour key on the right.
        ax = fig.add_axes((0.08, 0.08, 0.68, 0.84)) if top_down else \
            fig.add_axes((0.04, 0.0, 0.77, 0.95), projection="3d")
        norm = _height_norm(env.scenario, env.world)
        z_ref = env.config.formation.z_ref
        _set_limits(ax, env.scenario, not top_down, zoom=0.95)
        if top_down:
            _add_obstacles_top(ax, env.world, norm)
            ax.add_patch(Circle(env.goal[:2], env.config.episode.r_goal, fill=False, ec=GOAL_COLOUR, lw=1.5))
        else:
            _add_obstacles_3d(ax, env.world, norm)
        _height_colorbar(fig, norm, z_ref, cax=fig.add_axes((0.84, 0.08, 0.025, 0.42)))
        _set_points(_empty_line(ax, color=GOAL_COLOUR, marker="*", ms=16, mec="k", ls="none", zorder=6),
                    np.asarray(env.goal))
        colours = uav_colours(self.n)
        self.trails = [_empty_line(ax, color=c, lw=2.0 if i == 0 else 1.2, alpha=0.8, zorder=3)
                       for i, c in enumerate(colours)]
        self.bodies = [_empty_line(ax, color=c, marker="D" if i == 0 else "o", ms=8 if i == 0 else 6, mec="w",
                                   ls="none", zorder=5) for i, c in enumerate(colours)]
        self.headings = _segments(ax, colors=colours, linewidths=1.5, zorder=5)
        self.links = _segments(ax, colors="0.3", linewidths=0.8, linestyles="--", zorder=4)
        self.slots = _empty_line(ax, color="0.4", marker="o", mfc="none", ms=7, ls="none", zorder=4)
        self.crashes = _empty_line(ax, color=CRASH_COLOUR, marker="X", ms=11, mec="k", mew=0.5, ls="none", zorder=6)
        fig.legend(handles=_legend_handles(("leader", "followers", "slots", "goal", "crashed", "obstacles")),
                   loc="upper right", bbox_to_anchor=(0.995, 0.93), fontsize=8)
        self.hud = fig.text(0.01, 0.99, "", va="top", ha="left", fontsize=10)
        self.heading_length = 0.5 * float(np.max(np.linalg.norm(env.offsets[:, :2], axis=1), initial=2.0))
        self.dynamic = [*self.trails, self.links, self.slots, self.headings, *self.bodies, self.crashes, self.hud]
        for artist in self.dynamic:
            artist.set_animated(True)                 # left out of full redraws; blitted over the background

    def draw_dynamic(self, fig) -> None:
        for artist in self.dynamic:
            if hasattr(artist, "do_3d_projection"):   # 3D collections project only inside Axes3D.draw
                artist.do_3d_projection()
            fig.draw_artist(artist)

    def update(self, env) -> None:
        states = np.asarray(env.states, dtype=np.float64)
        pos, psi = states[:, :3], states[:, 3]
        trail = np.asarray(env.history["positions"], dtype=np.float64)            # (T+1, N, 3)
        for i in range(self.n):
            _set_points(self.trails[i], trail[:, i])
            _set_points(self.bodies[i], pos[i])
        tips = pos + self.heading_length * np.stack([np.cos(psi), np.sin(psi), np.zeros_like(psi)], axis=1)
        _set_segments(self.headings, pos, tips)
        _set_segments(self.links, np.repeat(pos[:1], self.n - 1, axis=0), pos[1:])
        slots = formation_slots(pos[0], psi[0], np.asarray(env.offsets), env.config.formation.z_ref, env.slot_altitude)
        _set_points(self.slots, slots[1:])
        _set_points(self.crashes, pos[np.asarray(env.crashed, bool)])
        t = env.step_count * env.config.uav.dt
        goal_dist = float(np.linalg.norm(pos[0] - np.asarray(env.goal)))
        name = getattr(env.scenario, "name", "")
        self.hud.set_text(f"{name}  t = {t:6.1f} s  step {env.step_count:5d}  leader->goal {goal_dist:6.1f} m  "
                          f"crashed {int(np.count_nonzero(env.crashed))}/{self.n}")


class Renderer:
    """Draws an env's current state: ``"rgb_array"`` returns an HxWx3 uint8 frame, ``"human"`` shows a window.

    The figure is made at the first ``draw`` (no window before that) and reused. Axes, ticks, legend
    and obstacles are drawn once into a cached background (again only when the env's world changes,
    e.g. a new layout after ``reset``, or the window is resized); each frame restores that background
    and blits the UAV artists over it.
    """

    def __init__(self, mode: str, top_down: bool = False, size=(800, 600)):
        if mode not in RENDER_MODES:
            raise ValueError(f"mode={mode!r}: expected one of {list(RENDER_MODES)}")
        try:
            width, height = (int(v) for v in size)
            ok = len(size) == 2 and all(float(v) == int(v) for v in size) and width >= 100 and height >= 100
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise ValueError(f"size={size!r}: expected (width, height) in whole pixels, each at least 100")
        self.mode = mode
        self.top_down = bool(top_down)
        self.size = (width, height)
        self._fig = None
        self._scene: _Scene | None = None
        self._background = None

    @property
    def figure(self):
        """The figure being drawn (None before the first ``draw``), e.g. to save the current frame as a PDF."""
        return self._fig

    def draw(self, env) -> np.ndarray | None:
        _check_env(env, "Renderer.draw")
        if self._fig is None or not self._figure_alive():
            self._fig, self._scene = self._new_figure(), None
        if self._scene is None or self._scene.world is not env.world or self._scene.n != env.n_uavs:
            self._fig.clear()
            self._scene, self._background = _Scene(self._fig, env, self.top_down), None
        self._scene.update(env)
        canvas = self._fig.canvas
        if self._background is None:
            canvas.draw()                             # fires draw_event -> _on_draw caches the background
        else:
            canvas.restore_region(self._background)
            self._scene.draw_dynamic(self._fig)
        if self.mode == "rgb_array":
            return np.asarray(canvas.buffer_rgba())[..., :3].copy()
        if canvas.required_interactive_framework is not None:   # a real window (not Agg)
            canvas.blit(self._fig.bbox)
            canvas.start_event_loop(1.0 / getattr(env, "metadata", {}).get("render_fps", DEFAULT_FPS))
        return None

    def close(self) -> None:
        if self._fig is not None and self.mode == "human":
            import matplotlib.pyplot as plt

            plt.close(self._fig)
        self._fig, self._scene, self._background = None, None, None

    def _on_draw(self, event) -> None:
        """Every full redraw (first frame, window resize) refreshes the cached background."""
        if self._scene is not None:
            self._background = self._fig.canvas.copy_from_bbox(self._fig.bbox)
            self._scene.draw_dynamic(self._fig)

    def _new_figure(self):
        figsize = (self.size[0] / DPI, self.size[1] / DPI)
        if self.mode == "rgb_array":
            fig = Figure(figsize=figsize, dpi=DPI)
            FigureCanvasAgg(fig)
        else:
            import matplotlib.pyplot as plt

            fig = plt.figure(figsize=figsize, dpi=DPI)
            if fig.canvas.required_interactive_framework is not None:
                plt.show(block=False)
        fig.canvas.mpl_connect("draw_event", self._on_draw)
        return fig

    def _figure_alive(self) -> bool:
        if self.mode == "rgb_array":
            return True
        import matplotlib.pyplot as plt

        return plt.fignum_exists(self._fig.number)


# ---------------------------------------------------------------------------------------------- episode picture
def _uav_handles(colours: list[str]) -> list:
    """One legend entry per UAV: the leader, then follower 1 .. N-1 in their colours."""
    return [Line2D([], [], color=c, lw=2.4 if i == 0 else 1.5, marker="D" if i == 0 else None,
                   label="leader (uav_0)" if i == 0 else f"follower {i}") for i, c in enumerate(colours)]


def _formation_panel(ax, t: np.ndarray, ferr: np.ndarray, colours: list[str], e_f: float) -> None:
    """Each follower's distance from its slot over time, with e_f and FAR_OFF_SLOT_M marked and their shares."""
    n = ferr.shape[1]
    ax.set_title("formation error: each follower's distance from its slot", fontsize=11)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("slot error [m]")
    ax.grid(True, lw=0.3, alpha=0.5)
    if n == 1:
        ax.text(0.5, 0.5, "a single UAV: no formation", transform=ax.transAxes, ha="center", va="center")
        ax.set_yticks([])
        return
    for i in reversed(range(1, n)):
        ax.plot(t, ferr[:, i], color=colours[i], lw=1.1)
    worst = ferr[:, 1:].max(axis=1)
    for level, style in ((e_f, ":"), (FAR_OFF_SLOT_M, "--")):
        ax.axhline(level, color="0.35", ls=style, lw=1.2)
        ax.text(1.003, level, f"{level:g} m", transform=ax.get_yaxis_transform(), va="center", fontsize=9)
    ax.text(0.995, 0.95, f"some follower > {e_f:g} m (e_f) off its slot in {np.mean(worst > e_f):.0%} of steps, "
            f"> {FAR_OFF_SLOT_M:g} m in {np.mean(worst > FAR_OFF_SLOT_M):.0%}", transform=ax.transAxes,
            ha="right", va="top", fontsize=9, bbox=dict(fc="white", ec="0.7", alpha=0.9))
    ax.set_ylim(0.0, max(float(worst.max()) * 1.08, FAR_OFF_SLOT_M * 1.2))


def plot_episode(env, path, title: str | None = None) -> Figure:
    """The trajectory picture of a finished (or running) episode.

    3D view (trajectories only), top view with formation snapshots (leader->follower links every
    ``SNAPSHOT_PERIOD_S`` seconds), the altitude profile and each follower's formation error over time.
    The format follows the suffix of ``path`` (``uavform fly --format png|svg|pdf``); the file is
    written atomically. Returns the figure (axes: 3D, top view, altitude, formation error, colour key).
    """
    path = Path(path)
    fmt = path.suffix.lower().lstrip(".")
    supported = FigureCanvasAgg(Figure()).get_supported_filetypes()
    if fmt not in supported:
        raise ValueError(f"path={str(path)!r}: expected a picture suffix, one of {sorted('.' + s for s in supported)}")
    _check_env(env, "plot_episode")
    pos = np.asarray(env.history["positions"], dtype=np.float64)              # (T+1, N, 3)
    crashed = np.asarray(env.history["crashed"], dtype=bool)                  # (T+1, N)
    dt = env.config.uav.dt
    z_ref = env.config.formation.z_ref
    n = pos.shape[1]
    colours = uav_colours(n)
    norm = _height_norm(env.scenario, env.world)
    crash_step = np.where(crashed.any(axis=0), crashed.argmax(axis=0), -1)
    crash_pts = pos[crash_step[crash_step >= 0], np.flatnonzero(crash_step >= 0)]
    every = max(1, round(SNAPSHOT_PERIOD_S / dt))
    snaps = np.unique(np.append(np.arange(0, len(pos), every), len(pos) - 1))

    fig = Figure(figsize=(16, 11.5), dpi=100)
    FigureCanvasAgg(fig)
    # Fixed placement: 3D view | top view + colour key; below, the altitude and formation-error strips + legend.
    ax3 = fig.add_axes((-0.02, 0.36, 0.54, 0.62), projection="3d")
    axt = fig.add_axes((0.53, 0.45, 0.37, 0.48))
    axz = fig.add_axes((0.05, 0.265, 0.66, 0.125))
    axf = fig.add_axes((0.05, 0.05, 0.66, 0.17), sharex=axz)
    _set_limits(ax3, env.scenario, True, zoom=1.0)
    _set_limits(axt, env.scenario, False)
    ax3.zaxis.set_rotate_label(False)                 # reads "z [m]" upwards, not "[m] z"
    ax3.set_zlabel("z [m]", rotation=90)
    _add_obstacles_3d(ax3, env.world, norm)
    _add_obstacles_top(axt, env.world, norm)
    _height_colorbar(fig, norm, z_ref, cax=fig.add_axes((0.925, 0.48, 0.012, 0.42)))
    axt.add_patch(Circle(np.asarray(env.goal)[:2], env.config.episode.r_goal, fill=False, ec=GOAL_COLOUR, lw=1.5,
                         zorder=6))

    start, goal = np.asarray(env.scenario.mission.start, float), np.asarray(env.goal, float)
    for k in snaps:                                   # formation snapshots in the top view only (less clutter)
        col = _segments(axt, colors="0.25", linewidths=0.9, linestyles="--", zorder=4, alpha=0.7)
        _set_segments(col, np.repeat(pos[k, :1], n - 1, axis=0), pos[k, 1:])
        axt.plot(*pos[k].T[:2], ls="none", marker="o", ms=3.5, color="0.25", zorder=4)
    for ax in (ax3, axt):
        d = _dims(ax)
        for i in reversed(range(n)):
            ax.plot(*pos[:, i].T[:d], color=colours[i], lw=2.4 if i == 0 else 1.3, zorder=5 if i == 0 else 3)
        ax.plot(*start[:d, None], ls="none", marker="s", ms=10, mfc="white", mec="k", mew=1.5, zorder=6)
        ax.plot(*goal[:d, None], ls="none", marker="*", ms=18, color=GOAL_COLOUR, mec="k", zorder=6)
        if len(crash_pts):
            ax.plot(*crash_pts.T[:d], ls="none", marker="X", ms=12, color=CRASH_COLOUR, mec="k", mew=0.6, zorder=7)
    ax3.set_title("3D view (vertical scale stretched)", fontsize=11, y=0.95)
    axt.set_title(f"top view: obstacles coloured by height, formation every {SNAPSHOT_PERIOD_S:g} s", fontsize=11)

    t = np.arange(len(pos)) * dt
    for i in reversed(range(n)):
        axz.plot(t, pos[:, i, 2], color=colours[i], lw=2.0 if i == 0 else 1.1)
    axz.axhline(z_ref, color="0.45", ls=":", lw=1.5)
    axz.text(1.003, z_ref, "z_ref", transform=axz.get_yaxis_transform(), va="center", fontsize=9)
    if len(crash_pts):
        axz.plot(crash_step[crash_step >= 0] * dt, crash_pts[:, 2], ls="none", marker="X", ms=10,
                 color=CRASH_COLOUR, mec="k", mew=0.6)
    axz.set_xlim(0.0, max(t[-1], dt))
    axz.set_ylabel("z [m]")
    axz.set_title("altitude", fontsize=11)
    axz.grid(True, lw=0.3, alpha=0.5)
    axz.tick_params(labelbottom=False)
    _formation_panel(axf, t, np.asarray(env.history["formation_error"], dtype=np.float64), colours,
                     env.config.formation.e_f)

    names = ("snapshots", "start", "goal") + (("crashed",) if len(crash_pts) else ()) + ("obstacles",)
    fig.legend(handles=_uav_handles(colours) + _legend_handles(names), loc="lower right",
               bbox_to_anchor=(0.995, 0.05), ncols=1 if n <= 10 else 2, fontsize=10)
    fig.suptitle(title if title is not None else _default_title(env, crashed[-1]), fontsize=13)
    atomic_write_figure(path, fig, format=fmt)
    return fig


def _default_title(env, crashed_final: np.ndarray) -> str:
    outcome = "success" if getattr(env, "success", False) else "not reached"
    return (f"{getattr(env.scenario, 'name', 'episode')}: {env.n_uavs} UAVs, {env.config.formation.shape}, "
            f"{env.step_count * env.config.uav.dt:.1f} s, {outcome}, {int(crashed_final.sum())} crashed")


# ---------------------------------------------------------------------------------------------- videos
def write_video(frames: list[np.ndarray], path, fps: int = DEFAULT_FPS) -> None:
    """Write frames as a looping GIF or an MP4 (by suffix), atomically.

    GIF goes through Pillow with one palette for the whole clip, built from the first, middle and
    last frames (ten times faster than imageio's per-frame median-cut palettes, and colours do not
    flicker between frames). MP4 goes through imageio's PyAV plugin. Both are the optional extra
    ``viz``; MP4 also needs PyAV (``pip install av``).
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in VIDEO_SUFFIXES:
        raise ValueError(f"path={str(path)!r}: expected a suffix in {list(VIDEO_SUFFIXES)}")
    if isinstance(fps, bool) or not isinstance(fps, (int, np.integer)) or not 1 <= fps <= 100:
        raise ValueError(f"fps={fps!r}: expected an integer in [1, 100]")
    if not isinstance(frames, (list, tuple)) or not frames:
        raise ValueError("frames: expected a non-empty list of HxWx3 uint8 arrays")
    first = np.asarray(frames[0])
    for k, frame in enumerate(frames):
        frame = np.asarray(frame)
        if frame.dtype != np.uint8 or frame.ndim != 3 or frame.shape[2] != 3 or frame.shape != first.shape:
            raise ValueError(f"frames[{k}]: expected a uint8 array of shape {first.shape} (HxWx3 like frames[0]), "
                             f"got {frame.dtype} {frame.shape}")
    data = _gif_bytes(frames, fps) if suffix == ".gif" else _mp4_bytes(frames, fps)
    atomic_write_bytes(path, data)


def _gif_bytes(frames: list[np.ndarray], fps: int) -> bytes:
    try:
        from PIL import Image
    except ImportError as exc:
        raise ImportError("write_video: GIF output needs Pillow; install the optional extra with "
                          "`pip install uavform[viz]`") from exc
    samples = np.concatenate([frames[0], frames[len(frames) // 2], frames[-1]], axis=0)
    palette = Image.fromarray(samples).quantize(colors=256, method=Image.Quantize.FASTOCTREE)
    images = [Image.fromarray(np.asarray(f)).quantize(palette=palette, dither=Image.Dither.NONE) for f in frames]
    buf = io.BytesIO()
    images[0].save(buf, format="GIF", save_all=True, append_images=images[1:], duration=1000.0 / fps, loop=0)
    return buf.getvalue()


def _mp4_bytes(frames: list[np.ndarray], fps: int) -> bytes:
    try:
        import av  # noqa: F401  (the backend of imageio's MP4 writer)
        import imageio.v3 as iio
    except ImportError as exc:
        raise ImportError("write_video: MP4 output needs imageio and PyAV: `pip install uavform[viz] av` "
                          "(or write a .gif, which needs only the extra `viz`)") from exc
    stack = np.stack(frames)
    pad = ((0, 0), (0, stack.shape[1] % 2), (0, stack.shape[2] % 2), (0, 0))      # H.264 needs even sizes
    return iio.imwrite("<bytes>", np.pad(stack, pad, mode="edge"), extension=".mp4", plugin="pyav",
                       codec="libx264", fps=fps)
