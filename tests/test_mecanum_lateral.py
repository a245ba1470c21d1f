"""The ``mecanum_lateral`` effect: lateral travel per wheel turn scaled, longitudinal travel kept."""

from __future__ import annotations

import math

import numpy as np
import pytest

from omni_gym.physics.effects import REGISTRY
from omni_gym.physics.model import load_model
from omni_gym.physics.replay import simulate_commands

SCALE = 0.9  # far from 1 so that a defect (no change, or the longitudinal travel scaled too) is plain


def _travel(model, body_velocity) -> np.ndarray:
    """Body-frame displacement [m] after 2 s of the nominal wheel speeds for ``body_velocity`` (vx, vy, ω)."""
    w = load_model("optiodom_omni4", "paper").robot.wheel_matrix() @ np.asarray(body_velocity, dtype=float)
    times = np.array([0.0, 2.0, 2.001])
    states = simulate_commands(model, times, np.vstack([w, w * 0.0]), dt=1e-3)
    return states[1, :3]


def test_lateral_travel_per_wheel_turn_scales_longitudinal_does_not():
    """Same wheel speeds, with and without the effect: sideways the body covers SCALE times the distance,
    forwards the same. Tolerance 1 % of the travel: the rollers' rolling friction (μ_T) and the friction law's
    creep slow the sideways motion a little differently at the two roller angles (measured 0.904 for 0.9,
    1.000 forwards); a per-wheel radius change would move both directions alike and fail one check by 10 %."""
    nominal = load_model("optiodom_omni4", "paper")
    model = nominal.with_effect("mecanum_lateral", {"scale": SCALE})
    lat0, lat1 = _travel(nominal, (0.0, 0.1, 0.0)), _travel(model, (0.0, 0.1, 0.0))
    lon0, lon1 = _travel(nominal, (0.1, 0.0, 0.0)), _travel(model, (0.1, 0.0, 0.0))
    # The nominal model drives sideways as commanded, less the rollers' rolling friction (μ_T on paper) and
    # the spin-up: measured 3.0 % short.
    assert lat0[1] == pytest.approx(0.2, rel=0.05)
    assert lat1[1] / lat0[1] == pytest.approx(SCALE, rel=0.01)
    assert lon1[0] / lon0[0] == pytest.approx(1.0, rel=0.01)
    # Neither motion picks up a cross component or a turn (all four wheels change alike).
    for d in (lat1, lon1):
        assert abs(d[2]) < 1e-3 and min(abs(d[0]), abs(d[1])) < 1e-3


def test_kernel_angles_keep_sign_and_null_point():
    from omni_gym.physics.layout import WP_COSG, WP_SING

    nominal = load_model("optiodom_omni4")
    _, wp0 = nominal.kernel_params()
    _, wp = nominal.with_effect("mecanum_lateral", {"scale": SCALE}).kernel_params()
    # tan γ' = tan γ / scale on every wheel, sign of γ kept
    np.testing.assert_allclose(wp[:, WP_SING] / wp[:, WP_COSG], wp0[:, WP_SING] / wp0[:, WP_COSG] / SCALE, rtol=1e-12)
    _, wp1 = nominal.with_effect("mecanum_lateral", {"scale": 1.0}).kernel_params()
    np.testing.assert_allclose(wp1[:, [WP_COSG, WP_SING]], wp0[:, [WP_COSG, WP_SING]], rtol=0, atol=1e-15)


def test_omni_robots_refuse_it_and_do_not_search_it():
    effect = REGISTRY["mecanum_lateral"]
    for robot in ("williams2002", "phunopas2018"):
        model = load_model(robot)
        assert not effect.applies_to(model.robot)
        with pytest.raises(ValueError, match="'mecanum_lateral' applies to mecanum wheels only"):
            model.with_effect("mecanum_lateral", {"scale": 0.95})
    assert effect.applies_to(load_model("optiodom_omni4").robot)


@pytest.mark.parametrize("value", [0.4, 2.5, math.nan])
def test_out_of_bound_scale_is_refused(value):
    with pytest.raises(ValueError, match="mecanum_lateral"):
        load_model("optiodom_omni4").with_effect("mecanum_lateral", {"scale": value})
