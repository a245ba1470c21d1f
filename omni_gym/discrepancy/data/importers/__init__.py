"""Importers: robot logs in other formats → a dataset folder (``docs/formats.md`` "Dataset").

Each importer reads one log format and writes a dataset with :func:`omni_gym.discrepancy.data.dataset.write_dataset`
inside an :class:`omni_gym.outputs.Output` transaction (complete or absent, ``--force`` as ``omni-gym synth``).

* :mod:`.optiodom`: the OptiOdom dataset's synchronised runs (encoder ticks per cycle + motion capture),
  ``omni-gym import optiodom``.
* :mod:`.csv_log`: any CSV with a header, a column map and units, ``omni-gym import csv``.
* :mod:`.rosbag2`: ROS 2 bags (SQLite3 or MCAP; the optional ``rosbags`` reader), ``omni-gym import rosbag2``.

:mod:`.logs` holds what the general-purpose importers share: timestamped wheel and pose streams → runs,
units, the complete-or-absent write.
"""

from __future__ import annotations

# Format name (the ``omni-gym import FORMAT`` argument) → one-line description.
FORMATS: dict[str, str] = {
    "optiodom": "OptiOdom sessions: <id>_metadata.csv + <id>_run-NN.csv (ticks per cycle, motion capture)",
    "csv": "CSV logs with a header: --model, --columns t=…,x=…,y=…,theta=…,enc1=… (or w1=…), --units",
    "rosbag2": "ROS 2 bags (sqlite3 or mcap): JointState wheels + PoseStamped/Odometry/tf pose, --model, --joints",
}
