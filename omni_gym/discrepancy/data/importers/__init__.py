"""Importers: robot logs in other formats → a dataset folder (``docs/formats.md`` "Dataset").

Each importer reads one log format and writes a dataset with :func:`omni_gym.discrepancy.data.dataset.write_dataset`
inside an :class:`omni_gym.outputs.Output` transaction (complete or absent, ``--force`` as ``omni-gym synth``).

* :mod:`.optiodom`: the OptiOdom dataset's synchronised runs (encoder ticks per cycle + motion capture),
  ``omni-gym import optiodom``.
"""

from __future__ import annotations

# Format name (the ``omni-gym import FORMAT`` argument) → one-line description.
FORMATS: dict[str, str] = {
    "optiodom": "OptiOdom sessions: <id>_metadata.csv + <id>_run-NN.csv (ticks per cycle, motion capture)",
}
