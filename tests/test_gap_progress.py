"""Progress lines inside gap's long fits where stderr is not a terminal (omni_gym.progress).

The lines: ``gap: WHAT k/N UNIT, T s, about R s left`` for a loop of known length (a fit's search rounds,
the kinematic calibration's folds, the identified refit's iterations), ``gap: WHAT k UNIT, T s`` for the
lift-event inference (its batches are not known in advance), at most one every PROGRESS_EVERY_S seconds;
none with ``progress=False``. They are output only: the result is the same.
"""

from __future__ import annotations

import io
import re

import pytest

import omni_gym.progress
from omni_gym.progress import ProgressLines

KNOWN = re.compile(r"^gap: fitting motor_lag: \d+/\d+ rounds, \d+ s, about \d+ s left$")
EVENTS = re.compile(r"^gap: fitting wheel_liftoff: lift events step [1-4]/4 \([a-z ]+\): \d+ batches, \d+ s")


class Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def test_a_line_at_most_every_interval_with_the_time_left_and_none_after_the_last_item():
    clock, out = Clock(), io.StringIO()
    lines = ProgressLines("gap", every_s=10.0, stream=out, clock=clock)
    loop = lines.loop("fitting x:", 4, "rounds")
    for dt in (4.0, 8.0, 4.0, 20.0):  # items done at t = 4, 12, 16, 36
        clock.t += dt
        loop.update()
    # t = 4: too soon; t = 12: a line (2 of 4 in 12 s: 12 s left); t = 16: too soon; t = 36: the last item
    assert out.getvalue() == "gap: fitting x: 2/4 rounds, 12 s, about 12 s left\n"


def test_a_loop_of_unknown_length_says_the_work_done_and_a_batch_its_parts_left():
    clock, out = Clock(), io.StringIO()
    lines = ProgressLines("gap", every_s=0.0, stream=out, clock=clock)
    loop = lines.loop("events step 1/4 (window search):", None, "batches")
    done = loop.inner("parts")
    clock.t = 30.0
    done(1, 4)  # one of the batch's 4 parts in 30 s
    done(4, 4)  # the batch's last part: no line (the batch's own count follows)
    loop.update()
    assert out.getvalue().splitlines() == [
        "gap: events step 1/4 (window search): 0 batches, 30 s; this batch 1/4 parts, 30 s, about 90 s left",
        "gap: events step 1/4 (window search): 1 batches, 30 s"]


def test_lines_that_are_off_print_nothing(capsys):
    lines = ProgressLines("gap", enabled=False, every_s=0.0)
    loop = lines.loop("x", 3)
    loop.update()
    loop.inner("parts")(1, 2)
    assert capsys.readouterr().err == ""


@pytest.fixture
def lag_and_liftoff(monkeypatch):
    """Fit only motor_lag (search rounds) and wheel_liftoff (lift-event inference)."""
    from omni_gym.discrepancy import workflow
    from omni_gym.discrepancy.fit import candidates

    monkeypatch.setattr(workflow, "candidates", lambda model: [
        c for c in candidates.candidates(model) if c.name in ("motor_lag", "wheel_liftoff")])


def test_gap_prints_progress_inside_the_fits_when_stderr_is_piped_and_none_when_off(lag_dataset, lag_and_liftoff,
                                                                                    monkeypatch, capsys):
    from omni_gym.discrepancy.workflow import gap

    monkeypatch.setattr(omni_gym.progress, "PROGRESS_EVERY_S", 0.0)  # a line at every tick
    result = gap(lag_dataset, None, progress=None, max_effects=1)  # capsys: stderr is not a terminal
    err = capsys.readouterr().err.splitlines()
    assert all(line.startswith("gap: ") for line in err)
    first = err.index("gap: fitting candidate 1/2 motor_lag")
    second = err.index("gap: fitting candidate 2/2 wheel_liftoff")
    end = err.index("gap: deciding")
    assert first < second < end
    rounds = err[first + 1:second]
    assert rounds and all(KNOWN.match(line) for line in rounds), rounds
    events = err[second + 1:end]
    assert events and all(EVENTS.match(line) for line in events), events
    assert len({line.split(" (")[0] for line in events}) >= 2  # the line follows the inference's steps

    quiet = gap(lag_dataset, None, progress=False, max_effects=1)
    assert capsys.readouterr().err == ""
    result.pop("work")  # measured CPU and wall times: the one part that differs from run to run
    quiet.pop("work")
    assert quiet == result
