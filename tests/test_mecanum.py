"""Mecanum wheels (roller angle γ ≠ 0): model JSON, refusals, and the preset through the model layer."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from omni_gym.physics.friction import surface_preset
from omni_gym.physics.model import SimModel, load_model
from omni_gym.physics.robot import optiodom_omni4, phunopas2018, williams2002


def test_model_json_round_trip_keeps_roller_angles():
    model = load_model("optiodom_omni4", "paper")
    data = json.loads(json.dumps(model.to_json()))
    assert [w["roller_angle"] for w in data["wheels"]] == pytest.approx([-math.pi / 4, math.pi / 4, math.pi / 4,
                                                                         -math.pi / 4], abs=0)
    back = SimModel.from_json(data)
    assert back.robot.wheels == model.robot.wheels
    np.testing.assert_array_equal(back.robot.wheel_matrix(), model.robot.wheel_matrix())


def test_omni_json_has_no_roller_angle_key():
    """Omni-wheel model files stay exactly as they were: the key is written only when non-zero."""
    for robot in ("williams2002", "phunopas2018"):
        data = load_model(robot).to_json()
        assert all(set(w) == {"position", "drive"} for w in data["wheels"])
    # A file with an explicit 0 reads as the omni wheel.
    data = load_model("williams2002").to_json()
    data["wheels"][0]["roller_angle"] = 0
    assert SimModel.from_json(data).robot == williams2002()


KEY = r"wheels\[1\].roller_angle"


@pytest.mark.parametrize(("value", "message"), [(1.2, KEY + " must be a number in"), ("x", KEY), (None, KEY)])
def test_bad_roller_angle_in_json_is_one_line(value, message):
    data = load_model("phunopas2018").to_json()
    data["wheels"][1]["roller_angle"] = value
    with pytest.raises(ValueError, match=message) as err:
        SimModel.from_json(data, where="m.json")
    assert "\n" not in str(err.value) and str(err.value).startswith("m.json: ")


def test_preset_defaults_to_initial_friction_and_refuses_roller_gap():
    assert load_model("optiodom_omni4").friction == "initial"
    assert load_model("phunopas2018").friction == "roller_gap"
    with pytest.raises(ValueError, match="'roller_gap' applies to omni wheels only"):
        load_model("optiodom_omni4", friction="roller_gap")
    data = load_model("optiodom_omni4").to_json()
    data["friction"] = "roller_gap"
    with pytest.raises(ValueError, match="^f.json: friction model 'roller_gap' applies to omni wheels only"):
        SimModel.from_json(data, where="f.json")


def test_roller_gap_effect_refused_on_mecanum_others_accepted():
    model = SimModel(robot=optiodom_omni4(), surface=surface_preset("carpet"), friction="initial")
    with pytest.raises(ValueError, match="effect 'roller_gap' applies to omni wheels only"):
        model.with_effect("roller_gap", {"mu_gap": 0.5, "roller_fraction": 0.9, "phase": [0.0] * 4})
    # Every other effect applies to mecanum wheels (docs/model.md, per effect).
    for name, params in {"kinetic_friction": {"ratio": 0.7, "v_s": 0.02}, "com_offset": {"com": [0.01, 0.0]},
                         "wheel_radius": {"scale": [1.0, 1.01, 0.99, 1.0]}, "motor_lag": {"tau": 0.05},
                         "wheel_liftoff": {"lift_rate": 0.5, "recover_rate": 5.0},
                         "wheel_geometry": {"distance": [1.0] * 4, "mount": [0.0, 0.01, 0.0, 0.0]}}.items():
        model.with_effect(name, params)
    from omni_gym.physics.effects import REGISTRY

    assert [n for n, e in REGISTRY.items() if not e.applies_to(model.robot)] == ["roller_gap"]
    # mecanum_lateral scales the lateral travel of angled rollers: omni wheels have none to scale.
    assert [n for n, e in REGISTRY.items() if not e.applies_to(phunopas2018())] == ["mecanum_lateral"]
    # The omni robot keeps the roller_gap effect.
    SimModel(robot=phunopas2018(), surface=surface_preset("carpet"), friction="initial").with_effect(
        "roller_gap", {"mu_gap": 0.5, "roller_fraction": 0.9, "phase": [0.0] * 4})


def test_kernel_params_carry_roller_angle():
    from omni_gym.physics.layout import WP_COSG, WP_SING

    _, wp = load_model("optiodom_omni4").kernel_params()
    np.testing.assert_allclose(wp[:, WP_COSG], math.sqrt(0.5))
    np.testing.assert_allclose(wp[:, WP_SING], [-math.sqrt(0.5), math.sqrt(0.5), math.sqrt(0.5), -math.sqrt(0.5)])
    _, wp = load_model("williams2002").kernel_params()
    assert np.all(wp[:, WP_COSG] == 1.0) and np.all(wp[:, WP_SING] == 0.0)


def test_unpowered_mecanum_wheel_carries_no_drive_torque():
    """Servo wheels whose motors give (almost) no torque spin with the floor: J dw/dt = −r F·d.

    The ground force reaches a mecanum wheel's axle through the roller's bearing, so the wheel is
    driven by F·d = −N (μ_W(v_W) cos γ − μ_T(v_T) sin γ) (docs/model.md), the rolling friction along the
    free direction included. Coasting robot, motor torque limit 1e-9 N·m: the wheel's angular
    acceleration (finite difference over 1 ms) must match that force, computed here from the slips the
    world reports and the surface's law. Tolerance 2 % of r·N·μ'_W (measured 1.1 %): the kernel takes
    the wheel's friction implicitly (dt·r²·N·dμ/dv ≈ 7 J), so the balance holds for the force
    linearised about each substep's start, not for the law at the sampled slip. Dropping the μ_T term
    leaves a residual of 24 %, flipping its sign 49 % (measured).
    """
    from omni_gym.physics.friction import regularised_coulomb
    from omni_gym.physics.model import Actuation
    from omni_gym.physics.world import World

    model = load_model("optiodom_omni4", "paper")
    act = Actuation("servo", kp=1e-9, ki=1e-9, torque_limit=1e-9, wheel_inertia=1e-4)
    world = World(model, actuation=act)
    world.reset()
    world.bodies[0].velocity = (0.3, 0.2)
    world.bodies[0].angular_velocity = 0.5
    world.set_commands(np.zeros(4))
    world.step(0.05)  # the wheels settle within ~0.1 ms (J / (r² N μ')); the body coasts
    h = 1e-3
    w0 = world.wheel_speed[0].copy()
    world.step(h / 2)
    slip = world.slip[0].copy()
    world.step(h / 2)
    dw_dt = (world.wheel_speed[0] - w0) / h
    r, s = model.robot.wheel_radius, model.surface
    load = model.robot.mass * model.gravity / 4
    gamma = model.robot.roller_angles()
    mu_w = regularised_coulomb(slip[:, 0], s.mu_drive, s.k)
    mu_t = regularised_coulomb(slip[:, 1], s.mu_transverse, s.k)
    torque = r * load * (mu_w * np.cos(gamma) - mu_t * np.sin(gamma))  # −r F·d
    assert np.all(np.abs(mu_t) > 0.5 * s.mu_transverse)  # the rollers' rolling friction is engaged
    np.testing.assert_allclose(act.wheel_inertia * dw_dt, torque, rtol=0, atol=0.02 * r * load * s.mu_drive)


def test_replay_runs_the_preset_with_liftoff_deterministically():
    """simulate_commands (what ``omni-gym simulate`` runs) drives the mecanum preset, lift-off included."""
    from omni_gym.physics.replay import simulate_commands

    lift = {"lift_rate": 5.0, "recover_rate": 5.0}
    model = load_model("optiodom_omni4", "carpet").with_effect("wheel_liftoff", lift)
    wm = model.robot.wheel_matrix()
    times = np.array([0.0, 0.5, 1.0, 1.5])
    commands = np.array([wm @ [0.3, 0.0, 0.0], wm @ [0.0, 0.3, 0.0], wm @ [0.0, 0.0, 1.0], np.zeros(4)])
    a = simulate_commands(model, times, commands, seed=3)
    b = simulate_commands(model, times, commands, seed=3)
    c = simulate_commands(model, times, commands, seed=4)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)  # another lift-off realisation
    # Forward 0.5 s at 0.3 m/s: 0.15 m less the start-up slip (forward, the floor rollers do not roll).
    assert 0.10 < a[1, 0] < 0.16 and abs(a[1, 1]) < 0.02
    # Then sideways: the rollers roll, and on carpet their rolling friction (μ'_T 0.15) is 60 % of the
    # sliding friction, so the forward speed decays at only (μ'_W − μ'_T)·g/2 ≈ 0.5 m/s² (docs/model.md)
    # and the robot moves left more slowly than commanded; it moves left all the same.
    assert a[2, 1] - a[1, 1] > 0.02


def test_sideways_start_accelerates_at_the_saturated_friction_balance():
    """From rest, commanded sideways on carpet, every roller slips and rolls at saturated friction.

    Hand derivation (docs/model.md): each wheel's sliding friction μ'_W along its roller axis e and
    rolling friction μ'_T along its free direction f both have a y component of magnitude N/√2, the
    first pulling left, the second holding back, so m·a_y = 4·N·(μ'_W − μ'_T)/√2 and
    a_y = g (μ'_W − μ'_T)/√2 = 0.694 m/s² on carpet, with no x motion or turn by symmetry. Over 0.2 s the
    slips stay above 0.1 m/s (atan(k·v) within 0.7 % of saturation, 0.4 % on average), so
    y(0.2 s) = a_y t²/2 less that share (measured −0.75 %); bound 2 %. A wrong roller angle sign or a
    missing rolling term changes a_y by tens of per cent.
    """
    from omni_gym.physics.world import World

    model = load_model("optiodom_omni4", "carpet")
    s = model.surface
    world = World(model)
    world.reset()
    world.set_commands(model.robot.wheel_matrix() @ [0.0, 0.3, 0.0])
    world.step(0.2)
    a_y = model.gravity * (s.mu_drive - s.mu_transverse) / math.sqrt(2.0)
    assert world.pose[0, 1] == pytest.approx(0.5 * a_y * 0.2**2, rel=0.02)
    assert abs(world.pose[0, 0]) < 1e-9 and abs(world.pose[0, 2]) < 1e-9


@pytest.mark.parametrize("surface", ["carpet", "paper", "grip"])
def test_forward_to_sideways_switch_decelerates_along_the_diagonal(surface):
    """docs/model.md's example: at 0.3 m/s forward, the command switched to 0.3 m/s sideways.

    Hand derivation (docs/model.md): wheels 2 and 3 turn at the same speed for both commands and hold
    the velocity's (1, 1)/√2 component; along (1, −1)/√2 wheels 1 and 4 slide (μ'_W·N each) and the
    rollers of wheels 2 and 3 roll against it (μ'_T·N each), so the forward speed falls at
    (μ'_W − μ'_T)·g/(2√2) (0.347 m/s² on carpet, 0.590 on paper, 6.94 on grip) and the sideways speed grows
    at the same rate. The slope is taken from 0.1 s after the switch (the rolling friction ramps up with the
    rolling speed, atan(k·v); on grip, with no rolling friction, from 15 % of the phase) to 60 % of the way
    to zero forward speed (the sliding wheels' slip shrinks near the end); there the measured slope is within
    0.3 % of the formula, so the bound is 1 %. The old example's (μ'_W − μ'_T)·g/2 is √2 larger: 41 % off.
    """
    from omni_gym.physics.world import World

    model = load_model("optiodom_omni4", surface)
    s = model.surface
    decel = model.gravity * (s.mu_drive - s.mu_transverse) / (2.0 * math.sqrt(2.0))
    matrix = model.robot.wheel_matrix()
    world = World(model)
    world.reset()
    world.set_commands(matrix @ [0.3, 0.0, 0.0])
    world.step(3.0)  # steady forward motion: the rollers do not roll, nothing slips
    assert world.velocity[0] == pytest.approx([0.3, 0.0, 0.0], abs=1e-9)
    world.set_commands(matrix @ [0.0, 0.3, 0.0])
    t_end = 0.3 / decel  # s: forward speed 0
    t0, t1 = min(0.1, 0.15 * t_end), 0.6 * t_end
    world.step(t0)
    v0 = world.velocity[0].copy()
    world.step(t1 - t0)
    v1 = world.velocity[0].copy()
    span = round((t1 - t0) / world.dt) * world.dt  # the time step() actually ran
    forward, sideways = (v0[0] - v1[0]) / span, (v1[1] - v0[1]) / span
    assert forward == pytest.approx(decel, rel=0.01)
    assert sideways == pytest.approx(decel, rel=0.01)  # the change is along the diagonal
    assert abs(v1[2]) < 1e-9  # no turn, by symmetry
