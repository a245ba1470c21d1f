"""RLlib (Ray) training and evaluation of the omni-gym agents: the ``rllib`` extra (``ray[rllib]``).

Modules import ray only inside functions, so ``import agents.rllib.X`` works without the extra and the
first use names it in one line (:func:`omni_gym.rllib.require_ray`). Bottom up:

* :mod:`.config`: the PPO configuration files (``agents/rllib/ppo.yml``, one entry per path-following id)
  read into :class:`.config.RLlibHyperparams`, and the ``PPOConfig`` built from them;
* :mod:`.env`: the training environment's RLlib creator (native vector env + the training reward);
* :mod:`.policy`: a trained RLlib checkpoint as a policy of the ``reset``/``act`` protocol (evaluation);
* :mod:`.train`: ``omni-gym train --backend rllib``.
"""
