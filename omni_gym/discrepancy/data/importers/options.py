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

# Options that belong to some formats only (docs/formats.md): given with another format they would be silently
# ignored, so they are refused (:func:`refuse_foreign_options`).
_LOGS = ("csv", "rosbag2")
ONLY: dict[str, tuple[str, ...]] = {
    "columns": ("csv",),
    **dict.fromkeys(("joints", "joint_topic", "wheel_field", "pose_topic", "frames", "command_topic"), ("rosbag2",)),
    **dict.fromkeys(("model", "mapping", "units", "window", "max_gap"), _LOGS),
    **dict.fromkeys(("mass", "inertia", "time_base"), ("optiodom",)),
}


def refuse_foreign_options(args: Namespace) -> None:
    """InputError (one line) for an option given on the command line that ``import FORMAT`` does not read.

    Call before the defaults are filled in (an option not given is None)."""
    fmt = args.format
    for key, owners in ONLY.items():
        if getattr(args, key, None) is not None and fmt not in owners:
            where = " and ".join(f"'import {o}'" for o in owners)
            raise InputError(f"--{key.replace('_', '-')} applies to {where}, not 'import {fmt}'")


def import_logs(args: Namespace) -> list[str]:
    """Run ``omni-gym import csv|rosbag2`` from parsed options; returns the lines to print (what was written
    and every assumption, also in the dataset's description)."""
    fmt = args.format
    refuse_foreign_options(args)
    _apply_mapping(args)
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
            if args.format not in ONLY.get(key, _LOGS):
                raise InputError(f"{args.mapping}: {key} applies to 'import {' and '.join(ONLY[key])}', not "
                                 f"'import {args.format}'")
            ok = (isinstance(value, list) and all(isinstance(v, str) for v in value) if key == "window"
                  else isinstance(value, (int, float)) and not isinstance(value, bool) if key == "max_gap"
                  else isinstance(value, str))
            if not ok:
                want = {"window": "a list of strings", "max_gap": "a number"}.get(key, "a string")
                raise InputError(f"{args.mapping}: {key}: expected {want}, got {value!r}")
    for key in MAPPING_KEYS:
        if getattr(args, key, None) is None:
            setattr(args, key, mapping.get(key, DEFAULTS.get(key)))
