"""Scripted baselines (EKF + PID) and Stable-Baselines3 agents for the omni-gym environments.

The SB3 parts (training, loading a trained model) need the ``agents`` extra
(``pip install -c constraints.txt -e '.[agents]'`` from the checkout's root: torch, stable-baselines3,
pyyaml); the scripted baselines do not.

Modules import only downward (``tests/test_architecture.py``): :mod:`.algorithms` (the SB3 algorithm
table) and :mod:`.rollout` (``make_env``, ``run_episode``, the ``Policy`` protocol) at the bottom;
:mod:`.zoo_config` (RL Zoo wrapper/callback keys) on :mod:`.wrappers`; :mod:`.sb3_vec_env` (SB3's
``VecEnv`` over the native vector env) on the environments only; :mod:`.sb3_policy` (loading trained
models) and :mod:`.evaluate` (statistics over episodes) above them; :mod:`.train` on top.
:mod:`.batched` (the EKF, slip detector, PID and scripted policies for N robots at once) builds on
:mod:`.ekf`, :mod:`.slip_detector` and :mod:`.pid`; :mod:`.wrappers` uses it for ``VectorEKFFeatures``.
"""

from __future__ import annotations

import importlib.util

# import name -> distribution name, for the message
AGENTS_EXTRA = {"torch": "torch", "stable_baselines3": "stable-baselines3", "yaml": "pyyaml"}
# How to install it: constraints.txt (in the source tree) pins torch's CPU build; without it pip may fetch a
# multi-gigabyte CUDA build (README, "Install with pip").
AGENTS_EXTRA_HINT = ("pip install -c constraints.txt -e '.[agents]' from the omni-gym checkout's root (constraints.txt "
                     "pins torch's CPU build; without it pip may download a multi-gigabyte CUDA build)")
# Marks this package as omni-gym's: another distribution (the OpenAI Agents SDK, ``openai-agents``) installs a
# top-level ``agents`` package too, and the command line checks which one Python finds.
OMNI_GYM_AGENTS = True


def require_agents_extra(purpose: str) -> None:
    """Raise ``ModuleNotFoundError`` naming the extra when a package of the ``agents`` extra is missing.

    ``purpose`` says what needed it (e.g. ``"omni-gym train"``); the message is one line.
    """
    missing = [dist for mod, dist in AGENTS_EXTRA.items() if importlib.util.find_spec(mod) is None]
    if missing:
        raise ModuleNotFoundError(f"{purpose} needs the agents extra (missing: {', '.join(missing)}): "
                                  f"{AGENTS_EXTRA_HINT}", name=missing[0])
