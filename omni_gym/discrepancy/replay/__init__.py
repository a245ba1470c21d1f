"""Stage 2, replay: runs replayed in the simulated world, and what their residuals show.

* :mod:`.measurement`: what the pose tracker reports for a simulated motion (the model's tracker effects).
* :mod:`.simulate`: batched replay of runs × models in one :class:`~omni_gym.physics.world.World`; the
  pose residual (x, y, heading × lever, metres).
* :mod:`.residuals`: multiple-shooting windows, per-run SSE, the decision's metric, the noise estimate.
* :mod:`.localise`: where the nominal model's residuals concentrate (multiple shooting).

Imports the data stage only (``tests/test_architecture.py``).
"""
