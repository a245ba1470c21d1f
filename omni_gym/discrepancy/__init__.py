"""Model-discrepancy workflow: find where simulation and measurement disagree, name the missing effect.

Modules (each one job):

* :mod:`.dataset`: the dataset folder format (a contract, ``docs/formats.md``): read, validate, write.
* :mod:`.units`: a run's rates beyond any wheeled robot (other units: millimetres, degrees, rpm) refused.
* :mod:`.importers`: real robot logs converted to datasets (``omni-gym import``: OptiOdom).
* :mod:`.synth`: datasets with a hidden effect, for testing the workflow where the truth is known.
* :mod:`.simulate`: batched simulation of runs × candidate models in one :class:`~omni_gym.physics.world.World`.
* :mod:`.outliers`: tracker outliers, single pose rows no motion and no tracker noise can explain.
* :mod:`.localise`: where the nominal model's residuals concentrate (multiple shooting).
* :mod:`.residuals`: shooting windows, per-run SSE, the decision metric, the noise estimate.
* :mod:`.settings`: the settings of the event search, the fit and the decision (one frozen dataclass per
  stage, recorded in full in ``result.json``).
* :mod:`.events`: lift-event inference for the stochastic ``wheel_liftoff`` candidate.
* :mod:`.candidates`: the effect library (``omni_gym.physics.effects``) as fit candidates (bounded
  parameter cubes, null points).
* :mod:`.search`: batched local searches (roller-phase sweeps, Levenberg–Marquardt, valley lines).
* :mod:`.fitting`: fit every candidate on all runs and on each fold's training runs (held-out errors).
* :mod:`.decision`: score the candidates on held-out runs and decide the outcome.
* :mod:`.plausible`: units and plausible ranges of the fitted parameters (flags only).
* :mod:`.finite`: standard JSON only (non-finite numbers become ``null``).
* :mod:`.report`: ``result.json``, ``report.md`` and plots.
* :mod:`.workflow`: :func:`gap`, the whole ``omni-gym gap`` command.
* :mod:`.recovery`: recovery study: hide an effect in synthetic data, run the workflow, compare with the truth.

Only the physics core is used (no environments, no agents).
"""
