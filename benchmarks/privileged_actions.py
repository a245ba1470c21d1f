"""What a privileged model does, against the true-state feedback law on the same observations.

    python benchmarks/privileged_actions.py MODEL_DIR [--steps 1500] [--robots 4] [--seed 10000]

Runs the model (deterministic) on the id it was trained on, no-slip floor (``surface="grip"``, no
lift-off: the easiest condition, where the law tracks to a fraction of a millimetre), ``--robots``
episodes from seeds ``--seed``…, for ``--steps`` control steps, and prints per action axis (vx, vy, ω,
in action units: twist / (v_max, v_max, ω_max)): the mean |a|, the mean |a − law(obs)| (the law of
:mod:`agents.feedback_law` on the same observation), the mean |a_t − a_{t−1}| (chattering: the law's is
~0.002 per 10 ms step) and the position and heading errors [m, rad] the model leaves.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing

import numpy as np  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("model", help="a privileged model directory (meta.json obs_mode 'state')")
    ap.add_argument("--steps", type=int, default=1500, help="control steps (default 1500 = 15 s; at most the episode)")
    ap.add_argument("--robots", type=int, default=4, help="episodes run at once (default 4)")
    ap.add_argument("--seed", type=int, default=10_000, help="first seed (default 10000)")
    args = ap.parse_args(argv)
    from agents.feedback_law import TrueStateFeedback
    from agents.sb3_policy import build_vector, read_meta
    from omni_gym.envs.observations import StateObsDecoder

    meta = read_meta(args.model)
    if meta.get("obs_mode") != "state":
        ap.error(f"{args.model}: not a privileged model (obs_mode {meta.get('obs_mode')!r})")
    kw = {"surface": "grip", "friction": "initial", "lift_rate": 0.0}
    venv, policy = build_vector(args.model, args.robots, meta["env_id"], kw)
    law = TrueStateFeedback(venv.unwrapped if meta["wrapper"] == "feedforward" else venv)
    decode = StateObsDecoder.for_env(venv)
    obs, _ = venv.reset(seed=[args.seed + i for i in range(args.robots)])
    acts, laws, pos, head = [], [], [], []
    for _ in range(args.steps):
        a = policy.act(obs)
        if meta["wrapper"] == "feedforward":  # what the environment receives: feed-forward + correction
            ref = obs[:, venv.ref]
            applied = np.clip(ref + venv.scale * np.clip(a, -1, 1), -1, 1)
        else:
            applied = np.clip(a, -1, 1)
        acts.append(applied)
        laws.append(law.act(obs))
        rows = [decode(o) for o in obs]
        pos.append([np.hypot(*r.tracking_error_body) for r in rows])
        head.append([abs(r.heading_error) for r in rows])
        obs, *_ = venv.step(a.astype(np.float32))
    venv.close()
    A, L = np.array(acts), np.array(laws)
    fmt = lambda v: ", ".join(f"{x:.3f}" for x in v)  # noqa: E731
    print(f"{args.model} on {meta['env_id']}, no slip, {args.robots} × {args.steps} steps (action axes vx, vy, ω)")
    print(f"  mean |a|            {fmt(np.abs(A).mean(axis=(0, 1)))}   law: {fmt(np.abs(L).mean(axis=(0, 1)))}")
    print(f"  mean |a - law|      {fmt(np.abs(A - L).mean(axis=(0, 1)))}")
    print(f"  mean |a_t - a_t-1|  {fmt(np.abs(np.diff(A, axis=0)).mean(axis=(0, 1)))}   law: "
          f"{fmt(np.abs(np.diff(L, axis=0)).mean(axis=(0, 1)))}")
    print(f"  position error mean {np.mean(pos):.4f} m, heading error mean {np.mean(head):.3f} rad")
    return 0


if __name__ == "__main__":
    sys.exit(main())
