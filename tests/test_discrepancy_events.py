"""Lift-event inference for the wheel_liftoff candidate (omni_gym.discrepancy.fit.events)."""

import math
from pathlib import Path

import numpy as np
import pytest

from omni_gym.discrepancy.data.dataset import Dataset, Run
from omni_gym.discrepancy.fit.events import PARAMS_PER_EVENT, EventProblem, infer_events
from omni_gym.discrepancy.fit.fitting import Evaluator
from omni_gym.discrepancy.replay.residuals import count_components, noise_estimate, run_sse
from omni_gym.discrepancy.replay.simulate import FIT_DT, Job, simulate_jobs
from omni_gym.discrepancy.settings import DecisionRules, EventSearchSettings
from omni_gym.discrepancy.synthetic.recovery import nominal_model
from omni_gym.discrepancy.synthetic.synth import pose_lever
from omni_gym.physics.liftoff import ScheduledContactProcess, contact_cases
from omni_gym.physics.world import DEFAULT_DT, World


def test_scheduled_process_replays_exactly_the_given_events():
    model = nominal_model()
    n = model.n_wheels
    cases = contact_cases(n)
    # Event times off the 1 ms substep grid, two events touching (2 → 1 without all-down between).
    events = [(0.0123, 0.0456, 2), (0.0456, 0.0601, 1), (0.1002, 0.2507, 3)]
    dt = 0.001
    world = World(model, dt=dt)
    world.set_contact_process(0, ScheduledContactProcess(n, events))
    world.reset()
    for k in range(300):
        world.substeps(1)
        t = k * dt  # substep k ran with the mask due at local time k·dt
        lifted = [c for a, b, c in events if a <= t < b]
        expected = cases[lifted[0]] if lifted else cases[0]
        assert np.array_equal(world.contact[0], expected), (k, world.contact[0], expected)
    # A reset replays the same schedule from its start.
    world.reset()
    world.substeps(20)
    assert np.array_equal(world.contact[0], cases[2])


def test_scheduled_process_rejects_malformed_events():
    with pytest.raises(ValueError, match="overlap"):
        ScheduledContactProcess(3, [(0.1, 0.3, 1), (0.2, 0.4, 2)])
    with pytest.raises(ValueError, match="case"):
        ScheduledContactProcess(3, [(0.1, 0.3, 0)])  # case 0 is all wheels down, not a lift
    with pytest.raises(ValueError, match="t_start < t_end"):
        ScheduledContactProcess(3, [(0.3, 0.1, 1)])


def test_event_inference_finds_one_known_lift():
    """Two runs of a steady combined move (tracked at 50 Hz, 1 mm noise); run 0 has wheel 2 lifted
    for 0.2 s, simulated at the data's 0.5 ms substep and inferred at the 1 ms fitting substep."""
    model = nominal_model()
    t = np.arange(126) / 50.0
    twist = np.tile([0.25, 0.1, 0.8], (len(t), 1))  # m/s, m/s, rad/s
    twist[-1] = 0.0
    cmd = twist @ model.robot.wheel_matrix().T
    truth = (1.23, 1.43, 2)  # case 2 of contact_cases(3): wheel 2 up
    shells = [Run(name=f"run{i}", t=t, cmd=cmd, pose=np.zeros((len(t), 3))) for i in range(2)]
    sims = simulate_jobs([Job(model, shells[0], schedule=(truth,)), Job(model, shells[1])], dt=DEFAULT_DT)
    lever = pose_lever(model)
    rng = np.random.default_rng(7)
    runs = []
    for shell, (pose, ang) in zip(shells, sims, strict=True):
        meas = pose + rng.normal(0.0, 1.0, pose.shape) * np.array([1e-3, 1e-3, 1e-3 / lever])
        meas[0] = 0.0
        runs.append(Run(name=shell.name, t=t, cmd=cmd, pose=meas, enc=ang))
    ds = Dataset(path=Path("."), model=model, model_json=model.to_json(), description="", runs=runs)
    res0 = Evaluator(ds, lever).residuals([model])[0]
    sse0 = np.array([run_sse(r) for r in res0])
    sigma = noise_estimate(res0, [r.t for r in runs])
    n_comp = count_components(ds)
    fit = infer_events(EventProblem(ds, model, lever, PARAMS_PER_EVENT * math.log(n_comp.sum()), sse0, n_comp,
                                    FIT_DT, sigma=sigma, adequacy=1.0 + DecisionRules().noise_margin))
    assert fit.events[1] == []  # the run without a lift gets no event
    assert len(fit.events[0]) == 1, fit.events
    start, end, case = fit.events[0][0]
    assert case == truth[2]
    # Start and end within 30 ms (1.5 tracker rows; the coarse search grid is 50 ms).
    assert abs(start - truth[0]) <= 0.03 and abs(end - truth[1]) <= 0.03, fit.events
    # With the event the run is reproduced to the tracker-noise level.
    assert fit.sse[0] <= 1.3 * n_comp[0] * sigma**2
    rates = fit.rates()
    assert rates is not None and rates[1] == pytest.approx(1.0 / (end - start))


def test_back_to_back_events_rounded_apart_are_accepted_but_real_overlaps_are_not():
    # The event search rounds times to 1e-6 s, so one event can end at 2.345 and the next start at
    # 2.3449999999999998: that is back to back, not an overlap (the recovery benchmark hit it).
    proc = ScheduledContactProcess(3, [(2.2, 2.345, 1), (2.3449999999999998, 2.4, 2)])
    assert [e[0] for e in proc.events] == [2.2, 2.345]
    with pytest.raises(ValueError, match="overlap"):
        ScheduledContactProcess(3, [(2.2, 2.345, 1), (2.34, 2.4, 2)])


def _slow_lift_dataset(duration: float, speed: float = 0.08, seed: int = 7) -> tuple[Dataset, float]:
    """Two runs of a slow steady combined move (tracked at 50 Hz, 1 mm noise); run 0 has wheel 2 lifted for
    ``duration`` s from 1.23 s (simulated at the data's 0.5 ms substep). Returns the dataset and the lever."""
    model = nominal_model()
    t = np.arange(126) / 50.0
    twist = np.tile([0.25 * speed, 0.1 * speed, 0.8 * speed], (len(t), 1))  # m/s, m/s, rad/s
    twist[-1] = 0.0
    cmd = twist @ model.robot.wheel_matrix().T
    shells = [Run(name=f"run{i}", t=t, cmd=cmd, pose=np.zeros((len(t), 3))) for i in range(2)]
    sims = simulate_jobs([Job(model, shells[0], schedule=((1.23, 1.23 + duration, 2),)), Job(model, shells[1])],
                         dt=DEFAULT_DT)
    lever = pose_lever(model)
    rng = np.random.default_rng(seed)
    runs = []
    for shell, (pose, ang) in zip(shells, sims, strict=True):
        meas = pose + rng.normal(0.0, 1.0, pose.shape) * np.array([1e-3, 1e-3, 1e-3 / lever])
        meas[0] = 0.0
        runs.append(Run(name=shell.name, t=t, cmd=cmd, pose=meas, enc=ang))
    return Dataset(path=Path("."), model=model, model_json=model.to_json(), description="", runs=runs), lever


def _infer(ds: Dataset, lever: float, settings: EventSearchSettings | None = None):
    res0 = Evaluator(ds, lever).residuals([ds.model])[0]
    sse0 = np.array([run_sse(r) for r in res0])
    sigma = noise_estimate(res0, [r.t for r in ds.runs])
    n_comp = count_components(ds)
    fit = infer_events(EventProblem(ds, ds.model, lever, PARAMS_PER_EVENT * math.log(n_comp.sum()), sse0, n_comp,
                                    FIT_DT, sigma=sigma, adequacy=1.0 + DecisionRules().noise_margin), settings)
    return fit, sse0 / n_comp / sigma**2


def test_event_search_uses_the_settings_it_is_given():
    """The 100 ms lift of the slow case keeps wheel 2 up for about 2 % of the 5 s of moving time (two runs): found
    with the default limit (50 %), rejected when the limit is 1 %, with the limit named in the note."""
    ds, lever = _slow_lift_dataset(0.1)
    fit, _ = _infer(ds, lever)
    assert fit.n_events() == 1 and fit.note == "", fit.events
    strict, _ = _infer(ds, lever, EventSearchSettings(max_lifted_share=0.01))
    assert strict.n_events() == 0 and "limit 1 %" in strict.note, strict.note


def test_events_must_beat_the_noise_level(monkeypatch):
    """An event is evidence only for what it explains above the decision's noise level (1.3 σ̂²), as a
    held-out score gives no effect credit for fitting noise. A 50 ms lift at a slow 0.08 scale of the move
    leaves the run at 1.10 σ̂² (measured): noise level, so no event may be inferred. Without the rule
    (check_evidence a no-op: the BIC keep test alone) an event was inferred at 0.68 s, half a second
    from the true lift, trimming the run to 0.95 σ̂²: fitted noise. A 100 ms lift at the same speed
    (1.46 σ̂²) beats the noise and is still found, at its time."""
    import omni_gym.discrepancy.fit.events as events

    ds, lever = _slow_lift_dataset(0.05)
    fit, mse0 = _infer(ds, lever)
    assert mse0[0] < 1.0 + DecisionRules().noise_margin, mse0  # the case is what it is meant to be: noise level
    assert fit.events == [[], []], fit.events
    monkeypatch.setattr(events.EventInference, "check_evidence", lambda self: None)
    old, _ = _infer(ds, lever)
    assert old.n_events() >= 1  # control: the data do fool the BIC keep test alone
    monkeypatch.undo()
    ds, lever = _slow_lift_dataset(0.1)
    fit, mse0 = _infer(ds, lever)
    assert mse0[0] > 1.0 + DecisionRules().noise_margin, mse0
    assert fit.events[1] == [] and len(fit.events[0]) == 1, fit.events
    start, end, case = fit.events[0][0]
    # Within 0.15 s of the truth (1.23-1.33 s; measured 1.32-1.43: at this speed a lift's first tenth of a
    # second moves the robot less than the noise, so its start is placed late; the window grid is 50 ms).
    assert case == 2 and abs(start - 1.23) <= 0.15 and abs(end - 1.33) <= 0.15, fit.events


def test_a_stochastic_candidate_must_remove_most_of_the_gap_even_at_noise_level():
    """decide(): a deterministic candidate that predicts held-out runs to the noise level is named whatever
    share of the gap that is; a stochastic one's error is in-sample with its inferred events (they can trim
    any residual to the noise), so it must remove 70 % of the gap beyond noise like every other effect, and
    is not kept as a partial explanation. Eight runs at 1.6 σ² nominal, 1.25 σ² with the candidate (at
    noise level: within 1.3 σ²; 35 % of the gap beyond noise removed)."""
    from fit_stub import FitStub as _Fit

    from omni_gym.discrepancy.decide.decision import decide
    from omni_gym.discrepancy.fit.candidates import Candidate
    from omni_gym.physics.effects import Dim

    sigma, n = 1e-3, np.full(8, 750)
    nominal = 1.6 * sigma**2 * n
    dims = (Dim("p", 0.1, 1.0), Dim("q", 0.1, 1.0))
    for stochastic, expect in ((False, "x"), (True, "unexplained")):
        cand = Candidate("x", dims, lambda v: {}, stochastic=stochastic)
        fit = _Fit(cand, {}, 1.25 * sigma**2 * n, n_params_eff=32 if stochastic else None)
        out = decide(nominal, [fit], n, sigma, np.random.default_rng(0))
        assert out.ranking[0]["beats_nominal"], out.ranking
        assert out.effect == expect, out
        assert out.partial is None
