"""Teacher → student: DAgger distillation of the model-predictive oracle into a sensor-only agent.

The teacher is :class:`agents.oracle.MPPIOracle` with the privileged state (the true pose, velocity and lifted
wheels; it plans with the simulator). The student is a PPO actor on the EKF features
(:class:`agents.wrappers.VectorEKFFeatures`, ``residual_scale`` 0: it outputs the whole twist) with the
:class:`agents.networks.AffineSkip` extractor: an affine map of the features plus a tanh MLP of them. The
features are what a robot's filter knows after the whole sensor history (estimate, its uncertainty, the
wheel-contact beliefs and encoder innovations, the PID's twist and integral, the previous action), so they
stand for the "short history of sensor observations" of the privileged-teacher recipe; the student never
reads the true state.

Recipe (Ross et al. 2011's DAgger, as in learning locomotion with privileged information):

1. The student starts as ``ekf-pid``'s exact clone: the affine part picks the PID twist columns of the
   features, the MLP's output weights are zero. The affine part stays the clone throughout (its gradient is
   masked): the student is ``ekf-pid`` plus a learned correction, and exactly ``ekf-pid`` where the
   correction is zero (a free affine part fitted to the teacher's labels lost ekf-pid's millimetre precision
   on a grip floor: 17 mm against 1.4 mm, measured while building this).
2. ``rounds`` rounds of ``round_steps`` control steps of ``robots`` robots in the training env (the id's
   randomised floors, friction, mass, lift-off rate and sensor noise; episodes run on across rounds). In
   round r each robot is driven, for the whole round, by the teacher with probability β_r = ``beta`` **
   (r + 1), otherwise by the current student (default ``beta`` 0: the student always drives, so round 0's
   data are ekf-pid's own states; pure behaviour cloning on the oracle's states, tried first, tracked 3-4x
   worse than ekf-pid, the classic compounding error). At every step the teacher labels the state the robot
   is in with its action (it plans from the true state wherever the robot is), and the (features, label)
   pair joins the aggregated data set.
3. After each round the correction is fitted to all data so far (mean squared error of the actor's mean
   against the clipped labels, Adam, ``epochs`` passes in minibatches of ``batch_size``, learning rate
   decaying linearly to 0), starting from the last round's weights.
4. Selection: after each fit the student is validated on ``validation_episodes`` episodes spread over the
   training floors, each without and with lift-off (:mod:`agents.validation`: seeds 5000…, apart from the
   benchmarks' 10 000+), scored as its mean tracking RMSE over all those episodes ÷ ``ekf-pid``'s on the
   same episodes (the pooled mean, as ``agents.train`` selects). The best round is kept (the clone, round
   "−1", is a candidate too). A geometric mean of the per-cell ratios, tried first, let the grip cells
   (ekf-pid 1.2-1.3 mm, a student 2-4 mm) outweigh 10 mm gains under lift-off and kept the clone on
   Phunopas and Mecanum.

The result is an ordinary model directory (``meta.json`` + ``policy.pt``, ``docs/formats.md``): evaluation,
the normalised score and export read it like any trained agent. Randomness: the env's seeds, the
driver draws and minibatch order come from ``seed``; the same seed gives the same student.

    python -m agents.distillation --env OmniPathFollow-Phunopas-v0 --out agents/models/student-phunopas
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from agents.oracle import OracleConfig
from agents.train import git_commit, load_hyperparams
from agents.validation import cell_episodes, episodes_per_cell, validation_cells, validation_seeds
from omni_gym.record_paths import record_args

TRAIN_SEED = 200_000  # the training env's first seed: apart from validation (5000+) and benchmark seeds
HYPERPARAMS = "ppo_features_bc_skip"  # the training distribution of the sensor-only agents (env_kwargs)
LABEL = "DAgger student of the MPPI oracle"


@dataclass(frozen=True)
class DAggerSpec:
    """Distillation settings (module docstring). ``robots``: training robots stepped together; ``rounds`` ×
    ``round_steps`` control steps (0.01 s each); ``beta``: the teacher's driving share in round r is beta**(r + 1);
    ``hidden``: width of the student's two tanh layers; ``epochs``, ``batch_size``, ``learning_rate``: the
    fit after each round; ``validation_episodes``: spread evenly over the validation cells; ``oracle``:
    the teacher's planner settings (privileged state); ``seed``: every draw."""

    robots: int = 64
    rounds: int = 12
    round_steps: int = 600
    beta: float = 0.0
    hidden: int = 128
    epochs: int = 5
    batch_size: int = 256
    learning_rate: float = 1e-3
    validation_episodes: int = 100
    oracle: OracleConfig = field(default_factory=OracleConfig)
    seed: int = 0

    def __post_init__(self) -> None:
        ints = {"robots": 1, "rounds": 1, "round_steps": 1, "hidden": 1, "epochs": 1, "batch_size": 1,
                "validation_episodes": 1}
        for key, low in ints.items():
            v = getattr(self, key)
            if not isinstance(v, int) or isinstance(v, bool) or v < low:
                raise ValueError(f"invalid DAggerSpec {key}={v!r}: a positive integer")
        if not (0.0 <= self.beta <= 1.0):
            raise ValueError(f"invalid DAggerSpec beta={self.beta!r}: in [0, 1]")
        if not (self.learning_rate > 0 and math.isfinite(self.learning_rate)):
            raise ValueError(f"invalid DAggerSpec learning_rate={self.learning_rate!r}: > 0")
        if self.oracle.state != "true":
            raise ValueError("the teacher plans from the privileged state: DAggerSpec.oracle.state must be 'true'")

    def as_dict(self) -> dict:
        return asdict(self)


def training_env_kwargs(env_id: str) -> dict:
    """The training distribution of ``env_id``'s sensor-only agents (:data:`HYPERPARAMS`' ``env_kwargs``)."""
    kw = dict(load_hyperparams("ppo", env_id, HYPERPARAMS).get("env_kwargs", {}))
    kw.pop("obs_mode", None)
    return kw


# --- the student network ----------------------------------------------------------------------------------------

def policy_kwargs(hidden: int) -> dict:
    """Declarative ``policy_kwargs`` (:mod:`agents.policy_spec`) of the student: an affine actor on
    ``[features, MLP(features)]``; the critic's layers are there only so that PPO can fine-tune it."""
    return {"features_extractor_class": "AffineSkip", "features_extractor_kwargs": {"hidden": int(hidden)},
            "share_features_extractor": False, "log_std_init": -3.5, "net_arch": {"pi": [], "vf": [64, 64]},
            "activation_fn": "Tanh", "use_sde": False}


def make_student(observation_space, action_space, hidden: int):
    """A PPO ``MlpPolicy`` whose deterministic action is ekf-pid's (features' PID twist columns, clipped)."""
    import torch
    from stable_baselines3.common.policies import ActorCriticPolicy

    from agents.policy_spec import to_sb3
    from agents.wrappers import pid_twist_columns

    policy = ActorCriticPolicy(observation_space, action_space, lambda _: 0.0, **to_sb3(policy_kwargs(hidden)))
    cols = pid_twist_columns(int(observation_space.shape[0]))
    with torch.no_grad():
        layer = policy.action_net
        layer.weight.zero_()
        layer.bias.zero_()
        for a, col in enumerate(range(cols.start, cols.stop)):
            layer.weight[a, col] = 1.0
    policy.set_training_mode(False)
    return policy


def _correction_params(policy) -> list:
    """The actor's parameters that fitting may change: the MLP, its output weights and the bias. The affine
    weights on the features themselves stay ekf-pid's clone (their gradient is masked in :func:`fit_student`),
    so the student is ekf-pid plus a learned correction, exact where the correction is zero."""
    return [*policy.pi_features_extractor.mlp.parameters(), policy.action_net.weight, policy.action_net.bias]


def student_actions(policy, obs: np.ndarray) -> np.ndarray:
    """(N, 3) float32 deterministic actions, clipped to the box (what evaluation applies)."""
    import torch

    with torch.no_grad():
        mean = policy.get_distribution(torch.as_tensor(np.asarray(obs, dtype=np.float32))).distribution.mean
    return np.clip(mean.numpy(), -1.0, 1.0).astype(np.float32)


def fit_student(policy, x: np.ndarray, y: np.ndarray, spec: DAggerSpec, rng: np.random.Generator) -> list[float]:
    """Adam on the actor's mean against the clipped labels ``y``; returns the mean squared error per epoch."""
    import torch

    xt = torch.as_tensor(x, dtype=torch.float32)
    yt = torch.as_tensor(np.clip(y, -1.0, 1.0), dtype=torch.float32)
    d = int(x.shape[1])
    keep = torch.ones_like(policy.action_net.weight)
    keep[:, :d] = 0.0  # the affine part on the features: ekf-pid's clone, not fitted
    hook = policy.action_net.weight.register_hook(lambda g: g * keep)
    opt = torch.optim.Adam(_correction_params(policy), lr=spec.learning_rate)
    sched = torch.optim.lr_scheduler.LambdaLR(opt, lambda e: 1.0 - e / spec.epochs)
    losses = []
    n = len(xt)
    policy.set_training_mode(True)
    for _ in range(spec.epochs):
        order = torch.as_tensor(rng.permutation(n))
        total = 0.0
        for start in range(0, n, spec.batch_size):
            idx = order[start:start + spec.batch_size]
            mean = policy.get_distribution(xt[idx]).distribution.mean
            loss = torch.mean((mean - yt[idx]) ** 2)
            opt.zero_grad()
            loss.backward()
            opt.step()
            total += loss.item() * len(idx)
        losses.append(total / n)
        sched.step()
    hook.remove()
    policy.set_training_mode(False)
    return losses


# --- data collection and validation -------------------------------------------------------------------------

def make_features_env(env_id: str, num: int, env_kwargs: dict):
    """A native vector env of ``num`` robots (sensors, twist, next-step autoreset) under the EKF features."""
    from agents.vector_rollout import make_vector_env
    from agents.wrappers import VectorEKFFeatures

    return VectorEKFFeatures(make_vector_env(env_id, num, env_kwargs, obs_mode="sensors"), residual_scale=0.0)


class _StudentActor:
    """:class:`agents.vector_rollout.VectorActor` of a student policy (stateless: the wrapper holds the filter)."""

    def __init__(self, policy) -> None:
        self.policy = policy

    def reset(self, obs, mask=None) -> None:
        """Nothing to reset."""

    def act(self, obs) -> np.ndarray:
        return student_actions(self.policy, obs)


class Validator:
    """Mean tracking RMSE ÷ ekf-pid's over all validation episodes (every cell), on fixed seeds."""

    def __init__(self, env_id: str, cells: list[dict], episodes: int) -> None:
        from agents.batched.policies import make_vector_policy
        from agents.vector_rollout import make_vector_env

        self.env_id, self.cells = env_id, cells
        self.seeds = validation_seeds(episodes_per_cell(episodes, len(cells)))
        self.reference = self._cell_rmse(lambda kw: make_vector_env(env_id, len(self.seeds), kw),
                                         lambda venv: make_vector_policy("ekf-pid", venv))

    def _cell_rmse(self, make_env, make_actor) -> list[float]:
        """Mean tracking RMSE [m] per cell of the actor ``make_actor(venv)`` in the envs ``make_env(kwargs)``."""
        venvs = [make_env(kw) for kw in self.cells]
        try:
            eps = cell_episodes(venvs, [make_actor(v) for v in venvs])
        finally:
            for venv in venvs:
                venv.close()
        return [float(np.mean([e.tracking_rmse for e in cell])) for cell in eps]

    @property
    def episodes(self) -> int:
        return len(self.seeds) * len(self.cells)

    def score(self, policy) -> tuple[float, list[float]]:
        """(mean RMSE over all episodes ÷ ekf-pid's, the student's mean RMSE per cell [m]); every cell has
        the same episode count, so the pooled mean is the mean of the cells' means."""
        rmse = self._cell_rmse(lambda kw: make_features_env(self.env_id, len(self.seeds), kw),
                               lambda venv: _StudentActor(policy))
        return float(np.sum(rmse) / np.sum(self.reference)), rmse


def collect_round(venv, obs: np.ndarray, oracle, policy, beta: float, steps: int, rng: np.random.Generator,
                  restart: np.ndarray, progress=None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``steps`` control steps of every robot, each driven by the teacher (probability ``beta``, drawn once
    per robot) or the student; returns (features (steps·N, D), teacher labels (steps·N, 3), the last
    observation, the robots whose next observation starts an episode)."""
    n = int(venv.num_envs)
    teacher_drives = rng.random(n) < beta
    xs, ys = [], []
    for _ in range(steps):
        if restart.any():
            oracle.reset(obs, restart)
        label = oracle.act(obs)  # the teacher's action at the state the robot is in
        xs.append(np.array(obs, dtype=np.float32))
        ys.append(np.array(label, dtype=np.float32))
        if teacher_drives.all():
            action = label
        else:
            action = np.where(teacher_drives[:, None], label, student_actions(policy, obs))
        obs, _, terminated, truncated, _ = venv.step(np.asarray(action, dtype=np.float32))
        restart = np.asarray(terminated | truncated, dtype=bool)
        if progress is not None:
            progress.update(1)
    return np.concatenate(xs), np.concatenate(ys), obs, restart


@dataclass
class RoundRow:
    """One DAgger round: data so far, the teacher's share, the fit and the validation."""

    round: int
    beta: float
    samples: int
    fit_mse: float
    val_ratio: float
    val_rmse_mm: list[float]
    wall_s: float


def distil(env_id: str, spec: DAggerSpec, out: str | Path, progress: bool | None = None,
           episode_seconds: float | None = None) -> dict:
    """Train a student for ``env_id`` (module docstring) into the model directory ``out``; returns meta.json.

    ``episode_seconds`` shortens the training and validation episodes (quick checks; None: the id's 20 s)."""
    import torch
    from tqdm import tqdm

    from agents.oracle import MPPIOracle
    from agents.weights import FORMAT, WEIGHTS, _box
    from omni_gym.outputs import write_text_atomic

    torch.set_num_threads(1)
    torch.manual_seed(spec.seed)
    t0 = time.time()
    show = progress if progress is not None else sys.stderr.isatty()
    train_kw = training_env_kwargs(env_id)  # an id without a training distribution: refused before any write
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    short = {} if episode_seconds is None else {"episode_seconds": float(episode_seconds)}
    cells = [{**c, **short} for c in validation_cells(train_kw)]
    train_kw = {**train_kw, **short}
    validator = Validator(env_id, cells, spec.validation_episodes)
    venv = make_features_env(env_id, spec.robots, train_kw)
    rng = np.random.default_rng(spec.seed)
    try:
        policy = make_student(venv.single_observation_space, venv.single_action_space, spec.hidden)
        oracle = MPPIOracle(venv, spec.oracle)
        obs, _ = venv.reset(seed=[TRAIN_SEED + 1000 * spec.seed + i for i in range(spec.robots)])
        oracle.reset(obs)
        restart = np.zeros(spec.robots, dtype=bool)
        ratio, rmse = validator.score(policy)
        rows = [RoundRow(-1, 0.0, 0, 0.0, ratio, [1e3 * r for r in rmse], time.time() - t0)]
        best = (ratio, -1, {k: v.clone() for k, v in policy.state_dict().items()})
        _report(rows[-1], show)
        xs, ys = [], []
        bar = tqdm(total=spec.rounds * spec.round_steps, desc=f"dagger {env_id}", unit="step", file=sys.stderr,
                   disable=not show)
        for r in range(spec.rounds):
            beta = spec.beta ** (r + 1)
            x, y, obs, restart = collect_round(venv, obs, oracle, policy, beta, spec.round_steps, rng, restart, bar)
            xs.append(x)
            ys.append(y)
            losses = fit_student(policy, np.concatenate(xs), np.concatenate(ys), spec, rng)
            ratio, rmse = validator.score(policy)
            rows.append(RoundRow(r, beta, int(sum(len(a) for a in xs)), losses[-1], ratio,
                                 [1e3 * v for v in rmse], time.time() - t0))
            _report(rows[-1], show)
            if ratio < best[0]:
                best = (ratio, r, {k: v.clone() for k, v in policy.state_dict().items()})
        bar.close()
    finally:
        venv.close()
    policy.load_state_dict(best[2])
    torch.save({k: v.detach().clone() for k, v in policy.state_dict().items()}, out / WEIGHTS)
    recorded = record_args(sys.argv[1:])
    meta = {
        "backend": "sb3", "algo": "ppo", "env_id": env_id, "train_env_kwargs": train_kw, "wrapper": "ekf-features",
        "residual_scale": 0.0, "obs_mode": "sensors", "seed": spec.seed, "n_envs": spec.robots,
        "hyperparams_file": HYPERPARAMS, "vecnormalize": None, "format": FORMAT, "model": WEIGHTS,
        "policy": {"class": "MlpPolicy", "kwargs": policy_kwargs(spec.hidden),
                   "observation_space": _box(venv.single_observation_space),
                   "action_space": _box(venv.single_action_space)},
        "hyperparams": spec.as_dict(), "git_commit": git_commit(),
        "distillation": {"label": LABEL, "validation_cells": cells,
                         "validation_seeds": [validator.seeds[0], validator.seeds[-1]],
                         "validation_episodes": validator.episodes,
                         "validation_ekf_pid_rmse_mm": [1e3 * v for v in validator.reference],
                         "rounds": [asdict(row) for row in rows], "best_round": best[1],
                         "best_val_ratio": best[0]},
        "timesteps": spec.rounds * spec.round_steps * spec.robots,
        "wall_time_s": round(time.time() - t0, 1),
        "command": "python -m agents.distillation " + " ".join(recorded) if __name__ == "__main__" else None,
    }
    write_text_atomic(out / "meta.json", json.dumps(meta, indent=2) + "\n")
    write_curve(out, meta)
    return meta


def write_curve(out: Path, meta: dict) -> None:
    """``curve.csv`` (one row per DAgger round: samples so far, wall time [s], pooled validation RMSE ÷
    ekf-pid's, each cell's mean RMSE [mm]) and ``curve.png`` (the ratio against samples, the best round
    marked) of a student's ``meta.json``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from omni_gym.outputs import write_text_atomic

    d = meta["distillation"]
    rows = d["rounds"]
    cells = [", ".join(f"{k}={v}" for k, v in c.items()) for c in d["validation_cells"]]
    head = ["round", "samples", "wall_s", "val_ratio"] + [f"val_rmse_mm[{c}]" for c in cells]
    lines = [",".join(f'"{h}"' if "," in h else h for h in head)]
    for r in rows:
        lines.append(",".join([str(r["round"]), str(r["samples"]), f"{r['wall_s']:.1f}", f"{r['val_ratio']:.6f}",
                               *(f"{v:.4f}" for v in r["val_rmse_mm"])]))
    write_text_atomic(Path(out) / "curve.csv", "\n".join(lines) + "\n")
    fig, ax = plt.subplots(figsize=(7, 4))
    x = [r["samples"] for r in rows]
    ax.plot(x, [r["val_ratio"] for r in rows], "o-", label="all validation episodes")
    best = next(r for r in rows if r["round"] == d["best_round"])
    ax.plot([best["samples"]], [best["val_ratio"]], "r*", ms=14, label=f"kept: round {best['round']}")
    ax.axhline(1.0, color="k", lw=0.8)
    ax.set_ylim(0, max(1.2, 1.05 * max(r["val_ratio"] for r in rows)))
    ax.set_xlabel("labelled robot-steps (DAgger data so far; 0: the ekf-pid clone)")
    ax.set_ylabel("validation tracking RMSE ÷ ekf-pid")
    ax.set_title(f"{meta['env_id']}: DAgger student, {d['validation_episodes']} validation episodes", fontsize=10)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(Path(out) / "curve.png", dpi=100)
    plt.close(fig)


def _report(row: RoundRow, show: bool) -> None:
    cells = ", ".join(f"{v:.1f}" for v in row.val_rmse_mm)
    print(f"round {row.round}: beta {row.beta:.2f}, {row.samples} samples, fit MSE {row.fit_mse:.2e}, "
          f"validation {row.val_ratio:.3f}x ekf-pid (cells [mm]: {cells}), {row.wall_s:.0f} s",
          file=sys.stderr if show else sys.stdout, flush=True)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m agents.distillation", description=__doc__.split("\n")[0])
    ap.add_argument("--env", required=True, help="a drivable OmniPathFollow id")
    ap.add_argument("--out", required=True, type=Path, help="model directory to write")
    defaults = DAggerSpec()
    for key in ("robots", "rounds", "round_steps", "hidden", "epochs", "validation_episodes", "seed"):
        ap.add_argument(f"--{key.replace('_', '-')}", type=int, default=getattr(defaults, key))
    ap.add_argument("--beta", type=float, default=defaults.beta)
    ap.add_argument("--episode-seconds", type=float, default=None, help="shorter episodes (quick checks)")
    args = ap.parse_args(argv)
    try:
        spec = DAggerSpec(robots=args.robots, rounds=args.rounds, round_steps=args.round_steps, beta=args.beta,
                          hidden=args.hidden, epochs=args.epochs, validation_episodes=args.validation_episodes,
                          seed=args.seed)
        meta = distil(args.env, spec, args.out, episode_seconds=args.episode_seconds)
    except (ValueError, OSError) as exc:  # bad settings or id; an output folder that cannot be written
        print(f"python -m agents.distillation: error: {exc}", file=sys.stderr)
        return 2
    d = meta["distillation"]
    print(f"wrote {args.out}: best round {d['best_round']}, validation {d['best_val_ratio']:.3f}x ekf-pid, "
          f"{meta['wall_time_s']:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
