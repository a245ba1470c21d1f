"""Known truth: datasets with a hidden effect, and the recovery study that runs ``gap`` on them.

Not a stage of the workflow but its test bench, so it sits above it: it replays runs to make data and
runs :func:`omni_gym.discrepancy.workflow.gap`; the workflow never imports it.

* :mod:`.synth`: ``omni-gym synth``: datasets simulated by the world with a hidden effect (truth in a
  separate file).
* :mod:`.reference_data`: datasets from the independent validation integrator, not the world we fit with.
* :mod:`.recovery`: hide an effect, run the workflow, compare with the truth (tests and benchmark).
"""
