"""omni-gym's model format: weights and numbers only, so opening a model runs no code from it.

A model directory (``agents/models/<name>/``, docs/formats.md) holds

* ``meta.json`` with ``"format": "weights-1"``, ``"model": "policy.pt"`` and ``"policy"``: the
  algorithm's policy alias (``MlpPolicy``), its ``policy_kwargs`` in the declarative form of
  :mod:`agents.policy_spec` (layer sizes, class *names*) and the observation and action boxes
  (``shape``, ``low``, ``high``; a bound equal for every element is one number);
* ``policy.pt``: the policy's ``state_dict`` (tensors only), read with ``torch.load(weights_only=True)``;
* ``normalisation.npz`` (when the model was trained with observation normalisation): ``mean``, ``var``
  (per observation element), ``clip`` and ``epsilon``, read with ``numpy.load(allow_pickle=False)``.

The policy is rebuilt from the project's own classes (:func:`load_policy`) and its weights loaded into
it; nothing in the files names code to import beyond the fixed tables of :mod:`agents.policy_spec`.
:func:`export` writes the format from a loaded SB3 model (``python -m agents.export_model``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from agents.policy_spec import declarative, to_sb3
from omni_gym.io import InputError, check_readable, excerpt, printable

FORMAT = "weights-1"
WEIGHTS = "policy.pt"
NORMALISATION = "normalisation.npz"
MAX_WEIGHTS_BYTES = 64 * 2**20  # the largest committed model is 1.5 MB; see docs/bounds.md


def refuse_pickle(path, what: str) -> InputError:
    """The one-line refusal of a pickled file read without ``--trust-pickle``."""
    return InputError(f"{path}: {what} is a Python pickle, and opening a pickle runs any code it holds; refused "
                      f"(pass --trust-pickle only for a file from someone you trust; docs/security.md)")


def inside(folder: Path, name, where: str, key: str) -> Path:
    """``folder / name`` for a file named in ``where`` (a meta.json) under ``key``, refused unless it is a
    relative path that stays inside ``folder`` (no ``..``, no absolute path, no link leading out)."""
    if not isinstance(name, str) or not name or len(name) > 255:
        raise InputError(f"{where}: key {key!r}: expected a file name inside {folder}, got {excerpt(name)!r}")
    target = (folder / name).resolve()
    if Path(name).is_absolute() or not target.is_relative_to(folder.resolve()):
        raise InputError(f"{where}: key {key!r}: {excerpt(name)!r} leads outside the model folder {folder}; "
                         "a model's files must be inside it")
    return folder / name


@dataclass(frozen=True)
class ObsNormaliser:
    """Observation normalisation as SB3's ``VecNormalize`` applies it at evaluation:
    ``clip((obs - mean) / sqrt(var + epsilon), -clip, clip)`` (float64 statistics, like SB3's)."""

    mean: np.ndarray
    var: np.ndarray
    clip: float
    epsilon: float

    def normalize_obs(self, obs: np.ndarray) -> np.ndarray:
        return np.clip((obs - self.mean) / np.sqrt(self.var + self.epsilon), -self.clip, self.clip)

    @classmethod
    def from_vecnormalize(cls, vn) -> ObsNormaliser | None:
        """The statistics of an SB3 ``VecNormalize`` (None if it does not normalise observations)."""
        if not vn.norm_obs:
            return None
        return cls(np.asarray(vn.obs_rms.mean, dtype=np.float64), np.asarray(vn.obs_rms.var, dtype=np.float64),
                   float(vn.clip_obs), float(vn.epsilon))

    def save(self, path: Path) -> None:
        with open(path, "wb") as fh:
            np.savez(fh, mean=self.mean, var=self.var, clip=np.float64(self.clip), epsilon=np.float64(self.epsilon))

    @classmethod
    def load(cls, path: Path, size: int) -> ObsNormaliser:
        """Statistics for observations of ``size`` elements; InputError naming the file."""
        check_readable(path, MAX_WEIGHTS_BYTES, "normalisation statistics")
        try:
            with np.load(path, allow_pickle=False) as data:
                arrays = {k: np.asarray(data[k], dtype=np.float64) for k in ("mean", "var", "clip", "epsilon")}
        except KeyError as exc:
            raise InputError(f"{path}: missing array {exc} (expected mean, var, clip, epsilon)") from None
        except (OSError, ValueError, TypeError) as exc:  # not an npz, or an object array (pickle refused)
            raise InputError(f"{path}: not normalisation statistics ({_short(exc)})") from None
        for key in ("mean", "var"):
            if arrays[key].shape != (size,) or not np.all(np.isfinite(arrays[key])):
                raise InputError(f"{path}: {key} must be {size} finite numbers, got shape {arrays[key].shape}")
        if np.any(arrays["var"] < 0):
            raise InputError(f"{path}: var must be >= 0")
        clip, eps = float(arrays["clip"]), float(arrays["epsilon"])
        if not (0 < clip <= 1e6 and 0 < eps <= 1):
            raise InputError(f"{path}: clip must be in (0, 1e6] and epsilon in (0, 1], got {clip:g}, {eps:g}")
        return cls(arrays["mean"], arrays["var"], clip, eps)


_ANSI = re.compile(r"\x1b\[[0-9;]*[A-Za-z]")  # terminal styling (torch writes bold text into its messages)


def _short(exc) -> str:
    """A library's message on one line of at most 120 characters, without terminal styling and with other
    control characters escaped. torch's refusal of a pickled object is a page of advice (re-run with
    weights_only=False: exactly what must not be done with an untrusted file); only its reason is kept,
    ``Unsupported global: GLOBAL io.open was not an allowed global by default``."""
    text = _ANSI.sub("", str(exc))
    reason = re.search(r"WeightsUnpickler error:\s*(.*?)(?:\. Please use|\n\n|$)", text, re.S)
    if reason:
        text = f"a pickled object, refused: {reason.group(1)}"
    s = printable(" ".join(text.split()))
    return s if len(s) <= 120 else s[:117] + "..."


def _box(space) -> dict:
    def bound(a):
        a = np.asarray(a, dtype=np.float64)
        return float(a.flat[0]) if a.size and np.all(a == a.flat[0]) else a.tolist()

    return {"shape": list(space.shape), "low": bound(space.low), "high": bound(space.high)}


def _space(d, where: str):
    from gymnasium.spaces import Box

    if not isinstance(d, dict) or not isinstance(d.get("shape"), list) or len(d["shape"]) != 1:
        raise InputError(f"{where}: expected {{'shape': [n], 'low': ..., 'high': ...}}")
    n = d["shape"][0]
    if not isinstance(n, int) or isinstance(n, bool) or not 1 <= n <= 4096:
        raise InputError(f"{where}: shape must be [n] with 1 <= n <= 4096, got {d['shape']}")
    try:
        low = np.broadcast_to(np.asarray(d.get("low"), dtype=np.float32), (n,))
        high = np.broadcast_to(np.asarray(d.get("high"), dtype=np.float32), (n,))
    except (ValueError, TypeError):
        raise InputError(f"{where}: low and high must be a number or {n} numbers") from None
    if np.any(np.isnan(low)) or np.any(np.isnan(high)) or np.any(low > high):
        raise InputError(f"{where}: low must be <= high (no NaN)")
    return Box(low.copy(), high.copy(), dtype=np.float32)


def policy_description(model) -> dict:
    """``meta["policy"]`` of an SB3 model: what :func:`load_policy` needs to rebuild its policy."""
    from stable_baselines3.common.policies import ActorCriticPolicy

    alias = next((a for a, c in type(model).policy_aliases.items() if c is type(model.policy)), None)
    if alias is None:
        raise ValueError(f"{type(model.policy).__name__}: not one of {type(model).__name__}'s policy aliases")
    kwargs = dict(model.policy_kwargs)
    if isinstance(model.policy, ActorCriticPolicy):  # on-policy algorithms pass use_sde beside policy_kwargs
        kwargs["use_sde"] = bool(model.use_sde)
    return {"class": alias, "kwargs": declarative(kwargs, "policy_kwargs"),
            "observation_space": _box(model.observation_space), "action_space": _box(model.action_space)}


def export(model, vecnormalize, folder: Path) -> dict:
    """Write ``policy.pt`` (and ``normalisation.npz``) of ``model`` into ``folder``; returns the ``meta.json``
    keys that name them (``format``, ``model``, ``vecnormalize``, ``policy``)."""
    import torch

    folder = Path(folder)
    torch.save({k: v.detach().clone() for k, v in model.policy.state_dict().items()}, folder / WEIGHTS)
    norm = ObsNormaliser.from_vecnormalize(vecnormalize) if vecnormalize is not None else None
    if norm is not None:
        norm.save(folder / NORMALISATION)
    return {"format": FORMAT, "model": WEIGHTS, "vecnormalize": NORMALISATION if norm is not None else None,
            "policy": policy_description(model)}


def load_policy(weights: Path, algo: str, description, where: str):
    """The SB3 policy (inference mode, CPU) of ``description`` (``meta["policy"]``) with the weights of
    ``weights``; InputError naming ``where`` (the meta.json) or the weights file."""
    import torch

    from agents.algorithms import algorithm_class

    if not isinstance(description, dict):
        raise InputError(f"{where}: key 'policy' must be a mapping (class, kwargs, observation_space, action_space)")
    cls = algorithm_class(algo)
    alias = description.get("class")
    if alias not in cls.policy_aliases or alias not in ("MlpPolicy",):
        raise InputError(f"{where}: key 'policy.class': {str(alias)[:40]!r} is not MlpPolicy")
    kwargs = declarative(description.get("kwargs"), f"{where}: key 'policy.kwargs'")
    obs_space = _space(description.get("observation_space"), f"{where}: key 'policy.observation_space'")
    act_space = _space(description.get("action_space"), f"{where}: key 'policy.action_space'")
    check_readable(weights, MAX_WEIGHTS_BYTES, "model weights")
    try:
        state = torch.load(weights, map_location="cpu", weights_only=True)
    except Exception as exc:  # torch raises many kinds for a damaged file or a refused object  # noqa: BLE001
        raise InputError(f"{weights}: not a weights file ({type(exc).__name__}: {_short(exc)})") from None
    if not isinstance(state, dict) or not all(isinstance(v, torch.Tensor) for v in state.values()):
        raise InputError(f"{weights}: not a weights file (expected a mapping of names to tensors)")
    try:
        policy = cls.policy_aliases[alias](obs_space, act_space, lambda _: 0.0, **to_sb3(kwargs))
        policy.load_state_dict(state, strict=True)
    except (RuntimeError, TypeError, ValueError) as exc:
        raise InputError(f"{weights}: does not fit the policy described in {where} ({_short(exc)})") from None
    policy.set_training_mode(False)
    return policy


