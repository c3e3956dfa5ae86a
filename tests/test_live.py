"""handeye live (issue 80): the capture page. The capture without the web (views written as taken,
removed into removed/, a failed detection, a camera that stops, a robot that disconnects, a killed
calibration process, a capture continued), the server (the token, the origin, a websocket closed
mid-capture, two clients), and the page in Debian's chromium through chromium-driver: 12 views by
clicks, one removed, Finish, and the result equal to ``handeye calibrate`` of the session written;
a reload mid-capture, two tabs, a closed websocket and a killed server, with no view lost and no
traceback in the server's log."""

from __future__ import annotations

import asyncio
import json
import logging
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
from contextlib import contextmanager
from pathlib import Path

import cv2
import numpy as np
import pytest

import browsers
from handeye.cli import main
from handeye.errors import HandEyeError
from handeye.frames.poses import format_poses
from handeye.io.session import load_session
from handeye.pipelines.folders import calibrate_session
from handeye.planning.poses import fronto_parallel_start
from handeye.sensors.camera import target_from_spec
from handeye.workflows.acquire import SimCamera, SimRobot, SimWorld
from handeye.workflows.live import LiveCapture, PoseFileRobot, StillSimCamera, preview_frame
from handeye.workflows.live.capture import STATE_FILE

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
CHROMEDRIVER = shutil.which("chromedriver")


def _sim(seed=1, target=None):
    world = SimWorld.default("eye_in_hand", seed=seed, target=target)
    robot = SimRobot(world)
    return world, robot, StillSimCamera(SimCamera(world, robot))


def _capture(folder, world, robot, camera, **kw):
    kw.setdefault("isolated", False)
    return LiveCapture(folder, robot, camera, "eye_in_hand", world.target_spec, world.K, world.dist, world.image_size,
                       world.X, world.Z, **kw)


def _wait(predicate, timeout=60.0, what="the condition"):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = predicate()
        if value:
            return value
        time.sleep(0.1)
    raise AssertionError(f"timed out waiting for {what}")


def _calibrated(live, n):
    """Wait until the page's state holds a calibration of ``n`` views (not merely asked for)."""
    return _wait(lambda: (c := live.snapshot()["calibration"]) is not None and len(c.get("views", [])) == n
                 and live.snapshot()["busy"] is None and c, what=f"a calibration of {n} views")


# -- the preview ------------------------------------------------------------------------------------------------
def test_preview_draws_the_detection_at_the_frames_scale_and_marks_missed_points():
    """The preview's corners (found on a copy 400 px wide) lie on the full-size detection's, scaled to
    the frame sent; a ChArUco board half hidden has its hidden corners marked missed, where they are."""
    spec = {"type": "charuco", "cols": 7, "rows": 5, "square": 0.03, "marker": 0.022, "dictionary": "DICT_5X5_100"}
    world, robot, camera = _sim(seed=3, target=spec)
    target = target_from_spec(spec)
    start = fronto_parallel_start(world.X, world.Z, target.object_points(), 0.45, "eye_in_hand")
    robot.move_to(format_poses(start[None], "quat_wxyz")[0])
    image = camera.grab()
    full = target.detect(image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY))
    assert full is not None and len(full) == len(target.object_points())
    header, jpeg = preview_frame(image, target, world.K, world.dist, detect_width=400, frame_width=320)
    shown = cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_UNCHANGED)
    scale = 320 / image.shape[1]
    assert shown.shape[1] == header["width"] == 320 and header["found"] and not header["missed"]
    corners = np.array(header["corners"])
    assert np.abs(corners - ((full.image_points + 0.5) * scale - 0.5)).max() < 0.5  # a fraction of a shown pixel
    assert header["axes"] is not None and len(header["axes"]) == 4
    # hide the board's right part: those corners are missed, and marked where the full detection had them
    hidden = image.copy()
    cut = int(np.percentile(full.image_points[:, 0], 70))
    hidden[:, cut:] = 128
    header, _ = preview_frame(hidden, target, world.K, world.dist, detect_width=400, frame_width=320)
    assert header["found"] and 0 < header["n_found"] < header["n_total"] and header["missed"]
    square_shown = 0.03 / 0.45 * world.K[0, 0] * scale  # a square's side in the frame's pixels, roughly
    assert np.min(np.array(header["missed"])[:, 0]) > (cut + 0.5) * scale - 0.5 - square_shown
    assert len(header["missed"]) + header["n_found"] == header["n_total"]
    blank = np.full_like(image, 128)
    header, _ = preview_frame(blank, target, world.K, world.dist)
    assert not header["found"] and header["corners"] == [] and header["axes"] is None


# -- the capture without the web --------------------------------------------------------------------------------
@pytest.mark.slow
def test_views_are_written_as_taken_removed_into_removed_and_finish_equals_calibrate(tmp_path):
    world, robot, camera = _sim()
    live = _capture(tmp_path / "cell", world, robot, camera)
    live.start(move_first=True)
    try:
        for k in range(6):
            if k:
                assert live.move_next().result(60)["ok"]
            answer = live.take().result(60)
            assert answer["ok"], answer
            session = load_session(tmp_path / "cell")  # on disk at once, as a session calibrate reads
            assert session.image_names == [f"{i:03d}.png" for i in range(k + 1)]
        assert live.remove("002.png").result(60)["ok"]
        assert not live.remove("002.png").result(60)["ok"]  # said, not an error
        assert (tmp_path / "cell" / "removed" / "002.png").is_file() and not (tmp_path / "cell" / "images" / "002.png").exists()
        assert load_session(tmp_path / "cell").image_names == ["000.png", "001.png", "003.png", "004.png", "005.png"]
        cal = _calibrated(live, 5)
        assert cal["error"] is None and cal["views"] == ["000.png", "001.png", "003.png", "004.png", "005.png"]
        assert live.move_next().result(60)["ok"]
        assert live.take().result(60)["ok"]  # a new name: the removed image is never overwritten
        assert load_session(tmp_path / "cell").image_names[-1] == "006.png"
        _calibrated(live, 6)
        done = live.finish().result(120)
        assert done["ok"], done
    finally:
        live.stop()
    rows = load_session(tmp_path / "cell").robot_input.values  # each move asked right after a view went to a new pose
    assert len(np.unique(np.round(rows, 6), axis=0)) == len(rows)
    written = json.loads((tmp_path / "cell-results" / "result.json").read_text())
    direct = calibrate_session(tmp_path / "cell", progress=False)
    assert np.abs(np.array(written["X"]["matrix"]) - direct.X).max() < 1e-9
    assert np.abs(np.array(live.snapshot()["calibration"]["X"]) - direct.X).max() < 1e-9
    record = __import__("yaml").safe_load((tmp_path / "cell" / STATE_FILE).read_text())
    assert [d["name"] for d in record["removed"]] == ["002.png"] and [h["n"] for h in record["history"]][-1] == 6


class _FlakyCamera:
    """The simulated camera that gives a blank image, or stops, when told."""

    def __init__(self, camera):
        self.camera, self.mode = camera, "ok"

    def grab(self):
        if self.mode == "stopped":
            raise HandEyeError("the camera gave no image (disconnected)")
        image = self.camera.grab()
        return np.full_like(image, 128) if self.mode == "blank" else image


class _FlakyRobot(SimRobot):
    def __init__(self, world):
        super().__init__(world)
        self.connected = True

    def current_pose(self):
        if not self.connected:
            raise RuntimeError("RTDE receive: connection lost")
        return super().current_pose()


@pytest.mark.slow
def test_a_failed_detection_a_stopped_camera_and_a_lost_robot_are_said_and_nothing_is_lost(tmp_path, capsys):
    world = SimWorld.default("eye_in_hand", seed=1)
    robot = _FlakyRobot(world)
    camera = _FlakyCamera(StillSimCamera(SimCamera(world, robot)))
    live = _capture(tmp_path / "cell", world, robot, camera)
    live.start(move_first=True)
    try:
        assert live.take().result(60)["ok"]
        camera.mode = "blank"
        answer = live.take().result(60)
        assert not answer["ok"] and "not taken" in answer["message"] and "rejected/001.png" in answer["message"]
        assert (tmp_path / "cell" / "rejected" / "001.png").is_file()
        camera.mode = "stopped"
        _wait(lambda: live.snapshot()["camera"]["error"], what="the camera's error")
        assert "disconnected" in live.snapshot()["camera"]["error"]
        answer = live.take().result(60)
        assert not answer["ok"] and "disconnected" in answer["message"]
        camera.mode = "ok"
        _wait(lambda: live.snapshot()["camera"]["error"] is None, what="frames again")
        robot.connected = False
        _wait(lambda: live.snapshot()["robot"]["error"], what="the robot's error")
        assert "connection lost" in live.snapshot()["robot"]["error"]
        answer = live.take().result(60)
        assert not answer["ok"] and "connection lost" in answer["message"]
        robot.connected = True
        assert live.move_next().result(60)["ok"] and live.take().result(60)["ok"]
        texts = [m["text"] for m in live.snapshot()["messages"]]
    finally:
        live.stop()
    assert load_session(tmp_path / "cell").image_names == ["000.png", "002.png"]  # nothing lost, nothing overwritten
    assert any("camera" in t and "disconnected" in t for t in texts) and any("robot" in t for t in texts)
    out = capsys.readouterr()
    assert "Traceback" not in out.out + out.err


@pytest.mark.slow
def test_a_killed_calibration_process_is_started_again(tmp_path):
    world, robot, camera = _sim()
    live = _capture(tmp_path / "cell", world, robot, camera, isolated=True)
    live.start(move_first=True)
    try:
        for k in range(4):
            if k:
                assert live.move_next().result(60)["ok"]
            assert live.take().result(60)["ok"]
        _calibrated(live, 4)
        pids = list(live._pool._processes)  # noqa: SLF001  (the test kills the process behind the pool)
        assert pids
        for pid in pids:
            os.kill(pid, signal.SIGKILL)
        assert live.move_next().result(60)["ok"] and live.take().result(60)["ok"]
        cal = _calibrated(live, 5)
        assert cal["error"] is None and cal["verdict"] in ("good", "weak")
        assert any("started again" in m["text"] for m in live.snapshot()["messages"])
    finally:
        live.stop()


@pytest.mark.slow
def test_a_stopped_capture_continues_with_its_views(tmp_path):
    world, robot, camera = _sim()
    live = _capture(tmp_path / "cell", world, robot, camera)
    live.start(move_first=True)
    try:
        for k in range(3):
            if k:
                assert live.move_next().result(60)["ok"]
            assert live.take().result(60)["ok"]
        assert live.remove("001.png").result(60)["ok"]
        before = live.snapshot()
    finally:
        live.stop()
    again = _capture(tmp_path / "cell", world, robot, camera)
    again.start()
    try:
        after = again.snapshot()
        assert [(v["name"], v["row"]) for v in after["views"]] == [(v["name"], v["row"]) for v in before["views"]]
        assert after["removed"] == ["001.png"]
    finally:
        again.stop()
    other = SimWorld.default("eye_to_hand", seed=1)
    with pytest.raises(HandEyeError, match="eye_in_hand capture"):
        LiveCapture(tmp_path / "cell", SimRobot(other), camera, "eye_to_hand", other.target_spec, other.K, other.dist,
                    other.image_size, other.X, other.Z, isolated=False).start()


@pytest.mark.slow
def test_a_robot_moved_by_hand_reports_its_pose_in_a_file(tmp_path):
    """--robot manual:POSE_FILE: the page shows the next pose to reach, cannot move the robot, and
    takes each view at the pose the file holds; a file it cannot read is said, and no view is taken."""
    world = SimWorld.default("eye_in_hand", seed=1)
    arm = SimRobot(world)  # what the operator jogs; the page only reads the file
    pose_file = tmp_path / "pose.txt"
    robot = PoseFileRobot(pose_file, "quat_wxyz", "m", "rad")
    live = LiveCapture(tmp_path / "cell", robot, StillSimCamera(SimCamera(world, arm)), "eye_in_hand", world.target_spec,
                       world.K, world.dist, world.image_size, world.X, world.Z, can_move=False, isolated=False)
    live.start()
    try:
        _wait(lambda: live.snapshot()["robot"]["error"], what="no pose file yet")
        answer = live.move_next().result(30)
        assert not answer["ok"] and "by hand" in answer["message"]
        for k in range(2):
            target = live.snapshot()["next_pose"]
            assert target is not None and not target["can_move"]
            arm.move_to(np.array(target["values"]))  # the operator jogs there; the robot program writes its pose
            pose_file.write_text(" ".join(f"{v:.9f}" for v in arm.current_pose()))
            answer = live.take().result(60)
            assert answer["ok"], answer
            _wait(lambda: (p := live.snapshot()["next_pose"]) is not None and p["candidate"] != target["candidate"],
                  what="the next pose")
        pose_file.write_text("1, 2, 3")
        _wait(lambda: "cannot read the pose" in (live.snapshot()["robot"]["error"] or ""), what="the file's error")
        answer = live.take().result(60)
        assert not answer["ok"] and "give the 7 numbers" in answer["message"]
    finally:
        live.stop()
    session = load_session(tmp_path / "cell")
    assert session.image_names == ["000.png", "001.png"] and session.robot_input.format == "quat_wxyz"


@pytest.mark.slow
def test_a_ur_moves_on_the_click_at_capped_speed_and_a_lost_connection_is_said(tmp_path):
    """The UR backend against a stand-in of ur_rtde: "Move to the next pose" is one linear move to the
    planner's pose in UR's format (the click confirms it: no terminal question) at the capped speed; a
    controller that stops answering is said on the page and no view is taken."""
    import types

    from handeye.frames.poses import parse_poses
    from handeye.workflows.acquire import URRobot

    world = SimWorld.default("eye_in_hand", seed=1)
    moves, state = [], {"pose": [0.4, 0.1, 0.3, 0.0, 3.1, 0.0], "up": True}

    def actual():
        if not state["up"]:
            raise RuntimeError("RTDE receive: the controller does not answer")
        return list(state["pose"])

    control = types.SimpleNamespace(moveL=lambda pose, v, a: moves.append((list(pose), v, a)) or state.update(pose=list(pose)) or True)
    robot = URRobot("192.0.2.1", speed=1.0, control=control, receive=types.SimpleNamespace(getActualTCPPose=actual), yes=True)
    camera = types.SimpleNamespace(grab=lambda: np.full((480, 640), 128, np.uint8))
    live = LiveCapture(tmp_path / "cell", robot, camera, "eye_in_hand", world.target_spec, world.K, world.dist,
                       world.image_size, world.X, world.Z, isolated=False)
    live.start()
    try:
        planned = live.snapshot()["next_pose"]
        assert planned["format"] == "rotvec" and planned["can_move"]
        assert live.move_next().result(30)["ok"]
        assert len(moves) == 1 and moves[0][1] == URRobot.MAX_SPEED
        assert np.allclose(parse_poses(np.array([moves[0][0]]), "rotvec", "m", "rad"),
                           parse_poses(np.array([planned["values"]]), "rotvec", "m", "rad"))
        answer = live.take().result(30)  # a grey image: no target, not taken
        assert not answer["ok"] and "rejected/000.png" in answer["message"]
        state["up"] = False
        _wait(lambda: "does not answer" in (live.snapshot()["robot"]["error"] or ""), what="the lost controller")
        answer = live.take().result(30)
        assert not answer["ok"] and "does not answer" in answer["message"]
    finally:
        live.stop()
    assert not (tmp_path / "cell" / "session.yaml").exists()


# -- the server -------------------------------------------------------------------------------------------------
aiohttp = browsers.importorskip("aiohttp", reason="handeye live's server needs aiohttp (pip install 'handeye[live]')")


@contextmanager
def _served(folder, token=None, flaky=False, **kw):
    """A LiveServer on 127.0.0.1 (any free port) in a thread of its own; yields (base url, capture);
    ``flaky``: the robot and camera of the bad-input tests (their ``connected`` and ``mode`` switches)."""
    from handeye.workflows.live import LiveServer

    world, robot, camera = _sim()
    if flaky:
        robot = _FlakyRobot(world)
        camera = _FlakyCamera(StillSimCamera(SimCamera(world, robot)))
    live = _capture(folder, world, robot, camera, **kw)
    server = LiveServer(live, token)
    box = {}
    ready = threading.Event()

    def run():
        async def go():
            box["stop"], box["loop"] = asyncio.Event(), asyncio.get_running_loop()
            await server.run("127.0.0.1", 0, False, lambda url: ready.set(), stop=box["stop"], move_first=True)
        asyncio.run(go())

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    assert ready.wait(60), "the server did not start"
    try:
        yield f"http://127.0.0.1:{server.port}", live
    finally:
        box["loop"].call_soon_threadsafe(box["stop"].set)
        thread.join(60)


async def _state_with(ws, predicate, timeout=60.0):
    """Read the websocket until a state message satisfies ``predicate``; frames are skipped."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        msg = await ws.receive(timeout=max(0.1, end - time.monotonic()))
        if msg.type == aiohttp.WSMsgType.TEXT:
            state = json.loads(msg.data)
            if predicate(state):
                return state
        elif msg.type in (aiohttp.WSMsgType.CLOSE, aiohttp.WSMsgType.CLOSED, aiohttp.WSMsgType.ERROR):
            raise AssertionError(f"the websocket closed: {msg}")
    raise AssertionError("timed out waiting for a state")


@pytest.mark.slow
def test_the_token_the_host_and_the_origin_are_required(tmp_path):
    async def probe(base):
        async with aiohttp.ClientSession(cookie_jar=aiohttp.CookieJar(unsafe=True)) as s:  # a browser keeps an IP's cookies
            r = await s.get(base + "/")
            assert r.status == 403 and "token" in await r.text()
            r = await s.post(base + "/api/take")
            assert r.status == 403
            r = await s.get(base + "/?token=wrong")
            assert r.status == 403
            r = await s.get(base + "/?token=secret-token")
            assert r.status == 200 and "handeye live" in await r.text()
            r = await s.get(base + "/state")  # the cookie now carries the token
            assert r.status == 200 and (await r.json())["session"].endswith("cell")
            r = await s.post(base + "/api/take", headers={"Origin": "http://example.com"})
            assert r.status == 403 and "only from the page" in await r.text()
            async with s.ws_connect(base + "/ws") as ws:
                state = await _state_with(ws, lambda st: True)
                assert state["views"] == []

    with _served(tmp_path / "cell", token="secret-token") as (base, _):
        asyncio.run(probe(base))

    async def loopback(base):
        async with aiohttp.ClientSession() as s:
            assert (await s.get(base + "/")).status == 200
            r = await s.get(base + "/", headers={"Host": "attacker.example:80"})  # DNS rebinding
            assert r.status == 403

    with _served(tmp_path / "cell2") as (base, _):
        asyncio.run(loopback(base))


@pytest.mark.slow
def test_a_websocket_closed_mid_capture_and_two_clients_lose_nothing(tmp_path, capsys, caplog):
    async def scenario(base):
        async with aiohttp.ClientSession() as s1, aiohttp.ClientSession() as s2:
            ws1 = await s1.ws_connect(base + "/ws")
            ws2 = await s2.ws_connect(base + "/ws")
            frame = None
            while frame is None:  # a frame: 4 bytes of header length, the header, a JPEG
                msg = await ws1.receive(timeout=60)
                if msg.type == aiohttp.WSMsgType.BINARY:
                    n = int.from_bytes(msg.data[:4], "big")
                    frame = json.loads(msg.data[4:4 + n])
                    assert msg.data[4 + n:4 + n + 2] == b"\xff\xd8" and frame["found"]
            take = asyncio.ensure_future(s1.post(base + "/api/take"))
            await asyncio.sleep(0.01)
            ws1._response.connection.transport.abort()  # noqa: SLF001  (the page's socket cut mid-take)
            answer = await (await take).json()
            assert answer["ok"], answer
            state = await _state_with(ws2, lambda st: len(st["views"]) == 1)
            ws3 = await s1.ws_connect(base + "/ws")  # the page reconnects: the same state
            again = await _state_with(ws3, lambda st: True)
            assert again["views"] == state["views"]
            r = await s2.post(base + "/api/remove", json={"name": "000.png"})
            assert (await r.json())["ok"]
            assert (await _state_with(ws3, lambda st: st["views"] == []))["removed"] == ["000.png"]
            r = await s2.post(base + "/api/remove", data=b"not json")
            assert r.status == 400
            r = await s2.get(base + "/views/../../etc/passwd.jpg")
            assert r.status == 404
            await ws2.close()
            await ws3.close()

    with _served(tmp_path / "cell") as (base, live):
        asyncio.run(scenario(base))
        assert not (tmp_path / "cell" / "session.yaml").exists()  # no view left: no session, and the view kept aside
        assert (tmp_path / "cell" / "removed" / "000.png").is_file()
        record = __import__("yaml").safe_load((tmp_path / "cell" / STATE_FILE).read_text())
        assert [d["name"] for d in record["removed"]] == ["000.png"] and len(record["removed"][0]["row"]) == 7
    out = capsys.readouterr()
    assert "Traceback" not in out.out + out.err and "Error handling request" not in out.out + out.err
    assert not [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]


# -- the page in a real browser ---------------------------------------------------------------------------------
class _Server:
    """``handeye live`` as a user runs it, in a process of its own; its output is the server's log."""

    def __init__(self, folder: Path, port: int = 0):
        self.log = folder.parent / f"{folder.name}-server.log"
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        self.out = open(self.log, "a")
        self.proc = subprocess.Popen([sys.executable, "-m", "handeye.cli", "live", str(folder), "--robot", "sim", "--camera",
                                      "sim", "--no-browser", "--port", str(port), "--fps", "5"],
                                     stdout=self.out, stderr=subprocess.STDOUT, env=env, start_new_session=True)
        m = _wait(lambda: re.search(r"is at (http://127\.0\.0\.1:(\d+)/)", self.log.read_text()) or self.proc.poll() is not None,
                  120, "the server's address")
        assert m is not True and self.proc.poll() is None, self.log.read_text()
        self.url, self.port = m.group(1), int(m.group(2))

    def stop(self, sig=signal.SIGINT):
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
            self.proc.wait(60)
        self._reap()
        self.out.close()

    def kill(self):
        """The server killed as a crash would (SIGKILL): its calibration process must leave by itself
        (before, it waited for work for ever); reaped in any case, so that a failure leaves nothing."""
        self.proc.kill()
        self.proc.wait(30)
        gone = _wait_group_gone(self.proc.pid, 10)
        self._reap()
        assert gone, "the server's calibration process outlived the killed server"

    def _reap(self):
        try:
            os.killpg(self.proc.pid, signal.SIGKILL)  # the server's session: its pool's workers too
        except ProcessLookupError:
            pass


def _wait_group_gone(pgid: int, seconds: float) -> bool:
    """Whether every process of the session ``pgid`` has exited (zombies count as exited) within ``seconds``."""
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if not any(_running_in_group(stat, pgid) for stat in Path("/proc").glob("[0-9]*/stat")):
            return True
        time.sleep(0.1)
    return False


def _running_in_group(stat: Path, pgid: int) -> bool:
    try:
        fields = stat.read_text().rsplit(")", 1)[1].split()  # state, ppid, pgrp, ...
    except OSError:  # exited meanwhile
        return False
    return int(fields[2]) == pgid and fields[0] != "Z"


def _browser(tmp_path, width=1400, height=1300):
    webdriver = browsers.importorskip("selenium.webdriver", reason="the browser test needs selenium (the test extra)")
    from selenium.webdriver.chrome.service import Service

    opts = webdriver.ChromeOptions()
    opts.binary_location = CHROMIUM
    for arg in ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                "--disable-background-networking", "--disable-component-update", "--disable-sync",
                f"--user-data-dir={tmp_path / 'chromium-profile'}", f"--window-size={width},{height}"):
        opts.add_argument(arg)
    return webdriver.Chrome(service=Service(CHROMEDRIVER), options=opts)


def _live(driver, expr):
    return driver.execute_script(f"return window.__live && {expr};")


def _n_views(driver):
    return _live(driver, "window.__live.state && window.__live.state.views.length")


def _click(driver, element_id):
    driver.find_element("id", element_id).click()


def _take_by_clicks(driver, n_before):
    """Move to the planner's next pose, wait for the robot, take a view; the page must show it."""
    _wait(lambda: driver.find_element("id", "move").is_enabled(), what="the move button")
    _click(driver, "move")
    _wait(lambda: _live(driver, "window.__live.pending() === 0") and driver.find_element("id", "take").is_enabled(),
          what="the move's answer")
    _click(driver, "take")
    _wait(lambda: _n_views(driver) == n_before + 1, what=f"view {n_before + 1} on the page")
    _wait(lambda: _live(driver, "window.__live.pending() === 0"), what="the take's answer")  # the state may come first
    answer = driver.find_element("id", "answer").text
    assert "taken" in answer, answer


@pytest.mark.slow
@browsers.skip_unless(CHROMIUM is not None and CHROMEDRIVER is not None,
                        reason="no chromium and chromium-driver on this machine (apt-get install chromium chromium-driver)")
def test_the_page_in_chromium_takes_12_views_removes_one_and_writes_what_calibrate_gives(tmp_path):
    """The simulated cell driven from the page by clicks: 12 views, one removed, Finish; the result
    written equals ``handeye calibrate`` of the session on disk. On the way: a reload while a view is
    being taken, a second tab, the page's websocket closed, and the server killed and started again:
    no view is lost, the page says what happened, and the server's log has no traceback."""
    folder = tmp_path / "cell"
    server = _Server(folder)
    driver = _browser(tmp_path)
    try:
        driver.get(server.url)
        _wait(lambda: _live(driver, "window.__live.frames.length > 0"), what="a frame on the page")
        _wait(lambda: "target found" in driver.find_element("id", "frame-status").text, 30, "the target found on the page")
        for k in range(5):
            _take_by_clicks(driver, k)
        # a reload while a view is being taken: the view is taken, and the page shows it after the reload
        _click(driver, "move")
        _wait(lambda: _live(driver, "window.__live.pending() === 0"), what="the move")
        _click(driver, "take")
        time.sleep(0.2)  # the request on its way (a reload before it leaves cancels the click, rightly)
        driver.refresh()
        _wait(lambda: _n_views(driver) == 6, what="the view taken across the reload")
        # a second tab shows the same state, and follows the first
        first = driver.current_window_handle
        driver.switch_to.new_window("tab")
        driver.get(server.url)
        _wait(lambda: _n_views(driver) == 6, what="the second tab's views")
        second = driver.current_window_handle
        driver.switch_to.window(first)
        for k in range(6, 9):
            _take_by_clicks(driver, k)
        driver.switch_to.window(second)
        _wait(lambda: _n_views(driver) == 9, what="the second tab following the first")
        driver.close()
        driver.switch_to.window(first)
        # the page's websocket closed: it says so, reconnects and shows the same state
        driver.execute_script("window.__live.ws.close();")
        _wait(lambda: "lost" in driver.find_element("id", "banner").text, 10, "the page saying the connection was lost")
        _wait(lambda: _live(driver, "window.__live.connected") and not driver.find_element("id", "banner").text
              and _n_views(driver) == 9, 30, "the page reconnected")
        # the server killed mid-capture: the page says so; started again on the same folder, nothing is lost
        names = [v["name"] for v in _live(driver, "window.__live.state.views")]
        server.kill()
        _wait(lambda: "lost" in driver.find_element("id", "banner").text, 10, "the page saying the server is gone")
        assert load_session(folder).image_names == names
        server.out.close()
        server = _Server(folder, server.port)
        _wait(lambda: _live(driver, "window.__live.connected") and _n_views(driver) == 9, 60, "the page back on the new server")
        assert [v["name"] for v in _live(driver, "window.__live.state.views")] == names
        for k in range(9, 12):
            _take_by_clicks(driver, k)
        _wait(lambda: _live(driver, "window.__live.state.calibration.n_views === 12"), 120, "the calibration of 12 views")
        # remove one view by its button
        figure = driver.find_element("css selector", '#views figure[data-name="004.png"]')
        figure.find_element("css selector", "button.remove").click()
        _wait(lambda: _n_views(driver) == 11 and _live(driver, "window.__live.state.calibration.views.length === 11")
              and _live(driver, "window.__live.state.busy === null"), 120, "the calibration of 11 views")
        page_X = np.array(_live(driver, "window.__live.state.calibration.X"))
        assert "good" in driver.find_element("id", "calib").text
        _click(driver, "finish")
        _wait(lambda: driver.find_element("id", "done").is_displayed(), 300, "the report written")
        assert "report.html" in driver.find_element("id", "done").text and str(folder.resolve()) in driver.find_element("id", "done").text
        assert not _live(driver, "window.__live.errors.length")
        # frames kept flowing while the calibrations ran (in their own process)
        assert _live(driver, "window.__live.frames.filter(function (f) { return f.busy && f.found; }).length") > 0
    finally:
        driver.quit()
        server.stop()
    log = "".join(p.read_text() for p in tmp_path.glob("*-server.log"))
    bad = min((log.find(w) for w in ("Traceback", "Error handling request") if w in log), default=-1)
    assert bad < 0, log[max(0, bad - 1500):bad + 3000]  # what came before it and the whole of it
    assert "004.png" not in load_session(folder).image_names and (folder / "removed" / "004.png").is_file()
    assert len(load_session(folder).image_names) == 11
    rows = load_session(folder).robot_input.values  # every move went to a new pose (none to a plan made before a view)
    assert len(np.unique(np.round(rows, 6), axis=0)) == len(rows)
    written = json.loads((tmp_path / "cell-results" / "result.json").read_text())
    assert main(["calibrate", str(folder), "--out", str(tmp_path / "again"), "--no-cache"]) in (0, 1)
    again = json.loads((tmp_path / "again" / "result.json").read_text())
    assert np.abs(np.array(written["X"]["matrix"]) - np.array(again["X"]["matrix"])).max() < 1e-9
    assert np.abs(page_X - np.array(again["X"]["matrix"])).max() < 1e-9
    assert written["verdict"] == again["verdict"]


@pytest.mark.slow
@browsers.skip_unless(CHROMIUM is not None and CHROMEDRIVER is not None,
                        reason="no chromium and chromium-driver on this machine (apt-get install chromium chromium-driver)")
def test_the_page_says_when_the_camera_stops_the_robot_is_lost_or_a_view_has_no_target(tmp_path):
    with _served(tmp_path / "cell", flaky=True) as (base, live):
        driver = _browser(tmp_path)
        try:
            driver.get(base + "/")
            _wait(lambda: "target found" in driver.find_element("id", "frame-status").text, 60, "the target on the page")
            _click(driver, "take")
            _wait(lambda: _n_views(driver) == 1, what="a view")
            live.camera.mode = "blank"
            _wait(lambda: "not found" in driver.find_element("id", "frame-status").text, 30, "the page saying no target")
            _click(driver, "take")
            _wait(lambda: "not taken" in driver.find_element("id", "answer").text, 60, "the page saying the view was not taken")
            assert "rejected/001.png" in driver.find_element("id", "answer").text
            live.camera.mode = "stopped"
            _wait(lambda: "Camera: the camera gave no image" in driver.find_element("id", "banner").text, 30,
                  "the page saying the camera stopped")
            _wait(lambda: "no image from the camera" in driver.find_element("id", "frame-status").text, 30,
                  "the page saying how long since the last frame")
            live.camera.mode = "ok"
            _wait(lambda: "Camera" not in driver.find_element("id", "banner").text, 30, "the camera back")
            live.robot.connected = False
            _wait(lambda: "Robot: RuntimeError: RTDE receive: connection lost" in driver.find_element("id", "banner").text, 30,
                  "the page saying the robot is lost")
            assert _n_views(driver) == 1 and "000.png" in driver.find_element("id", "views").text
        finally:
            driver.quit()
            live.robot.connected = True
