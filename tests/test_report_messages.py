"""Messages that must not contradict what they describe: the paired comparison's ratio beside its episode
shares, and what model.json is when the search started from the kinematic calibration."""

from __future__ import annotations

from agents.evaluate import format_comparison
from omni_gym.discrepancy.report.report import _model_json_lines

A = {"policy": "a", "seeds": [10000, 10049]}
B = {"policy": "b", "seeds": [10000, 10049]}


def test_a_ratio_that_disagrees_with_the_episode_shares_says_how_both_hold():
    text = format_comparison(A, B, {"metric": "tracking_rmse", "ratio": 0.437, "ci95": [0.3, 0.6],
                                    "a_better": 0.4, "ties": 0.0, "b_better": 0.6})
    assert "0.437" in text and "40%" in text and "few large wins" in text
    # When they agree nothing is added.
    text = format_comparison(A, B, {"metric": "tracking_rmse", "ratio": 0.8, "ci95": [0.7, 0.9],
                                    "a_better": 0.7, "ties": 0.0, "b_better": 0.3})
    assert "few large wins" not in text


def test_model_json_is_described_as_what_it_is():
    kin = "\n".join(_model_json_lines("unexplained", [], "kinematic"))
    assert "the kinematic calibration of the runs unchanged" in kin and "nominal model unchanged" not in kin
    assert "the nominal model unchanged" in "\n".join(_model_json_lines("none", [], "nominal"))
    assert "explains the data" in "\n".join(_model_json_lines("kinematic_calibration", [], "kinematic"))
    assert "kinematic calibration of the runs with tracker_offset added" in "\n".join(
        _model_json_lines("unexplained", ["tracker_offset"], "kinematic"))
