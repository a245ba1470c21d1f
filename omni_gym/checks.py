"""Argument checks shared by the core modules: one-line ValueErrors that name the argument."""

from __future__ import annotations

import difflib
import math
import numbers
from collections.abc import Iterable

import numpy as np


def is_number(value) -> bool:
    """A real number (Python or numpy), not a bool, a string or a complex."""
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def json_number(value, name: str) -> float:
    """``value`` as a float if it is a finite JSON number (not a bool); ValueError naming ``name``.

    The validator of numbers read from model files: unlike :func:`finite_scalar` it refuses strings
    and bools (a JSON ``"1"`` or ``true`` is a typo there, not a number).
    """
    if not is_number(value):
        raise ValueError(f"{name} must be a number, got {value!r}")
    try:
        x = float(value)
    except OverflowError:  # a JSON integer beyond float range
        raise ValueError(f"{name} must be finite, got an integer of {len(str(abs(value)))} digits") from None
    if not math.isfinite(x):
        raise ValueError(f"{name} must be finite, got {value!r}")
    return x


def unknown_key(key, allowed: Iterable[str], path: str = "", what: str = "key") -> str:
    """``unknown key 'PATH.KEY'; did you mean 'K'? (allowed: …)``: the one message for a key that a
    JSON object or a keyword set does not define (``path`` is where the object sits, e.g. ``wheels[2]``)."""
    allowed = list(allowed)
    name = str(key)
    full = f"{path}.{name}" if path else name
    close = difflib.get_close_matches(name, allowed, n=1, cutoff=0.6)
    hint = f"; did you mean {close[0]!r}?" if close else ""
    return f"unknown {what} {full!r}{hint} (allowed: {', '.join(allowed)})"


def known_keys(obj: dict, allowed: Iterable[str], path: str = "") -> None:
    """Raise ValueError (:func:`unknown_key`) for the first key of ``obj`` outside ``allowed``.

    A misspelt key would otherwise fall back to its default without a word (a calibrated model read
    as the nominal one), so every JSON object the package reads is checked with this.
    """
    allowed = tuple(allowed)
    for key in obj:
        if key not in allowed:
            raise ValueError(unknown_key(key, allowed, path))


def finite_scalar(name: str, value: float) -> float:
    """``value`` as a float; ValueError naming ``name`` if it is not a finite real number."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a finite number, got {value!r}") from None
    if not math.isfinite(x):
        raise ValueError(f"{name} must be a finite number, got {value!r}")
    return x


def nonnegative(name: str, value: float) -> float:
    """``value`` as a float; ValueError naming ``name`` unless finite and >= 0."""
    x = finite_scalar(name, value)
    if x < 0:
        raise ValueError(f"{name} must be >= 0, got {value!r}")
    return x


def positive(name: str, value: float) -> float:
    """``value`` as a float; ValueError naming ``name`` unless finite and > 0."""
    x = finite_scalar(name, value)
    if x <= 0:
        raise ValueError(f"{name} must be > 0, got {value!r}")
    return x


def finite_array(name: str, value: np.ndarray, shape: tuple[int | None, ...]) -> np.ndarray:
    """``value`` as a finite float array matching ``shape`` (None: any length); ValueError otherwise."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a numeric array of shape {shape}, got {value!r}") from None
    if arr.ndim != len(shape) or any(s is not None and s != a for s, a in zip(shape, arr.shape, strict=True)):
        shown = tuple("n" if s is None else s for s in shape)
        raise ValueError(f"{name} must have shape {shown}, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite (no NaN/inf), got {arr}")
    return arr
