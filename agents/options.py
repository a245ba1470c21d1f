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
# What one training may allocate unless raised (--max-parameters, --max-buffer-mb), checked before anything is
# built: the committed networks have 10^4 to 2·10^5 parameters and their buffers take at most ~0.3 GB, while
# net_arch [100000000, 100000000] (10^16 weights) or buffer_size 10^8 would take the machine's memory silently.
MAX_PARAMETERS = 10_000_000  # 40 MB of float32 weights; with gradients, Adam's moments and target copies ~0.3 GB
MAX_BUFFER_MB = 4096.0  # rollout or replay buffer plus one batch's activations

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
    Bound("--max-parameters", 1, 1e10, "", f"most network parameters (all networks of the algorithm; default "
          f"{MAX_PARAMETERS:.0e}, the committed agents have at most 2·10⁵): raise it for a larger network",
          integer=True),
    Bound("--max-buffer-mb", 1.0, 1e7, "MB", f"most memory of the rollout or replay buffer and a batch's "
          f"activations (default {MAX_BUFFER_MB:g}, the committed agents need at most ~300): raise it for a "
          "larger buffer_size, n_steps × n_envs or batch_size"),
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
        address = getattr(args, "address", None)
        if address:  # nothing listening: one line now, as gap --ray does (ray.init would retry for minutes)
            from omni_gym.parallel import check_ray_address

            check_ray_address(address)
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


# --- sizes: what a training allocates, estimated before anything is built ------------------------------------

# Stable-Baselines3's default net_arch per algorithm, and the networks each holds: (head, copies) where a head
# is "pi" (the actor: observation -> action) or "vf"/"qf" (value: observation [+ action] -> 1).
DEFAULT_NET_ARCH = {"ppo": [64, 64], "sac": [256, 256], "td3": [400, 300]}


def _layer_list(value, where: str) -> list[int]:
    if not isinstance(value, (list, tuple)):
        raise ValueError(f"{where}: expected a list of layer sizes, got {value!r}")
    for size in value:
        if isinstance(size, bool) or not isinstance(size, int) or size < 1:
            raise ValueError(f"{where}: layer sizes must be integers >= 1, got {size!r}")
    return list(value)


def _chain(dims: list[int]) -> int:
    """Weights and biases of fully connected layers ``dims[0] -> dims[1] -> ...``."""
    return sum(a * b + b for a, b in zip(dims, dims[1:], strict=False))


def network_parameters(policy_kwargs: dict | None, algo: str, obs_dim: int, act_dim: int, where: str) -> int:
    """The parameter count of ``algo``'s networks for the declarative ``policy_kwargs`` (``net_arch`` a list,
    or a mapping with ``pi`` and ``vf``/``qf``): PPO's actor (with its log std) and value network; SAC's actor
    (mean and log std heads) and ``n_critics`` Q networks with their target copies; TD3's actor and critics, each
    with a target copy. ValueError naming ``where`` for a malformed net_arch."""
    kw = policy_kwargs or {}
    arch = kw.get("net_arch", DEFAULT_NET_ARCH.get(algo, [64, 64]))
    value_key = "vf" if algo == "ppo" else "qf"
    if isinstance(arch, dict):
        pi = _layer_list(arch.get("pi", []), f"{where}: net_arch.pi")
        vf = _layer_list(arch.get(value_key, []), f"{where}: net_arch.{value_key}")
    else:
        pi = vf = _layer_list(arch, f"{where}: net_arch")
    critics = kw.get("n_critics", 2)
    critics = critics if isinstance(critics, int) and not isinstance(critics, bool) and critics >= 1 else 2
    if algo == "ppo":
        return _chain([obs_dim, *pi, act_dim]) + act_dim + _chain([obs_dim, *vf, 1])
    actor = _chain([obs_dim, *pi]) + (_chain([pi[-1] if pi else obs_dim, act_dim]) if algo == "sac" else 0) \
        + _chain([pi[-1] if pi else obs_dim, act_dim])
    q = critics * _chain([obs_dim + act_dim, *vf, 1])
    return (2 * actor if algo == "td3" else actor) + 2 * q  # target copies: TD3's actor, every critic


def buffer_megabytes(hp: dict, algo: str, n_envs: int, obs_dim: int, act_dim: int, widest: int) -> tuple[float, str]:
    """(MB, what) of the buffer ``algo`` allocates at the start (float32: PPO's rollout of ``n_steps`` ×
    ``n_envs`` transitions with six scalars each; SAC/TD3's replay buffer of ``buffer_size`` transitions,
    observation and next observation stored) plus one batch's activations (``batch_size`` × ``widest`` layer,
    forward and backward)."""
    batch = int(hp.get("batch_size", 64 if algo == "ppo" else 256))
    if algo == "ppo":
        rows = int(hp.get("n_steps", 2048)) * n_envs
        per_row, what = obs_dim + act_dim + 6, f"n_steps {int(hp.get('n_steps', 2048))} × n_envs {n_envs}"
    else:
        rows = int(hp.get("buffer_size", 1_000_000))
        per_row, what = 2 * obs_dim + act_dim + 3, f"buffer_size {rows}"
    return 4 * (rows * per_row + 2 * batch * max(widest, obs_dim)) / 2**20, f"{what}, batch_size {batch}"


def check_training_size(hp: dict, policy_kwargs: dict | None, algo: str, n_envs: int, obs_dim: int, act_dim: int,
                        where: str, max_parameters: int | None = None, max_buffer_mb: float | None = None) -> int:
    """Refuse a training whose networks or buffer exceed the limits (:data:`MAX_PARAMETERS`,
    :data:`MAX_BUFFER_MB`, or the given ones), before anything is allocated; returns the parameter count."""
    max_parameters = MAX_PARAMETERS if max_parameters is None else max_parameters
    max_buffer_mb = MAX_BUFFER_MB if max_buffer_mb is None else max_buffer_mb
    params = network_parameters(policy_kwargs, algo, obs_dim, act_dim, where)
    if params > max_parameters:
        raise ValueError(f"{where}: policy_kwargs: the {algo} networks would have {params:.3g} parameters "
                         f"({4 * params / 2**20:.3g} MB of weights, several times that in training), more than the "
                         f"limit {max_parameters:.3g}; use smaller net_arch layers, or raise --max-parameters")
    arch = (policy_kwargs or {}).get("net_arch", DEFAULT_NET_ARCH.get(algo, [64, 64]))
    widths = [w for layers in (arch.values() if isinstance(arch, dict) else [arch]) for w in layers]
    mb, what = buffer_megabytes(hp, algo, n_envs, obs_dim, act_dim, max(widths, default=1))
    if mb > max_buffer_mb:
        raise ValueError(f"{where}: {what}: the {'rollout' if algo == 'ppo' else 'replay'} buffer and a batch would "
                         f"take {mb:.4g} MB, more than the limit {max_buffer_mb:g} MB; make them smaller, or raise "
                         "--max-buffer-mb")
    return params
