"""The real captures in ../shared/data/real, read into :class:`handeye.estimation.validation.Views`.

Used by the real-data tests and by ``benchmarks/bench_realdata.py``. Image sets become session
folders (images copied, never into the repository) in a scratch folder the caller owns, then go through
:func:`handeye.pipelines.calibration.observe` (detection, PnP, symmetric targets), as ``handeye calibrate``
does. Each loader says how its files are read; the ABOUT.md of each set gives the conventions.
"""

from __future__ import annotations

import shutil
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import yaml
from scipy.spatial.transform import Rotation, Slerp

import handeye
from handeye.estimation.validation import Fit, Views
from handeye.frames.setups import constant_transforms
from handeye.geometry.se3 import from_rotvec_translation, invert, make_transform, mean_transform
from handeye.io.session import load_session, write_pose_table, write_session
from handeye.pipelines.calibration import Observations, calibrate_observed, observe

REAL_DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "real"

VISP_K_2025 = [[607.5931396484375, 0, 323.46282958984375], [0, 607.574951171875, 243.25529479980469], [0, 0, 1]]
VISP_K_2022 = [[605.146728515625, 0, 325.53253173828125], [0, 604.79150390625, 244.95083618164062], [0, 0, 1]]


@dataclass(frozen=True)
class RealSet:
    """One real capture: its views, and the session folder when it has images."""

    name: str
    views: Views
    observations: Observations | None = None  #: what handeye.pipelines.calibration.observe made of the images


def _session(scratch: Path, setup, target, K, names, images, flange2base) -> Path:
    folder = scratch
    (folder / "images").mkdir(parents=True)
    for name, src in zip(names, images):  # copies: a session reads no file outside its folder, links resolved
        shutil.copyfile(src, folder / "images" / name)
    write_session(folder, setup, target, names, np.asarray(flange2base), "matrix", "m", "rad", camera=(K, [0.0] * 5))
    return folder


def _observed(name: str, folder: Path) -> RealSet:
    obs = observe(load_session(folder), progress=False)
    views = obs.views()
    return RealSet(name, views, obs)


def _visp_pose(path: Path):
    v = np.array(yaml.safe_load(path.read_text())["data"], dtype=float).ravel()
    return from_rotvec_translation(v[3:], v[:3])  # vpPoseVector: t, theta-u


def visp_2025(kind: str, scratch: Path) -> RealSet:
    """ViSP's Franka 2025 sets: eye-in-hand chessboard 9x6 / 23.6 mm, or eye-to-hand AprilTag 48 mm id 10."""
    src = REAL_DATA / "visp-franka" / f"{kind}_2025"
    f2b = [_visp_pose(src / f"franka_pose_rPe_{i}.yaml") for i in range(1, 9)]
    names = [f"franka_image-{i}.png" for i in range(1, 9)]
    if kind == "eye_in_hand":
        target = {"type": "chessboard", "cols": 9, "rows": 6, "square": 0.0236}
    else:
        target = {"type": "apriltag", "square": 0.048, "id": 10, "dictionary": "DICT_APRILTAG_36h11"}
    return _observed(f"visp_{kind}_2025", _session(scratch, kind, target, VISP_K_2025, names,
                                                   [src / n for n in names], f2b))


def visp_2022(scratch: Path) -> RealSet:
    """ViSP's 2022 eye-in-hand set: chessboard 9x6, 26.2 mm squares, intrinsics of its camera.xml."""
    src = REAL_DATA / "visp-franka" / "legacy_eye_in_hand_2022"
    f2b = [_visp_pose(src / f"pose_fPe_{i}.yaml") for i in range(1, 9)]
    names = [f"image-{i}.png" for i in range(1, 9)]
    target = {"type": "chessboard", "cols": 9, "rows": 6, "square": 0.0262}
    return _observed("visp_eye_in_hand_2022", _session(scratch, "eye_in_hand", target, VISP_K_2022, names,
                                                       [src / n for n in names], f2b))


def visp_2018() -> RealSet:
    """ViSP's 2018 pose pairs: flange2base (fPe) and target2cam (cPo), eye-in-hand."""
    src = REAL_DATA / "visp-franka" / "legacy_posepairs_2018"
    f2b = np.array([_visp_pose(src / f"pose_fPe_{i}.yaml") for i in range(1, 9)])
    t2c = np.array([_visp_pose(src / f"pose_cPo_{i}.yaml") for i in range(1, 9)])
    return RealSet("visp_posepairs_2018", Views(f2b, t2c, "eye_in_hand"))


def industrial(kind: str, scratch: Path) -> RealSet:
    """ROS-Industrial's sets: 'charuco' (eye-to-hand, 16 images 1600x1200) or '10x10' (eye-in-hand
    modified circle grid, 15 images, nominal intrinsics). Images pair with poses by the listed names."""
    src = REAL_DATA / "industrial-calibration" / f"test_set_{kind}"
    data = yaml.safe_load((src / "cal_data.yaml").read_text())
    names, images, f2b = [], [], []
    for item in data["data"]:
        p = yaml.safe_load((src / item["pose"]).read_text())
        f2b.append(handeye.parse_poses([[p["x"], p["y"], p["z"], p["qx"], p["qy"], p["qz"], p["qw"]]], "quat_xyzw")[0])
        names.append(Path(item["image"]).name)
        images.append(src / item["image"])
    if kind == "charuco":
        K = [[1352.02747, 0, 789.67065], [0, 1356.14287, 627.2995], [0, 0, 1]]
        target = {"type": "charuco", "cols": 5, "rows": 7, "square": 0.036195, "marker": 0.018256,
                  "dictionary": "DICT_6X6_250"}
        setup = "eye_to_hand"
    else:
        K = [[550.0, 0, 320.0], [0, 550.0, 240.0], [0, 0, 1]]
        target = {"type": "modified_circles", "cols": 10, "rows": 10, "square": 0.0254}
        setup = "eye_in_hand"
    return _observed(f"industrial_{kind}", _session(scratch, setup, target, K, names, images, f2b))


def tabb() -> RealSet:
    """Tabb & Ahmad Yousef's dataset 1 (88 pose pairs, mm; robot matrices are base2hand)."""
    src = REAL_DATA / "tabb-ds1-posepairs"
    Bm = np.loadtxt(src / "robot_cali_B_3x4.txt")
    Am = np.loadtxt(src / "cali_A_R9_t3.txt")
    base2hand = np.tile(np.eye(4), (len(Bm), 1, 1))
    base2hand[:, :3, :] = Bm.reshape(-1, 3, 4)
    base2hand[:, :3, 3] /= 1e3
    t2c = make_transform(Am[:, :9].reshape(-1, 3, 3), Am[:, 9:] / 1e3)
    f2b = handeye.frames.poses.validate_transforms(invert(base2hand))
    return RealSet("tabb_ds1", Views(f2b, handeye.frames.poses.validate_transforms(t2c), "eye_in_hand"))


def eth(step: int = 15) -> RealSet:
    """ETH's robot-arm streams paired by time: the 50 Hz robot stream interpolated (Slerp and linear)
    at every ``step``-th camera time, clocks taken as equal (the offset is the streams issue's)."""
    src = REAL_DATA / "ethz-robot-arm-posepairs"
    robot = np.loadtxt(src / "robot_arm_complete_bag_color_and_ir_base_link_sr300_hinge.csv", delimiter=",")
    cam = np.loadtxt(src / "robot_arm_complete_bag_color_and_ir_target_ir.csv", delimiter=",")
    cam = cam[(cam[:, 0] > robot[0, 0]) & (cam[:, 0] < robot[-1, 0])][::step]
    rot = Slerp(robot[:, 0], Rotation.from_quat(robot[:, 4:8]))(cam[:, 0])
    pos = np.stack([np.interp(cam[:, 0], robot[:, 0], robot[:, k]) for k in (1, 2, 3)], axis=1)
    f2b = make_transform(rot.as_matrix(), pos)
    cam2target = make_transform(Rotation.from_quat(cam[:, 4:8]).as_matrix(), cam[:, 1:4])
    return RealSet("eth_robot_arm", Views(f2b, invert(cam2target), "eye_in_hand"))


def load_all(scratch: Path, names: list[str] | None = None) -> list[RealSet]:
    """Every real set (or those named), image sets observed in folders under ``scratch``."""
    loaders = {
        "visp_eye_in_hand_2025": lambda: visp_2025("eye_in_hand", scratch / "visp_eih_2025"),
        "visp_eye_to_hand_2025": lambda: visp_2025("eye_to_hand", scratch / "visp_eth_2025"),
        "visp_eye_in_hand_2022": lambda: visp_2022(scratch / "visp_eih_2022"),
        "visp_posepairs_2018": visp_2018,
        "industrial_charuco": lambda: industrial("charuco", scratch / "ind_charuco"),
        "industrial_10x10": lambda: industrial("10x10", scratch / "ind_10x10"),
        "tabb_ds1": tabb,
        "eth_robot_arm": eth,
    }
    return [loaders[n]() for n in (names or list(loaders))]


#: OpenCV's AX = XB methods, by name.
OPENCV_METHODS = {"TSAI": "CALIB_HAND_EYE_TSAI", "PARK": "CALIB_HAND_EYE_PARK", "HORAUD": "CALIB_HAND_EYE_HORAUD",
                  "ANDREFF": "CALIB_HAND_EYE_ANDREFF", "DANIILIDIS": "CALIB_HAND_EYE_DANIILIDIS"}


def opencv_fit(name: str) -> Fit:
    """``cv2.calibrateHandEye`` with one method on OpenCV's own pipeline (the same PnP poses), Z the
    mean of the per-pose Z_i as handeye's closed forms do. Eye-to-hand gets the inverted robot poses."""
    method = getattr(cv2, OPENCV_METHODS[name])

    def fit(flange2base, target2cam, setup, idx):
        g2b = flange2base if setup == "eye_in_hand" else invert(flange2base)
        R, t = cv2.calibrateHandEye(list(g2b[:, :3, :3]), list(g2b[:, :3, 3]), list(target2cam[:, :3, :3]),
                                    list(target2cam[:, :3, 3]), method=method)
        X = make_transform(R, t.ravel())
        if not np.isfinite(X).all():
            raise handeye.HandEyeError(f"OpenCV {name} returned NaN")
        return X, mean_transform(constant_transforms(X, flange2base, target2cam, setup))
    return fit


def handeye_fit(rs: RealSet) -> Fit:
    """handeye's default pipeline on a part of a real set, as a user would run it on those views:
    ``calibrate`` on the images (check, choice of the estimator by inner cross-validation), or
    ``calibrate_poses`` on pose pairs. The std is not needed here, so its jackknife is skipped."""
    def fit(flange2base, target2cam, setup, idx):
        if rs.observations is not None:
            cal = calibrate_observed(rs.observations.subset(idx), uncertainty=False)
            return cal.X, cal.Z, cal.camera_matrix, cal.dist_coeffs, cal.target_scale
        cal = handeye.calibrate_poses(flange2base, target2cam, setup)
        return cal.X, cal.Z
    return fit


def _one_thread() -> None:
    """Worker initializer: BLAS and OpenCV on one thread each. It runs after this module's imports
    (numpy, scipy, OpenCV) in the worker, so the limit reaches every library already loaded."""
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)
    cv2.setNumThreads(1)


def worker_pool(workers: int = 2):
    """A process pool whose workers run one BLAS thread each: two processes each running a
    multi-threaded BLAS on two cores fight over them (measured: a 200-session fixture 68 -> ~35 s).
    Workers start from a fork server, not from this process: a test that ran OpenCV's detectors
    here leaves OpenCV's thread pool behind, and a child forked from it hangs in its next OpenCV
    call (seen: the real-data fixture after the printing tests)."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    return ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("forkserver"), initializer=_one_thread)


#: RegHEC's objects (../shared/data/real/reghec, ABOUT.md): five scanned from the same 9 poses by
#: the camera on the flange, and a gripper with poses of its own.
REGHEC_SHARED = ("Cone", "Cylinder", "Sphere", "Plane", "Duck")


def reghec_session(obj: str, scratch: Path, setup: str = "eye_in_hand") -> Path:
    """One of RegHEC's objects as a depth session with ``target: {type: scene}`` in ``scratch``: its
    nine clouds copied into ``clouds/`` (a session reads only files inside its folder, links
    resolved, so links into the shared data would be refused), ``RobotPoses.dat`` (per row ``a,b,c,x,y,z,``:
    R = Rz(c) Ry(b) Rx(a), i.e. scipy's extrinsic "xyz" with [a, b, c], radians; the translation in
    mm, as the source's RegHEC.cpp reads it) written as ``poses.csv``."""
    src = REAL_DATA / "reghec" / obj
    rows = [line.strip().rstrip(",").split(",") for line in (src / "RobotPoses.dat").read_text().splitlines() if line.strip()]
    v = np.array(rows, float)
    flange2base = make_transform(Rotation.from_euler("xyz", v[:, :3]).as_matrix(), v[:, 3:] / 1e3)
    folder = Path(scratch)
    (folder / "clouds").mkdir(parents=True)
    names = [f"view{k + 1}d.pcd" for k in range(len(v))]
    for name in names:
        shutil.copyfile(src / name, folder / "clouds" / name)
    write_pose_table(folder / "poses.csv", names, flange2base, "quat_wxyz", "mm", "deg", id_column="cloud")
    spec = {"setup": setup, "target": {"type": "scene"}, "depth": {"unit": "m"},
            "poses": {"file": "poses.csv", "format": "quat_wxyz", "length_unit": "mm", "angle_unit": "deg"}}
    (folder / "session.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
    return folder
