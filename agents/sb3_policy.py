"""Load a trained SB3 model directory (``agents/models/<name>/``) and run it like a scripted policy.

A model directory holds ``meta.json`` (written by :mod:`agents.train`: algorithm, observation mode,
wrapper, residual bound), the model zip named by ``meta["model"]`` and, if the model was trained with
observation normalisation, the ``VecNormalize`` statistics named by ``meta["vecnormalize"]``.

    env, policy = build("agents/models/ppo-residual", "OmniPathFollow-Phunopas-v0", {"lift_rate": 0.5})
    episode = agents.evaluate.run_episode(env, policy, seed=10_000)

The environment is built with the evaluation's ``env_kwargs`` (not the training ones: no domain
randomisation) plus the observation mode the model needs, and wrapped with the model's wrapper. The
policy acts deterministically (the mean action), so an episode is a function of its seed.
"""

from __future__ import annotations

import json
import pickle
from pathlib import Path

import numpy as np

META = "meta.json"


class SB3Policy:
    """Adapter: an SB3 model (+ optional VecNormalize statistics) with the scripted policies' reset/act protocol.

    Args:
        model: a stable-baselines3 model.
        vecnormalize: a ``VecNormalize`` whose ``normalize_obs`` matches the model's training (or None).
        env: the (wrapped) environment it acts on; its ``estimate`` (EKF wrappers) is exposed.
    """

    name = "sb3"

    def __init__(self, model, vecnormalize, env) -> None:
        self.model = model
        self.vecnormalize = vecnormalize
        self.env = env
        self.twist = np.zeros(3)

    @property
    def estimate(self) -> np.ndarray | None:
        return getattr(self.env, "estimate", None)

    def reset(self, obs: np.ndarray) -> None:
        self.twist = np.zeros(3)

    def act(self, obs: np.ndarray) -> np.ndarray:
        o = np.asarray(obs, dtype=np.float32)
        if self.vecnormalize is not None:
            o = np.asarray(self.vecnormalize.normalize_obs(o), dtype=np.float32)
        action, _ = self.model.predict(o, deterministic=True)
        return np.asarray(action, dtype=np.float32)


def read_meta(path: str | Path) -> dict:
    """``meta.json`` of a model directory, checked for the keys evaluation needs."""
    d = Path(path)
    if not d.is_dir():
        raise ValueError(f"{path}: not a model directory (expected a directory with {META})")
    f = d / META
    try:
        meta = json.loads(f.read_text())
    except FileNotFoundError:
        raise ValueError(f"{f}: missing (a model directory needs {META}; see agents/train.py)") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"{f}: not valid JSON ({exc})") from None
    for key in ("algo", "model", "wrapper"):
        if key not in meta:
            raise ValueError(f"{f}: missing key {key!r}")
    from agents.train import ALGOS

    if meta["algo"] not in ALGOS:
        raise ValueError(f"{f}: key 'algo': unknown algorithm {meta['algo']!r}; one of {', '.join(ALGOS)}")
    return meta


def load(path: str | Path):
    """(meta, model, vecnormalize or None) of a model directory."""
    import torch
    from stable_baselines3 import PPO, SAC, TD3

    d = Path(path)
    meta = read_meta(d)
    cls = {"ppo": PPO, "sac": SAC, "td3": TD3}[meta["algo"]]
    zip_path = d / meta["model"]
    if not zip_path.is_file():
        raise ValueError(f"{d / META}: key 'model': file {zip_path} not found")
    torch.set_num_threads(1)  # small MLPs: one thread is fastest and leaves the cores to the simulation
    try:
        model = cls.load(zip_path, device="cpu")
    except Exception as exc:  # SB3 raises many kinds for a damaged zip  # noqa: BLE001
        raise ValueError(f"{zip_path}: cannot load the {meta['algo']} model ({type(exc).__name__}: {exc})") from None
    vn = None
    if meta.get("vecnormalize"):
        vn_path = d / meta["vecnormalize"]
        try:
            with open(vn_path, "rb") as fh:
                vn = pickle.load(fh)  # noqa: S301  (our own file, as VecNormalize.load does)
        except FileNotFoundError:
            raise ValueError(f"{d / META}: key 'vecnormalize': file {vn_path} not found") from None
        except (pickle.UnpicklingError, EOFError, AttributeError) as exc:
            raise ValueError(f"{vn_path}: not a VecNormalize pickle ({exc})") from None
        vn.training = False
    return meta, model, vn


def build(path: str | Path, env_id: str | None = None, env_kwargs: dict | None = None):
    """(wrapped env, :class:`SB3Policy`) for evaluating the model in ``path`` on ``env_id`` with ``env_kwargs``."""
    from agents.evaluate import make_env
    from agents.wrappers import wrap_env

    meta, model, vn = load(path)
    env_id = env_id or meta.get("env_id")
    kw = dict(env_kwargs or {})
    obs_mode = meta.get("obs_mode", "sensors")
    if kw.get("obs_mode", obs_mode) != obs_mode:
        raise ValueError(f"model {path} was trained with obs_mode={obs_mode!r}; got obs_mode={kw['obs_mode']!r}")
    kw.pop("obs_mode", None)
    env = wrap_env(make_env(env_id, kw, obs_mode=obs_mode), meta["wrapper"], float(meta.get("residual_scale", 0.3)))
    if env.observation_space.shape != model.observation_space.shape:
        env.close()
        raise ValueError(f"model {path} expects observations of shape {model.observation_space.shape}, the "
                         f"environment {env_id} gives {env.observation_space.shape}")
    return env, SB3Policy(model, vn, env)
