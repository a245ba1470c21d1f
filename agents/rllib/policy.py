"""A trained RLlib checkpoint as a policy of the scripted policies' ``reset``/``act`` protocol.

Two kinds of path are accepted (:func:`resolve`):

* our RLlib model directory (``omni-gym train --backend rllib --out DIR``): ``meta.json`` with
  ``"backend": "rllib"`` names the checkpoint folder (``meta["model"]``), observation mode and wrapper;
* a bare RLlib checkpoint folder (``rllib_checkpoint.json``, from ``Algorithm.save``): nothing records
  the observation mode, so it is ``obs_mode`` of ``--env-kwargs`` (default ``"state"``, the only agent the
  RLlib backend trains) and the observation shape is checked against the module's.

Only the RL module is loaded (``learner_group/learner/rl_module/default_policy``), in this process: no Ray
cluster starts. An RLlib checkpoint stores its module's class and constructor arguments as a Python pickle,
so loading one runs any code it holds: it is refused unless ``trust_pickle`` is set (``--trust-pickle``;
docs/security.md). The action is deterministic: the mean of the module's diagonal Gaussian, clipped to the
action space ([−1, 1]) as SB3's ``predict`` clips, so an episode is a function of its seed.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from agents.rollout import TrainedPolicy, check_env_id
from agents.weights import inside, refuse_pickle
from omni_gym.io import InputError, excerpt, read_json

CHECKPOINT_MARKER = "rllib_checkpoint.json"
MODULE_PATH = ("learner_group", "learner", "rl_module", "default_policy")
META = "meta.json"


@dataclass(frozen=True)
class RLlibSource:
    """Where an RLlib model's module is and how its environment is built: ``checkpoint`` (the RLlib
    checkpoint folder), ``obs_mode`` (None: the evaluation's ``--env-kwargs`` decide), ``wrapper``,
    ``env_id`` (None: not recorded), ``where`` (what the values came from, for messages)."""

    checkpoint: Path
    obs_mode: str | None
    wrapper: str
    env_id: str | None
    where: str


def _meta(d: Path) -> dict | None:
    try:
        meta = read_json(d / META)
    except (OSError, InputError):
        return None
    return meta if isinstance(meta, dict) else None


def is_rllib_model(path: str | Path) -> bool:
    """True for our RLlib model directory (meta.json says ``backend: rllib``) or a bare RLlib checkpoint."""
    p = Path(path)
    if not p.is_dir():
        return False
    if (p / CHECKPOINT_MARKER).is_file():
        return True
    meta = _meta(p)
    return meta is not None and meta.get("backend") == "rllib"


def resolve(path: str | Path) -> RLlibSource:
    """The checkpoint and environment of the RLlib model at ``path`` (ValueError naming what is wrong)."""
    p = Path(path)
    if (p / CHECKPOINT_MARKER).is_file() and not (p / META).is_file():
        return RLlibSource(p, None, "none", None, str(p))
    meta = _meta(p)
    if meta is None or meta.get("backend") != "rllib":
        raise ValueError(f"{path}: not an RLlib model (a directory with {META} of backend rllib, or an RLlib "
                         f"checkpoint with {CHECKPOINT_MARKER})")
    if not isinstance(meta.get("model"), str):
        raise ValueError(f"{p / META}: missing key 'model' (the checkpoint folder)")
    ckpt = inside(p, meta["model"], str(p / META), "model")
    if not (ckpt / CHECKPOINT_MARKER).is_file():
        raise ValueError(f"{p / META}: key 'model': {ckpt} is not an RLlib checkpoint (no {CHECKPOINT_MARKER})")
    if meta.get("env_id") is not None:  # never "MODULE:ID": making it would import MODULE
        check_env_id(meta["env_id"], f"{p / META}: key 'env_id'")
    return RLlibSource(ckpt, meta.get("obs_mode", "state"), meta.get("wrapper", "none"), meta.get("env_id"),
                       str(p / META))


def load_module(checkpoint: str | Path):
    """The RL module (torch, inference) of an RLlib checkpoint folder; ValueError if it cannot be read."""
    from omni_gym.rllib import require_ray

    require_ray("loading an RLlib checkpoint")
    import torch
    from ray.rllib.core.rl_module.rl_module import RLModule

    d = Path(checkpoint).resolve().joinpath(*MODULE_PATH)  # RLlib reads only absolute paths (or URIs)
    if not d.is_dir():
        raise ValueError(f"{checkpoint}: no RL module in the checkpoint ({d} missing)")
    torch.set_num_threads(1)  # small MLPs: one thread is fastest and leaves the cores to the simulation
    try:
        module = RLModule.from_checkpoint(d)
        module.eval()
    except Exception as exc:  # RLlib raises many kinds for a damaged checkpoint  # noqa: BLE001
        message = excerpt(f"{type(exc).__name__}: {exc}", 200)
        raise ValueError(f"{checkpoint}: cannot load the RLlib checkpoint ({message})") from None
    from gymnasium.spaces import Box

    for name in ("observation_space", "action_space"):  # a crafted checkpoint may build a module without them
        if not isinstance(getattr(module, name, None), Box):
            raise ValueError(f"{checkpoint}: the RLlib checkpoint's module has no box {name} (not a module "
                             "omni-gym can run)")
    return module


class RLlibPolicy(TrainedPolicy):
    """Adapter: an RLlib torch RL module acting deterministically (the mean action, clipped to the box).

    Args:
        module: an RLlib ``TorchRLModule`` with a diagonal-Gaussian action distribution (PPO's default).
        env: the environment it acts on (its ``estimate`` is exposed as for SB3 models:
            :class:`agents.rollout.TrainedPolicy`).
    """

    name = "rllib"

    def __init__(self, module, env=None) -> None:
        super().__init__(env)
        self.module = module
        space = module.action_space
        self.low = np.asarray(space.low, dtype=np.float32)
        self.high = np.asarray(space.high, dtype=np.float32)

    def act(self, obs: np.ndarray) -> np.ndarray:
        """The mean action for one observation (D,) → (A,), or a batch (N, D) → (N, A); float32."""
        import torch
        from ray.rllib.core.columns import Columns

        o = np.asarray(obs, dtype=np.float32)
        batch = o.reshape(-1, o.shape[-1])
        with torch.no_grad():
            out = self.module.forward_inference({Columns.OBS: torch.from_numpy(batch)})
            dist = self.module.get_inference_action_dist_cls().from_logits(out[Columns.ACTION_DIST_INPUTS])
            mean = dist.to_deterministic().sample().numpy()
        action = np.clip(mean.astype(np.float32), self.low, self.high)
        return action if o.ndim > 1 else action[0]


def build(path: str | Path, env_id: str | None = None, env_kwargs: dict | None = None, trust_pickle: bool = False):
    """(wrapped env, :class:`RLlibPolicy`) for evaluating the RLlib model at ``path`` on ``env_id``; refused
    (one line) unless ``trust_pickle``: loading the checkpoint unpickles it."""
    from agents.rollout import make_env
    from agents.wrappers import wrap_env

    src = resolve(path)
    if not trust_pickle:
        raise refuse_pickle(src.checkpoint, "an RLlib checkpoint")
    env_id = env_id or src.env_id
    if env_id is None:
        raise ValueError(f"{path}: the checkpoint does not record its environment: give the environment id")
    module = load_module(src.checkpoint)
    kw = dict(env_kwargs or {})
    obs_mode = src.obs_mode or kw.get("obs_mode", "state")
    if kw.get("obs_mode", obs_mode) != obs_mode:
        raise ValueError(f"model {path} was trained with obs_mode={obs_mode!r}; got obs_mode={kw['obs_mode']!r}")
    kw.pop("obs_mode", None)
    env = wrap_env(make_env(env_id, kw, obs_mode=obs_mode), src.wrapper)
    if env.observation_space.shape != module.observation_space.shape:
        env.close()
        raise ValueError(f"model {path} expects observations of shape {module.observation_space.shape}, the "
                         f"environment {env_id} with obs_mode {obs_mode!r} gives {env.observation_space.shape}")
    return env, RLlibPolicy(module, env)
