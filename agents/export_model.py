"""Make a model directory commit-sized: drop the optimizer moments from its ``model.zip``.

``python -m agents.export_model DIR [DIR ...]`` loads each model of ``omni-gym train``'s output (its
``meta.json`` names the algorithm and the zip), clears every optimizer's state (Adam's first and second
moments: as large as the networks themselves, twice for SAC's critics), saves the zip again, checks
that the deterministic actions on 64 random observations are unchanged bit for bit, and records
``"optimizer_state": "dropped"`` in ``meta.json``. The model then acts exactly as before; training it
further would restart Adam's moments. The committed SAC models are exported this way (3.2 → 1.5 MB).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

import numpy as np

from agents.algorithms import algorithm_class
from agents.sb3_policy import read_meta
from omni_gym.outputs import write_text_atomic


def export(model_dir: str | Path) -> int:
    """Drop the optimizer state of ``model_dir``'s model in place; returns the new zip size [bytes]."""
    d = Path(model_dir)
    meta = read_meta(d)  # the checks (and one-line messages) of evaluation's loader
    cls = algorithm_class(meta["algo"])
    zip_path = d / meta["model"]
    if not zip_path.is_file():
        raise ValueError(f"{zip_path}: no such model file (named by {d / 'meta.json'})")
    model = cls.load(zip_path, device="cpu")
    obs = np.random.default_rng(0).normal(size=(64, *model.observation_space.shape)).astype(np.float32)
    before, _ = model.predict(obs, deterministic=True)
    for module in (model.policy, getattr(model, "actor", None), getattr(model, "critic", None)):
        optimizer = getattr(module, "optimizer", None)
        if optimizer is not None:
            optimizer.state.clear()
    if getattr(model, "ent_coef_optimizer", None) is not None:
        model.ent_coef_optimizer.state.clear()
    tmp = zip_path.with_name(zip_path.stem + ".export.zip")
    model.save(tmp)
    after, _ = cls.load(tmp, device="cpu").predict(obs, deterministic=True)
    if not np.array_equal(before, after):
        tmp.unlink()
        raise ValueError(f"{zip_path}: the exported model would act differently; left unchanged")
    os.replace(tmp, zip_path)  # the original stays whole until the export is checked
    meta["optimizer_state"] = "dropped"
    write_text_atomic(d / "meta.json", json.dumps(meta, indent=2, default=str) + "\n")
    return zip_path.stat().st_size


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m agents.export_model", description=__doc__.splitlines()[0])
    ap.add_argument("dirs", nargs="+", help="model directories (meta.json + model zip)")
    args = ap.parse_args(argv)
    for d in args.dirs:
        try:
            size = export(d)
        except ValueError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        print(f"{d}: {size / 1e6:.2f} MB")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
