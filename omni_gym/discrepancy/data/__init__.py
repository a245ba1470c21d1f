"""Stage 1, data in: the runs a ``gap`` search reads, checked, cleaned and partitioned. Nothing is simulated.

* :mod:`.dataset`: the dataset folder format (a contract, ``docs/formats.md``): read, validate, write.
* :mod:`.units`: a run's rates beyond any wheeled robot (other units: millimetres, degrees, rpm) refused.
* :mod:`.importers`: real robot logs converted to datasets (``omni-gym import``: OptiOdom).
* :mod:`.measured_state`: the state a run's data imply at each row (smoothed tracked pose and rate,
  wheel angles), where a replay starts from a measured state.
* :mod:`.outliers`: tracker outliers, single pose rows no motion and no tracker noise can explain.
* :mod:`.budget`: the fit budget's numbers and check (light enough for ``omni-gym gap --help``).
* :mod:`.segments`: a dataset longer than the budget replaced by an even sample of its runs' segments.
* :mod:`.folds`: the held-out folds (by run, by source run of a segment, or by recording session).

Imports nothing of the later stages (``tests/test_architecture.py``).
"""
