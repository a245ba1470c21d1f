"""Stage 3, search and fit: every candidate effect fitted on all runs and on each fold's training runs.

* :mod:`.candidates`: the effect library (``omni_gym.physics.effects``) as fit candidates (bounded
  parameter cubes, null points).
* :mod:`.search`: batched local searches (roller-phase sweeps, Levenberg–Marquardt, valley lines).
* :mod:`.events`: lift-event inference for the stochastic ``wheel_liftoff`` candidate.
* :mod:`.fitting`: the evaluator (SSE of parameter points on every run) and a candidate's fit with folds.
* :mod:`.fit_tasks`: a search step's fits side by side, their simulation rounds cut into chunk tasks for
  the backend (``--jobs``, ``--ray``); the work record.
* :mod:`.kinematic_calibration`: the kinematic odometry calibration (the start model a dynamic model
  must beat); :mod:`.calibrate`: ``omni-gym calibrate``.
* :mod:`.identifiability`: which parameters and combinations the data determine (Jacobian, SVD);
  :mod:`.identified_fit`: the final fit restricted to them.
* :mod:`.plausible`: units and plausible ranges of the fitted parameters (flags only).

Imports the data and replay stages (``tests/test_architecture.py``), never the decision.
"""
