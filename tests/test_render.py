"""Rendering: obstacle geometry, live frames (rgb_array / human under Agg), the episode picture, videos.

Most tests use a small stand-in env with exactly the attributes the renderer reads, so pixel
positions and colours are known; one test drives the real env end to end.
"""

import os
import sys
import warnings
from types import SimpleNamespace

import matplotlib.image as mpimg
import matplotlib.pyplot as plt
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from matplotlib.colors import to_rgb
from mpl_toolkits.mplot3d import proj3d
from PIL import Image

from uavform_env import parallel_env
from uavform_env.config import EnvConfig
from uavform_env.formation import slot_offsets, slot_positions
from uavform_env.render import (CRASH_COLOUR, Renderer, box_faces, cylinder_faces, obstacle_footprints, plot_episode,
                                sphere_faces, uav_colours, write_video)

from .conftest import small_env_kwargs

FOREST = dict(boxes=np.array([[20.0, 10, 0, 24, 14, 2.5]]), spheres=np.array([[15.0, -5, 4, 1.0]]),
              cylinders=np.array([[x, y, 0.5, 0.0, h] for x, y, h in
                                  [(8, 6, 8), (12, -8, 2), (25, 3, 8), (30, -12, 9), (35, 9, 1.5), (40, -3, 8)]]))
EMPTY = dict(boxes=np.zeros((0, 6)), cylinders=np.zeros((0, 5)), spheres=np.zeros((0, 4)))


def stand_in_env(n=3, obstacles=FOREST):
    """An object with the attributes of a reset FormationEnv: a 55 x 50 x 10 m world, start (0, 0, 3)."""
    offsets = slot_offsets("triangle" if n <= 3 else "wedge", n, 2.0)
    states = np.zeros((n, 7))
    states[:, :3] = slot_positions(np.zeros(2), 0.0, offsets, 3.0)
    mission = SimpleNamespace(start=(0.0, 0.0, 3.0), goal=(50.0, 0.0, 3.0), start_heading=0.0)
    scenario = SimpleNamespace(name="stand-in", bounds_lo=(-5.0, -25.0, 0.0), bounds_hi=(50.0, 25.0, 10.0),
                               mission=mission)
    env = SimpleNamespace(world=SimpleNamespace(**obstacles), scenario=scenario, config=EnvConfig(), offsets=offsets,
                          goal=np.array(mission.goal), n_uavs=n, states=states, crashed=np.zeros(n, bool),
                          step_count=0, success=False, metadata={"render_fps": 10}, slot_altitude="z_ref")
    env.history = {"positions": [states[:, :3].copy()], "crashed": [env.crashed.copy()],
                   "formation_error": [np.zeros(n)]}
    return env


def advance(env, steps=10, dx=0.5):
    for _ in range(steps):
        env.states[~env.crashed, 0] += dx
        env.states[:, 2] = 3.0 + 0.5 * np.sin(0.1 * env.step_count + np.arange(env.n_uavs))
        env.step_count += 1
        env.history["positions"].append(env.states[:, :3].copy())
        env.history["crashed"].append(env.crashed.copy())
        env.history["formation_error"].append(0.1 * env.step_count * (np.arange(env.n_uavs) > 0))  # 0.1 m per step


def pixel_of(renderer, frame, point):
    """Row, column of a world point in a frame, through the renderer's own axes transforms."""
    ax = renderer.figure.axes[0]
    if ax.name == "3d":
        x, y, _ = proj3d.proj_transform(*point, ax.get_proj())
    else:
        x, y = point[:2]
    px, py = ax.transData.transform((x, y))
    return int(round(frame.shape[0] - py)), int(round(px))


def near_colour(frame, rc, colour, radius=2, tol=40):
    r, c = rc
    patch = frame[max(r - radius, 0):r + radius + 1, max(c - radius, 0):c + radius + 1].reshape(-1, 3).astype(int)
    return bool(np.any(np.abs(patch - np.array(to_rgb(colour)) * 255).max(axis=1) <= tol))


# ---------------------------------------------------------------------------------------------- geometry
def test_box_faces_known_answer():
    faces = box_faces(np.array([[0.0, 0.0, 0.0, 1.0, 2.0, 3.0]]))
    assert faces.shape == (6, 4, 3)
    corners = {tuple(v) for v in faces.reshape(-1, 3)}
    assert corners == {(x, y, z) for x in (0.0, 1.0) for y in (0.0, 2.0) for z in (0.0, 3.0)}
    for quad in faces:
        flat = [axis for axis in range(3) if np.ptp(quad[:, axis]) == 0]
        assert len(flat) == 1                                      # planar, on one box side
        steps = np.count_nonzero(quad - np.roll(quad, -1, axis=0), axis=1)
        assert np.all(steps == 1)                                  # walks the rim: no crossed quads


@settings(max_examples=25, deadline=None)
@given(st.floats(-50, 50), st.floats(-50, 50), st.floats(0.05, 5), st.floats(0, 5), st.floats(0.1, 10))
def test_cylinder_and_sphere_vertices_lie_on_the_surface(x, y, r, zlo, height):
    sides, caps = cylinder_faces(np.array([[x, y, r, zlo, zlo + height]]), segments=12)
    assert sides.shape == (12, 4, 3) and caps.shape == (1, 12, 3)
    pts = np.concatenate([sides.reshape(-1, 3), caps.reshape(-1, 3)])
    assert np.allclose(np.hypot(pts[:, 0] - x, pts[:, 1] - y), r)
    assert np.all(np.isclose(pts[:, 2], zlo) | np.isclose(pts[:, 2], zlo + height))
    assert np.allclose(caps[..., 2], zlo + height)
    quads = sphere_faces(np.array([[x, y, zlo, r]]), segments=(8, 4))
    assert quads.shape == (32, 4, 3)
    assert np.allclose(np.linalg.norm(quads - np.array([x, y, zlo]), axis=-1), r)


def test_footprints_are_sorted_by_top_height_and_match_the_shapes():
    outlines, tops = obstacle_footprints(SimpleNamespace(**FOREST))
    assert len(outlines) == 8 and np.all(np.diff(tops) >= 0)
    assert tops[-1] == 9.0 and np.allclose(np.hypot(*(outlines[-1] - [30.0, -12.0]).T), 0.5)
    box = outlines[list(tops).index(2.5)]
    assert {tuple(v) for v in box} == {(20.0, 10.0), (24.0, 10.0), (20.0, 14.0), (24.0, 14.0)}
    assert obstacle_footprints(SimpleNamespace(**EMPTY))[1].size == 0
    with pytest.raises(ValueError, match="world.boxes"):
        obstacle_footprints(SimpleNamespace(**{**EMPTY, "boxes": np.zeros((2, 5))}))


# ---------------------------------------------------------------------------------------------- live frames
@pytest.mark.parametrize("top_down", [False, True])
def test_frames_have_the_right_shape_and_follow_the_uavs(top_down):
    env = stand_in_env()
    renderer = Renderer("rgb_array", top_down=top_down, size=(640, 480))
    first = renderer.draw(env)
    assert first.shape == (480, 640, 3) and first.dtype == np.uint8
    assert np.array_equal(renderer.draw(env), first)               # blitted frame == full redraw
    children = len(renderer.figure.axes[0].get_children())
    advance(env)
    moved = renderer.draw(env)
    assert np.count_nonzero(np.any(moved != first, axis=2)) > 50
    fresh = Renderer("rgb_array", top_down=top_down, size=(640, 480)).draw(env)
    assert np.array_equal(moved, fresh)                             # no ghosts of earlier frames
    assert len(renderer.figure.axes[0].get_children()) == children  # artists reused, not added per frame
    for i, colour in enumerate(uav_colours(env.n_uavs)):
        assert near_colour(moved, pixel_of(renderer, moved, env.states[i, :3]), colour), f"uav {i} not drawn"
    renderer.close()


def test_crashed_uavs_are_marked():
    env = stand_in_env(obstacles=EMPTY)
    renderer = Renderer("rgb_array", top_down=True)
    advance(env, 5)
    where = pixel_of(renderer, renderer.draw(env), env.states[1, :3])
    assert not near_colour(renderer.draw(env), where, CRASH_COLOUR, tol=30)
    env.crashed[1] = True
    assert near_colour(renderer.draw(env), where, CRASH_COLOUR, tol=30)


def test_top_view_differs_from_3d_view():
    env = stand_in_env()
    assert not np.array_equal(Renderer("rgb_array").draw(env), Renderer("rgb_array", top_down=True).draw(env))


def test_new_world_rebuilds_the_obstacles():
    env = stand_in_env(obstacles=EMPTY)
    renderer = Renderer("rgb_array", top_down=True)
    empty = renderer.draw(env)
    env.world = SimpleNamespace(**FOREST)
    forest = renderer.draw(env)
    tall = pixel_of(renderer, forest, (30.0, -12.0, 0.0))          # centre of the 9 m cylinder
    assert not np.array_equal(empty[tall], forest[tall])


def test_human_mode_under_agg_returns_none_and_opens_no_window_early():
    before = set(plt.get_fignums())
    renderer = Renderer("human")
    assert set(plt.get_fignums()) == before
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert renderer.draw(stand_in_env()) is None
    assert len(set(plt.get_fignums()) - before) == 1
    renderer.close()
    assert set(plt.get_fignums()) == before


@pytest.mark.parametrize("kwargs, match", [(dict(mode="window"), "mode"), (dict(mode="human", size=(50, 600)), "size"),
                                           (dict(mode="rgb_array", size="big"), "size"),
                                           (dict(mode="rgb_array", size=(800.5, 600)), "size")])
def test_bad_renderer_arguments(kwargs, match):
    with pytest.raises(ValueError, match=match):
        Renderer(**kwargs)


def test_draw_before_reset_is_refused():
    env = stand_in_env()
    env.scenario = None
    with pytest.raises(ValueError, match="reset"):
        Renderer("rgb_array").draw(env)


# ---------------------------------------------------------------------------------------------- episode picture
@pytest.mark.parametrize("n", [1, 4])
def test_plot_episode_writes_a_png_atomically(tmp_path, n):
    env = stand_in_env(n=n)
    advance(env, 60)
    env.crashed[-1] = True
    advance(env, 60)
    path = tmp_path / "sub" / "trajectory.png"
    fig = plot_episode(env, path, title="a title")
    image = mpimg.imread(path)
    assert image.shape == (1150, 1600, 4) and image[..., :3].std() > 0.05
    assert os.listdir(path.parent) == ["trajectory.png"]          # no temporary file left behind
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert labels[:n] == ["leader (uav_0)"] + [f"follower {k}" for k in range(1, n)]
    assert fig.axes[0].get_zlabel() == "z [m]"
    texts = [t.get_text() for t in fig.axes[3].texts]
    if n == 1:
        assert "a single UAV: no formation" in texts
    else:   # 120 steps + reset; errors 0.1 m per step: > 0.5 m from step 6, > 5 m from step 51 (of 121)
        assert f"some follower > 0.5 m (e_f) off its slot in {115 / 121:.0%} of steps, > 5 m in {70 / 121:.0%}" in texts


@pytest.mark.parametrize("fmt, magic", [("svg", b"<?xml"), ("pdf", b"%PDF")])
def test_plot_episode_writes_vector_formats(tmp_path, fmt, magic):
    env = stand_in_env(n=3)
    advance(env, 20)
    plot_episode(env, tmp_path / f"trajectory.{fmt}")
    assert (tmp_path / f"trajectory.{fmt}").read_bytes().startswith(magic)


def test_plot_episode_rejects_bad_paths_and_unreset_envs(tmp_path):
    with pytest.raises(ValueError, match="suffix"):
        plot_episode(stand_in_env(), tmp_path / "trajectory.txt")
    env = stand_in_env()
    env.scenario = None
    with pytest.raises(ValueError, match="reset"):
        plot_episode(env, tmp_path / "trajectory.png")


# ---------------------------------------------------------------------------------------------- videos
def test_gif_round_trip_keeps_frames_timing_and_exact_colours(tmp_path):
    frames = [np.full((40, 60, 3), 255, np.uint8) for _ in range(5)]
    for k, frame in enumerate(frames):
        frame[10:20, 5 + 10 * k:15 + 10 * k] = (0, 0, 0)          # a moving black square
    frames[-1][30:, :] = (255, 0, 0)                               # red appears only in the last frame
    write_video(frames, tmp_path / "episode.gif", fps=5)
    gif = Image.open(tmp_path / "episode.gif")
    assert gif.n_frames == 5 and gif.size == (60, 40)
    assert gif.info["duration"] == 200 and gif.info["loop"] == 0
    for k in range(5):
        gif.seek(k)
        assert np.array_equal(np.asarray(gif.convert("RGB")), frames[k])


@pytest.mark.parametrize("frames, path, fps, match", [
    ([], "v.gif", 10, "frames"),
    ([np.zeros((8, 8, 3), np.uint8), np.zeros((8, 9, 3), np.uint8)], "v.gif", 10, r"frames\[1\]"),
    ([np.zeros((8, 8, 3))], "v.gif", 10, r"frames\[0\]"),
    ([np.zeros((8, 8, 3), np.uint8)], "v.avi", 10, "suffix"),
    ([np.zeros((8, 8, 3), np.uint8)], "v.gif", 0, "fps"),
])
def test_write_video_rejects_bad_input(tmp_path, frames, path, fps, match):
    with pytest.raises(ValueError, match=match):
        write_video(frames, tmp_path / path, fps=fps)


def test_missing_video_backends_name_what_to_install(tmp_path, monkeypatch):
    frame = [np.zeros((8, 8, 3), np.uint8)]
    monkeypatch.setitem(sys.modules, "PIL", None)
    with pytest.raises(ImportError, match=r"uavform\[viz\]"):
        write_video(frame, tmp_path / "v.gif")
    monkeypatch.setitem(sys.modules, "av", None)
    with pytest.raises(ImportError, match="av"):
        write_video(frame, tmp_path / "v.mp4")


# ---------------------------------------------------------------------------------------------- real env
def test_real_env_frames_and_episode_picture(tmp_path):
    penv = parallel_env(**small_env_kwargs(max_cycles=8), render_mode="rgb_array")
    penv.reset(seed=3)
    first = penv.render()
    assert first.shape == (600, 800, 3) and first.dtype == np.uint8
    while penv.agents:
        penv.step({a: np.array([1.0, 0.3, 0.0]) for a in penv.agents})
    assert not np.array_equal(penv.render(), first)
    plot_episode(penv.unwrapped, tmp_path / "trajectory.png")
    assert mpimg.imread(tmp_path / "trajectory.png").shape[2] == 4
    penv.close()
