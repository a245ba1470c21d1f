"""The gap report as a user reads it: one kind of percentage per comparison, what model.json is for,
next steps, plausibility flags, tracker outliers, progress on a pipe, standard JSON only.

Datasets are small (3 runs of 1.5-2 s at 50 Hz) and most workflow runs fit only the motor_lag
candidate (monkeypatched library), which keeps each case to seconds; the one full CLI run of the
outlier case fits the whole library on 3 runs of 2 s.
"""

import json
import math
import os
import re
import subprocess
import sys

import numpy as np
import pytest

from omni_gym.cli import main
from omni_gym.discrepancy import workflow
from omni_gym.discrepancy.data.dataset import load_dataset, write_dataset
from omni_gym.discrepancy.data.outliers import drop_outliers, find_outliers
from omni_gym.discrepancy.fit import candidates, plausible
from omni_gym.discrepancy.report.finite import dumps_strict, finite_json
from omni_gym.discrepancy.synthetic.recovery import nominal_model
from omni_gym.discrepancy.synthetic.synth import pose_lever, write_synthetic
from omni_gym.physics.effects import REGISTRY

JUMP = 3.0  # m, the outlier: one tracked row 3 m off


def _strict_load(text: str):
    """json.loads that refuses NaN/Infinity tokens, as strict (non-Python) parsers do."""
    def refuse(token):
        raise ValueError(f"non-standard JSON token {token}")
    return json.loads(text, parse_constant=refuse)


def _with_jump(src, dst, run: int, row: int, column: int = 0, jump: float = JUMP):
    """Copy dataset ``src`` to ``dst`` with one pose cell (0-based data row) moved by ``jump``."""
    ds = load_dataset(src)
    ds.runs[run].pose[row, column] += jump
    write_dataset(dst, ds.model_json, ds.description, ds.runs)
    return dst


# --- tracker outliers -----------------------------------------------------------------------------


def test_outlier_rows_are_flagged_where_they_are_and_nowhere_else(lag_dataset, tmp_path):
    ds = load_dataset(lag_dataset)
    lever = pose_lever(ds.model)
    assert find_outliers(ds, lever) == []  # clean data: nothing flagged
    bad = _with_jump(lag_dataset, tmp_path / "bad", run=1, row=40)
    ds_bad = load_dataset(bad)
    # Also the first and the last row of other runs (tested against an extrapolated line) and a heading
    # glitch of 0.5 rad (45 mm at the 0.09 m lever, 45 tracker-noise levels).
    ds_bad.runs[0].pose[-1, 2] += 0.5
    ds_bad.runs[2].pose[0, 1] -= 0.2
    found = find_outliers(ds_bad, lever)
    names = [r.name for r in ds.runs]
    assert [(o.run, o.row) for o in found] == [(names[0], len(ds.runs[0].t) + 1), (names[1], 42), (names[2], 2)]
    jump = next(o for o in found if o.run == names[1])
    assert jump.component == "x" and jump.t == pytest.approx(ds.runs[1].t[40])
    assert jump.deviation == pytest.approx(JUMP, abs=0.01)  # the jump, give or take the tracker noise
    # What is done with them: the flagged rows are unobserved, everything else is the data as given;
    # a flagged first row takes the next observed pose (runs start at rest).
    clean = drop_outliers(ds_bad, found)
    assert not clean.runs[1].observed[40] and clean.runs[1].observed.sum() == ds.runs[1].observed.sum() - 1
    np.testing.assert_array_equal(np.delete(clean.runs[1].pose, 40, axis=0), np.delete(ds.runs[1].pose, 40, axis=0))
    np.testing.assert_array_equal(clean.runs[2].pose[0], ds.runs[2].pose[1])
    assert not clean.runs[0].observed[-1]
    assert ds_bad.runs[1].pose[40, 0] == pytest.approx(ds.runs[1].pose[40, 0] + JUMP)  # input not modified


def test_no_outliers_on_noise_free_stick_slip_data(tmp_path):
    """The motion term of the threshold: without tracker noise the robust noise scale is ~0, yet the
    abrupt accelerations of a kinetic friction law (stick-slip) and of lift-offs are not flagged."""
    for hidden in ('kinetic_friction:{"ratio": 0.5, "v_s": 0.005}', "wheel_liftoff:{\"lift_rate\": 2.0}"):
        folder = tmp_path / hidden.split(":")[0]
        write_synthetic(folder, nominal_model(), hidden, 3, 0.0, 2, 2.0)
        ds = load_dataset(folder)
        assert find_outliers(ds, pose_lever(ds.model)) == [], hidden


@pytest.mark.slow  # about 16 CPU-s: gap through the CLI (make test-slow, which CI runs)
def test_gap_cli_flags_a_3m_outlier_keeps_the_effect_and_reports_stages(lag_dataset, tmp_path):
    """Full library, through the CLI with stderr piped (as under a log redirect)."""
    bad = _with_jump(lag_dataset, tmp_path / "bad", run=1, row=40)
    run_name = load_dataset(bad).runs[1].name
    env = dict(os.environ, MPLBACKEND="Agg")
    proc = subprocess.run([sys.executable, "-m", "omni_gym.cli", "gap", str(bad), "--out", str(tmp_path / "rep"),
                           "--no-plots"], capture_output=True, text=True, env=env)
    assert proc.returncode == 0, proc.stderr
    # One flushed line per stage on a pipe (no tqdm bar there), in order.
    # Stage lines only: the progress lines inside a fit (omni_gym/progress.py: "..., T s[, about R s left]") come
    # every 10 s, so how many a run prints depends on the machine's speed.
    progress = re.compile(r", \d+ s(, about \d+ s left)?(;|$)")
    stages = [line for line in proc.stderr.splitlines() if line.startswith("gap: ") and not progress.search(line)]
    robot = load_dataset(bad).model.robot
    n = sum(e.applies_to(robot) for e in REGISTRY.values())
    skipped = [name for name, e in REGISTRY.items() if not e.applies_to(robot)]  # mecanum_lateral on omni wheels
    expected = ["gap: loaded dataset", "gap: checking 3 runs for tracker outliers", "gap: 1 outlier row(s)",
                "gap: simulating the nominal model",
                *([f"gap: not tried (does not apply to this robot): {', '.join(skipped)}"] if skipped else []),
                "gap: localising"] + \
        [f"gap: fitting candidate {i}/{n}" for i in range(1, n + 1)] + ["gap: deciding"]
    assert all(s.startswith(e) for s, e in zip(stages, expected, strict=False)), stages
    # Then, if the search goes on after the first effect, its later steps; last, the report.
    later = stages[len(expected):-1]
    # ... and the whole-run held-out replay after the search (and what its drift check dropped, if anything),
    # then the identifiability of the named effects (and the refit restricted to it, if anything changed).
    assert all(s.startswith(("gap: named", "gap: kept", "gap: step ", "gap: scoring whole runs", "gap: dropped",
                             "gap: identifiability", "gap: refitted"))
               for s in later), later
    assert stages[-1].startswith("gap: writing report")
    assert "\r" not in proc.stderr  # no progress bar redraws in a log
    result = _strict_load((tmp_path / "rep" / "result.json").read_text())
    # The hidden effect is still named, with its parameter in the recovery tolerance (20 %), and the
    # gap is measured on the clean rows (a 3 m row left in would put metres into the held-out RMS).
    assert result["effect"] == "motor_lag"
    assert result["params"]["tau"] == pytest.approx(0.08, rel=0.2)
    jumped = next(r for r in result["gap"]["per_run"] if r["run"] == run_name)
    assert jumped["rms_before"] < 0.05  # with the row: >= 3 m / sqrt(3 x 76 components) = 0.2 m
    rows = result["outliers"]["rows"]
    assert [(o["run"], o["row"]) for o in rows] == [(run_name, 42)]
    assert f"tracker outliers excluded: 1 row(s) ({run_name} row 42)" in proc.stdout
    report = (tmp_path / "rep" / "report.md").read_text()
    assert "## Tracker outliers" in report and f"| {run_name} | 42 |" in report


# --- measures, model.json, next steps -------------------------------------------------------------


def _percent(text: str, before: str) -> int:
    """The integer percentage right before ``before`` in ``text`` (e.g. '64 % of the gap')."""
    head = text[:text.index(before)].rstrip(" %")
    return int(head.split()[-1])


def test_unexplained_report_compares_one_kind_of_percentage_and_gives_next_steps(tmp_path, only_motor_lag):
    folder = tmp_path / "drag"
    write_synthetic(folder, nominal_model(), "viscous_drag", 3, 0.001, 1, 2.0)
    result = workflow.gap(folder, tmp_path / "rep", progress=False, plots=False)
    best = result["ranking"][0]
    # The headline's percentage and the ranking's "gap removed" are the same measure (the excess RMS
    # reduction); the MSE reduction ("improvement") is another one, labelled as such.
    gap_removed = 1.0 - best["excess_rms"] / result["gap"]["before"]
    assert best["gap_reduction"] == pytest.approx(gap_removed, abs=1e-12)
    report = (tmp_path / "rep" / "report.md").read_text()
    row = next(line for line in report.splitlines() if line.startswith("| motor_lag |"))
    cells = [c.strip() for c in row.split("|")]
    assert cells[5] == f"{100 * gap_removed:.0f} %" and cells[6] == f"{100 * best['improvement']:.0f} %"
    assert "gap removed" in report and "MSE reduction" in report and "## How to read this report" in report
    if result["effect"] == "unexplained" and "removes only" in result["why"]:
        assert _percent(result["why"], "of the gap") == round(100 * gap_removed)
    assert result["effect"] == "unexplained"  # drag is outside the library (and motor_lag the only candidate)
    steps = report[report.index("## Next steps"):report.index("## How to read")]
    worst = max(result["where"]["runs"], key=lambda r: r["open_loop_rms"])["run"]
    assert worst in steps  # which runs to look at first
    assert "not in the library" in steps.lower() and "drag" in steps  # the effect that is not there
    assert "model.json" in report and "omni-gym simulate --model" in report and 'model=\\"' not in report
    assert 'gym.make(ENV_ID, model="REPORT/model.json")' in report
    # The kinematic calibration competed (the runs have encoders) and the steps say it did not explain the gap
    # either, with the command that writes it; how much data was fitted; how the gap relates to score's error.
    assert any(r["effect"] == "kinematic_calibration" for r in result["ranking"])
    assert "tried beside the library's effects" in steps and f"`omni-gym calibrate {folder} --out model.json`" in steps
    assert "**Data fitted**: all 3 runs, 6.0 s of robot time" in report  # 3 runs of 2 s: within the budget
    assert "This gap and `omni-gym score`" in report


def test_named_effect_headline_and_ranking_agree(lag_dataset, tmp_path, only_motor_lag):
    result = workflow.gap(lag_dataset, None, progress=False)
    assert result["effect"] == "motor_lag"
    # Two computations of one measure: gap.reduction from the reported model's held-out errors, the
    # ranking's gap_reduction from the decision's; and the percentage in the outcome line.
    assert result["ranking"][0]["gap_reduction"] == pytest.approx(result["gap"]["reduction"], abs=1e-9)
    assert _percent(result["why"], "of the held-out gap") == round(100 * result["gap"]["reduction"])


# --- plausibility -----------------------------------------------------------------------------------


def test_plausibility_flags_only_values_outside_the_ranges():
    model = nominal_model()
    ok = {"mu_gap": 0.56, "roller_fraction": 0.9, "phase": [0.1, 0.2, 0.3]}
    assert plausible.check("roller_gap", ok, model) == []
    flags = plausible.check("roller_gap", dict(ok, mu_gap=1.2), model)
    assert [(f.param, f.value) for f in flags] == [("mu_gap", 1.2)] and "rigid" in flags[0].why
    assert [f.param for f in plausible.check("wheel_radius", {"scale": [1.0, 0.9, 1.0]}, model)] == ["scale[2]"]
    assert plausible.check("motor_lag", {"tau": 0.0}, model) == []  # the ideal actuator is plausible
    lever = pose_lever(model)
    assert plausible.check("com_offset", {"com": [0.05 * lever, 0.0]}, model) == []
    # Half the lever away from wheel 3 (at (0, -lever)): wheel 3 keeps no load at all.
    far = plausible.check("com_offset", {"com": [0.0, 0.5 * lever]}, model)
    assert len(far) == 1 and far[0].value < 1 / 3
    for effect, units in plausible.UNITS.items():  # every range has its reason
        assert all(r.why for r in plausible.RANGES.get(effect, {}).values()) and units


def test_implausible_fit_is_flagged_in_json_report_and_cli(tmp_path, only_motor_lag, capsys):
    """A lag of 0.3 s: inside the fit bounds (0.5 s), outside the plausible 0.2 s."""
    folder = tmp_path / "slow"
    write_synthetic(folder, nominal_model(), 'motor_lag:{"tau": 0.3}', 3, 0.001, 2, 2.0)
    assert main(["gap", str(folder), "--out", str(tmp_path / "rep"), "--no-plots"]) == 0
    out = capsys.readouterr().out
    result = _strict_load((tmp_path / "rep" / "result.json").read_text())
    assert result["effect"] == "motor_lag" and result["params"]["tau"] > 0.2
    flags = result["plausibility"]["flags"]
    assert [f["param"] for f in flags] == ["tau"] and flags[0]["hi"] == 0.2
    assert "implausible: tau = " in out
    assert "**Implausible fitted values**" in (tmp_path / "rep" / "report.md").read_text()


# --- model show ---------------------------------------------------------------------------------------


def test_model_show_prints_every_effect_with_units(tmp_path, capsys):
    model = nominal_model().with_effect("motor_lag", {"tau": 0.08}).with_effect(
        "roller_gap", {"mu_gap": 0.5, "roller_fraction": 0.9, "phase": [0.1, 0.2, 0.3]})
    path = tmp_path / "m.json"
    path.write_text(json.dumps(model.to_json()))
    assert main(["model", "show", str(path)]) == 0
    out = capsys.readouterr().out
    assert "effect motor_lag:" in out and "tau = 0.08 s" in out
    assert "effect roller_gap:" in out and "phase = [0.1, 0.2, 0.3] rad" in out and "mu_gap = 0.5 (" in out


# --- standard JSON ------------------------------------------------------------------------------------


def test_finite_json_replaces_non_finite_values_and_names_them():
    clean, bad = finite_json({"a": [1.0, float("nan")], "b": {"c": np.float64(np.inf)}, "d": 2, "e": "x"})
    assert clean == {"a": [1.0, None], "b": {"c": None}, "d": 2, "e": "x"} and bad == ["a[1]", "b.c"]
    with pytest.raises(ValueError):
        dumps_strict({"x": math.nan})


def test_gap_outputs_stay_standard_json_whatever_happens_upstream(lag_dataset, tmp_path, only_motor_lag,
                                                                  monkeypatch, capsys):
    """Non-finite numbers from a stage (here: the localisation, as a 1e308 pose would make them) are
    written as null and listed, in result.json, model.json and --json alike."""
    real = workflow.localise

    def broken(*args, **kwargs):
        where = real(*args, **kwargs)
        where["runs"][0]["open_loop_rms"] = math.inf
        where["runs"][1]["end_error"] = math.nan
        return where

    monkeypatch.setattr(workflow, "localise", broken)
    assert main(["gap", str(lag_dataset), "--out", str(tmp_path / "rep"), "--json"]) == 0
    printed = _strict_load(capsys.readouterr().out)
    written = _strict_load((tmp_path / "rep" / "result.json").read_text())
    _strict_load((tmp_path / "rep" / "model.json").read_text())
    assert printed == written
    assert written["non_finite"] == ["where.runs[0].open_loop_rms", "where.runs[1].end_error"]
    assert written["where"]["runs"][0]["open_loop_rms"] is None
    report = (tmp_path / "rep" / "report.md").read_text()
    assert "could not be computed" in report and re.search(r"\b(nan|inf|infinity)\b", report, re.I) is None


def test_none_outcome_says_what_none_means_and_what_to_try(tmp_path, only_motor_lag):
    folder = tmp_path / "null"
    write_synthetic(folder, nominal_model(), "none", 3, 0.001, 4, 1.5)
    result = workflow.gap(folder, tmp_path / "rep", progress=False, plots=False)
    assert result["effect"] == "none" and result["model"]["effects"] == {}
    report = (tmp_path / "rep" / "report.md").read_text()
    steps = report[report.index("## Next steps"):report.index("## How to read")]
    assert "within the noise floor" in steps and "nominal model" in steps and "more and longer runs" in steps
    assert "the nominal model unchanged" in report  # what model.json then holds


# --- how much data was fitted, imported logs, plots ---------------------------------------------------


def test_report_says_how_much_of_the_data_the_fit_budget_used(tmp_path, only_motor_lag):
    folder = tmp_path / "long"
    write_synthetic(folder, nominal_model(), 'motor_lag:{"tau": 0.08}', 3, 0.001, 2, 4.0)
    total = sum(r.t[-1] - r.t[0] for r in load_dataset(folder).runs)  # 12 s of robot time
    result = workflow.gap(folder, tmp_path / "rep", progress=False, plots=False, fit_budget=6.0)
    fitted = result["dataset"]["fitted"]
    assert fitted["segmented"] and fitted["total_seconds"] == pytest.approx(total)
    assert fitted["seconds"] <= 6.0 + 1e-9 and result["settings"]["fit_budget"] == 6.0
    report = (tmp_path / "rep" / "report.md").read_text()
    assert (f"**Data fitted**: {fitted['seconds']:.0f} s of the {total:.0f} s of robot time "
            f"({100 * fitted['seconds'] / total:.0f} %), as {fitted['fitted_runs']} segments of at most "
            f"{fitted['segment_seconds']:g} s from 3 runs") in report
    assert "fit budget 6 s" in report
    # Segments are short and start from the tracked state: the report says why score's whole-run
    # error is larger.
    assert "drift that builds up over a whole run" in report


def test_commands_taken_from_the_encoders_drop_the_actuation_figures(lag_dataset, tmp_path, only_motor_lag):
    """An imported log whose commands are the encoder speeds: encoder − command is round-off, not shown."""
    ds = load_dataset(lag_dataset)
    for run in ds.runs:  # the encoders integrate the commands exactly (as the importers derive commands)
        run.enc = np.vstack([np.zeros((1, run.cmd.shape[1])),
                             np.cumsum(run.cmd[:-1] * np.diff(run.t)[:, None], axis=0)])
    folder = tmp_path / "imported"
    write_dataset(folder, ds.model_json, ds.description, ds.runs)
    result = workflow.gap(folder, tmp_path / "rep", progress=False, plots=False)
    where = result["where"]
    assert where["commands_from_encoders"] is True
    assert max(w["actuation_rms"] for w in where["wheels"].values()) < 1e-9  # round-off, what the flag means
    report = (tmp_path / "rep" / "report.md").read_text()
    assert "encoder − command RMS" not in report and "r·encoder − ground speed RMS" in report
    assert "disagrees most with its command" not in " ".join(where["summary"])
    # The synthetic encoders (wheel dynamics under a motor lag) are not flagged.
    assert "commands_from_encoders" not in workflow.gap(lag_dataset, None, progress=False)["where"]


def _record_figures(monkeypatch) -> dict:
    """Capture every figure the report saves, by file name (and still save it)."""
    from omni_gym.discrepancy.report import report

    figures = {}
    save = report._save

    def recording(fig, out, name):
        figures[name] = fig
        return save(fig, out, name)

    monkeypatch.setattr(report, "_save", recording)
    return figures


def _legend(fig) -> list[str]:
    return [t.get_text() for ax in fig.axes if ax.get_legend() for t in ax.get_legend().get_texts()]


def test_plots_show_one_nominal_curve_when_no_effect_is_named(tmp_path, only_motor_lag, monkeypatch):
    figures = _record_figures(monkeypatch)
    write_synthetic(tmp_path / "null", nominal_model(), "none", 3, 0.001, 4, 1.5)
    ds = load_dataset(tmp_path / "null")
    for i, run in enumerate(ds.runs):  # names as long as real logs' segments: they take the figure's height
        run.name = f"2024-05-01_optiodom_session_{i:02d}_run-{i:02d}@120s"
    folder = tmp_path / "long_names"
    write_dataset(folder, ds.model_json, ds.description, ds.runs)
    assert workflow.gap(folder, tmp_path / "rep", progress=False)["effects"] == []
    assert _legend(figures["paths.png"]) == ["measured", "nominal"]  # no "with nominal" on top of it
    assert _legend(figures["residuals.png"]) == ["nominal"]
    where = figures["where.png"]
    for ax in where.axes:  # every label inside the saved figure (the third one was cut off)
        box = ax.yaxis.label.get_window_extent()
        assert box.y0 >= 0 and box.y1 <= where.bbox.height and box.x0 >= 0, ax.get_ylabel()
    assert not any("elsewhere" in ax.get_ylabel() for ax in where.axes)


def test_staircase_title_says_what_ended_the_search(lag_dataset, tmp_path, monkeypatch):
    two = ("motor_lag", "wheel_radius")  # a second candidate: the search goes on after motor_lag and ends
    monkeypatch.setattr(workflow, "candidates",
                        lambda model: [c for c in candidates.candidates(model) if c.name in two])
    figures = _record_figures(monkeypatch)
    result = workflow.gap(lag_dataset, tmp_path / "rep", progress=False)
    assert result["effects"] == ["motor_lag"] and result["steps"][-1]["effect"] == "none"
    assert _legend(figures["paths.png"]) == ["measured", "nominal", "with motor_lag"]
    title = figures["staircase.png"].axes[0].get_title()
    assert "then: none" not in title and "found no further effect (none)" in title
