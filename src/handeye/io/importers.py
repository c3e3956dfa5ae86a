"""Recordings made by other tools, written as handeye folders.

* :func:`import_rosbag`: a ROS 2 (or ROS 1) bag, read with the ``rosbags`` package (no ROS
  install): the robot's pose from ``/tf`` (the chain from the base frame to the tool frame,
  ``/tf_static`` included) or from a pose topic, and the camera from an image topic (a session
  whose poses are a robot stream, the images with their stamps) or from a pose topic of the
  target in the camera (two pose streams). Stamps are the messages' header stamps (each sensor's
  clock), not the times the recorder received them.
* :func:`import_easy_handeye`: the ``.samples`` file easy_handeye2 saves (robot and tracking
  transforms per sample), written as a pose-pair folder.
* :func:`import_visp`: a folder of ViSP's hand-eye tutorial (``*_rPe_<i>.yaml`` / ``*_fPe_<i>.yaml``
  robot poses as vpPoseVector, ``*image-<i>.png``, ``camera.xml``, ``chessboard-data.txt`` or
  ``apriltag-data.txt``; or ``pose_cPo_<i>.yaml`` camera poses without images).
* :func:`import_industrial_calibration`: ROS-Industrial industrial_calibration's ``cal_data.yaml``
  (image and pose files paired by name, the target finder, the intrinsics, ``static_camera``).

The folders are ordinary handeye inputs: ``handeye calibrate`` / ``calibrate-poses`` read them.
Another kind's session is imported in its folder (``pipelines/<kind>/importers.py``: RobCalibrator's
laser scans, EasyHeC's masks), named by its registration's ``imports``; their old names here still
import, with a DeprecationWarning, for one release.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from .._shared.io import check_output_folder
from .._shared.lazy import lazy_module
from .._shared.moved import forward_names
from .._shared.text import summarize
from ..errors import HandEyeError, InputMismatchError
from ..frames.setups import check_setup, robot_world_A
from ..geometry.se3 import from_rotvec_translation, invert, make_transform
from ..robot.kinematics import arm_names, joints_at, load_arm
from ..sensors.camera.targets import target_from_spec
from .session import (
    POSEPAIRS_FILE,
    SESSION_FILE,
    SessionError,
    load_yaml,
    write_joint_session,
    write_joint_stream,
    write_pose_pairs,
    write_pose_stream,
    write_session,
    write_stream_session,
)

cv2 = lazy_module("cv2")

__getattr__ = forward_names(__name__)  # import_robcalibrator, import_easyhec: in their kinds' folders now

__all__ = ["import_rosbag", "import_easy_handeye", "import_visp", "import_industrial_calibration", "ImportSummary",
           "ROSBAGS_MISSING", "new_folder", "numbered_files"]

#: What to say when the optional ``rosbags`` package is absent.
ROSBAGS_MISSING = "reading bag files needs the rosbags package: pip install 'handeye[ros]'"


@dataclass(frozen=True)
class ImportSummary:
    """What an import wrote: the folder, its kind ('session', 'posepairs', or 'stream session' /
    'stream posepairs' / 'joint streams' for recordings on two clocks) and how many samples of
    each side."""

    folder: Path
    kind: str
    robot_samples: int
    camera_samples: int
    notes: list[str]


def _rosbags():
    try:
        from rosbags.highlevel import AnyReader  # noqa: PLC0415  (an optional extra)
        from rosbags.typesys import Stores, get_typestore  # noqa: PLC0415
    except ImportError:
        raise HandEyeError(ROSBAGS_MISSING) from None
    return AnyReader, Stores, get_typestore


def _stamp(msg) -> float:
    """A message's header stamp in seconds (ROS 2 ``sec``/``nanosec``, ROS 1 ``secs``/``nsecs``)."""
    st = msg.header.stamp
    sec = getattr(st, "sec", None)
    return float(sec if sec is not None else st.secs) + 1e-9 * float(getattr(st, "nanosec", getattr(st, "nsecs", 0)))


def _transform_of(t) -> NDArray[np.float64]:
    """A geometry_msgs Transform (translation, rotation) or Pose (position, orientation) as 4x4."""
    p = getattr(t, "translation", None) or t.position
    q = getattr(t, "rotation", None) or t.orientation
    return make_transform(Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix(), [p.x, p.y, p.z])


def _pose_topic(reader, topic: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Stamps and poses of a PoseStamped, TransformStamped or Odometry topic, in stamp order."""
    conns = [c for c in reader.connections if c.topic == topic]
    if not conns:
        raise InputMismatchError(f"no topic {topic} in the bag; it has {summarize(sorted(reader.topics))}")
    times, poses = [], []
    for conn, _, raw in reader.messages(connections=conns):
        msg = reader.deserialize(raw, conn.msgtype)
        body = getattr(msg, "pose", None) or getattr(msg, "transform", None)
        if body is not None and hasattr(body, "pose"):  # Odometry: PoseWithCovariance
            body = body.pose
        if body is None:
            raise InputMismatchError(f"{topic}: {conn.msgtype} holds no pose; use a PoseStamped, TransformStamped or "
                                     "Odometry topic")
        times.append(_stamp(msg))
        poses.append(_transform_of(body))
    return _ordered(np.array(times), np.array(poses), topic)


def _ordered(times, poses, what: str):
    if len(times) == 0:
        raise InputMismatchError(f"{what}: no messages in the bag")
    order = np.argsort(times, kind="stable")
    times, poses = times[order], poses[order]
    keep = np.r_[True, np.diff(times) > 0]  # a stamp published twice: the first
    return times[keep], poses[keep]


def _tf_edges(reader) -> tuple[dict, dict]:
    """Per (parent, child) edge of /tf: stamps and child2parent transforms; of /tf_static: one transform."""
    dynamic: dict[tuple[str, str], list] = defaultdict(list)
    static: dict[tuple[str, str], NDArray[np.float64]] = {}
    conns = [c for c in reader.connections if c.topic in ("/tf", "/tf_static")]
    for conn, _, raw in reader.messages(connections=conns):
        msg = reader.deserialize(raw, conn.msgtype)
        for tr in msg.transforms:
            edge = (tr.header.frame_id.lstrip("/"), tr.child_frame_id.lstrip("/"))
            T = _transform_of(tr.transform)
            if conn.topic == "/tf_static":
                static[edge] = T
            else:
                dynamic[edge].append((_stamp(tr), T))
    return dynamic, static


def _frame_path(edges: set, start: str, goal: str) -> list[tuple[str, str, bool]]:
    """The edges from ``start`` to ``goal`` (breadth first over tf's tree, either direction):
    (parent, child, forward) where forward means the edge maps child into parent along the path."""
    nbrs: dict[str, list] = defaultdict(list)
    for parent, child in edges:
        nbrs[parent].append((child, (parent, child, True)))
        nbrs[child].append((parent, (parent, child, False)))
    seen, queue = {start: []}, [start]
    while queue:
        f = queue.pop(0)
        for g, edge in nbrs[f]:
            if g not in seen:
                seen[g] = seen[f] + [edge]
                queue.append(g)
    if goal not in seen:
        frames = sorted({f for edge in edges for f in edge})  # the bag's own frames, not the ones asked for
        absent = [f for f in (start, goal) if f not in frames]
        why = (f": {' and '.join(absent)} {'is' if len(absent) == 1 else 'are'} not a frame of the bag" if absent
               else ": they are in separate trees")
        raise InputMismatchError(f"tf has no chain from {start} to {goal}{why}; its frames: {summarize(frames)} "
                                 "(--robot-frames BASE,TOOL)")
    return seen[goal]


def _tf_stream(reader, base: str, tool: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``tool2base`` over time from /tf and /tf_static: the chain's transforms composed at the
    stamps of its moving edges (robot_state_publisher stamps them alike; 0.5 ms apart at most)."""
    dynamic, static = _tf_edges(reader)
    path = _frame_path(set(dynamic) | set(static), base, tool)
    moving = [(p, c) for p, c, _ in path if (p, c) in dynamic]
    if not moving:
        raise InputMismatchError(f"the tf chain {base} -> {tool} never moves (only /tf_static): no robot motion")
    ref_t = np.array(sorted({t for t, _ in dynamic[moving[0]]}))
    series = {}
    for edge in moving:
        t, T = _ordered(np.array([s for s, _ in dynamic[edge]]), np.array([m for _, m in dynamic[edge]]), f"tf {edge}")
        k = np.clip(np.searchsorted(t, ref_t), 1, len(t) - 1)
        k = np.where(np.abs(ref_t - t[k - 1]) <= np.abs(t[k] - ref_t), k - 1, k)
        ok = np.abs(t[k] - ref_t) <= 5e-4
        series[edge] = (T[k], ok)
    ok = np.logical_and.reduce([o for _, o in series.values()])
    if ok.sum() < 2:
        raise InputMismatchError(f"the moving edges of the tf chain {base} -> {tool} ({summarize(moving)}) are never "
                                 "stamped alike; record the tool pose as one topic (--robot-topic)")
    tool2base = np.tile(np.eye(4), (int(ok.sum()), 1, 1))
    for parent, child, forward in path:  # base -> ... -> tool: each step maps the next frame into the current
        T = series[(parent, child)][0][ok] if (parent, child) in series else static[(parent, child)]
        tool2base = tool2base @ (T if forward else invert(T))
    return ref_t[ok], tool2base


_ENCODINGS = {"mono8": (1, np.uint8), "bgr8": (3, np.uint8), "rgb8": (3, np.uint8), "bgra8": (4, np.uint8),
              "rgba8": (4, np.uint8), "mono16": (1, np.uint16)}


def _image_of(msg, msgtype: str) -> NDArray[np.uint8]:
    """A grayscale 8-bit image from a sensor_msgs Image or CompressedImage."""
    if msgtype.endswith("CompressedImage"):
        img = cv2.imdecode(np.frombuffer(bytes(msg.data), np.uint8), cv2.IMREAD_GRAYSCALE)
        if img is None:
            raise InputMismatchError(f"a {msg.format!r} compressed image could not be decoded")
        return img
    if msg.encoding not in _ENCODINGS:
        raise InputMismatchError(f"image encoding {msg.encoding!r}; handeye reads {', '.join(_ENCODINGS)}")
    channels, dtype = _ENCODINGS[msg.encoding]
    raw = np.frombuffer(bytes(msg.data), np.uint8).reshape(msg.height, msg.step)
    img = raw[:, : msg.width * channels * np.dtype(dtype).itemsize].copy().view(dtype)
    img = img.reshape(msg.height, msg.width, channels)
    if dtype == np.uint16:
        img = (img.astype(np.float64) / max(1, img.max()) * 255).astype(np.uint8)
    if channels == 1:
        return img[..., 0]
    code = {"bgr8": cv2.COLOR_BGR2GRAY, "rgb8": cv2.COLOR_RGB2GRAY, "bgra8": cv2.COLOR_BGRA2GRAY,
            "rgba8": cv2.COLOR_RGBA2GRAY}[msg.encoding]
    return cv2.cvtColor(np.ascontiguousarray(img), code)


def _write_images(reader, topic: str, folder: Path, every: int) -> tuple[list[str], NDArray[np.float64]]:
    conns = [c for c in reader.connections if c.topic == topic]
    if not conns:
        raise InputMismatchError(f"no topic {topic} in the bag; it has {summarize(sorted(reader.topics))}")
    (folder / "images").mkdir(parents=True, exist_ok=True)
    names, times = [], []
    for k, (conn, _, raw) in enumerate(reader.messages(connections=conns)):
        if k % every:
            continue
        msg = reader.deserialize(raw, conn.msgtype)
        name = f"{len(names):06d}.png"
        if not cv2.imwrite(str(folder / "images" / name), _image_of(msg, conn.msgtype)):
            raise HandEyeError(f"cannot write {folder / 'images' / name}")
        names.append(name)
        times.append(_stamp(msg))
    if not names:
        raise InputMismatchError(f"{topic}: no images in the bag")
    return names, np.array(times)


def _joint_states(reader, topic: str) -> tuple[NDArray[np.float64], list[str], NDArray[np.float64]]:
    """Stamps, joint names and positions (rad) of a JointState topic: the messages that hold every
    joint of the first message (a gripper's joints published apart are left out), in stamp order."""
    conns = [c for c in reader.connections if c.topic == topic]
    if not conns:
        raise InputMismatchError(f"no topic {topic} in the bag; it has {summarize(sorted(reader.topics))}")
    names: list[str] | None = None
    times, positions = [], []
    for conn, _, raw in reader.messages(connections=conns):
        msg = reader.deserialize(raw, conn.msgtype)
        if not hasattr(msg, "position") or not hasattr(msg, "name"):
            raise InputMismatchError(f"{topic}: {conn.msgtype} is not a JointState topic")
        by_name = dict(zip(list(msg.name), np.asarray(msg.position, dtype=float)))
        names = names or list(msg.name)
        if all(n in by_name for n in names):
            times.append(_stamp(msg))
            positions.append([by_name[n] for n in names])
    if not names:
        raise InputMismatchError(f"{topic}: no joint states in the bag")
    t, q = _ordered(np.array(times), np.array(positions), topic)
    return t, names, q


def _joint_session_of_bag(reader, bag: Path, folder: Path, setup: str, joint_topic: str, arm: str, image_topic: str,
                          camera_info_topic: str | None, target: dict[str, Any], every: int) -> ImportSummary:
    """A session of the bag's images with the joint angles at each image's stamp."""
    t_joint, names, q = _joint_states(reader, joint_topic)
    image_names, t_img = _write_images(reader, image_topic, folder, every)
    outside = (t_img < t_joint[0] - JOINT_GAP_S) | (t_img > t_joint[-1] + JOINT_GAP_S)
    if outside.any():
        raise InputMismatchError(f"{joint_topic}: {int(outside.sum())} of {len(t_img)} images lie outside the joint states' "
                                 f"time span ({t_joint[0]:.3f}-{t_joint[-1]:.3f} s): record both topics together")
    gaps = np.diff(t_joint).max(initial=0.0)
    q_img = joints_at(t_joint, q, t_img)
    write_joint_session(folder, setup, target, image_names, q_img, arm, camera=_camera_info(reader, camera_info_topic),
                        comment=f"imported by handeye from {bag.name}: joint angles of {joint_topic} interpolated at "
                        "each image's stamp", joint_names=names, unit="rad")
    notes = [f"joint states up to {1e3 * gaps:.0f} ms apart, interpolated at the images' stamps"]
    return ImportSummary(folder, "session", len(t_joint), len(image_names), notes)


def _joint_streams_of_bag(reader, bag: Path, folder: Path, setup: str, joint_topic: str, arm: str | None,
                          camera_pose_topic: str, camera_pose: str) -> ImportSummary:
    """The bag's joint states and the target's poses as the two streams of ``calibrate-streams
    --arm``: joints.csv (radians, the columns named as the topic names its joints) and camera.csv."""
    t_joint, names, q = _joint_states(reader, joint_topic)
    if arm is not None and arm.lower() in arm_names() and load_arm(arm).n_joints != len(names):
        raise InputMismatchError(f"{joint_topic} names {len(names)} joints ({', '.join(names)}); {arm} has "
                                 f"{load_arm(arm).n_joints}")
    t_cam, poses = _pose_topic(reader, camera_pose_topic)
    target2cam = poses if camera_pose == "target2cam" else invert(poses)
    write_joint_stream(folder / "joints.csv", t_joint, q, names)
    write_pose_stream(folder / "camera.csv", t_cam, target2cam, "quat_wxyz")
    command = (f"handeye calibrate-streams {folder / 'joints.csv'} {folder / 'camera.csv'} --arm {arm or 'ARM'} "
               f"--camera-format quat_wxyz --setup {setup}")
    notes = [f"{bag.name}'s {joint_topic} (radians) and {camera_pose_topic} (as target2cam, metres) on the bag's clock; "
             f"calibrate them with: {command}"]
    return ImportSummary(folder, "joint streams", len(t_joint), len(t_cam), notes)


#: Images this far (s) outside the joint states' time span cannot be given joint angles.
JOINT_GAP_S = 0.05


def _camera_info(reader, topic: str | None) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    if topic is None:
        return None
    conns = [c for c in reader.connections if c.topic == topic]
    if not conns:
        raise InputMismatchError(f"no topic {topic} in the bag; it has {summarize(sorted(reader.topics))}")
    for conn, _, raw in reader.messages(connections=conns):
        msg = reader.deserialize(raw, conn.msgtype)
        K = np.asarray(getattr(msg, "k", None) if hasattr(msg, "k") else msg.K, dtype=float).reshape(3, 3)
        d = np.asarray(getattr(msg, "d", None) if hasattr(msg, "d") else msg.D, dtype=float).ravel()
        return K, (d if len(d) in (4, 5, 8, 12, 14) else np.zeros(5))
    raise InputMismatchError(f"{topic}: no CameraInfo message in the bag")


def _check_bag_request(setup: str, robot_frames, robot_topic, image_topic, camera_pose_topic, camera_pose: str,
                       target, every, joint_topic, arm) -> None:
    """:func:`import_rosbag`'s arguments make one request (a robot side, a camera side), or raise."""
    setup = check_setup(setup)
    if (image_topic is None) == (camera_pose_topic is None):
        raise InputMismatchError("give the camera as image_topic (images) or camera_pose_topic (poses), one of them")
    if joint_topic is not None:
        if image_topic is not None and arm is None:
            raise InputMismatchError("joint_topic with image_topic needs arm (the arm's kinematics: joints.csv is read "
                                     "with it)")
    elif (robot_topic is None) == (robot_frames is None):
        raise InputMismatchError("give the robot as robot_frames (tf) or robot_topic (a pose topic), one of them")
    if image_topic is not None:
        if target is None:
            raise InputMismatchError("images need the target's description (target=, as in session.yaml)")
        target_from_spec(target)
    if camera_pose not in ("target2cam", "cam2target"):
        raise InputMismatchError(f"camera_pose={camera_pose!r}; use 'target2cam' or 'cam2target'")
    if not (isinstance(every, int) and every >= 1):
        raise InputMismatchError(f"every={every!r}: give a whole number >= 1")


def import_rosbag(
    bag: str | Path,
    out: str | Path,
    setup: str = "eye_in_hand",
    robot_frames: tuple[str, str] | None = ("base_link", "tool0"),
    robot_topic: str | None = None,
    image_topic: str | None = None,
    camera_pose_topic: str | None = None,
    camera_pose: str = "target2cam",
    camera_info_topic: str | None = None,
    target: dict[str, Any] | None = None,
    every: int = 1,
    joint_topic: str | None = None,
    arm: str | None = None,
) -> ImportSummary:
    """Write a ROS bag's robot and camera recordings as a handeye folder in ``out``.

    Parameters
    ----------
    bag : path
        A ROS 2 bag folder (or its ``.db3``/``.mcap``) or a ROS 1 ``.bag``.
    setup : {'eye_in_hand', 'eye_to_hand'}
    robot_frames : (base, tool)
        tf frames: the robot's pose is ``tool2base`` (``flange2base``) from /tf and /tf_static.
    robot_topic : str, optional
        Instead of tf: a PoseStamped, TransformStamped or Odometry topic of the flange in the base.
    image_topic : str, optional
        An Image or CompressedImage topic: writes a session (``images/``, ``images.csv`` with the
        header stamps, ``robot.csv`` the robot stream); needs ``target`` (a session.yaml target
        mapping). ``every``: keep every n-th image.
    camera_pose_topic : str, optional
        Instead of images: the target's pose from the camera (``camera_pose='target2cam'``, or
        ``'cam2target'``): writes a pose-pair folder of two streams.
    camera_info_topic : str, optional
        A CameraInfo topic: K and dist into session.yaml (else handeye estimates them).
    joint_topic, arm : str, optional
        Instead of the robot's poses: a JointState topic (``/joint_states``) and the arm (a name of
        :func:`handeye.robot.kinematics.arm_names`, or a YAML table or URDF file the session will hold).
        With images: writes a session with ``joints.csv`` (radians, columns named as the topic
        names its joints), each image's joint angles interpolated at its stamp (one clock: the
        bag's), so that calibrate fits the arm's table with X. With ``camera_pose_topic``: writes
        the two streams of ``handeye calibrate-streams --arm`` (``joints.csv``: a time column,
        then the joint angles; ``camera.csv``: the target's poses, quat_wxyz in metres; the arm
        is optional then, named in the command the notes give).

    Returns
    -------
    ImportSummary

    Raises
    ------
    HandEyeError
        rosbags not installed; a topic or frame missing; an image encoding handeye does not read.
    """
    _check_bag_request(setup, robot_frames, robot_topic, image_topic, camera_pose_topic, camera_pose, target, every,
                       joint_topic, arm)
    bag = Path(bag)
    if not bag.exists():
        raise SessionError(f"{bag}: no such bag")
    folder = check_output_folder(out, [bag] if bag.is_dir() else [])  # never inside a ROS 2 bag's folder
    if (folder / SESSION_FILE).exists() or (folder / POSEPAIRS_FILE).exists():
        raise HandEyeError(f"{folder} already holds a session or pose pairs; choose an empty folder")
    AnyReader, Stores, get_typestore = _rosbags()
    try:
        with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
            if joint_topic is not None and image_topic is not None:
                return _joint_session_of_bag(reader, bag, folder, setup, joint_topic, arm, image_topic,
                                             camera_info_topic, dict(target), every)
            if joint_topic is not None:
                return _joint_streams_of_bag(reader, bag, folder, setup, joint_topic, arm, camera_pose_topic,
                                             camera_pose)
            if robot_topic is not None:
                t_robot, f2b = _pose_topic(reader, robot_topic)
            else:
                t_robot, f2b = _tf_stream(reader, *robot_frames)
            if image_topic is not None:
                names, t_img = _write_images(reader, image_topic, folder, every)
                camera = _camera_info(reader, camera_info_topic)
                write_stream_session(folder, setup, dict(target), t_robot, f2b, names, t_img, camera=camera,
                                     comment=f"imported by handeye from {bag.name}")
                return ImportSummary(folder, "stream session", len(t_robot), len(names), [])
            t_cam, poses = _pose_topic(reader, camera_pose_topic)
    except HandEyeError:
        raise
    except Exception as exc:  # rosbags' own errors: an unreadable or unknown bag
        raise SessionError(f"{bag}: cannot read the bag ({type(exc).__name__}: {exc})") from None
    t2c = poses if camera_pose == "target2cam" else invert(poses)
    write_pose_pairs(folder, setup, f2b, t2c, t_robot, t_cam, comment=f"imported by handeye from {bag.name}")
    return ImportSummary(folder, "stream posepairs", len(t_robot), len(t_cam), [])


def import_easy_handeye(samples: str | Path, out: str | Path, setup: str | None = None) -> ImportSummary:
    """Write easy_handeye2's saved samples (a ``.samples`` YAML: per sample the ``robot`` and
    ``tracking`` transforms as translation + quaternion) as a pose-pair folder in ``out``.

    easy_handeye2 samples ``robot`` as the effector in the robot base (eye-in-hand; for eye-on-base
    the base in the effector) and ``tracking`` as the marker in the tracking (camera) frame, i.e.
    ``target2cam``. ``setup`` is read from the file's ``calibration_type`` unless given.
    """
    samples = Path(samples)
    data = load_yaml(samples)
    params = data.get("parameters") or {}
    kind = str(params.get("calibration_type") or "")
    if setup is None:
        setup = {"eye_in_hand": "eye_in_hand", "eye_on_base": "eye_to_hand"}.get(kind)
        if setup is None:
            raise InputMismatchError(f"{samples}: calibration_type {kind!r} does not say the setup; give setup "
                                     "('eye_in_hand' or 'eye_to_hand', --setup)")
    setup = check_setup(setup)
    rows = data.get("samples")
    if not isinstance(rows, list) or len(rows) < 3:
        raise SessionError(f"{samples}: expected a list 'samples' of at least 3 robot/tracking pairs")
    robot, tracking = [], []
    for k, row in enumerate(rows):
        try:
            robot.append(_yaml_transform(row["robot"]))
            tracking.append(_yaml_transform(row["tracking"]))
        except (KeyError, TypeError, ValueError) as exc:
            raise SessionError(f"{samples}: sample {k}: expected robot and tracking with translation x, y, z and "
                               f"rotation x, y, z, w ({type(exc).__name__}: {exc})") from None
    f2b = robot_world_A(np.array(robot), setup)  # the sample is A (flange2base, or base2flange eye-on-base): A(A) = f2b
    folder = check_output_folder(out)  # one input file: it is never written over (write_pose_pairs writes new names)
    if (folder / POSEPAIRS_FILE).exists():
        raise HandEyeError(f"{folder} already holds pose pairs; choose an empty folder")
    write_pose_pairs(folder, setup, f2b, np.array(tracking), comment=f"imported by handeye from {samples.name} (easy_handeye2)")
    return ImportSummary(folder, "posepairs", len(rows), len(rows), [])


def _yaml_transform(d: dict) -> NDArray[np.float64]:
    t, q = d["translation"], d["rotation"]
    quat = np.array([float(q["x"]), float(q["y"]), float(q["z"]), float(q["w"])])
    if not np.all(np.isfinite(quat)) or abs(np.linalg.norm(quat) - 1) > 1e-3:
        raise InputMismatchError(f"rotation {quat.tolist()} is not a unit quaternion")
    return make_transform(Rotation.from_quat(quat).as_matrix(), [float(t["x"]), float(t["y"]), float(t["z"])])



def new_folder(out: str | Path, inputs: list[Path]) -> Path:
    """The folder ``out`` checked to take an import of ``inputs`` (never inside them, writable) and
    holding no session or pose pairs yet."""
    folder = check_output_folder(out, inputs)
    if (folder / SESSION_FILE).exists() or (folder / POSEPAIRS_FILE).exists() or (folder / "images").exists():
        raise HandEyeError(f"{folder} already holds a session or pose pairs; choose an empty folder")
    return folder


def _copy_images(images: list[Path], folder: Path) -> list[str]:
    """The images copied into ``folder/images`` (a session holds its own images); their names."""
    (folder / "images").mkdir(parents=True, exist_ok=True)
    names = []
    for src in images:
        if not src.is_file():
            raise SessionError(f"{src}: image file not found")
        (folder / "images" / src.name).write_bytes(src.read_bytes())
        names.append(src.name)
    return names


def _visp_pose(path: Path) -> NDArray[np.float64]:
    """A ViSP vpPoseVector YAML (``data``: tx, ty, tz, theta-u x, y, z; metres and radians) as 4x4."""
    try:
        v = np.array(load_yaml(path)["data"], dtype=float).ravel()
    except (KeyError, TypeError, ValueError):
        raise SessionError(f"{path}: expected a ViSP vpPoseVector (data: 6 rows tx, ty, tz, tux, tuy, tuz)") from None
    if v.shape != (6,) or not np.isfinite(v).all():
        raise SessionError(f"{path}: expected 6 finite numbers under data, got {v.tolist()}")
    return from_rotvec_translation(v[3:], v[:3])


def numbered_files(folder: Path, pattern: str) -> dict[int, Path]:
    """The files of ``folder`` whose names match ``pattern`` (a regular expression whose one group
    is the number), by number."""
    out = {}
    for p in folder.iterdir():
        m = re.fullmatch(pattern, p.name)
        if m and p.is_file():
            out[int(m[1])] = p
    return out


def _visp_camera(folder: Path) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
    """K and dist from ViSP's camera XML (px, py, u0, v0; kud is OpenCV's k1: ViSP distorts
    normalised points by ``1 + kud r^2``)."""
    files = sorted(folder.glob("*camera*.xml"))
    if not files:
        return None
    try:
        model = ET.parse(files[0]).getroot().find("camera/model")
        get = {c.tag: float(c.text) for c in model if c.tag in ("px", "py", "u0", "v0", "kud")}
    except (ET.ParseError, AttributeError, TypeError, ValueError):
        raise SessionError(f"{files[0]}: not a ViSP camera XML (camera/model with px, py, u0, v0)") from None
    if not {"px", "py", "u0", "v0"} <= set(get):
        raise SessionError(f"{files[0]}: camera/model lacks px, py, u0 or v0")
    K = np.array([[get["px"], 0, get["u0"]], [0, get["py"], get["v0"]], [0, 0, 1.0]])
    return K, np.array([get.get("kud", 0.0), 0, 0, 0, 0])


def _visp_target(folder: Path) -> dict[str, Any] | None:
    """The target of ``chessboard-data.txt`` ("9 x 6", "square size: 0.0236 m") or
    ``apriltag-data.txt`` ("36h11", "size: 0.048 m"), or None."""
    board, tag = folder / "chessboard-data.txt", folder / "apriltag-data.txt"
    if board.is_file():
        text = board.read_text(errors="replace")
        dims, size = re.search(r"(\d+)\s*x\s*(\d+)", text), re.search(r"size:\s*([0-9.eE+-]+)\s*m", text)
        if dims and size:
            return {"type": "chessboard", "cols": int(dims[1]), "rows": int(dims[2]), "square": float(size[1])}
        raise SessionError(f"{board}: expected 'C x R' inner corners and 'square size: S m'")
    if tag.is_file():
        text = tag.read_text(errors="replace")
        family, size = re.search(r"(\d+h\d+)", text), re.search(r"size:\s*([0-9.eE+-]+)\s*m", text)
        if family and size:
            return {"type": "apriltag", "square": float(size[1]), "dictionary": f"DICT_APRILTAG_{family[1]}"}
        raise SessionError(f"{tag}: expected the tag family (e.g. 36h11) and 'size: S m'")
    return None


def import_visp(folder: str | Path, out: str | Path, setup: str = "eye_in_hand",
                target: dict[str, Any] | None = None) -> ImportSummary:
    """A folder of ViSP's hand-eye tutorial as a session (images) or a pose-pair folder (``cPo``
    camera poses, no images), in ``out``.

    Robot poses ``*_rPe_<i>.yaml`` / ``*_fPe_<i>.yaml`` (the flange in the base), images
    ``*image-<i>.png`` paired by number, the intrinsics of ``*camera*.xml``, the target of
    ``chessboard-data.txt`` / ``apriltag-data.txt`` unless ``target`` is given (ViSP's 2022 set
    names its 26.2 mm board only in the tutorial's text). ViSP's files do not say the setup:
    ``setup`` (default eye-in-hand; the check names inverted robot poses when it is wrong).
    """
    src = Path(folder)
    if not src.is_dir():
        raise SessionError(f"{src}: no such folder")
    setup = check_setup(setup)
    poses = numbered_files(src, r"(?:.*_)?[rf]Pe_(\d+)\.yaml")
    if len(poses) < 3:
        raise SessionError(f"{src}: fewer than 3 robot poses (*_rPe_<i>.yaml or *_fPe_<i>.yaml)")
    cams = numbered_files(src, r"(?:.*_)?cPo_(\d+)\.yaml")
    images = numbered_files(src, r".*image-(\d+)\.png")
    dest = new_folder(out, [src])
    if not images and cams:
        common = sorted(set(poses) & set(cams))
        f2b = np.array([_visp_pose(poses[k]) for k in common])
        t2c = np.array([_visp_pose(cams[k]) for k in common])
        write_pose_pairs(dest, setup, f2b, t2c, ids=[str(k) for k in common], comment=f"imported by handeye from {src}")
        return ImportSummary(dest, "posepairs", len(common), len(common), [])
    common = sorted(set(poses) & set(images))
    if len(common) < 3:
        raise SessionError(f"{src}: fewer than 3 images (*image-<i>.png) with a robot pose of the same number")
    spec = target if target is not None else _visp_target(src)
    if spec is None:
        raise SessionError(f"{src}: no chessboard-data.txt or apriltag-data.txt; give the target (--target-spec)")
    target_from_spec(spec)
    names = _copy_images([images[k] for k in common], dest)
    f2b = np.array([_visp_pose(poses[k]) for k in common])
    write_session(dest, setup, spec, names, f2b, "rotvec", "m", "rad", camera=_visp_camera(src),
                  comment=f"imported by handeye from ViSP's {src}")
    return ImportSummary(dest, "session", len(common), len(common), [])


def _aruco_name(code: Any) -> str:
    """An OpenCV aruco dictionary given by number (industrial_calibration's) or name, as its name."""
    if isinstance(code, str):
        return code if code.startswith("DICT_") else f"DICT_{code}"
    names = {getattr(cv2.aruco, n): n for n in dir(cv2.aruco) if n.startswith("DICT_") and isinstance(getattr(cv2.aruco, n), int)}
    if int(code) not in names:
        raise SessionError(f"aruco dictionary {code!r} is not one of OpenCV's")
    return names[int(code)]


def import_industrial_calibration(cal_data: str | Path, out: str | Path) -> ImportSummary:
    """ROS-Industrial industrial_calibration's dataset (``cal_data.yaml``, or its folder) as a session.

    ``data`` pairs image and pose files by name (pose YAMLs with x, y, z, qx, qy, qz, qw: the flange
    in the base); ``target_finder`` gives the target (CharucoGridTargetFinder: ``cols`` x ``rows``
    squares, ``chessboard_dim``, ``aruco_marker_dim``, ``dictionary``; circle grids: ``rows``, ``cols``,
    ``spacing``, ModifiedCircleGridTargetFinder as ``modified_circles``); ``intrinsics`` fx, fy, cx, cy
    (no distortion in its model); ``static_camera: true`` means eye-to-hand.
    """
    path = Path(cal_data)
    if path.is_dir():
        path = path / "cal_data.yaml"
    data = load_yaml(path)
    root = path.parent
    rows = data.get("data")
    if not isinstance(rows, list) or len(rows) < 3:
        raise SessionError(f"{path}: expected a list 'data' of at least 3 image/pose entries")
    finder = data.get("target_finder") or {}
    kind = str(finder.get("type", ""))
    try:
        if "Charuco" in kind:
            spec = {"type": "charuco", "cols": int(finder["cols"]), "rows": int(finder["rows"]),
                    "square": float(finder["chessboard_dim"]), "marker": float(finder["aruco_marker_dim"]),
                    "dictionary": _aruco_name(finder["dictionary"])}
        elif "Circle" in kind:  # the modified grid's big circle gives every image one reading
            spec = {"type": "modified_circles" if "Modified" in kind else "circles", "cols": int(finder["cols"]),
                    "rows": int(finder["rows"]), "square": float(finder["spacing"])}
        else:
            raise SessionError(f"{path}: target_finder type {kind!r}; handeye imports Charuco and circle grid finders")
    except (KeyError, TypeError, ValueError) as exc:
        raise SessionError(f"{path}: target_finder lacks {exc}") from None
    intr = data.get("intrinsics") or {}
    camera = None
    if {"fx", "fy", "cx", "cy"} <= set(intr):
        camera = (np.array([[intr["fx"], 0, intr["cx"]], [0, intr["fy"], intr["cy"]], [0, 0, 1.0]], dtype=float),
                  np.zeros(5))
    f2b, images = [], []
    for k, item in enumerate(rows):
        try:
            p = load_yaml(root / str(item["pose"]))
            q = [float(p[c]) for c in ("qx", "qy", "qz", "qw")]
            f2b.append(make_transform(Rotation.from_quat(q).as_matrix(), [float(p[c]) for c in "xyz"]))
            images.append(root / str(item["image"]))
        except (KeyError, TypeError, ValueError) as exc:
            raise SessionError(f"{path}: data entry {k}: expected image and pose (x, y, z, qx, qy, qz, qw; {exc})") from None
    setup = "eye_to_hand" if data.get("static_camera") else "eye_in_hand"
    dest = new_folder(out, [root])
    names = _copy_images(images, dest)
    write_session(dest, setup, spec, names, np.array(f2b), "quat_xyzw", "m", "rad", camera=camera,
                  comment=f"imported by handeye from industrial_calibration's {path}")
    return ImportSummary(dest, "session", len(names), len(names), [])
