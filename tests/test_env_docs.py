"""The documented observation and action layouts agree with the spaces and with what the env writes.

The observation tables in the environment docstrings (``OmniPathEnv``, ``OmniPathVectorEnv``) and in
``docs/environments.md`` are parsed here independently (symbolic index ranges in n wheels and A action
values) and evaluated for every registered id, both observation modes and both action modes; they must
tile exactly the observation space. The named slices of ``omni_gym.envs.observations`` are then checked
against ground truth the environment reports in ``info`` (not against the encoder itself). The keyword
tables (written from the declarations in ``EnvConfig`` by ``omni_gym.envs.docgen``) must be current and
name, for every registered id, the value its environment runs with.
"""

from __future__ import annotations

import inspect
import math
import re
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import omni_gym  # noqa: F401  (registers the ids)
from omni_gym.envs import ENV_IDS, docgen
from omni_gym.envs.config import EnvConfig
from omni_gym.envs.observations import POS_SCALE, SensorObsDecoder, StateObsDecoder, build_layout
from omni_gym.envs.omni_env import OmniPathEnv
from omni_gym.envs.vector import OmniPathVectorEnv

DOCS = Path(__file__).resolve().parents[1] / "docs" / "environments.md"
MODES = ("state", "sensors")
SECTIONS = ("Description", "Action Space", "Observation Space", "Rewards", "Starting State", "Episode End",
            "Arguments", "Version History")


def _sources() -> dict[str, str]:
    return {"OmniPathEnv": inspect.getdoc(OmniPathEnv), "OmniPathVectorEnv": inspect.getdoc(OmniPathVectorEnv),
            "docs/environments.md": DOCS.read_text(encoding="utf-8")}


def _index(expr: str, n: int, a: int) -> int:
    """Evaluate a documented index such as ``n+28+A`` or ``n−1`` for n wheels and A action values."""
    total, pos = 0, 0
    text = expr.replace("−", "-")
    for sign, coef, var in re.findall(r"([+-]?)(\d*)([nA]?)", text):
        if not (coef or var):
            continue
        value = int(coef) if coef else 1
        value *= {"n": n, "A": a, "": 1}[var]
        total += -value if sign == "-" else value
        pos += 1
    assert pos, f"unparsable index {expr!r}"
    return total


def _table(text: str, mode: str) -> list[tuple[str, str, str]]:
    """(first, last, name) rows of the Markdown table that follows the ``obs_mode="<mode>"`` heading line."""
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if re.match(rf'^`{{1,2}}obs_mode="{mode}"`{{1,2}} \(', line))
    rows = []
    for line in lines[start + 1:]:
        if not line.strip() and rows:
            break
        if not line.startswith("| ") or line.startswith("| index"):
            continue
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        first, _, last = cells[0].partition("…")
        rows.append((first, last or first, cells[1].strip("`")))
    assert rows, f"no table after obs_mode={mode!r}"
    return rows


def _cases():
    for env_id in ENV_IDS:
        for obs_mode in MODES:
            for action_mode in ("twist", "wheels"):
                yield env_id, obs_mode, action_mode


@pytest.mark.parametrize("source", ["OmniPathEnv", "OmniPathVectorEnv"])
def test_docstrings_have_every_gymnasium_section(source):
    text = _sources()[source]
    for section in SECTIONS:
        assert f"## {section}" in text, f"{source}: missing section {section!r}"


@pytest.mark.parametrize("env_id,obs_mode,action_mode", list(_cases()))
def test_documented_tables_tile_the_observation_space(env_id, obs_mode, action_mode):
    env = gym.make(env_id, obs_mode=obs_mode, action_mode=action_mode)
    u = env.unwrapped
    n = u.robot.n_wheels
    a = env.action_space.shape[0]
    assert a == (3 if action_mode == "twist" else n)  # the documented action sizes
    size = env.observation_space.shape[0]
    layout = u.observation_layout
    assert layout.size == size
    for source, text in _sources().items():
        rows = _table(text, obs_mode)
        covered = []
        for first, last, name in rows:
            lo, hi = _index(first, n, a), _index(last, n, a)
            assert layout[name] == slice(lo, hi + 1), f"{source}: {name} documented {lo}…{hi}"
            covered += range(lo, hi + 1)
        assert covered == list(range(size)), f"{source}: the {obs_mode} table does not tile 0…{size - 1}"
    env.close()


@pytest.mark.parametrize("obs_mode", MODES)
def test_docs_show_the_table_observations_py_renders(obs_mode):
    table = build_layout(obs_mode, 3, 3).table()
    for source, text in _sources().items():
        assert table in text, f"{source}: the {obs_mode} table differs from observations.py's"


@pytest.mark.parametrize("env_id", list(ENV_IDS))
def test_vector_spaces_match_the_documented_layout(env_id):
    for obs_mode in MODES:
        vec = gym.make_vec(env_id, num_envs=2, vectorization_mode="vector_entry_point", obs_mode=obs_mode)
        u = vec.unwrapped
        size = u.observation_layout.size
        assert vec.single_observation_space.shape == (size,)
        assert vec.observation_space.shape == (2, size)
        assert u.wheel_matrix.shape == (u.robot.n_wheels, 3)
        vec.close()


def test_named_state_slices_hold_the_ground_truth():
    """The state fields, decoded by name, agree with ``info`` and with the action sent."""
    env = gym.make("OmniPathFollow-Phunopas-v0", obs_mode="state")
    decode = StateObsDecoder.for_env(env)
    obs, info = env.reset(seed=4)
    rng = np.random.default_rng(0)
    for _ in range(30):
        action = rng.uniform(-1.5, 1.5, env.action_space.shape).astype(np.float32)
        obs, _, term, trunc, info = env.step(action)
        s = decode(obs)
        x, y, th = info["pose"]
        rx, ry, _ = info["reference_pose"]
        c, si = math.cos(th), math.sin(th)
        body = np.array([c * (rx - x) + si * (ry - y), -si * (rx - x) + c * (ry - y)])
        # float32 observation: relative error ~6e-8 on values up to OBS_CLIP · POS_SCALE = 2.5 m
        if np.all(np.abs(body) < 10 * POS_SCALE):
            assert np.allclose(s.tracking_error_body, body, atol=1e-6)
        assert s.heading_error == pytest.approx(info["heading_error"], abs=1e-6)
        vx, vy, om = info["velocity"]
        assert np.allclose(s.body_velocity, [c * vx + si * vy, -si * vx + c * vy, om], atol=1e-5)
        assert np.array_equal(s.last_action, np.clip(action, -1, 1).astype(np.float32))
        if term or trunc:
            break


def test_named_sensor_slices_hold_the_ground_truth():
    """Reference now and the last action are exact in the sensors layout; the fix age stays in [0, 1] s."""
    env = gym.make("OmniPathFollow-WilliamsPaper-v0", obs_mode="sensors", action_mode="wheels")
    decode = SensorObsDecoder.for_env(env)
    layout = env.unwrapped.observation_layout
    obs, info = env.reset(seed=1)
    rng = np.random.default_rng(2)
    for _ in range(30):
        action = rng.uniform(-1.5, 1.5, env.action_space.shape).astype(np.float32)
        obs, _, term, trunc, info = env.step(action)
        s = decode(obs)
        ref = info["reference_pose"]
        # float32 x/h (h = 2 m): relative error ~6e-8; the angle through atan2 of float32 sin, cos ~1e-7
        assert np.allclose(s.ref_pose[:2], ref[:2], atol=1e-6)
        assert abs(math.remainder(s.ref_pose[2] - ref[2], 2 * math.pi)) < 1e-6
        assert np.array_equal(obs[layout["last_action"]], np.clip(action, -1, 1))
        assert 0.0 <= s.fix_age <= 1.0
        if term or trunc:
            break


# --- the keyword tables, written from the declarations in EnvConfig (omni_gym.envs.docgen) -----------


def test_generated_tables_are_current():
    """The keyword and observation tables in the docstrings and docs/environments.md are what docgen writes."""
    assert docgen.stale() == [], "stale generated tables: run python -m omni_gym.envs.docgen --write"


def test_docgen_finds_a_stale_table_and_rewrites_only_it(tmp_path):
    for t in docgen.targets():
        dest = tmp_path / t.path
        dest.parent.mkdir(parents=True, exist_ok=True)
        dest.write_text((docgen.ROOT / t.path).read_text(encoding="utf-8"), encoding="utf-8")
    md = tmp_path / "docs" / "environments.md"
    text = md.read_text(encoding="utf-8")
    row = next(line for line in text.splitlines() if line.startswith("| `control_hz` |"))
    md.write_text(text.replace(row, row.replace("| 100 |", "| 50 |")), encoding="utf-8")
    assert docgen.stale(tmp_path) == ["docs/environments.md"]
    _, new = docgen.rendered(tmp_path)["docs/environments.md"]
    assert new == text  # only the table changed back; the prose around it is untouched
    with pytest.raises(ValueError, match="no table after the anchor"):
        docgen.replace_table("## Arguments\n\ntext\n", r"## Arguments$", "| a |", "x.md")


def _keyword_rows(text: str) -> dict[str, list[str]]:
    """keyword -> its cells, from the table whose header starts ``| keyword | default |``."""
    lines = [line.strip() for line in text.splitlines()]
    start = lines.index("| keyword | default | allowed | unit | meaning |")
    rows = {}
    for line in lines[start + 2:]:
        if not line.startswith("|"):
            break
        cells = [c.strip() for c in line.strip("|").split("|")]
        rows[cells[0].strip("`")] = cells
    return rows


def _shown(value) -> str:
    """A configuration value as the tables show it (names in backticks, numbers in short form)."""
    if isinstance(value, str):
        return f"`{value}`"
    return f"{value:g}" if isinstance(value, float) else str(value)


@pytest.mark.parametrize("source", ["OmniPathEnv", "docs/environments.md"])
def test_every_keyword_is_documented_with_each_ids_default(source):
    """Every keyword make_config accepts has a row, and its default column names, for every registered id,
    the value that id's environment actually runs with."""
    rows = _keyword_rows(_sources()[source])
    assert set(rows) == set(inspect.signature(EnvConfig).parameters)
    for env_id in ENV_IDS:
        cfg = gym.make(env_id).unwrapped.cfg
        short = env_id.removeprefix("OmniPathFollow-").removeprefix("Omni")
        for name, cells in rows.items():
            default, *per_id = cells[1].split("; ")
            documented = default
            for part in per_id:
                ids, _, value = part.partition(": ")
                if short in ids.split(", "):
                    documented = value
            assert documented == _shown(getattr(cfg, name)), f"{source}: {name} on {env_id}"
