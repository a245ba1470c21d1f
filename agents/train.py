"""Train an SB3 agent (PPO, SAC or TD3) on an omni-gym environment; ``omni-gym train`` and ``python -m agents.train``.

    omni-gym train --algo ppo --env OmniPathFollow-Phunopas-v0 --timesteps 2000000 --seed 0 \\
                   --out agents/models/ppo-residual [--env-kwargs JSON] [--hyperparams FILE] [--n-envs N]
                   [--vec-env native|dummy|subproc] [--eval-freq STEPS] [--eval-episodes K] [--checkpoint-freq STEPS]
                   [--tensorboard DIR] [--progress | --no-progress] [--max-minutes M]

Hyperparameters come from ``agents/hyperparams/<algo>.yml`` in the RL Zoo's format, which
``python -m rl_zoo3.train --gym-packages omni_gym -conf FILE`` accepts as is: a top-level key per
environment id, with ``n_timesteps``, ``policy``, ``n_envs``, ``normalize`` (bool, or a string such as
``"{'norm_obs': True, 'norm_reward': False}"``), ``policy_kwargs`` (a mapping, or the RL Zoo's string
``"dict(net_arch=[64, 64], activation_fn=nn.Tanh)"``: read as data by :mod:`agents.policy_spec`, never
run), ``learning_rate`` (a number or ``lin_<x>`` for a linear schedule), ``noise_type`` /
``noise_std`` (TD3, SAC) and any other constructor argument of the algorithm, and:

* ``env_kwargs`` (dict): ``gym.make`` keywords for training (domain randomisation lives here);
  ``--env-kwargs`` is merged over them.
* ``env_wrapper``: a list of wrapper classes, innermost first, each a class path or
  ``{class path: {keyword: value}}``; this module knows ``agents.wrappers.SensorNoiseRandomizer``
  (``scale_range``: sensor noise scaled by U(lo, hi) per episode) and ``agents.wrappers.EKFFeatures``
  (``residual_scale`` > 0: ``residual-ekf-pid``, 0: ``ekf-features``; ``reward``: ``env``, ``tracking`` or
  ``squared``, :data:`agents.rewards.REWARDS`), in that order; or ``agents.rewards.TrackingReward``
  (keyword ``reward``) alone: the privileged agent's reward without the EKF.
* ``callback``: ``agents.callbacks.ResidualInit`` (``factor``: the actor's last layer is scaled by it
  and its bias zeroed at the start, so a residual policy starts as its baseline; ``log_std``: SAC's
  initial log std).

Files in the earlier layout (``env_wrapper`` a name of :data:`agents.wrappers.WRAPPERS` with the keys
``residual_scale``, ``reward``, ``sensor_noise_range``, ``residual_init``, ``init_log_std``) are still
read, and train the same agent; the RL Zoo refuses them.

The output directory receives ``policy.pt`` and ``normalisation.npz`` (the weights and observation
statistics of the checkpoint after step 0 with the lowest validation tracking RMSE, the final one if there is
no evaluation: :mod:`agents.weights`, what evaluation opens), the same checkpoint as SB3's ``model.zip`` and
``vecnormalize.pkl`` (pickles, to train further), ``final_model.zip``, ``final_vecnormalize.pkl``,
``meta.json`` (how to rebuild the environment and wrapper, the exact command, seed, git commit, timesteps,
wall time), ``curve.csv`` / ``curve.png`` (training curve: validation tracking RMSE and reward against
timesteps) and ``checkpoints/``.

Training environments (``--vec-env``, :func:`make_training_vec_env`): ``native`` (default) steps the
``n_envs`` robots in one native vector environment through :class:`agents.sb3_vec_env.NativeVecEnv`;
``dummy`` / ``subproc`` run one Monitor-wrapped single environment per robot in SB3's ``DummyVecEnv`` /
``SubprocVecEnv``. On ``native`` the EKF wrappers are :class:`agents.wrappers.VectorEKFFeatures` (the
batched EKF + PID) and the sensor-noise randomiser is the environment keyword ``randomize_sensor_noise``.
Without those two, native and dummy give the same training episodes (same seeds, same transitions, bit
for bit); with them, the same features within float rounding (batched EKF) but other noise draws.

Seeds: training environment i is reset first with ``seed + i`` (then unseeded, continuing its own
generator); validation episodes use seeds ``VALIDATION_SEED``…; the benchmarks use 10 000 and up, so
the three never share an episode.
"""

from __future__ import annotations

import argparse
import ast
import inspect
import io
import json
import math
import os
import shlex
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from agents import require_agents_extra
from agents.algorithms import ALGORITHMS, ALGOS, algorithm_class
from agents.options import (
    BACKENDS,
    MAX_BUFFER_MB,
    MAX_PARAMETERS,
    check_backend_args,
    check_hyperparams,
    check_train_args,
    check_training_size,
    parse_env_kwargs,
)
from agents.registry import Registry
from agents.rollout import make_env, run_episode
from agents.sb3_policy import VectorSB3Policy, wrap_vector_for
from agents.validation import (
    VALIDATION_EPISODES,
    VALIDATION_SEED,
    cell_episodes,
    episodes_per_cell,
    validation_cells,
    validation_seeds,
)
from agents.vector_rollout import make_vector_env
from agents.weights import export as export_weights
from agents.wrappers import wrap_env
from agents.zoo_config import WrapperSpec, bc_init_spec, residual_init, wrapper_spec
from omni_gym.envs.config import parse_model

HYPERPARAM_DIR = Path(__file__).resolve().parent / "hyperparams"
OWN_KEYS = ("n_timesteps", "policy", "n_envs", "normalize", "env_kwargs", "env_wrapper", "residual_scale", "reward",
            "sensor_noise_range", "residual_init", "init_log_std", "noise_type", "noise_std", "policy_kwargs",
            "learning_rate", "callback")


def shipped_hyperparams() -> list[str]:
    """The stems of the hyperparameter files shipped with the package (``agents/hyperparams/*.yml``), sorted."""
    return sorted(p.stem for p in HYPERPARAM_DIR.glob("*.yml"))


def hyperparams_path(algo: str, name: str | Path | None = None) -> Path:
    """The file ``--hyperparams NAME`` means: an existing path; else the shipped file of that stem
    (``ppo_residual`` → ``agents/hyperparams/ppo_residual.yml``, found in a checkout and after ``pip install``);
    None: ``agents/hyperparams/<algo>.yml``. ValueError naming the shipped stems when neither exists."""
    if name is None:
        return HYPERPARAM_DIR / f"{algo}.yml"
    path = Path(name)
    if path.exists():
        return path
    stem = str(name).removesuffix(".yml")
    if path.parent == Path(".") and stem in shipped_hyperparams():
        return HYPERPARAM_DIR / f"{stem}.yml"
    raise ValueError(f"--hyperparams {name}: no such file, nor a shipped hyperparameter file "
                     f"(shipped: {', '.join(shipped_hyperparams())})")


def _read_yaml(path: Path):
    """A YAML file's content; ValueError naming the file (:func:`omni_gym.io.read_yaml`: bounded, no
    aliases). Bytes go to PyYAML, which reads UTF-8 and, with a byte order mark, UTF-16 and UTF-32 (as the YAML
    specification allows)."""
    from omni_gym.io import read_yaml

    return read_yaml(path)


def files_holding(env_id: str) -> list[str]:
    """Stems of the shipped hyperparameter files with an entry for ``env_id`` (a file that does not read is
    skipped: this only feeds a hint)."""
    found = []
    for stem in shipped_hyperparams():
        try:
            data = _read_yaml(HYPERPARAM_DIR / f"{stem}.yml")
        except (ValueError, OSError):
            continue
        if isinstance(data, dict) and env_id in data:
            found.append(stem)
    return found


# Without --hyperparams, an id that ``<algo>.yml`` has no entry for trains with ``<algo>_<DEFAULT_KIND>.yml``
# when that file has one: the residual agent on ekf-pid starts at the scripted baseline, so it is the safe
# first agent on any robot (OmniPathFollow-Williams-v1, and OmniPathFollow-Custom-v0 built from a model file).
DEFAULT_KIND = "residual"


def default_hyperparams(algo: str, env_id: str, name: str | Path | None = None) -> str | Path | None:
    """The hyperparameter file ``train`` reads for ``env_id``: ``name`` when given; else None (``<algo>.yml``)
    when that file has an entry for the id; else the stem ``<algo>_residual`` when that shipped file has one;
    else None (:func:`load_hyperparams` then names the files that do)."""
    if name is not None:
        return name
    bare = env_id.rpartition(":")[2]
    holding = files_holding(bare)
    if algo in holding or f"{algo}_{DEFAULT_KIND}" not in holding:
        return None
    return f"{algo}_{DEFAULT_KIND}"


def load_hyperparams(algo: str, env_id: str, path: str | Path | None = None) -> dict:
    """The YAML entry for ``env_id`` in ``path`` (a file, or the stem of a shipped file; default
    ``agents/hyperparams/<algo>.yml``). ValueError naming the file (and key) on any problem; a missing
    entry names the shipped files that hold the id."""
    require_agents_extra("reading hyperparameter files")
    ALGORITHMS.check(algo)
    path = hyperparams_path(algo, path)
    data = _read_yaml(path)
    if not isinstance(data, dict):
        raise ValueError(f"{path}: must map environment ids to hyperparameters")
    bare = env_id.rpartition(":")[2]
    if bare not in data:
        holding = files_holding(bare)
        hint = (f"; choose one with --hyperparams NAME, e.g. --hyperparams {holding[0]} (shipped files with an "
                f"entry for it: {', '.join(holding)})" if holding else "; no shipped hyperparameter file has one")
        raise ValueError(f"{path}: no entry for {bare!r} (entries: {', '.join(map(str, data))}){hint}")
    hp = data[bare]
    if not isinstance(hp, dict):
        raise ValueError(f"{path}: key {bare!r}: must be a mapping of hyperparameters")
    return dict(hp)


def _policy_kwargs(text, where: str) -> dict:
    """SB3 ``policy_kwargs`` from a hyperparameter file's value: a mapping or an RL-Zoo string, read as data
    (:mod:`agents.policy_spec`: layer sizes, numbers and known class names such as ``nn.Tanh``; nothing runs)."""
    from agents.policy_spec import declarative, to_sb3

    return to_sb3(declarative(text, where))


def _learning_rate(value, where: str):
    if isinstance(value, str):
        if value.startswith("lin_"):
            start = float(value[4:])
            return lambda progress_remaining: progress_remaining * start
        try:
            return float(value)
        except ValueError:
            raise ValueError(f"{where}: learning_rate {value!r} must be a number or lin_<number>") from None
    return float(value)


def _normalize(value, where: str) -> dict | None:
    if value in (None, False):
        return None
    if value is True:
        return {}
    if isinstance(value, str):
        try:
            value = ast.literal_eval(value)
        except (ValueError, SyntaxError):
            raise ValueError(f"{where}: normalize {value!r} must be a bool or a dict string") from None
    if not isinstance(value, dict):
        raise ValueError(f"{where}: normalize must be a bool or a dict, got {value!r}")
    return dict(value)


def make_train_env(env_id: str, env_kwargs: dict, wrapper: str, residual_scale: float,
                   sensor_noise_range=None, reward: str = "env"):
    """One training/evaluation environment: :func:`agents.rollout.make_env` (with the obs mode the wrapper
    needs) and the wrapper."""

    kw = dict(env_kwargs)
    obs_mode = kw.pop("obs_mode", "sensors")  # "state": a privileged upper bound (no wrapper)
    env = make_env(env_id, kw, obs_mode=obs_mode)
    return wrap_env(env, wrapper, residual_scale, sensor_noise_range, reward)


class _EnvFactory:
    """Picklable environment constructor for SubprocVecEnv."""

    def __init__(self, env_id: str, env_kwargs: dict, wrapper: str, residual_scale: float, noise, reward) -> None:
        self.args = (env_id, env_kwargs, wrapper, residual_scale, noise, reward)

    def __call__(self):
        from stable_baselines3.common.monitor import Monitor

        import omni_gym  # noqa: F401

        return Monitor(make_train_env(*self.args))


# The SB3 vector environments training can run on (``--vec-env``), each with what it is.
VEC_ENV_KINDS: Registry[str] = Registry("vec_env", [
    ("native", "one native vector env of N robots (the batched EKF wrappers)"),
    ("dummy", "N single environments in this process (SB3's DummyVecEnv)"),
    ("subproc", "N single environments in worker processes (SB3's SubprocVecEnv)"),
])
VEC_ENVS = VEC_ENV_KINDS.names()


def make_training_vec_env(kind: str, env_id: str, env_kwargs: dict, spec: WrapperSpec, n: int, seed: int):
    """The SB3 vector env of ``n`` training environments, seeded (robot i: ``seed + i`` at the first reset).

    ``kind``: one of :data:`VEC_ENVS`; ``spec``: the wrapper stack of the hyperparameters. Returns
    ``(venv, kind used)``. The one place that builds training environments.

    ``native``: one native vector env in same_step autoreset mode; the EKF wrappers become
    :class:`agents.wrappers.VectorEKFFeatures` (the batched EKF + PID) and the sensor-noise randomiser
    the environment keyword ``randomize_sensor_noise`` (the same U(lo, hi) factor on every noise std per
    episode, drawn from the robot's generator instead of the wrapper's own, so a seed gives other
    episodes than on ``dummy``). ``dummy`` / ``subproc``: single environments, each wrapped as
    :func:`agents.wrappers.wrap_env` does.
    """
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv

    VEC_ENV_KINDS.check(kind)
    if kind == "native":
        from agents.sb3_vec_env import make_native_vec_env
        from agents.wrappers import wrap_vector_env

        kw = dict(env_kwargs)
        obs_mode = kw.pop("obs_mode", "sensors")  # as make_train_env: "state" is the privileged upper bound
        if spec.sensor_noise_range is not None:
            kw.setdefault("randomize_sensor_noise", tuple(spec.sensor_noise_range))
        # max_episode_steps=None: episodes end with the reference, as make_env matches the registered TimeLimit.
        venv = make_native_vec_env(env_id.rpartition(":")[2], n,
                                   wrap=lambda raw: wrap_vector_env(raw, spec.name, spec.residual_scale, spec.reward),
                                   obs_mode=obs_mode, action_mode="twist", max_episode_steps=None, **kw)
    else:
        factories = [_EnvFactory(env_id, env_kwargs, spec.name, spec.residual_scale, spec.sensor_noise_range,
                                 spec.reward) for _ in range(n)]
        venv = SubprocVecEnv(factories, start_method="spawn") if kind == "subproc" else DummyVecEnv(factories)
    venv.seed(seed)
    return venv, kind


def git_commit() -> str | None:
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], cwd=Path(__file__).resolve().parents[1],
                             capture_output=True, text=True, timeout=10)
        return out.stdout.strip() or None
    except (OSError, subprocess.SubprocessError):
        return None


def train(*args, force: bool = False, **kwargs) -> dict:
    """Train into the model directory ``out`` (arguments of :func:`train_into`); returns the meta dict.

    The directory is checked and locked before anything is imported or trained
    (:class:`omni_gym.outputs.Output`): an existing model directory is refused unless ``force``; an
    ``out`` that is the hyperparameter file (or a file named in ``env_kwargs``) is refused. Training
    writes into a temporary sibling ``.NAME.tmp-PID``, renamed to ``out`` at the end: an interrupted
    or killed training leaves the old directory (or none) in place.
    """
    return in_model_transaction(train_into, args, kwargs, force)


def in_model_transaction(train_into_fn: Callable[..., dict], args: tuple, kwargs: dict, force: bool) -> dict:
    """``train_into_fn(*args, **kwargs)`` writing into a temporary sibling of its ``out``, renamed to ``out``
    at the end (:class:`omni_gym.outputs.Output`); the hyperparameter file and any file named in
    ``env_kwargs`` are inputs ``out`` must not be. Both backends' ``train``."""
    from omni_gym.outputs import Output

    bound = inspect.signature(train_into_fn).bind(*args, **kwargs)
    kw = bound.arguments.get("env_kwargs")
    inputs = [bound.arguments.get("hyperparams"),
              *(v for v in (kw.values() if isinstance(kw, dict) else ()) if isinstance(v, str))]
    with Output(Path(bound.arguments["out"]), "dir", force=force, inputs=inputs, marker="meta.json",
                what="model directory") as tx:
        bound.arguments["out"] = tx.path
        return train_into_fn(*bound.args, **bound.kwargs)


def _check_bc(bc_spec, algo: str, spec: WrapperSpec, obs_mode: str | None, where: str) -> None:
    """A behaviour-cloning warm start needs PPO or SAC and the observation its teacher reads: the law the
    ``state`` observation with no wrapper; ekf-pid the EKF features with the whole-twist action."""
    if algo not in ("ppo", "sac"):
        raise ValueError(f"{where}: callback: BehaviourCloningInit needs ppo or sac, got {algo}")
    if bc_spec.teacher == "law" and (spec.name != "none" or obs_mode != "state"):
        raise ValueError(f"{where}: callback: BehaviourCloningInit with teacher 'law' clones the true-state law: it "
                         "needs obs_mode 'state' and no EKF or feed-forward wrapper")
    if bc_spec.teacher == "ekf-pid" and (spec.name != "ekf-features" or spec.residual_scale != 0):
        raise ValueError(f"{where}: callback: BehaviourCloningInit with teacher 'ekf-pid' reads the EKF features: it "
                         "needs the EKFFeatures wrapper with residual_scale 0 (the agent gives the whole twist)")


def train_into(algo: str, env_id: str, timesteps: int | None, seed: int, out: str | Path,
               env_kwargs: dict | None = None, hyperparams: str | Path | None = None, n_envs: int | None = None,
               vec_env: str = "native", eval_freq: int = 50_000, eval_episodes: int = VALIDATION_EPISODES,
               checkpoint_freq: int = 0,
               tensorboard: str | None = None, progress: bool | None = None, max_minutes: float | None = None,
               command: str | None = None, threads: int = 1, max_parameters: int | None = None,
               max_buffer_mb: float | None = None) -> dict:
    """Train and save into ``out`` directly (no transaction: :func:`train` gives one); returns the meta
    dict written to ``out/meta.json``.

    Args: see the module docstring; ``eval_freq`` and ``checkpoint_freq`` count environment steps over
    all environments (0 disables); ``max_minutes`` stops training early (the meta says so).
    """
    require_agents_extra("training")
    import torch
    from stable_baselines3.common.noise import NormalActionNoise
    from stable_baselines3.common.vec_env import VecNormalize

    from agents.callbacks import init_residual

    ALGORITHMS.check(algo)
    VEC_ENV_KINDS.check(vec_env)
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    if env_kwargs is not None and not isinstance(env_kwargs, dict):
        raise ValueError(f"env_kwargs must be a dict (a JSON object), got {env_kwargs!r}")
    hyperparams = default_hyperparams(algo, env_id, hyperparams)
    where = str(hyperparams_path(algo, hyperparams))
    raw_hp = load_hyperparams(algo, env_id, hyperparams)
    hp = check_hyperparams(raw_hp, where, algo)  # numbers in their bounds before the library sees them
    n_timesteps = int(float(timesteps if timesteps is not None else hp.get("n_timesteps", 0)))
    if n_timesteps < 1:
        raise ValueError(f"timesteps must be >= 1, got {n_timesteps} (--timesteps or n_timesteps in {where})")
    n = int(n_envs if n_envs is not None else hp.get("n_envs", 1))
    if n < 1:
        raise ValueError(f"n_envs must be >= 1, got {n}")
    kw = dict(hp.get("env_kwargs") or {})
    kw.update(env_kwargs or {})
    if isinstance(kw.get("model"), (str, os.PathLike)):
        # The model file's content, not its path, goes into the run and meta.json: a trained agent
        # must evaluate the same from any folder, and after the report it came from is replaced.
        kw["model"] = parse_model(kw["model"]).to_json()
    spec = wrapper_spec(hp, where)
    wrapper, residual_scale, noise = spec.name, spec.residual_scale, spec.sensor_noise_range
    init_factor, init_log_std, init_warmup = residual_init(hp, where)
    bc_spec = bc_init_spec(hp, where)
    if bc_spec is not None:
        _check_bc(bc_spec, algo, spec, dict(hp.get("env_kwargs") or {}, **(env_kwargs or {})).get("obs_mode"), where)
    norm = _normalize(hp.get("normalize"), where)
    extra = {k: v for k, v in hp.items() if k not in OWN_KEYS}
    if isinstance(threads, bool) or not isinstance(threads, int) or threads < 1:
        raise ValueError(f"threads must be an integer >= 1, got {threads!r}")
    if max_minutes is not None and not (isinstance(max_minutes, (int, float)) and max_minutes > 0):
        raise ValueError(f"max_minutes must be a number > 0 (or None), got {max_minutes!r}")
    torch.set_num_threads(threads)

    # Build one env in this process first: bad kwargs or wrapper fail here with a clear ValueError
    # (before anything is written).
    reward = spec.reward
    probe = make_train_env(env_id, kw, wrapper, residual_scale, noise, reward)
    probe.close()
    # The networks' and buffer's sizes within the limits (agents.options) before any of them is allocated.
    from agents.policy_spec import declarative

    check_training_size(hp, declarative(hp.get("policy_kwargs"), f"{where}: policy_kwargs"), algo, n,
                        int(np.prod(probe.observation_space.shape)), int(np.prod(probe.action_space.shape)), where,
                        max_parameters, max_buffer_mb)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    venv, vec_env = make_training_vec_env(vec_env, env_id, kw, spec, n, seed)
    if norm is not None:
        venv = VecNormalize(venv, gamma=float(hp.get("gamma", 0.99)), **norm)

    cls = algorithm_class(algo)
    args = dict(extra)
    args["policy_kwargs"] = _policy_kwargs(hp.get("policy_kwargs"), where)
    if "learning_rate" in hp:
        args["learning_rate"] = _learning_rate(hp["learning_rate"], where)
    if hp.get("noise_type") is not None:
        if hp["noise_type"] != "normal":
            raise ValueError(f"{where}: noise_type {hp['noise_type']!r}: only 'normal' is supported")
        dim = venv.action_space.shape[0]
        args["action_noise"] = NormalActionNoise(np.zeros(dim), float(hp.get("noise_std", 0.1)) * np.ones(dim))
    try:
        model = cls(hp.get("policy", "MlpPolicy"), venv, seed=seed, device="cpu", verbose=0,
                    tensorboard_log=tensorboard, **args)
    except TypeError as exc:
        raise ValueError(f"{where}: bad hyperparameter for {algo}: {exc}") from None
    if init_factor is not None:
        init_residual(model, init_factor, init_log_std)
    bc_summary = None
    if bc_spec is not None:  # supervised warm start on the feedback law; the agent still outputs the full twist
        from agents.behaviour_cloning import behaviour_clone

        bc_summary = behaviour_clone(model, venv, bc_spec, seed)

    meta = {
        "backend": "sb3", "algo": algo, "env_id": env_id, "train_env_kwargs": kw, "wrapper": wrapper,
        "residual_scale": residual_scale,
        "sensor_noise_range": noise, "obs_mode": kw.get("obs_mode", "sensors"), "seed": seed, "n_envs": n,
        "vec_env": vec_env, "reward": reward,
        "hyperparams_file": os.path.relpath(where, Path(__file__).resolve().parents[1]) if hyperparams is None
        else str(hyperparams), "hyperparams": raw_hp, "requested_timesteps": n_timesteps,
        "vecnormalize": "vecnormalize.pkl" if norm is not None else None, "model": "model.zip",
        "sb3_model": "model.zip",  # SB3's checkpoint (a pickle) to train further; "model" becomes the weights
        "command": command, "git_commit": git_commit(), "torch_threads": torch.get_num_threads(),
    }
    if bc_summary is not None:
        meta["bc_init"] = bc_summary
    # Validation (agents.validation): every training floor, with and without lift-off where the training
    # randomises it, nominal otherwise; ``eval_episodes`` spread over those cells, the same seeds in each.
    cells = validation_cells(kw)
    per_cell = episodes_per_cell(eval_episodes, len(cells))
    meta["validation_env_kwargs"] = cells[0]
    meta["validation_cells"] = cells
    meta["validation_seeds"] = [VALIDATION_SEED, VALIDATION_SEED + per_cell - 1] if eval_freq > 0 else None
    meta["validation_episodes"] = per_cell * len(cells) if eval_freq > 0 else 0

    def validation_envs() -> list:
        return [wrap_vector_for(make_vector_env(env_id, per_cell, c, obs_mode=meta["obs_mode"]), meta) for c in cells]

    callback = _Training(out, meta, env_id, eval_freq, checkpoint_freq, n_timesteps, progress,
                         max_minutes, validation_envs)
    callbacks = [callback]
    warmup = bc_spec.actor_warmup if bc_spec is not None else init_warmup
    if warmup:
        from agents.callbacks import HoldActor

        callbacks.append(HoldActor(warmup))
    rollout = int(getattr(model, "n_steps", 0) or 0) * int(getattr(model, "n_envs", 1) or 1)
    if rollout and n_timesteps % rollout:  # on-policy algorithms collect whole rollouts: say what will run
        ran = -(-n_timesteps // rollout) * rollout
        print(f"note: --timesteps {n_timesteps} rounds up to {ran}, whole rollouts of {rollout} steps (n_steps "
              f"{model.n_steps} x n_envs {model.n_envs}); meta.json records the steps run as timesteps",
              file=sys.stderr)
    t0 = time.time()
    try:
        model.learn(total_timesteps=n_timesteps, callback=callbacks, progress_bar=False,
                    tb_log_name=f"{algo}_{seed}")
    finally:
        callback.close()
        venv.close()
    wall = time.time() - t0
    model.save(out / "final_model.zip")
    if norm is not None:
        if not callback.best_saved:
            venv.save(str(out / "vecnormalize.pkl"))
        venv.save(str(out / "final_vecnormalize.pkl"))
    if not callback.best_saved:
        model.save(out / "model.zip")
        meta.update(export_weights(model, venv if norm is not None else None, out))
    else:
        meta.update(callback.exported)
    meta.update(timesteps=int(model.num_timesteps), wall_time_s=round(wall, 1), stopped_early=callback.stopped,
                best=callback.best, curve=callback.rows)
    _write_json(out / "meta.json", {k: v for k, v in meta.items() if k != "curve"})
    callback.write_curve()
    return meta


def _write_json(path: Path, data: dict) -> None:
    from omni_gym.outputs import write_text_atomic

    write_text_atomic(path, json.dumps(data, indent=2, default=str) + "\n")


def _Training(*args, **kwargs):
    """The training callback (:class:`_TrainingMixin` on SB3's BaseCallback; imported late: SB3 takes seconds)."""
    from stable_baselines3.common.callbacks import BaseCallback

    cls = type("TrainingCallback", (_TrainingMixin, BaseCallback), {})
    return cls(*args, **kwargs)


class _TrainingMixin:
    """Progress bar, periodic validation (tracking RMSE on fixed seeds, best model kept), checkpoints, time limit."""

    def __init__(self, out: Path, meta: dict, env_id: str, eval_freq: int, checkpoint_freq: int,
                 total: int, progress: bool | None, max_minutes: float | None, base_env) -> None:
        super().__init__()
        self.out, self.meta, self.env_id = out, meta, env_id
        self.eval_freq, self.checkpoint_freq = eval_freq, checkpoint_freq  # the episodes: base_env's cells
        self.total, self.max_minutes = total, max_minutes
        self.show = progress if progress is not None else sys.stderr.isatty()
        self.rows: list[dict] = []
        self.best: dict | None = None
        self.best_saved = False
        self.exported: dict = {}
        self.stopped = False
        self._base_env = base_env
        self._eval_env = None
        self._next_eval = 0
        self._next_ckpt = checkpoint_freq
        self._bar = None
        self._t0 = time.time()

    def _on_training_start(self) -> None:
        from tqdm import tqdm

        self._t0 = time.time()
        self._bar = tqdm(total=self.total, desc=f"train {self.meta['algo']}", file=sys.stderr, unit="step",
                         disable=not self.show, smoothing=0.05)
        if self.eval_freq > 0:
            self._validate()  # the untrained policy (for a residual agent: the baseline)
            self._next_eval = self.eval_freq

    def _on_step(self) -> bool:
        steps = self.num_timesteps
        if self._bar is not None:
            self._bar.update(steps - self._bar.n)
        if self.eval_freq > 0 and steps >= self._next_eval:
            self._validate()
            self._next_eval += self.eval_freq
        if self.checkpoint_freq > 0 and steps >= self._next_ckpt:
            (self.out / "checkpoints").mkdir(exist_ok=True)
            self.model.save(self.out / "checkpoints" / f"model_{steps}.zip")
            self._next_ckpt += self.checkpoint_freq
        if self.max_minutes is not None and time.time() - self._t0 > 60.0 * self.max_minutes:
            self.stopped = True
            return False
        return True

    def _validate(self) -> None:
        if self._eval_env is None:  # all validation episodes at once, as robots of one native vector env
            self._eval_env = self._base_env()
        vn = self.model.get_vec_normalize_env()
        row = validation_row_vector(self._eval_env, [VectorSB3Policy(self.model, vn, e) for e in self._eval_env],
                                    int(self.num_timesteps), time.time() - self._t0, self._train_reward())
        self.rows.append(row)
        rmse = row["val_tracking_rmse"]
        # The untrained policy (step 0) is a reference point on the curve, not a candidate; a behaviour-cloned
        # one (meta "bc_init") is a trained policy and is.
        candidate = self.num_timesteps > 0 or "bc_init" in self.meta
        if candidate and (self.best is None or rmse < self.best["val_tracking_rmse"]):
            self.best = dict(row)
            self.model.save(self.out / "model.zip")
            if vn is not None:
                vn.save(str(self.out / "vecnormalize.pkl"))
            self.exported = export_weights(self.model, vn, self.out)  # what evaluation opens: no pickle
            self.best_saved = True
        self.write_curve()
        if self._bar is not None and self.show:
            # No best before the first trained validation (step 0 is a reference point, not a candidate).
            best = "-" if self.best is None else f"{self.best['val_tracking_rmse']:.4f}"
            self._bar.set_postfix(val_rmse=f"{rmse:.4f}", best=best)
        print_progress(row, self.show)

    def _train_reward(self) -> float | None:
        buf = getattr(self.model, "ep_info_buffer", None)
        if not buf:
            return None
        return float(np.mean([e["r"] for e in buf]))

    def write_curve(self) -> None:
        """curve.csv and curve.png (:func:`write_curve`)."""
        write_curve(self.out, self.rows, self.meta)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
        for env in self._eval_env or []:
            env.close()


CURVE_COLUMNS = ("timesteps", "wall_s", "val_tracking_rmse", "val_final_error", "val_success", "train_ep_reward")


def validation_row(env, policy, episodes: int, timesteps: int, wall_s: float, train_reward: float | None) -> dict:
    """One row of the training curve: ``policy`` on ``episodes`` validation episodes of ``env`` (seeds
    ``VALIDATION_SEED``…). Keys :data:`CURVE_COLUMNS`: ``timesteps`` (environment steps so far),
    ``wall_s`` [s] since training started, the mean validation tracking RMSE and final position error [m],
    the success fraction, and ``train_ep_reward`` (the backend's mean training episode return, or None).
    Every backend validates through this function, so their curves compare."""
    eps = [run_episode(env, policy, seed) for seed in validation_seeds(episodes)]
    return _curve_row(eps, timesteps, wall_s, train_reward)


def validation_row_vector(venvs, policies, timesteps: int, wall_s: float, train_reward: float | None) -> dict:
    """:func:`validation_row` over the validation cells (:mod:`agents.validation`), each cell's episodes run
    as the robots of one native vector env (``venvs[c]``, robot i from seed ``VALIDATION_SEED`` + i; its
    vector actor ``policies[c]``): within one cell, the single-env episodes within float rounding (the batched
    EKF, ``tests/test_vector_rollout.py``), in a fraction of the time. The means are over all episodes."""
    eps = [e for cell in cell_episodes(venvs, policies) for e in cell]
    return _curve_row(eps, timesteps, wall_s, train_reward)


def _curve_row(eps, timesteps: int, wall_s: float, train_reward: float | None) -> dict:
    return {"timesteps": int(timesteps), "wall_s": round(wall_s, 1),
            "val_tracking_rmse": float(np.mean([e.tracking_rmse for e in eps])),
            "val_final_error": float(np.mean([e.final_position_error for e in eps])),
            "val_success": float(np.mean([e.success for e in eps])),
            "train_ep_reward": None if train_reward is None else float(train_reward)}


def print_progress(row: dict, to_stderr: bool) -> None:
    """A validation row as one JSON line: on stderr above a progress bar, else on stdout (also when piped)."""
    if to_stderr:
        from tqdm import tqdm

        tqdm.write(json.dumps(row), file=sys.stderr)  # clears the bar, writes the line, redraws the bar
    else:
        print(json.dumps(row), flush=True)


def write_curve(out: Path, rows: list[dict], meta: dict) -> None:
    """``out/curve.csv`` and ``out/curve.png`` (validation tracking RMSE and training episode reward vs
    timesteps) from :func:`validation_row` rows; nothing without rows."""
    if not rows:
        return
    from omni_gym.io import write_csv_atomic

    data = np.array([[math.nan if r[c] is None else r[c] for c in CURVE_COLUMNS] for r in rows], dtype=float)
    write_csv_atomic(out / "curve.csv", list(CURVE_COLUMNS), data)
    _plot_curve(out / "curve.png", data, meta)


def _zero_based(ax, values: np.ndarray) -> None:
    """Y range from zero to the data (or from the data to zero): a 1 % change then looks like 1 %, not like
    a cliff across an axis zoomed to the data's own span."""
    v = values[np.isfinite(values)]
    if v.size == 0:
        return
    lo, hi = min(0.0, float(v.min())), max(0.0, float(v.max()))
    pad = 0.05 * (hi - lo) or 1.0
    ax.set_ylim(lo - (pad if lo < 0 else 0.0), hi + (pad if hi > 0 else 0.0))


def _plot_curve(path: Path, data: np.ndarray, meta: dict) -> None:
    import matplotlib.pyplot as plt

    from omni_gym.outputs import write_bytes_atomic

    fig = curve_figure(data, meta)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    plt.close(fig)
    write_bytes_atomic(path, buf.getvalue())


def curve_figure(data: np.ndarray, meta: dict):
    """The figure of ``curve.png``: validation tracking RMSE [m] (axis from 0) and the training episode return
    of the training reward named with its formula (axis to 0), against timesteps; ``data`` rows in
    :data:`CURVE_COLUMNS` order."""
    os.environ.setdefault("MPLBACKEND", "Agg")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from agents.rewards import REWARDS

    reward = meta.get("reward", "env")
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.2), layout="constrained")
    ax[0].plot(data[:, 0], data[:, 2], "o-", ms=3)
    ax[0].set_xlabel("timesteps")
    ax[0].set_ylabel("validation tracking RMSE [m]")
    ax[0].set_title("validation: mean over the validation episodes (lower is better)", fontsize=9)
    _zero_based(ax[0], data[:, 2])
    ax[0].grid(alpha=0.3)
    ax[1].plot(data[:, 0], data[:, 5], "o-", ms=3, color="C1")
    ax[1].set_xlabel("timesteps")
    ax[1].set_ylabel("training episode return (no unit)")
    ax[1].set_title(f"training reward '{reward}' per control step, e: tracking error, a: action\n"
                    f"{REWARDS.get(reward) if reward in REWARDS else reward}\n"
                    "summed over an episode; mean of the last 100 episodes (higher is better)", fontsize=8)
    _zero_based(ax[1], data[:, 5])
    ax[1].set_xlim(ax[0].get_xlim())  # the same steps under each other
    ax[1].grid(alpha=0.3)
    algo = meta["algo"] if meta.get("backend", "sb3") == "sb3" else f"{meta['backend']} {meta['algo']}"
    fig.suptitle(f"{algo} / {meta['wrapper']} on {meta['env_id']} (seed {meta['seed']})")
    return fig


def build_arg_parser(parser: argparse.ArgumentParser | None = None) -> argparse.ArgumentParser:
    """Arguments of ``omni-gym train`` (also used by ``python -m agents.train``)."""
    p = parser or argparse.ArgumentParser(prog="python -m agents.train", description=__doc__.splitlines()[0])
    p.add_argument("--backend", choices=BACKENDS, default="sb3",
                   help="sb3 (Stable-Baselines3; default) or rllib (Ray RLlib PPO, agents/rllib; needs the rllib "
                        "extra)")
    p.add_argument("--algo", default=None, choices=ALGOS,
                   help="SB3 algorithm (required with --backend sb3; rllib trains ppo)")
    p.add_argument("--env", required=True, help="environment id, e.g. OmniPathFollow-Phunopas-v0")
    p.add_argument("--timesteps", type=float, default=None,
                   help="environment steps, 1 to 1e9 (default: n_timesteps in YAML)")
    p.add_argument("--seed", type=int, default=0, help="training seed, 0 to 2^31 - 1 (default 0)")
    p.add_argument("--out", required=True, help="output directory (model.zip, meta.json, curve.csv, ...)")
    p.add_argument("--env-kwargs", default=None, help="gym.make keywords as a JSON object (merged over the YAML's)")
    p.add_argument("--hyperparams", default=None,
                   help="YAML file, or the name of a shipped one: ppo, ppo_residual, sac_privileged, ... (the files "
                        "of agents/hyperparams; default: <algo>)")
    p.add_argument("--n-envs", type=int, default=None, help="parallel environments (default: n_envs in YAML)")
    p.add_argument("--vec-env", choices=VEC_ENVS, default="native",
                   help="vectorisation: native (one vector env of all robots; default), dummy or subproc (one "
                        "single env per robot)")
    p.add_argument("--eval-freq", type=int, default=50_000, help="validation every N steps (0: none; default 50000)")
    p.add_argument("--eval-episodes", type=int, default=None,
                   help=f"validation episodes, spread over the training floors (default {VALIDATION_EPISODES}; "
                        "rllib: 5, run one by one)")
    p.add_argument("--checkpoint-freq", type=int, default=0, help="checkpoint every N steps (0: none)")
    p.add_argument("--tensorboard", default=None, help="TensorBoard log directory (needs tensorboard)")
    p.add_argument("--max-minutes", type=float, default=None,
                   help="stop training after this wall time [min], > 0 (default: no limit)")
    p.add_argument("--threads", type=int, default=1, help="torch threads, >= 1 (default 1)")
    p.add_argument("--address", default=None,
                   help="rllib: a running Ray cluster's address HOST:PORT (default: start a local Ray for the run)")
    p.add_argument("--num-env-runners", type=int, default=None,
                   help="rllib: env runner actors, each stepping --n-envs robots in one native vector env "
                        "(default 0: sample in the training process)")
    p.add_argument("--max-parameters", type=float, default=None,
                   help=f"most network parameters, all networks together (default {MAX_PARAMETERS:.0e}); checked "
                        "before anything is built")
    p.add_argument("--max-buffer-mb", type=float, default=None,
                   help=f"most memory [MB] of the rollout or replay buffer and a batch (default {MAX_BUFFER_MB:g}); "
                        "checked before anything is built")
    p.add_argument("--force", action="store_true",
                   help="replace an existing model directory (default: refuse; the directory appears complete "
                        "or not at all, see docs/formats.md)")
    bar = p.add_mutually_exclusive_group()
    bar.add_argument("--progress", dest="progress", action="store_true", default=None, help="always show the bar")
    bar.add_argument("--no-progress", dest="progress", action="store_false", help="never show the bar")
    return p


def command_line(prog: str, args: argparse.Namespace) -> str:
    """The full command (every option spelled out) that reproduces ``args``; recorded in meta.json."""
    backend = getattr(args, "backend", "sb3")
    parts = [prog, *(["--backend", backend] if backend != "sb3" else []), "--algo", args.algo or "ppo",
             "--env", args.env]
    if args.timesteps is not None:
        parts += ["--timesteps", str(int(args.timesteps))]
    parts += ["--seed", str(args.seed), "--out", args.out]
    for opt, value in (("--env-kwargs", args.env_kwargs), ("--hyperparams", args.hyperparams),
                       ("--n-envs", args.n_envs), ("--tensorboard", args.tensorboard),
                       ("--max-minutes", args.max_minutes), ("--address", getattr(args, "address", None)),
                       ("--num-env-runners", getattr(args, "num_env_runners", None)),
                       ("--max-parameters", getattr(args, "max_parameters", None)),
                       ("--max-buffer-mb", getattr(args, "max_buffer_mb", None))):
        if value is not None:
            parts += [opt, str(value)]
    parts += ["--vec-env", args.vec_env, "--eval-freq", str(args.eval_freq)]
    if args.eval_episodes is not None:
        parts += ["--eval-episodes", str(args.eval_episodes)]
    parts += ["--checkpoint-freq", str(args.checkpoint_freq), "--threads", str(args.threads)]
    from omni_gym.record_paths import record_args  # a machine's absolute paths are not recorded

    return " ".join([prog, *(shlex.quote(x) for x in record_args(parts[1:]))])


def run_from_args(args: argparse.Namespace, command: str | None = None) -> dict:
    """Validate parsed arguments (:mod:`agents.options`) and call :func:`train`."""

    check_train_args(args)  # before anything is locked, read or written
    check_backend_args(args)
    if getattr(args, "backend", "sb3") != "sb3":
        raise ValueError("--backend rllib trains through omni-gym train or python -m agents.rllib.train")
    require_agents_extra("omni-gym train")
    kwargs = parse_env_kwargs(args.env_kwargs)
    if args.tensorboard is not None:
        try:
            import tensorboard  # noqa: F401
        except ImportError:
            raise ValueError("--tensorboard needs the tensorboard package (pip install tensorboard)") from None
    command = command or command_line("python -m agents.train", args)
    return train(args.algo, args.env, None if args.timesteps is None else int(args.timesteps), args.seed, args.out,
                 kwargs, args.hyperparams, args.n_envs, args.vec_env, args.eval_freq,
                 VALIDATION_EPISODES if args.eval_episodes is None else args.eval_episodes,
                 args.checkpoint_freq, args.tensorboard, args.progress, args.max_minutes, command, args.threads,
                 _int_or_none(getattr(args, "max_parameters", None)), getattr(args, "max_buffer_mb", None),
                 force=getattr(args, "force", False))


def _int_or_none(value) -> int | None:
    return None if value is None else int(value)


def main(argv: list[str] | None = None) -> int:
    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    argv = sys.argv[1:] if argv is None else argv
    args = build_arg_parser().parse_args(argv)
    return run_and_report("agents.train", run_from_args, args)


def run_and_report(prog: str, run: Callable[[argparse.Namespace], dict], args: argparse.Namespace) -> int:
    """``run(args)`` (a training), then its one-line summary; exit status 0, or 2 with a one-line error
    on stderr for bad input (ImportError: a missing extra, named in one line). Both trainers' ``main``."""
    try:
        meta = run(args)
    except (ValueError, OSError, ImportError) as exc:
        print(f"{prog}: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    best = meta.get("best") or {}
    print(f"trained {meta['timesteps']} steps in {meta['wall_time_s']:.0f} s; best validation tracking RMSE "
          f"{best.get('val_tracking_rmse', float('nan')):.4f} m at {best.get('timesteps')} steps -> {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
