"""``omni-gym export MODEL --out DIR``: a trained agent → ONNX (and TorchScript) for the robot's computer.

The agent is loaded as ``evaluate`` loads it (:func:`agents.loaders.find_loader`: an SB3 model directory, an
RL Zoo folder, an SB3 zip or an RLlib model), and its in-memory policy is exported, so nothing here depends on
how the model is stored. The exported network maps a batch of observations (B, D) float32 to the
deterministic actions (B, A) float32 the trained policy takes:

* the observation normalisation of training (SB3 ``VecNormalize``: (o − mean)/√(var + ε), clipped to
  ±clip_obs, computed in float64 as SB3 does) is built in: feed the raw observation;
* SB3: the policy's deterministic action (PPO: the Gaussian mean clipped to the action box; SAC: tanh of the
  mean, rescaled to the box); RLlib: the mean of the diagonal Gaussian, clipped to the box.

Written into ``DIR`` (complete or absent, ``--force`` to replace): ``policy.onnx``, ``policy.json`` (the
sidecar: observation layout with units and scales, action meaning and scaling, control period, whether the
observation is the EKF features and how to compute them, the parity check), and with ``torchscript``
``policy.pt``. Parity: the ONNX network run by ``onnxruntime`` on :data:`PARITY_OBSERVATIONS` observations
must give the policy's actions within :data:`PARITY_TOL`, or nothing is written.
"""

from __future__ import annotations

import json
import warnings
from dataclasses import asdict
from pathlib import Path

import numpy as np

from agents.loaders import find_loader
from agents.rollout import check_env_id
from agents.wrappers import CLIP, EKFFeatures, FeedForwardTwist
from omni_gym.io import read_json

PARITY_OBSERVATIONS = 1000
PARITY_TOL = 1e-5  # float32 networks: onnxruntime and torch sum in different orders (about 1e-7 apart)
OPSET = 17
SIDE_FORMAT = "omni-gym policy export 1"
MISSING = ("omni-gym export needs the optional packages onnx and onnxruntime: pip install -e '.[export]' (from the "
           "omni-gym checkout)")


def _require() -> None:
    try:
        import onnx  # noqa: F401
        import onnxruntime  # noqa: F401
    except ImportError:
        raise ValueError(MISSING) from None


def _normaliser(vecnormalize):
    """The observation statistics of ``vecnormalize`` (an :class:`agents.weights.ObsNormaliser`, an SB3
    ``VecNormalize`` or None) as an ObsNormaliser, or None when observations are not normalised."""
    from agents.weights import ObsNormaliser

    if vecnormalize is None or isinstance(vecnormalize, ObsNormaliser):
        return vecnormalize
    return ObsNormaliser.from_vecnormalize(vecnormalize)


def _torch_module(policy):
    """A torch module: raw observations (B, D) float32 → deterministic actions (B, A) float32 of ``policy``
    (an :class:`agents.sb3_policy.SB3Policy` or :class:`agents.rllib.policy.RLlibPolicy`)."""
    import torch

    class SB3Actor(torch.nn.Module):
        def __init__(self, model, vecnormalize) -> None:
            super().__init__()
            # The project's weights format loads the policy network itself (agents.weights); an SB3 zip opened
            # with --trust-pickle loads the algorithm, which holds it.
            self.policy = getattr(model, "policy", model)
            space = model.action_space
            self.register_buffer("low", torch.as_tensor(space.low, dtype=torch.float32))
            self.register_buffer("high", torch.as_tensor(space.high, dtype=torch.float32))
            stats = _normaliser(vecnormalize)
            self.normalise = stats is not None
            if self.normalise:
                self.register_buffer("mean", torch.as_tensor(stats.mean))
                self.register_buffer("std", torch.as_tensor(np.sqrt(stats.var + stats.epsilon)))
                self.clip = float(stats.clip)

        def forward(self, obs):
            x = obs
            if self.normalise:  # as VecNormalize.normalize_obs: float64, then float32 as SB3Policy.act casts
                x = torch.clamp((obs.double() - self.mean) / self.std, -self.clip, self.clip).float()
            a = self.policy._predict(x, deterministic=True)
            if self.policy.squash_output:  # SAC: tanh output in [-1, 1] → the box (BasePolicy.unscale_action)
                return self.low + 0.5 * (a + 1.0) * (self.high - self.low)
            return torch.maximum(torch.minimum(a, self.high), self.low)

    class RLlibActor(torch.nn.Module):
        def __init__(self, module, low, high) -> None:
            super().__init__()
            self.module = module
            self.register_buffer("low", torch.as_tensor(low))
            self.register_buffer("high", torch.as_tensor(high))
            self.n = int(np.asarray(low).size)

        def forward(self, obs):
            out = self.module.forward_inference({"obs": obs})["action_dist_inputs"]
            loc = out[..., : self.n]  # a diagonal Gaussian's inputs are (mean, log std)
            return torch.maximum(torch.minimum(loc, self.high), self.low)

    if hasattr(policy, "model") and hasattr(policy, "vecnormalize"):
        return SB3Actor(policy.model, policy.vecnormalize).eval(), "sb3"
    if hasattr(policy, "module"):
        return RLlibActor(policy.module, policy.low, policy.high).eval(), "rllib"
    raise ValueError(f"cannot export a {type(policy).__name__}: only trained SB3 or RLlib agents have a network")


def _wrapper(env):
    """(name, residual scale) of the wrapper stack the loader built around the environment."""
    e = env
    while e is not None:
        if isinstance(e, EKFFeatures):
            return ("residual-ekf-pid" if e.residual_scale > 0 else "ekf-features"), e.residual_scale
        if isinstance(e, FeedForwardTwist):
            return "feedforward", e.scale
        e = getattr(e, "env", None)
    return "none", 0.0


def ekf_feature_fields(n: int) -> list[dict]:
    """The EKF feature vector's blocks (:mod:`agents.wrappers`' table) for a robot of ``n`` wheels."""
    rows = [("tracking_error_body", 2, "reference − estimated position, estimated body frame", "m", "/ 0.05 m"),
            ("heading_error", 1, "wrap(θ_ref − θ̂)", "rad", "/ 0.1 rad"),
            ("estimated_twist", 3, "estimated body twist vx, vy, ω", "m/s, m/s, rad/s", "/ v_max, v_max, ω_max"),
            ("reference_velocity", 3, "reference velocity in the estimated body frame, ω_ref", "m/s, m/s, rad/s",
             "/ v_max, v_max, ω_max"),
            ("lookahead", 9, "reference at +0.25, +0.5, +1 s: body-frame offset x, y, heading error",
             "m, m, rad", "/ 0.5 m, / π"),
            ("ekf_std", 3, "EKF standard deviation of x, y, θ", "m, m, rad", "/ 0.01 m, / 0.02 rad"),
            ("wheel_belief", n, "detector belief that wheel i slips or is lifted", "", ""),
            ("wheels_used", n, "wheels the filter used this step (1) or rejected (0)", "", ""),
            ("encoder_innovation", n, "encoder rate − W·(estimated twist) per wheel", "rad/s", "/ w_max"),
            ("pid_twist", 3, "the PID's body twist (ekf-pid's action)", "", "action units"),
            ("pid_integral", 3, "the PID's integral terms, estimated body frame", "", "/ their limits"),
            ("last_action", 3, "the agent's previous action", "", "")]
    out, start = [], 0
    for name, size, quantity, unit, scale in rows:
        out.append({"name": name, "start": start, "stop": start + size, "quantity": quantity, "unit": unit,
                    "scale": scale, "range": f"±{CLIP:g}"})
        start += size
    return out


def sidecar(spec: str, env_id: str, env, kind: str, normalised: bool, parity: float) -> dict:
    """The JSON sidecar of an export: what a robot program must know to run the network."""
    u = env.unwrapped
    cfg = u.cfg
    wrapper, scale = _wrapper(env)
    ekf = wrapper in ("residual-ekf-pid", "ekf-features")
    obs_dim = int(env.observation_space.shape[0])
    if ekf:
        observation = {"mode": "ekf-features", "fields": ekf_feature_fields((obs_dim - 30) // 3)}
    else:
        observation = {"mode": u.observation_layout.mode, "fields": [asdict(f) for f in u.observation_layout.fields]}
    action_dim = int(env.action_space.shape[0])
    if cfg.action_mode == "twist":
        action = {"mode": "twist", "scale": {"vx": [cfg.max_speed, "m/s"], "vy": [cfg.max_speed, "m/s"],
                                             "omega": [cfg.max_yaw_rate, "rad/s"]},
                  "meaning": "body-frame twist (vx, vy, ω) = action · scale, clipped to [-1, 1] first",
                  # what the environment's inverse kinematics does: wheel speeds [rad/s] = W · twist
                  "wheel_matrix": np.asarray(u.wheel_matrix, dtype=float).tolist(),
                  "wheel_speeds": "w [rad/s] = wheel_matrix (n × 3) · (vx, vy, ω)"}
    else:
        action = {"mode": "wheels", "scale": {"w": [float(u.wheel_scale), "rad/s"]},
                  "meaning": "wheel speed commands = action · w_max"}
    if wrapper == "residual-ekf-pid":
        action["residual"] = {"scale": scale, "command": "clip(ekf_pid_action + scale · action, -1, 1)"}
    elif wrapper == "feedforward":
        action["feedforward"] = {"scale": scale, "command": "clip(reference_velocity + scale · action, -1, 1)"}
    return {
        "format": SIDE_FORMAT,
        "source": spec, "backend": kind, "env_id": env_id, "wrapper": wrapper,
        "input": {"name": "obs", "shape": ["batch", obs_dim], "dtype": "float32"},
        "output": {"name": "action", "shape": ["batch", action_dim], "dtype": "float32", "range": [-1.0, 1.0]},
        "normalisation": ("built in: feed the raw observation (training's VecNormalize statistics)" if normalised
                          else "none"),
        "observation": observation,
        "action": action,
        "control_period_s": float(cfg.control_dt),
        "ekf_features": ({"class": "agents.wrappers.EKFFeatureFilter",
                          "use": "EKFFeatureFilter.for_env(env, residual_scale) turns each sensor observation into "
                                 "the network's input (observe) and its output into the twist action (command); "
                                 "numpy and scipy only"} if ekf else None),
        "parity": {"observations": PARITY_OBSERVATIONS, "max_abs_difference": parity, "tolerance": PARITY_TOL,
                   "runtime": "onnxruntime"},
    }


def parity_observations(env, policy, n: int = PARITY_OBSERVATIONS, seed: int = 0) -> np.ndarray:
    """(n, D) float32 test observations: drawn around training's normalisation statistics when there are
    any (what the robot sees), else uniform in [-1, 1]; clipped to the observation box."""
    rng = np.random.default_rng(seed)
    space = env.observation_space
    D = int(space.shape[0])
    stats = _normaliser(getattr(policy, "vecnormalize", None))
    if stats is not None:
        obs = stats.mean + np.sqrt(stats.var) * rng.normal(size=(n, D)) * 1.5
    else:
        obs = rng.uniform(-1.0, 1.0, size=(n, D))
    return np.clip(obs, space.low, space.high).astype(np.float32)


def export(spec: str, out: str | Path, env_id: str | None = None, env_kwargs: dict | None = None,
           options=None, torchscript: bool = False, force: bool = False) -> dict:
    """Export the agent ``spec`` into the folder ``out``; returns the sidecar (module docstring)."""
    _require()
    import onnxruntime as ort
    import torch

    from omni_gym.outputs import Output

    loader = find_loader(spec)
    if loader.name == "scripted":
        raise ValueError(f"policy {spec!r} is a scripted controller, not a trained network: nothing to export")
    if loader.name == "gated":  # two controllers and a gate: only the network half is a network
        from agents.gated import read_gate

        raise ValueError(f"{spec}: a gated controller is ekf-pid and a student with a gate between them, not one "
                         f"network; export its student ({read_gate(spec).student.name}) and run the gate of "
                         "agents/gated.py beside it")
    loader.check_options(spec, options)
    if env_id is None and loader.name in ("sb3-model", "rllib"):
        env_id = _recorded_env(spec)
    if env_id is None:
        raise ValueError(f"{spec}: the model does not record its environment: give --env")
    out = Path(out)
    with Output(out, "dir", force=force, inputs=[Path(spec)], marker="policy.json", what="exported policy") as tx:
        env, policy = loader.load(spec, env_id, env_kwargs, options)
        try:
            module, kind = _torch_module(policy)
            obs = parity_observations(env, policy)
            expected = np.asarray(policy.act(obs), dtype=np.float32).reshape(len(obs), -1)
            onnx_path = tx.path / "policy.onnx"
            example = torch.from_numpy(obs[:2])
            with warnings.catch_warnings():  # the TorchScript-based exporter: the one that traces SB3 policies
                warnings.simplefilter("ignore")
                torch.onnx.export(module, (example,), str(onnx_path), input_names=["obs"], output_names=["action"],
                                  dynamic_axes={"obs": {0: "batch"}, "action": {0: "batch"}}, opset_version=OPSET,
                                  dynamo=False)
            session = ort.InferenceSession(str(onnx_path), providers=["CPUExecutionProvider"])
            got = session.run(["action"], {"obs": obs})[0]
            parity = float(np.max(np.abs(got - expected)))
            if not parity <= PARITY_TOL:
                raise ValueError(f"{spec}: the exported network's actions differ from the policy's by {parity:.3g} "
                                 f"(> {PARITY_TOL:g}) on {len(obs)} observations; nothing written")
            if torchscript:
                with torch.no_grad():
                    traced = torch.jit.trace(module, example)
                traced.save(str(tx.path / "policy.pt"))
            normalised = bool(getattr(module, "normalise", False))
            side = sidecar(spec, env_id, env, kind, normalised, parity)
            (tx.path / "policy.json").write_text(json.dumps(side, indent=2, ensure_ascii=False) + "\n")
        finally:
            env.close()
    return side


def _recorded_env(spec: str) -> str | None:
    """The environment id a model directory records (``meta.json``'s ``env_id``), else None."""
    f = Path(spec) / "meta.json"
    if not f.is_file():
        return None
    meta = read_json(f)  # bounded (size, nesting): a bad file is one line naming it
    env_id = meta.get("env_id") if isinstance(meta, dict) else None
    # never "MODULE:ID" (making it would import MODULE), whatever --trust-pickle says
    return None if env_id is None else check_env_id(env_id, f"{f}: key 'env_id'")
