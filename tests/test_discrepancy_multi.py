"""Several effects at once: the workflow names one effect, adds it to the model and
searches the remaining gap again, until the answer is `none` or `unexplained`."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from omni_gym.cli import main
from omni_gym.discrepancy.data.dataset import write_dataset
from omni_gym.discrepancy.synthetic import recovery, synth
from omni_gym.discrepancy.workflow import gap

# Two effects that act on different things: wheel radii (a steady kinematic error) and a motor lag (an
# error only while the commands change). Large sizes of the recovery study.
HIDDEN = {"wheel_radius": recovery.SIZES["wheel_radius"]["large"], "motor_lag": recovery.SIZES["motor_lag"]["large"]}
RUNS, DURATION, NOISE = 4, 2.5, 0.001  # the recovery study's quick cases: 4 runs of 2.5 s, 1 mm tracker


@pytest.fixture(scope="module")
def two_effects(tmp_path_factory) -> Path:
    nominal = recovery.nominal_model()
    (first, p1), (second, p2) = HIDDEN.items()
    truth = nominal.with_effect(first, p1)
    runs, _ = synth.synthesize(truth, f"{second}:{json.dumps(p2)}", RUNS, NOISE, seed=5, duration=DURATION)
    folder = tmp_path_factory.mktemp("multi") / "data"
    write_dataset(folder, nominal.to_json(), "two hidden effects", runs)  # the nominal model has neither
    return folder


@pytest.fixture(scope="module")
def report(two_effects, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("multi_report") / "report"
    # Two hidden effects: a third search step could only end the search, so it is not paid for here.
    gap(two_effects, out, seed=0, progress=False, max_effects=2)
    return out


@pytest.fixture(scope="module")
def result(report) -> dict:
    return json.loads((report / "result.json").read_text())


@pytest.mark.slow  # about 50 CPU-s: a two-step gap search (make test-slow, which CI runs)
def test_two_hidden_effects_are_named_with_a_staircase_in_result_and_report(result, report):
    # One test over the module's gap run: under pytest-xdist each worker that runs a test of this module
    # computes the module fixture again (about 50 CPU-s per gap run), so its checks share one test.
    _check_both_named(result)
    _check_staircase(result)
    _check_report(report)


def _check_both_named(result: dict) -> None:
    """Both hidden effects are named (in either order) and fitted within the recovery study's tolerances."""
    assert set(result["effects"][:2]) == set(HIDDEN), (result["effects"], [s["why"] for s in result["steps"]])
    # The extended model carries every named effect with its fitted parameters.
    assert set(HIDDEN) <= set(result["model"]["effects"])
    scale = result["model"]["effects"]["wheel_radius"]["scale"]
    # The recovery study's tolerance for wheel_radius (0.01): a second effect in the data must not spoil it.
    assert max(abs(a - b) for a, b in zip(scale, HIDDEN["wheel_radius"]["scale"], strict=True)) < 0.01
    tau = result["model"]["effects"]["motor_lag"]["tau"]
    assert abs(tau / HIDDEN["motor_lag"]["tau"] - 1) < 0.2  # the study's relative tolerance for tau


def _check_staircase(result: dict) -> None:
    """The staircase goes down, and the single-effect keys describe the first step."""
    steps = result["steps"]
    named = [s for s in steps if "params" in s]
    assert [s["effect"] for s in named] == result["effects"]
    # Each named step removes gap: its held-out gap after is below its gap before, and the chain links up.
    for a, b in zip(named, named[1:], strict=False):
        assert b["gap_before"] == a["gap_after"]
    assert all(s["gap_after"] < s["gap_before"] for s in named)
    assert result["effect"] == named[0]["effect"] and result["params"] == named[0]["params"]
    assert result["gap"]["after"] == pytest.approx(named[-1]["gap_after"])
    # Together the two effects remove more of the gap than either alone: the first step's best candidate
    # (motor_lag on this data) removes 67 %, short of the 70 % rule, so it is kept as a partial explanation;
    # with wheel_radius the chain removes 87 % (measured; the rest is the noise estimate's own bias,
    # see test_discrepancy_independent.py). 75 % sits between the two.
    assert result["gap"]["after"] < 0.25 * result["gap"]["before"]
    assert result["effect"] != "unexplained"


def _check_report(report: Path) -> None:
    """report.md shows the staircase; model.json carries both effects."""
    out = report
    text = (out / "report.md").read_text()
    assert "## Effects, step by step" in text and "staircase.png" in text
    assert (out / "staircase.png").stat().st_size > 0
    assert json.loads((out / "model.json").read_text())["effects"].keys() >= set(HIDDEN)


def test_cli_passes_max_effects_and_refuses_zero(two_effects, tmp_path, capsys, monkeypatch):
    """Plumbing only (a full gap run costs a minute): the recovery sweep runs gap with max_effects=1 on
    every effect and checks that one effect at most comes back (tests/test_discrepancy_recovery.py)."""
    from omni_gym.discrepancy import workflow

    seen = {}

    def fake_gap(dataset, out, **kwargs):
        seen.update(kwargs)
        raise ValueError("stop here")

    monkeypatch.setattr(workflow, "gap", fake_gap)
    assert main(["gap", str(two_effects), "--out", str(tmp_path / "one"), "--max-effects", "1", "--no-plots"]) == 2
    assert seen["max_effects"] == 1
    assert main(["gap", str(two_effects), "--out", str(tmp_path / "zero"), "--max-effects", "0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].endswith("--max-effects must be an integer in [1, 100], got 0") and not (tmp_path / "zero").exists()
    with pytest.raises(ValueError, match="max_effects must be an integer >= 1"):
        gap(two_effects, None, max_effects=0)
