"""``--policy recommended``: one name that resolves, per environment id, to the controller to deploy.

Where a gated controller (:mod:`agents.gated`: ekf-pid, then the student once ekf-pid's estimate leaves the path)
is measured never worse than ``ekf-pid`` on the grip floor and better where the wheels slip
(``benchmarks/results/gated.md``, held-out episodes), it is the recommendation; elsewhere the scripted ``ekf-pid``,
which nothing measured beats on every floor.
"""

from __future__ import annotations

from pathlib import Path

NAME = "recommended"
MODELS = Path(__file__).resolve().parent / "models"
GATED = {"OmniPathFollow-Williams-v1": "gated-student-williams",
         "OmniPathFollow-Phunopas-v0": "gated-student-phunopas",
         "OmniPathFollow-Mecanum-v0": "gated-student-mecanum"}
FALLBACK = "ekf-pid"


def resolve(env_id: str) -> str:
    """The policy spec ``recommended`` stands for on ``env_id``: a gated model directory or ``ekf-pid``.

    ValueError (one line) where the gated directory is missing (an installation without the committed models)."""
    name = GATED.get(env_id)
    if name is None:
        return FALLBACK
    path = MODELS / name
    if not (path / "meta.json").is_file():
        raise ValueError(f"policy 'recommended' on {env_id} is {name}, which this installation does not hold (the "
                         "committed models live in the repository's agents/models, not in the wheel)")
    return str(path)
