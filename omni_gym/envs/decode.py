"""Compatibility module: the decoders live with the layouts in :mod:`omni_gym.envs.observations`.

``SensorObsDecoder.for_env(env)`` decodes a ``sensors`` observation into physical units by field name;
``StateObsDecoder`` does the same for ``state``; ``BatchSensorObsDecoder`` decodes (N, D) batches of a
vector environment.
"""

from omni_gym.envs.observations import (
    BatchSensorObs,
    BatchSensorObsDecoder,
    SensorObs,
    SensorObsDecoder,
    StateObs,
    StateObsDecoder,
)

__all__ = ["BatchSensorObs", "BatchSensorObsDecoder", "SensorObs", "SensorObsDecoder", "StateObs", "StateObsDecoder"]
