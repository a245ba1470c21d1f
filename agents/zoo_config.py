"""The RL Zoo keys of one hyperparameter entry that name classes: ``env_wrapper`` and ``callback``.

Read both by the trainer (:mod:`agents.train`, from ``agents/hyperparams/*.yml``) and by the model
loader (:mod:`agents.sb3_policy`, from an RL Zoo output folder's ``config.yml``), so it sits below both.
The earlier layout (``env_wrapper: <name>`` plus the keys of :data:`LEGACY_KEYS`) is still read.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from agents.wrappers import WRAPPERS

LEGACY_KEYS = ("residual_scale", "reward", "sensor_noise_range", "residual_init", "init_log_std")
NOISE_WRAPPER = "agents.wrappers.SensorNoiseRandomizer"
EKF_WRAPPER = "agents.wrappers.EKFFeatures"
REWARD_WRAPPER = "agents.rewards.TrackingReward"
FF_WRAPPER = "agents.wrappers.FeedForwardTwist"
RESIDUAL_INIT = "agents.callbacks.ResidualInit"
BC_INIT = "agents.callbacks.BehaviourCloningInit"


@dataclass(frozen=True)
class WrapperSpec:
    """The wrapper stack of a hyperparameter entry (see :func:`agents.wrappers.wrap_env`).

    ``name``: one of :data:`agents.wrappers.WRAPPERS`; ``residual_scale``: the residual bound (fraction of
    the action range); ``reward``: one of :data:`agents.rewards.REWARDS`; ``sensor_noise_range``:
    ``[lo, hi]`` sensor-noise scale per episode, or None.
    """

    name: str = "none"
    residual_scale: float = 0.3
    reward: str = "env"
    sensor_noise_range: list[float] | None = None


def _zoo_entries(value, key: str, where: str) -> list[tuple[str, dict]]:
    """The RL Zoo's list syntax (``- path`` or ``- path: {kw: v}``, or a single entry) as (path, kwargs)."""
    if value is None:
        return []
    out = []
    for item in value if isinstance(value, list) else [value]:
        if isinstance(item, str):
            out.append((item, {}))
        elif (isinstance(item, dict) and len(item) == 1 and isinstance(next(iter(item)), str)
              and isinstance(next(iter(item.values())), (dict, type(None)))):
            path, kw = next(iter(item.items()))
            out.append((path, dict(kw or {})))
        else:
            raise ValueError(f"{where}: {key}: each entry must be a class path or {{class path: {{keyword: value}}}}, "
                             f"got {item!r}")
    return out


def _known_keywords(path: str, kw: dict, allowed: tuple[str, ...], key: str, where: str) -> None:
    unknown = sorted(set(kw) - set(allowed))
    if unknown:
        raise ValueError(f"{where}: {key}: {path}: unknown keyword {unknown[0]!r} (known: {', '.join(allowed)})")


def wrapper_spec(hp: dict, where: str) -> WrapperSpec:
    """Read ``env_wrapper`` (RL Zoo list of classes, or the earlier name + keys) of one hyperparameter entry."""
    value = hp.get("env_wrapper")
    if value is None or (isinstance(value, str) and "." not in value):  # the earlier layout
        name = str(hp.get("env_wrapper", "none"))
        if name not in WRAPPERS:
            raise ValueError(f"{where}: env_wrapper {name!r}: use a wrapper class path such as {EKF_WRAPPER} "
                             f"(or one of the names {', '.join(WRAPPERS)})")
        noise = hp.get("sensor_noise_range")
        return WrapperSpec(name, float(hp.get("residual_scale", 0.3)), str(hp.get("reward", "env")),
                           None if noise is None else [float(v) for v in noise])
    stray = [k for k in LEGACY_KEYS if k in hp]
    if stray:
        raise ValueError(f"{where}: key {stray[0]!r} belongs to the earlier layout; with env_wrapper as a list "
                         f"of classes give it as a keyword of the wrapper or of {RESIDUAL_INIT}")
    spec = WrapperSpec()
    seen: list[str] = []
    for path, kw in _zoo_entries(value, "env_wrapper", where):
        if path == NOISE_WRAPPER and not seen:
            _known_keywords(path, kw, ("scale_range",), "env_wrapper", where)
            if "scale_range" not in kw:
                raise ValueError(f"{where}: env_wrapper: {path} needs the keyword 'scale_range' ([low, high])")
            spec = replace(spec, sensor_noise_range=[float(v) for v in kw["scale_range"]])
        elif path == EKF_WRAPPER and EKF_WRAPPER not in seen:
            _known_keywords(path, kw, ("residual_scale", "reward"), "env_wrapper", where)
            scale = float(kw.get("residual_scale", 0.3))  # EKFFeatures' default
            spec = replace(spec, name="residual-ekf-pid" if scale > 0 else "ekf-features", residual_scale=scale,
                           reward=str(kw.get("reward", "env")))
        elif path == FF_WRAPPER and not seen:  # privileged: reference feed-forward + correction
            _known_keywords(path, kw, ("scale",), "env_wrapper", where)
            spec = replace(spec, name="feedforward", residual_scale=float(kw.get("scale", 0.5)))
        elif path == REWARD_WRAPPER and (not seen or seen == [FF_WRAPPER]):  # privileged: the reward, no EKF
            _known_keywords(path, kw, ("reward",), "env_wrapper", where)
            spec = replace(spec, reward=str(kw.get("reward", "squared")))
        else:
            raise ValueError(f"{where}: env_wrapper: {path!r}: this trainer builds {NOISE_WRAPPER} then {EKF_WRAPPER} "
                             f"(each at most once, in this order), or {REWARD_WRAPPER} alone (privileged; optionally "
                             f"after {FF_WRAPPER})")
        seen.append(path)
    return spec


def residual_init(hp: dict, where: str) -> tuple[float | None, float | None, int]:
    """(factor, SAC log std, actor warm-up steps) of the ``ResidualInit`` callback (or the earlier
    ``residual_init`` keys, which have no warm-up)."""
    if "callback" not in hp:
        factor, log_std = hp.get("residual_init"), hp.get("init_log_std")
        return (None if factor is None else float(factor)), (None if log_std is None else float(log_std)), 0
    factor = log_std = None
    warmup = 0
    for path, kw in _zoo_entries(hp["callback"], "callback", where):
        if path == BC_INIT:
            continue  # read by bc_init_spec
        if path != RESIDUAL_INIT:
            raise ValueError(f"{where}: callback: {path!r}: this trainer knows only {RESIDUAL_INIT} and {BC_INIT}")
        _known_keywords(path, kw, ("factor", "log_std", "actor_warmup"), "callback", where)
        factor = float(kw.get("factor", 0.01))
        log_std = None if kw.get("log_std") is None else float(kw["log_std"])
        warmup = kw.get("actor_warmup", 0)
        if isinstance(warmup, bool) or not isinstance(warmup, int) or warmup < 0:
            raise ValueError(f"{where}: callback: {path}: actor_warmup must be an integer >= 0, got {warmup!r}")
    return factor, log_std, warmup


def bc_init_spec(hp: dict, where: str):
    """The :class:`agents.behaviour_cloning.BCSpec` of a ``BehaviourCloningInit`` callback entry, or None."""
    from agents.behaviour_cloning import BC_KEYS, BCSpec

    if "callback" not in hp:
        return None
    for path, kw in _zoo_entries(hp["callback"], "callback", where):
        if path == BC_INIT:
            _known_keywords(path, kw, BC_KEYS, "callback", where)
            try:
                spec = BCSpec(**{k: type(getattr(BCSpec, k))(v) for k, v in kw.items()})
            except (TypeError, ValueError) as exc:
                raise ValueError(f"{where}: callback: {path}: {exc}") from None
            from agents.behaviour_cloning import TEACHERS

            if spec.teacher not in TEACHERS:
                raise ValueError(f"{where}: callback: {path}: teacher {spec.teacher!r}: choose one of "
                                 f"{', '.join(TEACHERS)}")
            if spec.rollout_steps < 1 or spec.epochs < 1 or spec.batch_size < 1 or spec.gain < 0 or spec.noise < 0:
                raise ValueError(f"{where}: callback: {path}: rollout_steps, epochs, batch_size must be >= 1 and "
                                 f"gain, noise >= 0")
            return spec
    return None
