"""The options of ``omni-gym import csv`` and ``omni-gym import rosbag2`` → an import, and its printed lines.

Kept beside the importers so that the command line only forwards its parsed options; every refusal is a
one-line :class:`~omni_gym.io.InputError` naming the option.
"""

from __future__ import annotations

from argparse import Namespace

from omni_gym.bounds import FILES
from omni_gym.discrepancy.data.importers.logs import parse_units, parse_windows
from omni_gym.io import InputError
from omni_gym.physics.model import load_model

# Options that belong to one format only: given with another format, they would be silently ignored.
ONLY = {"columns": "csv", "joints": "rosbag2", "pose_topic": "rosbag2", "frames": "rosbag2", "command_topic": "rosbag2",
        "mass": "optiodom", "inertia": "optiodom"}


def import_logs(args: Namespace) -> list[str]:
    """Run ``omni-gym import csv|rosbag2`` from parsed options; returns the lines to print (what was written
    and every assumption, also in the dataset's description)."""
    fmt = args.format
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
