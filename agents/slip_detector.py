"""Per-wheel slip and lift-off detection for :class:`agents.ekf.OmniEKF`.

Every control period the filter hands the detector the wheel-speed innovation vector

    ν = z − W·q̂⁻        (n,) rad/s,  covariance  S = W·P_qq·Wᵀ + σ_w²·I

where z are the encoder rates, W the wheel matrix, q̂⁻ = (vx, vy, ω) the filter's twist *before*
any wheel is used (constant-velocity prediction refined by the gyro and the accelerometer) and P_qq
its covariance. With R = σ_w²·I the Gaussian log-likelihood of ν splits exactly into two independent
parts, which give the detector's three cues:

* the **wheel-consistency residual** r = (I − W W⁺)·z = (I − W W⁺)·ν: the part of the encoder
  rates no rigid no-slip motion produces (zero for three wheels; one direction for four), covariance
  σ_w²·(I − W W⁺), independent of the prior;
* the **encoder twist against the predicted twist** W⁺·ν = W⁺z − q̂⁻, whose ω component is the
  encoder-derived yaw rate against the gyro (the gyro is already in q̂⁻) and whose velocity components
  compare the wheels with the accelerometer-propagated velocity.

The per-wheel NIS ν_i²/S_ii is the marginal of the same Gaussian. A single redundant direction
cannot tell *which* wheel slips (on the symmetric four-wheel robot a fault on wheel 1 looks exactly
like a fault on wheel 3 plus a body translation along wheel 1's drive direction); the
accelerometer-propagated velocity in q̂⁻ resolves that ambiguity, which is why the filter runs the
accelerometer update before the detector.

Hypothesis test. For every set F of faulty wheels (all 2ⁿ sets, or those with at most
``max_faults`` members) the innovation is modelled as ν ~ N(0, S + σ_f²·D_F), D_F the diagonal
indicator of F: a slipping or lifted wheel's reading carries an extra independent error of std
σ_f = ``fault_speed_std``/r (the spread of slip speeds). Each wheel carries a two-state Markov
prior (fault onset and recovery rates), and the posterior over the sets gives each wheel's
marginal belief that it is faulty (a factored HMM: the marginals are propagated, not the joint).

Hysteresis. A wheel in use is dropped when its belief exceeds ``exclude_belief``; a dropped wheel
comes back after its belief has stayed below ``include_belief`` for ``include_steps`` consecutive
periods ("until it agrees again"). The belief itself already has memory through the Markov prior.

What cannot be detected: a lifted wheel whose speed equals the rigid-body motion (e.g. a wheel
commanded consistently with the others under ideal actuation while the wheels still on the floor
grip) produces no discrepancy in any sensor; it is also harmless to the odometry.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class DetectorConfig:
    """Parameters of :class:`SlipDetector`.

    Attributes:
        fault_speed_std: std [m/s] of the rim-speed error of a slipping or lifted wheel (0.1 m/s:
            slips of a few rad/s on 3–5 cm wheels, the size the environments produce).
        onset_rate: rate [1/s] at which a wheel in contact starts to slip or lifts (1/s: the
            Phunopas lift-off rate 0.5/s plus slips).
        recover_rate: rate [1/s] at which a faulty wheel recovers (5/s: the environments' default).
        exclude_belief: belief above which a wheel in use is dropped.
        include_belief: belief below which a dropped wheel starts counting agreeing periods.
        include_steps: agreeing periods before a dropped wheel is used again.
        max_faults: largest number of simultaneously faulty wheels considered (None: all n).
    """

    fault_speed_std: float = 0.1
    onset_rate: float = 1.0
    recover_rate: float = 5.0
    exclude_belief: float = 0.5
    include_belief: float = 0.2
    include_steps: int = 3
    max_faults: int | None = None

    def __post_init__(self) -> None:
        for name in ("fault_speed_std", "onset_rate", "recover_rate"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
        if not 0.0 < self.include_belief <= self.exclude_belief < 1.0:
            raise ValueError("need 0 < include_belief <= exclude_belief < 1, got "
                             f"{self.include_belief!r}, {self.exclude_belief!r}")
        if int(self.include_steps) != self.include_steps or self.include_steps < 1:
            raise ValueError(f"include_steps must be an integer >= 1, got {self.include_steps!r}")
        if self.max_faults is not None and (int(self.max_faults) != self.max_faults or self.max_faults < 0):
            raise ValueError(f"max_faults must be None or an integer >= 0, got {self.max_faults!r}")


class SlipDetector:
    """Per-wheel fault beliefs from the wheel-speed innovations; see the module docstring.

    Args:
        W: wheel matrix (n, 3) [rad/s per (m/s, m/s, rad/s)].
        wheel_radius: r [m] (converts ``fault_speed_std`` to rad/s).
        wheel_rate_std: σ_w [rad/s], the encoder-rate noise the filter assumes.
        config: :class:`DetectorConfig`.

    Attributes (after each :meth:`step`):
        belief: (n,) probability that wheel i is slipping or lifted.
        ok: (n,) bool, wheels the odometry may use.
        residual: (n,) consistency residual (I − W W⁺)·z [rad/s].
        residual_nis: its NIS (χ² with n − 3 degrees of freedom when nothing slips; 0 for n = 3).
        yaw_rate_encoders: ω from the encoders alone, (W⁺ z)_ω [rad/s].
        yaw_nis: NIS of the encoder yaw rate against the predicted (gyro-refined) yaw rate (χ²(1)).
    """

    def __init__(self, W: np.ndarray, wheel_radius: float, wheel_rate_std: float,
                 config: DetectorConfig | None = None) -> None:
        self.W = np.asarray(W, dtype=float)
        if self.W.ndim != 2 or self.W.shape[1] != 3 or self.W.shape[0] < 3:
            raise ValueError(f"W must have shape (n >= 3, 3), got {self.W.shape}")
        self.config = DetectorConfig() if config is None else config
        self.n = self.W.shape[0]
        self.sigma_w = float(wheel_rate_std)
        self.sigma_f = self.config.fault_speed_std / float(wheel_radius)
        self.W_pinv = np.linalg.pinv(self.W)
        self.P_perp = np.eye(self.n) - self.W @ self.W_pinv
        # Residual covariance σ_w²·P⊥ is singular (rank n − 3); its pseudo-inverse is P⊥/σ_w².
        self._rank_perp = self.n - 3
        max_f = self.n if self.config.max_faults is None else min(self.config.max_faults, self.n)
        sets = [m for m in itertools.product((False, True), repeat=self.n) if sum(m) <= max_f]
        self.hypotheses = np.array(sets, dtype=bool)  # (H, n), row 0 = no fault
        self._fault_cov = (self.sigma_f**2) * self.hypotheses[:, None, :] * np.eye(self.n)[None, :, :]
        self._var_enc_yaw = self.sigma_w**2 * float(self.W_pinv[2] @ self.W_pinv[2])
        self.reset()

    def reset(self) -> None:
        """Every wheel believed in contact and gripping."""
        n = self.n
        self.belief = np.zeros(n)
        self.ok = np.ones(n, dtype=bool)
        self._agree = np.zeros(n, dtype=np.int64)
        self.residual = np.zeros(n)
        self.residual_nis = 0.0
        self.yaw_rate_encoders = 0.0
        self.yaw_nis = 0.0

    def step(self, z: np.ndarray, nu: np.ndarray, S: np.ndarray, yaw_pred: float, yaw_var: float,
             dt: float) -> np.ndarray:
        """Update the beliefs with one period's encoder rates; returns the new ``ok`` mask.

        Args:
            z: encoder rates (n,) [rad/s].
            nu: innovation z − W q̂⁻ (n,) [rad/s].
            S: its covariance W P_qq Wᵀ + σ_w² I (n, n).
            yaw_pred, yaw_var: predicted yaw rate [rad/s] and its variance (diagnostics only).
            dt: control period [s] (for the Markov transition).
        """
        cfg = self.config
        z = np.asarray(z, dtype=float)
        nu = np.asarray(nu, dtype=float)
        # Diagnostics: the two independent parts of the joint test (module docstring).
        self.residual = self.P_perp @ z
        self.residual_nis = float(self.residual @ self.residual) / self.sigma_w**2 if self._rank_perp > 0 else 0.0
        q_enc = self.W_pinv @ z
        self.yaw_rate_encoders = float(q_enc[2])
        self.yaw_nis = (self.yaw_rate_encoders - yaw_pred) ** 2 / (self._var_enc_yaw + yaw_var)

        # Markov prediction of each wheel's fault probability over one period.
        p_on = -math.expm1(-cfg.onset_rate * dt)
        p_off = -math.expm1(-cfg.recover_rate * dt)
        prior = self.belief * (1.0 - p_off) + (1.0 - self.belief) * p_on

        # Joint Gaussian likelihood of ν under every fault set.
        masks = self.hypotheses
        C = S[None, :, :] + self._fault_cov
        _, logdet = np.linalg.slogdet(C)
        quad = np.einsum("i,hij,j->h", nu, np.linalg.inv(C), nu)
        loglik = -0.5 * (quad + logdet)
        logprior = masks @ np.log(prior) + (~masks) @ np.log1p(-prior)
        logpost = loglik + logprior
        logpost -= logpost.max()
        post = np.exp(logpost)
        post /= post.sum()
        self.belief = np.clip(post @ masks, 0.0, 1.0)

        # Hysteresis on the wheels the odometry may use.
        drop = self.ok & (self.belief > cfg.exclude_belief)
        self.ok[drop] = False
        agreeing = ~self.ok & (self.belief < cfg.include_belief)
        self._agree = np.where(agreeing, self._agree + 1, 0)
        back = agreeing & (self._agree >= cfg.include_steps)
        self.ok[back] = True
        self._agree[back] = 0
        return self.ok.copy()
