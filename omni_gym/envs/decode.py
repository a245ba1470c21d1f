"""Compatibility module: the decoders live with the layouts in :mod:`omni_gym.envs.observations`.

``SensorObsDecoder.for_env(env)`` decodes a ``sensors`` observation into physical units by field name;
``StateObsDecoder`` does the same for ``state``.
"""

from omni_gym.envs.observations import SensorObs, SensorObsDecoder, StateObs, StateObsDecoder

__all__ = ["SensorObs", "SensorObsDecoder", "StateObs", "StateObsDecoder"]
