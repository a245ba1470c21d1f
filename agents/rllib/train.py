"""Train RLlib PPO on an omni-gym path-following id: ``omni-gym train --backend rllib``.

    omni-gym train --backend rllib --env OmniPathFollow-Phunopas-v0 --timesteps 2000000 --seed 0 --out DIR
                   [--address ADDRESS] [--num-env-runners N] [--n-envs ROBOTS_PER_RUNNER] [--hyperparams FILE]
                   [--eval-freq STEPS] [--eval-episodes K] [--checkpoint-freq STEPS] [--max-minutes M]

The configuration comes from ``agents/rllib/ppo.yml`` (:mod:`agents.rllib.config`). Ray: ``--address``
connects to a running cluster (``ray start --head``; its GCS address ``HOST:PORT``); without it a local
Ray starts for the run and stops after it. ``--num-env-runners`` env runner actors (default 0: sampling
in this process) each step one native vector env of ``--n-envs`` robots (:mod:`agents.rllib.env`).

Training runs ``algo.train()`` iterations until ``--timesteps`` env steps (whole iterations: the last
may pass the budget) or ``--max-minutes``. Validation is the SB3 path's (``agents.train.validation_row``:
the same episodes, seeds 5000…, metrics and curve), after the first iteration that reaches each multiple
of ``--eval-freq``, and on the untrained policy. The output directory matches the SB3 one
(``docs/formats.md``): ``checkpoint/`` (the RLlib checkpoint with the lowest validation tracking RMSE
after step 0, else the final one), ``final_checkpoint/``, ``meta.json`` (``"backend": "rllib"``,
``"model": "checkpoint"``), ``curve.csv`` / ``curve.png`` and ``checkpoints/``.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from agents.rllib.config import RLlibHyperparams, default_file, load, ppo_config
from agents.rllib.env import register_training_env
from agents.rllib.policy import RLlibPolicy
from agents.rollout import make_env
from agents.train import (
    VALIDATION_SEED,
    _write_json,
    git_commit,
    in_model_transaction,
    print_progress,
    run_and_report,
    validation_row,
    write_curve,
)
from agents.wrappers import wrap_env
from omni_gym.envs.config import parse_model
from omni_gym.parallel import check_ray_address
from omni_gym.rllib import require_ray

ROOT = Path(__file__).resolve().parents[2]
CHECKPOINT = "checkpoint"
FINAL_CHECKPOINT = "final_checkpoint"
SERIAL_EPISODES = 5  # default validation episodes: RLlib validates one single env at a time


@dataclass(frozen=True)
class IterationStats:
    """What one ``algo.train()`` result says: lifetime env steps sampled, and the mean return of the
    training episodes that ended lately (RLlib's smoothing window; None before any ended)."""

    timesteps: int
    episode_return_mean: float | None


def iteration_stats(result: dict) -> IterationStats:
    """:class:`IterationStats` from an RLlib (new API stack) result dict."""
    runners = result.get("env_runners", {}) or {}
    steps = runners.get("num_env_steps_sampled_lifetime", result.get("num_env_steps_sampled_lifetime", 0))
    ret = runners.get("episode_return_mean")
    finite = ret is not None and ret == ret  # NaN before any episode ended
    return IterationStats(int(steps or 0), float(ret) if finite else None)


def env_stack(runner) -> str:
    """The env runner's environment as nested class names, outermost first, e.g.
    ``DictInfoToList(DistinctSeeds(VectorTrackingReward(OmniPathVectorEnv)))`` (recorded in meta.json)."""
    names, env = [], runner.env
    while env is not None and len(names) < 20:
        names.append(type(env).__name__)
        env = getattr(env, "env", None)
    return "(".join(names) + ")" * (len(names) - 1)


def runner_envs(algo, num_env_runners: int) -> list[str]:
    """:func:`env_stack` of every env runner that samples (the driver's with 0 env runner actors)."""
    if num_env_runners == 0:
        return [env_stack(algo.env_runner)]
    return list(algo.env_runner_group.foreach_env_runner(env_stack, local_env_runner=False))


@contextlib.contextmanager
def ray_session(address: str | None, num_env_runners: int) -> Iterator[None]:
    """Connect to the cluster at ``address`` or start a local Ray (stopped afterwards); if this process is
    already connected (a test's cluster, a notebook), use that connection and leave it open. A cluster
    with fewer CPUs than ``num_env_runners`` is refused (the env runner actors would wait forever)."""
    import ray

    owned = not ray.is_initialized()
    if owned:
        if address:
            check_ray_address(address)  # one line at once for an address nothing listens on
            try:
                ray.init(address=address, log_to_driver=False, configure_logging=False)
            except (ConnectionError, RuntimeError, ValueError) as exc:
                raise ValueError(f"--address {address}: cannot connect to a Ray cluster "
                                 f"({' '.join(str(exc).split())[:200]})") from None
        else:  # loopback only: a local run needs no network
            ray.init(num_cpus=max(os.cpu_count() or 1, num_env_runners), include_dashboard=False,
                     _node_ip_address="127.0.0.1", log_to_driver=False, configure_logging=False)
    try:
        cpus = float(ray.cluster_resources().get("CPU", 0))
        if num_env_runners > cpus:
            raise ValueError(f"--num-env-runners {num_env_runners}: the Ray cluster has {cpus:g} CPUs "
                             "(one per env runner)")
        yield
    finally:
        if owned:
            ray.shutdown()


def train(*args, force: bool = False, **kwargs) -> dict:
    """Train into the model directory ``out`` (arguments of :func:`train_into`) through an
    :class:`omni_gym.outputs.Output` transaction, as :func:`agents.train.train` does; returns the meta dict."""
    return in_model_transaction(train_into, args, kwargs, force)


def _settings(env_id: str, timesteps: int | None, seed: int, env_kwargs: dict | None, hyperparams,
              n_envs: int | None, num_env_runners: int) -> tuple[RLlibHyperparams, int, int, dict, str]:
    """Checked (hyperparameters, budget [env steps], robots per runner, training env kwargs, file)."""
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    if isinstance(num_env_runners, bool) or not isinstance(num_env_runners, int) or num_env_runners < 0:
        raise ValueError(f"num_env_runners must be an integer >= 0, got {num_env_runners!r}")
    if env_kwargs is not None and not isinstance(env_kwargs, dict):
        raise ValueError(f"env_kwargs must be a dict (a JSON object), got {env_kwargs!r}")
    where = str(hyperparams or default_file())
    hp = load(env_id, hyperparams)
    budget = int(timesteps if timesteps is not None else hp.n_timesteps)
    if budget < 1:
        raise ValueError(f"timesteps must be >= 1, got {budget} (--timesteps or n_timesteps in {where})")
    n = int(n_envs if n_envs is not None else hp.n_envs)
    if n < 1:
        raise ValueError(f"n_envs must be >= 1, got {n}")
    kw = {**hp.env_kwargs, **(env_kwargs or {})}
    if isinstance(kw.get("model"), (str, os.PathLike)):  # as the SB3 path: the model's content, not its path
        kw["model"] = parse_model(kw["model"]).to_json()
    return hp, budget, n, kw, where


def _check_sizes(hp: RLlibHyperparams, where: str, env, max_parameters: int | None, max_buffer_mb: float | None
                 ) -> None:
    """The PPO module's networks (``model``: ``fcnet_hiddens`` then ``head_fcnet_hiddens``, for the policy, whose
    output is a mean and a log std per action, and the value function) and one train batch within the limits of
    :func:`agents.options.check_training_size`."""
    import numpy as np

    from agents.options import check_training_size

    obs_dim = int(np.prod(env.observation_space.shape))
    act_dim = int(np.prod(env.action_space.shape))
    layers = [*hp.model.get("fcnet_hiddens", [256, 256]), *hp.model.get("head_fcnet_hiddens", [])]
    sizes = {"n_steps": hp.training.get("train_batch_size_per_learner", 4000),
             "batch_size": hp.training.get("minibatch_size", 128)}
    for key, value in sizes.items():
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            name = "train_batch_size_per_learner" if key == "n_steps" else "minibatch_size"
            raise ValueError(f"{where}: training: {name} must be an integer >= 1, got {value!r}")
    check_training_size(sizes, {"net_arch": layers}, "ppo", 1, obs_dim, 2 * act_dim, f"{where}: model",
                        max_parameters, max_buffer_mb)


def train_into(env_id: str, timesteps: int | None, seed: int, out: str | Path, env_kwargs: dict | None = None,
               hyperparams: str | Path | None = None, n_envs: int | None = None, num_env_runners: int = 0,
               address: str | None = None, eval_freq: int = 50_000, eval_episodes: int = SERIAL_EPISODES,
               checkpoint_freq: int = 0, progress: bool | None = None, max_minutes: float | None = None,
               command: str | None = None, threads: int = 1, max_parameters: int | None = None,
               max_buffer_mb: float | None = None) -> dict:
    """Train and save into ``out`` directly (:func:`train` gives the transaction); returns the meta dict.

    Arguments as ``omni-gym train`` (module doc); ``eval_freq`` / ``checkpoint_freq`` [env steps over all
    robots] (0 disables); ``max_minutes`` [min] stops after the iteration that passes it.
    """
    require_ray("omni-gym train --backend rllib")
    import torch

    hp, budget, n, kw, where = _settings(env_id, timesteps, seed, env_kwargs, hyperparams, n_envs, num_env_runners)
    if max_minutes is not None and not (isinstance(max_minutes, (int, float)) and max_minutes > 0):
        raise ValueError(f"max_minutes must be a number > 0 (or None), got {max_minutes!r}")
    obs_mode = kw.get("obs_mode", "sensors")
    val_kw = {k: v for k, v in kw.items() if not k.startswith("randomize_") and k != "obs_mode"}
    # One env in this process first: bad keywords fail here with a clear ValueError, before Ray starts.
    eval_env = wrap_env(make_env(env_id, val_kw, obs_mode=obs_mode), "none")
    make_env(env_id, {k: v for k, v in kw.items() if k != "obs_mode"}, obs_mode=obs_mode).close()
    _check_sizes(hp, where, eval_env, max_parameters, max_buffer_mb)  # before Ray starts or anything is allocated
    torch.set_num_threads(threads)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    meta = {
        "backend": "rllib", "algo": "ppo", "env_id": env_id, "train_env_kwargs": kw, "wrapper": "none",
        "residual_scale": 0.0, "sensor_noise_range": None, "obs_mode": obs_mode, "seed": seed, "n_envs": n,
        "num_env_runners": num_env_runners, "ray_address": address, "vec_env": "native", "reward": hp.spec.reward,
        "hyperparams_file": os.path.relpath(where, ROOT) if hyperparams is None else str(hyperparams),
        "hyperparams": hp.raw, "requested_timesteps": budget,
        "validation_seeds": [VALIDATION_SEED, VALIDATION_SEED + eval_episodes - 1] if eval_freq > 0 else None,
        "validation_env_kwargs": val_kw, "vecnormalize": None, "model": CHECKPOINT, "command": command,
        "git_commit": git_commit(), "torch_threads": torch.get_num_threads(),
    }
    run = _Run(out, meta, eval_env, eval_episodes, progress)
    try:
        with ray_session(address, num_env_runners):
            name = register_training_env()
            env_config = {**kw, "env_id": env_id, "reward": hp.spec.reward, "seed": seed}
            algo = ppo_config(hp, env_config, n, num_env_runners, seed, name, where).build_algo()
            try:
                meta["env_runner_envs"] = runner_envs(algo, num_env_runners)
                run.loop(algo, budget, eval_freq, checkpoint_freq, max_minutes)
            finally:
                algo.stop()
    finally:
        eval_env.close()
    meta.update(timesteps=run.timesteps, wall_time_s=round(run.wall, 1), stopped_early=run.stopped,
                best=run.best, iterations=run.iterations)
    _write_json(out / "meta.json", meta)
    write_curve(out, run.rows, meta)
    return {**meta, "curve": run.rows}


class _Run:
    """The training loop's state: validation rows, the best one, checkpoints, the time limit."""

    def __init__(self, out: Path, meta: dict, eval_env, eval_episodes: int, progress: bool | None) -> None:
        self.out, self.meta, self.eval_env, self.eval_episodes = out, meta, eval_env, eval_episodes
        self.show = progress if progress is not None else sys.stderr.isatty()
        self.rows: list[dict] = []
        self.best: dict | None = None
        self.timesteps = self.iterations = 0
        self.stopped = False
        self.wall = 0.0
        self._t0 = time.time()

    def loop(self, algo, budget: int, eval_freq: int, checkpoint_freq: int, max_minutes: float | None) -> None:
        """``algo.train()`` until ``budget`` env steps or ``max_minutes``; validate and checkpoint on the way."""
        from tqdm import tqdm

        self._t0 = time.time()
        next_eval, next_ckpt = eval_freq, checkpoint_freq
        reward = None
        with tqdm(total=budget, desc="train rllib ppo", file=sys.stderr, unit="step", disable=not self.show) as bar:
            if eval_freq > 0:
                self._validate(algo, None)
            while self.timesteps < budget:
                stats = iteration_stats(algo.train())
                self.iterations += 1
                self.timesteps, reward = stats.timesteps, stats.episode_return_mean
                bar.update(min(self.timesteps, budget) - bar.n)
                if eval_freq > 0 and self.timesteps >= next_eval:
                    self._validate(algo, reward)
                    next_eval = (self.timesteps // eval_freq + 1) * eval_freq
                if checkpoint_freq > 0 and self.timesteps >= next_ckpt:
                    algo.save(str(self.out.resolve() / "checkpoints" / f"checkpoint_{self.timesteps}"))
                    next_ckpt = (self.timesteps // checkpoint_freq + 1) * checkpoint_freq
                if max_minutes is not None and time.time() - self._t0 > 60.0 * max_minutes:
                    self.stopped = True
                    break
        self.wall = time.time() - self._t0
        algo.save(str(self.out.resolve() / FINAL_CHECKPOINT))
        if self.best is None:
            algo.save(str(self.out.resolve() / CHECKPOINT))
        if eval_freq > 0 and (not self.rows or self.rows[-1]["timesteps"] != self.timesteps):
            self._validate(algo, reward)  # the final policy is always on the curve

    def _validate(self, algo, train_reward: float | None) -> None:
        policy = RLlibPolicy(algo.get_module(), self.eval_env)
        row = validation_row(self.eval_env, policy, self.eval_episodes, self.timesteps, time.time() - self._t0,
                             train_reward)
        self.rows.append(row)
        # The untrained policy (step 0) is a reference point on the curve, not a candidate.
        if self.timesteps > 0 and (self.best is None or row["val_tracking_rmse"] < self.best["val_tracking_rmse"]):
            self.best = dict(row)
            algo.save(str(self.out.resolve() / CHECKPOINT))
        write_curve(self.out, self.rows, self.meta)
        print_progress(row, self.show)


def run_from_args(args: argparse.Namespace, command: str | None = None) -> dict:
    """Validate parsed ``omni-gym train --backend rllib`` arguments and call :func:`train`."""
    from agents.options import check_backend_args, check_train_args, parse_env_kwargs
    from agents.train import command_line

    check_train_args(args)
    check_backend_args(args)
    require_ray("omni-gym train --backend rllib")
    kwargs = parse_env_kwargs(args.env_kwargs)
    command = command or command_line("python -m agents.rllib.train", args)
    return train(args.env, None if args.timesteps is None else int(args.timesteps), args.seed, args.out, kwargs,
                 args.hyperparams, args.n_envs, args.num_env_runners or 0, args.address, args.eval_freq,
                 SERIAL_EPISODES if args.eval_episodes is None else args.eval_episodes,
                 args.checkpoint_freq, args.progress, args.max_minutes, command, args.threads,
                 None if args.max_parameters is None else int(args.max_parameters), args.max_buffer_mb,
                 force=args.force)


def main(argv: list[str] | None = None) -> int:
    from agents.train import build_arg_parser

    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    argv = sys.argv[1:] if argv is None else argv
    parser = build_arg_parser(argparse.ArgumentParser(prog="python -m agents.rllib.train",
                                                      description=__doc__.splitlines()[0]))
    args = parser.parse_args(["--backend", "rllib", *argv])
    return run_and_report("agents.rllib.train", run_from_args, args)


if __name__ == "__main__":
    sys.exit(main())
