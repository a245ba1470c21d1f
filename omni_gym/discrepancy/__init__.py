"""Model-discrepancy workflow: find where simulation and measurement disagree, name the missing effect.

The folders are the workflow's stages, in the order the data flows (a stage imports only earlier
ones, ``tests/test_architecture.py``); each folder's ``__init__`` lists its modules:

1. :mod:`.data`: data in: the dataset format, importers, unit checks, tracker outliers, the fit budget's
   segments, the held-out folds.
2. :mod:`.replay`: batched replay of runs in the world, the tracker's view of it, residuals, localisation.
3. :mod:`.fit`: search and fit: candidates, searches, lift-event inference, fits with folds and their
   parallel tasks, the kinematic calibration, identifiability and the identified refit, plausibility flags.
4. :mod:`.decide`: the decision on held-out runs, the open-loop whole-run score.
5. :mod:`.report`: ``result.json``, ``report.md`` and plots; standard JSON.

Beside them:

* :mod:`.settings`: the settings of the event search, the fit and the decision (one frozen dataclass per
  stage, recorded in full in ``result.json``), read by the stages and the workflow.
* :mod:`.workflow`: :func:`~omni_gym.discrepancy.workflow.gap`, the whole ``omni-gym gap`` command,
  walking the stages.
* :mod:`.synthetic`: the test bench above the workflow: datasets with a known hidden effect and the
  recovery study.

Only the physics core is used (no environments, no agents).
"""
