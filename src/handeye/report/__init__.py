"""Files for robots and people from a :class:`~handeye.result.Calibration`.

* :mod:`handeye.report.files`: ``result.json`` / ``result.yaml`` (:func:`result_dict`) and the ROS 2
  snippets (:func:`ros2_static_transform_command`, :func:`urdf_joint`);
* :mod:`handeye.report.html`: the self-contained ``report.html`` (:func:`report_html`);
* :func:`write_calibration`: all of them into one folder, atomically, never over an input.
"""

from __future__ import annotations

from pathlib import Path
from typing import Iterable

import numpy as np
from numpy.typing import NDArray

from .._shared.io import atomic_write, check_output_folder
from ..estimation.diagnostics import compare_solvers
from ..pipelines.kinds import joins_sensors, kind_of_model
from ..result import Calibration
from .files import (
    EXPORTS,
    check_exports,
    default_frames,
    result_dict,
    ros2_rig_launch_file,
    ros2_static_transform_command,
    urdf_joint,
    write_exports,
    write_results,
)
from .html import SECTIONS, report_html, write_report
from .verification import verification_html, write_verification

__all__ = ["write_calibration", "result_dict", "write_results", "report_html", "write_report", "default_frames",
           "ros2_static_transform_command", "urdf_joint", "SECTIONS", "EXPORTS", "write_exports",
           "verification_html", "write_verification"]


def write_calibration(cal: Calibration, out_dir: str | Path, *, protect: Iterable[str | Path] = (), report: bool = True,
                      compare: bool = True, parent_frame: str | None = None,
                      child_frame: str | None = None, exports: Iterable[str] = (),
                      tool2flange: NDArray[np.float64] | None = None) -> list[Path]:
    """Write ``result.json``, ``result.yaml`` and (``report``) ``report.html`` into ``out_dir``.

    Every file is written atomically. The folder is checked first
    (:func:`handeye._shared.io.check_output_folder`): never a file, never inside the folder the
    inputs came from (``cal.input_folder``), writable. ``protect``: paths never to overwrite; the
    input images are always protected. ``compare``: draw every solver on the same data in the report
    (``cal.solver_comparison``, or computed here by :func:`handeye.estimation.diagnostics.compare_solvers`
    when it holds none). ``parent_frame`` / ``child_frame`` name the frames of the ROS snippets
    (default ``tool0`` or ``base_link``, and ``camera_optical_frame``, a laser profiler's
    ``laser_profiler_optical_frame``). ``exports``: more files for
    robot software (keys of :data:`EXPORTS`: a ROS 2 launch file, a ROS 1 / MoveIt launch file,
    easy_handeye2's .calib; 'all'). ``tool2flange``: the robot's tool (TCP) frame, so that the
    result files also give the camera (eye-in-hand) or the target (eye-to-hand) relative to it.
    A rig's calibration (:func:`handeye.pipelines.rig.pipeline.calibrate_rig_session`) also gets
    ``rig_static_tf.launch.py`` and each sensor's own ``sensors/<name>/result.json`` and ``.yaml``
    (:func:`handeye.pipelines.rig.pipeline.rig_members`). Returns the paths written, the report last.

    Examples
    --------
    >>> import tempfile, handeye
    >>> from handeye.simulate import random_scene
    >>> scene = random_scene(8, "eye_in_hand", rng=0)
    >>> cal = handeye.calibrate_poses(scene.flange2base, scene.target2cam, progress=False)
    >>> [p.name for p in handeye.write_calibration(cal, tempfile.mkdtemp(), report=False)]
    ['result.json', 'result.yaml']
    """
    inputs = [cal.input_folder] if cal.input_folder is not None else []
    exports = check_exports(exports)  # before any file is written
    out_dir = check_output_folder(out_dir, inputs)
    protect = list(protect) + list(cal.image_paths or [])
    paths = write_results(cal, out_dir, protect, parent_frame, child_frame, tool2flange)
    paths += write_exports(cal, out_dir, exports, protect, parent_frame, child_frame) if exports else []
    if joins_sensors(cal):  # a rig: every sensor's frame
        frames = {n: np.asarray(f["X"]) for n, f in cal.sensor.figures["X_per_sensor"].items()}
        path = out_dir / "rig_static_tf.launch.py"
        atomic_write(path, ros2_rig_launch_file(frames, parent_frame or default_frames(cal.setup)[0]), protect)
        paths.append(path)
        kind = kind_of_model(cal.sensor.sensor)  # its kind's hook: each sensor's own result (its import is heavy)
        for name, member in (kind.hook("members")(cal).items() if kind is not None and kind.members else ()):
            # each sensor's own result files, as one sensor's calibration writes them
            paths += write_results(member, out_dir / "sensors" / name, protect, parent_frame, f"{name}_optical_frame", tool2flange)
    if report:
        rows = None
        if compare:
            rows = cal.solver_comparison
            if rows is None and cal.target2cam is not None:
                rows = compare_solvers(cal.flange2base, cal.target2cam, cal.setup, cal.X, cal.pairs)
        paths.append(write_report(cal, out_dir / "report.html", protect, parent_frame, child_frame, rows))
    return paths
