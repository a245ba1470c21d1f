"""The ``mecanum_lateral`` effect: sideways and forward travel per wheel turn split by ``ratio``, mean kept."""

from __future__ import annotations

import math

import numpy as np
import pytest

from omni_gym.physics.effects import REGISTRY
from omni_gym.physics.model import load_model
from omni_gym.physics.replay import simulate_commands

RATIO = 0.9  # far from 1 so that a defect (no change, both directions scaled alike) is plain


def _travel(model, body_velocity) -> np.ndarray:
    """Body-frame displacement [m] after 2 s of the nominal wheel speeds for ``body_velocity`` (vx, vy, ω)."""
    w = load_model("optiodom_omni4", "paper").robot.wheel_matrix() @ np.asarray(body_velocity, dtype=float)
    times = np.array([0.0, 2.0, 2.001])
    states = simulate_commands(model, times, np.vstack([w, w * 0.0]), dt=1e-3)
    return states[1, :3]


def test_lateral_and_longitudinal_travel_per_wheel_turn_split_by_the_ratio():
    """Same wheel speeds, with and without the effect: forwards the body covers 2/(1 + RATIO) times the
    distance, sideways 2·RATIO/(1 + RATIO) times (their mean unchanged). Tolerance 1 % of the travel: the
    rollers' rolling friction (μ_T) and the friction law's creep slow the sideways motion a little
    differently at the two roller angles (measured 0.4 %); a per-wheel radius change would scale both
    directions alike and fail by 10 %, a lateral-only change (mean not kept) by 5 %."""
    nominal = load_model("optiodom_omni4", "paper")
    model = nominal.with_effect("mecanum_lateral", {"ratio": RATIO})
    lat0, lat1 = _travel(nominal, (0.0, 0.1, 0.0)), _travel(model, (0.0, 0.1, 0.0))
    lon0, lon1 = _travel(nominal, (0.1, 0.0, 0.0)), _travel(model, (0.1, 0.0, 0.0))
    # The nominal model drives sideways as commanded, less the rollers' rolling friction (μ_T on paper) and
    # the spin-up: measured 3.0 % short.
    assert lat0[1] == pytest.approx(0.2, rel=0.05)
    assert lat1[1] / lat0[1] == pytest.approx(2 * RATIO / (1 + RATIO), rel=0.01)
    assert lon1[0] / lon0[0] == pytest.approx(2 / (1 + RATIO), rel=0.01)
    # Neither motion picks up a cross component or a turn (all four wheels change alike).
    for d in (lat1, lon1):
        assert abs(d[2]) < 1e-3 and min(abs(d[0]), abs(d[1])) < 1e-3


def test_kernel_numbers_and_null_point():
    from omni_gym.physics.layout import WP_COSG, WP_R, WP_SING

    nominal = load_model("optiodom_omni4")
    _, wp0 = nominal.kernel_params()
    _, wp = nominal.with_effect("mecanum_lateral", {"ratio": RATIO}).kernel_params()
    # tan γ' = tan γ / ratio on every wheel (sign of γ kept), radius × 2/(1 + ratio)
    np.testing.assert_allclose(wp[:, WP_SING] / wp[:, WP_COSG], wp0[:, WP_SING] / wp0[:, WP_COSG] / RATIO, rtol=1e-12)
    np.testing.assert_allclose(wp[:, WP_R], wp0[:, WP_R] * 2 / (1 + RATIO), rtol=1e-12)
    _, wp1 = nominal.with_effect("mecanum_lateral", {"ratio": 1.0}).kernel_params()
    np.testing.assert_allclose(wp1, wp0, rtol=0, atol=1e-15)


def test_order_with_wheel_radius_does_not_matter():
    """A model file may list the effects in any order: the calibrated radius and the split compose."""
    nominal = load_model("optiodom_omni4")
    radius, lateral = {"scale": [1.05, 1.06, 1.04, 1.07]}, {"ratio": RATIO}
    a = nominal.with_effect("wheel_radius", radius).with_effect("mecanum_lateral", lateral).kernel_params()[1]
    b = nominal.with_effect("mecanum_lateral", lateral).with_effect("wheel_radius", radius).kernel_params()[1]
    np.testing.assert_allclose(a, b, rtol=1e-15)


def test_omni_robots_refuse_it_and_do_not_search_it():
    effect = REGISTRY["mecanum_lateral"]
    for robot in ("williams2002", "phunopas2018"):
        model = load_model(robot)
        assert not effect.applies_to(model.robot)
        with pytest.raises(ValueError, match="'mecanum_lateral' applies to mecanum wheels only"):
            model.with_effect("mecanum_lateral", {"ratio": 0.95})
    assert effect.applies_to(load_model("optiodom_omni4").robot)


@pytest.mark.parametrize("value", [0.4, 2.5, math.nan])
def test_out_of_bound_ratio_is_refused(value):
    with pytest.raises(ValueError, match="mecanum_lateral"):
        load_model("optiodom_omni4").with_effect("mecanum_lateral", {"ratio": value})
