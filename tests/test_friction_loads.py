"""Friction law, roller/gap geometry, static loads and the lift-off process."""

import numpy as np
import pytest

from omni_gym.physics import kernel
from omni_gym.physics.friction import SURFACES, gap_measure, on_gap, regularised_coulomb
from omni_gym.physics.liftoff import PHUNOPAS_TABLE2, ContactProcess, contact_cases
from omni_gym.physics.loads import static_loads, wheel_loads
from omni_gym.physics.robot import phunopas2018, williams2002


def test_surfaces_are_table_one():
    assert (SURFACES["paper"].mu_drive, SURFACES["paper"].mu_transverse, SURFACES["paper"].mu_gap) == (0.26, 0.09, 0.47)
    assert (SURFACES["carpet"].mu_drive, SURFACES["carpet"].mu_transverse, SURFACES["carpet"].mu_gap) == (
        0.25, 0.15, 0.56)


def test_regularised_law_shape():
    mu = regularised_coulomb(np.array([-1.0, -1e-3, 0.0, 1e-3, 1.0]), 0.5, 1000.0)
    # Odd, zero at rest, 0.5·(2/π)·atan(1) = 0.25 at v = 1/k, and within 0.07 % of μ_max at 1 m/s.
    np.testing.assert_allclose(mu[[0, 1]], -mu[[4, 3]])
    assert mu[2] == 0.0
    np.testing.assert_allclose(mu[3], 0.25, rtol=1e-12)
    assert 0.4996 < mu[4] < 0.5


def test_kernel_coefficient_matches_law_and_its_derivative():
    for v in [-0.3, -2e-3, 0.0, 5e-4, 0.1]:
        mu, dmu = kernel.friction_coefficient(v, 0.47, 1000.0, 1.0, 1.0)
        np.testing.assert_allclose(mu, regularised_coulomb(v, 0.47), rtol=1e-13, atol=1e-15)
        h = 1e-7
        fd = (kernel.friction_coefficient(v + h, 0.47, 1000.0, 1.0, 1.0)[0]
              - kernel.friction_coefficient(v - h, 0.47, 1000.0, 1.0, 1.0)[0]) / (2 * h)
        np.testing.assert_allclose(dmu, fd, rtol=1e-5)  # central difference error O(h²·μ''') ≪ 1e-5
        # Kinetic shaping: derivative again against finite differences; level drops to ratio·μ_s fast.
        mu_k, dmu_k = kernel.friction_coefficient(v, 0.47, 1000.0, 0.6, 0.05)
        fd_k = (kernel.friction_coefficient(v + h, 0.47, 1000.0, 0.6, 0.05)[0]
                - kernel.friction_coefficient(v - h, 0.47, 1000.0, 0.6, 0.05)[0]) / (2 * h)
        np.testing.assert_allclose(dmu_k, fd_k, rtol=1e-5, atol=1e-9)
    assert abs(kernel.friction_coefficient(1.0, 0.5, 1000.0, 0.6, 0.05)[0] - 0.3) < 1e-3


def test_gap_sector_convention():
    p = 2 * np.pi / 8
    g = 0.1 * p
    # Angle 0 is mid-roller; the rigid sector is centred half a pitch away.
    assert not on_gap(0.0, p, g)
    assert on_gap(p / 2, p, g)
    assert on_gap(p / 2 + 0.49 * g, p, g) and not on_gap(p / 2 + 0.51 * g, p, g)
    assert on_gap(-p / 2, p, g)
    # Over whole turns the rigid share is exactly 10 %.
    np.testing.assert_allclose(gap_measure(2 * np.pi, p, g), 0.1 * 2 * np.pi, rtol=1e-12)
    np.testing.assert_allclose(gap_measure(-2 * np.pi, p, g), -0.1 * 2 * np.pi, rtol=1e-12)


def test_gap_fraction_is_exact_average_of_indicator():
    p = 2 * np.pi / 8
    g = 0.1 * p
    rng = np.random.default_rng(3)
    for _ in range(200):
        a, b = rng.uniform(-10, 10, size=2) * rng.choice([1e-3, 1.0])
        frac = kernel.gap_fraction(a, b, p, g)
        samples = np.linspace(a, b, 200001)
        ref = on_gap(samples, p, g).mean()
        # Midpoint-sampled indicator: error ≤ 2 boundary cells of 1/200000 per sector crossed.
        crossings = abs(b - a) / p * 2 + 2
        assert abs(frac - ref) <= crossings * 1e-5 + 1e-12


def test_equal_loads_and_static_balance():
    robot = williams2002()
    # The paper's assumption: equal shares when the centre of mass is the geometric centre...
    np.testing.assert_allclose(wheel_loads(robot.positions(), np.zeros(2), 2.0, 9.81), 2.0 * 9.81 / 3, rtol=1e-12)
    np.testing.assert_allclose(wheel_loads(robot.positions(), np.zeros(2), 2.0, 9.81, np.array([1, 1, 0])),
                               [9.81, 9.81, 0.0], rtol=1e-12)
    # ...and static balance with an offset centre of mass.
    com = np.array([0.01, -0.02])
    loads = static_loads(robot.positions(), com, 2.0, 9.81)
    np.testing.assert_allclose(loads.sum(), 2.0 * 9.81, rtol=1e-12)
    np.testing.assert_allclose(loads @ (robot.positions() - com), 0.0, atol=1e-12)  # no tipping moment
    # Four wheels: least-norm loads, equal when centred; a lifted wheel carries nothing.
    four = phunopas2018()
    np.testing.assert_allclose(static_loads(four.positions(), np.zeros(2), 3.0, 9.81), 3.0 * 9.81 / 4)
    lifted = static_loads(four.positions(), np.zeros(2), 3.0, 9.81, np.array([True, False, True, True]))
    assert lifted[1] == 0.0
    np.testing.assert_allclose(lifted.sum(), 3.0 * 9.81, rtol=1e-12)
    # Diagonal pair (Table 2 case 7): the remaining diagonal carries half each.
    diag = static_loads(four.positions(), np.zeros(2), 3.0, 9.81, np.array([True, False, True, False]))
    np.testing.assert_allclose(diag, [3.0 * 9.81 / 2, 0, 3.0 * 9.81 / 2, 0], atol=1e-12)


def test_contact_cases_match_paper_table2():
    cases = contact_cases(4)
    as_set = {tuple(c) for c in cases}
    assert as_set == {tuple(c) for c in PHUNOPAS_TABLE2[1:]}  # case 1 (all up) is not used
    assert len(contact_cases(5)) == 6  # all down + each single wheel up (no opposite pairs)


def test_contact_process_is_seeded_and_has_expected_duty():
    def run(seed):
        proc = ContactProcess(4, lift_rate=2.0, recover_rate=6.0, rng=np.random.default_rng(seed))
        t = np.arange(0, 2000, 0.01)
        masks = []
        for ti in t:
            proc.advance(ti)
            masks.append(proc.mask.copy())
        return np.array(masks)

    a, b = run(7), run(7)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, run(8))
    lifted_share = (~a.all(axis=1)).mean()
    # Stationary share 2/(2+6) = 0.25; ~4000 switches over 2000 s give a std of about 0.01.
    assert abs(lifted_share - 0.25) < 0.04
    # Every mask visited is one of Table 2's cases.
    assert {tuple(m) for m in a} <= {tuple(c) for c in PHUNOPAS_TABLE2}


def test_contact_process_rejects_bad_rates():
    with pytest.raises(ValueError, match="lift_rate"):
        ContactProcess(4, -1.0, 1.0, np.random.default_rng(0))
    with pytest.raises(ValueError, match="recover_rate"):
        ContactProcess(4, 1.0, float("nan"), np.random.default_rng(0))
