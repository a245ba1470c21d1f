"""Load a trained SB3 model and run it like a scripted policy.

Three kinds of model are accepted (:func:`resolve`):

* our model directory (``agents/models/<name>/``, written by :mod:`agents.train`): ``meta.json``
  (algorithm, observation mode, wrapper, residual bound; docs/formats.md), the weights named by
  ``meta["model"]`` and, if the model was trained with observation normalisation, the statistics named by
  ``meta["vecnormalize"]`` (:mod:`agents.weights`: no pickle, so opening it runs no code). Both names must
  stay inside the directory. A directory of the older layout (an SB3 zip and a ``VecNormalize`` pickle) is
  read only with ``trust_pickle``;
* an RL Zoo output folder (``logs/ppo/ENV_1/``: ``ENV.zip`` and ``ENV/`` with ``args.yml``,
  ``config.yml`` and, when normalising, ``vecnormalize.pkl``): the algorithm comes from ``args.yml``,
  the wrapper and observation mode from ``config.yml`` (``env_wrapper``, ``env_kwargs``);
* a plain SB3 ``model.zip``: nothing can be read but the weights, so the algorithm (``--algo``), the
  wrapper (``--wrapper``, default none), the observation mode (``obs_mode`` in ``--env-kwargs``, default
  sensors) and the normalisation statistics (``--vecnormalize``) come from :class:`ModelOptions`.

SB3 zips and ``VecNormalize`` pickles are unpickled when read, which runs any code they hold: the last two
kinds (and the older layout) are refused unless :class:`ModelOptions` ``trust_pickle`` is set
(``--trust-pickle``; docs/security.md). ``python -m agents.export_model`` converts a trusted one.

    env, policy = build("agents/models/ppo-residual", "OmniPathFollow-Phunopas-v0", {"lift_rate": 0.5})
    episode = agents.rollout.run_episode(env, policy, seed=10_000)

The environment is built with the evaluation's ``env_kwargs`` (not the training ones: no domain
randomisation) plus the observation mode the model needs, and wrapped with the model's wrapper. The
policy acts deterministically (the mean action), so an episode is a function of its seed.
"""

from __future__ import annotations

import pickle
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from agents import require_agents_extra
from agents.algorithms import ALGORITHMS, algorithm_class
from agents.rollout import TrainedPolicy, check_env_id, make_env
from agents.weights import FORMAT, ObsNormaliser, inside, load_policy, refuse_pickle
from agents.wrappers import WRAPPERS, wrap_env
from agents.zoo_config import wrapper_spec
from omni_gym.io import check_readable, excerpt, read_json, read_yaml

META = "meta.json"
ZOO_ALGO_FILE = "args.yml"
ZOO_CONFIG = "config.yml"


@dataclass(frozen=True)
class ModelOptions:
    """What the command line says about a model (None: not given). A plain SB3 zip needs ``algo``; for
    our model directories and RL Zoo folders the values are read from the files, and an option that
    contradicts them is refused.

    ``wrapper``: one of :data:`agents.wrappers.WRAPPERS`; ``residual_scale``: its residual bound
    (fraction of the action range); ``vecnormalize``: a ``VecNormalize`` pickle; ``trust_pickle``: unpickle
    SB3 zips and ``VecNormalize`` pickles (which runs any code they hold; refused without it).
    """

    algo: str | None = None
    wrapper: str | None = None
    residual_scale: float | None = None
    vecnormalize: str | None = None
    trust_pickle: bool = False

    def given(self) -> list[str]:
        """The options that were given, as command-line names."""
        names = {"algo": "--algo", "wrapper": "--wrapper", "residual_scale": "--residual-scale",
                 "vecnormalize": "--vecnormalize"}
        return [flag for key, flag in names.items() if getattr(self, key) is not None]


@dataclass(frozen=True)
class ModelSource:
    """Where a model's files are and how its environment is built (see the module doc).

    ``kind``: "meta" (our directory), "zoo" (RL Zoo folder) or "zip" (plain SB3); ``meta``: our
    ``meta.json`` or the equivalent keys read from the Zoo's files or the options (``algo``, ``wrapper``,
    ``residual_scale``, ``obs_mode`` or None, ``env_id`` or None, ``model``, ``vecnormalize``).
    """

    kind: str
    meta: dict
    zip_path: Path
    vecnormalize: Path | None
    where: str  # the file the meta keys came from, for error messages

    @property
    def pickled(self) -> bool:
        """True if loading it unpickles (an SB3 zip, a VecNormalize pickle): not our weights format."""
        return not (self.kind == "meta" and self.meta.get("format") == FORMAT)


class SB3Policy(TrainedPolicy):
    """Adapter: an SB3 model (+ optional VecNormalize statistics) with the scripted policies' reset/act protocol.

    Args:
        model: a stable-baselines3 model.
        vecnormalize: a ``VecNormalize`` whose ``normalize_obs`` matches the model's training (or None).
        env: the (wrapped) environment it acts on; its ``estimate`` (EKF wrappers) is exposed
            (:class:`agents.rollout.TrainedPolicy`).
    """

    name = "sb3"

    def __init__(self, model, vecnormalize, env) -> None:
        super().__init__(env)
        self.model = model
        self.vecnormalize = vecnormalize

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
    if not f.exists():
        raise ValueError(f"{f}: missing (a model directory needs {META}; see agents/train.py)")
    meta = read_json(f)
    if not isinstance(meta, dict):
        raise ValueError(f"{f}: expected a JSON object")
    for key in ("algo", "model", "wrapper"):
        if key not in meta:
            raise ValueError(f"{f}: missing key {key!r}")
    _check_algo(meta["algo"], f"{f}: key 'algo'")
    if meta.get("env_id") is not None:  # never "MODULE:ID": making it would import MODULE
        check_env_id(meta["env_id"], f"{f}: key 'env_id'")
    return meta


def is_model_path(path: str | Path) -> bool:
    """True if ``path`` looks like a model :func:`resolve` may accept (a directory or a ``.zip`` file)."""
    p = Path(path)
    return p.is_dir() or p.suffix == ".zip"


def _check_algo(algo, where: str) -> str:
    return ALGORITHMS.check(algo, what="algorithm", where=where)


def _check_options(options: ModelOptions, values: dict, where: str) -> None:
    """Refuse a command-line option that contradicts what the model's files say."""
    for key, flag in (("algo", "--algo"), ("wrapper", "--wrapper"), ("residual_scale", "--residual-scale")):
        given = getattr(options, key)
        if given is not None and given != values.get(key):
            raise ValueError(f"{flag} {given!r} contradicts {where}, which says {values.get(key)!r}")


def _zoo_yaml(path: Path) -> dict:
    """An RL Zoo ``args.yml``/``config.yml`` (an OrderedDict in PyYAML's python tag) as a dict, safely."""
    import yaml

    class Loader(yaml.SafeLoader):
        pass

    def ordered(loader, node):  # [[key, value], ...] -> dict; no other python object is built
        return dict(loader.construct_sequence(node.value[0], deep=True)) if node.value else {}

    Loader.add_constructor("tag:yaml.org,2002:python/object/apply:collections.OrderedDict", ordered)
    if not path.exists():
        raise ValueError(f"{path}: missing (an RL Zoo folder has ENV.zip and ENV/{path.name})")
    data = read_yaml(path, Loader)  # bounded, no aliases
    if not isinstance(data, dict):
        raise ValueError(f"{path}: not an RL Zoo YAML file (expected a mapping)")
    return data


def _resolve_zoo(d: Path, options: ModelOptions) -> ModelSource:
    zips = sorted(z for z in d.glob("*.zip") if (d / z.stem).is_dir() and (d / z.stem / ZOO_ALGO_FILE).is_file())
    if not zips:
        raise ValueError(f"{d}: neither our model directory ({META}) nor an RL Zoo folder (ENV.zip beside "
                         f"ENV/{ZOO_ALGO_FILE})")
    zip_path = zips[0]
    params = zip_path.with_suffix("")
    args = _zoo_yaml(params / ZOO_ALGO_FILE)
    config = _zoo_yaml(params / ZOO_CONFIG)
    algo = _check_algo(args.get("algo"), f"{params / ZOO_ALGO_FILE}: key 'algo'")
    if args.get("env") is not None:  # never "MODULE:ID": making it would import MODULE
        check_env_id(args["env"], f"{params / ZOO_ALGO_FILE}: key 'env'")
    spec = wrapper_spec(config, str(params / ZOO_CONFIG))
    env_kwargs = config.get("env_kwargs") or {}
    meta = {"algo": algo, "env_id": args.get("env"), "wrapper": spec.name, "residual_scale": spec.residual_scale,
            "obs_mode": env_kwargs.get("obs_mode", "state"),  # gym.make's default: the Zoo passes env_kwargs as is
            "model": zip_path.name, "vecnormalize": None}
    _check_options(options, meta, str(params / ZOO_CONFIG))
    vn = params / "vecnormalize.pkl"
    if config.get("normalize") not in (None, False):
        if not vn.is_file():
            raise ValueError(f"{params / ZOO_CONFIG}: 'normalize' is set but {vn} is missing")
        meta["vecnormalize"] = str(vn)
    if options.vecnormalize is not None:
        raise ValueError(f"--vecnormalize: the RL Zoo folder {d} names its own statistics ({vn})")
    return ModelSource("zoo", meta, zip_path, vn if meta["vecnormalize"] else None, str(params / ZOO_CONFIG))


def resolve(path: str | Path, options: ModelOptions | None = None) -> ModelSource:
    """Where the files of the model at ``path`` are and how to build its environment (see the module doc)."""
    options = options or ModelOptions()
    p = Path(path)
    if p.is_dir() and (p / META).is_file():
        meta = read_meta(p)
        _check_options(options, {**meta, "residual_scale": meta.get("residual_scale", 0.3)}, str(p / META))
        if options.vecnormalize is not None:
            raise ValueError(f"--vecnormalize: the model directory {p} names its own statistics in {META}")
        where = str(p / META)
        vn = inside(p, meta["vecnormalize"], where, "vecnormalize") if meta.get("vecnormalize") else None
        return ModelSource("meta", meta, inside(p, meta["model"], where, "model"), vn, where)
    if p.is_dir():
        return _resolve_zoo(p, options)
    if p.suffix != ".zip":
        raise ValueError(f"{path}: not a model (a model directory with {META}, an RL Zoo folder or an SB3 .zip)")
    if not p.is_file():
        raise ValueError(f"{path}: no such model file")
    if options.algo is None:
        raise ValueError(f"{path}: a plain SB3 model records no algorithm: give --algo (ppo, sac or td3)")
    wrapper = options.wrapper or "none"
    WRAPPERS.check(wrapper, what="--wrapper")
    meta = {"algo": _check_algo(options.algo, "--algo"), "env_id": None, "wrapper": wrapper,
            "residual_scale": 0.3 if options.residual_scale is None else options.residual_scale,
            "obs_mode": None, "model": p.name, "vecnormalize": options.vecnormalize}
    vn = Path(options.vecnormalize) if options.vecnormalize else None
    return ModelSource("zip", meta, p, vn, "the command line")


def load(path: str | Path, options: ModelOptions | None = None):
    """(meta, model, vecnormalize or None) of a model (see :func:`resolve`)."""
    require_agents_extra("loading an SB3 model")
    import torch

    options = options or ModelOptions()
    src = resolve(path, options)
    meta = src.meta
    cls = algorithm_class(meta["algo"])
    if not src.zip_path.is_file():
        raise ValueError(f"{src.where}: key 'model': file {src.zip_path} not found")
    torch.set_num_threads(1)  # small MLPs: one thread is fastest and leaves the cores to the simulation
    if not src.pickled:  # our weights format: nothing is unpickled
        policy = load_policy(src.zip_path, meta["algo"], meta.get("policy"), src.where)
        vn = None
        if src.vecnormalize is not None:
            vn = ObsNormaliser.load(src.vecnormalize, int(policy.observation_space.shape[0]))
        return meta, policy, vn
    if not options.trust_pickle:
        raise refuse_pickle(src.zip_path, "an SB3 model zip")
    if src.vecnormalize is not None and src.vecnormalize.suffix != ".npz":
        check_readable(src.vecnormalize, None, "VecNormalize statistics")
    check_readable(src.zip_path, 256 * 2**20, "an SB3 model zip")
    try:
        model = cls.load(src.zip_path, device="cpu")
    except Exception as exc:  # SB3 raises many kinds for a damaged zip or another algorithm  # noqa: BLE001
        message = " ".join(f"{type(exc).__name__}: {exc}".split())[:200]
        raise ValueError(f"{src.zip_path}: cannot load it as a {meta['algo']} model ({message})") from None
    vn = None
    if src.vecnormalize is not None and src.vecnormalize.suffix == ".npz":
        vn = ObsNormaliser.load(src.vecnormalize, int(model.observation_space.shape[0]))
    elif src.vecnormalize is not None:
        vn = _load_vecnormalize(src.vecnormalize, src.where)
    return meta, model, vn


def _load_vecnormalize(path: Path, where: str):
    """A trusted ``VecNormalize`` pickle (only with ``--trust-pickle``: unpickling runs its code)."""
    from stable_baselines3.common.vec_env import VecNormalize

    try:
        with open(path, "rb") as fh:
            vn = pickle.load(fh)  # noqa: S301  (a trusted model's file, as VecNormalize.load does)
    except FileNotFoundError:
        raise ValueError(f"{where}: key 'vecnormalize': file {path} not found") from None
    except (pickle.UnpicklingError, EOFError, AttributeError, ValueError, ImportError) as exc:
        raise ValueError(f"{path}: not a VecNormalize pickle ({excerpt(exc)})") from None
    if not isinstance(vn, VecNormalize):
        raise ValueError(f"{path}: not a VecNormalize pickle (holds a {type(vn).__name__})")
    vn.training = False
    return vn


def build(path: str | Path, env_id: str | None = None, env_kwargs: dict | None = None,
          options: ModelOptions | None = None):
    """(wrapped env, :class:`SB3Policy`) for evaluating the model in ``path`` on ``env_id`` with ``env_kwargs``."""
    meta, model, vn = load(path, options)
    env_id = env_id or meta.get("env_id")
    if env_id is None:
        raise ValueError(f"{path}: the model does not record its environment: give the environment id")
    kw = dict(env_kwargs or {})
    obs_mode = meta.get("obs_mode", "sensors")
    if obs_mode is None:  # a plain zip: the user's obs_mode, else what the scripted policies use
        obs_mode = kw.get("obs_mode", "sensors")
    if kw.get("obs_mode", obs_mode) != obs_mode:
        raise ValueError(f"model {path} was trained with obs_mode={obs_mode!r}; got obs_mode={kw['obs_mode']!r}")
    kw.pop("obs_mode", None)
    env = wrap_env(make_env(env_id, kw, obs_mode=obs_mode), meta["wrapper"], float(meta.get("residual_scale", 0.3)))
    if env.observation_space.shape != model.observation_space.shape:
        env.close()
        hint = (" (give the wrapper it was trained with, --wrapper, or its obs_mode in --env-kwargs)"
                if meta.get("env_id") is None else "")
        raise ValueError(f"model {path} expects observations of shape {model.observation_space.shape}, the "
                         f"environment {env_id} with wrapper {meta['wrapper']!r} gives {env.observation_space.shape}"
                         f"{hint}")
    return env, SB3Policy(model, vn, env)


class VectorSB3Policy(SB3Policy):
    """An SB3 model (+ optional VecNormalize statistics) acting for N robots at once (the
    :class:`agents.vector_rollout.VectorActor` protocol): one batched deterministic ``predict`` per step.

    Args: as :class:`SB3Policy`, ``env`` the (wrapped) vector env it acts on; ``estimate`` is then (N, 3).
    """

    def reset(self, obs: np.ndarray, mask=None) -> None:
        """Nothing to reset: the model acts on each observation alone (the wrapper restarts its filters)."""

    def act(self, obs: np.ndarray) -> np.ndarray:
        """(N, A) float32 actions for the observations (N, D)."""
        return super().act(obs).reshape(np.shape(obs)[0], -1)


def wrap_vector_for(venv, meta: dict):
    """``venv`` (a native vector env) wrapped as the model of ``meta`` (its meta.json) was trained: the EKF
    features (``residual-ekf-pid``: the model's residual bound; ``ekf-features``: 0) or the reference
    feed-forward; unwrapped for ``none`` (:func:`agents.wrappers.wrap_vector_env`, the environment's reward)."""
    from agents.wrappers import wrap_vector_env

    default = 0.5 if meta["wrapper"] == "feedforward" else 0.3  # meta.json without the key (older models)
    return wrap_vector_env(venv, meta["wrapper"], float(meta.get("residual_scale", default)))


def build_vector(path: str | Path, num: int, env_id: str | None = None, env_kwargs: dict | None = None,
                 options: ModelOptions | None = None):
    """(vector env, :class:`VectorSB3Policy`): :func:`build` for ``num`` robots at once.

    The env is :func:`agents.vector_rollout.make_vector_env` (``next_step`` autoreset, the model's
    observation mode) wrapped, for the EKF-feature models, by :class:`agents.wrappers.VectorEKFFeatures`
    (``residual-ekf-pid``: the model's residual bound; ``ekf-features``: 0). Each robot's episode equals the
    single :func:`build` environment's within float rounding (the batched EKF; ``tests/test_vector_rollout.py``).
    """
    from agents.vector_rollout import make_vector_env

    meta, model, vn = load(path, options)
    env_id = env_id or meta.get("env_id")
    if env_id is None:
        raise ValueError(f"{path}: the model does not record its environment: give the environment id")
    kw = dict(env_kwargs or {})
    obs_mode = meta.get("obs_mode", "sensors") or kw.get("obs_mode", "sensors")
    if kw.get("obs_mode", obs_mode) != obs_mode:
        raise ValueError(f"model {path} was trained with obs_mode={obs_mode!r}; got obs_mode={kw['obs_mode']!r}")
    kw.pop("obs_mode", None)
    venv = wrap_vector_for(make_vector_env(env_id, num, kw, obs_mode=obs_mode), meta)
    if venv.single_observation_space.shape != model.observation_space.shape:
        venv.close()
        raise ValueError(f"model {path} expects observations of shape {model.observation_space.shape}, the "
                         f"environment {env_id} with wrapper {meta['wrapper']!r} gives "
                         f"{venv.single_observation_space.shape}")
    return venv, VectorSB3Policy(model, vn, venv)
