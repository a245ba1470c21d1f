"""One demo episode per registered environment, driven by a privileged tracking controller.

Outputs go to ``--out`` (default ``out/demo/``, untracked: ``make demo`` never touches tracked files;
the committed pictures in ``benchmarks/results/demo/`` were made with ``--out benchmarks/results/demo``).

Controller (seed 0, each id's default keywords): proportional feedback plus the reference velocity as
feed-forward, both privileged (the true pose from ``info["pose"]``, the reference from the env's core)::

    v_world = v_ref + K_POS·(p_ref − p),  ω = ω_ref + K_HEAD·wrap(θ_ref − θ)

rotated into the body frame and sent as the twist action (vx, vy, ω) / (max_speed, max_speed,
max_yaw_rate), clipped to [−1, 1]. (Without the feed-forward the robot lags ~0.2 m behind the
reference; that was the demo's controller up to now.)

Why ``OmniPathFollow-WilliamsPaper-v0`` ends lost (measured on seed 0 with this controller): at t ≈ 5.5 s
the reference turns round and accelerates to ~0.4 m/s while the heading (``ref_heading="forward"``)
turns with it. On carpet with roller-gap friction the three wheels cannot transmit that force: the
drive saturates (action −1), the wheels slip, the robot yaws ~0.6 rad/s against the command and barely
translates, and the error passes ``lost_distance`` = 0.5 m at t ≈ 7.4 s. Not the controller's gains
(K = 4/6 or 6/10 per s are lost at the same time) but the surface and the speed: the same episode
stays on the reference with ``surface="paper"`` (mean error 5 mm) or ``ref_speed=0.1``. The baseline
table (``benchmarks/results/baselines.md``) shows how often this happens to the scripted baselines.
The picture says so: a lost episode is annotated with the saturated share of commands and the
uncommanded yaw in its last second.

Writes per id into ``--out``: ``<id>.gif`` (every 5th frame, a colour key below each frame; 600 px,
or 300 px if that would exceed :data:`GIF_BUDGET`) and ``<id>.png`` (reference vs driven path on
axes fitted to the data, tracking error vs time). Usage::

    python benchmarks/demo_episodes.py [--out out/demo] [--seconds 8] [--quick]
"""

from __future__ import annotations

import argparse
import math
import os
import time
from dataclasses import dataclass
from pathlib import Path

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("MPLBACKEND", "Agg")

import gymnasium as gym  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from PIL import Image, ImageDraw  # noqa: E402

import omni_gym  # noqa: E402, F401  (registers the environments)
from omni_gym.angles import wrap_angle  # noqa: E402
from omni_gym.envs import ENV_IDS, render  # noqa: E402

iio = render.require("imageio.v3", "writing the demo GIFs")  # clear message without the render extra

SEED = 0
K_POS = 2.0  # 1/s
K_HEAD = 2.0  # 1/s
CONTROLLER = f"P + feed-forward (K = {K_POS:g}/s, {K_HEAD:g}/s)"
FRAME_EVERY = 5  # control steps per GIF frame
GIF_SMALL = 300  # px, fallback GIF size
GIF_BUDGET = 1_500_000  # bytes per GIF
QUICK_SECONDS = 0.5  # s, --quick episode cap (tests)
KEY_BAND = 34  # px, colour key strip below each GIF frame
MARGIN = 0.1  # m, around the data on the path plot
SATURATED = 0.999  # |action| at or above this counts as saturated


def control(info: dict, ref_vel: np.ndarray, cfg) -> np.ndarray:
    """Twist action of the P + feed-forward controller; ``ref_vel`` = (vx, vy, ω) world frame [m/s, rad/s]."""
    x, y, th = info["pose"]
    rx, ry, rth = info["reference_pose"]
    vx_w, vy_w = ref_vel[0] + K_POS * (rx - x), ref_vel[1] + K_POS * (ry - y)
    om = ref_vel[2] + K_HEAD * wrap_angle(rth - th)
    c, s = math.cos(th), math.sin(th)
    vx_b, vy_b = c * vx_w + s * vy_w, -s * vx_w + c * vy_w
    a = np.array([vx_b / cfg.max_speed, vy_b / cfg.max_speed, om / cfg.max_yaw_rate])
    return np.clip(a, -1.0, 1.0).astype(np.float32)


def colour_key(width: int) -> np.ndarray:
    """RGB strip explaining the renderer's colours (drawn below every GIF frame)."""
    img = Image.new("RGB", (width, KEY_BAND), render.BACKGROUND)
    d = ImageDraw.Draw(img)
    d.fontmode = "1"  # no anti-aliasing: few colours, so the GIF palette stays exact (3x smaller files)
    items = [("reference path", render.REFERENCE, "line"), ("reference now", render.REF_POINT, "ring"),
             ("driven", render.TRAIL, "line")]
    wheels = [("rolling", render.ROLLING), ("slipping", render.SLIP_HIGH), ("lifted", render.LIFTED)]
    x = 6
    for label, colour, kind in items:
        if kind == "line":
            d.line([(x, 9), (x + 16, 9)], fill=colour, width=2)
        else:
            d.ellipse([(x + 3, 3), (x + 15, 15)], outline=colour, width=2)
        d.text((x + 20, 3), label, fill=render.TEXT)
        x += 26 + int(d.textlength(label))
    x = 6
    d.text((x, 19), "wheels:", fill=render.TEXT)
    x += 8 + int(d.textlength("wheels:"))
    for label, colour in wheels:
        d.rectangle([(x, 21), (x + 12, 29)], fill=colour)
        d.text((x + 16, 19), label, fill=render.TEXT)
        x += 24 + int(d.textlength(label))
    return np.asarray(img)


def write_gif(path: Path, frames: list[np.ndarray], frame_ms: int) -> None:
    """Frames with the colour key below, full size or box-filtered to 300 px if the full size is over budget.

    (Box filtering keeps flat colours flat; smoother filters add noise that GIF compresses badly.)
    """
    key = colour_key(frames[0].shape[1])
    keyed = [np.concatenate([f, key], axis=0) for f in frames]
    iio.imwrite(path, np.stack(keyed), duration=frame_ms, loop=0)
    if path.stat().st_size > GIF_BUDGET and frames[0].shape[0] > GIF_SMALL:
        small = [np.asarray(Image.fromarray(f).resize((GIF_SMALL, GIF_SMALL), Image.Resampling.BOX)) for f in frames]
        key = colour_key(GIF_SMALL)
        iio.imwrite(path, np.stack([np.concatenate([f, key], axis=0) for f in small]), duration=frame_ms, loop=0)


@dataclass
class Trace:
    """One recorded episode (world frame; t [s], poses (x, y, θ) [m, m, rad], errors [m])."""

    t: np.ndarray
    pose: np.ndarray
    ref: np.ndarray
    err: np.ndarray
    lifted: np.ndarray  # wheels without floor contact per step
    actions: np.ndarray  # (steps, 3) twist actions in [−1, 1]
    slip: np.ndarray  # (steps,) largest drive slip |v_W| over the wheels [m/s]
    outcome: str
    n_wheels: int
    frames: int = 0


def outcome_text(terminated: bool, truncated: bool, info: dict, t_end: float) -> str:
    """lost / collided (with the time), success / not within tolerance at the end or at the --seconds cap."""
    if terminated:
        return f"{'collided' if info['collided'] else 'lost'} at t = {t_end:.2f} s"
    ok = "success" if info["is_success"] else "not within the success tolerance"
    return ok if truncated else f"{ok} at the {t_end:g} s cap"


def run_episode(env_id: str, seconds: float, out: Path):
    """Drive one episode (seed 0), write ``<id>.gif``; return the trace and the env's config."""
    env = gym.make(env_id, render_mode="rgb_array")
    cfg, core = env.unwrapped.cfg, env.unwrapped.core
    _, info = env.reset(seed=SEED)
    steps = int(round(seconds * cfg.control_hz))
    frames = [env.render()]
    poses, refs, errs, lifted, actions = [info["pose"]], [info["reference_pose"]], [info["tracking_error"]], [0], []
    slip = []
    terminated = truncated = False
    for k in range(1, steps + 1):
        a = control(info, core.ref_vel[0, core.step_count[0]], cfg)
        _, _, terminated, truncated, info = env.step(a)
        actions.append(a)
        slip.append(float(np.max(np.abs(info["slip"][:, 0]))))
        poses.append(info["pose"])
        refs.append(info["reference_pose"])
        errs.append(info["tracking_error"])
        lifted.append(int(np.sum(~info["contact"])))
        if k % FRAME_EVERY == 0 or terminated or truncated:
            frames.append(env.render())
        if terminated or truncated:
            break
    env.close()
    write_gif(out / f"{env_id}.gif", frames, int(round(1000 * FRAME_EVERY / cfg.control_hz)))
    t = np.arange(len(errs)) / cfg.control_hz
    return Trace(t=t, pose=np.array(poses), ref=np.array(refs), err=np.array(errs), lifted=np.array(lifted),
                 actions=np.array(actions).reshape(-1, 3), slip=np.array(slip),
                 outcome=outcome_text(terminated, truncated, info, t[-1]),
                 n_wheels=core.n_wheels, frames=len(frames)), cfg


def lost_note(tr: Trace, hz: float, max_yaw_rate: float) -> str:
    """Why the last second went wrong: saturated commands, slipping wheels, the yaw not asked for [rad/s]."""
    n = min(len(tr.actions), int(hz))
    if n < 2:
        return ""
    sat = np.mean(np.any(np.abs(tr.actions[-n:]) >= SATURATED, axis=1))
    yaw_rate = np.unwrap(tr.pose[-n - 1:, 2])
    actual = (yaw_rate[-1] - yaw_rate[0]) * hz / n
    asked = float(np.mean(tr.actions[-n:, 2])) * max_yaw_rate
    slipping = np.mean(tr.slip[-n:] > render.SLIP_THRESHOLD)
    return (f"last {n / hz:.1f} s: {100 * sat:.0f} % of commands saturated, a wheel slipping "
            f"(|v_W| > {render.SLIP_THRESHOLD:g} m/s) on {100 * slipping:.0f} % of steps,\nyaw rate {actual:+.2f} "
            f"rad/s vs {asked:+.2f} asked: the floor does not transmit the force\nthe reference needs "
            "(see the script's docstring)")


def fit_limits(ax, xy: np.ndarray) -> None:
    """Equal-aspect square limits around the data plus MARGIN [m] (not the whole arena)."""
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    half = max(float((hi - lo).max()) / 2 + MARGIN, 0.1)
    cx, cy = (lo + hi) / 2
    ax.set_xlim(cx - half, cx + half)
    ax.set_ylim(cy - half, cy + half)
    ax.set_aspect("equal")


def plot(path: Path, env_id: str, tr: Trace, cfg) -> None:
    """Path (fitted, equal axes, legend) and tracking error vs time; the title gives id, seed, controller, outcome."""
    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(11, 4.8), gridspec_kw={"width_ratios": [1, 1.4]})
    ax0.plot(tr.ref[:, 0], tr.ref[:, 1], color="tab:blue", lw=1.5, label="reference (up to the end)")
    ax0.plot(tr.pose[:, 0], tr.pose[:, 1], color="k", lw=1.0, label="driven (true pose)")
    ax0.plot(*tr.pose[0, :2], "o", color="tab:green", ms=6, label="start")
    ax0.plot(*tr.pose[-1, :2], "s", color="tab:red", ms=6, label="robot at the end")
    ax0.plot(*tr.ref[-1, :2], "o", mfc="none", mec="tab:orange", mew=2, ms=10,
             label="reference at the end\n(orange ring in the GIF)")
    fit_limits(ax0, np.vstack([tr.ref[:, :2], tr.pose[:, :2]]))
    ax0.set_xlabel("x [m]")
    ax0.set_ylabel("y [m]")
    ax0.grid(alpha=0.3)
    ax0.legend(fontsize=7, loc="best")
    ax1.plot(tr.t, tr.err * 1000.0, color="k", lw=1.0)
    if tr.err.max() > 0.5 * cfg.lost_distance:  # only when it matters: it would squash a small error
        ax1.axhline(cfg.lost_distance * 1000.0, color="tab:red", ls=":", lw=1,
                    label=f"lost_distance {cfg.lost_distance * 1000:g} mm")
    ax1.set_xlabel("t [s]")
    ax1.set_ylabel("position error to the reference [mm]")
    ax1.set_ylim(bottom=0)
    ax1.grid(alpha=0.3)
    handles = [Line2D([], [], color="k", lw=1, label="position error"), *ax1.get_legend_handles_labels()[0]]
    if tr.lifted.any():
        ax2 = ax1.twinx()
        ax2.fill_between(tr.t, tr.lifted, step="post", color="tab:gray", alpha=0.25)
        ax2.set_ylabel("wheels lifted")
        ax2.set_ylim(0, tr.n_wheels)
        handles.append(plt.Rectangle((0, 0), 1, 1, color="tab:gray", alpha=0.25, label="wheels lifted"))
    ax1.legend(handles=handles, fontsize=7, loc="upper left")
    if tr.outcome.startswith("lost"):
        ax1.text(0.02, 0.80, lost_note(tr, cfg.control_hz, cfg.max_yaw_rate), transform=ax1.transAxes,
                 fontsize=7, va="top", color="tab:red")
    label = f" ({ILLUSTRATIONS[env_id]})" if env_id in ILLUSTRATIONS else ""
    fig.suptitle(f"{env_id}{label}, seed {SEED}, {CONTROLLER}: {tr.outcome}, final error {tr.err[-1] * 1000:.1f} mm",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


# The paper's own task, which its robot cannot follow on carpet (see above): shown last, labelled as such.
ILLUSTRATIONS = {"OmniPathFollow-WilliamsPaper-v0": "illustration: the paper's task, infeasible on carpet"}


def demo_order() -> list[str]:
    """The registered ids, the drivable ones first and the paper's infeasible task last."""
    return [i for i in ENV_IDS if i not in ILLUSTRATIONS] + [i for i in ENV_IDS if i in ILLUSTRATIONS]


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                     epilog="Outputs: <out>/<id>.gif and <out>/<id>.png per registered id.")
    parser.add_argument("--out", default="out/demo", help="output directory (default out/demo, untracked)")
    parser.add_argument("--seconds", type=float, default=8.0, help="episode length cap [s] (default 8)")
    parser.add_argument("--quick", action="store_true", help=f"cap episodes at {QUICK_SECONDS} s (tests)")
    args = parser.parse_args(argv)
    if not args.seconds > 0:
        parser.error(f"--seconds must be > 0, got {args.seconds}")
    seconds = QUICK_SECONDS if args.quick else args.seconds
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for env_id in demo_order():
        t0 = time.perf_counter()
        tr, cfg = run_episode(env_id, seconds, out)
        plot(out / f"{env_id}.png", env_id, tr, cfg)
        label = f" [{ILLUSTRATIONS[env_id]}]" if env_id in ILLUSTRATIONS else ""
        print(f"{env_id:28s}{label} steps {len(tr.err) - 1:4d} ({tr.outcome}): tracking error final "
              f"{tr.err[-1] * 1000:6.1f} mm, mean {tr.err.mean() * 1000:6.1f} mm, max {tr.err.max() * 1000:6.1f} mm; "
              f"GIF {tr.frames} frames; {time.perf_counter() - t0:.1f} s")
    print(f"wrote {out}/<id>.gif and {out}/<id>.png")


if __name__ == "__main__":
    main()
