"""Bounds of the numeric command-line options of ``omni-gym train`` and ``omni-gym evaluate``, and of the
numeric keys of a hyperparameter file.

``docs/bounds.md`` (section "Command-line options", ``train`` and ``evaluate``) shows these tables as
rendered by :func:`omni_gym.bounds.markdown_table` (a test compares them). Every option is checked
before any work starts, so a bad value never reaches training or an output directory.
"""

from __future__ import annotations

import argparse

from agents.registry import Registry
from omni_gym.bounds import Bound

SEED_MAX = 2**31 - 1  # SB3 seeds numpy's legacy generator (< 2^32) with seed + i for environment i

TRAIN: dict[str, Bound] = {b.name: b for b in (
    Bound("--timesteps", 1, 1e9, "steps", "at least one step; the committed agent trained at 450 steps/s "
          "(1.5·10⁶ steps in 55 min), so 10⁹ steps is almost a month: a larger number is a typo", integer=True),
    Bound("--seed", 0, SEED_MAX, "", "SB3 seeds numpy's legacy generator, which takes < 2³², with "
          "seed + i for environment i; 2³¹ − 1 leaves room for any --n-envs", integer=True),
    Bound("--n-envs", 1, 256, "", "parallel environments, each a simulation (a process with "
          "--vec-env subproc); more than 256 exceeds any machine this runs on", integer=True),
    Bound("--eval-freq", 0, 1e9, "steps", "0 disables validation; at most --timesteps' bound", integer=True),
    Bound("--eval-episodes", 1, 1000, "", "validation episodes per evaluation; each costs an episode "
          "of simulation, 1000 would dwarf the training", integer=True),
    Bound("--checkpoint-freq", 0, 1e9, "steps", "0 disables checkpoints; at most --timesteps' bound",
          integer=True),
    Bound("--max-minutes", 0.0, 43200.0, "min", "wall-time limit: must be > 0 (a limit of 0 or less "
          "would train nothing yet write a model); 30 days is longer than any run", lo_open=True),
    Bound("--threads", 1, 1024, "", "torch threads: at least one (torch refuses 0, which was silently "
          "replaced by 1); 1024 exceeds any machine's cores", integer=True),
    Bound("--num-env-runners", 0, 1024, "", "RLlib env runner actors (0: sample in the training process); "
          "each needs a CPU of the Ray cluster, 1024 exceeds any cluster this runs on", integer=True),
)}

# The training backends (``--backend``); argparse refuses other names with its own message.
TRAINING_BACKENDS: Registry[str] = Registry("backend", [
    ("sb3", "Stable-Baselines3 (PPO, SAC, TD3), in this process"),
    ("rllib", "RLlib PPO on Ray (agents/rllib)"),
])
BACKENDS = TRAINING_BACKENDS.names()
# Options that only one backend reads: option -> (attribute, backend). Given with the other, they are refused.
BACKEND_ONLY = {"--address": ("address", "rllib"), "--num-env-runners": ("num_env_runners", "rllib"),
                "--tensorboard": ("tensorboard", "sb3")}

EVALUATE: dict[str, Bound] = {b.name: b for b in (
    Bound("--episodes", 1, 100_000, "", "at least one episode; 10⁵ episodes of 20 s is days of "
          "simulation, so a larger number is a typo", integer=True),
    Bound("--seed", 0, 2**53, "", "episode i uses seed + i; seeds are written to JSON, whose readers "
          "keep integers exact up to 2^53", integer=True),
    Bound("--residual-scale", 0.0, 1.0, "", "fraction of the action range a residual agent may add to "
          "the PID's twist (agents.wrappers.EKFFeatures)"),
)}


# Numeric keys of a hyperparameter entry (agents/hyperparams/*.yml), checked before the library sees them:
# Stable-Baselines3 answers a bad one with an assertion, a numpy error or a traceback that names no key.
HYPERPARAMS: dict[str, Bound] = {b.name: b for b in (
    Bound("n_timesteps", 1, 1e9, "steps", "as --timesteps", integer=True),
    Bound("n_envs", 1, 256, "", "as --n-envs", integer=True),
    Bound("n_steps", 1, 1e6, "steps", "PPO: steps per environment per rollout; the rollout buffer holds "
          "n_steps × n_envs transitions in memory (committed files: 256 to 1024)", integer=True),
    Bound("batch_size", 1, 1e6, "", "transitions per gradient step (committed files: 256 to 4096)", integer=True),
    Bound("n_epochs", 1, 1000, "", "PPO: passes over each rollout (committed files: 5 to 10)", integer=True),
    Bound("gamma", 0.0, 1.0, "", "discount factor per control step (10 ms)"),
    Bound("gae_lambda", 0.0, 1.0, "", "PPO: GAE weighting"),
    Bound("clip_range", 0.0, 10.0, "", "PPO: policy ratio clip; > 0", lo_open=True),
    Bound("target_kl", 0.0, 100.0, "", "PPO: KL divergence that stops an update early; > 0", lo_open=True),
    Bound("vf_coef", 0.0, 1e3, "", "PPO: weight of the value loss"),
    Bound("ent_coef", 0.0, 1e3, "", "weight of the entropy bonus (SAC also: auto or auto_<initial value>)"),
    Bound("max_grad_norm", 0.0, 1e6, "", "gradient norm clip; > 0", lo_open=True),
    Bound("buffer_size", 1, 1e8, "transitions", "SAC, TD3: the replay buffer is allocated at the start "
          "(committed files: 3·10⁵ to 10⁶); 10⁸ transitions are tens of GB", integer=True),
    Bound("learning_starts", 0, 1e9, "steps", "SAC, TD3: random steps before learning", integer=True),
    Bound("tau", 0.0, 1.0, "", "SAC, TD3: soft target update factor"),
    Bound("gradient_steps", -1, 1e6, "", "SAC, TD3: per rollout (−1: as many as steps collected)", integer=True),
    Bound("policy_delay", 1, 1e6, "", "TD3: critic updates per actor update", integer=True),
    Bound("target_policy_noise", 0.0, 10.0, "", "TD3: target smoothing noise std (actions in [−1, 1])"),
    Bound("target_noise_clip", 0.0, 10.0, "", "TD3: target smoothing noise clip"),
    Bound("noise_std", 0.0, 10.0, "", "TD3, SAC with noise_type normal: exploration noise std (actions in "
          "[−1, 1])"),
    Bound("learning_rate", 0.0, 1.0, "", "a number or lin_<number> (linear schedule from it to 0); > 0",
          lo_open=True),
)}
# Keys that also take a word (SB3's own spelling), and the algorithms that read it: SAC's automatic entropy
# coefficient (``auto`` or ``auto_<initial value>``) and target entropy (``auto``).
HYPERPARAM_WORDS = {"ent_coef": ("sac",), "target_entropy": ("sac",)}


def _auto(value) -> bool:
    if value == "auto":
        return True
    try:
        return isinstance(value, str) and value.startswith("auto_") and float(value[5:]) > 0
    except ValueError:
        return False


def _number(value, key: str, where: str) -> float:
    """A YAML value as a number: int/float, or a string that reads as one (PyYAML reads ``1e-3`` as a string)."""
    if isinstance(value, bool):
        raise ValueError(f"{where}: {key}: must be a number, got {value!r}")
    if isinstance(value, (int, float)):
        return value
    if isinstance(value, str):
        try:
            return float(value)
        except ValueError:
            pass
    raise ValueError(f"{where}: {key}: must be a number, got {value!r}")


def check_hyperparams(hp: dict, where: str, algo: str = "ppo") -> dict:
    """The entry with every key of :data:`HYPERPARAMS` checked against its bound and made a number (an int for
    integer bounds); ValueError ``FILE: KEY must be … in [lo, hi], got V`` on the first bad one.

    ``learning_rate`` may be ``lin_<x>`` (x checked); with ``algo`` sac, ``ent_coef`` ``auto`` or ``auto_<x>``
    and ``target_entropy`` ``auto``; other keys pass unchanged (the algorithm's constructor refuses unknown ones).
    """
    out = dict(hp)
    for key, value in hp.items():
        if algo in HYPERPARAM_WORDS.get(key, ()) and _auto(value):
            continue
        if key == "learning_rate" and isinstance(value, str) and value.startswith("lin_"):
            HYPERPARAMS[key].check(_number(value[4:], key, where), f"{where}: {key} lin_<x>: x")
            continue
        bound = HYPERPARAMS.get(key)
        if bound is None:
            continue
        x = bound.check(_number(value, key, where), f"{where}: {key}")
        out[key] = int(x) if bound.integer else float(x)
    return out


def _check(table: dict[str, Bound], args: argparse.Namespace) -> None:
    for name, bound in table.items():
        value = getattr(args, name.lstrip("-").replace("-", "_"), None)
        if value is not None:
            bound.check(value, name)


def parse_env_kwargs(text: str | None) -> dict | None:
    """``--env-kwargs`` of train and evaluate: a JSON object of environment keywords (None if not given)."""
    if text is None:
        return None
    from omni_gym.io import excerpt, parse_json

    kwargs = parse_json(text, "--env-kwargs")
    if not isinstance(kwargs, dict):
        raise ValueError(f"--env-kwargs must be a JSON object, got {excerpt(text)!r}")
    return kwargs


def check_train_args(args: argparse.Namespace) -> None:
    """Refuse a ``train`` option outside :data:`TRAIN` (ValueError naming the option)."""
    _check(TRAIN, args)


def check_backend_args(args: argparse.Namespace) -> None:
    """Refuse options that the chosen ``--backend`` does not read (ValueError naming the option).

    sb3 needs ``--algo``; rllib trains PPO on the native vector env only (``--algo ppo``, ``--vec-env native``).
    """
    backend = getattr(args, "backend", "sb3")
    for option, (attr, only) in BACKEND_ONLY.items():
        if getattr(args, attr, None) is not None and backend != only:
            raise ValueError(f"{option} applies to --backend {only}, not --backend {backend}")
    if backend == "sb3" and getattr(args, "algo", None) is None:
        raise ValueError("--algo is required with --backend sb3 (ppo, sac or td3)")
    if backend == "rllib":
        if getattr(args, "algo", None) not in (None, "ppo"):
            raise ValueError(f"--algo {args.algo}: --backend rllib trains ppo only")
        if getattr(args, "vec_env", "native") != "native":
            raise ValueError(f"--vec-env {args.vec_env}: --backend rllib steps the native vector env only")


def check_evaluate_args(args: argparse.Namespace) -> None:
    """Refuse an ``evaluate`` option outside :data:`EVALUATE`, and seeds past the last bound."""
    _check(EVALUATE, args)
    last = args.seed + args.episodes - 1
    if last > EVALUATE["--seed"].hi:
        raise ValueError(f"--seed {args.seed} with --episodes {args.episodes}: the last seed {last} exceeds 2^53")
