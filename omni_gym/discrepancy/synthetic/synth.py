"""Datasets with a hidden effect: the nominal model is written, the truth goes to a separate file.

``omni-gym synth`` simulates varied maneuvers (steps, ramps, rotations, diagonal moves, stops) with
the nominal model plus a hidden effect, adds measurement noise, and writes a dataset folder whose
``dataset.json`` holds only the nominal model. The truth (effect, parameters, noise, seed) goes to
``DATASET.truth.json`` beside the folder, which the workflow never reads.

Noise model (σ = ``noise`` [m]): tracker x, y with Gaussian σ; heading with σ / lever [rad], lever
= the largest wheel-centre distance (so a heading error moves a wheel by about σ); encoders
quantised to 2048 counts per revolution (a 512-line quadrature encoder).
"""

from __future__ import annotations

import hashlib
import json
import math
from pathlib import Path

import numpy as np

from omni_gym.bounds import CLI
from omni_gym.checks import unknown_key
from omni_gym.discrepancy.data.dataset import Run, write_dataset
from omni_gym.discrepancy.replay.simulate import Job, simulate_jobs
from omni_gym.io import parse_json, read_bytes, read_json
from omni_gym.outputs import Output
from omni_gym.physics.effects import REGISTRY
from omni_gym.physics.model import EFFECT_PARAMS, SimModel
from omni_gym.physics.world import DEFAULT_DT

RATE = 50.0  # Hz, command and tracker rows
COUNTS_PER_REV = 2048
# Effects outside the library that synth can hide (to test the `unexplained` outcome).
EXTRA_EFFECTS = {"viscous_drag": ("c",)}
EXTRA_DEFAULTS = {"viscous_drag": {"c": 4.0}}  # N·s/m


def pose_lever(model: SimModel) -> float:
    """Length [m] that turns a heading error into a displacement: the largest wheel-centre distance."""
    return model.robot.lever()


def default_params(name: str, model: SimModel, rng: np.random.Generator) -> dict:
    """Moderate default parameters of a hidden effect (the library's own defaults; random draws such as
    roller phases from ``rng``)."""
    if name in REGISTRY:
        return REGISTRY[name].synth_default(model, rng)
    return dict(EXTRA_DEFAULTS.get(name, {}))


def parse_hidden(spec: str, model: SimModel, rng: np.random.Generator) -> tuple[str, dict]:
    """``EFFECT`` or ``EFFECT:{json params}`` (missing keys take defaults) or ``none``."""
    name, colon, raw = spec.partition(":")
    name = name.strip()
    if name != "none" and name not in EFFECT_PARAMS and name not in EXTRA_EFFECTS:
        raise ValueError(f"--hidden: unknown effect {name!r}; choose none, one of {sorted(EFFECT_PARAMS)} "
                         f"or {sorted(EXTRA_EFFECTS)}")
    if name == "none" and colon:
        raise ValueError("--hidden none takes no parameters (give none alone)")
    if colon and not raw.strip():
        raise ValueError(f"--hidden {name}: nothing after ':' (give {name} alone for its default parameters, or "
                         f"{name}:{{JSON object}})")
    params = default_params(name, model, rng)
    if raw.strip():
        given = parse_json(raw, f"--hidden {name}: parameters")
        if not isinstance(given, dict):
            raise ValueError(f"--hidden {name}: parameters must be a JSON object")
        allowed = EFFECT_PARAMS.get(name) or EXTRA_EFFECTS.get(name, ())
        for key in given:
            if key not in allowed:
                raise ValueError(f"--hidden {name}: {unknown_key(key, allowed, what='parameter')}")
        params.update(given)
    if name in EFFECT_PARAMS:
        try:
            model.with_effect(name, params)  # validates, bounds included
        except ValueError as exc:
            raise ValueError(f"--hidden {name}: {exc}") from None
    elif name == "viscous_drag":
        _check_drag(params["c"], model.robot.mass)
    return name, params


def _check_drag(c, mass: float) -> None:
    """Refuse a drag coefficient c [N·s/m] outside ``bounds.CLI`` (as c / mass [1/s])."""
    if isinstance(c, bool) or not isinstance(c, (int, float)) or not math.isfinite(c):
        raise ValueError(f"--hidden viscous_drag: c must be a finite number [N·s/m], got {c!r}")
    bound = CLI["--hidden viscous_drag c / mass"]
    if not bound.contains(c / mass):
        raise ValueError(f"--hidden viscous_drag: c / mass {bound.describe()} (mass {mass:g} kg), got c = {c!r}")


def maneuver(model: SimModel, rng: np.random.Generator, duration: float, rate: float = RATE) -> tuple:
    """Times (K,) [s] and wheel commands (K, n) [rad/s] of one random maneuver.

    Segments of 0.4–1.2 s, each a step or a ramp to a new body twist drawn from: straight moves,
    diagonal moves, pure rotations, combined moves and stops; up to 0.35 m/s and 2 rad/s.
    """
    k = int(round(duration * rate)) + 1
    t = np.arange(k) / rate
    twist = np.zeros((k, 3))
    current = np.zeros(3)
    i = 0
    while i < k - 1:
        length = int(rng.integers(int(0.4 * rate), int(1.2 * rate) + 1))
        kind = rng.integers(5)
        v = rng.uniform(0.1, 0.35)
        ang = rng.uniform(-math.pi, math.pi)
        if kind == 0:  # straight along a body axis
            axis = rng.integers(4) * math.pi / 2
            target = np.array([v * math.cos(axis), v * math.sin(axis), 0.0])
        elif kind == 1:  # diagonal
            d = (rng.integers(4) + 0.5) * math.pi / 2
            target = np.array([v * math.cos(d), v * math.sin(d), 0.0])
        elif kind == 2:  # rotation on the spot
            target = np.array([0.0, 0.0, rng.choice([-1, 1]) * rng.uniform(0.8, 2.0)])
        elif kind == 3:  # combined
            target = np.array([v * math.cos(ang), v * math.sin(ang), rng.uniform(-1.5, 1.5)])
        else:  # stop
            target = np.zeros(3)
        end = min(k - 1, i + length)
        if rng.random() < 0.5:  # step
            twist[i:end] = target
        else:  # ramp over the segment
            frac = (np.arange(end - i) + 1) / (end - i)
            twist[i:end] = current + frac[:, None] * (target - current)
        current = target
        i = end
    twist[-1] = 0.0
    return t, twist @ model.robot.wheel_matrix().T


def synthesize(model: SimModel, hidden: str, runs: int, noise: float, seed: int, duration: float = 5.0,
               observe: str = "all") -> tuple[list[Run], dict]:
    """Simulate ``runs`` maneuvers with the hidden effect; returns (runs with noisy measurements, truth).

    ``runs``, ``noise`` [m], ``duration`` [s] and ``seed`` must lie inside ``bounds.CLI`` (their options).
    """
    for option, value in (("--runs", runs), ("--noise", noise), ("--duration", duration), ("--seed", seed)):
        CLI[option].check(value)
    CLI["--runs × --duration"].check(runs * duration)
    if observe not in ("all", "end"):
        raise ValueError(f"--observe must be 'all' or 'end', got {observe!r}")
    rng = np.random.default_rng(seed)
    r_param, r_man, r_noise, r_lift = rng.spawn(4)
    name, params = parse_hidden(hidden, model, r_param)
    true_model = model.with_effect(name, params) if name in EFFECT_PARAMS else model
    drag = float(params["c"]) if name == "viscous_drag" else 0.0
    plans = [maneuver(model, r_man, duration) for _ in range(runs)]
    lift_seeds = r_lift.integers(0, 2**31, runs)
    shells = [Run(name=f"run{i:03d}", t=t, cmd=c, pose=np.zeros((len(t), 3))) for i, (t, c) in enumerate(plans)]
    sims = simulate_jobs([Job(true_model, r, seed=int(s), drag=drag) for r, s in zip(shells, lift_seeds, strict=True)],
                         dt=DEFAULT_DT, start_window=None)  # making data: nothing measured to align to
    lever = pose_lever(model)
    out = []
    quantum = 2 * math.pi / COUNTS_PER_REV
    for run, (pose, ang) in zip(shells, sims, strict=True):
        if not (np.all(np.isfinite(pose)) and np.all(np.isfinite(ang))):  # NaN would be written as "not observed"
            raise ValueError(f"synth: the simulation of {run.name} became non-finite; nothing written")
        meas = pose + r_noise.normal(0.0, 1.0, pose.shape) * np.array([noise, noise, noise / lever])
        meas[0] = 0.0  # each run starts at rest at the origin, known exactly
        if observe == "end":
            meas[:-1] = np.nan
        enc = np.floor(ang / quantum) * quantum
        out.append(Run(name=run.name, t=run.t, cmd=run.cmd, pose=meas, enc=enc))
    truth = {"effect": name, "params": params, "noise": noise, "seed": seed, "runs": runs,
             "duration": duration, "observe": observe,
             "model": true_model.to_json() if name in EFFECT_PARAMS else None}
    return out, truth


def truth_path(dataset: str | Path) -> Path:
    """Where the truth of a synthetic dataset goes: ``DATASET.truth.json`` beside the folder."""
    p = Path(dataset)
    return p.parent / f"{p.name}.truth.json"


def write_synthetic(out: str | Path, model: SimModel, hidden: str, runs: int, noise: float, seed: int,
                    duration: float = 5.0, observe: str = "all", force: bool = False,
                    inputs: tuple = ()) -> dict:
    """Synthesize and write the dataset folder and its truth file, complete or absent; returns the truth.

    The output is checked and locked before the simulation starts (:class:`omni_gym.outputs.Output`):
    an existing dataset (or truth file) is refused unless ``force``, an output that is one of
    ``inputs`` (e.g. the model file) always. The folder is built in a temporary sibling and renamed
    in; the truth file is renamed in after it and records ``dataset_digest`` (:func:`dataset_digest`
    of the folder), so a truth file that does not belong to its folder is detectable (:func:`read_truth`).
    """
    out = Path(out)
    truth_file = truth_path(out)
    with Output(out, "dir", force=force, inputs=inputs, marker="dataset.json", what="dataset",
                companions=(truth_file,)) as tx:
        data, truth = synthesize(model, hidden, runs, noise, seed, duration, observe)
        desc = (f"synthetic: {runs} runs of {duration:g} s, tracker noise {noise:g} m, seed {seed} "
                f"(generated by omni-gym synth; the hidden effect is not recorded here)")
        write_dataset(tx.path, model.to_json(), desc, data)
        truth["dataset_digest"] = dataset_digest(tx.path)
        tx.stage_companion(truth_file, (json.dumps(truth, indent=2, allow_nan=False) + "\n").encode())
    return truth


def dataset_digest(folder: str | Path) -> str:
    """SHA-256 (hex) of a dataset's content: dataset.json and every run file (name and bytes, sorted)."""
    folder = Path(folder)
    h = hashlib.sha256()
    files = [folder / "dataset.json", *sorted(f for f in (folder / "runs").glob("*.csv") if not f.name.startswith("."))]
    for f in files:
        h.update(f.relative_to(folder).as_posix().encode() + b"\0")
        h.update(read_bytes(f))
    return h.hexdigest()


def read_truth(dataset: str | Path) -> dict:
    """The truth of a synthetic dataset; ValueError if it is missing or was written for other content."""
    path = truth_path(dataset)
    if not path.exists():
        raise ValueError(f"{path}: file not found (no truth for {dataset})")
    truth = read_json(path)
    if not isinstance(truth, dict):
        raise ValueError(f"{path}: expected a JSON object")
    if truth.get("dataset_digest") != dataset_digest(dataset):
        raise ValueError(f"{path}: does not belong to {dataset} (dataset_digest differs): the folder was "
                         "changed or replaced after the truth was written")
    return truth
