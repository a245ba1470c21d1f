"""What calibrating saves a user, end to end, on the omni4 robot: controllers designed on the nominal model and
on the model calibrated from the real logs, both evaluated on the calibrated model (the robot's stand-in).

    python benchmarks/omni4_end_to_end.py [--quick] [--episodes 50] [--seed 10000] [--tune-episodes 32]
                                          [--ppo-nominal DIR] [--ppo-calibrated DIR] [--workers 2]
                                          [--out benchmarks/results]

The two design models:

* **nominal**: ``OmniPathFollow-Mecanum-v0`` with its defaults (the ``optiodom_omni4`` preset: wheel centres at
  ±0.1 m, wheel radius 0.03 m; carpet, ``initial`` friction, lift-off 0.5 /s);
* **calibrated**: ``OmniPathFollow-Custom-v0`` with ``benchmarks/inputs/omni4_calibrated_model.json``, the model an
  earlier ``benchmarks/real_optiodom.py`` fitted to the real omni4 logs on the files' time column (wheel
  centres at ±0.104 m, effective wheel radii 1.070–1.086 × 0.03 m, a floor where the wheels grip, no lift-off;
  the logs are MIT-licensed, ``data/optiodom-omni4/LICENSE``).

A controller designed on a model uses that model's **kinematics** (the wheel matrix W: body twist → wheel
speeds, with the per-wheel effective radii where the model has them; the EKF's encoder model and the
feed-forward both go through W) and **gains** tuned in that model's simulation. So every controller here
commands wheel speeds (``action_mode="wheels"``): on the robot, nothing converts its twist with a model it did
not choose. ``ekf-pid``'s gains are tuned by the same procedure and budget on each design model: a grid of
multipliers on the proportional gains (kp_pos, kp_head: ×0.25 … ×3) and on the integral gains (ki_pos, ki_head:
×0.25 … ×4) of :class:`agents.pid.PIDGains`, each cell scored by the mean tracking RMSE of ``--tune-episodes``
episodes (seeds 0…, disjoint from the held-out seeds), the lowest mean kept. The factorial rows (nominal
kinematics with the calibrated gains and the reverse) say which of the two carries the difference.

PPO (optional, ``--ppo-nominal`` / ``--ppo-calibrated``: model directories of ``omni-gym train`` with
``benchmarks/inputs/omni4_ppo_feedforward.yml`` on the two ids): a learned agent trained on each model, both
evaluated on the calibrated one (twist actions, the environment's conversion: the agents learn the plant as
they find it). Privileged (true-state observation), labelled so.

Every row runs on the same held-out seeds (``--seed``…, default 10 000…10 049) of the calibrated model, so
the comparisons are paired: the ratio of mean tracking RMSE (designed on calibrated ÷ designed on nominal)
with its 95 % paired-bootstrap interval, and the share of episodes in which the calibrated design tracks
better, with its 95 % bootstrap interval (10 000 resamples of the seeds, Generator seeded 0). Writes
``omni4_end_to_end.md`` (command first), ``omni4_end_to_end.json`` (per-episode RMSE) and
``omni4_end_to_end.png`` (paired episodes) into ``--out``. ``--quick``: a 2 × 2 grid, 4 tuning and 6
held-out episodes of 4 s, for a smoke test (its figures mean nothing).
"""

from __future__ import annotations

import argparse
import io
import json
import os
import shlex
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("MPLBACKEND", "Agg")
ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

import numpy as np  # noqa: E402
from scipy import stats  # noqa: E402

from agents.evaluate import BOOTSTRAP_RESAMPLES  # noqa: E402
from agents.pid import PIDGains  # noqa: E402
from omni_gym.outputs import write_bytes_atomic, write_text_atomic  # noqa: E402
from omni_gym.record_paths import record_args  # noqa: E402

MODEL = ROOT / "benchmarks" / "inputs" / "omni4_calibrated_model.json"
NOMINAL, CALIBRATED = "nominal", "calibrated"
ENV_KINEMATICS = "env"  # the policy the environment builds with kinematics="nominal" (twist actions)
ENV_MODEL_KINEMATICS = "env-model"  # the same with the env keyword kinematics="model" (the model's wheel matrix)
ENV_BUILT = (ENV_KINEMATICS, ENV_MODEL_KINEMATICS)  # policies the environment builds (twist actions)
DESIGN_IDS = {NOMINAL: "OmniPathFollow-Mecanum-v0", CALIBRATED: "OmniPathFollow-Custom-v0"}
P_GRID = (0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0)  # multipliers of kp_pos, kp_head
I_GRID = (0.25, 0.5, 1.0, 2.0, 4.0)  # multipliers of ki_pos, ki_head
QUICK_P, QUICK_I = (1.0, 2.0), (1.0, 2.0)
TUNE_SEED = 0  # tuning seeds 0…; held-out seeds from --seed (10 000)
BOOT_SEED = 0


# The calibrated design runs OmniPathFollow-Mecanum-v0's task (its references, drawn as they are), not the custom
# id's own default task (turns in place, references fitted to the model's traction): both designs then meet the
# same references, as this benchmark has compared them from the start.
MECANUM_TASK = {"ref_turn": "during", "ref_traction": 0.0}


def env_kwargs(design: str, model_path: Path = MODEL) -> dict:
    """gym.make keywords of a design model (besides obs/action mode and episode length)."""
    return {"model": str(model_path), **MECANUM_TASK} if design == CALIBRATED else {}


def design_model(design: str, model_path: Path = MODEL):
    """The design's :class:`~omni_gym.physics.model.SimModel` (the preset, or the calibrated file)."""
    from omni_gym.physics.model import load_model

    return load_model("optiodom_omni4") if design == NOMINAL else load_model(str(model_path))


def make_env(design: str, num: int, seconds: float | None, action_mode: str = "wheels", obs_mode: str = "sensors",
             model_path: Path = MODEL, extra: dict | None = None):
    """A native vector env (``next_step`` autoreset, episodes end with the reference) of a design model."""
    import gymnasium as gym

    import omni_gym  # noqa: F401  (registers the ids)

    kw = {**env_kwargs(design, model_path), **({} if seconds is None else {"episode_seconds": seconds}),
          **(extra or {})}
    return gym.make_vec(DESIGN_IDS[design], num_envs=num, vectorization_mode="vector_entry_point",
                        autoreset_mode="next_step", max_episode_steps=None, obs_mode=obs_mode,
                        action_mode=action_mode, **kw)


@dataclass(frozen=True)
class Scripted:
    """A scripted controller: policy name, the design model its kinematics come from, its gains."""

    policy: str  # open-loop or ekf-pid
    kinematics: str  # NOMINAL or CALIBRATED, or one of ENV_BUILT
    gains: PIDGains | None = None


def build_scripted(venv, spec: Scripted, model_path: Path = MODEL):
    """The batched policy of ``spec`` on ``venv`` with the wheel matrix of its design model (EKF included)."""
    from agents.batched.estimation import BatchEKF
    from agents.batched.policies import make_vector_policy
    from agents.ekf import EKFConfig
    from omni_gym.physics.kinematics import effective_kinematics

    policy = make_vector_policy(spec.policy, venv, spec.gains)
    if spec.kinematics in ENV_BUILT:
        return policy
    # The design model's effective kinematics (wheel matrix with its effects, mean effective radius).
    kinematics = effective_kinematics(design_model(spec.kinematics, model_path))
    policy.kinematics = kinematics
    policy.W = kinematics.wheel_matrix()  # feed-forward and PID twist → wheel speeds
    if hasattr(policy, "ekf"):  # the encoder model of the filter and its slip detector
        cfg = policy.cfg
        policy.ekf = BatchEKF(kinematics, policy.num, EKFConfig.from_sensor_config(cfg.sensor_config(),
                                                                                    cfg.control_hz))
        policy.estimate = policy.ekf.pose
    return policy


def run_scripted(args: tuple) -> list[dict]:
    """Per-episode metrics of a scripted controller on a design model (one batch of robots)."""
    from agents.vector_rollout import run_episodes_vector

    design, spec, seeds, seconds, model_path = args
    mode = "twist" if spec.kinematics in ENV_BUILT else "wheels"
    # Explicit both ways: OmniPathFollow-Custom-v0 defaults to "model", the other ids to "nominal".
    extra = ({"kinematics": "model" if spec.kinematics == ENV_MODEL_KINEMATICS else "nominal"}
             if spec.kinematics in ENV_BUILT else None)
    venv = make_env(design, len(seeds), seconds, action_mode=mode, model_path=model_path, extra=extra)
    try:
        return [e.metrics() for e in run_episodes_vector(venv, build_scripted(venv, spec, model_path), seeds)]
    finally:
        venv.close()


def run_ppo(args: tuple) -> list[dict]:
    """Per-episode metrics of an SB3 model directory on a design model (twist actions, as it was trained)."""
    from agents.sb3_policy import build_vector
    from agents.vector_rollout import run_episodes_vector

    design, path, seeds, seconds, model_path = args
    kw = {**env_kwargs(design, model_path), **({} if seconds is None else {"episode_seconds": seconds})}
    venv, policy = build_vector(path, len(seeds), DESIGN_IDS[design], kw)
    try:
        return [e.metrics() for e in run_episodes_vector(venv, policy, seeds)]
    finally:
        venv.close()


def scaled_gains(p: float, i: float) -> PIDGains:
    """:class:`PIDGains` with the proportional gains ×p and the integral gains ×i (the rest as designed)."""
    g = PIDGains()
    return PIDGains(kp_pos=g.kp_pos * p, ki_pos=g.ki_pos * i, kd_pos=g.kd_pos, kp_head=g.kp_head * p,
                    ki_head=g.ki_head * i, kd_head=g.kd_head, d_tau=g.d_tau, i_limit_pos=g.i_limit_pos,
                    i_limit_head=g.i_limit_head)


@dataclass
class Tuning:
    """The grid of one design model: (p, i) → mean tracking RMSE [m] of the tuning episodes; the best cell."""

    design: str
    grid: dict = field(default_factory=dict)
    lost: dict = field(default_factory=dict)

    @property
    def best(self) -> tuple[float, float]:
        return min(self.grid, key=self.grid.get)


def tune(designs, p_grid, i_grid, seeds, seconds, pmap, model_path: Path = MODEL) -> dict[str, Tuning]:
    """Tune ekf-pid's gain multipliers on each design model with its own kinematics (same grid, same seeds)."""
    cells = [(d, p, i) for d in designs for p in p_grid for i in i_grid]
    results = pmap(run_scripted, [(d, Scripted("ekf-pid", d, scaled_gains(p, i)), seeds, seconds, model_path)
                                  for d, p, i in cells])
    out = {d: Tuning(d) for d in designs}
    for (d, p, i), eps in zip(cells, results, strict=True):
        out[d].grid[(p, i)] = float(np.mean([e["tracking_rmse"] for e in eps]))
        out[d].lost[(p, i)] = sum(e["terminated"] for e in eps)
    return out


def paired(a: np.ndarray, b: np.ndarray, resamples: int = BOOTSTRAP_RESAMPLES) -> dict:
    """a against b on the same seeds: mean(a)/mean(b) and the share of seeds where a < b, each with its 95 %
    percentile bootstrap interval over seeds (Generator seeded :data:`BOOT_SEED`)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if a.shape != b.shape or a.ndim != 1 or len(a) < 2:
        raise ValueError(f"paired needs two equal 1-D samples of >= 2 episodes, got shapes {a.shape}, {b.shape}")
    idx = np.random.default_rng(BOOT_SEED).integers(0, len(a), size=(resamples, len(a)))
    ratios = a[idx].mean(axis=1) / b[idx].mean(axis=1)
    shares = (a[idx] < b[idx]).mean(axis=1)  # ties (equal RMSE: the same controller) count as not better
    q = [0.025, 0.975]
    return {"ratio": float(a.mean() / b.mean()), "ratio_ci95": [float(v) for v in np.quantile(ratios, q)],
            "better": float((a < b).mean()), "better_ci95": [float(v) for v in np.quantile(shares, q)],
            "ties": float((a == b).mean()),
            "episodes": len(a)}


def mean_ci_mm(x) -> str:
    x = 1e3 * np.asarray(x, dtype=float)
    half = stats.t.ppf(0.975, len(x) - 1) * x.std(ddof=1) / np.sqrt(len(x)) if len(x) > 1 else float("nan")
    return f"{x.mean():.2f} [{x.mean() - half:.2f}, {x.mean() + half:.2f}]"


def _pmap(workers: int):
    from omni_gym.parallel import backend_from_options, parallel_map

    backend = backend_from_options(workers, None)

    def pmap(fn, tasks):
        return parallel_map(fn, tasks, backend)
    return pmap


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog="\n".join(__doc__.splitlines()[1:]))
    ap.add_argument("--quick", action="store_true", help="smoke test: 2x2 grid, 4 + 6 episodes of 4 s")
    ap.add_argument("--episodes", type=int, default=50, help="held-out episodes (default 50)")
    ap.add_argument("--seed", type=int, default=10_000, help="first held-out seed (default 10000)")
    ap.add_argument("--tune-episodes", type=int, default=32, help="tuning episodes per grid cell (default 32)")
    ap.add_argument("--ppo-nominal", default=None, help="PPO model directory trained on the nominal model")
    ap.add_argument("--ppo-calibrated", default=None, help="PPO model directory trained on the calibrated model")
    ap.add_argument("--model", default=str(MODEL.relative_to(ROOT)), help="calibrated model JSON (default %(default)s)")
    ap.add_argument("--workers", type=int, default=2, help="worker processes (default 2)")
    ap.add_argument("--out", default="benchmarks/results", help="output directory")
    args = ap.parse_args(argv)
    if args.episodes < 2 or args.tune_episodes < 1 or args.seed < 0 or args.workers < 1:
        ap.error("--episodes must be >= 2, --tune-episodes >= 1, --seed >= 0, --workers >= 1")
    model_path = Path(args.model)
    if not model_path.is_file():
        ap.error(f"--model {args.model}: no such file")
    for opt in ("ppo_nominal", "ppo_calibrated"):
        v = getattr(args, opt)
        if v is not None and not (Path(v) / "meta.json").is_file():
            ap.error(f"--{opt.replace('_', '-')} {v}: not a model directory (no meta.json)")
    if args.quick:
        p_grid, i_grid, n_tune, n_eval, seconds = QUICK_P, QUICK_I, 4, 6, 4.0
    else:
        p_grid, i_grid, n_tune, n_eval, seconds = P_GRID, I_GRID, args.tune_episodes, args.episodes, None
    recorded = record_args(argv if argv is not None else sys.argv[1:])
    command = "python benchmarks/omni4_end_to_end.py " + shlex.join(recorded)
    pmap = _pmap(args.workers)
    t0 = time.time()
    tune_seeds = list(range(TUNE_SEED, TUNE_SEED + n_tune))
    tuned = tune((NOMINAL, CALIBRATED), p_grid, i_grid, tune_seeds, seconds, pmap, model_path)
    gains = {d: scaled_gains(*tuned[d].best) for d in tuned}
    t_tune = time.time() - t0

    seeds = list(range(args.seed, args.seed + n_eval))
    rows: dict[str, tuple[str, Scripted | str]] = {
        "open-loop, nominal kinematics": (CALIBRATED, Scripted("open-loop", NOMINAL)),
        "open-loop, calibrated kinematics": (CALIBRATED, Scripted("open-loop", CALIBRATED)),
        "ekf-pid, nominal kinematics, default gains": (CALIBRATED, Scripted("ekf-pid", NOMINAL)),
        "ekf-pid as `omni-gym evaluate` runs it on the calibrated model (twist actions; the model's wheel "
        "layout, the nominal wheel radius), default gains": (CALIBRATED, Scripted("ekf-pid", ENV_KINEMATICS)),
        "ekf-pid as `omni-gym evaluate` runs it with `kinematics=\"model\"` (twist actions through the model's "
        "wheel matrix, effective radii included), default gains": (CALIBRATED, Scripted("ekf-pid",
                                                                                         ENV_MODEL_KINEMATICS)),
        "ekf-pid designed on nominal (nominal kinematics, gains tuned on nominal)":
            (CALIBRATED, Scripted("ekf-pid", NOMINAL, gains[NOMINAL])),
        "ekf-pid, nominal kinematics, gains tuned on calibrated": (CALIBRATED, Scripted("ekf-pid", NOMINAL,
                                                                                         gains[CALIBRATED])),
        "ekf-pid, calibrated kinematics, gains tuned on nominal": (CALIBRATED, Scripted("ekf-pid", CALIBRATED,
                                                                                         gains[NOMINAL])),
        "ekf-pid designed on calibrated (calibrated kinematics, gains tuned on calibrated)":
            (CALIBRATED, Scripted("ekf-pid", CALIBRATED, gains[CALIBRATED])),
        "[on its own model] ekf-pid designed on nominal, on the nominal model":
            (NOMINAL, Scripted("ekf-pid", NOMINAL, gains[NOMINAL])),
    }
    if args.ppo_nominal:
        rows["PPO trained on nominal (privileged)"] = (CALIBRATED, args.ppo_nominal)
        rows["[on its own model] PPO trained on nominal, on the nominal model"] = (NOMINAL, args.ppo_nominal)
    if args.ppo_calibrated:
        rows["PPO trained on calibrated (privileged)"] = (CALIBRATED, args.ppo_calibrated)
    tasks = [(run_scripted if isinstance(spec, Scripted) else run_ppo, (design, spec, seeds, seconds, model_path))
             for design, spec in rows.values()]
    results = pmap(_call, tasks)
    eps = {name: np.array([e["tracking_rmse"] for e in r]) for name, r in zip(rows, results, strict=True)}
    lost = {name: sum(e["terminated"] for e in r) for name, r in zip(rows, results, strict=True)}
    elapsed = time.time() - t0

    pairs = [("ekf-pid: designed on calibrated vs designed on nominal",
              "ekf-pid designed on calibrated (calibrated kinematics, gains tuned on calibrated)",
              "ekf-pid designed on nominal (nominal kinematics, gains tuned on nominal)"),
             ("ekf-pid, the gains alone (nominal kinematics)", "ekf-pid, nominal kinematics, gains tuned on calibrated",
              "ekf-pid designed on nominal (nominal kinematics, gains tuned on nominal)"),
             ("ekf-pid, the kinematics alone (gains tuned on nominal)",
              "ekf-pid, calibrated kinematics, gains tuned on nominal",
              "ekf-pid designed on nominal (nominal kinematics, gains tuned on nominal)"),
             ("open-loop (feed-forward only): calibrated vs nominal kinematics", "open-loop, calibrated kinematics",
              "open-loop, nominal kinematics"),
             ("PPO: trained on calibrated vs trained on nominal", "PPO trained on calibrated (privileged)",
              "PPO trained on nominal (privileged)")]
    comparisons = [(title, paired(eps[a], eps[b])) for title, a, b in pairs if a in eps and b in eps]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    write_report(out, command.strip(), args, tuned, gains, rows, eps, lost, comparisons, seeds, n_tune, seconds,
                 t_tune, elapsed, model_path)
    print(f"wrote {out / 'omni4_end_to_end.md'}")
    return 0


def _call(task):
    fn, a = task
    return fn(a)


def _gain_text(g: PIDGains) -> str:
    return f"kp_pos {g.kp_pos:g}, ki_pos {g.ki_pos:g}, kp_head {g.kp_head:g}, ki_head {g.ki_head:g}"


def write_report(out: Path, command: str, args, tuned, gains, rows, eps, lost, comparisons, seeds, n_tune,
                 seconds, t_tune, elapsed, model_path) -> None:
    ep_len = "20 s" if seconds is None else f"{seconds:g} s"
    lines = ["# What calibrating saves a user: omni4, end to end", "", "```", command, "```", "",
             f"Controllers designed on the **nominal** model (`{DESIGN_IDS[NOMINAL]}` defaults: the `optiodom_omni4` "
             f"preset on carpet with lift-off) and on the **calibrated** model (`{DESIGN_IDS[CALIBRATED]}` with "
             f"`{model_path}`, fitted to the real omni4 logs: wheel centres ±0.104 m instead of ±0.1 m, effective "
             "wheel radii 1.070–1.086 × the nominal 0.03 m, a floor where the wheels grip, no lift-off), all "
             f"evaluated on the calibrated model, the robot's stand-in: {len(seeds)} paired held-out episodes of "
             f"{ep_len} (seeds {seeds[0]}–{seeds[-1]}), mean tracking RMSE [mm] with its 95 % t-interval. A "
             "controller designed on a model commands wheel speeds through that model's kinematics (its EKF's "
             "encoder model too) with gains tuned in that model's simulation (method: the script's docstring).",
             f"Wall time {elapsed / 60:.1f} min on this machine (tuning {t_tune / 60:.1f} min).", "",
             f"## ekf-pid gain tuning (same grid and {n_tune} tuning episodes, seeds {TUNE_SEED}–"
             f"{TUNE_SEED + n_tune - 1}, on each design model)", ""]
    for d in (NOMINAL, CALIBRATED):
        t = tuned[d]
        ps = sorted({p for p, _ in t.grid})
        is_ = sorted({i for _, i in t.grid})
        lines += [f"**{d}** (mean tracking RMSE [mm] of the tuning episodes; rows kp ×, columns ki ×; best in bold; "
                  f"chosen: {_gain_text(gains[d])}):", "",
                  "| kp × \\ ki × | " + " | ".join(f"{i:g}" for i in is_) + " |", "|---|" + "---|" * len(is_)]
        for p in ps:
            cells = []
            for i in is_:
                v = f"{1e3 * t.grid[(p, i)]:.2f}" + (f" ({t.lost[(p, i)]} lost)" if t.lost[(p, i)] else "")
                cells.append(f"**{v}**" if (p, i) == t.best else v)
            lines.append(f"| {p:g} | " + " | ".join(cells) + " |")
        lines.append("")
    lines += ["## On the calibrated model (the robot's stand-in)", "",
              "| controller | mean tracking RMSE [mm] | lost |", "|---|---|---|"]
    for name, (design, _spec) in rows.items():
        if design == CALIBRATED:
            lines.append(f"| {name} | {mean_ci_mm(eps[name])} | {lost[name]} |")
    own = [n for n, (d, _s) in rows.items() if d == NOMINAL]
    if own:
        lines += ["", "What the nominal designs promised: the same controllers on the model they were designed on "
                  "(the nominal model, same seeds):", "", "| controller | mean tracking RMSE [mm] | lost |",
                  "|---|---|---|"]
        lines += [f"| {n.replace('[on its own model] ', '')} | {mean_ci_mm(eps[n])} | {lost[n]} |" for n in own]
    lines += ["", "## Paired comparisons on the calibrated model", "",
              "ratio = mean RMSE of the first ÷ the second (below 1: the first tracks better); better = share of "
              "episodes in which the first has the smaller RMSE (ties: the same RMSE, i.e. the same commands); [95 % "
              "bootstrap intervals over seeds].", "",
              "| comparison | ratio of means | better | ties |", "|---|---|---|---|"]
    for title, c in comparisons:
        lines.append(f"| {title} | {c['ratio']:.3f} [{c['ratio_ci95'][0]:.3f}, {c['ratio_ci95'][1]:.3f}] | "
                     f"{100 * c['better']:.0f} % [{100 * c['better_ci95'][0]:.0f}, {100 * c['better_ci95'][1]:.0f}] | "
                     f"{100 * c['ties']:.0f} % |")
    lines.append("")
    write_text_atomic(out / "omni4_end_to_end.md", "\n".join(lines))
    payload = {"command": command, "seeds": seeds, "episode_seconds": seconds,
               "gains": {d: gains[d].__dict__ for d in gains},
               "tuning": {d: {f"{p:g},{i:g}": v for (p, i), v in tuned[d].grid.items()} for d in tuned},
               "tracking_rmse": {n: eps[n].tolist() for n in eps}, "lost": lost,
               "comparisons": {t: c for t, c in comparisons}}
    write_text_atomic(out / "omni4_end_to_end.json", json.dumps(payload, indent=1))
    plot(out / "omni4_end_to_end.png", eps, rows)


def plot(path: Path, eps: dict, rows: dict) -> None:
    """Paired episodes: RMSE designed on nominal (x) against designed on calibrated (y), per controller."""
    import matplotlib.pyplot as plt

    pairs = [("ekf-pid", "ekf-pid designed on nominal (nominal kinematics, gains tuned on nominal)",
              "ekf-pid designed on calibrated (calibrated kinematics, gains tuned on calibrated)"),
             ("open-loop", "open-loop, nominal kinematics", "open-loop, calibrated kinematics"),
             ("PPO (privileged)", "PPO trained on nominal (privileged)", "PPO trained on calibrated (privileged)")]
    pairs = [p for p in pairs if p[1] in eps and p[2] in eps]
    fig, ax = plt.subplots(figsize=(5.2, 4.8))
    for (label, a, b), m in zip(pairs, "os^", strict=False):
        ax.loglog(1e3 * eps[a], 1e3 * eps[b], m, ms=4, alpha=0.7, label=label)
    lo = min(1e3 * min(eps[a].min(), eps[b].min()) for _, a, b in pairs) * 0.8
    hi = max(1e3 * max(eps[a].max(), eps[b].max()) for _, a, b in pairs) * 1.25
    ax.plot([lo, hi], [lo, hi], "k-", lw=0.8)
    ax.set_xlim(lo, hi)
    ax.set_ylim(lo, hi)
    ax.set_xlabel("designed on the nominal model: tracking RMSE [mm]")
    ax.set_ylabel("designed on the calibrated model: tracking RMSE [mm]")
    ax.set_title("omni4, evaluated on the calibrated model\n(one point per held-out episode; below the line: "
                 "calibrating helped)", fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=120)
    plt.close(fig)
    write_bytes_atomic(path, buf.getvalue())


if __name__ == "__main__":
    sys.exit(main())
