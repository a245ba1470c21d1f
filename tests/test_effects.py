"""Every registered effect round-trips: model JSON, the kernel, synth and a fit.

The effect library (:mod:`omni_gym.physics.effects`) is the one place an effect is defined; these
tests run each registered effect through every consumer, so a new effect that forgets a part fails
here, not in a user's run.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from omni_gym.discrepancy.data.dataset import Dataset
from omni_gym.discrepancy.data.folds import make_folds
from omni_gym.discrepancy.fit import plausible
from omni_gym.discrepancy.fit.candidates import candidates, null_point
from omni_gym.discrepancy.fit.fitting import Evaluator, fit_candidate
from omni_gym.discrepancy.replay.measurement import measured
from omni_gym.discrepancy.settings import FitSettings, GapSettings
from omni_gym.discrepancy.synthetic import recovery, synth
from omni_gym.physics.effects import REGISTRY, Effect, get
from omni_gym.physics.model import MODEL_BOUNDS, SimModel
from omni_gym.physics.replay import simulate_commands

NAMES = list(REGISTRY)


@pytest.fixture
def nominal(request) -> SimModel:
    """The study's nominal model (Williams robot, carpet, initial friction), or its mecanum robot for an
    effect that applies to mecanum wheels only (the test's ``name``)."""
    name = getattr(request.node, "callspec", None) and request.node.callspec.params.get("name")
    return recovery.nominal_model(name)


def _defaults(effect: Effect, model: SimModel) -> dict:
    return effect.synth_default(model, np.random.default_rng(3))


def _maneuver(model: SimModel, seed: int = 1, duration: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    return synth.maneuver(model, np.random.default_rng(seed), duration)


def test_registry_names_its_effects_and_refuses_unknown_ones():
    assert all(REGISTRY[name].name == name for name in NAMES)
    assert NAMES[:6] == ["roller_gap", "kinetic_friction", "com_offset", "wheel_radius", "motor_lag",
                         "wheel_liftoff"]  # candidate order is part of every gap result (seeded designs)
    with pytest.raises(ValueError, match="unknown effect 'nope'; choose one of"):
        get("nope")


@pytest.mark.parametrize("name", NAMES)
def test_schema_bounds_and_ranges_are_consistent(name):
    effect = REGISTRY[name]
    assert effect.summary and effect.params
    for p in effect.params:
        bound = MODEL_BOUNDS[f"effects.{name}.{p.key}"]  # every key is in the documented bounds table
        assert bound.reason and p.unit
        if p.plausible is not None:  # a plausible value must be a valid one
            assert bound.lo <= p.plausible.lo <= p.plausible.hi <= bound.hi and p.plausible.why
    assert set(effect.recovery_sizes) == {"small", "large"} and effect.tolerances
    assert set(plausible.UNITS[name]) == set(effect.keys)


@pytest.mark.parametrize("name", NAMES)
def test_model_json_round_trip(name, nominal):
    effect = REGISTRY[name]
    model = nominal.with_effect(name, _defaults(effect, nominal))
    text = json.dumps(model.to_json())
    back = SimModel.from_json(json.loads(text), where="round trip")
    assert back.effects == model.effects
    for a, b in zip(back.kernel_params(), model.kernel_params(), strict=True):
        np.testing.assert_array_equal(a, b)
    # Both sizes of the recovery study are valid parameters too.
    for size in effect.recovery_sizes.values():
        nominal.with_effect(name, {**_defaults(effect, nominal), **size})


@pytest.mark.parametrize("name", NAMES)
def test_effect_changes_the_simulation(name, nominal):
    """At its synth default the effect changes the kernel's numbers or installs a contact process,
    and a replayed maneuver moves differently (else the workflow could never find it)."""
    effect = REGISTRY[name]
    model = nominal.with_effect(name, _defaults(effect, nominal))
    sp0, wp0 = nominal.kernel_params()
    sp, wp = model.kernel_params()
    changes_kernel = not (np.array_equal(sp, sp0) and np.array_equal(wp, wp0))
    process = model.contact_process(np.random.default_rng(0))
    assert nominal.contact_process(np.random.default_rng(0)) is None
    t, cmd = _maneuver(nominal, duration=4.0)
    p0 = simulate_commands(nominal, t, cmd, seed=2)
    p1 = simulate_commands(model, t, cmd, seed=2)
    if effect.kind == "tracker":
        # A measurement effect leaves the physics alone (simulators and environments ignore it) and
        # changes what the tracker reports of the same motion.
        assert not changes_kernel and process is None
        np.testing.assert_array_equal(p1, p0)
        p1 = measured(model, t, p0[:, :3])
    else:
        assert changes_kernel or process is not None
    # 1 mm: the tracker noise of the study; the defaults are sized to move the robot by more.
    assert np.max(np.hypot(*(p1[:, :2] - p0[:, :2]).T)) > 1e-3


@pytest.mark.parametrize("name", [n for n in NAMES if REGISTRY[n].null_fit(recovery.nominal_model(n)) is not None])
def test_null_point_leaves_the_motion_nominal(name, nominal):
    """The fit's null point (where the search starts from 'no effect') simulates like the nominal model."""
    cand = next(c for c in candidates(nominal) if c.name == name)
    u = null_point(cand)
    assert u is not None and np.all((u >= 0) & (u <= 1))
    model = nominal.with_effect(name, cand.params(u))
    t, cmd = _maneuver(nominal)
    p0 = simulate_commands(nominal, t, cmd, seed=2)
    p1 = simulate_commands(model, t, cmd, seed=2)
    # 0.5 mm, half the study's tracker noise: the nulls are exact (no gap, no Stribeck drop, nominal
    # com, unit scales) except motor_lag's shortest lag (1 ms: about v·τ ≈ 0.3 mm of path) and
    # wheel_liftoff's rarest rate (0.05 /s: a lift in 2 s is unlikely, and seed 2 draws none).
    assert np.max(np.hypot(*(p1[:, :2] - p0[:, :2]).T)) < 5e-4


@pytest.mark.parametrize("name", NAMES)
def test_synth_hides_the_effect_and_a_fit_finds_parameters_that_explain_it(name, nominal, tmp_path: Path):
    """synth → dataset → fit: the fitted parameters are valid model parameters and explain most of the
    gap the hidden effect opened (fits shortened to keep the test quick)."""
    effect = REGISTRY[name]
    runs, truth = synth.synthesize(nominal, name, runs=3, noise=0.0005, seed=4, duration=3.0)
    assert truth["effect"] == name and set(truth["params"]) == set(effect.keys)
    assert SimModel.from_json(truth["model"]).effects == {name: truth["params"]}
    ds = Dataset(path=tmp_path, model=nominal, model_json=nominal.to_json(), description="", runs=runs)
    ev = Evaluator(ds, synth.pose_lever(nominal))
    rng = np.random.default_rng(0)
    folds = make_folds(len(runs), rng)
    cand = next(c for c in candidates(nominal) if c.name == name)
    quick = FitSettings(iterations=2, fold_iterations=1, phase_sweeps=1, phase_restarts=2, valley_rounds=1)
    fit = fit_candidate(cand, ev, nominal, folds, rng, GapSettings(fit=quick))
    nominal.with_effect(name, fit.params_all)  # valid: validates schema and bounds
    nominal_sse = float(ev.nominal_baseline(nominal)[1].sum())
    # The hidden effect at its default size moves the robot by several noise levels (test above), so a
    # fit that found it leaves well under half the nominal error (0.5 mm noise is a small share of it).
    assert float(fit.sse_all.sum()) < 0.5 * nominal_sse, (name, fit.params_all, truth["params"])
    errors = recovery.param_error(name, truth["params"], fit.params_all, nominal)
    assert set(errors) == set(effect.tolerances)


def test_tracker_effects_have_their_own_key_in_model_files(nominal):
    """Measurement effects are written under "tracker" (a simulator user wants the physics under
    "effects"), read back from there, and refused one line under the wrong key."""
    model = nominal.with_effect("com_offset", {"com": [0.01, 0.0]}).with_effect(
        "tracker_offset", {"offset": [0.02, 0.0], "yaw": 0.0})
    data = model.to_json()
    assert set(data["effects"]) == {"com_offset"} and set(data["tracker"]) == {"tracker_offset"}
    assert SimModel.from_json(data).effects == model.effects
    assert "tracker" not in nominal.to_json()  # files without tracker effects are unchanged
    wrong = {**data, "effects": {**data["effects"], **data.pop("tracker")}}
    with pytest.raises(ValueError, match="tracker_offset.*put it under 'tracker'"):
        SimModel.from_json(wrong)
