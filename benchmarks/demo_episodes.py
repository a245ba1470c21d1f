"""One demo episode per registered environment, driven by a proportional tracking controller.

For each id (seed 0) the controller reads the privileged ``info["pose"]`` and ``info["reference_pose"]``:

    v_world = K_POS·(p_ref − p),  ω = K_HEAD·wrap(θ_ref − θ)

(no feed-forward: the reference velocity is not in ``info``), rotates v_world into the body frame and
sends the twist action (vx, vy, ω) / (max_speed, max_speed, max_yaw_rate), clipped to [−1, 1].

Writes per id into ``--out``: ``<id>.gif`` (every 5th frame; 600 px, or 300 px if that would exceed
:data:`GIF_BUDGET`) and ``<id>.png`` (reference vs
driven path, tracking error vs time). Usage::

    python benchmarks/demo_episodes.py [--out benchmarks/results/demo] [--seconds 8]
"""

from __future__ import annotations

import argparse
import math
import os
import time
from pathlib import Path

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("MPLBACKEND", "Agg")

import gymnasium as gym  # noqa: E402
import imageio.v3 as iio  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from PIL import Image  # noqa: E402

import omni_gym  # noqa: E402, F401  (registers the environments)
from omni_gym.envs import ENV_IDS  # noqa: E402

K_POS = 2.0  # 1/s
K_HEAD = 2.0  # 1/s
FRAME_EVERY = 5  # control steps per GIF frame
GIF_SMALL = 300  # px, fallback GIF size
GIF_BUDGET = 1_500_000  # bytes per GIF


def wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def p_control(info: dict, cfg) -> np.ndarray:
    """Twist action of the proportional tracking controller."""
    x, y, th = info["pose"]
    rx, ry, rth = info["reference_pose"]
    vx_w, vy_w = K_POS * (rx - x), K_POS * (ry - y)
    om = K_HEAD * wrap(rth - th)
    c, s = math.cos(th), math.sin(th)
    vx_b, vy_b = c * vx_w + s * vy_w, -s * vx_w + c * vy_w
    a = np.array([vx_b / cfg.max_speed, vy_b / cfg.max_speed, om / cfg.max_yaw_rate])
    return np.clip(a, -1.0, 1.0).astype(np.float32)


def write_gif(path: Path, frames: list[np.ndarray], frame_ms: int) -> None:
    """Full-size GIF, or a box-filtered 300 px one if the full size exceeds the budget.

    (Box filtering keeps flat colours flat; smoother filters add noise that GIF compresses badly.)
    """
    iio.imwrite(path, np.stack(frames), duration=frame_ms, loop=0)
    if path.stat().st_size > GIF_BUDGET and frames[0].shape[0] > GIF_SMALL:
        small = [np.asarray(Image.fromarray(f).resize((GIF_SMALL, GIF_SMALL), Image.Resampling.BOX)) for f in frames]
        iio.imwrite(path, np.stack(small), duration=frame_ms, loop=0)


def run(env_id: str, seconds: float, out: Path) -> dict:
    env = gym.make(env_id, render_mode="rgb_array")
    cfg = env.unwrapped.cfg
    _, info = env.reset(seed=0)
    steps = int(round(seconds * cfg.control_hz))
    frames = [env.render()]
    poses, refs, errs, lifted = [info["pose"]], [info["reference_pose"]], [info["tracking_error"]], [0]
    end = "time limit"
    for k in range(1, steps + 1):
        _, _, terminated, truncated, info = env.step(p_control(info, cfg))
        poses.append(info["pose"])
        refs.append(info["reference_pose"])
        errs.append(info["tracking_error"])
        lifted.append(int(np.sum(~info["contact"])))
        if k % FRAME_EVERY == 0 or terminated or truncated:
            frames.append(env.render())
        if terminated or truncated:
            end = ("collided" if info["collided"] else "lost") if terminated else "truncated"
            break
    core = env.unwrapped.core
    full_ref = core.ref_pose[0, : min(cfg.episode_steps + 1, steps + 1)].copy()
    env.close()

    gif = out / f"{env_id}.gif"
    write_gif(gif, frames, int(round(1000 * FRAME_EVERY / cfg.control_hz)))

    poses, refs, errs, lifted = np.array(poses), np.array(refs), np.array(errs), np.array(lifted)
    t = np.arange(len(errs)) / cfg.control_hz
    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(10, 4.2), gridspec_kw={"width_ratios": [1, 1.4]})
    ax0.plot(full_ref[:, 0], full_ref[:, 1], color="tab:blue", lw=1.5, label="reference")
    ax0.plot(poses[:, 0], poses[:, 1], color="k", lw=1.0, label="driven")
    ax0.plot(poses[0, 0], poses[0, 1], "o", color="tab:green", ms=5, label="start")
    ax0.plot(poses[-1, 0], poses[-1, 1], "s", color="tab:red", ms=5, label="end")
    h = cfg.arena_half_size
    ax0.set_xlim(-h, h)
    ax0.set_ylim(-h, h)
    ax0.set_aspect("equal")
    ax0.set_xlabel("x [m]")
    ax0.set_ylabel("y [m]")
    ax0.grid(alpha=0.3)
    ax0.legend(fontsize=8, loc="upper right")
    ax0.set_title(env_id, fontsize=10)
    ax1.plot(t, errs * 1000.0, color="k", lw=1.0, label="position error")
    ax1.set_xlabel("t [s]")
    ax1.set_ylabel("tracking error [mm]")
    ax1.grid(alpha=0.3)
    if lifted.any():
        ax2 = ax1.twinx()
        ax2.fill_between(t, lifted, step="post", color="tab:gray", alpha=0.25, label="wheels lifted")
        ax2.set_ylabel("wheels lifted")
        ax2.set_ylim(0, core.n_wheels)
        ax2.legend(fontsize=8, loc="upper right")
    ax1.set_title(f"P control (K = {K_POS:g}/s), no feed-forward; end: {end}", fontsize=10)
    fig.tight_layout()
    png = out / f"{env_id}.png"
    fig.savefig(png, dpi=80)
    plt.close(fig)
    return {"steps": len(errs) - 1, "final_mm": errs[-1] * 1000.0, "mean_mm": errs.mean() * 1000.0,
            "max_mm": errs.max() * 1000.0, "end": end, "gif_kb": gif.stat().st_size / 1024,
            "frames": len(frames)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--out", default="benchmarks/results/demo", help="output directory")
    parser.add_argument("--seconds", type=float, default=8.0, help="episode length cap [s]")
    args = parser.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for env_id in ENV_IDS:
        t0 = time.perf_counter()
        r = run(env_id, args.seconds, out)
        print(f"{env_id:28s} steps {r['steps']:4d} ({r['end']}): tracking error final {r['final_mm']:6.1f} mm, "
              f"mean {r['mean_mm']:6.1f} mm, max {r['max_mm']:6.1f} mm; GIF {r['frames']} frames "
              f"{r['gif_kb']:.0f} kB; {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main()
