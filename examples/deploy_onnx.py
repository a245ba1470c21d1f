"""A minimal deployment loop: an exported policy (``omni-gym export``) driving a robot: the simulator, or any plant.

    omni-gym export agents/models/ppo-residual-williams --out exported
    python examples/deploy_onnx.py exported [--seconds 10] [--seed 10000] [--env-kwargs JSON]
    python examples/deploy_onnx.py exported --plant-model TRUTH.json [--plant-extra '{"drag": 2.0}']

The robot is a *plant* (``omni_gym.physics.plant``: ``reset(pose, seed)``, ``step(wheel_speeds, duration)``).
By default the environment's own world; ``--plant-model`` drives the second generator in closed loop instead
(a robot with the hidden effects of a model file, integrated apart from the world); :class:`YourRobotDriver`
below is where a real robot's driver goes: its ``step`` sends the wheel speeds to the motor drivers, waits one
control period and returns what the robot's sensors read. The environment only supplies the reference path
and scores the run (docs/formats.md, "Plants").

Each control period (``policy.json``'s ``control_period_s``):

1. read the sensors (here: the simulated robot's sensor observation; on a robot, your drivers);
2. build the network's input: the EKF features for agents trained on them (``EKFFeatureFilter``, numpy and
   scipy only), else the environment's observation as the sidecar lays it out;
3. run the ONNX network with ``onnxruntime`` (the observation normalisation is inside it);
4. turn its action into the twist command (a residual agent adds it to ``ekf-pid``'s, the filter does that),
   and the twist into wheel speeds w = W · (vx, vy, ω) [rad/s] with the sidecar's ``wheel_matrix``; send them.
   (The simulator takes the twist action and applies the same W itself.)

Needs ``onnxruntime`` and numpy; imports neither torch nor Stable-Baselines3.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np
import onnxruntime as ort


class YourRobotDriver:
    """The third plant: your robot behind its driver (a sketch to fill in; every method says what it must do).

    ``n_wheels``: the model's wheel count, in the model's wheel order. Units: metres, radians, seconds.
    """

    n_wheels = 3

    def reset(self, pose, seed):
        """Wait until the robot stands still at ``pose`` (x, y [m], θ [rad], the reference's start; place it
        there, or drive it there first) and return ``PlantState(pose, velocity=zeros, wheel_angles, reading=...)``
        with ``SensorReading(wheel_angles, gyro, compass, accel, fix)`` from the robot's own sensors."""
        raise NotImplementedError("send the robot to the start pose, then return its PlantState")

    def step(self, wheel_speeds, duration):
        """Send ``wheel_speeds`` [rad/s] to the motor drivers, hold them for ``duration`` [s] (one control period:
        sleep until the period's end on the robot's clock), then return the PlantState with the sensors' reading;
        its pose and velocity come from motion capture, for scoring only."""
        raise NotImplementedError("send the wheel speeds, wait one period, return the PlantState")


class SimulatedRobot:
    """The robot's side: sensors in, twist action out (an omni-gym environment with sensor observations), with the
    wheel commands driving ``plant`` when one is given (else the environment's own world)."""

    def __init__(self, env_id: str, obs_mode: str, env_kwargs: dict, seed: int, plant=None) -> None:
        import gymnasium as gym

        import omni_gym  # noqa: F401  (registers the ids)

        self.env = gym.make(env_id, obs_mode=obs_mode, action_mode="twist", **env_kwargs)
        if plant is not None:
            self.env.unwrapped.core.attach_plant(plant)
        self.obs, _ = self.env.reset(seed=seed)
        self.done = False
        self.errors: list[float] = []

    def read_sensors(self) -> np.ndarray:
        return self.obs

    def send(self, twist_action: np.ndarray) -> None:
        self.obs, _, terminated, truncated, info = self.env.step(twist_action.astype(np.float32))
        self.errors.append(float(info["tracking_error"]))
        self.done = bool(terminated or truncated)


def run(export_dir: str | Path, seconds: float = 10.0, seed: int = 10000, env_kwargs: dict | None = None,
        record: bool = False, plant=None) -> dict:
    """Drive the robot (``plant``, else the simulator) with the exported policy for ``seconds``; returns tracking
    RMSE [m], steps and the largest wheel speed sent [rad/s]; with ``record`` also every network input and output
    (lists)."""
    export_dir = Path(export_dir)
    side = json.loads((export_dir / "policy.json").read_text())
    session = ort.InferenceSession(str(export_dir / "policy.onnx"), providers=["CPUExecutionProvider"])
    ekf = side["ekf_features"] is not None
    obs_mode = "sensors" if ekf else side["observation"]["mode"]
    kwargs = {"episode_seconds": seconds, **(env_kwargs or {})}
    robot = SimulatedRobot(side["env_id"], obs_mode, kwargs, seed, plant)
    W = np.asarray(side["action"]["wheel_matrix"])
    scale = np.array([side["action"]["scale"][k][0] for k in ("vx", "vy", "omega")])
    features = None
    if ekf:
        from agents.wrappers import EKFFeatureFilter

        residual = side["action"].get("residual", {}).get("scale", 0.0)
        features = EKFFeatureFilter.for_env(robot.env, residual)
        x = features.reset(robot.read_sensors())
    else:
        x = robot.read_sensors()
    w_max = 0.0
    inputs, outputs = [], []
    while not robot.done:
        action = session.run(["action"], {"obs": x[None].astype(np.float32)})[0][0]
        if record:
            inputs.append(x.tolist())
            outputs.append(action.tolist())
        twist = features.command(action) if features is not None else np.clip(action, -1.0, 1.0)
        wheel_speeds = W @ (twist * scale)  # what a robot's motor drivers receive [rad/s]
        w_max = max(w_max, float(np.max(np.abs(wheel_speeds))))
        robot.send(twist)
        obs = robot.read_sensors()
        x = features.observe(obs) if features is not None else obs
    robot.env.close()
    rmse = math.sqrt(float(np.mean(np.square(robot.errors))))
    out = {"tracking_rmse": rmse, "steps": len(robot.errors), "max_wheel_speed": w_max}
    return {**out, "inputs": inputs, "outputs": outputs} if record else out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("export_dir", help="folder written by omni-gym export (policy.onnx, policy.json)")
    p.add_argument("--seconds", type=float, default=10.0, help="episode length [s]")
    p.add_argument("--seed", type=int, default=10000, help="episode seed")
    p.add_argument("--env-kwargs", default="{}", help="JSON keywords of the environment (e.g. its model=)")
    p.add_argument("--plant-model", default=None, help="drive the second generator with this model file's effects")
    p.add_argument("--plant-extra", default=None, help="effects outside the library for it, e.g. {\"drag\": 2.0}")
    args = p.parse_args(argv)
    plant = None
    if args.plant_model is not None:
        from omni_gym.analysis.closed_loop import SecondGeneratorPlant
        from omni_gym.envs.config import parse_model

        extra = json.loads(args.plant_extra) if args.plant_extra else None
        plant = SecondGeneratorPlant(parse_model(args.plant_model), extra)
    result = run(args.export_dir, args.seconds, args.seed, json.loads(args.env_kwargs), plant=plant)
    print(f"{result['steps']} control periods, tracking RMSE {result['tracking_rmse'] * 1000:.2f} mm, "
          f"largest wheel speed {result['max_wheel_speed']:.2f} rad/s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
