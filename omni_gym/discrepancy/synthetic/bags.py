"""Write rosbag2 recordings of simulated runs with ``rosbags``' writer (the optional extra ``ros``): the
known-truth bags of the import tests, the walkthrough test and ``benchmarks/import_speed.py``.

A run's wheel angles [rad] become ``sensor_msgs/JointState`` messages (joint names of our choosing, with a
sign per joint), its tracked pose ``geometry_msgs/PoseStamped`` (or ``nav_msgs/Odometry`` or ``/tf``)
messages; header stamps are the measurement times, the bag's arrival times lag them by a random delay
(so a reader that used arrival times would be off).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

EPOCH_NS = 1_700_000_000 * 1_000_000_000  # header stamps start here (a realistic wall-clock time)


def _typestore():
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_HUMBLE)


def _time(ts, ns: int):
    return ts.types["builtin_interfaces/msg/Time"](sec=int(ns // 1_000_000_000), nanosec=int(ns % 1_000_000_000))


def _header(ts, ns: int, frame: str):
    return ts.types["std_msgs/msg/Header"](stamp=_time(ts, ns), frame_id=frame)


def _quat(ts, yaw: float):
    return ts.types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))


def write_bag(path: Path, segments: list[tuple[np.ndarray, np.ndarray, np.ndarray]], joints: list[str],
              signs: list[float], *, storage: str = "sqlite3", field: str = "position", pose_kind: str = "pose",
              pose_topic: str = "/tracker/pose", frame: str = "world", child: str = "base_link",
              length_scale: float = 1.0, pose_every: int = 1, seed: int = 0, gap_s: float = 0.0,
              arrival_t: np.ndarray | None = None, commands: list[np.ndarray] | None = None,
              command_topic: str = "/wheel_commands", command_type: str = "joint_state") -> None:
    """Write a bag of ``segments`` (t (K,) [s], wheel values (K, n) in model order, pose (K, 3)) one after
    another (``gap_s`` [s] of nothing between them, wheels continuing from where they were).

    ``field``: JointState ``position`` or ``velocity``; ``pose_kind``: ``pose`` (PoseStamped), ``odom``
    (Odometry) or ``tf`` (TFMessage on /tf, frame -> child); ``length_scale``: positions are written ×
    this (1000: millimetres); ``pose_every``: a pose message every this many wheel samples, stamped with
    that sample's time;
    ``arrival_t`` (K,) [s]: when each sample reached the recorder (default its stamp: a publisher whose clock
    jumps back stamps out of arrival order). ``commands``: per segment (K, n) wheel speed commands [rad/s] in
    model order, written on ``command_topic`` as JointState velocities (``command_type`` "joint_state") or
    a Float64MultiArray in joint order ("array": no header, the arrival time is all a reader has).
    """
    from rosbags.rosbag2 import StoragePlugin, Writer

    ts = _typestore()
    JS = ts.types["sensor_msgs/msg/JointState"]
    PS = ts.types["geometry_msgs/msg/PoseStamped"]
    rng = np.random.default_rng(seed)
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    with Writer(path, version=9, storage_plugin=plugin) as w:
        jc = w.add_connection("/joint_states", JS.__msgtype__, typestore=ts)
        if pose_kind == "tf":
            pc = w.add_connection("/tf", "tf2_msgs/msg/TFMessage", typestore=ts)
        elif pose_kind == "odom":
            pc = w.add_connection(pose_topic, "nav_msgs/msg/Odometry", typestore=ts)
        else:
            pc = w.add_connection(pose_topic, PS.__msgtype__, typestore=ts)
        MA = "std_msgs/msg/Float64MultiArray"
        cc = None if commands is None else w.add_connection(
            command_topic, JS.__msgtype__ if command_type == "joint_state" else MA, typestore=ts)
        offset_s = 0.0
        last = np.zeros(len(joints))
        for s_i, (t, wheels, pose) in enumerate(segments):
            if field == "position":
                wheels = wheels - wheels[0] + last
                last = wheels[-1]
            for k in range(len(t)):
                ns = EPOCH_NS + int(round((offset_s + t[k]) * 1e9))
                sent = t[k] if arrival_t is None else arrival_t[k]
                delay = int(rng.integers(1_000_000, 9_000_000))  # 1-9 ms transport delay (order kept)
                arrival = EPOCH_NS + int(round((offset_s + sent) * 1e9)) + delay
                values = np.array(wheels[k]) * np.array(signs)
                empty = np.zeros(0)
                msg = JS(header=_header(ts, ns, ""), name=list(joints),
                         position=values if field == "position" else np.zeros(len(joints)),
                         velocity=values if field == "velocity" else empty, effort=empty)
                w.write(jc, arrival, ts.serialize_cdr(msg, JS.__msgtype__))
                if cc is not None:
                    c = np.asarray(commands[s_i][k], dtype=float) * np.array(signs)
                    if command_type == "joint_state":
                        cm = JS(header=_header(ts, ns, ""), name=list(joints), position=np.zeros(0), velocity=c,
                                effort=np.zeros(0))
                    else:
                        layout = ts.types["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0)
                        cm = ts.types[MA](layout=layout, data=c)
                    w.write(cc, arrival - 500_000, ts.serialize_cdr(cm, cc.msgtype))
                if k % pose_every:
                    continue
                x, y, th = pose[k]
                P = ts.types["geometry_msgs/msg/Pose"](
                    position=ts.types["geometry_msgs/msg/Point"](x=x * length_scale, y=y * length_scale, z=0.0),
                    orientation=_quat(ts, th))
                if pose_kind == "tf":
                    T = ts.types["geometry_msgs/msg/TransformStamped"](
                        header=_header(ts, ns, frame), child_frame_id=child,
                        transform=ts.types["geometry_msgs/msg/Transform"](
                            translation=ts.types["geometry_msgs/msg/Vector3"](x=x * length_scale, y=y * length_scale,
                                                                              z=0.0),
                            rotation=_quat(ts, th)))
                    msg = ts.types["tf2_msgs/msg/TFMessage"](transforms=[T])
                elif pose_kind == "odom":
                    cov = np.zeros(36)
                    msg = ts.types["nav_msgs/msg/Odometry"](
                        header=_header(ts, ns, frame), child_frame_id=child,
                        pose=ts.types["geometry_msgs/msg/PoseWithCovariance"](pose=P, covariance=cov),
                        twist=ts.types["geometry_msgs/msg/TwistWithCovariance"](
                            twist=ts.types["geometry_msgs/msg/Twist"](
                                linear=ts.types["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
                                angular=ts.types["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)),
                            covariance=cov))
                else:
                    msg = PS(header=_header(ts, ns, frame), pose=P)
                w.write(pc, arrival + 500_000, ts.serialize_cdr(msg, pc.msgtype))
            offset_s += float(t[-1]) + gap_s
