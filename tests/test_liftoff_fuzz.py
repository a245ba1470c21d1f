"""The wheel contact process terminates and stays finite for every allowed rate.

Tiny rates used to hang or overflow the world's switch scheduling (``lift_rate=1e-30`` hung
``reset``, ``1e-16`` raised OverflowError, ``recover_rate=1e-30`` hung mid-episode). The code now
decides "no switch" in float seconds before forming any integer (``omni_gym.physics.world.switch_tick``), so
nothing here depends on 1/rate. The tests cannot time that structure; a regression would show as a
test that never ends, so every case runs under a SIGALRM guard that turns a hang into a failure
(the limit is minutes, far above the fraction of a second a case takes: it is not a timing test).
"""

from __future__ import annotations

import copy
import math
import signal
from contextlib import contextmanager
from functools import cache

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import omni_gym  # noqa: F401  (registers the environments)
from omni_gym.cli import main as cli_main
from omni_gym.physics.liftoff import RATE_MAX, ContactProcess, contact_cases
from omni_gym.physics.model import load_model
from omni_gym.physics.replay import simulate_commands
from omni_gym.physics.world import World

HANG_SECONDS = 300  # a hang guard, not a timing test: each guarded case needs well under a second
FUZZ = settings(derandomize=True, max_examples=40, deadline=None,
                suppress_health_check=[HealthCheck.too_slow])

# Values that once failed: lift_rate 1e-30 hung reset, 1e-16 overflowed, 3.88e-78 came from fuzzing;
# recover_rate 1e-30 hung mid-episode.
REPORTED = [pytest.param({"lift_rate": 1e-30}, id="lift1e-30"),
            pytest.param({"lift_rate": 1e-16}, id="lift1e-16"),
            pytest.param({"lift_rate": 3.88e-78}, id="lift3.88e-78"),
            pytest.param({"lift_rate": 50.0, "recover_rate": 1e-30}, id="recover1e-30")]


class Hang(BaseException):
    """Raised by the guard; a BaseException so hypothesis does not catch it and re-run the case."""


@contextmanager
def hang_guard(seconds: int = HANG_SECONDS):
    """Fail the enclosed block if it has not finished after ``seconds`` (SIGALRM, main thread)."""
    def on_alarm(signum, frame):
        raise Hang(f"did not finish in {seconds} s: the contact process hangs")

    previous = signal.signal(signal.SIGALRM, on_alarm)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


# Rates log-uniform over [1e-300, RATE_MAX], plus 0, the subnormal/min-normal edges and the bound itself.
LOG_RATES = st.floats(min_value=-300.0, max_value=math.log10(RATE_MAX)).map(lambda e: min(10.0**e, RATE_MAX))
RATES = st.one_of(st.just(0.0), st.sampled_from([5e-324, 1e-320, 2.2250738585072014e-308, RATE_MAX]), LOG_RATES)
BAD_RATES = st.one_of(
    st.floats(max_value=-5e-324),  # negative, -inf included
    st.just(math.nan), st.just(math.inf),
    st.floats(min_value=math.nextafter(RATE_MAX, math.inf), allow_infinity=False),
)
SUBSTEPS = 60


@cache
def shared_world(dt: float) -> World:
    """One world per substep, reused by every example (its global tick keeps growing, as in an env)."""
    return World(load_model("phunopas2018"), dt=dt)


@FUZZ
@given(lift=RATES, recover=RATES, seed=st.integers(0, 2**32 - 1), dt=st.sampled_from([0.0005, 0.002]),
       command=st.floats(-20.0, 20.0))
def test_world_contact_process_terminates_for_any_allowed_rate(lift, recover, seed, dt, command):
    """World scheduling equals polling the process at every substep; masks valid; rate 0 honoured."""
    world = shared_world(dt)
    cases = {tuple(c) for c in contact_cases(4)}
    with hang_guard():
        world.set_contact_process(0, ContactProcess(4, lift, recover, np.random.default_rng(seed)))
        world.reset()
        world.set_commands(np.array([command, -command, 0.5 * command, 2.0]))
        # Same state and generator as the world's process: polled at every local time k·dt it must give
        # the mask the world applies at substep k (the world only visits the substeps it scheduled).
        polled = copy.deepcopy(world.contact_processes[0])
        masks = []
        for k in range(SUBSTEPS):
            world.substeps(1)
            polled.advance(k * dt)
            assert world.contact[0].dtype == bool
            np.testing.assert_array_equal(world.contact[0], polled.mask)
            masks.append(tuple(world.contact[0]))
        pose = world.pose[0]
    assert set(masks) <= cases
    assert np.all(np.isfinite(pose)) and np.all(np.isfinite(world.velocity[0]))
    if lift == 0.0:
        assert all(all(m) for m in masks)  # never lifts
    if recover == 0.0:
        lifted = [not all(m) for m in masks]
        first = lifted.index(True) if any(lifted) else len(masks)
        assert all(lifted[first:])  # once up, a wheel with recover_rate 0 stays up


@FUZZ
@given(lift=RATES, recover=RATES, seed=st.integers(0, 2**32 - 1),
       times=st.lists(st.floats(0.0, 1.0), min_size=1, max_size=20).map(sorted))
def test_process_next_switch_is_later_or_never(lift, recover, seed, times):
    """After advance(t) the next switch lies after t (or is +inf): never NaN, never in the past.

    Times span 1 s: advance draws every switch in between, about rate·Δt <= 1000 of them.
    """
    proc = ContactProcess(4, lift, recover, np.random.default_rng(seed))
    with hang_guard():
        for t in times:
            proc.advance(t)
            assert proc.next_switch > t
            assert 0 <= proc.case < len(proc.cases)
            if lift == 0.0:
                assert proc.case == 0 and proc.next_switch == math.inf


@settings(derandomize=True, max_examples=60, deadline=None)
@given(name=st.sampled_from(["lift_rate", "recover_rate"]), bad=BAD_RATES)
def test_out_of_range_rates_are_refused_naming_the_parameter(name, bad):
    rates = {"lift_rate": 1.0, "recover_rate": 1.0, name: bad}
    with pytest.raises(ValueError, match=name) as err:
        ContactProcess(4, rates["lift_rate"], rates["recover_rate"], np.random.default_rng(0))
    assert "\n" not in str(err.value)


@pytest.mark.parametrize("bad", [True, "1.0", None, [1.0], 10**400])
def test_non_numeric_rates_are_refused(bad):
    with pytest.raises(ValueError, match="recover_rate"):
        ContactProcess(4, 1.0, bad, np.random.default_rng(0))


def test_numpy_scalar_rates_are_accepted():
    proc = ContactProcess(4, np.float32(0.5), np.int64(5), np.random.default_rng(0))
    assert (proc.lift_rate, proc.recover_rate) == (0.5, 5.0)
    assert type(proc.lift_rate) is float


# --- the reported values, through every entry point -------------------------------------------------


@pytest.mark.parametrize("rates", REPORTED)
def test_reported_rates_through_the_environment_keyword(rates):
    """The keyword either runs 200 steps or is refused with the usual one-line ValueError naming it.

    (The environments bound their rates more tightly than the contact process; either answer is fine,
    a hang, an OverflowError or a traceback from inside the world is not.)
    """
    with hang_guard():
        try:
            env = gym.make("OmniPathFollow-Phunopas-v0", **rates)
        except ValueError as err:
            assert any(key in str(err) for key in rates) and "\n" not in str(err)
            return
        env.reset(seed=3)
        env.action_space.seed(3)
        for _ in range(200):
            obs, reward, terminated, truncated, _ = env.step(env.action_space.sample())
            assert np.all(np.isfinite(obs)) and math.isfinite(reward)
            if terminated or truncated:
                env.reset()
    env.close()


@pytest.mark.parametrize("rates", REPORTED)
def test_reported_rates_inside_an_environment_episode(rates):
    """The reported rates driving the environment's own world: reset, then 200 steps mid-episode."""
    params = {"lift_rate": 0.5, "recover_rate": 5.0, **rates}
    env = gym.make("OmniPathFollow-Phunopas-v0", lift_rate=0.0, lost_distance=100.0)
    env.action_space.seed(3)
    world = env.unwrapped.core.world
    with hang_guard():
        env.reset(seed=3)
        world.set_contact_process(0, ContactProcess(4, params["lift_rate"], params["recover_rate"],
                                                    np.random.default_rng(3)))  # starts now, mid-episode
        lifted = []
        for _ in range(200):
            obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
            assert np.all(np.isfinite(obs)) and math.isfinite(reward)
            assert not (terminated or truncated)  # lost_distance 100 m: one episode throughout
            lifted.append(not info["contact"].all())
    env.close()
    if params["lift_rate"] < 1e-10:
        # P(any lift in these 2 s) <= 2e-10: a lift would mean the rate is not the one set.
        assert not any(lifted)
    else:
        # lift_rate 50 /s lifts within 0.1 s with probability 1 - e^-5; with recovery 1e-30 /s the
        # wheel then stays up to the end (P(recovery in 2 s) ~ 2e-30).
        assert any(lifted) and all(lifted[lifted.index(True):])


@pytest.mark.parametrize("rates", REPORTED)
def test_reported_rates_through_simulate_commands(rates):
    params = {"lift_rate": 0.5, "recover_rate": 5.0, **rates}
    model = load_model("phunopas2018").with_effect("wheel_liftoff", params)
    times = np.linspace(0.0, 1.0, 11)
    commands = np.tile([3.0, -2.0, 1.0, 4.0], (11, 1))
    with hang_guard():
        states = simulate_commands(model, times, commands, seed=5)
    assert states.shape == (11, 6) and np.all(np.isfinite(states))
    assert np.hypot(states[-1, 0], states[-1, 1]) > 0.01  # it moved (commands of a few rad/s for 1 s)


@pytest.mark.parametrize("rates", REPORTED)
def test_reported_rates_through_synth_cli(rates, tmp_path, capsys):
    import json

    params = {"lift_rate": 0.5, "recover_rate": 5.0, **rates}
    out = tmp_path / "data"
    with hang_guard():
        code = cli_main(["synth", "--model", "phunopas2018", "--hidden", f"wheel_liftoff:{json.dumps(params)}",
                         "--runs", "1", "--duration", "0.5", "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    assert out.is_dir() and any(out.iterdir())


def test_synth_refuses_a_rate_above_the_bound(tmp_path, capsys):
    code = cli_main(["synth", "--model", "phunopas2018", "--hidden",
                     'wheel_liftoff:{"lift_rate": 1e5, "recover_rate": 5}', "--runs", "1", "--duration", "0.5",
                     "--out", str(tmp_path / "data")])
    err = capsys.readouterr().err
    assert code == 2 and "lift_rate" in err and err.count("\n") == 1 and "Traceback" not in err


def test_scheduled_lift_event_beyond_the_horizon_never_fires():
    """The discrepancy workflow's replayed events go through the same scheduling: an event at 1e300 s
    (a run ending at t = 1e308) must neither hang nor fire."""
    from omni_gym.physics.liftoff import ScheduledContactProcess

    world = World(load_model("phunopas2018"))
    with hang_guard():
        world.set_contact_process(0, ScheduledContactProcess(4, [(0.01, 0.02, 1), (1e300, 2e300, 2)]))
        world.reset()
        masks = []
        for _ in range(100):  # 50 ms
            world.substeps(1)
            masks.append(world.contact[0].all())
    # Down, up from 10 ms to 20 ms (substeps 20..39 at 0.5 ms), down again, then nothing.
    assert masks[:20] == [True] * 20 and not any(masks[20:40]) and all(masks[40:])
