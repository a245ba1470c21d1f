"""The options of ``omni-gym import csv`` and ``omni-gym import rosbag2`` → an import, and its printed lines.

Kept beside the importers so that the command line only forwards its parsed options; every refusal is a
one-line :class:`~omni_gym.io.InputError` naming the option.
"""

from __future__ import annotations

from argparse import Namespace

from omni_gym.bounds import FILES
from omni_gym.checks import known_keys
from omni_gym.discrepancy.data.importers.logs import parse_units, parse_windows
from omni_gym.io import InputError, read_json
from omni_gym.physics.model import load_model

# --mapping FILE.json: the same settings as the options, for a robot imported often (an option given on the
# command line wins). Values are strings as on the command line; "window" a list of them.
MAPPING_KEYS = ("model", "units", "window", "max_gap", "columns", "joints", "joint_topic", "wheel_field",
                "pose_topic", "frames", "command_topic")
DEFAULTS = {"joint_topic": "/joint_states", "wheel_field": "position", "max_gap": 0.25}

# Options that belong to one format only: given with another format, they would be silently ignored.
ONLY = {"columns": "csv", "joints": "rosbag2", "pose_topic": "rosbag2", "frames": "rosbag2", "command_topic": "rosbag2",
        "mass": "optiodom", "inertia": "optiodom", "time_base": "optiodom"}


def import_logs(args: Namespace) -> list[str]:
    """Run ``omni-gym import csv|rosbag2`` from parsed options; returns the lines to print (what was written
    and every assumption, also in the dataset's description)."""
    fmt = args.format
    _apply_mapping(args)
    for key, owner in ONLY.items():
        if getattr(args, key, None) is not None and owner != fmt:
            raise InputError(f"--{key.replace('_', '-')} applies to 'import {owner}', not 'import {fmt}'")
    if not args.model:
        raise InputError(f"import {fmt}: --model is required (a preset name or a model JSON file: the nominal model "
                         "of the robot that wrote the log)")
    if not (0 < args.max_gap <= FILES["t"].hi):
        raise InputError(f"--max-gap must be > 0 s, got {args.max_gap:g}")
    model = load_model(args.model, surface=args.surface)
    units = parse_units(args.units)
    windows = parse_windows(args.window)
    if fmt == "csv":
        from omni_gym.discrepancy.data.importers.csv_log import import_csv

        if not args.columns:
            raise InputError("import csv: --columns is required (e.g. t=time,x=px,y=py,theta=yaw,enc1=a,enc2=b,enc3=c)")
        names, desc = import_csv(args.sessions, args.out, model, args.columns, units, windows, args.max_gap,
                                 args.force, args.model)
    else:
        from omni_gym.discrepancy.data.importers.rosbag2 import BagMap, import_rosbag2, parse_frames, parse_joints

        if not args.joints or not args.pose_topic:
            raise InputError("import rosbag2: --joints (one joint per model wheel) and --pose-topic are required")
        bmap = BagMap(parse_joints(args.joints, model.n_wheels), args.joint_topic, args.wheel_field,
                      args.pose_topic, parse_frames(args.frames), args.command_topic)
        names, desc = import_rosbag2(args.sessions, args.out, model, bmap, units, windows, args.max_gap,
                                     args.force, args.model)
    return [f"imported {len(names)} run(s) ({', '.join(names)}) -> {args.out}", f"assumptions: {desc}"]


def _apply_mapping(args: Namespace) -> None:
    """Fill the options not given on the command line from ``--mapping`` (then from :data:`DEFAULTS`)."""
    mapping = {}
    if getattr(args, "mapping", None):
        mapping = read_json(args.mapping)
        if not isinstance(mapping, dict):
            raise InputError(f"{args.mapping}: expected an object with keys {', '.join(MAPPING_KEYS)}")
        try:
            known_keys(mapping, MAPPING_KEYS)
        except ValueError as exc:
            raise InputError(f"{args.mapping}: {exc}") from None
        for key, value in mapping.items():
            ok = (isinstance(value, list) and all(isinstance(v, str) for v in value) if key == "window"
                  else isinstance(value, (int, float)) and not isinstance(value, bool) if key == "max_gap"
                  else isinstance(value, str))
            if not ok:
                want = {"window": "a list of strings", "max_gap": "a number"}.get(key, "a string")
                raise InputError(f"{args.mapping}: {key}: expected {want}, got {value!r}")
    for key in MAPPING_KEYS:
        if getattr(args, key, None) is None:
            setattr(args, key, mapping.get(key, DEFAULTS.get(key)))
