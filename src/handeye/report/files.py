"""Result files: a calibration in the forms robot programs and ROS need, written atomically.

``result.json`` and ``result.yaml`` hold the same mapping (:func:`result_dict`): X and Z as 4x4
matrices, translations in m and mm, quaternions in both orders (labelled), rotation vectors,
Euler angles in the convention the robot poses were given in, the inverse of X, the uncertainty,
the verdict and advice, per-pose residuals, the handeye version and a hash of the inputs — and two
snippets that paste straight into a ROS 2 system (:func:`ros2_static_transform_command`,
:func:`urdf_joint`). Numbers are written with full precision (shortest round-trip repr).
"""

from __future__ import annotations

import json
import warnings
from dataclasses import replace
from pathlib import Path
from typing import Any, Iterable

import numpy as np
import yaml
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation

from .._shared.io import atomic_write, dump_yaml
from .._version import __version__
from ..errors import HandEyeError
from ..frames.poses import format_poses, pose_columns
from ..frames.setups import setup_info
from ..geometry.se3 import invert
from ..pipelines.kinds import kind_of_model
from ..result import Calibration
from ..robot.kinematics import chain_yaml
from ..robot.urdf import chain_urdf

__all__ = ["result_dict", "write_results", "ros2_static_transform_command", "urdf_joint", "default_frames",
           "euler_angles", "ros2_launch_file", "ros2_rig_launch_file", "ros1_launch_file", "easy_handeye_calibration", "in_tool_frame",
           "write_exports", "check_exports", "EXPORTS"]


def default_frames(setup: str, sensor: str | None = None) -> tuple[str, str]:
    """``(parent, child)`` frame names for X: ROS-Industrial's ``tool0`` / ``base_link`` and the
    sensor's optical frame (OpenCV's camera frame: z forward, x right, y down, REP 103's *_optical_frame*;
    ``sensor``: the sensor model's kind; another kind than a camera names its frame in its registration,
    :attr:`handeye.pipelines.kinds.SensorKind.frame`: a laser profiler's, x along its line and z along its
    measuring axis, is an optical frame too)."""
    info = setup_info(setup)
    kind = kind_of_model(sensor)
    return info.ros_parent_frame, kind.frame if kind is not None and kind.frame else info.ros_child_frame


def _frames_of(cal: Calibration) -> tuple[str, str]:
    """:func:`default_frames` of ``cal``'s setup and sensor."""
    return default_frames(cal.setup, None if cal.sensor is None else cal.sensor.sensor)


def euler_angles(rot: Rotation, seq: str, degrees: bool = False) -> NDArray[np.float64]:
    """``rot.as_euler(seq)`` without scipy's gimbal-lock warning (the angles still give the rotation)."""
    # at gimbal lock scipy warns and sets the third angle to zero; the angles still give the rotation
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Gimbal lock", category=UserWarning)
        return rot.as_euler(seq, degrees=degrees)


def _num(v: float) -> str:
    return repr(float(v))


def ros2_static_transform_command(T: NDArray[np.float64], parent: str, child: str) -> str:
    """The ``ros2 run tf2_ros static_transform_publisher`` line that publishes ``T = child2parent``.

    ROS 2 (Foxy and later) named arguments; the quaternion is in ROS's x, y, z, w order.
    """
    q = Rotation.from_matrix(T[:3, :3]).as_quat(canonical=True)
    x, y, z = T[:3, 3]
    return (f"ros2 run tf2_ros static_transform_publisher --x {_num(x)} --y {_num(y)} --z {_num(z)} "
            f"--qx {_num(q[0])} --qy {_num(q[1])} --qz {_num(q[2])} --qw {_num(q[3])} "
            f"--frame-id {parent} --child-frame-id {child}")


def urdf_joint(T: NDArray[np.float64], parent: str, child: str, name: str | None = None) -> str:
    """A fixed URDF ``<joint>`` placing ``child`` in ``parent`` by ``T = child2parent``.

    URDF's ``rpy`` is roll about x, then pitch about y, then yaw about z, all about the parent's
    fixed axes: ``R = Rz(yaw) Ry(pitch) Rx(roll)`` (scipy's extrinsic ``'xyz'``).
    """
    rpy = euler_angles(Rotation.from_matrix(T[:3, :3]), "xyz")
    xyz = " ".join(_num(v) for v in T[:3, 3])
    return (f'<joint name="{name or child + "_joint"}" type="fixed">\n'
            f'  <parent link="{parent}"/>\n'
            f'  <child link="{child}"/>\n'
            f'  <origin xyz="{xyz}" rpy="{" ".join(_num(v) for v in rpy)}"/>\n'
            f'</joint>')


def ros2_launch_file(T: NDArray[np.float64], parent: str, child: str) -> str:
    """A ROS 2 Python launch file that publishes ``T = child2parent`` as a static transform."""
    q = Rotation.from_matrix(T[:3, :3]).as_quat(canonical=True)
    args = [f"'--x', '{_num(T[0, 3])}'", f"'--y', '{_num(T[1, 3])}'", f"'--z', '{_num(T[2, 3])}'",
            f"'--qx', '{_num(q[0])}'", f"'--qy', '{_num(q[1])}'", f"'--qz', '{_num(q[2])}'", f"'--qw', '{_num(q[3])}'",
            f"'--frame-id', '{parent}'", f"'--child-frame-id', '{child}'"]
    return ("# Written by handeye: the hand-eye calibration as a static transform.\n"
            "# ros2 launch ./handeye_static_tf.launch.py\n"
            "from launch import LaunchDescription\nfrom launch_ros.actions import Node\n\n\n"
            "def generate_launch_description():\n    return LaunchDescription([Node(\n"
            "        package='tf2_ros', executable='static_transform_publisher', name='handeye_static_tf',\n"
            f"        arguments=[{', '.join(args)}],\n    )])\n")


def ros2_rig_launch_file(frames: dict[str, NDArray[np.float64]], parent: str) -> str:
    """A ROS 2 Python launch file that publishes every sensor of a rig as a static transform from
    ``parent`` (``frames``: sensor name -> ``sensor2parent``; child frames ``<name>_optical_frame``)."""
    nodes = []
    for name, T in frames.items():
        q = Rotation.from_matrix(T[:3, :3]).as_quat(canonical=True)
        args = [f"'--x', '{_num(T[0, 3])}'", f"'--y', '{_num(T[1, 3])}'", f"'--z', '{_num(T[2, 3])}'",
                f"'--qx', '{_num(q[0])}'", f"'--qy', '{_num(q[1])}'", f"'--qz', '{_num(q[2])}'", f"'--qw', '{_num(q[3])}'",
                f"'--frame-id', '{parent}'", f"'--child-frame-id', '{name}_optical_frame'"]
        nodes.append("        Node(package='tf2_ros', executable='static_transform_publisher', "
                     f"name='handeye_{name}_tf',\n             arguments=[{', '.join(args)}]),\n")
    return ("# Written by handeye: every sensor of the rig as a static transform.\n"
            "# ros2 launch ./rig_static_tf.launch.py\n"
            "from launch import LaunchDescription\nfrom launch_ros.actions import Node\n\n\n"
            "def generate_launch_description():\n    return LaunchDescription([\n" + "".join(nodes) + "    ])\n")


def ros1_launch_file(T: NDArray[np.float64], parent: str, child: str) -> str:
    """A ROS 1 launch file (as MoveIt Calibration exports) publishing ``T = child2parent``:
    tf2_ros's static_transform_publisher with ``x y z qx qy qz qw parent child``."""
    q = Rotation.from_matrix(T[:3, :3]).as_quat(canonical=True)
    values = " ".join(_num(v) for v in (*T[:3, 3], *q))
    return ('<launch>\n  <!-- Written by handeye: the hand-eye calibration as a static transform -->\n'
            f'  <node pkg="tf2_ros" type="static_transform_publisher" name="handeye_static_tf" '
            f'args="{values} {parent} {child}"/>\n</launch>\n')


def easy_handeye_calibration(cal: Calibration, parent: str, child: str, name: str = "handeye") -> dict[str, Any]:
    """The calibration as easy_handeye2 saves it (its ``.calib`` YAML): the parameters (frames,
    ``eye_in_hand`` or ``eye_on_base``) and ``transform``, X as translation and quaternion (x, y, z, w)."""
    info = setup_info(cal.setup)
    q = Rotation.from_matrix(cal.X[:3, :3]).as_quat(canonical=True)
    return {
        "parameters": {"name": name, "calibration_type": "eye_in_hand" if info.camera_on_flange else "eye_on_base",
                       "robot_base_frame": parent if not info.camera_on_flange else "base_link",
                       "robot_effector_frame": parent if info.camera_on_flange else "tool0",
                       "tracking_base_frame": child, "tracking_marker_frame": "calibration_target",
                       "freehand_robot_movement": True, "move_group_namespace": "/", "move_group": "manipulator"},
        "transform": {"translation": dict(zip("xyz", map(float, cal.X[:3, 3]))),
                      "rotation": dict(zip("xyzw", map(float, q)))},
    }


def in_tool_frame(cal: Calibration, tool2flange: NDArray[np.float64]) -> tuple[str, NDArray[np.float64]]:
    """The transform a robot program wants relative to its tool (TCP) frame rather than the flange,
    given ``tool2flange``: eye-in-hand the camera in the tool frame (``inv(tool2flange) @ X``),
    eye-to-hand the target in the tool frame (``inv(tool2flange) @ Z``). Returns its name and value."""
    if setup_info(cal.setup).camera_on_flange:
        return "cam2tool", invert(tool2flange) @ cal.X
    return "target2tool", invert(tool2flange) @ cal.Z


#: What ``write_exports`` can write besides result.json/yaml and report.html: name -> file name.
EXPORTS = {"ros2-launch": "handeye_static_tf.launch.py", "ros1-launch": "handeye_static_tf.launch",
           "easy-handeye": "handeye.calib"}


def check_exports(exports: Iterable[str]) -> list[str]:
    """``exports`` checked (keys of :data:`EXPORTS`, or 'all'), in order, each once."""
    exports = list(exports)
    exports = list(EXPORTS) if "all" in exports else list(dict.fromkeys(exports))
    unknown = [e for e in exports if e not in EXPORTS]
    if unknown:
        raise HandEyeError(f"unknown export(s) {', '.join(map(str, unknown))}; use {', '.join(EXPORTS)} or all")
    return exports


def write_exports(cal: Calibration, out_dir: str | Path, exports: Iterable[str], protect: Iterable[Path] = (),
                  parent_frame: str | None = None, child_frame: str | None = None) -> list[Path]:
    """Write the ``exports`` (keys of :data:`EXPORTS`; 'all' for every one) into ``out_dir``, atomically."""
    exports = check_exports(exports)
    parent, child = _frames_of(cal)
    parent, child = parent_frame or parent, child_frame or child
    paths = []
    for e in exports:
        path = Path(out_dir) / EXPORTS[e]
        text = {"ros2-launch": lambda: ros2_launch_file(cal.X, parent, child),
                "ros1-launch": lambda: ros1_launch_file(cal.X, parent, child),
                "easy-handeye": lambda: yaml.safe_dump(easy_handeye_calibration(cal, parent, child), sort_keys=False)}[e]()
        atomic_write(path, text, protect)
        paths.append(path)
    return paths


def _robot_format(T: NDArray[np.float64], cal: Calibration) -> dict[str, Any] | None:
    """``T`` written as the robot's own pose rows are (format and units of the robot poses given):
    to teach a work object or a tool from it."""
    ri = cal.robot_input
    if ri is None:
        return None
    return {"format": ri.format, "length_unit": ri.length_unit, "angle_unit": ri.angle_unit,
            "columns": pose_columns(ri.format),
            "values": format_poses(T[None], ri.format, ri.length_unit, ri.angle_unit)[0].tolist()}


def _euler_of_input(rot: Rotation, cal: Calibration) -> dict[str, Any] | None:
    ri = cal.robot_input
    if ri is None or not ri.format.startswith("euler:"):
        return None
    seq, deg = ri.format.split(":", 1)[1], ri.angle_unit == "deg"
    return {"sequence": seq, "unit": ri.angle_unit, "angles": euler_angles(rot, seq, deg).tolist(),
            "note": "the convention of the robot poses given (upper case intrinsic, lower case extrinsic)"}


def _transform_dict(T: NDArray[np.float64], cal: Calibration | None = None) -> dict[str, Any]:
    rot = Rotation.from_matrix(T[:3, :3])
    out = {
        "matrix": T.tolist(),
        "translation_m": T[:3, 3].tolist(),
        "translation_mm": (1e3 * T[:3, 3]).tolist(),
        "quaternion_wxyz": rot.as_quat(canonical=True, scalar_first=True).tolist(),
        "quaternion_xyzw": rot.as_quat(canonical=True).tolist(),
        "rotvec_rad": rot.as_rotvec().tolist(),
        "rotvec_deg": rot.as_rotvec(degrees=True).tolist(),
        "rpy_rad": euler_angles(rot, "xyz").tolist(),
        "rpy_note": "roll, pitch, yaw about fixed x, y, z (scipy 'xyz', URDF/ROS rpy)",
    }
    if cal is not None:
        euler = _euler_of_input(rot, cal)
        if euler is not None:
            out["euler_input_convention"] = euler
        robot = _robot_format(T, cal)
        if robot is not None:
            out["robot_format"] = robot
    return out


def _finite_or_none(v: NDArray[np.float64]) -> list[float | None]:
    """JSON has no infinity: an undetermined std is null (see ``unobservable``)."""
    return [float(x) if np.isfinite(x) else None for x in v]


def _determined(cal: Calibration) -> dict[str, str]:
    """Per parameter of X (rotation, translation x, y, z in X's parent frame): 'data', 'given' (a
    known value fixed it: named) or 'undetermined'."""
    x_name = setup_info(cal.setup).x_name
    out = {"rotation": "data"}
    given = [name for name, k in cal.known.items() if k["used"]]
    for k, axis in enumerate("xyz"):
        if cal.std is not None and np.isinf(cal.std[3 + k]):
            out[f"{x_name}.{axis}"] = "undetermined"
        elif given and cal.motion_kind != "general" and _along_open(cal, k):
            out[f"{x_name}.{axis}"] = "given (" + ", ".join(given) + ")"
        else:
            out[f"{x_name}.{axis}"] = "data"
    return out


def _along_open(cal: Calibration, k: int) -> bool:
    """Whether X's translation component ``k`` lies along a direction the motions cannot see (the
    robot's only rotation axis for one-axis motions; every direction for pure translations)."""
    if cal.motion_kind == "translation_only":
        return True
    axis = cal.motions.dq_a[:, 1:4] if cal.motions is not None else None
    if axis is None or not len(axis):
        return False
    e = np.linalg.eigh(axis.T @ axis)[1][:, -1]  # the robot's rotation axis, in X's parent frame
    return abs(e[k]) > 0.35


def _scale_dict(cal: Calibration) -> dict[str, Any]:
    """result.json's ``target_scale`` when the check found the target's size wrong, else nothing."""
    return {} if cal.target_scale == 1.0 else {"target_scale": {
        "factor": cal.target_scale, "std": cal.diagnostics.scale_std if cal.diagnostics is not None else None,
        "meaning": "the check found the target's given size wrong: X, Z, the camera's poses and the target's points "
                   "are for the target this many times the size given (the scale the robot's motions give)"}}


def _images_dict(cal: Calibration) -> dict[str, Any]:
    return {
        "images": {"used": list(cal.image_names), "reprojection_rms_px": cal.reprojection_rms.tolist(),
                   "skipped": [{"image": n, "reason": r} for n, r in cal.skipped],
                   # each used image's bytes: verify refuses to call the calibration's own images a second capture
                   "sha256": cal.image_sha256},
        "camera": {"source": cal.intrinsics_source, "K": cal.camera_matrix.tolist(), "dist": cal.dist_coeffs.tolist(),
                   "rms_px": cal.intrinsics_rms},
    }


def _uncertainty_dict(cal: Calibration) -> dict[str, Any]:
    out = {
        "std_rotation_deg": _finite_or_none(cal.std[:3]),
        "std_translation_mm": _finite_or_none(cal.std[3:]),
        "cov": [_finite_or_none(row) for row in cal.cov],
        "cov_parameters": "X: rotation vector increment (rad, left), translation (m)",
    }
    if cal.robot_accuracy is not None:
        out["robot_accuracy"] = {"rotation_deg": float(cal.robot_accuracy[0]), "translation_mm": float(cal.robot_accuracy[1]),
                                 "meaning": "per axis, the robot's absolute accuracy X's std includes"}
    if cal.std_sources is not None:
        out["sources"] = {k: (None if v is None else {"rotation_deg": _finite_or_none(v[:3]),
                                                      "translation_mm": _finite_or_none(v[3:])})
                          for k, v in cal.std_sources.items()}
    return out


def _sensor_dict(cal: Calibration) -> dict[str, Any]:
    """result.json's ``sensor``: the sensor and target, each view's residual (and held-out error), the
    sensor's own figures."""
    sf = cal.sensor
    return {"kind": sf.sensor, "target": sf.target, "views": list(sf.views),
            "residual_mm": [float(v) for v in sf.residual_mm],
            "heldout_mm": None if sf.heldout_mm is None else _finite_or_none(np.asarray(sf.heldout_mm)),
            "fit_rms_mm": sf.fit_rms_mm, "points": sf.points, "rejected_points": sf.rejected, "figures": sf.figures,
            "unknowns": list(sf.unknowns), **({"x_holds_with": _holds_with(sf.unknowns)} if sf.unknowns else {})}


def _holds_with(unknowns: list[dict[str, Any]]) -> str:
    """The sentence result.json says of the sensor's unknowns: X holds with them, as fitted or held."""
    words = [f"{u['name']} {u['value']:.6g}{' ' + u['unit'] if u['unit'] else ''} ({u['status']})" for u in unknowns]
    return ("X holds with these values of the sensor's unknowns applied to its measurements: " + ", ".join(words)
            + "; a held one's tolerance is in X's std (uncertainty.sources.held_unknowns)")


def _residuals_dict(cal: Calibration) -> dict[str, Any]:
    """The camera's poses: the motions' screw congruence and each pose's own Z (none without them)."""
    if cal.target2cam is None:
        return {}
    mres, pres = cal.motion_residuals, cal.pose_residuals
    out = {"motion_residuals": {"columns": ["angle_deg", "pitch_mm"], "median": np.median(mres, axis=0).tolist(),
                                "max": mres.max(axis=0).tolist(), "pitch_where_turning": dict(cal.pitch_where_turning)},
           "pose_residuals": {"columns": ["rotation_deg", "translation_mm"],
                              "pose_indices": [int(i) for i in (cal.pose_indices if cal.pose_indices is not None
                                                                 else range(len(pres)))],
                              "values": pres.tolist()}}
    if cal.image_names is not None:
        out["pose_residuals"]["images"] = list(cal.image_names)
    return out


def _poses_dict(cal: Calibration) -> dict[str, Any]:
    """The poses the calibration used (each a row of 16, the 4x4 row by row): what made it, so that it
    can be read back whole (:func:`handeye.load_result`) and checked again."""
    if cal.flange2base is None:
        return {}
    return {"poses": {"flange2base": np.asarray(cal.flange2base).reshape(-1, 16).tolist(),
                      "target2cam": None if cal.target2cam is None else np.asarray(cal.target2cam).reshape(-1, 16).tolist(),
                      "pairs": np.asarray(cal.pairs).tolist(),
                      "layout": "each pose a row of 16: the 4x4 matrix row by row, metres"}}


def _cross_validation_dict(cal: Calibration) -> dict[str, Any]:
    if cal.cross_validation is None:
        return {}
    meaning = ("RMS error of the target's points in views held out of the fit, predicted from the robot pose alone: "
               "pixels (with images) and millimetres at the target's distance; the number to trust for how well X and "
               "Z predict new views") if cal.sensor is None else (
               "RMS residual (mm) of the measurements of views held out of the fit, predicted from the robot alone: "
               "the number to trust for how well X predicts new views")
    return {"cross_validation": {"estimator": cal.estimator, "prediction_error": cal.prediction_error,
                                 "per_estimator": dict(cal.cross_validation), "folds": cal.cross_validation.folds,
                                 "meaning": meaning}}


def _check_dict(cal: Calibration) -> dict[str, Any]:
    if cal.diagnostics is None:
        return {"check": {"verdict": "not checked", "advice": []}}
    d = cal.diagnostics
    return {"check": {"verdict": cal.verdict, "outliers": list(d.outliers),
                      "pose_indices_used": [int(i) for i in cal.pose_indices], "n_poses": int(d.n_poses),
                      "names": None if d.names is None else list(d.names), "consistency": float(d.consistency),
                      "scale": d.scale, "scale_std": d.scale_std, "advice": list(d.advice)}}


def _extras_dict(cal: Calibration, tool2flange: NDArray[np.float64] | None) -> dict[str, Any]:
    """What only some calibrations have: a tool frame, known values, a certificate, two clocks, skipped views."""
    out: dict[str, Any] = {}
    if tool2flange is not None:
        name, T = in_tool_frame(cal, tool2flange)
        out["tool"] = {"tool2flange": _transform_dict(tool2flange), "name": name, "transform": _transform_dict(T, cal)}
    out["determined"] = _determined(cal)
    if cal.unobservable:
        out["unobservable"] = [u.as_dict() for u in cal.unobservable]
    if cal.known:
        out["known"] = {k: dict(v) for k, v in cal.known.items()}
    if cal.certificate is not None:
        out["certificate"] = cal.certificate.as_dict()
    if cal.time_offset is not None:
        out["time_sync"] = {"time_offset_s": cal.time_offset, "time_offset_std_s": cal.time_offset_std,
                            "meaning": "camera clock minus robot clock: the camera sample stamped t shows the robot "
                                       "at robot time t - time_offset",
                            **(cal.streams or {})}
    if cal.skipped and cal.image_names is None:
        out["skipped"] = [{"view": n, "reason": r} for n, r in cal.skipped]
    return out


def result_dict(cal: Calibration, parent_frame: str | None = None, child_frame: str | None = None,
                tool2flange: NDArray[np.float64] | None = None) -> dict[str, Any]:
    """A plain, JSON/YAML-ready description of a calibration (see the module docstring), the same keys
    for every sensor: ``X``, ``Z``, ``verdict``, ``uncertainty``, ``cross_validation``, ``check``,
    ``notes``; the camera's own under ``images`` and ``camera``, any other sensor's under ``sensor``.

    ``parent_frame`` / ``child_frame`` name the frames in the ROS snippets (defaults:
    :func:`default_frames`). ``tool2flange``: the robot's tool (TCP) frame in the flange frame;
    adds the camera (eye-in-hand) or the target (eye-to-hand) relative to that tool (``tool``).
    """
    info = setup_info(cal.setup)
    parent, child = _frames_of(cal)
    parent, child = parent_frame or parent, child_frame or child
    out: dict[str, Any] = {
        "handeye_version": __version__,
        "inputs_sha256": cal.inputs_sha256,
        "setup": cal.setup,
        "method": cal.method,
        "estimator": cal.estimator,
        "X_name": info.x_name,
        "X": _transform_dict(cal.X, cal),
        "X_inverse_name": info.x_inverse_name,
        "X_inverse": _transform_dict(invert(cal.X), cal),
        "Z_name": info.z_name,
        "Z": _transform_dict(cal.Z, cal) | ({} if cal.std_Z is None else {
            "std_rotation_deg": _finite_or_none(cal.std_Z[:3]), "std_translation_mm": _finite_or_none(cal.std_Z[3:])}),
        "ros": {
            "parent_frame": parent,
            "child_frame": child,
            "static_transform_publisher": ros2_static_transform_command(cal.X, parent, child),
            "urdf_joint": urdf_joint(cal.X, parent, child),
            "ros1_launch": ros1_launch_file(cal.X, parent, child),
        },
        "easy_handeye": easy_handeye_calibration(cal, parent, child),
        "verdict": cal.verdict,
        "n_poses": int(len(cal.flange2base)),
        "n_motions": int(len(cal.pairs)),
    }
    out.update(_residuals_dict(cal))
    if cal.sensor is not None:
        out["sensor"] = _sensor_dict(cal)
    if cal.image_names is not None:
        out.update(_images_dict(cal))
    out.update(_scale_dict(cal))
    if cal.kinematic is not None:
        out["kinematics"] = cal.kinematic.as_dict()
    out["refinement"] = {"type": cal.refinement}
    if cal.refined_rms is not None:
        out["refinement"]["rms_px"] = cal.refined_rms
    if cal.pose_noise is not None:
        out["refinement"]["pose_noise"] = dict(cal.pose_noise)
    if cal.cov is not None:
        out["uncertainty"] = _uncertainty_dict(cal)
    out.update(_cross_validation_dict(cal))
    out.update(_extras_dict(cal, tool2flange))
    out.update(_check_dict(cal))
    out["notes"] = list(cal.notes)
    out.update(_poses_dict(cal))
    return out


def write_results(cal: Calibration, out_dir: str | Path, protect: Iterable[Path] = (),
                  parent_frame: str | None = None, child_frame: str | None = None,
                  tool2flange: NDArray[np.float64] | None = None) -> list[Path]:
    """Write ``result.json`` and ``result.yaml`` into ``out_dir``; returns their paths.

    Each file is written atomically; none of the ``protect`` paths (the inputs) is overwritten.
    """
    out_dir = Path(out_dir)
    data = result_dict(cal, parent_frame, child_frame, tool2flange)
    protect = list(protect)
    paths = [out_dir / "result.json", out_dir / "result.yaml"]
    atomic_write(paths[0], json.dumps(data, indent=2) + "\n", protect)
    atomic_write(paths[1], dump_yaml(data, sort_keys=False, width=1000), protect)
    if cal.kinematic is not None:  # the corrected table, as handeye.robot.kinematics.load_arm (and --arm) read it
        k = cal.kinematic
        paths.append(out_dir / "arm_corrected.yaml")
        atomic_write(paths[-1], chain_yaml(replace(k.chain, name=f"{k.nominal.name} (corrected)"),
                                           f"{k.nominal.name}'s table corrected by handeye's calibration from joint angles "
                                           f"({len(k.names)} entries fitted, {len(k.undetermined)} held near nominal)."
                                           f"\nNominal table: {k.nominal.source or k.nominal.name}"), protect)
        paths.append(out_dir / "arm_corrected.urdf")
        atomic_write(paths[-1], chain_urdf(replace(k.chain, name=f"{k.nominal.name}_corrected")), protect)
    return paths
