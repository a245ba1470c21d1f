"""Behaviour-cloning warm start of a privileged full-twist agent from the true-state feedback law.

A privileged agent (``obs_mode="state"``, full twist, no controller underneath) trained from scratch
must first discover that its action should be about the reference velocity; until then every episode is
lost within a second and carries no tracking signal (docs/agents.md, "Diagnosis"). Here the actor is
instead pre-trained, by supervised regression, on the actions of :class:`agents.feedback_law.TrueStateFeedback`
(reference feed-forward + k·error) in the training environments, and RL fine-tunes it from there. The
agent still outputs the whole twist: the law only supplies the initial weights (and, for SAC, the
policy the critic first learns about). Agents so trained are labelled "BC-initialised from the feedback
law" (``meta.json`` ``bc_init``).

Data: ``rollout_steps`` vector steps of the training environments (all robots), driven by the law's
action plus Gaussian noise of std ``noise`` (action units; so the data holds the law's recoveries from
states it would not reach itself) and labelled with the law's noise-free action. With VecNormalize the
running observation statistics are updated by these steps, and the regression sees the observations as
the policy will.

Fit: an affine PPO actor (``net_arch=dict(pi=[], ...)``) is solved by least squares on the law's
unclipped actions: the law is affine in the state observation and PPO clips to the action box as the law
does, so the clone is the law itself (to float32 rounding). Any other actor (hidden layers; SAC's
tanh-squashed mean) is regressed on the clipped actions by Adam (mean squared error, ``epochs`` passes in
minibatches of ``batch_size``, learning rate decaying linearly to 0), then optionally ``lbfgs_steps`` of
full-batch L-BFGS. Afterwards the policy's log std is set to ``log_std`` (small: exploration noise of
σ = e^log_std in action units, so fine-tuning starts near the clone).

Teachers (``teacher``): ``"law"`` (above; a privileged agent on the ``state`` observation) or ``"ekf-pid"``
(an agent on the EKF features, :class:`agents.wrappers.VectorEKFFeatures` with ``residual_scale`` 0: the
label is the ekf-pid twist the features already hold, :func:`agents.wrappers.pid_twist_columns`; the data are
driven by it plus the same action noise). The features are affine in nothing simpler, but ekf-pid's action is
one of them: an affine actor's clone of it is exact, so such an agent starts as ``ekf-pid``, and only sees
what a real robot's filter knows. Labelled "BC-initialised from ekf-pid".

Hyperparameter files name it as a callback (RL Zoo syntax)::

    callback:
      - agents.callbacks.BehaviourCloningInit: {gain: 2.0, rollout_steps: 512, noise: 0.05, log_std: -3.0}
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np


@dataclass(frozen=True)
class BCSpec:
    """Behaviour-cloning settings (see the module docstring); units: ``gain`` 1/s, ``noise`` action units."""

    gain: float = 2.0
    rollout_steps: int = 512
    noise: float = 0.1
    epochs: int = 30
    batch_size: int = 4096
    learning_rate: float = 1e-3
    log_std: float = -2.5
    lbfgs_steps: int = 0  # full-batch L-BFGS iterations after Adam, for the precision millimetres need
    actor_warmup: int = 0  # environment steps during which the actor is held at its clone (critic warm-up)
    teacher: str = "law"  # "law" (true-state feedback law, `state` observation) or "ekf-pid" (EKF features)

    def as_dict(self) -> dict:
        return asdict(self)


BC_KEYS = tuple(BCSpec.__dataclass_fields__)
TEACHERS = {"law": "BC-initialised from the feedback law", "ekf-pid": "BC-initialised from ekf-pid"}


def _raw_obs(venv, obs: np.ndarray) -> np.ndarray:
    from stable_baselines3.common.vec_env import VecNormalize

    return venv.get_original_obs() if isinstance(venv, VecNormalize) else obs


def _normalise(venv, raw: np.ndarray) -> np.ndarray:
    from stable_baselines3.common.vec_env import VecNormalize

    return venv.normalize_obs(raw) if isinstance(venv, VecNormalize) else raw


def _state_decoder(venv):
    """The ``state`` decoder of the omni-gym vector env under an SB3 VecEnv (native) stack."""
    from omni_gym.envs.observations import StateObsDecoder

    inner = venv
    while hasattr(inner, "venv"):
        inner = inner.venv
    return StateObsDecoder.for_env(inner)


def _teacher(venv, spec: BCSpec):
    """The teacher's action before clipping, as a function of raw observations (M, D) -> (M, 3)."""
    if spec.teacher == "ekf-pid":
        from agents.wrappers import pid_twist_columns

        cols = pid_twist_columns(int(venv.observation_space.shape[0]))
        return lambda raw: np.asarray(raw, dtype=float)[:, cols]
    from agents.feedback_law import law_actions

    decode = _state_decoder(venv)
    return lambda raw: law_actions(decode, np.asarray(raw, dtype=float), spec.gain, clip=False)


def collect(venv, spec: BCSpec, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Drive ``venv`` (an SB3 VecEnv over a native env: ``state`` for the law, EKF features for ekf-pid) with
    the noisy teacher for ``spec.rollout_steps`` vector steps; returns (raw observations (M, D), the
    teacher's actions before clipping to the action box (M, 3))."""
    teacher = _teacher(venv, spec)
    obs = venv.reset()
    xs, ys = [], []
    for _ in range(spec.rollout_steps):
        raw = _raw_obs(venv, obs)
        label = teacher(raw)
        xs.append(np.array(raw, dtype=np.float32))
        ys.append(label.astype(np.float32))
        act = np.clip(label + spec.noise * rng.standard_normal(label.shape), -1.0, 1.0)
        obs, _, _, _ = venv.step(act.astype(np.float32))
    return np.concatenate(xs), np.concatenate(ys)


def _actor_mean(model, x):
    from stable_baselines3 import PPO, SAC

    if isinstance(model, PPO):
        return model.policy.get_distribution(x).distribution.mean
    if isinstance(model, SAC):
        return model.actor(x, deterministic=True)
    raise ValueError(f"behaviour cloning supports PPO and SAC, got {type(model).__name__}")


def _actor_params(model):
    from stable_baselines3 import PPO

    if isinstance(model, PPO):
        p = model.policy
        return [*p.mlp_extractor.policy_net.parameters(), *p.action_net.parameters()]
    return list(model.actor.parameters())


def _linear_actor(model) -> bool:
    """PPO with no hidden layer in the actor (``net_arch=dict(pi=[], ...)``) on the observation itself or on
    :class:`agents.networks.AffineSkip`'s ``[x, mlp(x)]``: its mean is affine in the observation (plus, for
    the latter, a nonlinear term that the clone sets to zero), as the law is."""
    from stable_baselines3 import PPO

    if not isinstance(model, PPO) or len(list(model.policy.mlp_extractor.policy_net.parameters())) > 0:
        return False
    from stable_baselines3.common.torch_layers import FlattenExtractor

    from agents.networks import AffineSkip

    return isinstance(model.policy.pi_features_extractor, (FlattenExtractor, AffineSkip))


def fit_linear(model, x: np.ndarray, y: np.ndarray) -> float:
    """Least squares of an affine actor's mean on the unclipped labels ``y`` (PPO clips its actions to the box
    as the law does, so the fit is the law itself wherever the data span the observation space); returns the
    mean squared error of the clipped actions."""
    import torch

    X = np.column_stack([x.astype(float), np.ones(len(x))])
    coef, *_ = np.linalg.lstsq(X, y.astype(float), rcond=None)
    layer = model.policy.action_net
    d = x.shape[1]
    with torch.no_grad():
        # Features [x, mlp(x)] (agents.networks.AffineSkip): the clone on x, the nonlinear part starts at 0.
        layer.weight.zero_()
        layer.weight[:, :d] = torch.as_tensor(coef[:-1].T, dtype=layer.weight.dtype)
        layer.bias.copy_(torch.as_tensor(coef[-1], dtype=layer.bias.dtype))
    return float(np.mean((np.clip(X @ coef, -1, 1) - np.clip(y, -1, 1)) ** 2))


def fit(model, x: np.ndarray, y: np.ndarray, spec: BCSpec, rng: np.random.Generator) -> list[float]:
    """Regress the actor's deterministic action on the clipped labels ``y`` for (normalised) observations
    ``x`` (an affine PPO actor: :func:`fit_linear` instead); returns the mean squared error (action units²)
    after each epoch."""
    import torch

    if _linear_actor(model):
        return [fit_linear(model, x, y)]
    y = np.clip(y, -1.0, 1.0)

    xt = torch.as_tensor(x, dtype=torch.float32)
    yt = torch.as_tensor(y, dtype=torch.float32)
    opt = torch.optim.Adam(_actor_params(model), lr=spec.learning_rate)
    # Learning rate decays linearly to 0 over the epochs: the law's feedback term at millimetre errors is a
    # few thousandths of the action range, which a constant-rate Adam keeps jittering over.
    sched = torch.optim.lr_scheduler.LambdaLR(opt, lambda e: 1.0 - e / spec.epochs)
    losses = []
    n = len(xt)
    for _ in range(spec.epochs):
        order = torch.as_tensor(rng.permutation(n))
        total = 0.0
        for start in range(0, n, spec.batch_size):
            idx = order[start:start + spec.batch_size]
            loss = torch.mean((_actor_mean(model, xt[idx]) - yt[idx]) ** 2)
            opt.zero_grad()
            loss.backward()
            opt.step()
            total += loss.item() * len(idx)
        losses.append(total / n)
        sched.step()
    if spec.lbfgs_steps > 0:
        lbfgs = torch.optim.LBFGS(_actor_params(model), lr=1.0, max_iter=spec.lbfgs_steps, history_size=50,
                                  line_search_fn="strong_wolfe", tolerance_grad=1e-12, tolerance_change=1e-15)

        def closure():
            lbfgs.zero_grad()
            loss = torch.mean((_actor_mean(model, xt) - yt) ** 2)
            loss.backward()
            return loss

        lbfgs.step(closure)
        with torch.no_grad():
            losses.append(float(torch.mean((_actor_mean(model, xt) - yt) ** 2)))
    return losses


def set_log_std(model, log_std: float) -> None:
    """The policy's initial log std (PPO: the state-independent parameter; SAC: the log-std layer's
    output, made state-independent by zeroing its weights)."""
    import torch
    from stable_baselines3 import PPO

    with torch.no_grad():
        if isinstance(model, PPO):
            model.policy.log_std.fill_(log_std)
        else:
            model.actor.log_std.weight.zero_()
            model.actor.log_std.bias.fill_(log_std)


def behaviour_clone(model, venv, spec: BCSpec, seed: int) -> dict:
    """Collect law data in ``venv``, fit ``model``'s actor, set its log std; returns a summary for meta.json
    (the settings, samples, the fit's first and last epoch MSE and the wall time [s])."""
    import time

    t0 = time.time()
    rng = np.random.default_rng(seed)
    raw, labels = collect(venv, spec, rng)
    losses = fit(model, _normalise(venv, raw), labels, spec, rng)
    set_log_std(model, spec.log_std)
    if hasattr(model, "actor_target") and model.actor_target is not None:  # TD3-like targets follow the actor
        model.actor_target.load_state_dict(model.actor.state_dict())
    return {**spec.as_dict(), "samples": int(len(raw)), "mse_first_epoch": losses[0], "mse_last_epoch": losses[-1],
            "wall_s": round(time.time() - t0, 1),
            "label": TEACHERS[spec.teacher]}
