"""Actor networks named in hyperparameter files.

:class:`AffineSkip` is a features extractor whose output is the observation itself next to a small MLP of it,
``[x, mlp(x)]``. Under an actor with no hidden layer (``net_arch=dict(pi=[], ...)``) the action mean is then
``W₁·x + W₂·mlp(x) + b``: an affine map (which a least-squares behaviour clone fits exactly, as for the plain
affine actor: :func:`agents.behaviour_cloning.fit_linear` zeroes ``W₂``) plus a nonlinear correction that starts
at zero and that fine-tuning can grow. The affine actor is the law's exact clone but one map for every floor;
this one can be the law on a floor where the wheels grip and a different controller where they slip
(docs/agents.md, "Floor randomisation"). Hyperparameter files name it in ``policy_kwargs``::

    policy_kwargs: "dict(features_extractor_class=AffineSkip, features_extractor_kwargs=dict(hidden=64),
                         share_features_extractor=False, net_arch=dict(pi=[], vf=[64, 64]), log_std_init=-3.5)"
"""

from __future__ import annotations

import gymnasium as gym
import torch
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from torch import nn


class AffineSkip(BaseFeaturesExtractor):
    """Features ``[x, tanh-MLP(x)]`` of a flat Box observation x (D,): D + ``hidden`` features.

    Args:
        observation_space: the (flat) observation space.
        hidden: width of the MLP's two tanh layers.
    """

    def __init__(self, observation_space: gym.spaces.Box, hidden: int = 64) -> None:
        dim = int(observation_space.shape[0])
        super().__init__(observation_space, features_dim=dim + int(hidden))
        self.obs_dim = dim
        self.mlp = nn.Sequential(nn.Linear(dim, hidden), nn.Tanh(), nn.Linear(hidden, hidden), nn.Tanh())

    def forward(self, observations: torch.Tensor) -> torch.Tensor:
        x = observations.reshape(observations.shape[0], -1).float()
        return torch.cat([x, self.mlp(x)], dim=1)
