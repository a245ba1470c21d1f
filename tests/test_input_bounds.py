"""Every input read is bounded (docs/bounds.md, "Files"): sizes, special files, JSON nesting, YAML aliases;
messages quote a short excerpt and name the file, line or key."""

import gzip
import json
import os
import signal
from pathlib import Path

import pytest

from omni_gym import io as oio
from omni_gym.cli import main
from omni_gym.io import InputError, parse_json, read_json, read_text, read_yaml


@pytest.fixture
def small_limit():
    """A 1 kB text limit for the test (restored afterwards)."""
    before = oio.max_input_bytes()
    oio.set_max_input_mb(0.001)
    yield oio.max_input_bytes()
    oio._limits["input_bytes"] = before


def _cli(capsys, *args: str) -> str:
    assert main(list(args)) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("omni-gym: error: "), err
    assert len(err[0]) < 400, err[0]  # a short line, whatever the input held
    return err[0]


def test_special_files_are_refused_before_they_are_opened(tmp_path, capsys):
    """/dev/zero would be read forever; a pipe would block the open until a writer comes."""
    fifo = tmp_path / "commands.csv"
    os.mkfifo(fifo)
    for path in ("/dev/zero", str(fifo)):
        err = _cli(capsys, "simulate", "--model", "williams2002", "--commands", path, "--out", str(tmp_path / "o.csv"))
        assert f"{path}: not a regular file" in err
    with pytest.raises(InputError, match="not a regular file"):
        read_json("/dev/zero")


def test_size_limit_and_the_flag_that_raises_it(tmp_path, capsys, small_limit):
    f = tmp_path / "commands.csv"
    f.write_text("t,w1,w2,w3\n" + "".join(f"{i * 0.01:.2f},1,1,1\n" for i in range(200)))
    assert f.stat().st_size > small_limit
    with pytest.raises(InputError, match=r"commands.csv: .* MB is more than the .* limit .*--max-input-mb"):
        read_text(f)
    # The command-line flag sets the limit for the command (here: back up to 1 MB, so the file is read).
    out = tmp_path / "traj.csv"
    assert main(["--max-input-mb", "1", "simulate", "--model", "williams2002", "--commands", str(f),
                 "--out", str(out)]) == 0
    assert out.is_file()
    assert "--max-input-mb must be in" in _cli(capsys, "--max-input-mb", "0", "model", "show", "williams2002")


def test_gzip_bomb_is_bounded_after_decompression(tmp_path, small_limit):
    f = tmp_path / "run.csv.gz"
    f.write_bytes(gzip.compress(b"0" * (50 * small_limit)))  # about 100 bytes on disk
    assert f.stat().st_size < small_limit
    with pytest.raises(InputError, match="decompresses to more than"):
        read_text(f)


def test_json_nesting_is_bounded_and_named(tmp_path, capsys):
    deep = "[" * 100_000 + "]" * 100_000
    err = _cli(capsys, "evaluate", "--policy", "ekf-pid", "--env", "OmniPathFollow-Phunopas-v0", "--episodes", "1",
               "--env-kwargs", deep)
    assert "--env-kwargs: not valid JSON" in err or "--env-kwargs: JSON nested" in err
    f = tmp_path / "model.json"
    f.write_text("[" * 100 + "]" * 100)
    with pytest.raises(InputError, match=r"model.json: JSON nested more than 64 levels"):
        read_json(f)
    assert parse_json("[" * 64 + "]" * 64, "x") is not None  # the bound itself is accepted


def test_huge_integers_in_json_name_the_file(tmp_path, capsys):
    f = tmp_path / "robot.json"
    f.write_text('{"mass": ' + "9" * 5000 + "}")
    err = _cli(capsys, "model", "show", str(f))
    assert f"{f}: not valid JSON" in err


def test_yaml_alias_bomb_is_refused_in_one_short_line(tmp_path, capsys):
    levels = ["a: &a [x, x, x, x, x, x, x, x, x]"]
    for k in range(1, 9):
        prev, cur = chr(ord("a") + k - 1), chr(ord("a") + k)
        levels.append(f"{cur}: &{cur} [" + ", ".join([f"*{prev}"] * 9) + "]")
    f = tmp_path / "hp.yml"
    f.write_text("\n".join(levels) + "\n")
    with pytest.raises(InputError, match="hp.yml: more than 100000 values once its aliases"):
        read_yaml(f)
    err = _cli(capsys, "train", "--algo", "ppo", "--env", "OmniPathFollow-Phunopas-v0", "--out", str(tmp_path / "m"),
               "--hyperparams", str(f), "--no-progress")
    assert "hp.yml" in err
    # Aliases within the bound are read (the shipped hyperparameter files use merge keys).
    f.write_text("base: &b {gamma: 0.9}\nenv: {<<: *b, n_envs: 2}\n")
    assert read_yaml(f)["env"] == {"gamma": 0.9, "n_envs": 2}


def test_yaml_errors_quote_a_short_excerpt(tmp_path):
    f = tmp_path / "hp.yml"
    f.write_text("key: [" + "x, " * 20_000 + "\n: :")
    with pytest.raises(InputError) as info:
        read_yaml(f)
    assert "hp.yml: not valid YAML (line" in str(info.value) and len(str(info.value)) < 300


def test_hidden_effect_with_an_empty_parameter_list_is_refused(tmp_path, capsys):
    err = _cli(capsys, "synth", "--model", "williams2002", "--hidden", "motor_lag:", "--out", str(tmp_path / "ds"))
    assert "--hidden motor_lag: nothing after ':'" in err
    err = _cli(capsys, "synth", "--model", "williams2002", "--hidden", "motor_lag:" + "[" * 100_000,
               "--out", str(tmp_path / "ds"))
    assert "--hidden motor_lag: parameters" in err
    assert "--hidden none takes no parameters" in _cli(capsys, "synth", "--model", "williams2002", "--hidden",
                                                         "none:{}", "--out", str(tmp_path / "ds"))
    assert not (tmp_path / "ds").exists()


def test_roller_angle_at_the_printed_bound_is_accepted():
    """docs/bounds.md prints the bound as 1.0472 (π/3 rounded); that value itself must be accepted."""
    from omni_gym.physics.model import MODEL_BOUNDS

    bound = MODEL_BOUNDS["wheels[i].roller_angle"]
    assert bound.contains(1.0472) and bound.contains(-1.0472) and not bound.contains(1.0473)


def test_nested_temporaries_of_a_companion_are_cleaned(tmp_path):
    """A run killed inside a staged companion's own atomic write leaves '..NAME.tmp-P-0.tmp-P-0'."""
    out = tmp_path / "x"
    assert main(["synth", "--model", "williams2002", "--hidden", "none", "--runs", "1", "--duration", "0.4",
                 "--out", str(out)]) == 0
    stale = tmp_path / "..x.truth.json.tmp-123-0.tmp-123-0"
    stale.write_text("partial")
    keep = tmp_path / "..y.truth.json.tmp-1-0.tmp-1-0"  # another target's: not ours to remove
    keep.write_text("other")
    assert main(["synth", "--model", "williams2002", "--hidden", "none", "--runs", "1", "--duration", "0.4",
                 "--out", str(out), "--force"]) == 0
    assert not stale.exists() and keep.exists()


def test_the_command_line_ignores_a_late_interrupt_once_main_returns(monkeypatch):
    """After main() returns in the command line, a Ctrl-C while the interpreter exits must not end it with
    status -2 and no message (the work is already committed)."""
    import omni_gym.interrupts as interrupts

    before = signal.getsignal(signal.SIGINT)
    monkeypatch.setattr(interrupts, "is_command_line", lambda: True)
    try:
        assert main(["model", "show", "williams2002", "--json"]) == 0
        assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, before)


def test_messages_quote_short_excerpts(capsys):
    err = _cli(capsys, "evaluate", "--policy", "ekf-pid", "--env", "OmniPathFollow-Phunopas-v0", "--episodes", "1",
               "--env-kwargs", json.dumps(["x" * 10_000]))
    assert "--env-kwargs must be a JSON object" in err


def test_read_text_names_the_file_for_bad_bytes(tmp_path):
    f = tmp_path / "runs.csv"
    f.write_bytes(b"t,w1\n0,\xff\n")
    with pytest.raises(InputError, match=r"runs.csv: not a UTF-8 text file"):
        read_text(f)
    assert Path(f).exists()


def test_a_huge_integer_hyperparameter_names_the_file_and_key(tmp_path, capsys):
    f = tmp_path / "hp.yml"
    f.write_text("OmniPathFollow-Phunopas-v0: {batch_size: " + "9" * 400 + "}\n")
    err = _cli(capsys, "train", "--algo", "ppo", "--env", "OmniPathFollow-Phunopas-v0", "--hyperparams", str(f),
               "--out", str(tmp_path / "m"), "--no-progress")
    assert "hp.yml: batch_size must be an integer" in err and "..." in err
