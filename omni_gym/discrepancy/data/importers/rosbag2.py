"""Import ROS 2 bags (``omni-gym import rosbag2``): wheel joints + a tracked pose → a dataset.

Reads rosbag2 recordings (SQLite3 ``.db3`` or MCAP storage) with the pure-Python reader ``rosbags`` (the
optional extra ``ros``: ``pip install -e '.[ros]'`` from the checkout's root; no ROS installation needed):

* **Wheels**: ``sensor_msgs/msg/JointState`` on ``--joint-topic`` (default ``/joint_states``); ``--joints``
  names one joint per model wheel, in the model's wheel order, a leading ``-`` flipping its sign;
  ``--wheel-field position`` (wheel angles, default) or ``velocity`` (wheel speeds). Messages that lack
  one of the joints are skipped (a robot may publish its joints in several messages).
* **Pose**: ``--pose-topic`` of type ``geometry_msgs/msg/PoseStamped``, ``PoseWithCovarianceStamped``,
  ``nav_msgs/msg/Odometry`` or ``tf2_msgs/msg/TFMessage`` (``/tf``: the transform ``--frames PARENT:CHILD``);
  the heading is the yaw of the orientation quaternion.
* **Wheel commands** (optional, ``--command-topic``): what the robot was told, ``JointState`` velocities
  [rad/s] by the same joint names, or a ``std_msgs/msg/Float64MultiArray`` in ``--joints`` order (no header:
  stamped by the bag's arrival time, which the description says). The rows are then the commands, each held
  until the next; the JointState wheel angles become ``enc`` (interpolated at the command times).
* **Times** are the messages' header stamps (when the sensor measured), never the bag's arrival times;
  the run starts at the first wheel sample with a tracked pose. Stamps must be strictly increasing per
  topic (a zero stamp, i.e. never set, is refused).

Each bag is one run (named after the bag folder), or each ``--window`` of each bag is one. The conversion
to dataset rows is :func:`~omni_gym.discrepancy.data.importers.logs.make_run`. Every error is one line
naming the bag and the topic (and the joint or message where it applies).
"""

from __future__ import annotations

import math
import struct
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from omni_gym.discrepancy.data.importers.logs import (
    PoseLog,
    Units,
    WheelLog,
    Window,
    check_increasing,
    check_moving,
    make_run,
    write_imported,
)
from omni_gym.io import InputError, excerpt, printable
from omni_gym.physics.model import SimModel

MISSING = ("omni-gym import rosbag2 needs the optional package 'rosbags': pip install -e '.[ros]' (from the omni-gym "
           "checkout's root)")
JOINT_STATE = "sensor_msgs/msg/JointState"
MULTI_ARRAY = "std_msgs/msg/Float64MultiArray"
POSE_TYPES = ("geometry_msgs/msg/PoseStamped", "geometry_msgs/msg/PoseWithCovarianceStamped",
              "nav_msgs/msg/Odometry", "tf2_msgs/msg/TFMessage")
MAX_MESSAGES = 50_000_000  # per topic: 58 days at 10 Hz; a longer read is refused rather than filling memory


@dataclass(frozen=True)
class BagMap:
    """How a bag maps onto the model: ``joints`` ((name, sign) per model wheel), ``joint_topic``,
    ``wheel_field`` ("position" or "velocity"), ``pose_topic``, ``frames`` ((parent, child) for ``/tf``
    topics, else None)."""

    joints: tuple[tuple[str, float], ...]
    joint_topic: str = "/joint_states"
    wheel_field: str = "position"
    pose_topic: str = "/pose"
    frames: tuple[str, str] | None = None
    command_topic: str | None = None

    def describe(self) -> str:
        joints = ", ".join(f"w{i + 1}={'-' if s < 0 else ''}{j}" for i, (j, s) in enumerate(self.joints))
        frames = f" (transform {self.frames[0]} -> {self.frames[1]})" if self.frames else ""
        command = (f"; wheel commands: {self.command_topic} (JointState velocities by joint, or a Float64MultiArray "
                   "in --joints order stamped by arrival time), each held until the next" if self.command_topic
                   else "")
        return (f"wheels: {self.joint_topic} JointState {self.wheel_field}s, joints {joints}; pose: "
                f"{self.pose_topic}{frames}{command}")


def parse_joints(spec: str, n_wheels: int, option: str = "--joints") -> tuple[tuple[str, float], ...]:
    """``fl,-fr,rear`` → ((name, sign), …), one per model wheel; InputError naming the problem."""
    out = []
    for item in spec.split(","):
        item = item.strip()
        if not item:
            continue
        sign = -1.0 if item.startswith("-") else 1.0
        name = item.lstrip("-").strip()
        if not name:
            raise InputError(f"{option}: an empty joint name")
        out.append((name, sign))
    if len(out) != n_wheels:
        raise InputError(f"{option}: {len(out)} joint(s) given; the model has {n_wheels} wheels (one joint per "
                         "wheel, in the model's wheel order)")
    names = [n for n, _ in out]
    dup = next((n for n in names if names.count(n) > 1), None)
    if dup:
        raise InputError(f"{option}: joint {dup!r} given twice")
    return tuple(out)


def parse_frames(spec: str | None, option: str = "--frames") -> tuple[str, str] | None:
    """``PARENT:CHILD`` → (parent, child) without leading slashes; None if not given."""
    if not spec:
        return None
    parent, sep, child = spec.partition(":")
    if not sep or not parent.strip() or not child.strip():
        raise InputError(f"{option} {spec!r}: expected PARENT:CHILD (e.g. world:base_link)")
    return parent.strip().lstrip("/"), child.strip().lstrip("/")


def _reader(bag: Path):
    """An open-able ``rosbags`` reader of ``bag`` (a rosbag2 folder, or a file inside one)."""
    try:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise InputError(MISSING) from None
    folder = bag.parent if bag.is_file() else bag
    if not folder.is_dir():
        raise InputError(f"{bag}: not found (expected a rosbag2 folder with metadata.yaml)")
    # Bags written without message definitions (older SQLite3 bags) are read with the ROS 2 Humble types.
    return AnyReader([folder], default_typestore=get_typestore(Stores.ROS2_HUMBLE))


# Where a damaged bag's errors come from: rosbags itself, and what it reads with (SQLite3, MCAP, YAML, and the
# zstd of a compressed bag: zstandard, backports.zstd or Python 3.14's compression.zstd).
_READER_MODULES = ("rosbags", "zstandard", "backports", "compression", "zstd", "lz4", "sqlite3", "mcap", "ruamel",
                   "yaml", "zlib", "struct")


def _is_reader_error(exc: BaseException) -> bool:
    """True for an error of reading a damaged or unsupported bag (not a bug of this module)."""
    # RecursionError: a metadata.yaml nested thousands deep (the YAML reader recurses per level)
    return (isinstance(exc, (EOFError, struct.error, zlib.error, UnicodeDecodeError, RecursionError))
            or type(exc).__module__.split(".")[0] in _READER_MODULES)


def _stamp_ns(header) -> int:
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def _yaw(q) -> float:
    """Yaw [rad] of a quaternion (x, y, z, w), rotation about the world z axis."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def _connections(reader, bag: Path, topic: str, types: tuple[str, ...]):
    conns = [c for c in reader.connections if c.topic == topic]
    if not conns:
        have = ", ".join(sorted({f"{c.topic} ({c.msgtype.rsplit('/', 1)[-1]})" for c in reader.connections}))
        raise InputError(f"{bag}: no topic {topic} (the bag has: {printable(have) or 'no topics'})")
    bad = [c.msgtype for c in conns if c.msgtype not in types]
    if bad:
        raise InputError(f"{bag}: topic {topic} is {bad[0]}; expected {' or '.join(types)}")
    return conns


def read_bag(bag: str | Path, bmap: BagMap, units: Units
             ) -> tuple[WheelLog, PoseLog, dict[str, str], WheelLog | None]:
    """The wheel and pose streams of one bag (SI, seconds from the first wheel stamp), what was found
    (``frame``: the pose's header frame) and the wheel-command stream (``--command-topic``, else None).
    InputError naming bag, topic, joint or message."""
    bag = Path(bag)
    folder = bag.parent if bag.is_file() else bag
    if folder.is_dir() and not (folder / "metadata.yaml").is_file():
        raise InputError(f"{bag}: not a rosbag2 folder (no metadata.yaml)")
    try:
        with _reader(bag) as reader:
            wheel = _read_joints(reader, bag, bmap)
            pose, info = _read_pose(reader, bag, bmap)
            command = (None if bmap.command_topic is None
                       else _read_joints(reader, bag, bmap, bmap.command_topic, "velocity"))
    except InputError:
        raise
    except Exception as exc:  # the reader's own errors (a damaged bag, an unknown storage): one line
        if not _is_reader_error(exc):
            raise
        raise InputError(f"{bag}: cannot read the bag ({type(exc).__name__}: {excerpt(ascii(str(exc)), 200)})"
                         ) from None
    t_ns, values = wheel
    where_w = f"{bag}: {bmap.joint_topic}"
    where_p = f"{bag}: {bmap.pose_topic}"
    ref = t_ns[0]
    t_w = (t_ns - ref) * 1e-9
    check_increasing(t_w, where_w)
    p_ns, p = pose
    t_p = (p_ns - ref) * 1e-9
    check_increasing(t_p, where_p)
    signs = np.array([s for _, s in bmap.joints])
    names = tuple(f"{'-' if s < 0 else ''}{j}" for j, s in bmap.joints)
    wheels = WheelLog(t_w, values * signs * units.wheel, bmap.wheel_field, where_w, names)
    check_moving(wheels)
    p = p * np.array([units.length, units.length, 1.0])  # the yaw of a quaternion is in radians
    commands = None
    if command is not None:
        where_c = f"{bag}: {bmap.command_topic}"
        t_c = (command[0] - ref) * 1e-9
        check_increasing(t_c, where_c)
        # wheel units per second (rpm: per minute, already in units.wheel)
        commands = WheelLog(t_c, command[1] * signs * units.wheel, "command", where_c, names)
    return wheels, PoseLog(t_p, p, where_p), info, commands


def _read_joints(reader, bag: Path, bmap: BagMap, topic: str | None = None, field_name: str | None = None
                 ) -> tuple[np.ndarray, np.ndarray]:
    """(stamps [ns], values (K, n) in --joints order) of a JointState topic (default the wheels': --joint-topic
    and --wheel-field), or of a ``std_msgs/msg/Float64MultiArray`` command topic (values in --joints order;
    it has no header: the bag's arrival times stand in for stamps)."""
    topic = topic or bmap.joint_topic
    field_name = field_name or bmap.wheel_field
    conns = _connections(reader, bag, topic, (JOINT_STATE, MULTI_ARRAY) if topic == bmap.command_topic
                         else (JOINT_STATE,))
    wanted = [j for j, _ in bmap.joints]
    stamps: list[int] = []
    rows: list[list[float]] = []
    seen_names: set[str] = set()
    for count, (conn, arrival, raw) in enumerate(reader.messages(connections=conns), start=1):
        if count > MAX_MESSAGES:
            raise InputError(f"{bag}: {topic}: more than {MAX_MESSAGES} messages; import windows of a shorter bag")
        msg = reader.deserialize(raw, conn.msgtype)
        if conn.msgtype == MULTI_ARRAY:
            data = np.asarray(msg.data, dtype=float)
            if data.size != len(wanted):
                raise InputError(f"{bag}: {topic}: message {count}: {data.size} values; --joints names "
                                 f"{len(wanted)} wheels (the command array is read in --joints order)")
            stamps.append(int(arrival))
            rows.append(data.tolist())
            continue
        names = list(msg.name)
        seen_names.update(names)
        if not all(j in names for j in wanted):
            continue
        field = np.asarray(getattr(msg, field_name), dtype=float)
        if field.size != len(names):
            raise InputError(f"{bag}: {topic}: message {count}: {len(names)} joint names but "
                             f"{field.size} {field_name} values")
        stamp = _stamp_ns(msg.header)
        if stamp == 0:
            raise InputError(f"{bag}: {topic}: message {count}: header stamp is zero (not set); "
                             "the import needs the measurement times")
        stamps.append(stamp)
        rows.append([float(field[names.index(j)]) for j in wanted])
    if not rows:
        missing = next((j for j in wanted if j not in seen_names), wanted[0])
        have = printable(", ".join(sorted(seen_names))) or "none"  # names from the bag: escaped
        raise InputError(f"{bag}: {topic}: no message has joint {missing!r} (joints in the bag: {have})")
    values = np.asarray(rows)
    bad = np.nonzero(~np.all(np.isfinite(values), axis=1))[0]
    if bad.size:
        raise InputError(f"{bag}: {topic}: a {field_name} value is NaN or infinite "
                         f"(message with stamp {stamps[int(bad[0])] * 1e-9:.9f} s)")
    return np.asarray(stamps, dtype=np.int64), values


def _read_pose(reader, bag: Path, bmap: BagMap) -> tuple[tuple[np.ndarray, np.ndarray], dict[str, str]]:
    conns = _connections(reader, bag, bmap.pose_topic, POSE_TYPES)
    is_tf = conns[0].msgtype == "tf2_msgs/msg/TFMessage"
    if is_tf and bmap.frames is None:
        raise InputError(f"{bag}: {bmap.pose_topic} is a tf topic: give --frames PARENT:CHILD (e.g. world:base_link)")
    stamps: list[int] = []
    rows: list[tuple[float, float, float]] = []
    frames: set[str] = set()
    pairs: set[str] = set()
    for count, (conn, _arrival, raw) in enumerate(reader.messages(connections=conns), start=1):
        if count > MAX_MESSAGES:
            raise InputError(f"{bag}: {bmap.pose_topic}: more than {MAX_MESSAGES} messages")
        msg = reader.deserialize(raw, conn.msgtype)
        if is_tf:
            items = []
            for tr in msg.transforms:
                pair = (tr.header.frame_id.lstrip("/"), tr.child_frame_id.lstrip("/"))
                pairs.add(f"{pair[0]}:{pair[1]}")
                if pair == bmap.frames:
                    items.append((tr.header, tr.transform.translation, tr.transform.rotation))
        else:
            pose = msg.pose.pose if hasattr(msg.pose, "pose") else msg.pose
            items = [(msg.header, pose.position, pose.orientation)]
        for header, p, q in items:
            stamp = _stamp_ns(header)
            if stamp == 0:
                raise InputError(f"{bag}: {bmap.pose_topic}: message {count}: header stamp is zero (not set)")
            frames.add(header.frame_id)
            stamps.append(stamp)
            rows.append((float(p.x), float(p.y), _yaw(q)))
    if not rows:
        if is_tf:
            raise InputError(f"{bag}: {bmap.pose_topic}: no transform {bmap.frames[0]}:{bmap.frames[1]} (the topic "
                             f"has: {printable(', '.join(sorted(pairs))) or 'none'})")
        raise InputError(f"{bag}: {bmap.pose_topic}: no messages")
    if bmap.frames is not None and not is_tf and bmap.frames[0] not in {f.lstrip("/") for f in frames}:
        raise InputError(f"{bag}: {bmap.pose_topic}: poses are in frame {printable(', '.join(sorted(frames)))}, not "
                         f"{bmap.frames[0]} (--frames)")
    pose = np.asarray(rows)
    if not np.all(np.isfinite(pose)):
        raise InputError(f"{bag}: {bmap.pose_topic}: a pose value is NaN or infinite")
    return (np.asarray(stamps, dtype=np.int64), pose), {"frame": ", ".join(sorted(frames))}


def describe(bags: list[Path], bmap: BagMap, units: Units, frame: str, model_name: str, max_gap: float) -> str:
    """The dataset description: the source and every assumption of the import."""
    what = ("wheel angles; the held command is the mean speed between samples" if bmap.wheel_field == "position"
            else "wheel speeds; the held command is the mean of two samples (trapezoid)")
    # printable: the frame (and names) come from the bag and the description is printed: escape sequences escaped
    return printable(f"imported by omni-gym import rosbag2 from {', '.join(b.name for b in bags)}: {bmap.describe()} "
                     f"({what}); pose frame {frame or '(empty)'}; times are header stamps; units {units.describe()}; "
                     f"the pose is interpolated linearly to the wheel sample times (rows between pose samples more "
                     f"than {max_gap:g} s apart are unobserved); nominal model {model_name}.")


def import_rosbag2(bags: list[str | Path], out: str | Path, model: SimModel, bmap: BagMap, units: Units,
                   windows: list[Window] | None = None, max_gap: float = 0.25, force: bool = False,
                   model_name: str = "") -> tuple[list[str], str]:
    """Import rosbag2 recordings into the dataset folder ``out`` (complete or absent); returns (run names,
    description)."""
    paths = [Path(b) for b in bags]
    if not paths:
        raise InputError("rosbag2: no bag given")
    if len(bmap.joints) != model.n_wheels:
        raise InputError(f"--joints: {len(bmap.joints)} joints; the model has {model.n_wheels} wheels")
    result: dict[str, object] = {}

    def build():
        runs = []
        frames = set()
        for p in paths:
            wheels, pose, info, commands = read_bag(p, bmap, units)
            frames.add(info["frame"])
            for w in windows or [None]:
                stem = p.stem if p.is_dir() else p.parent.stem
                name = stem if w is None else (w.name if len(paths) == 1 else f"{stem}-{w.name}")
                runs.append(make_run(name, wheels, pose, model.robot.wheel_radius, w, max_gap, commands=commands))
        desc = describe(paths, bmap, units, ", ".join(sorted(frames)), model_name or model.robot.name, max_gap)
        result["desc"] = desc
        result["names"] = [r.name for r in runs]
        return model.to_json(), desc, runs

    write_imported(out, paths, force, build)
    return list(result["names"]), str(result["desc"])  # type: ignore[arg-type]
