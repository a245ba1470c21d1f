"""The one angle wrap (omni_gym.angles.wrap_angle) and its numba twin."""

from __future__ import annotations

import math

import numpy as np
import pytest

from omni_gym.angles import wrap_angle, wrap_angle_nb


@pytest.mark.parametrize(("angle", "expected"), [
    (math.pi, math.pi), (-math.pi, math.pi), (3 * math.pi, math.pi), (-3 * math.pi, math.pi),
    (0.0, 0.0), (2 * math.pi, 0.0), (-math.pi / 2, -math.pi / 2), (7 * math.pi / 2, -math.pi / 2),
])
def test_wrap_angle_lands_in_the_half_open_interval(angle: float, expected: float) -> None:
    # Tolerance: the +π/−π of the wrap and the multiples of π above carry a few rounding steps of 2π·k.
    assert wrap_angle(angle) == pytest.approx(expected, abs=1e-14)


def test_scalar_array_and_numba_wraps_agree_bit_for_bit() -> None:
    rng = np.random.default_rng(3)
    angles = np.concatenate([rng.uniform(-50.0, 50.0, 2000), [math.pi, -math.pi, 0.0, -0.0, 1e-300, np.nan]])
    wrapped = wrap_angle(angles)
    scalar = np.array([wrap_angle(float(a)) for a in angles])
    compiled = np.array([wrap_angle_nb(float(a)) for a in angles])
    np.testing.assert_array_equal(scalar, wrapped)  # NaN compares equal to NaN here
    np.testing.assert_array_equal(compiled, wrapped)
    finite = wrapped[np.isfinite(wrapped)]
    assert np.all(finite > -math.pi) and np.all(finite <= math.pi)
    # The wrap only removes whole turns: (input − output)/2π is an integer up to rounding of |input| ≤ 50.
    turns = (angles[:-1] - wrapped[:-1]) / (2 * math.pi)
    assert np.max(np.abs(turns - np.round(turns))) < 1e-13
