"""Top-down pygame rendering of robot 0 of a :class:`~omni_gym.envs.core.TaskCore`.

Imported only when an environment is made with a ``render_mode`` and ``render()`` is first called;
pygame itself is imported inside :class:`Renderer`, so the rest of the package never needs it. Without
pygame (or, for GIF writing, imageio) :func:`require` raises a ``ModuleNotFoundError`` that names the
extra to install: ``pip install -e ".[render]"`` (from the repository root).

What is drawn (world frame, x right, y up, the arena ``[-h, h]²`` filling the canvas below a text band):

* a 0.5 m grid, the arena walls (if ``cfg.walls``) and the obstacles;
* the episode's reference path (blue polyline) and the current reference pose (orange ring + tick);
* the driven trail (dark polyline), one point per control step;
* the robot body (disc of ``body_radius`` with a heading line) and each wheel as a rectangle at its
  centre, long side along its drive direction, coloured by state: lifted (no floor contact)
  :data:`LIFTED`, slipping (drive slip |v_W| > :data:`SLIP_THRESHOLD`) red, darker with more slip,
  rolling :data:`ROLLING`; a mecanum wheel (roller angle γ ≠ 0) also shows its floor roller's axis
  e = cos γ·d + sin γ·a as a dark stripe across the rectangle (for an omni wheel the axis is the
  drive direction itself, so no stripe is drawn);
* a text line with time, tracking error and the contact mask (skipped if no font is available).
"""

from __future__ import annotations

import importlib
import math
import os
from types import ModuleType

import numpy as np

from omni_gym.envs.config import EnvConfig
from omni_gym.physics.robot import RobotSpec

SIZE = 600  # px, default canvas width and height
PAD = 8  # px around the arena
TEXT_BAND = 22  # px above the arena for the status line
GRID = 0.5  # m

BACKGROUND = (250, 250, 247)
OUTSIDE = (228, 228, 224)
GRID_COLOR = (232, 232, 228)
WALL = (40, 40, 40)
OBSTACLE = (120, 110, 100)
REFERENCE = (70, 120, 220)
REF_POINT = (240, 140, 20)
TRAIL = (30, 30, 30)
BODY = (190, 205, 225)
BODY_EDGE = (60, 70, 90)
HEADING = (20, 30, 60)
ROLLING = (40, 170, 60)
LIFTED = (175, 175, 175)
LIFTED_EDGE = (110, 110, 110)
SLIP_LOW = (240, 120, 120)  # colour at the slip threshold
SLIP_HIGH = (170, 0, 0)  # colour at SLIP_FULL and above
TEXT = (20, 20, 20)

SLIP_THRESHOLD = 0.02  # m/s of drive slip |v_W| above which a wheel counts as slipping
SLIP_FULL = 0.2  # m/s of drive slip drawn in the darkest red
WHEEL_WIDTH = 0.5  # wheel rectangle width as a fraction of the wheel radius
MIN_WHEEL_PX = 3.0  # px, smallest drawn wheel side
PX_LIMIT = 10_000  # px, coordinates are clipped to ±this so a runaway robot cannot overflow pygame


RENDER_EXTRA = 'pip install -e ".[render]" (from the repository root)'
# module -> the distribution the render extra installs it from
RENDER_PACKAGES = {"pygame": "pygame-ce", "imageio": "imageio", "imageio.v3": "imageio"}


def require(module: str, purpose: str) -> ModuleType:
    """Import ``module`` for ``purpose``; if it is missing, a one-line ModuleNotFoundError naming the extra."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        package = RENDER_PACKAGES.get(module, module.split(".")[0])
        raise ModuleNotFoundError(f"{purpose} needs the {package!r} package ({module!r} could not be imported: "
                                  f"{exc}); install the render extra: {RENDER_EXTRA}",
                                  name=module.split(".")[0]) from None


def init_display(pg: ModuleType, environ=os.environ) -> None:
    """``pg.display.init()``, without SDL probing Wayland on a machine with no display.

    With neither ``DISPLAY`` nor ``WAYLAND_DISPLAY`` set and no ``SDL_VIDEODRIVER`` of the user's, SDL tries
    X11 and Wayland before it settles on its offscreen driver, and libwayland prints "error:
    XDG_RUNTIME_DIR is invalid or not set in the environment" on the way. Naming the offscreen driver for
    this one call gives the same window (none is shown: there is no display) without the message.
    """
    headless = not (environ.get("DISPLAY") or environ.get("WAYLAND_DISPLAY") or environ.get("SDL_VIDEODRIVER"))
    if not headless:
        pg.display.init()
        return
    environ["SDL_VIDEODRIVER"] = "offscreen"
    try:
        pg.display.init()
    finally:
        del environ["SDL_VIDEODRIVER"]


def roller_stripe(axis, drive, half_len: float, half_wid: float) -> tuple[float, float]:
    """Half-length vector [px, world orientation: y up] of a mecanum wheel's roller stripe: along the roller
    axis ``axis`` (unit, world frame), as long as fits in the wheel rectangle of half sides ``half_len``
    (along the unit ``drive``) and ``half_wid`` (across it)."""
    along = abs(axis[0] * drive[0] + axis[1] * drive[1])  # |cos γ|
    across = abs(axis[0] * drive[1] - axis[1] * drive[0])  # |sin γ|
    t = min(half_len / along if along > 1e-12 else math.inf, half_wid / across if across > 1e-12 else math.inf)
    return t * axis[0], t * axis[1]


def wheel_color(contact: bool, drive_slip: float) -> tuple[int, int, int]:
    """Colour of a wheel: lifted, slipping (red, darker with |v_W|) or rolling."""
    if not contact:
        return LIFTED
    s = abs(drive_slip)
    if s <= SLIP_THRESHOLD:
        return ROLLING
    u = min((s - SLIP_THRESHOLD) / (SLIP_FULL - SLIP_THRESHOLD), 1.0)
    return tuple(int(round(lo + u * (hi - lo))) for lo, hi in zip(SLIP_LOW, SLIP_HIGH, strict=True))


class Renderer:
    """Draws robot 0 of a task core; ``human`` shows a window, otherwise :meth:`draw` returns RGB frames.

    Interface used by the environments: :meth:`reset` at each episode start, :meth:`record` after each
    step (stores the driven trail), :meth:`draw` to render, :meth:`close`.
    """

    def __init__(self, cfg: EnvConfig, robot: RobotSpec, human: bool, fps: int, size: int = SIZE) -> None:
        pygame = require("pygame", f"rendering (render_mode={'human' if human else 'rgb_array'!r})")

        self._pg = pygame
        self.cfg = cfg
        self.robot = robot
        self.human = bool(human)
        self.fps = int(fps)
        self.width = self.height = int(size)
        h = cfg.arena_half_size
        self.half_size = h
        self.scale = min(self.width - 2 * PAD, self.height - 2 * PAD - TEXT_BAND) / (2.0 * h)  # px per m
        self.cx = self.width / 2.0
        self.cy = TEXT_BAND + (self.height - TEXT_BAND) / 2.0
        self._wheel_pos = robot.positions()
        self._wheel_dir = robot.drives()
        self._roller_dir = robot.roller_axes()  # floor roller axes e_i (body frame)
        self._mecanum = robot.roller_angles() != 0.0
        self._trail = np.zeros((max(cfg.episode_steps, 1) + 1, 2))
        self._n_trail = 0
        self._background = None
        self.canvas = pygame.Surface((self.width, self.height))
        self.font = None
        try:
            pygame.font.init()
            self.font = pygame.font.Font(None, 20)
        except Exception:  # no font module or default font (minimal SDL builds): draw without text
            self.font = None
        self.window = None
        self.clock = None
        if self.human:
            init_display(pygame)
            self.window = pygame.display.set_mode((self.width, self.height))
            pygame.display.set_caption(f"omni-gym: {robot.name}")
            self.clock = pygame.time.Clock()

    # --- coordinates ---------------------------------------------------------------------------

    def world_to_pixel(self, x: float, y: float) -> tuple[int, int]:
        """Canvas pixel (column, row) of the arena-frame point (x, y) [m]; y points up on screen."""
        px = self._to_px(np.array([[x, y]], dtype=float))[0]
        return int(px[0]), int(px[1])

    def _to_px(self, xy: np.ndarray) -> np.ndarray:
        """(k, 2) arena-frame points [m] → (k, 2) integer pixel coordinates."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        out = np.empty_like(xy)
        out[:, 0] = self.cx + xy[:, 0] * self.scale
        out[:, 1] = self.cy - xy[:, 1] * self.scale
        out = np.nan_to_num(out, nan=0.0, posinf=PX_LIMIT, neginf=-PX_LIMIT)
        return np.rint(np.clip(out, -PX_LIMIT, PX_LIMIT)).astype(np.int64)

    # --- episode bookkeeping -------------------------------------------------------------------

    def reset(self, core) -> None:
        """New episode: rebuild the static layer (arena, reference path) and restart the trail."""
        self._background = self._draw_background(core)
        self._n_trail = 0
        self.record(core)

    def record(self, core) -> None:
        """Append robot 0's current position (``core.true``, filled by ``observe()``) to the trail."""
        if self._n_trail == len(self._trail):
            self._trail = np.concatenate([self._trail, np.zeros_like(self._trail)])
        self._trail[self._n_trail] = core.true[0, 0:2]
        self._n_trail += 1

    # --- drawing -------------------------------------------------------------------------------

    def _draw_background(self, core):
        pg = self._pg
        surf = pg.Surface((self.width, self.height))
        surf.fill(OUTSIDE)
        h = self.half_size
        (x0, y0), (x1, y1) = self.world_to_pixel(-h, h), self.world_to_pixel(h, -h)
        arena = pg.Rect(x0, y0, x1 - x0 + 1, y1 - y0 + 1)
        surf.fill(BACKGROUND, arena)
        n = int(math.floor(h / GRID))
        for k in range(-n, n + 1):
            g = k * GRID
            a, b = self.world_to_pixel(g, -h), self.world_to_pixel(g, h)
            pg.draw.line(surf, GRID_COLOR, a, b)
            a, b = self.world_to_pixel(-h, g), self.world_to_pixel(h, g)
            pg.draw.line(surf, GRID_COLOR, a, b)
        if self.cfg.walls:
            pg.draw.rect(surf, WALL, arena, width=3)
        for x, y, r in self.cfg.obstacles:
            pg.draw.circle(surf, OBSTACLE, self.world_to_pixel(x, y), max(int(round(r * self.scale)), 1))
        steps = min(self.cfg.episode_steps + 1, core.ref_pose.shape[1])
        path = self._to_px(core.ref_pose[0, :steps, 0:2])
        if len(path) >= 2:
            pg.draw.aalines(surf, REFERENCE, False, path.tolist())
        return surf

    def _draw_frame(self, core) -> None:
        pg = self._pg
        surf = self.canvas
        if self._background is None:
            self._background = self._draw_background(core)
        surf.blit(self._background, (0, 0))
        scale = self.scale
        robot = self.robot
        # Driven trail.
        if self._n_trail >= 2:
            pg.draw.aalines(surf, TRAIL, False, self._to_px(self._trail[: self._n_trail]).tolist())
        # Current reference pose: ring of the body radius and a heading tick.
        k = min(int(core.step_count[0]), core.ref_pose.shape[1] - 1)
        rx, ry, rth = core.ref_pose[0, k]
        rpx = self.world_to_pixel(rx, ry)
        rad = max(int(round(robot.body_radius * scale)), 2)
        pg.draw.circle(surf, REF_POINT, rpx, rad, width=2)
        pg.draw.circle(surf, REF_POINT, rpx, 3)
        tip = self.world_to_pixel(rx + robot.body_radius * math.cos(rth), ry + robot.body_radius * math.sin(rth))
        pg.draw.line(surf, REF_POINT, rpx, tip, 2)
        # Body.
        x, y, th = core.true[0, 0:3]
        c, s = math.cos(th), math.sin(th)
        centre = self.world_to_pixel(x, y)
        pg.draw.circle(surf, BODY, centre, rad)
        pg.draw.circle(surf, BODY_EDGE, centre, rad, width=1)
        tip = self.world_to_pixel(x + robot.body_radius * c, y + robot.body_radius * s)
        pg.draw.line(surf, HEADING, centre, tip, 2)
        # Wheels: rectangles along the drive direction, coloured by contact and drive slip.
        rot = np.array([[c, -s], [s, c]])
        pos = self._wheel_pos @ rot.T + np.array([x, y])
        drive = self._wheel_dir @ rot.T
        roller = self._roller_dir @ rot.T
        half_len = max(robot.wheel_radius * scale, MIN_WHEEL_PX / 2)
        half_wid = max(0.5 * WHEEL_WIDTH * robot.wheel_radius * scale, MIN_WHEEL_PX / 2)
        contact = core.world.contact[0]
        slip = core.world.slip[0]
        for i in range(robot.n_wheels):
            cx, cy = self._to_px(pos[i])[0]
            # Screen axes: y flipped.
            dx, dy = drive[i, 0], -drive[i, 1]
            ax, ay = -dy, dx
            corners = [(cx + sx * half_len * dx + sy * half_wid * ax, cy + sx * half_len * dy + sy * half_wid * ay)
                       for sx, sy in ((1, 1), (1, -1), (-1, -1), (-1, 1))]
            color = wheel_color(bool(contact[i]), float(slip[i, 0]))
            pg.draw.polygon(surf, color, corners)
            edge = LIFTED_EDGE if not contact[i] else HEADING
            pg.draw.polygon(surf, edge, corners, width=1)
            if self._mecanum[i]:
                stripe = roller_stripe(roller[i], drive[i], half_len, half_wid)
                pg.draw.line(surf, edge, (cx + stripe[0], cy - stripe[1]), (cx - stripe[0], cy + stripe[1]), 2)
        # Status line.
        if self.font is not None:
            t = int(core.step_count[0]) * self.cfg.control_dt
            mask = "".join("1" if v else "0" for v in contact)
            line = f"t = {t:5.2f} s   error = {core.err[0, 0] * 1000.0:6.1f} mm   contact = {mask}"
            if core.world.collided[0]:
                line += "   COLLIDED"
            try:
                surf.blit(self.font.render(line, True, TEXT), (PAD, 3))
            except Exception:
                self.font = None

    def draw(self, core) -> np.ndarray | None:
        """Render robot 0: an (H, W, 3) uint8 RGB array, or None in human mode (shown in the window)."""
        self._draw_frame(core)
        if self.human:
            pg = self._pg
            if self.window is None:  # closed meanwhile: reopen
                init_display(pg)
                self.window = pg.display.set_mode((self.width, self.height))
                self.clock = pg.time.Clock()
            self.window.blit(self.canvas, (0, 0))
            pg.event.pump()
            pg.display.flip()
            self.clock.tick(self.fps)
            return None
        return np.ascontiguousarray(self._pg.surfarray.array3d(self.canvas).transpose(1, 0, 2))

    def close(self) -> None:
        """Close the window (human mode). Other pygame users in the process are left alone."""
        if self.window is not None:
            self._pg.display.quit()
            self.window = None
            self.clock = None
