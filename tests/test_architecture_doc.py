"""docs/architecture.md is true to the code: every session.yaml (and posepairs.yaml) it shows is read
by its reader from a folder made to match it, the readers refuse an unknown key in every mapping the
page says they check and ignore one in those it says they do not, result.json's keys are those
its tables name, and section 6's table has one row per registered sensor kind, with its names, hooks
and two folders."""

from __future__ import annotations

import copy
import fnmatch
import re
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

import handeye
from handeye.errors import HandEyeError
from handeye.estimation.core import estimate
from handeye.geometry.se3 import invert, make_transform
from handeye.io.session import load_pose_pairs, load_session, write_joint_table, write_pose_table
from handeye.pipelines.depth.session import load_depth_session
from handeye.pipelines.depth.simulate_board import sphere_scene
from handeye.pipelines.kinds import sensor_kinds
from handeye.pipelines.laser.session import load_laser_session
from handeye.pipelines.linescan.session import load_linescan_session
from handeye.pipelines.rig.session import load_rig_session
from handeye.pipelines.silhouette.session import load_silhouette_session
from handeye.report.files import result_dict
from handeye.robot.kinematics import load_arm
from handeye.robot.models import ControllerPoses
from handeye.sensors.camera.targets import target_types
from handeye.sensors.depth.model import SphereCentres
from handeye.simulate import random_scene

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src" / "handeye"
DOC = ROOT / "docs" / "architecture.md"
FILES = ROOT / "src" / "handeye" / "report" / "files.py"

READERS = {"images": load_session, "posepairs": load_pose_pairs, "depth": load_depth_session, "laser": load_laser_session,
           "linescan": load_linescan_session, "silhouette": load_silhouette_session, "rig": load_rig_session}
#: The mappings whose keys the readers do not check, as the page says ("The mappings whose keys are not
#: checked today"): ``reader:path``, a mapping with a ``type`` as ``path:type``.
BOARDS = target_types()
UNCHECKED = (["posepairs:*", "*:unknowns", "rig:sensors.*.camera", "depth:target:sphere"]
             + [f"{reader}:{path}:{t}" for t in BOARDS for reader, path in
                [("images", "target"), ("linescan", "target"), ("depth", "target"), ("rig", "target"),
                 ("rig", "sensors.*.target")]])
N = 4
BOGUS = "zz_not_a_key"


def _blocks() -> list[tuple[str, dict]]:
    found = re.findall(r"<!-- reader: (\w+) -->\n```yaml\n(.*?)```", DOC.read_text(encoding="utf-8"), flags=re.S)
    return [(reader, yaml.safe_load(text)) for reader, text in found]


def _poses(rng: np.random.Generator, n: int = N) -> np.ndarray:
    return make_transform(Rotation.random(n, random_state=rng).as_matrix(), rng.uniform(-0.5, 0.5, (n, 3)))


def _png(path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), np.zeros((8, 8), np.uint8))


def _placeholder(path: Path, text: str = "x\n") -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)


def _pose_table(folder: Path, block: dict, names: list[str], flange2base: np.ndarray, id_column: str) -> None:
    inverse = block.get("pose") in ("base2flange", "cam2target")
    write_pose_table(folder / block["file"], names, invert(flange2base) if inverse else flange2base, block["format"],
                     block["length_unit"], block.get("angle_unit", "rad"), id_column=id_column)


def _robot(folder: Path, spec: dict, names: list[str], id_column: str, rng: np.random.Generator) -> None:
    """The pose table and the joint table a session names, its views ``names``; both of one arm's
    poses when both are given (the readers check them against each other)."""
    if spec.get("joints"):
        arm = load_arm(spec["joints"]["arm"])
        q = rng.uniform(-0.6, 0.6, (len(names), arm.n_joints))
        write_joint_table(folder / spec["joints"]["file"], names, q, spec["joints"]["unit"], id_column=id_column)
        F = arm.forward(q)
    else:
        F = _poses(rng, len(names))
    if spec.get("poses"):
        _pose_table(folder, spec["poses"], names, F, id_column)


def _seconds(block: dict) -> float:
    return {"s": 1.0, "ms": 1e3, "us": 1e6, "ns": 1e9}[block.get("time_unit", "s")]


def _images_table(folder: Path, block: dict, names: list[str], times: np.ndarray) -> None:
    rows = [f"{n},{float(t * _seconds(block))!r}" for n, t in zip(names, times)]
    _placeholder(folder / block["file"], "image,time\n" + "\n".join(rows) + "\n")


def _make(reader: str, spec: dict, folder: Path) -> None:
    """The files ``spec`` names, made to match it (nothing a reader does not open)."""
    rng = np.random.default_rng(0)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / ("posepairs.yaml" if reader == "posepairs" else "session.yaml")).write_text(yaml.safe_dump(spec))
    views = [f"v{k + 1:02d}" for k in range(N)]
    target = spec.get("target") or {}
    if reader == "posepairs":
        _pose_table(folder, spec["robot_poses"], views, _poses(rng), "id")
        _pose_table(folder, spec["camera_poses"], views, _poses(rng), "id")
    elif reader == "images" and "time_unit" in spec["poses"]:  # a robot stream: times, and the images' own
        times = np.linspace(0.0, 2.0, 20)
        F = _poses(rng, len(times))
        _pose_table(folder, spec["poses"], [f"{float(t * _seconds(spec['poses']))!r}" for t in times], F, "time")
        _images_table(folder, spec["images"], [f"{v}.png" for v in views], np.linspace(0.2, 1.8, N))
        for v in views:
            _png(folder / "images" / f"{v}.png")
    elif reader == "images":
        _robot(folder, spec, [f"{v}.png" for v in views], "image", rng)
        for v in views:
            _png(folder / "images" / f"{v}.png")
    elif reader == "depth":
        board = target.get("type") in BOARDS
        _robot(folder, spec, [f"{v}.png" if board else v for v in views], "image" if board else "cloud", rng)
        (folder / "clouds").mkdir()
        for v in views:
            np.save(folder / "clouds" / f"{v}.npy", np.zeros((2, 2, 3)))
            if board:
                _png(folder / "images" / f"{v}.png")
        if target.get("type") == "mesh":
            _placeholder(folder / target["file"], "solid flange\nendsolid flange\n")
    elif reader == "laser":
        _robot(folder, spec, [f"{v}.csv" for v in views], "profile", rng)
        for v in views:
            _placeholder(folder / "profiles" / f"{v}.csv", "x,z\n0.0,0.1\n")
    elif reader == "linescan":
        times = np.linspace(0.0, 3.0, 10)
        arm = load_arm(spec["joints"]["arm"]) if spec.get("joints") else None
        q = rng.uniform(-0.6, 0.6, (len(times), arm.n_joints)) if arm is not None else None
        if arm is not None:
            write_joint_table(folder / spec["joints"]["file"], [f"{float(t * _seconds(spec['joints']))!r}" for t in times], q,
                              spec["joints"]["unit"], id_column="time")
        if spec.get("poses"):
            F = arm.forward(q) if arm is not None else _poses(rng, len(times))
            _pose_table(folder, spec["poses"], [f"{float(t * _seconds(spec['poses']))!r}" for t in times], F, "time")
        _images_table(folder, spec["images"], [f"{v}.png" for v in views], np.linspace(0.5, 2.5, N))
        for v in views:
            _png(folder / "images" / f"{v}.png")
    elif reader == "silhouette":
        _robot(folder, spec, [f"{v}.png" for v in views], "image", rng)
        for v in views:
            _png(folder / spec["silhouette"].get("masks", "masks") / f"{v}.png")
    elif reader == "rig":
        _robot(folder, spec, views, "view", rng)
        for name, block in spec["sensors"].items():
            for v in views if isinstance(block, dict) else []:
                if "laser" in block:
                    _placeholder(folder / block.get("profiles", name) / f"{v}.csv", "x,z\n0.0,0.1\n")
                elif "depth" in block:
                    (folder / block.get("clouds", name)).mkdir(exist_ok=True)
                    np.save(folder / block.get("clouds", name) / f"{v}.npy", np.zeros((2, 2, 3)))
                    if (block.get("target") or target).get("type") in BOARDS:
                        _png(folder / block.get("images", block.get("clouds", name)) / f"{v}.png")
                else:
                    _png(folder / block.get("images", name) / f"{v}.png")
    else:
        raise AssertionError(f"docs/architecture.md names a reader this test does not know: {reader}")


def _mappings(spec: dict, path: str = "") -> list[str]:
    """Every mapping of ``spec``, as dotted paths ('' the top level)."""
    out = [path]
    for key, value in spec.items():
        if isinstance(value, dict):
            out += _mappings(value, f"{path}.{key}" if path else str(key))
    return out


def _at(spec: dict, path: str) -> dict:
    node = spec
    for key in filter(None, path.split(".")):
        node = node[key]
    return node


def _label(reader: str, spec: dict, path: str) -> str:
    kind = _at(spec, path).get("type")
    return f"{reader}:{path}" + (f":{kind}" if kind is not None and path else "")


def _unchecked(label: str) -> bool:
    return any(fnmatch.fnmatchcase(label, pattern) for pattern in UNCHECKED)


BLOCKS = _blocks()


def test_the_page_shows_every_kind_of_session():
    assert {reader for reader, _ in BLOCKS} == set(READERS)
    assert len(BLOCKS) >= 14  # images (3), pose pairs, depth (5), laser (2), line-scan, silhouette, rig


@pytest.mark.parametrize("k", range(len(BLOCKS)), ids=[f"{r}{k}" for k, (r, _) in enumerate(BLOCKS)])
def test_each_session_format_is_read_and_each_key_check_is_as_the_page_says(k, tmp_path):
    reader, spec = BLOCKS[k]
    _make(reader, spec, tmp_path / "as_shown")
    READERS[reader](tmp_path / "as_shown")  # read whole, as the page shows it
    for n, path in enumerate(_mappings(spec)):
        mutated = copy.deepcopy(spec)
        _at(mutated, path)[BOGUS] = "hold"
        folder = tmp_path / f"mutated{n}"
        _make(reader, mutated, folder)
        try:
            READERS[reader](folder)
            refused = False
        except HandEyeError as exc:
            refused = BOGUS in str(exc)
        label = _label(reader, spec, path)
        assert refused != _unchecked(label), (
            f"{label}: an unknown key is {'refused' if refused else 'ignored'}, and docs/architecture.md says it is "
            f"{'ignored' if _unchecked(label) else 'refused'} (section 7's list of mappings not checked, and this test's "
            "UNCHECKED): make the page true")


def _table(name: str) -> dict[str, str]:
    """The keys the page's table ``name`` names (each first cell's backticked names) -> that row's text."""
    text = DOC.read_text(encoding="utf-8").split(f"<!-- keys: {name} -->\n", 1)[1]
    rows = re.findall(r"^\| (.*?) \| (.*?) \|$", text.split("\n\n", 1)[0], flags=re.M)[1:]  # after the header (the rule row has no spaces)
    return {key: what for cell, what in rows for key in re.findall(r"`([^`]+)`", cell)}


def _results() -> list[dict]:
    """result.json's mapping of a sensor fit (a depth camera's balls, its nuisances fitted) and of pose
    pairs (the estimator choice, with a tool frame)."""
    scene = sphere_scene(8, "eye_to_hand", rng=1)
    centres = scene.target2cam[:, :3, 3] + np.random.default_rng(0).normal(0, 1e-4, (8, 3))
    sensor = estimate(SphereCentres("eye_to_hand", [f"v{i}" for i in range(8)], centres), ControllerPoses(scene.flange2base,
                                                                                                             (0.03, 0.3)))
    poses = random_scene(8, "eye_in_hand", rng=0)
    cal = handeye.calibrate_poses(poses.flange2base, poses.target2cam, progress=False)
    return [result_dict(sensor), result_dict(cal, tool2flange=np.eye(4))]


@pytest.mark.slow
def test_result_json_has_the_keys_the_page_names():
    tables = {name: _table(name) for name in ("result", "transform", "uncertainty", "sensor")}
    source = FILES.read_text(encoding="utf-8")
    for name, keys in tables.items():  # every key the page names is one result_dict writes
        assert keys and all(f'"{k}"' in source for k in keys), (name, [k for k in keys if f'"{k}"' not in source])
    sources = set(re.findall(r"`([a-z_]+)`", tables["uncertainty"]["sources"])) - {"rotation_deg", "translation_mm"}
    assert {"model", "jackknife", "robot_accuracy", "data", "held_unknowns", "arm_table", "intrinsics"} <= sources
    for data in _results():  # and every key a result has is on the page
        assert set(data) <= set(tables["result"]), set(data) - set(tables["result"])
        for transform in (data["X"], data["Z"], data["X_inverse"], data.get("tool", {}).get("transform", {})):
            assert set(transform) <= set(tables["transform"]), set(transform) - set(tables["transform"])
        assert set(data["uncertainty"]) <= set(tables["uncertainty"])
        assert set(data["uncertainty"]["sources"]) <= sources, set(data["uncertainty"]["sources"]) - sources
        if "sensor" in data:
            assert set(data["sensor"]) <= set(tables["sensor"]), set(data["sensor"]) - set(tables["sensor"])


HOOKS = ("calibrate", "extras", "rig_member", "rig_extras", "members", "simulate", "plan")


def _kind_rows() -> list[list[str]]:
    """Section 6's table of the registered kinds (after ``<!-- kinds -->``): each row's cells."""
    text = DOC.read_text(encoding="utf-8").split("<!-- kinds -->\n", 1)[1].split("\n\n", 1)[0]
    return [[cell.strip() for cell in row.strip().strip("|").split("|")] for row in text.splitlines()[2:]]


def _folder_cell_is_true(cell: str, folder: Path) -> list[str]:
    """What a folder's cell says that is false: a module it names that ``folder`` lacks (or one it says
    the folder has not, ``no `plan.py```, that it has), a name it gives that no module there defines."""
    source = "".join(p.read_text(encoding="utf-8") for p in folder.glob("*.py"))
    wrong = []
    for no, module in re.findall(r"(no )?`(\w+\.py)`", cell):
        if (folder / module).is_file() == bool(no):
            wrong.append(f"{folder.name}/{module} {'exists' if no else 'is missing'}")
    wrong += [f"{folder.name}/: no {name}" for name in re.findall(r"`([A-Za-z_]\w*)`", cell)
              if not re.search(rf"^(class|def) {name}\b", source, flags=re.M)]
    return wrong


def test_section_6_has_a_row_per_registered_kind_with_its_names_hooks_and_folders():
    """Issue 78: a kind is two folders and one registration; the page's table says which, for every
    kind ``register_kind`` made known (and no other): its section, --sensor and display names, each hook
    its registration names, and its sensors/<kind>/ and pipelines/<kind>/ with the modules they hold."""
    rows = _kind_rows()
    kinds = sensor_kinds()
    assert [r[1] for r in rows] == [f"`{k.section}`" for k in kinds], (
        "docs/architecture.md section 6: the table's rows are not the registered kinds, in registration order "
        f"(rows {[r[1] for r in rows]}, kinds {[k.section for k in kinds]})")
    for row, kind in zip(rows, kinds):
        folder = kind.package.rsplit(".", 1)[1]
        assert row[0].startswith(f"`{kind.display}`") and row[2] == f"`{kind.cli}`", (kind.section, row[:3])
        named = dict(re.findall(r"`(\w+)` `(\w+:\w+)`", row[3]))
        assert named == {h: getattr(kind, h) for h in HOOKS if getattr(kind, h)}, (kind.section, named)
        assert row[4].startswith(f"`sensors/{folder}/`") and row[5].startswith(f"`pipelines/{folder}/`"), (kind.section, row[4:])
        wrong = _folder_cell_is_true(row[4].split(":", 1)[1], SRC / "sensors" / folder)
        wrong += _folder_cell_is_true(row[5].split(":", 1)[1], SRC / "pipelines" / folder)
        assert not wrong, f"docs/architecture.md section 6, {kind.section}'s row: " + "; ".join(wrong)
