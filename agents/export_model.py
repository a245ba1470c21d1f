"""Convert a model directory to omni-gym's weights format (:mod:`agents.weights`): no pickle left to open.

``python -m agents.export_model DIR [DIR ...] [--remove-pickles]`` loads each model of the older layout
(``meta.json`` naming an SB3 ``model.zip`` and a ``VecNormalize`` pickle: *unpickled*, so run it only on
models you trust, such as your own ``omni-gym train`` output), writes ``policy.pt`` (the policy's weights)
and ``normalisation.npz`` (the observation statistics), checks that the deterministic actions on 64 random
observations are unchanged bit for bit when the new files are read back, and points ``meta.json`` at them
(``format``, ``model``, ``vecnormalize``, ``policy``). ``--remove-pickles`` then deletes the zip and the
pickles the directory no longer needs (``model.zip``, ``vecnormalize.pkl``, ``final_model.zip``,
``final_vecnormalize.pkl``).
The committed models were converted this way.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from agents.sb3_policy import ModelOptions, load, read_meta
from agents.weights import FORMAT
from agents.weights import export as export_weights
from omni_gym.outputs import write_text_atomic

PICKLES = ("model.zip", "vecnormalize.pkl", "final_model.zip", "final_vecnormalize.pkl")


def _actions(model, vn, obs: np.ndarray) -> np.ndarray:
    o = obs if vn is None else np.asarray(vn.normalize_obs(obs), dtype=np.float32)
    return model.predict(o, deterministic=True)[0]


def export(model_dir: str | Path, remove_pickles: bool = False) -> int:
    """Convert ``model_dir`` in place; returns the size of the new weights file [bytes]."""
    d = Path(model_dir)
    meta = read_meta(d)
    if meta.get("format") == FORMAT:
        raise ValueError(f"{d}: already in the weights format")
    _, model, vn = load(d, ModelOptions(trust_pickle=True))
    obs = np.random.default_rng(0).normal(scale=3.0, size=(64, *model.observation_space.shape)).astype(np.float32)
    before = _actions(model, vn, obs)
    keys = export_weights(model, vn, d)
    new_meta = {**meta, **keys, "converted_from": {"model": meta["model"], "vecnormalize": meta.get("vecnormalize")}}
    write_text_atomic(d / "meta.json", json.dumps(new_meta, indent=2, default=str) + "\n")
    _, policy, norm = load(d)
    after = _actions(policy, norm, obs)
    if not np.array_equal(before, after):
        write_text_atomic(d / "meta.json", json.dumps(meta, indent=2, default=str) + "\n")
        raise ValueError(f"{d}: the converted model would act differently; meta.json left unchanged")
    if remove_pickles:
        for name in PICKLES:
            (d / name).unlink(missing_ok=True)
    return (d / keys["model"]).stat().st_size


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m agents.export_model", description=__doc__.splitlines()[0])
    ap.add_argument("dirs", nargs="+", help="model directories (meta.json + model zip)")
    ap.add_argument("--remove-pickles", action="store_true", help="delete " + ", ".join(PICKLES) + " once converted")
    args = ap.parse_args(argv)
    for d in args.dirs:
        try:
            size = export(d, args.remove_pickles)
        except ValueError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        print(f"{d}: policy.pt {size / 1e6:.2f} MB")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
