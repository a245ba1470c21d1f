"""The second integrator (analysis/event_integrator.py) and its dataset writer (analysis/second_generator.py).

(a) nothing hidden, the world and the second integrator agree on the same commands (two implementations
written independently from the same documents); (b) every effect moves the tracked output by more than
the tracker noise; (c) one seed gives the same bytes; (d) bad input is refused in one line naming it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from omni_gym.analysis.event_integrator import build_plant, draw_lift_schedule, integrate
from omni_gym.analysis.second_generator import run_commands, simulate_run, write_second_dataset
from omni_gym.discrepancy.data.dataset import load_dataset
from omni_gym.physics.liftoff import ScheduledContactProcess
from omni_gym.physics.model import load_model
from omni_gym.physics.replay import simulate_commands
from omni_gym.physics.world import World

NOISE = 1e-3  # m: the generator's default tracker noise (heading 2 mrad, i.e. 0.18-0.28 mm at the lever)


def _pooled_mm(a: np.ndarray, b: np.ndarray, lever: float) -> float:
    res = (a - b) * np.array([1e3, 1e3, 1e3 * lever])
    return float(np.sqrt(np.mean(np.mean(res ** 2, axis=0))))


def _lever(model) -> float:
    return max(math.hypot(*w.position) for w in model.robot.wheels)


@pytest.mark.parametrize("robot,friction,family,effects", [
    ("williams2002", "initial", "steps", {}),
    ("williams2002", "roller_gap", "turns", {}),
    ("optiodom_omni4", "initial", "smooth", {}),
    # a lagged wheel switching between roller and rigid material: the gap events on the integrated angle
    ("williams2002", "roller_gap", "steps", {"motor_lag": {"tau": 0.05}}),
])
def test_world_and_second_integrator_agree(robot, friction, family, effects):
    nominal = load_model(robot, surface="carpet", friction=friction)
    model = nominal
    for name, params in effects.items():
        model = model.with_effect(name, params)
    times, cmd = run_commands(nominal, family, 2.5, 100.0, np.random.default_rng(11))
    mine = integrate(build_plant(model), times, cmd, times).pose
    lever = _lever(model)
    coarse = _pooled_mm(mine, simulate_commands(model, times, cmd, dt=1e-3)[:, :3], lever)
    fine = _pooled_mm(mine, simulate_commands(model, times, cmd, dt=5e-4)[:, :3], lever)
    # The world is first order in its step (docs/model.md: 0.15 mm / 1 mrad over 2 s at 0.5 ms against
    # the first reference); measured on these runs 0.05-0.2 mm pooled at 1 ms
    # (benchmarks/results/second_generator_disagreement.md). 0.3 mm at 0.5 ms is a third of the 1 mm
    # tracker noise and ten times below the smallest effect of the study; a convention difference
    # (gap phase, loads, command timing) gives millimetres.
    assert fine < 0.3, (coarse, fine)
    # The disagreement is the world's step error, not a model difference: it halves with the step
    # (ratio measured 0.47-0.55; 0.7 leaves room and still fails for a constant offset).
    assert fine < 0.7 * coarse, (coarse, fine)


@pytest.mark.parametrize("robot", ["williams2002", "optiodom_omni4"])
def test_world_and_second_integrator_agree_on_a_lift_schedule(robot):
    # Wheel 2 up over [0.4, 0.9) s, wheel 1 over [1.3, 1.8) s: the loads switch exactly at these
    # times here, at the first substep at or after them in the world.
    model = load_model(robot, surface="carpet", friction="initial")
    n = model.n_wheels
    times, cmd = run_commands(model, "steps", 2.5, 100.0, np.random.default_rng(5))
    up = np.eye(n, dtype=bool)
    schedule = [(0.4, up[1]), (0.9, ~up[0] & up[0]), (1.3, up[0]), (1.8, ~up[0] & up[0])]
    mine = integrate(build_plant(model), times, cmd, times, lift_schedule=schedule).pose
    dt = 5e-4
    world = World(model, dt=dt)
    world.set_contact_process(0, ScheduledContactProcess(n, [(0.4, 0.9, 2), (1.3, 1.8, 1)]))
    world.reset()
    pose = np.zeros((len(times), 3))
    ticks = np.rint(times / dt).astype(np.int64)
    for j in range(len(times) - 1):
        world.set_commands(cmd[j])
        world.substeps(int(ticks[j + 1] - ticks[j]))
        pose[j + 1] = world.pose[0]
    # Measured 0.13-0.15 mm at 0.5 ms (0.25-0.30 mm at 1 ms: first order), while the two lifts move
    # the pose by 28-37 mm; the bound of the nothing-hidden test.
    assert _pooled_mm(mine, pose, _lever(model)) < 0.3


EFFECTS_3 = {
    "com_offset": {"com": [0.015, -0.01]},
    "wheel_radius": {"scale": [1.04, 1.0, 0.97]},
    "wheel_geometry": {"distance": [1.03, 1.0, 0.98], "mount": [0.03, 0.0, -0.02]},
    "motor_lag": {"tau": 0.06},
    "kinetic_friction": {"ratio": 0.7, "v_s": 0.02},
    "roller_gap": {"mu_gap": 0.5, "roller_fraction": 0.85, "phase": [0.1, 0.3, 0.5]},
    "wheel_liftoff": {"lift_rate": 2.0, "recover_rate": 4.0},
    "tracker_offset": {"offset": [0.02, -0.01], "yaw": 0.02},
    "time_offset": {"delay": 0.04},
    "drag": 3.0,
}


@pytest.mark.parametrize("robot,name,params", [("williams2002", k, v) for k, v in EFFECTS_3.items()]
                         + [("optiodom_omni4", "mecanum_lateral", {"ratio": 0.9}),
                            ("optiodom_omni4", "wheel_liftoff", {"lift_rate": 2.0, "recover_rate": 4.0})])
def test_each_effect_moves_the_tracked_output_beyond_noise(robot, name, params):
    model = load_model(robot, surface="carpet", friction="initial")
    times, cmd = run_commands(model, "steps", 2.5, 100.0, np.random.default_rng(5))
    start = np.array([0.1, -0.2, 0.5])
    nominal = simulate_run(model, {}, times, cmd, start, np.random.default_rng(0))
    hidden = simulate_run(model, {name: params}, times, cmd, start, np.random.default_rng(0))
    if name == "wheel_liftoff":
        assert hidden["lift_schedule"], "the seed must lift a wheel within the run"
    # RMS over the run of the noise-free change, against the 1 mm noise std of one sample
    change = _pooled_mm(hidden["pose"], nominal["pose"], _lever(model))
    assert change > 1e3 * NOISE, change


def test_lift_schedule_follows_the_contact_process():
    plant = build_plant(load_model("optiodom_omni4", surface="carpet", friction="initial"),
                        {"wheel_liftoff": {"lift_rate": 3.0, "recover_rate": 6.0}})
    schedule = draw_lift_schedule(plant, 400.0, np.random.default_rng(1))
    lifted = [m for _, m in schedule[0::2]]
    downs = [m for _, m in schedule[1::2]]
    assert all(not m.any() for m in downs)
    pairs = [tuple(np.flatnonzero(m)) for m in lifted if m.sum() == 2]
    assert set(pairs) == {(0, 3), (1, 2)}  # the diagonal pairs of the mecanum layout
    # Mean dwell all-down 1/3 s, lifted 1/6 s (several hundred draws: within 15 %).
    t = np.array([0.0] + [s for s, _ in schedule])
    dwell = np.diff(t)
    assert abs(dwell[0::2].mean() - 1 / 3) < 0.05 and abs(dwell[1::2].mean() - 1 / 6) < 0.025


def _files(root):
    return {p.relative_to(root.parent).as_posix(): p.read_bytes() for p in sorted(root.parent.rglob("*"))
            if p.is_file() and not p.name.startswith(".")}


def test_one_seed_one_dataset(tmp_path):
    kw = dict(robot="williams2002", hidden={"com_offset": {"com": [0.01, 0.0]}}, runs=3, duration=2.5,
              manoeuvre="turns", position_noise=0.001, heading_noise=0.002, encoder_counts=1024)
    a = write_second_dataset(tmp_path / "a" / "d", seed=7, **kw)
    b = write_second_dataset(tmp_path / "b" / "d", seed=7, **kw)
    c = write_second_dataset(tmp_path / "c" / "d", seed=8, **kw)
    assert _files(a) == _files(b)
    assert _files(a) != _files(c)
    data = load_dataset(a)
    assert len(data.runs) == 3 and data.model.effects == {}
    q = 2 * math.pi / 1024
    enc = data.runs[0].enc
    assert np.allclose(enc[0], 0.0) and np.allclose(enc / q, np.round(enc / q), atol=1e-9)


@pytest.mark.parametrize("hidden,robot,match", [
    ({"wheel_slip": {}}, "williams2002", "unknown effect 'wheel_slip'"),
    ({"wheel_radius": {"scale": [1.0, 1.0]}}, "williams2002", "expected 3 values"),
    ({"wheel_geometry": {"distance": [1.0] * 3, "mount": [0.0] * 3}}, "optiodom_omni4", "expected 4 values"),
    ({"mecanum_lateral": {"ratio": 0.9}}, "williams2002", "mecanum wheels only"),
    ({"roller_gap": {"mu_gap": 0.5, "roller_fraction": 0.9, "phase": [0.0] * 4}}, "optiodom_omni4", "omni wheels only"),
    ({"motor_lag": {"tau": float("nan")}}, "williams2002", "NaN"),
    ({"drag": float("nan")}, "williams2002", "NaN"),
])
def test_bad_hidden_effect_is_refused_in_one_line(tmp_path, hidden, robot, match):
    with pytest.raises(ValueError, match=match) as info:
        write_second_dataset(tmp_path / "d", robot=robot, hidden=hidden, runs=3, duration=2.5, seed=1)
    assert "\n" not in str(info.value)
    assert not (tmp_path / "d").exists()


@pytest.mark.parametrize("kw,match", [({"duration": float("nan")}, "duration: NaN"),
                                      ({"runs": 2}, "runs"), ({"manoeuvre": "zigzag"}, "zigzag"),
                                      ({"robot": "rover"}, "rover"), ({"position_noise": -1.0}, "position_noise")])
def test_bad_settings_are_refused_in_one_line(tmp_path, kw, match):
    args = dict(robot="williams2002", runs=3, duration=2.5, seed=1)
    args.update(kw)
    with pytest.raises(ValueError, match=match) as info:
        write_second_dataset(tmp_path / "d", **args)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("family", ["steps", "smooth", "turns"])
def test_runs_rest_at_both_ends(family):
    model = load_model("optiodom_omni4", surface="carpet", friction="initial")
    times, cmd = run_commands(model, family, 3.0, 100.0, np.random.default_rng(3), start_rest=0.5)
    moving = np.any(cmd != 0.0, axis=1)
    assert not moving[times < 0.5].any() and moving[(times > 0.5) & (times < 1.5)].any()
    assert not moving[times >= 3.0 - 0.3].any()
