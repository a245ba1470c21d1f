"""The start-window alignment trusts a run's start pose as far as the data say (replay/start_trust.py)."""

from dataclasses import replace

import numpy as np
import pytest

from omni_gym.discrepancy.data.dataset import Dataset
from omni_gym.discrepancy.replay.measurement import align_to_start_window
from omni_gym.discrepancy.replay.start_trust import _shrink, estimate_start_trust, with_start_trust
from omni_gym.discrepancy.synthetic import synth
from omni_gym.discrepancy.synthetic.recovery import nominal_model

NOISE = 0.003  # m: the recovery sweeps' camera tracker, where a wrong alignment hid a 3 % wheel error
RUNS, DURATION = 8, 2.5


@pytest.fixture(scope="module")
def exact_start() -> Dataset:
    """Synthetic runs whose first row is the true start pose (the library's generator writes it exactly)."""
    model = nominal_model()
    runs, _ = synth.synthesize(model, "none", RUNS, NOISE, seed=11, duration=DURATION)
    return Dataset(path=None, model=model, model_json=model.to_json(), description="", runs=runs)


def _noisy_start(ds: Dataset, seed: int) -> Dataset:
    """The same runs with tracker noise on the first row too, as a real tracker reports it."""
    rng = np.random.default_rng(seed)
    lever = ds.model.robot.lever()
    runs = []
    for r in ds.runs:
        pose = r.pose.copy()
        pose[0] += rng.normal(0.0, 1.0, 3) * np.array([NOISE, NOISE, NOISE / lever])
        runs.append(replace(r, pose=pose))
    return replace(ds, runs=runs)


def test_exact_first_rows_are_trusted_over_the_window(exact_start):
    trust = estimate_start_trust(exact_start, 0.2)
    w = np.array(list(trust.weights.values()))
    # s^2 = 0 in truth; its estimate has a sampling sd of about sigma^2/n/sqrt(runs) (n = 20 rows, 8 runs),
    # so the weights s^2/(s^2 + sigma^2/n) stay well below 1/2 (measured: 0.0-0.2 on seeds 11-14).
    assert w.mean(axis=0).max() < 0.5, w
    # The per-row noise the trust is measured against is the tracker's (the generator's heading noise is
    # NOISE / lever): within 25 %, the spread of a median-based estimate on about 2000 rows per channel.
    assert trust.row_position == pytest.approx(NOISE, rel=0.25)


def test_noisy_first_rows_are_measured_and_replaced_by_the_window_mean(exact_start):
    """With tracker noise on the first row the start pose's error is real (the run's rest rows average part of
    it away); the estimate should find its size, and the replays should take most of the window offset."""
    ratios, weights = [], []
    for noise_seed in range(4):
        ds = _noisy_start(exact_start, noise_seed)
        trust = estimate_start_trust(ds, 0.2)
        err = np.array([r.start_pose for r in ds.runs])  # the true start is the origin
        ratios.append((trust.start_position / np.sqrt(np.mean(err[:, :2] ** 2)),
                       trust.start_heading / np.sqrt(np.mean(err[:, 2] ** 2))))
        weights.append(np.array(list(trust.weights.values())).mean(axis=0))
    # 8 runs give s^2 from 8 (heading) or 16 (position) squared offsets: over 18 draws (3 data seeds x 6 noise
    # seeds) the ratio estimate / true RMS was 0.70-1.13 for position and 0.57-1.00 for heading (one 0.0); the
    # median of four draws stays within [0.6, 1.2].
    med = np.median(np.array(ratios), axis=0)
    assert np.all((med > 0.6) & (med < 1.2)), ratios
    # ...and the replays take most of the offset (exact first rows: under 0.5, the test above).
    assert np.median(np.array(weights), axis=0).min() > 0.6, weights


def test_weights_reach_the_replay(exact_start):
    trust = estimate_start_trust(exact_start, 0.2)
    ds = with_start_trust(exact_start, trust)
    assert [r.start_weight for r in ds.runs] == [trust.weights[r.name] for r in ds.runs]
    assert with_start_trust(exact_start, None) is exact_start


def test_alignment_weight_scales_the_move():
    t = np.arange(0.0, 1.0, 0.01)
    pose = np.column_stack([0.3 * t, np.zeros_like(t), np.zeros_like(t)])
    a = 0.004  # the tracker sees the replay rotated by 4 mrad about the origin and moved by (2, -1) mm
    measured = np.column_stack([0.002 + np.cos(a) * pose[:, 0], -0.001 + np.sin(a) * pose[:, 0], pose[:, 2] + a])
    full = align_to_start_window(t, measured, pose, 0.2)
    np.testing.assert_allclose(full, measured, atol=1e-12)  # a rigid move is undone exactly, along the whole run
    none = align_to_start_window(t, measured, pose, 0.2, weight=(0.0, 0.0))
    np.testing.assert_array_equal(none, pose)
    half = align_to_start_window(t, measured, pose, 0.2, weight=(0.5, 0.5))
    assert half[0, 2] == pytest.approx(a / 2)
    # Half the heading offset about the first row, then half the remaining mean offset over the window, where
    # the rows (x up to 0.06 m) are still off by x (sin a - sin a/2) in y and x (cos a - cos a/2) in x.
    x = pose[t <= 0.2 + 1e-9, 0]
    assert half[0, 0] == pytest.approx(0.5 * (0.002 + np.mean(x) * (np.cos(a) - np.cos(a / 2))), abs=1e-12)
    assert half[0, 1] == pytest.approx(0.5 * (-0.001 + np.mean(x) * (np.sin(a) - np.sin(a / 2))), abs=1e-12)


def test_shrinkage_weights():
    # Offsets at the noise level carry no start error: weight 0. Offsets far beyond it: weight near 1.
    s2, w = _shrink(np.array([1.0, 1.0]), np.array([1.0, 1.0]))
    assert s2 == 0.0 and np.all(w == 0.0)
    s2, w = _shrink(np.array([10.0, 12.0]), np.array([1.0, 1.0]))
    assert s2 == pytest.approx(10.0) and np.allclose(w, 10.0 / 11.0)
