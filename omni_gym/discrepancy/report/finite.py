"""Standard JSON only: every non-finite number becomes ``null`` before anything is written.

``json.dump`` writes ``NaN`` and ``Infinity`` by default, which strict parsers (JavaScript, jq,
most other languages) refuse. The gap workflow passes its result through :func:`finite_json` and
writes with ``allow_nan=False``, so no output can hold such a token whatever happens upstream (a
pose of 1e308, an overflowing residual); the keys that were replaced are listed in the output.
"""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np


def finite_json(obj: Any, path: str = "") -> tuple[Any, list[str]]:
    """A copy of ``obj`` (dicts, lists, tuples, numbers, strings, None) with every NaN or ±inf
    replaced by None, and the JSON paths (``a.b[2]``) of the replaced values."""
    bad: list[str] = []
    return _clean(obj, path, bad), bad


def _clean(obj: Any, path: str, bad: list[str]) -> Any:
    if isinstance(obj, dict):
        return {k: _clean(v, f"{path}.{k}" if path else str(k), bad) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v, f"{path}[{i}]", bad) for i, v in enumerate(obj)]
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        if math.isfinite(float(obj)):
            return obj if type(obj) is float else float(obj)
        bad.append(path)
        return None
    if isinstance(obj, np.ndarray):
        return _clean(obj.tolist(), path, bad)
    return obj


def dumps_strict(obj: Any, indent: int | None = 2) -> str:
    """``json.dumps`` that refuses non-finite numbers (ValueError) instead of writing NaN/Infinity."""
    return json.dumps(obj, indent=indent, allow_nan=False)
