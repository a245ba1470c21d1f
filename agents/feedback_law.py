"""The true-state feedback law: reference feed-forward plus proportional feedback (privileged, scripted).

For N robots reading the ``state`` observation (``obs_mode="state"``; true errors, body frame)::

    v_body = v_ref,body + k·e_body,    ω = ω_ref + k·e_θ

clipped to the action box (``action_mode="twist"``, action = twist / (v_max, v_max, ω_max)), with
e_body [m] the reference − robot position in the robot's body frame, e_θ = wrap(θ_ref − θ) [rad] and k
[1/s] the gain: the errors decay as exp(−k·t) while the wheels follow. It is what perfect estimation is
worth with the simplest control law: a reference point for learned privileged agents (the same
observation), not a robot controller and not an upper bound on control. ``benchmarks/headroom.py``
compares it with ``ekf-pid``; ``benchmarks/normalised_score.py`` scores it.
"""

from __future__ import annotations

import numpy as np

from omni_gym.envs.observations import POS_SCALE, StateObsDecoder

DEFAULT_GAIN = 2.0  # 1/s: the middle of headroom.md's 1, 2, 4 /s (none tuned on the benchmark seeds)


class TrueStateFeedback:
    """Feed-forward + proportional feedback on the ``state`` observation of N robots (privileged).

    ``gain`` k [1/s]. Follows :class:`agents.vector_rollout.VectorActor`; stateless, so ``reset`` does nothing.
    """

    def __init__(self, vec_env, gain: float = DEFAULT_GAIN) -> None:
        self.decode = StateObsDecoder.for_env(vec_env)
        sc = self.decode.scales
        self.gain = float(gain)
        self.twist_scale = np.array([sc.max_speed, sc.max_speed, sc.max_yaw_rate])

    def reset(self, obs: np.ndarray, mask=None) -> None:
        """Nothing to reset: the law reads only the current observation."""

    def act(self, obs: np.ndarray) -> np.ndarray:
        return law_actions(self.decode, np.asarray(obs, dtype=float), self.gain)


def law_actions(decode: StateObsDecoder, obs: np.ndarray, gain: float = DEFAULT_GAIN, clip: bool = True) -> np.ndarray:
    """The law's actions (N, 3) for ``state`` observations ``obs`` (N, D) of the layout ``decode`` reads
    (``clip=False``: before clipping to the action box; linear in ``obs``).

    Vectorised form of :class:`TrueStateFeedback` (one array expression, no per-row decoding), for
    behaviour cloning (:mod:`agents.behaviour_cloning`) where millions of rows are labelled.
    """
    sc = decode.scales
    twist = np.array([sc.max_speed, sc.max_speed, sc.max_yaw_rate])
    if obs.ndim != 2 or obs.shape[1] != decode.dim:
        raise ValueError(f"state observations must have shape (N, {decode.dim}), got {obs.shape}")
    L = decode.layout
    ref = obs[:, L["reference_velocity"]] * twist  # m/s, m/s, rad/s
    err = np.column_stack([obs[:, L["tracking_error_body"]] * POS_SCALE,
                           obs[:, L["heading_error"]][:, 0] * np.pi])  # m, m, rad
    a = (ref + gain * err) / twist
    return np.clip(a, -1.0, 1.0) if clip else a
