"""The ``omni-gym`` command line.

Bad input never shows a traceback: it prints one line ``omni-gym: error: …`` naming what is wrong
and where, and exits with status 2.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys

import numpy as np

from omni_gym import __version__
from omni_gym.bounds import CLI as CLI_BOUNDS
from omni_gym.discrepancy.data.budget import FIT_BUDGET, MIN_FIT_BUDGET, MIN_SEGMENT, SEGMENT, check_fit_budget
from omni_gym.discrepancy.data.importers import FORMATS as IMPORT_FORMATS
from omni_gym.interrupts import EXIT_INTERRUPTED, exit_interrupted, is_command_line, main_handler
from omni_gym.interrupts import MESSAGE as INTERRUPTED
from omni_gym.parallel import add_ray_option, backend_from_options, usable_cores
from omni_gym.physics.friction import FRICTION_MODELS, SURFACES
from omni_gym.physics.robot import PRESETS

EXIT_BAD_INPUT = 2


def _add_model_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--surface", choices=sorted(SURFACES), help="floor (overrides the model's)")
    p.add_argument("--friction", choices=FRICTION_MODELS, help="friction model (overrides the model's)")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="omni-gym", description="Omnidirectional robots that slip: tools.")
    parser.add_argument("--version", action="version", version=f"omni-gym {__version__}")
    parser.add_argument("--max-input-mb", type=float, default=None, metavar="MB",
                        help="largest input file read [MB] (default 32; docs/bounds.md): raise it for a "
                             "legitimately large dataset or run file")
    sub = parser.add_subparsers(dest="command", required=True)

    model = sub.add_parser("model", help="inspect robot models")
    msub = model.add_subparsers(dest="model_command", required=True)
    show = msub.add_parser("show", help="print a model (preset name or JSON file)")
    show.add_argument("name", help=f"{', '.join(PRESETS)}, regularN or a model JSON file")
    _add_model_options(show)
    show.add_argument("--json", action="store_true", help="print JSON (the machine-readable contract)")

    sim = sub.add_parser("simulate", help="replay wheel commands through the world")
    sim.add_argument("--model", required=True, help="preset name or model JSON file")
    _add_model_options(sim)
    sim.add_argument("--commands", required=True, help="CSV with header t,w1,...,wn")
    sim.add_argument("--out", required=True, help="trajectory CSV to write (t,x,y,theta,vx,vy,omega)")
    sim.add_argument("--dt", type=float, default=None,
                     help="physics substep [s], 1e-05 to 0.002 (default 0.0005; docs/bounds.md)")
    sim.add_argument("--actuation", choices=("ideal", "servo"), default="ideal", help="wheel actuation")
    sim.add_argument("--seed", type=int, default=0, help="seed (>= 0) for random effects (wheel lift-off)")
    _add_force_option(sim, "an existing --out file")

    ev = sub.add_parser("evaluate", help="evaluate a policy on held-out seeds (mean and 95%% CI per metric)")
    ev.add_argument("--policy", required=True,
                    help="open-loop, odometry-pid, ekf-pid, ekf-pid-traction, recommended (per id: the controller "
                         "to deploy, docs/agents.md), or a trained model: our model directory (meta.json), a gated "
                         "controller, an RL Zoo output folder (logs/ALGO/ENV_1), a plain SB3 .zip or an RLlib "
                         "checkpoint folder (rllib_checkpoint.json)")
    ev.add_argument("--env", required=True, help="environment id, e.g. OmniPathFollow-Phunopas-v0")
    ev.add_argument("--episodes", type=int, required=True, help="number of episodes, 1 to 100000")
    ev.add_argument("--seed", type=int, default=None,
                    help="first seed (>= 0); episode i uses seed + i (default 10000: held out from training, which "
                         "uses small seeds, and validation, 5000 and up)")
    ev.add_argument("--against", default=None, metavar="POLICY",
                    help="a second policy (same forms as --policy) run on the same seeds: paired ratio of mean "
                         "tracking RMSE with a 95%% bootstrap interval, and the share of episodes each wins")
    ev.add_argument("--score", action="store_true",
                    help="also run open-loop and ekf-pid on the same seeds and keywords and print the normalised "
                         "score: 100*(RMSE_open - RMSE_policy)/(RMSE_open - RMSE_ekfpid), 0 = open-loop, 100 = "
                         "ekf-pid (agents/normalised_score.py)")
    ev.add_argument("--env-kwargs", default=None, help="gym.make keywords as a JSON object")
    ev.add_argument("--plant", choices=PLANTS, default=None,
                    help="drive a plant instead of the environment's own world, on the same references and seeds: "
                         "'second-generator' (the separately written event integrator, closed loop) or 'simulator' "
                         "(omni-gym's world through the plant protocol); docs/formats.md, 'Plants'")
    ev.add_argument("--plant-model", default=None, metavar="MODEL.json",
                    help="the plant's model file (the robot's truth, hidden effects included; default: the "
                         "environment's own model)")
    ev.add_argument("--plant-extra", default=None, metavar="JSON",
                    help="second-generator only: effects outside the library on top of --plant-model, e.g. "
                         "'{\"drag\": 2.0}' or '{\"slope\": {\"angle\": 0.03, \"direction\": 0.5}}'")
    ev.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    ev.add_argument("--algo", default=None, help="plain SB3 .zip: its algorithm (ppo, sac, td3)")
    ev.add_argument("--wrapper", default=None,
                    help="plain SB3 .zip: the wrapper it was trained with (none, residual-ekf-pid, ekf-features)")
    ev.add_argument("--residual-scale", type=float, default=None,
                    help="plain SB3 .zip with residual-ekf-pid: the residual bound, 0 to 1 (default 0.3)")
    ev.add_argument("--vecnormalize", default=None,
                    help="plain SB3 .zip: its observation statistics (a VecNormalize .pkl, or normalisation.npz)")
    ev.add_argument("--trust-pickle", action="store_true",
                    help="open a model that is a Python pickle (an SB3 .zip, a VecNormalize .pkl, an RLlib "
                         "checkpoint, a model folder of the older layout): loading it runs any code it holds, so "
                         "only for a file from someone you trust (docs/security.md); omni-gym's own models need "
                         "no flag")

    show.set_defaults(handler=_cmd_model_show)
    sim.set_defaults(handler=_cmd_simulate)
    ev.set_defaults(handler=_cmd_evaluate)
    tr = sub.add_parser("train", help="train an SB3 agent (ppo, sac, td3; hyperparameters from agents/hyperparams) "
                                      "or RLlib PPO (--backend rllib; agents/rllib)")
    _add_train_options(tr)
    tr.set_defaults(handler=_cmd_train)
    gp = sub.add_parser("gap", help="find, name and add the effect missing from a dataset's nominal model")
    gp.add_argument("dataset", help="dataset folder (dataset.json + runs/*.csv, see docs/formats.md)")
    gp.add_argument("--out", required=True, help="report folder (result.json, report.md, plots)")
    gp.add_argument("--json", action="store_true", help="print result.json")
    gp.add_argument("--seed", type=int, default=0, help="seed (>= 0) of folds, designs and bootstraps")
    gp.add_argument("--no-plots", action="store_true", help="skip the plots")
    gp.add_argument("--max-effects", type=int, default=3,
                    help="most effects named one after another (each step searches the gap left by the last; "
                         "1: name one effect only)")
    gp.add_argument("--fit-budget", type=float, default=None, metavar="SECONDS",
                    help=f"most robot time fitted [s] (default {FIT_BUDGET:g}, at least {MIN_FIT_BUDGET:g}); a "
                         "longer dataset is fitted on an even sample of segments of every run, each "
                         f"SECONDS / runs long ({MIN_SEGMENT:g} to {SEGMENT:g} s; 24 runs and the default: 5 s) "
                         "and replayed from the tracked state at its start; inf: always whole runs")
    gp.add_argument("--start", choices=("auto", "kinematic", "tracker", "nominal"), default="auto",
                    help="first model, on top of which effects are searched: auto (default): the dataset's model, "
                         "with the kinematic odometry calibration (as omni-gym calibrate) competing with the "
                         "library's effects at the first step when every run has wheel odometry; kinematic = start "
                         "from the calibration; tracker = start from the calibration with the tracked frame fitted "
                         "jointly over whole runs (as omni-gym calibrate --tracker; faster, see docs/discrepancy.md); "
                         "nominal = the dataset's model, no calibration")
    add_ray_option(gp, "the candidate fits", "all (or --jobs N > 1)")
    gp.add_argument("--jobs", type=int, default=1,
                    help="local worker processes for the candidate fits, at most this machine's cores (with "
                         "--ray and no ADDRESS: the local Ray's CPUs); default 1, this process")
    _add_force_option(gp, "an existing report folder")
    gp.set_defaults(handler=_cmd_gap)
    sc = sub.add_parser("score", help="replay a dataset's runs open loop with its nominal model and other models; "
                                      "position RMS against the tracked poses (check a calibrated model on new runs)")
    sc.add_argument("dataset", help="dataset folder (dataset.json + runs/*.csv, see docs/formats.md)")
    sc.add_argument("--model", action="append", default=[], metavar="MODEL",
                    help="a model to compare with the dataset's nominal model: preset name or model JSON file "
                         "(e.g. a gap report's model.json); repeatable")
    sc.add_argument("--linear-map-from", metavar="TRAINING_DATASET", default=None,
                    help="also score a linear wheel-to-twist map (3 x n, the best a purely kinematic description "
                         "can do) fitted on this dataset's runs (wheel encoders needed); a model should beat it")
    sc.add_argument("--json", action="store_true", help="print per-run scores and means as JSON")
    sc.set_defaults(handler=_cmd_score)
    sy = sub.add_parser("synth", help="write a dataset with a hidden effect (truth to DATASET.truth.json)")
    sy.add_argument("--model", required=True, help="nominal model: preset name or model JSON file")
    _add_model_options(sy)
    sy.add_argument("--hidden", required=True, help="EFFECT[:JSON params], none, or viscous_drag[:{\"c\": N.s/m}]")
    sy.add_argument("--runs", type=int, default=10, help="number of runs")
    sy.add_argument("--duration", type=float, default=5.0, help="seconds per run")
    sy.add_argument("--noise", type=float, default=0.001, help="tracker noise sigma [m] (heading: sigma / lever)")
    sy.add_argument("--seed", type=int, default=0, help="seed of maneuvers, noise and random effects")
    sy.add_argument("--observe", choices=("all", "end"), default="all", help="track every row or only end points")
    sy.add_argument("--out", required=True, help="dataset folder to write")
    _add_force_option(sy, "an existing dataset folder and its DATASET.truth.json")
    sy.set_defaults(handler=_cmd_synth)
    im = sub.add_parser("import", help="write a dataset from another log format (ROS 2 bags, CSV logs, OptiOdom "
                                       "sessions; docs/formats.md)")
    im.add_argument("format", choices=sorted(IMPORT_FORMATS), help="log format: rosbag2, csv or optiodom")
    im.add_argument("sessions", nargs="+", metavar="INPUT",
                    help="rosbag2: bag folder(s), one run each; csv: CSV file(s), one run each; optiodom: session "
                         "folder(s) of one robot with <id>_metadata.csv and <id>_run-NN.csv[.gz]")
    im.add_argument("--out", required=True, help="dataset folder to write")
    im.add_argument("--mass", type=float, default=None, help="optiodom: assumed robot mass [kg] (not published; "
                    "default and why in docs/formats.md, 'Importing OptiOdom logs')")
    im.add_argument("--inertia", type=float, default=None,
                    help="optiodom: assumed yaw inertia [kg·m²] (default 0.5·mass·ρ², ρ the wheel centres' distance)")
    im.add_argument("--time-base", choices=("auto", "tracker", "file"), default=None,
                    help="optiodom: auto (default): each run on the tracker's clock from the metadata's "
                         "synchronisation window, where there is one; file: the time column as written "
                         "(docs/formats.md, 'The time base')")
    im.add_argument("--surface", choices=sorted(SURFACES), default=None,
                    help="floor preset of the nominal model (optiodom default grip: no slip, as kinematic odometry "
                         "assumes; csv, rosbag2: overrides the --model's)")
    lg = im.add_argument_group("csv and rosbag2 (docs/formats.md, 'Importing ROS 2 bags and CSV logs')")
    lg.add_argument("--model", help="nominal model: preset name or model JSON file (required)")
    lg.add_argument("--mapping", help="JSON file with any of these options (keys as the option names, with _), "
                                      "e.g. {\"joints\": \"fl,-fr,rear\", \"pose_topic\": \"/mocap/pose\"}")
    lg.add_argument("--units", default=None, help="log units, e.g. mm,deg,ms,wheel=rev (default m, rad, s)")
    lg.add_argument("--window", action="append", metavar="[NAME=]START:END",
                    help="one run per window [s from the first wheel sample] of each input (repeatable)")
    lg.add_argument("--max-gap", type=float, default=None,
                    help="pose samples further apart [s] leave the rows between unobserved (default 0.25)")
    lg.add_argument("--columns", help="csv: NAME=COLUMN pairs t,x,y,theta and enc1…encn (or w1…wn); -COLUMN flips a "
                                      "wheel")
    lg.add_argument("--joints", help="rosbag2: one joint per model wheel in model order; -NAME flips a wheel")
    lg.add_argument("--joint-topic", default=None, help="rosbag2: JointState topic (default /joint_states)")
    lg.add_argument("--wheel-field", choices=("position", "velocity"), default=None,
                    help="rosbag2: JointState field of the wheels (default position)")
    lg.add_argument("--pose-topic", help="rosbag2: PoseStamped, PoseWithCovarianceStamped, Odometry or tf topic")
    lg.add_argument("--frames", help="rosbag2: PARENT:CHILD of the tracked transform (tf topics; checks the parent "
                                     "frame of the others)")
    lg.add_argument("--command-topic", help="rosbag2: wheel commands (JointState velocities, or Float64MultiArray in "
                                            "--joints order); rows are then the commands")
    _add_force_option(im, "an existing dataset folder")
    im.set_defaults(handler=_cmd_import)
    ca = sub.add_parser("calibrate", help="kinematic odometry calibration of a dataset with wheel odometry (wheel "
                                          "diameters and L, or l1 + l2 for mecanum wheels) -> a model JSON")
    ca.add_argument("dataset", help="dataset folder with enc1…encn columns (e.g. from omni-gym import optiodom)")
    ca.add_argument("--out", required=True, help="model JSON to write (the nominal model with the fitted values)")
    ca.add_argument("--tracker", action="store_true",
                    help="also fit the tracked frame (the tracked point's offset from the wheel centre and its yaw) "
                         "with the kinematics, written as a tracker_offset effect (a measurement effect: score and "
                         "gap apply it; the physics is unchanged)")
    _add_force_option(ca, "an existing --out file")
    ca.set_defaults(handler=_cmd_calibrate)
    xp = sub.add_parser("export", help="a trained agent -> ONNX (and TorchScript) with its observation "
                                       "normalisation and a JSON sidecar, for the robot's computer")
    xp.add_argument("policy", help="model directory, RL Zoo folder, SB3 .zip or RLlib model (as evaluate --policy)")
    xp.add_argument("--out", required=True, help="folder to write: policy.onnx, policy.json[, policy.pt]")
    xp.add_argument("--env", default=None, help="environment id (default: the one the model records)")
    xp.add_argument("--env-kwargs", default=None, help="JSON keywords of the environment (e.g. its model=)")
    xp.add_argument("--torchscript", action="store_true", help="also write policy.pt (TorchScript)")
    xp.add_argument("--trust-pickle", action="store_true",
                    help="open a model that is a Python pickle (an SB3 .zip, an RLlib checkpoint, ...): as evaluate "
                         "--trust-pickle, only for a file from someone you trust (docs/security.md)")
    _add_force_option(xp, "an existing export folder")
    xp.set_defaults(handler=_cmd_export)
    # Further subcommands register here with their own set_defaults(handler=...).
    return parser


def _add_force_option(p: argparse.ArgumentParser, what: str) -> None:
    p.add_argument("--force", action="store_true",
                   help=f"replace {what} (default: refuse; the output appears complete or not at all, "
                        "see docs/formats.md)")


def _foreign_agents() -> str | None:
    """None when ``import agents`` finds omni-gym's package; else the one-line message saying whose it is.

    The OpenAI Agents SDK (``openai-agents``) installs a top-level ``agents`` package too; with both
    installed Python finds one of them, and train/evaluate must say so rather than fail on a missing module.
    """
    try:
        import agents
    except ImportError as exc:
        return f"omni-gym's 'agents' package cannot be imported ({exc}); reinstall omni-gym"
    if getattr(agents, "OMNI_GYM_AGENTS", False):
        return None
    where = getattr(agents, "__file__", None) or ", ".join(getattr(agents, "__path__", [])) or "?"
    return (f"the package 'agents' that Python imports ({where}) is not omni-gym's: another distribution (e.g. the "
            "OpenAI Agents SDK, openai-agents) installs one of the same name; train and evaluate need omni-gym's, "
            "so keep the other in a separate virtual environment")


def _require_our_agents() -> None:
    problem = _foreign_agents()
    if problem is not None:
        raise ValueError(problem)


def _add_train_options(p: argparse.ArgumentParser) -> None:
    if _foreign_agents() is not None:  # the other commands must still work; the handler says what is wrong
        p.prefix_chars = "\0"  # no options: every word after "train" lands in "rest", unchecked
        p.add_argument("rest", nargs="*")
        return
    from agents.train import build_arg_parser  # argparse only; the heavy imports happen in the handler

    build_arg_parser(p)


def check_option(option: str, value) -> None:
    """Refuse a command-line value outside its bound in ``bounds.CLI`` (one line naming the option)."""
    bound = CLI_BOUNDS[option]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not bound.contains(value):
        raise ValueError(f"{option} {bound.describe()}, got {value!r}")


def _cmd_train(args: argparse.Namespace) -> int:
    _require_our_agents()
    from agents.options import check_backend_args, check_train_args
    from agents.train import command_line, run_from_args

    check_train_args(args)  # before the command line is spelled out (it rounds --timesteps)
    check_backend_args(args)
    if args.backend == "rllib":
        from agents.rllib.train import run_from_args
    try:
        meta = run_from_args(args, command_line("omni-gym train", args))
    except ImportError as exc:  # a missing extra: one line naming it (agents.require_agents_extra)
        raise ValueError(str(exc)) from None
    best = meta.get("best") or {}
    rmse = best.get("val_tracking_rmse")
    note = f"; best validation tracking RMSE {rmse:.4f} m at {best['timesteps']} steps" if rmse is not None else ""
    print(f"trained {meta['timesteps']} steps in {meta['wall_time_s']:.0f} s{note} -> {args.out}")
    return 0


def _cmd_model_show(args: argparse.Namespace) -> int:
    from omni_gym.physics.model import load_model

    model = load_model(args.name, args.surface, args.friction)
    data = model.to_json()
    if args.json:
        print(json.dumps(data, indent=2))
        return 0
    r = model.robot
    print(f"{r.name}: {r.n_wheels} wheels, r = {r.wheel_radius} m, m = {r.mass} kg, I = {r.inertia:.5g} kg·m²")
    print(f"  friction {model.friction} on {model.surface.name}: mu_drive {model.surface.mu_drive}, "
          f"mu_transverse {model.surface.mu_transverse}, mu_gap {model.surface.mu_gap}, k {model.surface.k}")
    for i, w in enumerate(r.wheels, start=1):
        print(f"  wheel {i}: position ({w.position[0]:+.4f}, {w.position[1]:+.4f}) m, "
              f"drive ({w.drive[0]:+.4f}, {w.drive[1]:+.4f})")
    for key, why in r.assumptions.items():
        print(f"  assumption {key}: {why}")
    if not model.effects:
        print("  effects: none")
    for name, params in model.effects.items():
        print(f"  effect {name}:")
        for key, line in _effect_param_lines(name, params):
            print(f"    {key} = {line}")
    return 0


def _effect_param_lines(name: str, params: dict) -> list[tuple[str, str]]:
    """(parameter, "value unit") of one model effect (units from omni_gym.discrepancy.fit.plausible)."""
    from omni_gym.discrepancy.fit.plausible import UNITS

    units = UNITS.get(name, {})
    out = []
    for key, value in params.items():
        text = ("[" + ", ".join(f"{float(v):.6g}" for v in value) + "]" if isinstance(value, (list, tuple))
                else f"{float(value):.6g}")
        out.append((key, f"{text} {units.get(key, '')}".rstrip()))
    return out


def _cmd_simulate(args: argparse.Namespace) -> int:
    from omni_gym.outputs import Output

    # Checked and locked before the work; an output that is an input (commands, model file) is refused.
    with Output(args.out, "file", force=args.force, inputs=[args.commands, args.model], what="trajectory CSV") as tx:
        return _simulate_into(args, tx.path)


def _simulate_into(args: argparse.Namespace, out) -> int:
    """The simulation of ``omni-gym simulate``, written to ``out`` (the transaction's temporary file)."""
    from omni_gym.io import TRAJECTORY_HEADER, read_commands, write_csv_atomic
    from omni_gym.physics import effects as effect_library
    from omni_gym.physics.model import Actuation, load_model
    from omni_gym.physics.replay import simulate_commands
    from omni_gym.physics.world import DEFAULT_DT

    dt = DEFAULT_DT if args.dt is None else args.dt
    check_option("--dt", dt)
    check_option("--seed", args.seed)
    model = load_model(args.model, args.surface, args.friction)
    if tracker := [name for name in model.effects if effect_library.get(name).kind == "tracker"]:
        # One line, so that nobody compares this with tracked poses and loses what the tracker part explains.
        print(f"omni-gym simulate: note: {args.model} has a tracker part ({', '.join(tracker)}); it describes "
              "how a pose tracker measures the robot, not how the robot moves, so this trajectory leaves it out "
              "(the body's physics only); `omni-gym score DATASET --model MODEL` applies it when comparing "
              "with tracked runs", file=sys.stderr)
    times, commands = read_commands(args.commands, model.n_wheels)
    from omni_gym.discrepancy.data.units import check_wheel_commands

    check_wheel_commands(args.commands, commands, model.robot.wheel_radius)  # rim speed bound (bounds.py)
    substeps = CLI_BOUNDS["run duration / --dt"]
    if not substeps.contains(round(times[-1] / dt)):
        raise ValueError(f"--dt {dt:g} s: the commands in {args.commands} last {times[-1]:g} s, "
                         f"{times[-1] / dt:.3g} substeps; at most {substeps.hi:.3g} are allowed "
                         f"(a few minutes): use a larger --dt or a shorter run")
    states = simulate_commands(model, times, commands, dt=dt, actuation=Actuation(kind=args.actuation),
                               seed=args.seed)
    bad = np.nonzero(~np.all(np.isfinite(states), axis=1))[0]
    if bad.size:  # never write a non-finite number: refuse instead
        raise ValueError(f"simulate: the state became non-finite at t = {times[bad[0]]:g} s "
                         f"(row {int(bad[0]) + 2} of {args.commands}); nothing written to {args.out}")
    write_csv_atomic(out, TRAJECTORY_HEADER, np.column_stack([times, states]))
    return 0


def _cmd_evaluate(args: argparse.Namespace) -> int:
    _require_our_agents()
    from agents.evaluate import DEFAULT_SEED, check_policy_name, compare, evaluate, format_comparison, format_table
    from agents.options import check_evaluate_args, parse_env_kwargs
    from agents.sb3_policy import ModelOptions

    if args.seed is None:
        args.seed = DEFAULT_SEED
    check_evaluate_args(args)
    options = ModelOptions(args.algo, args.wrapper, args.residual_scale, args.vecnormalize, args.trust_pickle)
    kwargs = parse_env_kwargs(args.env_kwargs) or {}
    try:
        if args.against is not None:  # a typo in the second policy fails before the first runs
            try:
                check_policy_name(args.against)
            except ValueError as exc:
                raise ValueError(f"--against: {exc}") from None
        plant = _plant_factory(args)
        result = evaluate(args.policy, args.env, args.episodes, args.seed, kwargs, model_options=options, plant=plant)
        other = None if args.against is None else evaluate(args.against, args.env, args.episodes, args.seed, kwargs,
                                                           model_options=ModelOptions(trust_pickle=args.trust_pickle),
                                                           plant=plant)
        if plant is not None:
            for res in (result, other):
                if res is not None:
                    res["plant"] = {"kind": args.plant, "model": _record_path(args.plant_model),
                                    "extra": _plant_extra(args)}
        anchors = _score_anchors(args, kwargs, result, other) if args.score else None
    except ImportError as exc:  # a missing extra: one line naming it (agents.require_agents_extra)
        raise ValueError(str(exc)) from None
    if "model" in kwargs and "kinematics" not in kwargs and args.env.rpartition(":")[2] != "OmniPathFollow-Custom-v0":
        print(f"note: {args.env} with model= keeps the robot preset's nominal kinematics; add "
              "\"kinematics\": \"model\" to --env-kwargs for the model's calibrated wheel matrix "
              "(OmniPathFollow-Custom-v0's default)", file=sys.stderr)
    out, blocks = dict(result), [format_table(result)]
    if other is not None:
        cmp = compare(result, other)
        out.update(against=other, comparison=cmp)
        blocks += [format_table(other), format_comparison(result, other, cmp)]
    if anchors is not None:
        from agents.normalised_score import score_results

        for res, where in ((result, out), (other, out.get("against"))):
            if res is not None:
                sc = score_results(res, *anchors)
                where["score"] = sc.to_dict()
                blocks.append(f"{res['policy']}: {sc.text()}")
    print(json.dumps(out) if args.json else "\n\n".join(blocks))
    return 0


PLANTS = ("second-generator", "simulator")


def _record_path(path: str | None) -> str | None:
    """A path as a result records it: its file name only (no machine's folders in a record)."""
    return None if path is None else os.path.basename(path)


def _plant_extra(args: argparse.Namespace) -> dict | None:
    """``--plant-extra`` as an object (effects outside the library), checked to be one."""
    if args.plant_extra is None:
        return None
    if args.plant != "second-generator":
        raise ValueError("--plant-extra: only the second-generator plant takes effects outside the library")
    from omni_gym.io import parse_json

    extra = parse_json(args.plant_extra, "--plant-extra")
    if not isinstance(extra, dict):
        raise ValueError(f"--plant-extra: expected a JSON object {{effect: params}}, got {type(extra).__name__}")
    return extra


def _plant_factory(args: argparse.Namespace):
    """``plant(core) -> Plant`` from ``--plant``, ``--plant-model`` and ``--plant-extra`` (None: no plant). The
    model file and extra effects are read and checked here, before any episode runs."""
    if args.plant is None:
        for name in ("plant_model", "plant_extra"):
            if getattr(args, name) is not None:
                raise ValueError(f"--{name.replace('_', '-')} needs --plant")
        return None
    from omni_gym.envs.config import parse_model

    model = None if args.plant_model is None else parse_model(args.plant_model)
    extra = _plant_extra(args)
    if args.plant == "simulator":
        return lambda core: core.simulator_plant(model)
    from omni_gym.analysis.closed_loop import SecondGeneratorPlant
    from omni_gym.analysis.event_integrator import check_effects

    if extra is not None and model is not None:
        check_effects(extra, model)

    def second_generator(core):
        truth = model if model is not None else core.base_model
        if extra is not None:
            check_effects(extra, truth)
        return SecondGeneratorPlant(truth, extra)

    return second_generator


def _score_anchors(args: argparse.Namespace, kwargs: dict, *done: dict | None) -> tuple[dict, dict]:
    """The open-loop and ekf-pid results on the seeds and keywords of ``args``; a policy already evaluated
    (``--policy ekf-pid``) is reused, not run twice."""
    from agents.evaluate import evaluate
    from agents.normalised_score import ANCHORS

    ran = {r["policy"]: r for r in done if r is not None}
    # The anchors read sensors and command twists; only the physical keywords (condition, randomisation)
    # carry over from a model's evaluation.
    physical = {k: v for k, v in kwargs.items() if k not in ("obs_mode", "action_mode")}
    return tuple(ran[a] if a in ran else evaluate(a, args.env, args.episodes, args.seed, physical)  # type: ignore
                 for a in ANCHORS)


def _cmd_gap(args: argparse.Namespace) -> int:
    from omni_gym.outputs import Output

    # Refuse a bad --out in a fraction of a second, before the slow imports and the work.
    Output(args.out, "dir", force=args.force, inputs=[args.dataset], marker="result.json",
           what="gap report").preflight()
    from omni_gym.discrepancy.workflow import gap

    check_option("--seed", args.seed)
    check_option("--max-effects", args.max_effects)
    check_option("--jobs", args.jobs)
    budget = {} if args.fit_budget is None else {"fit_budget": args.fit_budget}
    if args.fit_budget is not None:
        check_fit_budget(args.fit_budget, "--fit-budget")
    jobs = args.jobs
    cores = usable_cores()
    if args.ray is None and jobs > cores:  # more processes than cores only share them (same result, more memory)
        print(f"omni-gym: warning: --jobs {jobs} is more than the {cores} core{'s' * (cores > 1)} this process may "
              f"use; running {cores} local process{'es' * (cores > 1)}", file=sys.stderr)
        jobs = cores
    # ray missing, an address nothing listens on: one line now (BackendError: ValueError), not after the first stages
    backend = backend_from_options(jobs, args.ray)
    result = gap(args.dataset, args.out, seed=args.seed, plots=not args.no_plots, force=args.force,
                 max_effects=args.max_effects, backend=backend, start=args.start, **budget)
    if args.json:
        print(json.dumps(result, indent=2, allow_nan=False))  # standard JSON (non-finite values are null)
    else:
        g = result["gap"]

        def mm(v: float | None) -> str:
            return "-" if v is None else f"{1e3 * v:.2f}"

        print(f"effect: {result['effect']} ({result['why']})")
        for st in result["steps"][1:]:  # the effects named after the first, and the answer that ended the search
            print(f"then: {st['effect']} ({st['why']})")
        print(f"held-out gap beyond noise: {mm(g['before'])} mm -> {mm(g['after'])} mm"
              + (f" with {' + '.join(result['effects'])}" if len(result["effects"]) > 1 else "")
              + f"; report: {args.out}/report.md")
        flags = result["plausibility"]["flags"]
        if flags:
            print("implausible: " + "; ".join(
                f"{f['param']} = {f['value']:.4g} outside [{f['lo']:.4g}, {f['hi']:.4g}]" for f in flags))
        rows = result["outliers"]["rows"]
        if rows:
            print(f"tracker outliers excluded: {len(rows)} row(s) (" + ", ".join(
                f"{o['run']} row {o['row']}" for o in rows[:5]) + (", ..." if len(rows) > 5 else "") + ")")
    return 0


def _cmd_score(args: argparse.Namespace) -> int:
    from dataclasses import asdict

    from omni_gym.discrepancy.data.dataset import load_dataset
    from omni_gym.discrepancy.decide.score import score_models, summary
    from omni_gym.physics.model import load_model

    ds = load_dataset(args.dataset)
    models = {"nominal": ds.model}
    for path in args.model:
        models[path] = load_model(path, None, None)
    maps = {}
    if args.linear_map_from is not None:
        from omni_gym.discrepancy.fit.linear_map import fit_linear_map

        train = load_dataset(args.linear_map_from)
        if train.n_wheels != ds.n_wheels:
            raise ValueError(f"--linear-map-from {args.linear_map_from}: {train.n_wheels} wheels, the dataset "
                             f"{args.dataset} has {ds.n_wheels}")
        lm = fit_linear_map(train.runs, train.model)
        maps[f"linear map ({lm.runs} runs of {args.linear_map_from})"] = lm
    scores = score_models(ds, models, linear_maps=maps)
    means = summary(scores)
    if args.json:
        from omni_gym.discrepancy.report.finite import finite_json

        clean, _ = finite_json({"runs": [asdict(s) for s in scores], "models": means,
                                "note": "open-loop replay from each run's start pose; lengths in m, angles in "
                                        "rad; heading_offset, yaw_scale and refit_position_rms: the per-run "
                                        "refit (null where a run has too few tracked rows)"})
        print(json.dumps(clean, indent=2, allow_nan=False))
        return 0
    width = max(len(n) for n in [*models, *maps])
    print(f"{'run':<28s} {'model':<{width}s} {'s':>6s} {'pos RMS [mm]':>13s} {'final [mm]':>11s} "
          f"{'refit: heading [deg]':>21s} {'yaw scale':>10s} {'pos RMS [mm]':>13s}")
    for sc in scores:
        print(f"{sc.run:<28s} {sc.model:<{width}s} {sc.seconds:6.1f} {1e3 * sc.position_rms:13.1f} "
              f"{1e3 * sc.final_error:11.1f} {math.degrees(sc.heading_offset):21.2f} {sc.yaw_scale:10.3f} "
              f"{1e3 * sc.refit_position_rms:13.1f}")
    for name, m in means.items():
        print(f"over {m['runs']} runs, {name}: position RMS mean {1e3 * m['mean_position_rms']:.1f} mm (median "
              f"{1e3 * m['median_position_rms']:.1f}, {1e3 * m['min_position_rms']:.1f}-"
              f"{1e3 * m['max_position_rms']:.1f}, sd {1e3 * m['std_position_rms']:.1f}), final error "
              f"{1e3 * m['mean_final_error']:.1f} mm; after a per-run heading refit "
              f"{1e3 * m['mean_refit_position_rms']:.1f} mm (offsets sd {math.degrees(m['std_heading_offset']):.2f} "
              f"deg, yaw scales sd {m['std_yaw_scale']:.3f})")
    print("refit: the initial heading offset and yaw-rate scale that bring each replay closest to its run, and "
          "the error left: run-to-run variation no model of the robot predicts")
    return 0


def _cmd_synth(args: argparse.Namespace) -> int:
    from omni_gym.outputs import Output

    # Refuse a bad --out before the slow imports; write_synthetic checks again (with the truth file).
    Output(args.out, "dir", force=args.force, inputs=[args.model], marker="dataset.json", what="dataset").preflight()
    from omni_gym.discrepancy.synthetic.synth import truth_path, write_synthetic
    from omni_gym.physics.model import load_model

    check_option("--seed", args.seed)
    model = load_model(args.model, args.surface, args.friction)
    write_synthetic(args.out, model, args.hidden, args.runs, args.noise, args.seed, args.duration, args.observe,
                    force=args.force, inputs=(args.model,))
    print(f"wrote {args.out} ({args.runs} runs); truth in {truth_path(args.out)}")
    return 0


def _cmd_import(args: argparse.Namespace) -> int:
    from omni_gym.outputs import Output

    # Refuse a bad --out before reading the logs; the importers check again under the lock.
    Output(args.out, "dir", force=args.force, inputs=args.sessions, marker="dataset.json", what="dataset").preflight()
    from omni_gym.discrepancy.data.importers.options import refuse_foreign_options

    refuse_foreign_options(args)  # an option of another format is refused, never ignored
    if args.format != "optiodom":
        from omni_gym.discrepancy.data.importers.options import import_logs

        print("\n".join(import_logs(args)))
        return 0
    from omni_gym.discrepancy.data.importers import optiodom

    surface = optiodom.SURFACE if args.surface is None else args.surface
    # mass None: the default of the sessions' robot type (omni3 8 kg, omni4 4 kg; docs/formats.md)
    s = optiodom.import_optiodom(args.sessions, args.out, force=args.force, mass=args.mass, inertia=args.inertia,
                                 surface=surface, time_base=args.time_base or "auto")
    print(f"imported {s.runs} runs from {len(s.sessions)} session(s), {s.duration:.1f} s of robot time "
          f"(assumed: mass {s.mass:g} kg, inertia {s.inertia:.4g} kg·m², surface {s.surface}) -> {s.out}")
    print(s.time_base)
    for note in s.notes:
        print(note)
    return 0


def _cmd_export(args: argparse.Namespace) -> int:
    _require_our_agents()
    from agents.export import export
    from agents.options import parse_env_kwargs
    from agents.sb3_policy import ModelOptions

    side = export(args.policy, args.out, args.env, parse_env_kwargs(args.env_kwargs),
                  options=ModelOptions(trust_pickle=True) if args.trust_pickle else None,
                  torchscript=args.torchscript, force=args.force)
    files = "policy.onnx, policy.json" + (", policy.pt" if args.torchscript else "")
    print(f"exported {args.policy} -> {args.out} ({files}): observation {side['observation']['mode']} "
          f"({side['input']['shape'][1]} values), action {side['action']['mode']}, control period "
          f"{side['control_period_s']:g} s; onnxruntime matches the policy within "
          f"{side['parity']['max_abs_difference']:.1e} on {side['parity']['observations']} observations")
    return 0


def _cmd_calibrate(args: argparse.Namespace) -> int:
    from omni_gym.discrepancy.fit.calibrate import calibrate_dataset, summary_lines

    cal, checks = calibrate_dataset(args.dataset, args.out, force=args.force, tracker=args.tracker)
    print("\n".join(summary_lines(cal, args.out, checks)))
    return 0


# What bad input raises on its way through the handlers (the standard library's int/float/JSON parsers,
# numpy, file access): each is one line and status 2. OverflowError: a number too large for a float or
# a C integer (e.g. a 400-digit value).
INPUT_ERRORS = (ValueError, OSError, OverflowError)


def _interrupted() -> int:
    print(INTERRUPTED, file=sys.stderr)
    if is_command_line():  # the way out is done: leave without the interpreter's exit joins
        exit_interrupted()
    return EXIT_INTERRUPTED


def main(argv: list[str] | None = None) -> int:
    restore = main_handler()  # Ctrl-C from here on: rolled back, workers stopped, one line, status 130
    try:
        parser = build_parser()
        args = parser.parse_args(argv)
        from omni_gym.io import input_limit_mb

        with input_limit_mb(args.max_input_mb):  # for this command only (main() may be called again)
            return args.handler(args)
    except INPUT_ERRORS as exc:
        if restore.interrupted:  # an error on the interrupt's way out, not bad input
            return _interrupted()
        from omni_gym.io import printable

        # one line, whatever the source; control characters (an escape sequence in a file's name or content) escaped
        message = printable(" ".join(str(exc).split()))
        print(f"omni-gym: error: {message}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        return _interrupted()
    except Exception:
        if restore.interrupted:  # the interrupt, re-raised as another type by a library (numba's imports)
            return _interrupted()
        raise
    finally:
        restore()


if __name__ == "__main__":
    sys.exit(main())
