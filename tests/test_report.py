"""Result files (YAML/JSON, ROS and URDF snippets) and report.html (issue 8)."""

from __future__ import annotations

import base64
import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
from dataclasses import replace
from html.parser import HTMLParser
from pathlib import Path

import cv2
import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

import browsers
import handeye
from handeye._shared.io import file_digest, files_digest
from handeye.cli import SAMPLE_SESSION, main
from handeye.io.session import load_session
from handeye.report import SECTIONS, result_dict, ros2_static_transform_command, urdf_joint, write_calibration
from handeye.simulate import random_scene

SAMPLE = Path(handeye.__file__).parent / "data" / SAMPLE_SESSION


@pytest.fixture(scope="module")
def sample_out(tmp_path_factory):
    """The bundled sample session calibrated by the CLI with --out (the DESIGN §6 contract)."""
    out = tmp_path_factory.mktemp("out")
    assert main(["calibrate", str(SAMPLE), "--no-progress", "--out", str(out)]) == 0
    return out


@pytest.fixture(scope="module")
def sample_cal():
    return handeye.calibrate(SAMPLE, progress=False)


def _rx(a):
    return np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])


def _ry(a):
    return np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])


def _rz(a):
    return np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])


def _parse_ros_line(line: str) -> tuple[np.ndarray, str, str]:
    """The transform a ROS 2 static_transform_publisher command line publishes (quaternion by hand)."""
    tok = shlex.split(line)
    assert tok[:4] == ["ros2", "run", "tf2_ros", "static_transform_publisher"]
    args = dict(zip(tok[4::2], tok[5::2]))
    x, y, z, w = (float(args[k]) for k in ("--qx", "--qy", "--qz", "--qw"))
    R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                  [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                  [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, [float(args[k]) for k in ("--x", "--y", "--z")]
    return T, args["--frame-id"], args["--child-frame-id"]


def _parse_urdf(snippet: str) -> tuple[np.ndarray, str, str]:
    """The transform a URDF fixed joint describes: R = Rz(yaw) Ry(pitch) Rx(roll) (URDF spec)."""
    joint = ET.fromstring(snippet)
    assert joint.get("type") == "fixed"
    origin = joint.find("origin")
    roll, pitch, yaw = (float(v) for v in origin.get("rpy").split())
    T = np.eye(4)
    T[:3, :3] = _rz(yaw) @ _ry(pitch) @ _rx(roll)
    T[:3, 3] = [float(v) for v in origin.get("xyz").split()]
    return T, joint.find("parent").get("link"), joint.find("child").get("link")


def test_result_files_parse_back_to_the_same_X(sample_out, sample_cal):
    js = json.loads((sample_out / "result.json").read_text())
    ym = yaml.safe_load((sample_out / "result.yaml").read_text())
    # the pitch difference where a screw axis exists: the motions that turn 20 deg or more, as the CLI says
    turning = js["motion_residuals"]["pitch_where_turning"]
    share = sample_cal.motion_pitch_share
    assert turning["motions"] == np.isfinite(share).sum() == 64 and round(turning["min_turn_deg"]) == 20
    assert np.isclose(turning["max_share"], np.nanmax(share)) and turning["max_mm"] <= js["motion_residuals"]["max"][1]
    for data in (js, ym):
        X = np.array(data["X"]["matrix"])
        assert np.abs(X - sample_cal.X).max() <= 1e-12
        Xi = np.array(data["X_inverse"]["matrix"])
        assert np.abs(Xi @ X - np.eye(4)).max() < 1e-12
        q_wxyz, q_xyzw = np.array(data["X"]["quaternion_wxyz"]), np.array(data["X"]["quaternion_xyzw"])
        assert np.allclose(np.roll(q_wxyz, -1), q_xyzw, atol=0)
        R = Rotation.from_quat(q_xyzw).as_matrix()
        assert np.abs(R - X[:3, :3]).max() < 1e-12
        assert np.allclose(np.array(data["X"]["translation_mm"]), 1e3 * X[:3, 3], rtol=0, atol=1e-9)
        # the sample's robot poses are KUKA-style euler:ZYX in degrees: X is given that way too
        eu = data["X"]["euler_input_convention"]
        assert eu["sequence"] == "ZYX" and eu["unit"] == "deg"
        assert np.abs(Rotation.from_euler("ZYX", eu["angles"], degrees=True).as_matrix() - X[:3, :3]).max() < 1e-12
        assert len(data["inputs_sha256"]) == 64
        assert data["check"]["verdict"] == "good" and data["handeye_version"] == handeye.__version__
        std = np.r_[data["uncertainty"]["std_rotation_deg"], data["uncertainty"]["std_translation_mm"]]
        assert np.all(std > 0) and np.allclose(std, sample_cal.std, rtol=1e-6)
        res = np.array(data["pose_residuals"]["values"])
        assert res.shape == (len(data["images"]["used"]), 2)


def test_ros_line_and_urdf_joint_describe_X(sample_out):
    data = json.loads((sample_out / "result.json").read_text())
    X = np.array(data["X"]["matrix"])
    T_ros, parent, child = _parse_ros_line(data["ros"]["static_transform_publisher"])
    assert (parent, child) == ("tool0", "camera_optical_frame")  # eye_in_hand: X = cam2flange
    assert np.abs(T_ros - X).max() < 1e-12
    T_urdf, parent, child = _parse_urdf(data["ros"]["urdf_joint"])
    assert (parent, child) == ("tool0", "camera_optical_frame")
    assert np.abs(T_urdf - X).max() < 1e-12


@pytest.mark.parametrize("seed", range(6))
def test_snippets_for_any_rotation_and_both_setups(seed):
    """Near-gimbal-lock pitch and 180-degree turns included; eye_to_hand names base_link."""
    rng = np.random.default_rng(seed)
    scene = random_scene(6, "eye_to_hand" if seed % 2 else "eye_in_hand", rng)
    cal = handeye.calibrate_poses(scene.flange2base, scene.target2cam, scene.setup, refine="none", check=False)
    if seed == 4:
        cal.X[:3, :3] = Rotation.from_euler("xyz", [0.3, np.pi / 2 - 1e-9, -1.0]).as_matrix()
    if seed == 5:
        cal.X[:3, :3] = Rotation.from_rotvec([np.pi, 0, 0]).as_matrix()
    d = result_dict(cal, parent_frame="flange", child_frame="cam")
    assert np.abs(_parse_ros_line(d["ros"]["static_transform_publisher"])[0] - cal.X).max() < 1e-12
    T, parent, child = _parse_urdf(d["ros"]["urdf_joint"])
    assert (parent, child) == ("flange", "cam") and np.abs(T - cal.X).max() < 1e-9
    assert ros2_static_transform_command(cal.X, "a", "b").endswith("--frame-id a --child-frame-id b")
    assert "<parent link=\"a\"/>" in urdf_joint(cal.X, "a", "b")


def test_inputs_hash_follows_the_inputs(tmp_path, sample_cal):
    session = tmp_path / "s"
    shutil.copytree(SAMPLE, session)
    again = handeye.calibrate(session, progress=False)
    assert again.inputs_sha256 == sample_cal.inputs_sha256  # names and bytes, not the folder's location
    # hashed in the background while X is estimated (issue 37): the same as hashed there and then
    files = load_session(session).input_files
    assert again.inputs_sha256 == files_digest(files, session)
    assert again.image_sha256 == [file_digest(session / "images" / name) for name in again.image_names]
    img = session / "images" / "003.jpg"
    data = bytearray(img.read_bytes())
    data[-3] ^= 1  # one bit of one image
    img.write_bytes(bytes(data))
    assert handeye.calibrate(session, progress=False).inputs_sha256 != sample_cal.inputs_sha256


def test_calibration_write_never_overwrites_its_images(tmp_path, sample_cal):
    images = tmp_path / "imgs"
    images.mkdir()
    cal = handeye.calibrate(SAMPLE, progress=False)
    keep = images / "report.html"
    keep.write_text("mine")
    cal = replace(cal, image_paths=[keep])  # pretend an input image had that name
    with pytest.raises(handeye.HandEyeError, match="refusing to overwrite"):
        write_calibration(cal, images)
    assert keep.read_text() == "mine"


class _Page(HTMLParser):
    def __init__(self):
        super().__init__()
        self.sections, self.images, self.urls, self.tags = [], [], [], set()

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        self.tags.add(tag)
        if tag == "section":
            self.sections.append(a.get("id"))
        if tag == "img":
            self.images.append(a.get("src", ""))
        for key in ("src", "href", "action", "data"):
            if key in a and not (a[key].startswith("data:") or a[key].startswith("#")):
                self.urls.append(a[key])


def _check_page(text: str) -> _Page:
    page = _Page()
    page.feed(text)
    assert page.sections == list(SECTIONS)
    assert "://" not in text and not page.urls  # self-contained: nothing fetched from anywhere
    assert not ({"link", "iframe", "object", "embed"} & page.tags)
    for src in page.images:
        m = re.match(r"data:image/(png|jpeg);base64,(.*)$", src, re.S)
        assert m, src[:40]
        img = cv2.imdecode(np.frombuffer(base64.b64decode(m.group(2), validate=True), np.uint8), cv2.IMREAD_COLOR)
        assert img is not None and img.shape[0] > 20 and img.shape[1] > 20
    page.figures = _svg_figures(text)
    return page


_SVG = ""  # inline in HTML: no namespace


def _svg_figures(text: str) -> list[ET.Element]:
    """Every inline <svg> figure of a page, parsed as XML (a text not escaped would not parse)."""
    found = re.findall(r"<svg .*?</svg>", text, re.S)
    assert text.count("<svg") == len(found)
    return [ET.fromstring(s) for s in found]


def _of_class(root: ET.Element, cls: str, tag: str | None = None) -> list[ET.Element]:
    return [e for e in root.iter() if cls in (e.get("class") or "").split() and (tag is None or e.tag == _SVG + tag)]


def _svg_texts(root: ET.Element) -> list[tuple[str, tuple[float, float, float, float]]]:
    """(text, box) of every text of a figure: the box (x0, y0, x1, y1) from its position, size, anchor and
    rotation, a character's width taken as 0.5 of the font size (system sans fonts: 0.45-0.55)."""
    out = []
    for t in root.iter(_SVG + "text"):
        s, size = "".join(t.itertext()), float(t.get("font-size"))
        x, y = float(t.get("x")), float(t.get("y")) + (0.35 * size if t.get("dy") else 0.0)
        w = 0.5 * size * len(s)
        x0 = {"start": x, "middle": x - w / 2, "end": x - w}[t.get("text-anchor", "start")]
        box = (x0, y - 0.75 * size, x0 + w, y + 0.2 * size)
        if "rotate(-90" in (t.get("transform") or ""):  # about (x, y): along the height, upwards
            box = (x - 0.75 * size, y - (box[2] - x), x + 0.2 * size, y - (box[0] - x))
        out.append((s, box))
    return out


def test_report_structure_from_images(sample_out, sample_cal):
    text = (sample_out / "report.html").read_text(encoding="utf-8")
    page = _check_page(text)
    n_images = len(sample_cal.image_names)
    assert len(page.images) == n_images  # an overlay per image
    assert [f.get("aria-label") for f in page.figures] == ["per-pose residuals", "3D view of the robot base frame", "rotation axes"]
    assert "GOOD" in text.upper() and "static_transform_publisher" in text
    for method in handeye.solvers.available(closed_forms=True):  # the comparison lists every closed form
        assert f">{method}<" in text
    for name in sample_cal.image_names:
        assert name in text
    # screw congruence as a share of each motion's translation, not bare millimetres (issue 40)
    found = re.search(r"Screw congruence per motion .*?median ([\d.]+) deg / ([\d.]+)%, worst ([\d.]+) deg / ([\d.]+)%", text)
    assert found is not None and float(found.group(4)) == pytest.approx(100 * np.nanmax(sample_cal.motion_pitch_share), abs=0.06)


def test_report_from_poses_only(tmp_path):
    scene = random_scene(10, "eye_to_hand", np.random.default_rng(3))
    rng = np.random.default_rng(4)
    noisy = handeye.simulate.perturb_poses(scene.target2cam, np.radians(0.05), 0.2e-3, rng)
    cal = handeye.calibrate_poses(scene.flange2base, noisy, "eye_to_hand")
    paths = write_calibration(cal, tmp_path / "r")
    assert [p.name for p in paths] == ["result.json", "result.yaml", "report.html"]
    assert paths[-1] == tmp_path / "r" / "report.html"
    page = _check_page(paths[-1].read_text(encoding="utf-8"))
    assert len(page.images) == 0 and len(page.figures) == 3  # residuals, 3D scene, rotation axes: SVG
    d = json.loads(paths[0].read_text())
    assert d["ros"]["parent_frame"] == "base_link" and d["X_name"] == "cam2base"


_CHROMIUM = next((shutil.which(b) for b in ("chromium", "chromium-browser", "google-chrome", "chrome") if shutil.which(b)), None)

_PROBE = """<script>window.addEventListener('load', function () {
  var imgs = document.images, bad = 0;
  for (var i = 0; i < imgs.length; i++) { if (!(imgs[i].complete && imgs[i].naturalWidth > 0)) bad++; }
  var wide = 0, all = document.querySelectorAll('section, section *');
  for (var j = 0; j < all.length; j++) {  // a figure's inner SVG shapes: inside its box (a test checks its texts)
    if (all[j] instanceof SVGElement && !(all[j] instanceof SVGSVGElement)) continue;
    if (all[j].scrollWidth > all[j].clientWidth + 1 && all[j].clientWidth > 0) wide++; }
  var b = document.body;
  b.setAttribute('data-images', imgs.length); b.setAttribute('data-broken', bad);
  b.setAttribute('data-sections', document.querySelectorAll('section').length);
  b.setAttribute('data-height', document.documentElement.scrollHeight);
  b.setAttribute('data-overflow', wide + (document.documentElement.scrollWidth > window.innerWidth ? 1 : 0));
  b.setAttribute('data-errors', (window.__errors || []).length);
  var thumbs = document.querySelectorAll('#overlays figure img.zoom'), narrow = 0;
  for (var k = 0; k < thumbs.length; k++) { if (Math.abs(thumbs[k].clientWidth - 360) > 1) narrow++; }
  b.setAttribute('data-thumbs', thumbs.length); b.setAttribute('data-offsize', narrow);
  b.setAttribute('data-scene', Math.round(document.querySelector('#scene svg').getBoundingClientRect().width));
  b.setAttribute('data-axes', Math.round(document.querySelector('#axes svg').getBoundingClientRect().width));
});</script></body>"""
#: collects script errors and console.error calls from the start of the page
_ERRORS = """<head><script>window.__errors = [];
window.addEventListener('error', function (e) { window.__errors.push(String(e.message)); });
(function () { var ce = console.error; console.error = function () { window.__errors.push([].join.call(arguments, ' '));
  ce.apply(console, arguments); }; })();</script>"""


@browsers.skip_unless(_CHROMIUM is not None, reason="no chromium binary on this machine")
def test_report_renders_in_headless_chromium(sample_out, tmp_path):
    """The page renders at 1200 px, the browser decodes every embedded image, nothing overflows
    its box sideways (the ROS line was cut off) and no script error or console error is logged
    (a probe script added to a copy); the gallery's thumbnails are shown 360 px wide and the 3D view
    and the rotation axes at most of the page's width."""
    text = (sample_out / "report.html").read_text(encoding="utf-8")
    probe = tmp_path / "probe.html"
    probe.write_text(text.replace("<head>", _ERRORS, 1).replace("</body>", _PROBE), encoding="utf-8")
    res = subprocess.run([_CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                          "--disable-component-update", "--no-first-run", f"--user-data-dir={tmp_path / 'profile'}",
                          "--window-size=1200,900", "--virtual-time-budget=10000", "--dump-dom", probe.as_uri()],
                         capture_output=True, text=True, timeout=120)
    m = re.search(r'<body data-images="(\d+)" data-broken="(\d+)" data-sections="(\d+)" data-height="(\d+)" '
                  r'data-overflow="(\d+)" data-errors="(\d+)" data-thumbs="(\d+)" data-offsize="(\d+)" '
                  r'data-scene="(\d+)" data-axes="(\d+)"', res.stdout)
    assert m, res.stdout[:300] + res.stderr[-500:]
    n_img, broken, sections, height, overflow, errors, thumbs, offsize, scene, axes = (int(g) for g in m.groups())
    assert thumbs == text.count('class="zoom"') and offsize == 0 and scene >= 750 and axes >= 750
    assert n_img == text.count("<img ") and broken == 0
    assert sections == len(SECTIONS) and height > 2000
    assert overflow == 0 and errors == 0


def test_exports_for_robot_software_describe_X(tmp_path, sample_cal):
    """--export all: a ROS 2 launch file, a ROS 1 (MoveIt Calibration) launch file and easy_handeye2's
    .calib, each giving X back; --tool: the camera relative to the tool frame; Z in the robot's own
    pose format (to teach a work object)."""
    import ast

    tool = handeye.geometry.se3.make_transform(Rotation.from_rotvec([0, 0, 30], degrees=True).as_matrix(), [0, 0, 0.15])
    paths = write_calibration(sample_cal, tmp_path / "x", exports=["all"], tool2flange=tool, report=False)
    names = [p.name for p in paths]
    assert names == ["result.json", "result.yaml", "handeye_static_tf.launch.py", "handeye_static_tf.launch",
                     "handeye.calib"]
    X = sample_cal.X
    # ROS 2: the Node's arguments
    tree = ast.parse(paths[2].read_text())
    args = next(n for n in ast.walk(tree) if isinstance(n, ast.keyword) and n.arg == "arguments").value
    values = [ast.literal_eval(e) for e in args.elts]
    kv = dict(zip(values[::2], values[1::2]))
    R = Rotation.from_quat([float(kv[f"--q{c}"]) for c in "xyzw"]).as_matrix()
    assert np.abs(R - X[:3, :3]).max() < 1e-12 and np.abs([float(kv[f"--{c}"]) for c in "xyz"] - X[:3, 3]).max() < 1e-15
    assert kv["--frame-id"] == "tool0" and kv["--child-frame-id"] == "camera_optical_frame"
    # ROS 1: x y z qx qy qz qw parent child
    node = ET.fromstring(paths[3].read_text()).find("node")
    a = node.get("args").split()
    assert np.abs(np.array(a[:3], float) - X[:3, 3]).max() < 1e-15 and a[7:] == ["tool0", "camera_optical_frame"]
    assert np.abs(Rotation.from_quat(np.array(a[3:7], float)).as_matrix() - X[:3, :3]).max() < 1e-12
    # easy_handeye2
    calib = yaml.safe_load(paths[4].read_text())
    assert calib["parameters"]["calibration_type"] == "eye_in_hand" and calib["parameters"]["robot_effector_frame"] == "tool0"
    t, q = calib["transform"]["translation"], calib["transform"]["rotation"]
    assert np.abs([t["x"], t["y"], t["z"]] - X[:3, 3]).max() < 1e-15
    assert np.abs(Rotation.from_quat([q["x"], q["y"], q["z"], q["w"]]).as_matrix() - X[:3, :3]).max() < 1e-12
    # the tool frame and the robot's own format
    data = json.loads(paths[0].read_text())
    assert data["tool"]["name"] == "cam2tool"
    cam2tool = np.array(data["tool"]["transform"]["matrix"])
    assert np.abs(tool @ cam2tool - X).max() < 1e-12
    z = data["Z"]["robot_format"]
    assert z["format"] == "euler:ZYX" and z["columns"] == ["x", "y", "z", "a", "b", "c"]
    Z_back = handeye.parse_poses([z["values"]], z["format"], z["length_unit"], z["angle_unit"])[0]
    assert np.abs(Z_back - sample_cal.Z).max() < 1e-12
    with pytest.raises(handeye.HandEyeError, match="unknown export"):
        write_calibration(sample_cal, tmp_path / "y", exports=["urdf-xacro"], report=False)
    assert not (tmp_path / "y").exists()  # nothing written before the error


def test_gallery_flags_large_errors_and_shows_rejected_images(tmp_path, sample_cal):
    """An image whose predicted points lie far from the detected ones gets a red frame and a caption
    saying so; images that were not used appear with the reason; thumbnails enlarge on a click."""
    from handeye.report import report_html

    shifted = [p + (25.0 if k == 4 else 0.0) for k, p in enumerate(sample_cal.image_points)]
    folder = tmp_path / "session"
    shutil.copytree(SAMPLE, folder)
    cv2.imwrite(str(folder / "images" / "blank.png"), np.full((480, 640), 200, np.uint8))
    cal = replace(sample_cal, image_points=shifted, input_folder=folder,
                  skipped=[("blank.png", "target not found")])
    text = report_html(cal)
    assert text.count('<figure class="flag">') == 1
    assert "<figcaption>004.jpg" in text.split('<figure class="flag">')[1].split("</figure>")[0]
    assert "check this view" in text
    rejected = text.split('<figure class="rejected">')
    assert len(rejected) == 2 and "not used — blank.png: target not found" in rejected[1]
    assert text.count('class="zoom" tabindex="0"') == len(sample_cal.image_names) + 1


def test_advice_names_what_could_be_better(sample_cal):
    """A good verdict with rotation axes that are not well spread, or solvers far apart compared with
    X's std, gets advice instead of 'nothing to fix'."""
    from handeye.report import report_html

    diag = replace(sample_cal.diagnostics, axis_shares=np.array([0.82, 0.09, 0.09]), advice=[],
                   weakest_axis=np.array([0.0, 0.0, 1.0]))
    rows = [{"method": m, "dX_deg": 0.5, "dX_mm": 10 * float(np.linalg.norm(sample_cal.std[3:])), "median_pose_deg": 0.1,
             "median_pose_mm": 1.0, "ms": 1.0} for m in ("tsai_lenz", "park_martin")]
    text = report_html(replace(sample_cal, diagnostics=diag, notes=[]), solver_rows=rows)
    advice = text.split('<section id="advice">')[1]
    assert "Nothing to fix" not in advice
    assert "rotation axes are not well spread" in advice and "land a median 10.0 std of X away" in advice


def test_gallery_of_a_view_predicted_into_the_camera_plane(sample_cal):
    """A robot pose that puts the target in the camera's own plane projects its points to ~1e10 px
    (found by fuzzing calibrate: OpenCV's drawMarker took them for no position and the report
    failed): the marks off the image are left out and the report is written."""
    from handeye.frames.setups import predicted_target2cam
    from handeye.geometry.se3 import invert, make_transform
    from handeye.report import report_html

    in_plane = make_transform(np.eye(3), [0.0, 0.0, 1e-9])  # the target's plane through the camera centre
    f2b = sample_cal.flange2base.copy()
    f2b[0] = sample_cal.Z @ invert(in_plane) @ invert(sample_cal.X)
    assert np.allclose(predicted_target2cam(sample_cal.X, sample_cal.Z, f2b, "eye_in_hand")[0], in_plane, atol=1e-9)
    text = report_html(replace(sample_cal, flange2base=f2b))
    assert text.count('<figure class="flag">') >= 1 and "<figcaption>000.jpg" in text


def _colour_shares(src: str, width: int) -> tuple[float, float, tuple[float, float]]:
    """Shares of green-dominant and red-dominant pixels of a JPEG data URI shown ``width`` px wide,
    and the extent of the green pixels as fractions of the picture's width and height."""
    img = cv2.imdecode(np.frombuffer(base64.b64decode(src.split(",", 1)[1]), np.uint8), cv2.IMREAD_COLOR)
    shown = cv2.resize(img, (width, round(img.shape[0] * width / img.shape[1])), interpolation=cv2.INTER_AREA).astype(int)
    b, g, r = shown[..., 0], shown[..., 1], shown[..., 2]
    green, red = (g > r + 60) & (g > b + 60), (r > g + 60) & (r > b + 60)
    ys, xs = np.nonzero(green)
    extent = (float(np.ptp(xs)) / shown.shape[1], float(np.ptp(ys)) / shown.shape[0]) if len(xs) else (0.0, 0.0)
    return float(green.mean()), float(red.mean()), extent


def test_gallery_marks_read_at_thumbnail_size(sample_out):
    """At the size the gallery shows them (360 px wide), each thumbnail shows the target large (the
    image cropped around it) with green rings and red crosses that both cover a visible share of the
    picture (on the whole 640x480 image they were 0.15% and 0.4% of it: dots)."""
    from handeye.report._overlay import THUMB_WIDTH

    text = (sample_out / "report.html").read_text(encoding="utf-8")
    gallery = text.split('<section id="overlays">')[1].split("</section>")[0]
    srcs = re.findall(r'<img class="zoom" tabindex="0" src="(data:image/jpeg;base64,[^"]+)"', gallery)
    assert srcs
    for src in srcs:
        green, red, extent = _colour_shares(src, THUMB_WIDTH)
        assert green > 0.02 and red > 0.01, (green, red)
        assert max(extent) > 0.5, extent  # the board's points span over half the thumbnail


def test_overlay_thumbnail_of_points_off_the_image(tmp_path):
    """Predicted points far outside the image (or NaN) are left out and the crop falls back to the
    detected ones; an unreadable image gives no thumbnail, not an error."""
    from handeye.report._overlay import overlay_thumbnail

    path = tmp_path / "grey.png"
    cv2.imwrite(str(path), np.full((480, 640, 3), 128, np.uint8))
    det = np.array([[300.0, 200], [320, 200], [300, 220], [320, 220]])
    far = np.array([[1e20, 1e20], [np.nan, 0.0], [310.0, 210.0], [5e4, 5e4]])
    green, red, extent = _colour_shares(overlay_thumbnail(path, det, far), 360)
    assert green > 0.005 and red > 0.0005 and max(extent) > 0.05
    (tmp_path / "bad.png").write_bytes(b"not an image")
    assert overlay_thumbnail(tmp_path / "bad.png", det, far) is None


def test_thumbnails_from_the_previews_detection_cut(tmp_path, no_detection_cache, monkeypatch):
    """While previews are kept, detection cuts each image's part around its target and the
    thumbnail is drawn on it without reading the file again (the same picture as from the file,
    grey); a prediction outside the part, or a file changed since, reads the file; outside the
    block nothing is kept."""
    from handeye.report import _overlay
    from handeye.sensors.camera import detect_images, preview, target_from_spec

    folder = tmp_path / "s"
    shutil.copytree(SAMPLE, folder)
    paths = sorted((folder / "images").iterdir())[:4]
    target = target_from_spec(yaml.safe_load((folder / "session.yaml").read_text())["target"])
    assert all(preview.recall(p) is None for p in paths)
    with preview.kept(3):
        found = detect_images(paths, target, jobs=2, progress=False)
        kept = [preview.recall(p) for p in paths]
        assert [v is not None for v in kept] == [r.detection is not None for r in found[:3]] + [False]
        det = np.asarray(found[0].detection.image_points)
        near = det + 1.5  # predictions a pixel or two off, as usual
        from_file = _overlay.overlay_thumbnail(paths[0], det, near)
        monkeypatch.setattr(_overlay, "_from_file", lambda *a: pytest.fail("the file was read again"))
        from_preview = _overlay.overlay_thumbnail(paths[0], det, near)
        a, b = (cv2.imdecode(np.frombuffer(base64.b64decode(s.split(",", 1)[1]), np.uint8), cv2.IMREAD_COLOR)
                for s in (from_file, from_preview))
        assert a.shape == b.shape and np.mean(np.abs(a.astype(int) - b.astype(int))) < 3
        saturation = cv2.cvtColor(b, cv2.COLOR_BGR2HSV)[..., 1]
        assert np.mean(saturation < 40) > 0.8  # the picture grey, only the marks coloured
        monkeypatch.undo()
        read = []
        monkeypatch.setattr(_overlay, "_from_file", lambda *a: read.append(1) or _overlay.cut(
            cv2.imread(str(a[0]), cv2.IMREAD_GRAYSCALE), np.vstack(a[1:])))
        _overlay.overlay_thumbnail(paths[0], det, det + [300.0, 0.0])  # the crosses outside the part
        assert read == [1]
        os.utime(paths[0], ns=(1, 1))  # the file changed
        assert preview.recall(paths[0]) is None
    assert preview.recall(paths[1]) is None  # dropped with the block
    assert preview.wanted() == 0


def test_scene_and_rotation_axes_use_the_page_and_their_labels_do_not_overlap(sample_cal, sample_out):
    """The 3D view and the rotation-axes figure are drawn at most of the page's width (1,068 px of
    content; they were 634 and 460 px), and no two of their labels overlap (the sphere's tick labels
    ran into each other at a tick every 0.25), nor run off the figure."""
    from handeye.frames.motions import MotionSet
    from handeye.report.html import _axes_figure, _residual_figure, _scene_figure

    motions = MotionSet.from_poses(sample_cal.flange2base, sample_cal.target2cam, sample_cal.setup, sample_cal.pairs)
    for svg in (_scene_figure(sample_cal), _axes_figure(sample_cal, motions), _residual_figure(sample_cal)):
        root = ET.fromstring(svg)
        width, height = (float(v) for v in root.get("viewBox").split()[2:])
        texts = _svg_texts(root)
        assert len(texts) > 10 and width >= 750
        clashes = [(a, b) for i, (a, ba) in enumerate(texts) for b, bb in texts[i + 1:]
                   if ba[0] < bb[2] and bb[0] < ba[2] and ba[1] < bb[3] and bb[1] < ba[3]]
        assert not clashes, clashes
        outside = [t for t, (x0, y0, x1, y1) in texts if x0 < 0 or y0 < 0 or x1 > width or y1 > height]
        assert not outside, outside


def test_the_camera_reports_figures_are_svg_with_every_pose_and_motion(sample_out, sample_cal):
    """Issue 81: the --sample report's figures are inline SVG drawn by handeye.report._svg, not PNGs
    drawn by matplotlib (its import and drawing were half of calibrate --sample's 0.9 s), with what the
    PNGs showed: a bar per pose in each of the three residual panels (rotation, translation, PnP RMS)
    with its labels, each pose's flange, camera and target in the 3D view with its legend, and each
    motion's axis twice on the sphere and once on the disc with the colour bar."""
    text = (sample_out / "report.html").read_text(encoding="utf-8")
    residuals, scene, axes = (_svg_figures(text.split(f'<section id="{s}">')[1].split("</section>")[0])
                              for s in ("residuals", "scene", "axes"))
    n = len(sample_cal.flange2base)
    panels = _of_class(residuals[0], "panel")
    assert [len(_of_class(p, "bar", "rect")) for p in panels] == [n, n, n]
    heights = [float(r.get("height")) for r in _of_class(panels[2], "bar")]  # the PnP RMS: tallest bar, largest RMS
    assert int(np.argmax(heights)) == int(np.argmax(sample_cal.reprojection_rms))
    words = [t for t, _ in _svg_texts(residuals[0])]
    assert {"rotation (deg)", "translation (mm)", "PnP RMS (px)", *sample_cal.image_names} <= set(words)
    assert "per pose: how far its own target2base (through X) is from the common one" in words
    assert len(_of_class(scene[0], "pt", "circle")) == 2 * n and len(_of_class(scene[0], "pt", "rect")) == n
    words = [t for t, _ in _svg_texts(scene[0])]
    assert {"x (m)", "y (m)", "z (m)", "base", "camera", "target", "flange positions (capture order)"} <= set(words)
    m = len(sample_cal.motions.B)
    dots = _of_class(axes[0], "pt", "circle")
    assert len(dots) == 3 * m and len({d.get("fill") for d in dots}) > m // 2  # coloured by angle: mostly distinct
    words = [t for t, _ in _svg_texts(axes[0])]
    assert {"camera x", "camera y", "camera z", "30°", "60°", "90°", "rotation angle (deg)"} <= set(words)


def _matplotlib_modules_of(argv: list[str], timeout: float) -> str:
    """The matplotlib modules a ``handeye`` command imported, run in a new process (it must succeed)."""
    code = (f"import sys; from handeye.cli import main; rc = main({argv!r}); "
            "print(sorted(m for m in sys.modules if m.split('.')[0] == 'matplotlib')); sys.exit(rc)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=timeout)
    assert done.returncode == 0, done.stderr[-500:]
    return done.stdout.strip().splitlines()[-1]


def test_calibrate_sample_does_not_import_matplotlib(tmp_path):
    """Issue 81: a camera's report draws its figures without matplotlib (its import alone took ~0.3 s of
    calibrate --sample's 0.9 s): the whole command, in a new process, never imports it."""
    assert _matplotlib_modules_of(["calibrate", "--sample", "--no-progress", "--out", str(tmp_path / "out")], 120) == "[]"
    assert "<svg" in (tmp_path / "out" / "report.html").read_text(encoding="utf-8")



@pytest.mark.slow
def test_a_rigs_report_is_svg_without_matplotlib(tmp_path):
    """Issue 78: a rig's report drew its picture, each sensor's residual per view and each view's section as
    matplotlib PNGs; now as inline SVG (handeye.report._svg), so that calibrating a rig never imports
    matplotlib. The figures keep what the PNGs showed: every sensor labelled in the picture, the flange and
    the target; a bar per view for each sensor; each drawn section's label and its corners, one dot each."""
    assert main(["simulate", "--sensor", "rig", "--seed", "1", "-o", str(tmp_path / "rig")]) == 0
    assert _matplotlib_modules_of(["calibrate", str(tmp_path / "rig"), "--no-progress", "--out", str(tmp_path / "out")], 300) == "[]"
    text = (tmp_path / "out" / "report.html").read_text(encoding="utf-8")
    assert "data:image/png" not in text
    cal = handeye.load_result(tmp_path / "out")
    sensors, views = list(cal.sensor.figures["X_per_sensor"]), list(cal.diagnostics.names)
    rig = text.split('<section id="rig">')[1].split('<section id="residuals">')[0]
    picture, *bars = _svg_figures(rig)
    assert len(bars) == len(sensors) == 2
    words = {t for t, _ in _svg_texts(picture)}
    assert {*sensors, "flange", "target (first view)", "x (m)", "y (m)", "z (m)"} <= words
    for name, figure in zip(sensors, bars):
        assert len(_of_class(figure, "bar", "rect")) == len(views)
        assert f"sensor {name}: its residual per view in the joint fit (none where it saw nothing)" in {t for t, _ in _svg_texts(figure)}
    sections = next(f for f in _svg_figures(text) if f.get("aria-label") == "each view with the fitted target's section")
    seen = {f"{v} {name}" for name, rms in cal.sensor.figures["view_rms_mm_per_sensor"].items()
            for v, r in zip(views, rms) if r is not None}  # a section per sensor and view it saw: at most 24 drawn
    labels = [t.split(":")[0] for t, _ in _svg_texts(sections) if ": " in t and t.endswith(" mm")]
    assert len(labels) == min(24, len(seen)) and set(labels) <= seen
    assert len(_of_class(sections, "pt", "circle")) >= 20 * len(labels)  # each section's corners, a dot each


def test_a_sections_figure_keeps_the_points_worth_seeing():
    """A section of thousands of points is drawn thinned (a profile's dots all but hide one another): its
    largest residuals always among those drawn, the rest evenly, in the points' order."""
    from handeye.report.html import MAX_SECTION_POINTS, _thinned

    residual = np.random.default_rng(0).normal(0.0, 0.01, 3000)
    residual[[17, 1500, 2999]] = [0.5, -0.7, np.nan]
    kept = _thinned(residual, MAX_SECTION_POINTS)
    assert len(kept) == MAX_SECTION_POINTS and np.all(np.diff(kept) > 0) and {17, 1500} <= set(kept.tolist())
    worst = np.argsort(-np.abs(np.nan_to_num(residual)))[:MAX_SECTION_POINTS // 4]
    assert set(worst.tolist()) <= set(kept.tolist())
    assert np.array_equal(_thinned(residual[:50], MAX_SECTION_POINTS), np.arange(50))

#: result.json's keys as the sub-records' parts wrote them before they were grouped (issue 36): the
#: top level shared by every calibration, and the sections of the optional parts
_TOP = {"X", "X_inverse", "X_inverse_name", "X_name", "Z", "Z_name", "check", "determined", "easy_handeye",
        "estimator", "handeye_version", "inputs_sha256", "method", "motion_residuals", "n_motions", "n_poses", "notes",
        "pose_residuals", "poses", "refinement", "ros", "setup", "verdict"}


def test_result_json_keeps_its_keys_with_the_sub_records(sample_cal):
    """Calibration groups its optional parts (cross-validation, observability, certificate, streams)
    into sub-records, read through the names the guide documents; result.json writes the same keys
    as before for a calibration from images, a partial one, one with known= values, a certified one
    and one from streams."""
    from handeye.report import result_dict
    from handeye.result import HeldOutErrors, Observability, StreamSync
    from handeye.simulate import low_dof_scene, stream_scene

    d = result_dict(sample_cal)
    assert set(d) == _TOP | {"camera", "cross_validation", "images", "uncertainty"}
    assert set(d["cross_validation"]) == {"estimator", "folds", "meaning", "per_estimator", "prediction_error"}
    assert isinstance(sample_cal.cross_validation, HeldOutErrors) and sample_cal.cross_validation.folds >= 2
    assert d["cross_validation"]["per_estimator"] == dict(sample_cal.cross_validation)
    assert sample_cal.prediction_error == sample_cal.cross_validation[sample_cal.estimator]
    assert sample_cal.observability == Observability() and sample_cal.time_offset is None and sample_cal.streams is None

    sc = low_dof_scene(12, "eye_in_hand", "scara", 1, robot_noise=(0, 0), pixel_px=0)
    partial = handeye.calibrate_poses(sc.flange2base, sc.target2cam, "eye_in_hand")
    d = result_dict(partial)
    assert set(d) == _TOP | {"uncertainty", "unobservable"}
    assert partial.observability.motion_kind == partial.motion_kind == "one_axis"
    assert d["unobservable"] == [u.as_dict() for u in partial.observability.unobservable]
    known = handeye.calibrate_poses(sc.flange2base, sc.target2cam, "eye_in_hand", known={"cam2flange.z": float(sc.X[2, 3])})
    d = result_dict(known)
    assert set(d) == _TOP | {"uncertainty", "known"} and set(d["known"]) == {"cam2flange.z"}
    assert d["known"]["cam2flange.z"] == known.observability.known["cam2flange.z"]

    st = stream_scene(20, "eye_in_hand", rng=3)
    streamed = handeye.calibrate_streams(st.robot_times, st.flange2base, st.camera_times, st.target2cam, "eye_in_hand")
    d = result_dict(streamed)
    assert set(d) == _TOP | {"cross_validation", "time_sync", "uncertainty"}
    assert set(d["time_sync"]) == {"camera_rate_hz", "camera_samples", "coarse_alignment", "coarse_offset_s", "fit_outliers",
                                   "fit_samples", "keyframe_camera_times_s", "meaning", "offset_std_fit_s",
                                   "offset_std_jackknife_s", "robot_rate_hz", "robot_samples", "search_s", "time_offset_s",
                                   "time_offset_std_s"}
    assert isinstance(streamed.sync, StreamSync) and d["time_sync"]["time_offset_s"] == streamed.sync.time_offset
    assert streamed.time_offset_std == streamed.sync.time_offset_std and streamed.streams is streamed.sync.details

    pytest.importorskip("cvxpy")
    s = random_scene(8, "eye_in_hand", np.random.default_rng(2))
    certified = handeye.certify_calibration(handeye.calibrate_poses(s.flange2base, s.target2cam, method="certifiable",
                                                                    refine="none"))
    d = result_dict(certified)
    assert set(d) == _TOP | {"certificate", "uncertainty"}  # a closed form alone has a std too
    assert d["certificate"] == certified.certificate.as_dict() and set(d["certificate"]) == {
        "cost", "cost_name", "gap", "lower_bound", "optimal", "tight"}


def test_rotation_axes_figure_draws_a_share_of_many_motions(sample_cal, monkeypatch):
    """Thousands of motions (200 views: 6,700) cover each other on the rotation-axes figure and cost
    ~0.3 s to draw: at most MAX_AXES_DRAWN are, evenly chosen, and the title says so (issue 37)."""
    from handeye.report import html

    drawn = []
    original = html.screw_parameters
    monkeypatch.setattr(html, "screw_parameters", lambda B: drawn.append(len(B)) or original(B))
    n = len(sample_cal.motions.B)
    monkeypatch.setattr(html, "MAX_AXES_DRAWN", n - 3)
    svg = html._axes_figure(sample_cal, sample_cal.motions)
    title = _of_class(ET.fromstring(svg), "title", "text")[0].text
    assert drawn == [n - 3] and f"({n - 3} of {n} motions drawn)" in title
    assert len(_of_class(ET.fromstring(svg), "pt")) == 3 * (n - 3)
    monkeypatch.setattr(html, "MAX_AXES_DRAWN", n)
    svg = html._axes_figure(sample_cal, sample_cal.motions)
    assert drawn[-1] == n and "drawn" not in svg


@pytest.fixture(scope="module")
def laser_cal():
    """A laser profiler's calibration (10 profiles of a ball, an exact robot): a sensor's fit."""
    from handeye.estimation.core import estimate
    from handeye.pipelines.laser.simulate import laser_scene
    from handeye.robot.models import ControllerPoses
    from handeye.sensors.laser.model import SphereProfiles

    sc = laser_scene(10, "eye_in_hand", rng=7)
    return estimate(SphereProfiles("eye_in_hand", [f"p{k:02d}.csv" for k in range(10)], sc.profiles, radius=sc.radius),
                    ControllerPoses(sc.flange2base))


@pytest.mark.slow  # over 3.5 s: the fast tier keeps a margin under its 2 minutes
def test_a_sensors_report_says_what_its_fit_is(laser_cal):
    """Issue 77: a sensor's report said '10 views, 0 motions' (a sensor's fit pairs none), Z's std '—'
    where the terminal prints it, a held-out paragraph about the camera's refinements, and its figures
    as raw keys and floats ('1200.', 'placement_given 1.'). Now: views alone, Z's std (a ball's
    orientation 'not defined'), the sensor's own held-out account, figures in words."""
    from handeye.report.html import report_html

    page = report_html(laser_cal)
    assert "· 10 views ·" in page and "motions" not in page.split("</h1>")[1].split("</p>")[0]
    z = page.split("<h3>Z = target2base</h3>")[1].split("</table>")[0]
    std = laser_cal.std_Z
    assert f"<td>{', '.join(f'{v:.3f}' for v in std[3:])}</td>" in z and "not defined, not defined, not defined" in z
    held = page.split("Held-out prediction error (cross-validated)</h3>")[1].split("</p>")[0]
    assert "pixel refinement" not in held and "laser line profiler" in held and "closed-form start" in held
    assert "<td class=\"l\">radius (mm)</td>" in page and "<td class=\"l\">centre (m)</td>" in page
    from handeye.report.html import _figure_label, _figure_text

    assert [_figure_label(k) for k in ("line_rate_hz", "clock_offset_s", "placement_given", "k1")] == [
        "line rate (Hz)", "clock offset (s)", "placement given", "k1"]
    assert [_figure_text(v) for v in (1200.0, True, False, 18000, [], [0.5, 2.0], None)] == [
        "1200", "yes", "no", "18000", "none", "[0.5, 2]", "—"]


@pytest.mark.slow  # shares the laser fixture (5 s) with test_a_sensors_report_says_what_its_fit_is
def test_a_laser_profilers_ros_frame_is_named_for_a_profiler(laser_cal, tmp_path):
    """Issue 77: a laser profiler's ROS snippets and launch files published X as camera_optical_frame;
    its frame is laser_profiler_optical_frame (x along the line, z along the measuring axis), a
    camera's stays camera_optical_frame, and --child-frame still renames it."""
    from handeye.report import write_exports

    ros = result_dict(laser_cal)["ros"]
    assert ros["child_frame"] == "laser_profiler_optical_frame" and ros["parent_frame"] == "tool0"
    assert ros["static_transform_publisher"].endswith("--child-frame-id laser_profiler_optical_frame")
    launch = write_exports(laser_cal, tmp_path, ["ros2-launch"])[0].read_text()
    assert "'laser_profiler_optical_frame'" in launch and "camera_optical_frame" not in launch
    assert result_dict(laser_cal, child_frame="profiler")["ros"]["child_frame"] == "profiler"
    cal = handeye.calibrate_poses(*(lambda s: (s.flange2base, s.target2cam))(random_scene(8, "eye_in_hand", rng=0)),
                                  progress=False)
    assert result_dict(cal)["ros"]["child_frame"] == "camera_optical_frame"


def test_verification_histogram_is_svg_with_every_view():
    """verify.html's distribution is an inline SVG chart too (no matplotlib): per unit a histogram whose
    bars count every view once, the RMS line and the promised error's, and the labels."""
    from handeye.pipelines.verify import Verification
    from handeye.report.verification import verification_html

    rng = np.random.default_rng(0)
    px = np.abs(rng.normal(0.4, 0.1, 23))
    v = Verification("eye_in_hand", [f"v{k:02d}.png" for k in range(23)], px, 1.3 * px, "good", promised={"px": 0.45, "mm": 0.6})
    figures = _svg_figures(verification_html(v))
    assert len(figures) == 1
    panels = _of_class(figures[0], "panel")
    for panel in panels:
        counts = [int(re.search(r": (\d+) views$", b.find("title").text).group(1)) for b in _of_class(panel, "bar", "rect")]
        assert sum(counts) == 23 and len(counts) == 11  # min(20, max(5, n // 2)) bins
    words = [t for t, _ in _svg_texts(figures[0])]
    assert {"RMS", "promised (cross-validated)", "views", "error per view (px)", "error per view (mm at the target)"} <= set(words)
    assert len([ln for ln in figures[0].iter("line") if ln.get("stroke-dasharray")]) == 2  # the promised error, per unit
