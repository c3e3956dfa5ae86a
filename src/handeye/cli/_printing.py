"""How the commands print a calibration on the terminal."""

from __future__ import annotations

import shutil
import sys
import textwrap

import numpy as np
from scipy.spatial.transform import Rotation

from ..estimation.verdict import headline
from ..frames.setups import pose_name, setup_info
from ..pipelines.kinds import joins_sensors
from ..result import Calibration
from ..robot.kinematics import display_unit


def wrapped(text: str, prefix: str, stream=None) -> str:
    """``prefix + text`` folded to the terminal's width, the lines after the first indented, when
    ``stream`` (default stdout) is a terminal; one line otherwise (logs and pipes keep a note per
    line, for grep)."""
    stream = stream or sys.stdout
    if not getattr(stream, "isatty", lambda: False)():
        return prefix + text
    width = max(shutil.get_terminal_size((100, 24)).columns - 1, 40)
    return textwrap.fill(text, width, initial_indent=prefix, subsequent_indent="  ", break_on_hyphens=False,
                         break_long_words=False)


def fmt_vec(v: np.ndarray, digits: int = 6) -> str:
    return "[" + ", ".join(f"{x: .{digits}f}" for x in v) + "]"


def std_label(cal: Calibration) -> str:
    """What the std of X comes from, in words: the estimator and the parts it adds up."""
    who = cal.estimator or cal.method
    who = f"{who} refinement" if who in ("pose", "reprojection") else who
    parts = [k.replace("_", " ") for k, v in (cal.std_sources or {}).items() if v is not None and k != "data"]
    return who + (f": {' + '.join(parts)}" if parts else "")


def print_calibration(cal: Calibration, out=None) -> None:
    """Print X in the forms people paste into robot programs, and the residual summary."""
    info = setup_info(cal.setup)
    x_name, z_name = info.x_name, info.z_name
    rot = Rotation.from_matrix(cal.X[:3, :3])
    w = (out or sys.stdout).write
    d = cal.diagnostics
    if d is not None and d.verdict == "inconsistent":  # the fix first: X below is not a result to use
        w(f"INCONSISTENT DATA: {d.advice[0] if d.advice else 'the poses do not agree on one X'}\n"
          + "".join(f"  also: {a}\n" for a in d.advice[1:])
          + ("X below is what the data give as declared, to compare after the fix; do not use it.\n\n"
             if cal.target_scale == 1.0 else
             f"X below is for the target {cal.target_scale:.4f} times the size declared (the scale the robot's motions "
             "give); fix the size and calibrate again before you use it.\n\n"))
    what = "camera" if cal.sensor is None else "sensor"
    w(f"{cal.setup}: X = {x_name} (maps {what} coordinates into the {info.x_parent} frame), method {cal.method}, "
      + (f"{len(cal.flange2base)} poses, {len(cal.pairs)} motions\n\n" if cal.sensor is None else
         f"{len(cal.flange2base)} views\n\n"))
    with np.printoptions(precision=6, suppress=True, floatmode="fixed", sign=" "):
        w(f"{x_name} (4x4, metres):\n{cal.X}\n\n")
    w(f"translation      m : {fmt_vec(cal.X[:3, 3])}\n")
    w(f"translation     mm : {fmt_vec(1e3 * cal.X[:3, 3], 3)}\n")
    w(f"quaternion    wxyz : {fmt_vec(rot.as_quat(canonical=True, scalar_first=True))}\n")
    w(f"rotation vec   rad : {fmt_vec(rot.as_rotvec())}\n")
    w(f"rotation vec   deg : {fmt_vec(rot.as_rotvec(degrees=True), 4)}\n\n")
    w(f"{z_name} translation mm : {fmt_vec(1e3 * cal.Z[:3, 3], 3)}\n")
    if cal.std_Z is not None:
        rot = "not defined" if np.isnan(cal.std_Z[:3]).all() else f"{fmt_vec(cal.std_Z[:3], 4)} deg"
        w(f"std of {z_name}: rotation {rot}, translation {fmt_vec(cal.std_Z[3:], 3)} mm\n")
    pres = cal.pose_residuals
    if len(pres):  # the camera's poses: the motions' screw congruence and each pose's own Z
        w(f"screw congruence per motion (|angle_A - angle_B|; |pitch_A - pitch_B| as a share of the motion's "
          f"translation; both 0 for consistent data): {cal.screw_congruence_text()}\n")
        worst = int(np.argmax(pres[:, 1]))
        w(f"{z_name} consistency per pose: median {np.median(pres[:, 0]):.3f} deg / {np.median(pres[:, 1]):.3f} mm, "
          f"worst {cal.pose_name(worst)}: {pres[worst, 0]:.3f} deg / {pres[worst, 1]:.3f} mm\n")
    if cal.std is not None:
        w(f"std of X ({std_label(cal)}): rotation {fmt_vec(cal.std[:3], 4)} deg, "
          f"translation {fmt_vec(cal.std[3:], 3)} mm" + (" (inf: not determined by the data)"
                                                        if np.isinf(cal.std).any() else "") + "\n")
    else:  # uncertainty skipped (or too few poses to refit without one, and an exact robot): say so
        w(f"std of X: not computed ({cal.method}): the check below judges the poses, not how far X can be trusted\n")
    if joins_sensors(cal):
        _print_rig(cal, w)
    if cal.kinematic is not None:
        k = cal.kinematic
        big = np.argsort(-np.abs(k.correction / k.prior_std))[:4]
        w(f"arm table ({k.nominal.name}): {int(k.determined.sum())} of {len(k.names)} entries determined; the corrected "
          f"table moves the flange {k.flange_shift_mm[0]:.2f} mm (median; up to {k.flange_shift_mm[1]:.2f}) from the "
          "nominal one; largest corrections: " + ", ".join(
              f"{k.names[i]} {_entry(k.names[i], k.correction[i])} +- {_entry(k.names[i], k.std[i])}" for i in big)
          + " (all in result.json; the table in arm_corrected.yaml)\n")
        if k.accuracy_mm is not None:
            a = k.accuracy_mm
            w(f"arm accuracy at the flange within the capture's joint ranges: nominal table {a['before_median']:.2f} mm "
              f"(median; up to {a['before_max']:.2f}), corrected {a['after_median']:.3f} mm (predicted by the fit, "
              f"1 std; up to {a['after_max']:.3f})\n")
            if "workspace_after_median" in a:
                w(f"  over the joints' whole range (limits; beyond the capture's: extrapolated): nominal table "
                  f"{a['workspace_before_median']:.2f} mm (median; up to {a['workspace_before_max']:.2f}), corrected "
                  f"{a['workspace_after_median']:.3f} mm (1 std; up to {a['workspace_after_max']:.3f})\n")
    for u in cal.unobservable:
        w(f"NOT DETERMINED: {u.parameter}; set to {u.choice}. {u.coupled[:1].upper() + u.coupled[1:]}. To fix: {u.fix}\n")
    for name, k in cal.known.items():
        w(f"known {name} = {k['value_m']:.5f} +- {k['std_m']:.5f} m: "
          + ("used (the data cannot determine it)\n" if k["used"] else f"not used (the data give {k['data_m']:.5f} m)\n"))
    if cal.time_offset is not None:
        w(f"clock offset (camera minus robot): {1e3 * cal.time_offset:.2f} +- {1e3 * cal.time_offset_std:.2f} ms "
          f"({len(cal.streams['keyframe_camera_times_s'])} keyframes of {cal.streams['camera_samples']} camera and "
          f"{cal.streams['robot_samples']} robot samples)\n")
    if cal.pose_noise is not None:
        w(f"pose noise estimated from the data (per axis): {cal.pose_noise_text()}\n")
    if cal.prediction_error is not None:
        pe = cal.prediction_error
        w(f"held-out prediction error ({cal.estimator}, cross-validated): "
          + (f"{pe['px']:.3f} px, " if pe.get("px") is not None else "") + f"{pe['mm']:.3f} mm at the target\n")
    if cal.diagnostics is not None:
        left, _ = cal.outliers_split()  # images: listed as skipped, and those put back in a note
        d = cal.diagnostics
        w(f"check: {d.verdict}" + (f" ({headline(cal)})" if cal.verdict == "weak" else "")
          + (f"; left out as outliers: {d.pose_names(left)}" if left and not cal.image_names and cal.sensor is None else "")
          + "\n")
    for note in cal.notes:
        w(wrapped(note, "note: ", out) + "\n")


def _print_rig(cal: Calibration, w) -> None:
    """A rig's every sensor: its X from the joint fit (or its own, when it was left out) and its pose
    relative to the first sensor, each with its std."""
    f = cal.sensor.figures
    joint = list(f["X_per_sensor"])
    parent = setup_info(cal.setup).x_name.split("2", 1)[1]
    width = max(len(pose_name(n, parent)) for n in list(joint) + list(f.get("alone", {})))

    def line(name: str, T, std, tail: str = "") -> None:
        rot = Rotation.from_matrix(np.asarray(T, float)[:3, :3]).as_rotvec(degrees=True)
        w(f"  {name:<{width}}  translation mm {fmt_vec(1e3 * np.asarray(T, float)[:3, 3], 3)}, rotation vec deg "
          f"{fmt_vec(rot, 4)}" + ("" if std is None else f"; std {fmt_vec(std[:3], 4)} deg, {fmt_vec(std[3:], 3)} mm")
          + tail + "\n")
    w(f"every sensor of the rig (X of each from the joint fit of {', '.join(joint)}, its std with the robot's accuracy; "
      f"the first, {joint[0]}, is X above):\n")
    for name in joint:
        s = f["X_per_sensor"][name]
        line(pose_name(name, parent), s["X"], np.asarray(s["std_deg_mm"], float))
    for name in joint[1:]:
        rel = f.get("relative", {}).get(pose_name(name, joint[0]))
        if rel is not None:
            line(pose_name(name, joint[0]), rel["matrix"], np.asarray(rel["std_deg_mm"], float),
                 " (the robot's error cancels in it)")
    for name, own in f.get("alone", {}).items():
        if name not in joint:
            line(pose_name(name, parent), own["X"], None if own.get("std_deg_mm") is None else np.asarray(own["std_deg_mm"], float),
                 f" (left out of the joint fit: its own calibration, {own.get('verdict')})")


def _entry(name: str, value: float) -> str:
    """A table entry's value in mm, deg or (compliance) deg/m."""
    f, unit = display_unit(name)
    return f"{f * value:.{3 if unit == 'mm' else 4}f} {unit}"


def print_image_summary(cal: Calibration) -> None:
    n_used, n_skip = len(cal.image_names or []), len(cal.skipped)
    print(f"images: {n_used} used, {n_skip} skipped")
    for name, reason in cal.skipped:
        print(f"  skipped {name}: {reason}")
    if cal.intrinsics_source.startswith("estimated"):
        print(f"intrinsics: {cal.intrinsics_source} (camera calibration RMS {cal.intrinsics_rms:.3f} px)")
    else:
        print("intrinsics: from session.yaml")
    rms = cal.reprojection_rms
    worst = int(np.argmax(rms))
    print(f"PnP reprojection RMS per image: median {np.median(rms):.3f} px, worst {cal.image_names[worst]} {rms[worst]:.3f} px")
    if cal.refinement == "reprojection":
        print(f"refined X and Z on the pixel errors of all target points: RMS {cal.refined_rms:.3f} px")
    print()


def print_sensor_views(cal: Calibration, out=None) -> None:
    """A sensor's fit (depth, laser, ...): how many views it used, each view's residual (and held-out
    error), the views not used with why, and the sensor's own figures."""
    sf = cal.sensor
    w = (out or sys.stdout).write
    total = len(sf.views) + len(cal.skipped)
    w(f"{sf.sensor} ({sf.target}): {len(sf.views)} of {total} views used; {sf.points} measurements, {sf.rejected} set aside "
      f"as outliers; fit {sf.fit_rms_mm:.3f} mm RMS\n")
    held = sf.heldout_mm if sf.heldout_mm is not None else [None] * len(sf.views)
    for name, r, h in zip(sf.views, sf.residual_mm, held):
        w(f"  {name:<24} {r:7.3f} mm" + ("" if h is None or not np.isfinite(h) else f"   held out {h:7.3f} mm") + "\n")
    for name, why in cal.skipped:
        w(f"  {name:<24} left out: {why}\n")
    for key, value in sf.figures.items():
        if isinstance(value, dict) and "value" in value:
            w(f"{key.replace('_', ' ')}: {value['value']:.6g} +- {value['std']:.3g}"
              + ("" if value.get("fitted", True) else " (not fitted)") + "\n")
    w("\n")


def print_next_views(cal: Calibration, views) -> str:
    """Print the proposed joint configurations (``handeye.planning.joints.JointViews``) and return
    them as next_views.csv's text (a view column, then one column per joint, degrees)."""
    k = cal.kinematic
    names = list(k.nominal.joint_names or [f"joint{j + 1}" for j in range(k.nominal.n_joints)])
    text = "view," + ",".join(names) + "\n" + "".join(
        f"{i + 1}," + ",".join(f"{v:.3f}" for v in np.degrees(row)) + "\n" for i, row in enumerate(views.joints))
    if views.aim == "X":
        print(f"next views: X's std ({1e3 * views.x_std_before:.2f} mm) is {views.x_std_before / views.x_std_table_known:.1f}x "
              "what this capture would give with the arm's table known: the joints moved too little to tell the table's "
              f"errors from X. {len(views.joints)} joint configurations (degrees) where the camera sees the target, "
              f"moving the joints further, would bring it to {1e3 * views.x_std_after:.2f} mm (predicted):")
    else:
        print(f"next views: {len(views.joints)} joint configurations (degrees) where the camera sees the target and "
              f"{', '.join(views.determined_after) or 'none of the undetermined entries'} would be determined (posterior "
              "std under half the prior's, predicted):")
    print(text.rstrip())
    return text
