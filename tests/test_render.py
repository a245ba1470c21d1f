"""Rendering: rgb_array frames, human mode on the dummy video driver, no renderer without a render mode,
wheel state colours, and gymnasium's RecordVideo wrapper."""

import math
import os
import sys
import warnings

import gymnasium as gym
import numpy as np
import pytest

import omni_gym  # noqa: F401  (registers the environments)

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
pytest.importorskip("pygame")

from omni_gym.envs import render  # noqa: E402

WILLIAMS = "OmniPathFollow-WilliamsPaper-v0"
PHUNOPAS = "OmniPathFollow-Phunopas-v0"


def wheel_pixel(env, renderer, i):
    """Screen pixel (column, row) of wheel i's centre for the current pose of robot 0."""
    core = env.unwrapped.core
    x, y, th = core.true[0, 0:3]
    px, py = core.robot.positions()[i]
    c, s = math.cos(th), math.sin(th)
    return renderer.world_to_pixel(x + c * px - s * py, y + s * px + c * py)


def test_rgb_array_shape_and_changes_between_steps():
    env = gym.make(PHUNOPAS, render_mode="rgb_array", episode_seconds=2.0)
    env.reset(seed=0)
    first = env.render()
    assert isinstance(first, np.ndarray)
    assert first.dtype == np.uint8 and first.ndim == 3 and first.shape[2] == 3
    assert first.shape[:2] == (render.SIZE, render.SIZE)
    for _ in range(30):  # drive sideways (+y body) at half speed: the robot moves by ~8 cm
        env.step(np.array([0.0, 0.5, 0.0], dtype=np.float32))
    second = env.render()
    assert second.shape == first.shape and second.dtype == np.uint8
    changed = np.any(second != first, axis=2)
    assert changed.sum() > 100
    env.close()
    assert env.unwrapped._renderer is None


def test_trail_restarts_at_reset():
    env = gym.make(PHUNOPAS, render_mode="rgb_array", episode_seconds=1.0)
    env.reset(seed=1)
    env.render()
    renderer = env.unwrapped._renderer
    for _ in range(10):
        env.step(np.zeros(3, dtype=np.float32))
    assert renderer._n_trail == 11
    env.reset(seed=2)
    assert env.unwrapped._renderer is renderer and renderer._n_trail == 1
    env.close()


def test_world_to_pixel_mapping():
    env = gym.make(WILLIAMS, render_mode="rgb_array", arena_half_size=2.0)
    env.reset(seed=0)
    env.render()
    r = env.unwrapped._renderer
    cx, cy = r.world_to_pixel(0.0, 0.0)
    right, _ = r.world_to_pixel(1.0, 0.0)
    _, up = r.world_to_pixel(0.0, 1.0)
    assert right - cx == pytest.approx(r.scale, abs=1) and cy - up == pytest.approx(r.scale, abs=1)  # y up
    (x0, y0), (x1, y1) = r.world_to_pixel(-2.0, 2.0), r.world_to_pixel(2.0, -2.0)
    assert 0 <= x0 < x1 < r.width and 0 <= y0 < y1 < r.height  # the whole arena is on the canvas
    env.close()


def test_no_render_mode_creates_no_renderer():
    env = gym.make(WILLIAMS)
    env.reset(seed=0)
    for _ in range(5):
        env.step(env.action_space.sample())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert env.render() is None
    assert env.unwrapped._renderer is None
    env.close()


def test_human_mode_on_dummy_driver_returns_none():
    env = gym.make(WILLIAMS, render_mode="human", episode_seconds=0.1)
    env.reset(seed=0)  # human mode renders at reset and at every step
    assert env.unwrapped._renderer is not None and env.unwrapped._renderer.window is not None
    for _ in range(3):
        env.step(np.zeros(3, dtype=np.float32))
    assert env.render() is None
    env.close()
    assert env.unwrapped._renderer is None


def test_lifted_wheel_drawn_in_lifted_colour():
    env = gym.make(WILLIAMS, render_mode="rgb_array")  # no random lift-off in this id
    env.reset(seed=0)
    frame = env.render()
    r = env.unwrapped._renderer
    for i in range(3):
        col, row = wheel_pixel(env, r, i)
        assert tuple(frame[row, col]) == render.ROLLING  # at rest: in contact, no slip
    env.unwrapped.core.world.set_contact(0, np.array([False, True, True]))
    frame = env.render()
    col, row = wheel_pixel(env, r, 0)
    assert tuple(frame[row, col]) == render.LIFTED
    for i in (1, 2):
        col, row = wheel_pixel(env, r, i)
        assert tuple(frame[row, col]) == render.ROLLING
    env.close()


def test_wheel_colour_states():
    assert render.wheel_color(False, 1.0) == render.LIFTED
    assert render.wheel_color(True, 0.0) == render.ROLLING
    assert render.wheel_color(True, -0.5 * render.SLIP_THRESHOLD) == render.ROLLING
    low = render.wheel_color(True, 1.01 * render.SLIP_THRESHOLD)
    high = render.wheel_color(True, -10.0)
    assert high == render.SLIP_HIGH and low != high
    assert all(c[0] > max(c[1], c[2]) for c in (low, high))  # reds


def test_record_video(tmp_path):
    pytest.importorskip("moviepy")
    env = gym.make(WILLIAMS, render_mode="rgb_array", episode_seconds=0.5)
    env = gym.wrappers.RecordVideo(env, str(tmp_path / "videos"), episode_trigger=lambda ep: ep == 0,
                                   disable_logger=True)
    env.reset(seed=0)
    done = False
    while not done:
        _, _, terminated, truncated, _ = env.step(np.array([0.0, 0.3, 0.0], dtype=np.float32))
        done = terminated or truncated
    env.close()
    videos = list((tmp_path / "videos").glob("*.mp4"))
    assert videos and videos[0].stat().st_size > 0


def test_render_without_pygame_names_the_extra(monkeypatch):
    """A missing pygame gives a one-line ModuleNotFoundError naming the render extra, not a bare import error."""
    env = gym.make(PHUNOPAS, render_mode="rgb_array", episode_seconds=1.0)
    env.reset(seed=0)
    monkeypatch.setitem(sys.modules, "pygame", None)  # `import pygame` now fails as if not installed
    with pytest.raises(ModuleNotFoundError) as info:
        env.render()
    message = str(info.value)
    assert 'pip install -e ".[render]"' in message and "pygame" in message and "rgb_array" in message
    assert "\n" not in message
    assert info.value.name == "pygame"
    env.close()


def test_gif_writing_without_imageio_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "imageio", None)
    monkeypatch.setitem(sys.modules, "imageio.v3", None)
    with pytest.raises(ModuleNotFoundError, match=r'writing GIFs needs the .imageio. package.*-e "\.\[render\]"'):
        render.require("imageio.v3", "writing GIFs")


def test_mecanum_wheels_show_their_roller_axis():
    """Each optiodom_omni4 wheel carries a dark stripe along its floor roller's axis e (±45° from the drive);
    the other diagonal of the wheel stays in the wheel's colour, so the stripe tells the two roller hands apart."""
    env = gym.make("OmniPathFollow-Mecanum-v0", render_mode="rgb_array", arena_half_size=0.25, lift_rate=0.0)
    env.reset(seed=0)
    frame = env.render()
    r = env.unwrapped._renderer
    core = env.unwrapped.core
    th = core.true[0, 2]
    c, s = math.cos(th), math.sin(th)
    robot = core.robot
    half_len = max(robot.wheel_radius * r.scale, render.MIN_WHEEL_PX / 2)
    half_wid = max(0.5 * render.WHEEL_WIDTH * robot.wheel_radius * r.scale, render.MIN_WHEEL_PX / 2)
    assert half_wid > 6  # large enough (arena_half_size 0.25) that a stripe pixel and a wheel pixel are apart
    for i, (e_body, d_body) in enumerate(zip(robot.roller_axes(), robot.drives(), strict=True)):
        e = np.array([c * e_body[0] - s * e_body[1], s * e_body[0] + c * e_body[1]])
        d = np.array([c * d_body[0] - s * d_body[1], s * d_body[0] + c * d_body[1]])
        mirrored = 2 * (e @ d) * d - e  # the roller axis of the opposite hand
        col, row = wheel_pixel(env, r, i)
        t = 0.6 * min(half_len / abs(e @ d), half_wid / abs(e[0] * d[1] - e[1] * d[0]))
        on = frame[int(round(row - t * e[1])), int(round(col + t * e[0]))]
        off = frame[int(round(row - t * mirrored[1])), int(round(col + t * mirrored[0]))]
        assert tuple(on) == render.HEADING, (i, on)
        assert tuple(off) == render.ROLLING, (i, off)
    env.close()


def test_a_headless_window_opens_on_the_offscreen_driver_without_probing_wayland():
    """libwayland prints "error: XDG_RUNTIME_DIR is invalid ..." when SDL probes it on a machine with no
    display; the renderer names SDL's offscreen driver (where SDL ends up anyway) for that one call."""
    from types import SimpleNamespace

    from omni_gym.envs.render import init_display

    seen = []
    environ: dict[str, str] = {}
    pg = SimpleNamespace(display=SimpleNamespace(init=lambda: seen.append(environ.get("SDL_VIDEODRIVER"))))
    init_display(pg, environ)
    assert seen == ["offscreen"] and environ == {}  # the user's environment as it was
    for given in ({"DISPLAY": ":0"}, {"WAYLAND_DISPLAY": "wayland-0"}, {"SDL_VIDEODRIVER": "dummy"}):
        environ.clear()
        environ.update(given)
        init_display(pg, environ)
        assert environ == given
    assert seen == ["offscreen", None, None, "dummy"]
