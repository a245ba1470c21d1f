"""``omni-gym import FORMAT`` refuses an option that FORMAT does not read (docs/formats.md), in one line and
before anything is written, rather than ignoring it."""

from __future__ import annotations

from pathlib import Path

import pytest

from omni_gym.cli import main

ROOT = Path(__file__).resolve().parents[1]
SESSION = ROOT / "data" / "optiodom-omni3" / "circular" / "221220201730"


@pytest.mark.parametrize("fmt, extra, message", [
    ("optiodom", ["--columns", "t=a,x=b,y=c,theta=d,enc1=e,enc2=f,enc3=g"], "--columns applies to 'import csv', not "
                                                                           "'import optiodom'"),
    ("optiodom", ["--joints", "a,b,c"], "--joints applies to 'import rosbag2', not 'import optiodom'"),
    ("optiodom", ["--units", "mm"], "--units applies to 'import csv' and 'import rosbag2', not 'import optiodom'"),
    ("optiodom", ["--model", "williams2002"], "--model applies to 'import csv' and 'import rosbag2'"),
    ("csv", ["--joint-topic", "/js"], "--joint-topic applies to 'import rosbag2', not 'import csv'"),
    ("csv", ["--wheel-field", "velocity"], "--wheel-field applies to 'import rosbag2', not 'import csv'"),
    ("csv", ["--time-base", "file"], "--time-base applies to 'import optiodom', not 'import csv'"),
    ("rosbag2", ["--mass", "3"], "--mass applies to 'import optiodom', not 'import rosbag2'"),
])
def test_an_option_of_another_format_is_refused(tmp_path, capsys, fmt, extra, message):
    # The OptiOdom session itself imports (test_import_optiodom): only the foreign option is wrong.
    rc = main(["import", fmt, str(SESSION), "--out", str(tmp_path / "ds"), *extra])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and message in err, err
    assert not (tmp_path / "ds").exists()


def test_a_mapping_key_of_another_format_is_refused(tmp_path, capsys):
    mapping = tmp_path / "map.json"
    mapping.write_text('{"joint_topic": "/js"}')
    rc = main(["import", "csv", str(tmp_path / "log.csv"), "--mapping", str(mapping), "--out", str(tmp_path / "ds")])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and "joint_topic applies to 'import rosbag2', not 'import csv'" in err, err
