"""A model-predictive oracle: MPPI that plans with the simulator itself (privileged; a bound, not a controller).

Every ``replan`` control steps the oracle copies each robot of the evaluation env, bit for bit
(:meth:`omni_gym.physics.world.World.copy_robot`: pose, velocity, wheel states, contact mask, the episode's
randomised model), into ``samples`` robots of its own planning world and drives each copy over the horizon
with the true-state feedback law (:mod:`agents.feedback_law`, evaluated on the copy's own state) plus a
sequence of corrections δ_k(h) [normalised twist]. Each sequence is scored by the tracking error it produces
against the robot's own reference:

    J_k = Σ_h |p_k(t+h) − p_ref(t+h)|² + (lever · wrap(θ_k(t+h) − θ_ref(t+h)))²      [m²]

(p the geometric centre in the arena frame, h = 1…H control steps, lever ``heading_lever`` [m]), plus a large
cost for touching a wall. MPPI averages the sequences with weights exp(−(J_k − J_min)/λ), λ the
``temperature`` times the spread J_median − J_min; the robot then applies the law on its own state plus the
averaged correction, which shifts by one step per control step (the tail filled with zeros) and is the
sequence 0 of the next plan: the law alone is always one of the scored candidates. Perturbations are
smooth (AR(1), correlation time ``correlation``) and drawn at four scales (``noise`` × 1, 1/3, 1/10, 1/30,
cycled over the samples): white or single-scale noise made the average jitter, and on a grip floor the
oracle was then worse than the law it starts from (3.5× at noise 0.3, measured while building it).

What the oracle knows: the true state, the floor and model of the episode (its randomised parameters), and
which wheels are up now (``contacts="hold"``: it assumes they stay so over the horizon; it does not know when
the next lift-off comes). Rollout actions are cast to float32 as the evaluation loop casts them.
``state="ekf"`` (sensor-only) starts the copies from the EKF's pose and velocity instead, all wheels down.

Randomness: one ``numpy.random.Generator`` seeded by ``OracleConfig.seed`` draws every perturbation; the same
seed, batch and episodes give the same actions bit for bit. Follows :class:`agents.vector_rollout.VectorActor`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from omni_gym.angles import wrap_angle
from omni_gym.envs.core import apply_actions
from omni_gym.physics.world import World

STATES = ("true", "noisy", "ekf")  # where the planner's start state comes from (OracleConfig.state)
LADDER = np.array([1.0, 1 / 3, 1 / 10, 1 / 30])  # perturbation scales, × OracleConfig.noise
WALL_COST = 1e3  # m²: a rollout that touches a wall loses to any that does not (tracking costs are < 1 m²·H)


@dataclass(frozen=True)
class OracleConfig:
    """The planner's settings (defaults: the benchmark's, ``benchmarks/oracle.py``).

    horizon [s]: planning horizon (whole control steps); samples: sequences per plan (sequence 0 the current
    plan); noise: standard deviation of the perturbations, in normalised action units (an action of 1 is
    ``max_speed`` or ``max_yaw_rate``); temperature: λ as a fraction of the cost spread; replan: control steps
    between plans (the plan's corrections are followed in between); heading_lever [m]: weight of the heading
    error; gain [1/s]: the rollout law's k; correlation [s]: the perturbations' correlation time; state:
    ``"true"`` (privileged: the true pose, velocity and contact mask), ``"noisy"`` (the true state plus the
    sensors' noise at every control step: the camera's position and heading noise, the gyro's on ω; what
    estimation could give at best with these sensors, without their 10 Hz rate, biases or slip) or ``"ekf"``
    (sensor-only: pose and
    velocity from :class:`agents.batched.estimation.BatchEKF` on the ``sensors`` observation, every wheel
    assumed down; the episode's model and floor are still known, as a calibrated simulator would know them);
    seed: the perturbations' Generator.
    """

    horizon: float = 0.5
    samples: int = 32
    noise: float = 0.3
    temperature: float = 0.1
    replan: int = 5
    heading_lever: float = 0.1
    gain: float = 2.0
    correlation: float = 0.1
    state: str = "true"
    seed: int = 0

    def __post_init__(self) -> None:
        checks = {"horizon": self.horizon > 0 and math.isfinite(self.horizon),
                  "samples": isinstance(self.samples, int) and self.samples >= 2,
                  "noise": self.noise > 0 and math.isfinite(self.noise),
                  "temperature": self.temperature > 0 and math.isfinite(self.temperature),
                  "replan": isinstance(self.replan, int) and self.replan >= 1,
                  "heading_lever": self.heading_lever >= 0 and math.isfinite(self.heading_lever),
                  "gain": self.gain >= 0 and math.isfinite(self.gain),
                  "correlation": self.correlation > 0 and math.isfinite(self.correlation),
                  "state": self.state in STATES}
        bad = [k for k, ok in checks.items() if not ok]
        if bad:
            raise ValueError(f"invalid OracleConfig {bad[0]}={getattr(self, bad[0])!r}: horizon, noise, temperature "
                             "> 0; samples >= 2 and replan >= 1 integers; heading_lever >= 0; state one of "
                             f"{', '.join(STATES)}")


class MPPIOracle:
    """MPPI over twist actions for the N robots of a native vector env (module docstring).

    ``vec_env``: from :func:`agents.vector_rollout.make_vector_env` (``action_mode="twist"``, any observation
    mode: the oracle reads the env's true state, not the observation).
    """

    def __init__(self, vec_env, config: OracleConfig | None = None) -> None:
        self.config = config = config or OracleConfig()
        core = vec_env.unwrapped.core
        if core.cfg.action_mode != "twist":
            raise ValueError("MPPIOracle plans twist actions: make the env with action_mode='twist'")
        self.core = core
        self.N, self.K = core.B, config.samples
        self.H = max(1, int(round(config.horizon * core.cfg.control_hz)))
        w = core.world
        self.planner = World(w.models[0], n_robots=self.N * self.K, dt=w.dt, actuation=w.actuation, arena=w.arena)
        self.rng = np.random.default_rng(config.seed)
        self.state_rng = np.random.default_rng([config.seed, 1])  # ``noisy``: its own stream
        self.plan = np.zeros((self.N, self.H, 3))
        self.steps = 0  # control steps taken: every robot is planned for together, every ``replan`` steps
        self._clipped = np.zeros((self.N * self.K, 3))
        self.ekf = None
        if config.state == "ekf":
            from agents.batched.estimation import BatchEKF
            from agents.ekf import EKFConfig
            from omni_gym.envs.observations import BatchSensorObsDecoder

            u = vec_env.unwrapped
            if core.cfg.obs_mode != "sensors":
                raise ValueError("MPPIOracle(state='ekf') reads the sensors: make the env with obs_mode='sensors'")
            self.decode = BatchSensorObsDecoder(u.observation_layout, u.obs_scales)
            self.ekf = BatchEKF(u.wheel_kinematics, self.N,
                                EKFConfig.from_sensor_config(core.cfg.sensor_config(), core.cfg.control_hz))
            self._started = np.zeros(self.N, dtype=bool)

    # --- the VectorActor interface --------------------------------------------------------------------

    def reset(self, obs: np.ndarray, mask=None) -> None:
        """New episodes for the robots of ``mask`` (all if None): their corrections start at zero."""
        rows = np.arange(self.N) if mask is None else np.flatnonzero(np.asarray(mask, dtype=bool))
        self.plan[rows] = 0.0  # a new episode follows the law until the next plan
        if self.ekf is not None:
            m = np.zeros(self.N, dtype=bool)
            m[rows] = True
            self.ekf.reset(m, self.decode(obs).ref_pose[m])  # at rest at the reference's first pose
            self._started[m] = False

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        """What the planner starts from: (N, 3) poses [m, m, rad] and (N, 3) velocities ẋ, ẏ [m/s] (world
        frame), ω [rad/s]; the true ones or the EKF's (``OracleConfig.state``)."""
        if self.ekf is None:
            pose, vel = self.core.true[:, 0:3].copy(), self.core.true[:, 3:6].copy()
            if self.config.state == "noisy":
                sc = self.core.sensor_config
                scale = self.core.sensor_noise_scale  # per robot (randomize_sensor_noise), 1 by default
                z = self.state_rng.normal(size=(self.N, 4))
                pose[:, 0:2] += z[:, 0:2] * (sc.camera_position_std * scale)[:, None]
                pose[:, 2] = wrap_angle(pose[:, 2] + z[:, 2] * sc.camera_heading_std * scale)
                vel[:, 2] += z[:, 3] * sc.gyro_noise_std * scale
            return pose, vel
        pose, twist = self.ekf.pose, self.ekf.body_twist
        c, s = np.cos(pose[:, 2]), np.sin(pose[:, 2])
        return pose, np.column_stack([c * twist[:, 0] - s * twist[:, 1], s * twist[:, 0] + c * twist[:, 1],
                                      twist[:, 2]])

    def act(self, obs: np.ndarray) -> np.ndarray:
        if self.ekf is not None:  # every observation after the reset one closes a control period
            if self._started.any():
                self.ekf.process(self.decode(obs), self.core.cfg.control_dt, self._started)
            self._started[:] = True
        pose, vel = self.state()
        if self.steps % self.config.replan == 0:
            self._optimise(pose, vel)
        core = self.core
        law = self._law(np.arange(self.N), core.step_count, pose)
        actions = np.clip(law + self.plan[:, 0], -1.0, 1.0).astype(np.float32)
        self.plan[:, :-1] = self.plan[:, 1:]  # the next step's correction: this plan's tail, then none
        self.plan[:, -1] = 0.0
        self.steps += 1
        return actions

    # --- planning -----------------------------------------------------------------------------------------

    def _law(self, owner: np.ndarray, steps: np.ndarray, pose: np.ndarray) -> np.ndarray:
        """The true-state law's normalised twist (before clipping) for robots at ``pose`` (M, 3) [m, m, rad,
        arena frame] following the references of robots ``owner`` (M,) at control steps ``steps`` (M,):
        (v_ref,body + k·e_body, ω_ref + k·e_θ) / (v_max, v_max, ω_max), as :mod:`agents.feedback_law`."""
        core = self.core
        k = np.minimum(steps, core.n_samples - 1)
        ref, vel = core.ref_pose[owner, k], core.ref_vel[owner, k]
        c, s = np.cos(pose[:, 2]), np.sin(pose[:, 2])
        ex, ey = ref[:, 0] - pose[:, 0], ref[:, 1] - pose[:, 1]
        g = self.config.gain
        twist = np.column_stack([c * vel[:, 0] + s * vel[:, 1] + g * (c * ex + s * ey),
                                 -s * vel[:, 0] + c * vel[:, 1] + g * (-s * ex + c * ey),
                                 vel[:, 2] + g * wrap_angle(ref[:, 2] - pose[:, 2])])
        return twist / core.twist_scale

    def _optimise(self, pose: np.ndarray, vel: np.ndarray) -> None:
        """One MPPI update of every robot's plan from ``pose``/``vel`` (N, 3), the state :meth:`state` gives
        (used where it is an estimate); all N·K rollouts run as one batch."""
        cfg, core, N, K, H = self.config, self.core, self.N, self.K, self.H
        planner = self.planner
        down = np.ones(core.n_wheels, dtype=bool)
        for i in range(N):
            copies = np.arange(i * K, (i + 1) * K)
            planner.copy_robot(core.world, int(i), copies, contacts="hold")
            if self.config.state != "true":  # the estimate replaces the true state; the lifted wheels are unknown
                planner.place(copies, np.tile(pose[i], (K, 1)), np.tile(vel[i], (K, 1)))
                for k in copies:
                    planner.set_contact(int(k), down)
        # Smooth perturbations (AR(1) with correlation time ``correlation``): white noise per 10 ms step makes
        # wheel commands jitter and slip, and 32 samples cannot average it out.
        beta = math.exp(-core.cfg.control_dt / cfg.correlation)
        # Samples at several scales (``noise`` × 1, 1/3, 1/10, 1/30, cycled over the samples): large corrections
        # find the way back after a slip, small ones polish millimetre tracking, where large ones only add jitter.
        scale = cfg.noise * LADDER[np.arange(K) % len(LADDER)]
        white = self.rng.normal(0.0, 1.0, size=(N, K, H, 3)) * scale[None, :, None, None]
        eps = np.empty_like(white)
        eps[:, :, 0] = white[:, :, 0]
        for h in range(1, H):
            eps[:, :, h] = beta * eps[:, :, h - 1] + math.sqrt(1.0 - beta * beta) * white[:, :, h]
        eps[:, 0] = 0.0  # sequence 0: the current plan
        seqs = self.plan[:, None] + eps  # (N, K, H, 3)
        flat = seqs.reshape(N * K, H, 3)
        owner = np.repeat(np.arange(N), K)
        step0 = core.step_count[owner]
        cost = np.zeros(N * K)
        lever = cfg.heading_lever
        pose = planner.pose
        for h in range(H):
            # The rollout policy: the law on the copy's own state plus the sequence's correction, cast as the
            # evaluation loop casts actions (float32), so sequence 0's first step is what the env will do.
            act = np.clip(self._law(owner, step0 + h, pose) + flat[:, h], -1.0, 1.0).astype(np.float32)
            apply_actions(act.astype(np.float64), True, core.twist_scale, core.W, planner.wheels, self._clipped)
            planner.substeps(core.cfg.substeps)
            pose = planner.pose
            ref = core.ref_pose[owner, np.minimum(step0 + h + 1, core.n_samples - 1)]
            d = pose - ref
            cost += d[:, 0] ** 2 + d[:, 1] ** 2 + (lever * wrap_angle(d[:, 2])) ** 2
        cost += WALL_COST * planner.collided
        J = cost.reshape(N, K)
        lo = J.min(axis=1, keepdims=True)
        spread = np.median(J, axis=1, keepdims=True) - lo
        lam = cfg.temperature * np.maximum(spread, 1e-12)
        w = np.exp(-(J - lo) / lam)
        w /= w.sum(axis=1, keepdims=True)
        self.plan = np.einsum("nk,nkha->nha", w, seqs)


# --- names: the oracle as a policy of the benchmark tables ---------------------------------------------------

ORACLE = "mppi oracle"  # the default OracleConfig, true state
SENSOR_ORACLE = "mppi oracle, sensor-only"  # the default OracleConfig, state="ekf"
NOISY_ORACLE = "mppi oracle, true state + noise"  # the default OracleConfig, state="noisy"
_NAMES = {"true": ORACLE, "ekf": SENSOR_ORACLE, "noisy": NOISY_ORACLE}


def oracle_name(config: OracleConfig) -> str:
    """The table name of an oracle: :data:`ORACLE`, :data:`NOISY_ORACLE` or :data:`SENSOR_ORACLE` by its state,
    with the fields that differ from the defaults appended (``"mppi oracle [horizon=1, samples=64]"``);
    :func:`oracle_config` reads it."""
    base = _NAMES[config.state]
    default = OracleConfig(state=config.state)
    diff = [f"{k}={getattr(config, k):g}" for k in OracleConfig.__dataclass_fields__
            if k != "state" and getattr(config, k) != getattr(default, k)]
    return base + (f" [{', '.join(diff)}]" if diff else "")


def oracle_config(name: str) -> OracleConfig | None:
    """The settings :func:`oracle_name` wrote into ``name``; None if ``name`` names no oracle."""
    base, _, rest = name.partition(" [")
    states = {v: k for k, v in _NAMES.items()}
    if base not in states or (rest and not rest.endswith("]")):
        return None
    kw: dict = {"state": states[base]}
    fields = OracleConfig.__dataclass_fields__
    for item in filter(None, rest[:-1].split(", ")):
        key, _, value = item.partition("=")
        if key not in fields or key == "state":
            return None
        kw[key] = int(value) if fields[key].type in (int, "int") else float(value)
    return OracleConfig(**kw)
