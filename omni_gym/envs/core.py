"""The batched engine behind both the single and the vectorised environments.

``TaskCore`` holds B robots in one :class:`~omni_gym.physics.world.World` and does, for all of them at once:
action → wheel commands, one control period of physics, observations, rewards and flags. A single
environment is a core with B = 1, so the vectorised environment reproduces N single environments
exactly: every per-robot quantity is computed by the same code on the same numbers, every random
draw of robot j comes from robot j's own generator, and each robot keeps its own clock.

Observation layouts (``state``, ``sensors``): owned by :mod:`omni_gym.envs.observations`, which the
numba kernels below take their offsets from. In ``sensors`` mode one :class:`~omni_gym.sensor_bank.SensorBank`
measures every robot in one compiled call and :func:`encode_sensor_obs` writes every observation.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numba
import numpy as np

from omni_gym.angles import wrap_angle_nb as _wrap  # (−π, π], compiled for the njit kernels below
from omni_gym.envs.config import (
    EnvConfig,
    draw_floor,
    draw_model_factors,
    randomized_model,
    sensor_noise_scale,
)
from omni_gym.envs.observations import (  # noqa: F401  (LOOKAHEAD_SECONDS, ACC_SCALE: re-exported)
    ACC_SCALE,
    LOOK_SCALE,
    LOOKAHEAD_SECONDS,
    OBS_CLIP,
    POS_SCALE,
    ObsScales,
    build_layout,
    sensor_offsets,
    state_offsets,
)
from omni_gym.envs.references import draw_task_reference
from omni_gym.envs.reward import RewardInputs, check_reward, evaluate, tracking_reward
from omni_gym.physics.kinematics import WheelKinematics, effective_kinematics
from omni_gym.physics.layout import SP_CX, SP_CY, WH_CMD
from omni_gym.physics.liftoff import ContactProcess, contact_cases
from omni_gym.physics.model import Actuation, SimModel
from omni_gym.physics.plant import Plant, PlantState, SimulatorPlant, check_plant_state
from omni_gym.physics.traction import TractionLimiter
from omni_gym.physics.world import Arena, World
from omni_gym.sensor_bank import SensorBank


@numba.njit(cache=True)
def apply_actions(raw, twist_mode, scale, W, wheels, out_clipped):
    """Clip actions to [−1, 1] and write wheel commands [rad/s] into ``wheels``; False if any is NaN/inf.

    raw, out_clipped (B, A); scale: (max_speed, max_speed, max_yaw_rate) in twist mode, else
    (wheel_scale,); W (n, 3) the wheel matrix; wheels (B, n, 5), commands at WH_CMD. Nothing is
    written unless every action is finite.
    """
    n_robots, n_act = raw.shape
    for b in range(n_robots):
        for j in range(n_act):
            if not math.isfinite(raw[b, j]):
                return False
    for b in range(n_robots):
        for j in range(n_act):
            out_clipped[b, j] = min(1.0, max(-1.0, raw[b, j]))
        for i in range(W.shape[0]):
            if twist_mode:
                cmd = 0.0
                for j in range(3):
                    cmd += W[i, j] * out_clipped[b, j] * scale[j]
            else:
                cmd = out_clipped[b, i] * scale[0]
            wheels[b, i, WH_CMD] = cmd
    return True


@numba.njit(cache=True, inline="always")
def _observe_robot(b, state, origins, sp, ref_pose, ref_vel, step, look, prev_action, scales, offsets, out_obs,
                   out_err, out_true, out_reward):
    """Robot b's part of :func:`observe_state` (shared by the serial and the threaded loop)."""
    n_act = prev_action.shape[1]
    vmax = scales[0]
    wmax = scales[1]
    err, vel, rvel, look0, stride, act = offsets[0], offsets[1], offsets[2], offsets[3], offsets[4], offsets[5]
    x = state[b, 0] - origins[b, 0]
    y = state[b, 1] - origins[b, 1]
    th = state[b, 2]
    c = math.cos(th)
    s = math.sin(th)
    om = state[b, 5]
    # Geometric-centre velocity: v_com − ω z × (R com).
    rcx = c * sp[b, SP_CX] - s * sp[b, SP_CY]
    rcy = s * sp[b, SP_CX] + c * sp[b, SP_CY]
    vx = state[b, 3] + om * rcy
    vy = state[b, 4] - om * rcx
    out_true[b, 0] = x
    out_true[b, 1] = y
    out_true[b, 2] = th
    out_true[b, 3] = vx
    out_true[b, 4] = vy
    out_true[b, 5] = om
    k = step[b]
    dx = ref_pose[b, k, 0] - x
    dy = ref_pose[b, k, 1] - y
    dth = _wrap(ref_pose[b, k, 2] - th)
    out_err[b, 0] = math.sqrt(dx * dx + dy * dy)
    out_err[b, 1] = dth
    o = out_obs[b]
    o[err] = (c * dx + s * dy) / POS_SCALE  # tracking_error_body, then heading_error
    o[err + 1] = (-s * dx + c * dy) / POS_SCALE
    o[err + 2] = dth / math.pi
    o[vel] = (c * vx + s * vy) / vmax
    o[vel + 1] = (-s * vx + c * vy) / vmax
    o[vel + 2] = om / wmax
    rvx = ref_vel[b, k, 0]
    rvy = ref_vel[b, k, 1]
    o[rvel] = (c * rvx + s * rvy) / vmax
    o[rvel + 1] = (-s * rvx + c * rvy) / vmax
    o[rvel + 2] = ref_vel[b, k, 2] / wmax
    for j in range(look.shape[0]):
        kk = k + look[j]
        lx = ref_pose[b, kk, 0] - x
        ly = ref_pose[b, kk, 1] - y
        q = look0 + stride * j
        o[q] = (c * lx + s * ly) / LOOK_SCALE
        o[q + 1] = (-s * lx + c * ly) / LOOK_SCALE
        o[q + 2] = _wrap(ref_pose[b, kk, 2] - th) / math.pi
    effort = 0.0
    for j in range(n_act):
        o[act + j] = prev_action[b, j]
        effort += prev_action[b, j] * prev_action[b, j]
    out_reward[b] = tracking_reward(out_err[b, 0], dth, effort, n_act)  # the built-in; see observe()
    for j in range(o.shape[0]):
        if o[j] > OBS_CLIP:
            o[j] = OBS_CLIP
        elif o[j] < -OBS_CLIP:
            o[j] = -OBS_CLIP


@numba.njit(cache=True)
def observe_state(state, origins, sp, ref_pose, ref_vel, step, look, prev_action, scales, offsets, out_obs,
                  out_err, out_true, out_reward):
    """State observations, tracking errors, true poses/velocities and rewards for all robots.

    state (B, 6): pymunk body x, y (world), θ, COM velocity V_x, V_y, ω. scales: max_speed, max_yaw_rate.
    offsets: where each field starts (``omni_gym.envs.observations.state_offsets``).
    out_err (B, 2): position error [m], heading error [rad]. out_true (B, 6): local pose and the
    geometric centre's world velocity. out_reward (B,): reward of the last action (``prev_action``).
    """
    for b in range(state.shape[0]):
        _observe_robot(b, state, origins, sp, ref_pose, ref_vel, step, look, prev_action, scales, offsets,
                       out_obs, out_err, out_true, out_reward)


@numba.njit(cache=True, parallel=True)
def observe_state_parallel(state, origins, sp, ref_pose, ref_vel, step, look, prev_action, scales, offsets,
                           out_obs, out_err, out_true, out_reward):
    """:func:`observe_state` with the robots shared among threads (each writes only its own rows, so
    results are bit-identical); used where the world's kernel is threaded."""
    for b in numba.prange(state.shape[0]):
        _observe_robot(b, state, origins, sp, ref_pose, ref_vel, step, look, prev_action, scales, offsets,
                       out_obs, out_err, out_true, out_reward)


@numba.njit(cache=True)
def all_finite(obs, reward):
    """True if every observation (B, D) and reward (B,) is a real number (one pass, no temporaries)."""
    for v in obs.ravel():
        if not math.isfinite(v):
            return False
    for v in reward:
        if not math.isfinite(v):
            return False
    return True


@numba.njit(cache=True)
def body_acceleration(robots, true, prev_true, step, dt, out):
    """Body-frame acceleration [m/s²] of the geometric centres of ``robots`` (indices) over the last
    control period, into out (B, 2).

    true, prev_true (B, 6): local pose and world velocity now and one period ago (``TaskCore.true``);
    zero for a robot at its first sample after a reset (step 0).
    """
    for b in robots:
        if step[b] == 0:
            out[b, 0] = 0.0
            out[b, 1] = 0.0
            continue
        ax = (true[b, 3] - prev_true[b, 3]) / dt
        ay = (true[b, 4] - prev_true[b, 4]) / dt
        c = math.cos(true[b, 2])
        s = math.sin(true[b, 2])
        out[b, 0] = c * ax + s * ay
        out[b, 1] = -s * ax + c * ay


@numba.njit(cache=True)
def encode_sensor_obs(robots, enc, gyro, compass, accel, fix, has_fix, step, dt, prev_enc, last_fix, fix_age,
                      ref_pose, ref_vel, look, prev_action, scales, offsets, out_obs):
    """Sensors observations of ``robots`` (indices) from the bank's readings (the arithmetic of ``encode_sensors``).

    enc (B, n) quantised wheel angles [rad]; gyro, compass (B,); accel (B, 2); fix (B, 3), valid where
    has_fix. Updated per robot: prev_enc (the previous encoder angles), last_fix and fix_age (the held
    camera fix and its age [s], capped at 1 s; the age does not grow at step 0). scales: wheel_scale,
    max_yaw_rate, max_speed, arena_half_size, ACC_SCALE. offsets: ``sensor_offsets`` of the layout.
    """
    wscale, wmax, vmax, h, acc_scale = scales[0], scales[1], scales[2], scales[3], scales[4]
    o_enc, o_gyro, o_comp, o_acc, o_fix, o_age = offsets[0], offsets[1], offsets[2], offsets[3], offsets[4], offsets[5]
    o_now, o_vel, o_look, stride, o_act = offsets[6], offsets[7], offsets[8], offsets[9], offsets[10]
    for b in robots:
        o = out_obs[b]
        for i in range(enc.shape[1]):
            o[o_enc + i] = ((enc[b, i] - prev_enc[b, i]) / dt) / wscale
            prev_enc[b, i] = enc[b, i]
        if has_fix[b]:
            last_fix[b, 0] = fix[b, 0]
            last_fix[b, 1] = fix[b, 1]
            last_fix[b, 2] = fix[b, 2]
            fix_age[b] = 0.0
        elif step[b] > 0:
            fix_age[b] = min(fix_age[b] + dt, 1.0)
        o[o_gyro] = gyro[b] / wmax
        o[o_comp] = math.sin(compass[b])
        o[o_comp + 1] = math.cos(compass[b])
        o[o_acc] = accel[b, 0] / acc_scale
        o[o_acc + 1] = accel[b, 1] / acc_scale
        _put_pose(o, o_fix, last_fix[b, 0], last_fix[b, 1], last_fix[b, 2], h)
        o[o_age] = fix_age[b]
        k = step[b]
        _put_pose(o, o_now, ref_pose[b, k, 0], ref_pose[b, k, 1], ref_pose[b, k, 2], h)
        o[o_vel] = ref_vel[b, k, 0] / vmax
        o[o_vel + 1] = ref_vel[b, k, 1] / vmax
        o[o_vel + 2] = ref_vel[b, k, 2] / wmax
        for j in range(look.shape[0]):
            kk = k + look[j]
            _put_pose(o, o_look + stride * j, ref_pose[b, kk, 0], ref_pose[b, kk, 1], ref_pose[b, kk, 2], h)
        for j in range(prev_action.shape[1]):
            o[o_act + j] = prev_action[b, j]
        for j in range(o.shape[0]):
            if o[j] > OBS_CLIP:
                o[j] = OBS_CLIP
            elif o[j] < -OBS_CLIP:
                o[j] = -OBS_CLIP


@numba.njit(cache=True, inline="always")
def _put_pose(o, i, x, y, theta, h):
    """o[i:i + 4] = x/h, y/h, sin θ, cos θ (``observations._put_pose_sin_cos``)."""
    o[i] = x / h
    o[i + 1] = y / h
    o[i + 2] = math.sin(theta)
    o[i + 3] = math.cos(theta)


def _brief(value) -> str:
    """repr on one line (numpy wraps long arrays), cut to 80 characters."""
    text = " ".join(repr(value).split())
    return text if len(text) <= 80 else text[:77] + "..."


def traction_limiter(model: SimModel) -> TractionLimiter | None:
    """The friction set references are fitted to and measured against: the model's robot, floor and centre of
    mass, "moving" mode (the rollers turn: the drive boxes around the rolling resistance), all wheels down;
    None where the wheels cannot transmit every planar wrench (no set to measure in)."""
    try:
        return TractionLimiter(model.robot, model.surface, mode="moving", com=model.com, gravity=model.gravity)
    except ValueError:
        return None


def put_reading(bank: SensorBank, reading) -> None:
    """Write a real robot's :class:`~omni_gym.physics.plant.SensorReading` into robot 0's row of ``bank``."""
    angles = np.asarray(reading.wheel_angles, dtype=float)
    accel = np.asarray(reading.accel, dtype=float)
    if angles.shape != bank.wheel_angles.shape[1:] or accel.shape != (2,):
        raise ValueError(f"plant reading: wheel_angles must have shape {bank.wheel_angles.shape[1:]} and accel (2,), "
                         f"got {angles.shape} and {accel.shape}")
    values = [angles, accel, [reading.gyro, reading.compass]]
    if reading.fix is not None:
        values.append(np.asarray(reading.fix, dtype=float).reshape(3))
    if not all(np.all(np.isfinite(v)) for v in values):
        raise ValueError("plant reading: a sensor value is NaN or infinite")
    bank.wheel_angles[0] = angles
    bank.gyro[0] = float(reading.gyro)
    bank.compass[0] = float(reading.compass)
    bank.accel[0] = accel
    bank.has_fix[0] = reading.fix is not None
    if reading.fix is not None:
        bank.fix[0] = np.asarray(reading.fix, dtype=float).reshape(3)


def as_actions(actions, shape: tuple[int, ...]) -> np.ndarray:
    """``actions`` as a float64 array of exactly ``shape``; ValueError for other shapes or non-real values.

    Complex, boolean, string and object values are refused rather than converted (a complex action
    would lose its imaginary part); so is a batch-shaped action given to a single environment.
    """
    try:
        arr = np.asarray(actions)
    except (TypeError, ValueError):
        raise ValueError(f"action must be an array of real numbers of shape {shape}, got {_brief(actions)}") from None
    if arr.dtype.kind not in "fiu":
        raise ValueError(f"action must hold real numbers (int or float), got dtype {arr.dtype}: {_brief(actions)}")
    if arr.shape != shape:
        raise ValueError(f"action must have shape {shape}, got shape {arr.shape}")
    return arr.astype(np.float64)


class TaskCore:
    """B robots following their references; see the module docstring."""

    def __init__(self, cfg: EnvConfig, n_robots: int) -> None:
        self.cfg = cfg
        self.B = n_robots
        self.base_model = cfg.base_model()
        self.robot = self.base_model.robot
        self.n_wheels = self.robot.n_wheels
        self.world = World(self.base_model, n_robots=n_robots, dt=cfg.physics_dt,
                           actuation=Actuation(kind=cfg.actuation),
                           arena=Arena(cfg.arena_half_size, cfg.walls, cfg.obstacles))
        # The twist → wheel-speed map of twist actions and of controllers (``kinematics``); the wheel
        # scale stays the nominal robot's, so the action and observation scales do not change with it.
        self.kinematics = (effective_kinematics(self.base_model) if cfg.kinematics == "model"
                           else WheelKinematics.of_robot(self.robot))
        self.W = self.kinematics.matrix
        self.twist_scale = np.array([cfg.max_speed, cfg.max_speed, cfg.max_yaw_rate])
        corners = np.array([[sx, sy, sw] for sx in (-1, 1) for sy in (-1, 1) for sw in (-1, 1)]) * self.twist_scale
        self.wheel_scale = float(np.abs(corners @ self.robot.wheel_matrix().T).max())  # rad/s at wheel action ±1
        self.action_dim = 3 if cfg.action_mode == "twist" else self.n_wheels
        self.look = np.array([int(round(s * cfg.control_hz)) for s in LOOKAHEAD_SECONDS], dtype=np.int64)
        self.n_samples = cfg.episode_steps + int(self.look.max()) + 1
        self.ref_pose = np.zeros((n_robots, self.n_samples, 3))
        self.ref_vel = np.zeros((n_robots, self.n_samples, 3))
        self.step_count = np.zeros(n_robots, dtype=np.int64)
        self.prev_action = np.zeros((n_robots, self.action_dim))
        self.scales = np.array([cfg.max_speed, cfg.max_yaw_rate])
        self.err = np.zeros((n_robots, 2))
        self.reward = np.zeros(n_robots)
        self._custom_reward = check_reward(cfg.reward)  # None: the kernel's built-in (omni_gym.envs.reward)
        self._twist_mode = cfg.action_mode == "twist"
        self._action_scale = self.twist_scale if self._twist_mode else np.array([self.wheel_scale])
        self._clipped = np.zeros((n_robots, self.action_dim))
        self.true = np.zeros((n_robots, 6))
        self.prev_true = np.zeros((n_robots, 6))
        self.sensors = SensorBank(n_robots, self.n_wheels)
        self.sensor_config = cfg.sensor_config()
        self.sensor_noise_scale = np.ones(n_robots)  # per robot, drawn at reset (randomize_sensor_noise)
        self.prev_encoders = np.zeros((n_robots, self.n_wheels))
        self.last_fix = np.zeros((n_robots, 3))
        self.fix_age = np.ones(n_robots)
        self._acc_body = np.zeros((n_robots, 2))
        self._all = np.arange(n_robots)
        state = build_layout("state", self.n_wheels, self.action_dim)  # computed in both modes (errors, reward)
        self.state_dim = state.size
        self._state_offsets = state_offsets(state)
        self.layout = build_layout(cfg.obs_mode, self.n_wheels, self.action_dim)
        self.obs_scales = ObsScales(self.wheel_scale, cfg.max_speed, cfg.max_yaw_rate, cfg.arena_half_size)
        self.obs_dim = self.layout.size
        if cfg.obs_mode == "sensors":
            self._sensor_offsets = sensor_offsets(self.layout)
            self._sensor_scales = np.array([self.wheel_scale, cfg.max_yaw_rate, cfg.max_speed, cfg.arena_half_size,
                                            ACC_SCALE])
        self._state_obs = np.zeros((n_robots, self.state_dim))
        # In state mode the observation is the state rows themselves (no copy per step).
        self.obs = self._state_obs if cfg.obs_mode == "state" else np.zeros((n_robots, self.obs_dim))
        self._sensors_mode = cfg.obs_mode == "sensors"
        self._observe_state = observe_state_parallel if self.world.parallel else observe_state
        self.models = [self.base_model] * n_robots
        self._contact_cases = contact_cases(self.n_wheels)  # shared by every robot's contact process: read-only
        self._contact_cases.setflags(write=False)
        self.limiter = traction_limiter(self.base_model)
        self.ref_stretch = np.ones(n_robots)  # how much slower than drawn each reference runs (ref_traction)
        self.ref_use = np.full(n_robots, np.nan)  # the share of the friction set it asks for (NaN: no limiter)
        self.plant: Plant | None = None  # attach_plant: a plant in place of the world (one robot)
        self._plant_state: PlantState | None = None

    # --- a plant in place of the world -------------------------------------------------------

    def attach_plant(self, plant: Plant | None) -> None:
        """Drive ``plant`` (:mod:`omni_gym.physics.plant`) instead of this core's own world (None: the world
        again). Everything else stays: the reference, the observation, the reward and the scoring. Takes
        effect from the next reset; one robot only."""
        if plant is not None:
            if self.B != 1:
                raise ValueError(f"a plant drives one robot; this core has {self.B}")
            if not isinstance(plant, Plant):
                raise ValueError(f"plant must have n_wheels, reset(pose, seed) and step(wheel_speeds, duration), "
                                 f"got {type(plant).__name__}")
            if int(plant.n_wheels) != self.n_wheels:
                raise ValueError(f"the plant has {plant.n_wheels} wheels, the environment's robot "
                                 f"{self.n_wheels}")
            self._plant_body = np.zeros((1, 6))  # the plant's motion as a body row with the com at the centre
            self._plant_origins = np.zeros((1, 2))
            self._plant_sp = self.world.sp.copy()
            self._plant_sp[:, SP_CX] = 0.0
            self._plant_sp[:, SP_CY] = 0.0
            self._plant_angles = np.zeros((1, self.n_wheels))
        self.plant = plant
        self._plant_state = None

    def simulator_plant(self, model: SimModel | None = None) -> SimulatorPlant:
        """A :class:`~omni_gym.physics.plant.SimulatorPlant` with this environment's substep, actuation and arena:
        of its own model and lift-off rates (None: the environment's own world, no domain randomisation), or of
        ``model`` (its ``wheel_liftoff`` effect, if any, sets the rates)."""
        cfg = self.cfg
        rates = cfg.contact_rates() if model is None else None
        return SimulatorPlant(self.base_model if model is None else model, cfg.physics_dt,
                              Actuation(kind=cfg.actuation), Arena(cfg.arena_half_size, cfg.walls, cfg.obstacles),
                              lift_rates=rates)

    def _take_plant_state(self, state: object, where: str) -> None:
        st = check_plant_state(state, self.n_wheels, where)
        self._plant_state = st
        self._plant_body[0, 0:3] = st.pose
        self._plant_body[0, 3:6] = st.velocity
        self._plant_angles[0] = st.wheel_angles

    # --- reset -------------------------------------------------------------------------------

    def reset_robot(self, j: int, rng: np.random.Generator) -> None:
        """New episode for robot j; every draw (model, path, contacts, sensors) comes from ``rng``."""
        cfg = self.cfg
        draws = draw_model_factors(cfg, rng)
        ref = draw_task_reference(cfg, rng, self.n_samples, self.limiter)
        pose = ref.pose
        self.ref_pose[j] = pose
        self.ref_vel[j] = ref.velocity
        self.ref_stretch[j] = ref.stretch
        self.ref_use[j] = np.nan if ref.use is None else ref.use.peak
        contact_seed, sensor_seed = rng.integers(0, 2**63 - 1, size=2)
        self.sensor_noise_scale[j] = sensor_noise_scale(cfg, rng)  # draws only if randomize_sensor_noise is set
        # The floor is the last draw (only if randomize_floor is set): every other draw of a seed stays as
        # it is, so a draw of floor F gives the episode of surface=F with the same seed.
        draws = replace(draws, floor=draw_floor(cfg, rng))
        model = randomized_model(self.base_model, draws)
        if model is not self.models[j]:
            self.world.set_model(j, model)
            self.models[j] = model
        lift_rate = draws.lift_rate
        if lift_rate > 0:
            recover_rate = cfg.contact_rates()[1]  # the model's wheel_liftoff effect, if any, else the keyword
            proc = ContactProcess(self.n_wheels, lift_rate, recover_rate, np.random.default_rng(contact_seed),
                                  cases=self._contact_cases)
            self.world.set_contact_process(j, proc)
        elif self.world.contact_processes[j] is not None:
            self.world.set_contact_process(j, None)
        self.world.reset(poses=pose[0:1], robots=[j])
        if self.plant is not None:  # the plant's own hidden randomness is seeded as the world's contacts are
            self._take_plant_state(self.plant.reset(pose[0].copy(), int(contact_seed)), "plant.reset")
        self.step_count[j] = 0
        self.prev_action[j] = 0.0
        if cfg.obs_mode == "sensors":
            bank = self.sensors
            bank.reset(j, np.random.default_rng(sensor_seed), self.sensor_config, self.sensor_noise_scale[j])
            angles = self.world.wheel_angle if self.plant is None else self._plant_angles
            self.prev_encoders[j] = np.floor(angles[j] / bank.quantum[j]) * bank.quantum[j]
            self.last_fix[j] = 0.0
            self.fix_age[j] = 1.0

    # --- stepping ----------------------------------------------------------------------------

    def advance(self, actions: np.ndarray) -> None:
        """Clip ``actions`` (B, action_dim) to [−1, 1] and run one control period for all robots.

        An action with NaN or infinity raises ValueError before anything changes.
        """
        raw = np.asarray(actions, dtype=np.float64)
        if raw.size != self._clipped.size:
            raise ValueError(f"action must have {self.action_dim} values per robot, got shape {raw.shape}")
        if not apply_actions(raw.reshape(self._clipped.shape), self._twist_mode, self._action_scale, self.W,
                             self.world.wheels, self._clipped):
            raise ValueError(f"action contains NaN or infinity: {_brief(raw.tolist())}")
        if self._sensors_mode:
            self.prev_true[:] = self.true  # for the accelerometer (body_acceleration)
        if self.plant is not None:
            if self._plant_state is None:
                raise RuntimeError("a plant was attached after the last reset: reset before stepping")
            commands = self.world.wheels[0, :, WH_CMD].copy()
            self._take_plant_state(self.plant.step(commands, self.cfg.control_dt), "plant.step")
        else:
            self.world.substeps(self.cfg.substeps)
        self.step_count += 1
        self.prev_action[:] = self._clipped

    def observe(self, robots: np.ndarray | None = None) -> None:
        """Fill ``obs``, ``err`` and ``true`` for every robot from the current world state.

        Call exactly once per robot per reset or step: sensor readings draw noise. ``robots`` (indices)
        limits the sensor readings to those robots (a same-step autoreset observes only the robots it
        just reset); ``err``, ``true``, the reward and the ``state`` rows are recomputed for all, which
        is deterministic and leaves the other robots' values unchanged.
        """
        world = self.world
        if self.plant is None:
            body, origins, sp = world.body_states(), world.origins, world.sp
        else:  # the plant reports the geometric centre's motion: a body row with the com at the centre
            body, origins, sp = self._plant_body, self._plant_origins, self._plant_sp
        self._observe_state(body, origins, sp, self.ref_pose, self.ref_vel, self.step_count, self.look,
                            self.prev_action, self.scales, self._state_offsets, self._state_obs, self.err, self.true,
                            self.reward)
        if self._custom_reward is not None:  # the kernel's built-in reward replaced by the user's
            evaluate(self._custom_reward, self._reward_inputs(), self.reward)
        if self._sensors_mode:
            self._observe_sensors(self._all if robots is None else np.asarray(robots, dtype=np.int64))
        if not all_finite(self.obs, self.reward):
            # Never hand NaN to a learner: within the keyword and model bounds this should not happen.
            bad = np.flatnonzero(~(np.isfinite(self.obs).all(axis=1) & np.isfinite(self.reward)))
            raise FloatingPointError(f"the simulation diverged (non-finite observation or reward) for robot(s) "
                                     f"{bad.tolist()}; please report the keywords and model that caused it")

    def _reward_inputs(self) -> RewardInputs:
        """What a user's reward sees (``omni_gym.envs.reward.RewardInputs``), after the state kernel ran."""
        rows = np.arange(len(self.step_count))
        return RewardInputs(position_error=self.err[:, 0], heading_error=self.err[:, 1], action=self.prev_action,
                            pose=self.true[:, 0:3], velocity=self.true[:, 3:6],
                            reference_pose=self.ref_pose[rows, self.step_count],
                            reference_velocity=self.ref_vel[rows, self.step_count], step=self.step_count,
                            control_dt=self.cfg.control_dt)

    def _observe_sensors(self, robots: np.ndarray) -> None:
        """Sample the sensors of ``robots`` (indices; one draw block each, see ``omni_gym.sensor_bank``) and
        encode their observations, in one compiled call each."""
        dt = self.cfg.control_dt
        true = self.true
        body_acceleration(robots, true, self.prev_true, self.step_count, dt, self._acc_body)
        bank = self.sensors
        reading = None if self._plant_state is None else self._plant_state.reading
        if reading is not None:  # a real robot's own sensors replace the sensor models
            put_reading(bank, reading)
        else:
            angles = self.world.wheel_angle if self.plant is None else self._plant_angles
            bank.measure(self.step_count * dt, dt, angles, true[:, 0:3], true[:, 5], self._acc_body, robots)
        encode_sensor_obs(robots, bank.wheel_angles, bank.gyro, bank.compass, bank.accel, bank.fix, bank.has_fix,
                          self.step_count, dt, self.prev_encoders, self.last_fix, self.fix_age, self.ref_pose,
                          self.ref_vel, self.look, self.prev_action, self._sensor_scales, self._sensor_offsets,
                          self.obs)

    def rewards(self) -> np.ndarray:
        """Per-robot reward for the last control period (see the module constants), after :meth:`observe`."""
        return self.reward.copy()

    def contact(self, j: int) -> np.ndarray:
        """Robot j's wheels on the floor (the plant's, when one is attached and reports them)."""
        st = self._plant_state
        if self.plant is not None and st is not None and st.contact is not None:
            return np.asarray(st.contact, dtype=bool).copy()
        return self.world.contact[j].copy()

    def terminated(self) -> np.ndarray:
        return (self.err[:, 0] > self.cfg.lost_distance) | self.world.collided

    def truncated(self) -> np.ndarray:
        return self.step_count >= self.cfg.episode_steps

    def floor(self, j: int) -> str:
        """Robot j's floor this episode, ``"surface:friction_model"`` (``info["floor"]`` with ``randomize_floor``)."""
        model = self.models[j]
        return f"{model.surface.name}:{model.friction}"

    def infos(self, robots: int | slice = slice(None)) -> dict[str, np.ndarray]:
        """Ground truth (never part of the observation) for ``robots``: arrays over robots for a slice."""
        err = self.err[robots]
        cfg = self.cfg
        out = {
            "pose": self.true[robots, 0:3].copy(),
            "velocity": self.true[robots, 3:6].copy(),
            "reference_pose": self.ref_pose[np.arange(self.B)[robots], self.step_count[robots]].copy(),
            "tracking_error": err[..., 0].copy(),
            "heading_error": err[..., 1].copy(),
            "slip": self.world.slip[robots].copy(),
            "contact": self.world.contact[robots].copy(),
            "collided": self.world.collided[robots].copy(),
            "is_success": (err[..., 0] <= cfg.success_distance) & (np.abs(err[..., 1]) <= cfg.success_heading),
            "reference_traction": self.ref_use[robots].copy(),
        }
        if cfg.randomize_floor is not None:
            out["floor"] = np.array([self.floor(j) for j in range(self.B)], dtype=object)[robots]
        return out

    def info(self, j: int) -> dict:
        """:meth:`infos` of robot j, with plain Python scalars (built directly: a single environment
        returns one per step, and the generic path cost a third of its step)."""
        e = float(self.err[j, 0])
        e_theta = float(self.err[j, 1])
        true = self.true[j].copy()
        world = self.world
        info = {
            "pose": true[0:3],
            "velocity": true[3:6],
            "reference_pose": self.ref_pose[j, self.step_count[j]].copy(),
            "tracking_error": e,
            "heading_error": e_theta,
            "slip": world.slip[j].copy(),
            "contact": self.contact(j),
            "collided": bool(world.collided[j]),
            "is_success": e <= self.cfg.success_distance and abs(e_theta) <= self.cfg.success_heading,
            "reference_traction": float(self.ref_use[j]),
        }
        if self.cfg.randomize_floor is not None:
            info["floor"] = self.floor(j)
        return info

    def outcome(self, j: int) -> tuple[float, bool, bool]:
        """(reward, terminated, truncated) of robot j as Python scalars, as :meth:`rewards`,
        :meth:`terminated` and :meth:`truncated` give them for all robots."""
        terminated = bool(self.err[j, 0] > self.cfg.lost_distance or self.world.collided[j])
        return float(self.reward[j]), terminated, bool(self.step_count[j] >= self.cfg.episode_steps)


class RobotEnvAttributes:
    """Public, read-only views of a :class:`TaskCore` shared by the single and the vector environment.

    Agents read these (through ``env.unwrapped``) instead of reaching into ``env.unwrapped.core``.
    """

    core: TaskCore

    @property
    def robot(self):
        """The robot (:class:`omni_gym.physics.robot.RobotSpec`: wheel layout, radii, mass) of the base model."""
        return self.core.robot

    @property
    def wheel_matrix(self) -> np.ndarray:
        """(n, 3) map from body twist (vx, vy [m/s], ω [rad/s], body frame) to wheel speeds [rad/s] that
        twist actions go through: the robot's, or the model's effective one (``kinematics="model"``); a copy."""
        return self.core.W.copy()

    @property
    def wheel_kinematics(self):
        """The :class:`omni_gym.physics.kinematics.WheelKinematics` (wheel matrix, rolling radius [m]) that
        twist actions go through and scripted controllers build their feed-forward and estimators from:
        nominal, or the model's effective kinematics with ``kinematics="model"``."""
        return self.core.kinematics

    @property
    def wheel_scale(self) -> float:
        """w_max [rad/s]: the wheel speed at wheel action ±1 and the encoder-rate observation scale."""
        return self.core.wheel_scale

    @property
    def observation_layout(self):
        """The :class:`~omni_gym.envs.observations.ObservationLayout` of this ``obs_mode`` (named slices)."""
        return self.core.layout

    @property
    def obs_scales(self):
        """The :class:`~omni_gym.envs.observations.ObsScales` observations are divided by."""
        return self.core.obs_scales

    @property
    def sensor_config(self):
        """The :class:`omni_gym.sensors.SensorConfig` the next ``reset`` builds the sensors from.

        Assigning a new config (e.g. scaled noise levels) takes effect at the next reset of each robot.
        """
        return self.core.sensor_config

    @sensor_config.setter
    def sensor_config(self, config) -> None:
        self.core.sensor_config = config
