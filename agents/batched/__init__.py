"""The estimation and control stack for N robots at once (a native vector environment's batch).

* :class:`BatchEKF` / :class:`BatchSlipDetector` (:mod:`agents.batched.estimation`, compiled kernels in
  :mod:`agents.batched.kernels`): :class:`agents.ekf.OmniEKF` and its slip detector over a robot axis.
* :class:`BatchPathPID` (:mod:`agents.batched.pid`): :class:`agents.pid.PathPID` over a robot axis.
* vector policies (:mod:`agents.batched.policies`): ``open-loop``, ``odometry-pid``, ``ekf-pid`` for the
  native vector environment's (N, D) sensor observations.

The single-robot classes stay the readable, tested reference; ``tests/test_batched_estimation.py``
checks these against them robot by robot.
"""

from agents.batched.estimation import BatchEKF, BatchSlipDetector, robot_mask
from agents.batched.pid import BatchPathPID

__all__ = ["BatchEKF", "BatchPathPID", "BatchSlipDetector", "robot_mask"]
