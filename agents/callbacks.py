"""Training callbacks named in the hyperparameter files (``callback:`` in the RL Zoo's format).

:class:`ResidualInit` makes a freshly built residual agent start as its baseline: it scales the actor's
output layer by ``factor`` and zeroes its bias, so the initial action (the residual added to the PID's
twist, see :class:`agents.wrappers.EKFFeatures`) is ≈ 0. ``agents/train.py`` applies the same
initialisation right after building the model; ``python -m rl_zoo3.train`` applies it through this
callback when training starts. The scaling draws no random numbers, so the two give the same weights.
"""

from __future__ import annotations

from stable_baselines3.common.callbacks import BaseCallback


def init_residual(model, factor: float, log_std: float | None = None) -> None:
    """Scale the actor's output layer of ``model`` (PPO, SAC or TD3) by ``factor`` and zero its bias.

    ``log_std`` (SAC only): the log-std layer is scaled by ``factor`` and its bias set to ``log_std``
    (the initial log standard deviation of the action, in units of the [-1, 1] action range).
    """
    import torch
    from stable_baselines3 import PPO, SAC, TD3

    if not isinstance(model, (PPO, SAC, TD3)):
        raise ValueError(f"ResidualInit supports PPO, SAC and TD3, got {type(model).__name__}")
    with torch.no_grad():
        if isinstance(model, PPO):
            layer = model.policy.action_net
        elif isinstance(model, SAC):
            layer = model.actor.mu
        else:
            layer = model.actor.mu[-2]  # the Linear before TD3's final Tanh
        layer.weight.mul_(factor)
        layer.bias.zero_()
        if isinstance(model, SAC) and log_std is not None:
            model.actor.log_std.weight.mul_(factor)
            model.actor.log_std.bias.fill_(log_std)
        if isinstance(model, TD3):
            model.actor_target.load_state_dict(model.actor.state_dict())


class BehaviourCloningInit(BaseCallback):
    """At the start of training from scratch, :func:`agents.behaviour_cloning.behaviour_clone` of the actor
    on the true-state feedback law in the training environments (keywords: the fields of
    :class:`agents.behaviour_cloning.BCSpec`). For the RL Zoo; ``agents/train.py`` does the same right
    after building the model, and for SAC also holds the actor for ``actor_warmup`` steps."""

    def __init__(self, verbose: int = 0, **kwargs) -> None:
        from agents.behaviour_cloning import BCSpec

        super().__init__(verbose)
        self.spec = BCSpec(**kwargs)
        self.summary: dict | None = None

    def _on_training_start(self) -> None:
        from agents.behaviour_cloning import behaviour_clone

        if self.model.num_timesteps == 0:
            self.summary = behaviour_clone(self.model, self.training_env, self.spec, int(self.model.seed or 0))

    def _on_step(self) -> bool:
        return True


class HoldActor(BaseCallback):
    """After behaviour cloning: for the first ``steps`` environment steps the actor (PPO: the policy network,
    the action layer and log std; SAC: the actor) is put back to its weights at the start before every
    rollout (PPO) or after every step (SAC), while the critic trains. The critic then first learns the
    value of the cloned policy; a randomly initialised critic would otherwise give the first policy updates
    advantages that are noise, and pull the clone anywhere."""

    def __init__(self, steps: int, verbose: int = 0) -> None:
        super().__init__(verbose)
        self.steps = int(steps)
        self._state = None

    def _actor_modules(self):
        from stable_baselines3 import PPO

        if isinstance(self.model, PPO):
            p = self.model.policy
            held = {"policy_net": p.mlp_extractor.policy_net, "action_net": p.action_net}
            if not p.share_features_extractor:  # the actor's own extractor (e.g. agents.networks.AffineSkip)
                held["pi_features_extractor"] = p.pi_features_extractor
            return held
        return {"actor": self.model.actor}

    def _save(self) -> None:
        import copy

        self._state = {k: copy.deepcopy(m.state_dict()) for k, m in self._actor_modules().items()}
        log_std = getattr(self.model.policy, "log_std", None)
        self._log_std = None if log_std is None or not hasattr(log_std, "detach") else log_std.detach().clone()

    def _restore(self) -> None:
        import torch

        for k, m in self._actor_modules().items():
            m.load_state_dict(self._state[k])
        if self._log_std is not None:
            with torch.no_grad():
                self.model.policy.log_std.copy_(self._log_std)

    def _on_training_start(self) -> None:
        self._save()

    def _hold(self) -> None:
        if self._state is not None and self.num_timesteps < self.steps:
            self._restore()
        elif self._state is not None:
            self._state = None  # released: the algorithm trains the actor from here on

    def _on_rollout_start(self) -> None:
        self._hold()

    def _on_step(self) -> bool:
        from stable_baselines3 import SAC

        if isinstance(self.model, SAC):
            self._hold()
        return True

    def _on_training_end(self) -> None:
        if self._state is not None:  # training ended within the warm-up: undo the last updates
            self._restore()


class ResidualInit(HoldActor):
    """At the start of training from scratch, :func:`init_residual` (see the module doc), then (``actor_warmup``
    > 0) the actor is held at that start for that many environment steps while the critic learns its value
    (:class:`HoldActor`).

    Args:
        factor: scale of the actor's output layer (e.g. 0.01: the policy starts at 1 % of its output; 0: exactly
            at the baseline).
        log_std: SAC's initial log std (None: SB3's default).
        actor_warmup: environment steps of the critic warm-up (0: none).
    """

    def __init__(self, factor: float = 0.01, log_std: float | None = None, actor_warmup: int = 0,
                 verbose: int = 0) -> None:
        super().__init__(actor_warmup, verbose)
        self.factor = float(factor)
        self.log_std = None if log_std is None else float(log_std)

    def _on_training_start(self) -> None:
        if self.model.num_timesteps == 0:  # not when training continues from a saved agent
            init_residual(self.model, self.factor, self.log_std)
            if self.steps > 0:
                self._save()
