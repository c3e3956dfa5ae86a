"""The web server of ``handeye live``: aiohttp, one page, one websocket, a few JSON actions.

aiohttp (the ``live`` extra) is the server and the websocket in one maintained dependency with no
compiled web stack of its own; the page (``static/``: one HTML file, one script, one style sheet,
written by hand) is served from the package, so nothing is fetched from the internet.

* ``GET /``: the page; ``GET /static/NAME``: its script and style sheet.
* ``GET /ws``: a websocket. The server sends the whole state as JSON (:meth:`LiveCapture.snapshot`)
  on connecting and after every change, and each frame as one binary message: 4 bytes (big-endian
  length of a JSON header), the header (:func:`~handeye.workflows.live.capture.preview_frame`'s, with
  ``seq`` and ``captured_at``), the JPEG. A slow page gets the newest frame, never a queue of old ones.
* ``POST /api/take``, ``/api/remove`` (``{"name": ...}``), ``/api/move``, ``/api/finish``: the actions,
  answered ``{"ok": bool, "message": str}``.
* ``GET /views/NAME.jpg``: a view's thumbnail; ``GET /results/NAME``: the files ``finish`` wrote.

Bound to 127.0.0.1 (the default), the page needs no token; the server still refuses requests whose
``Host`` is not the loopback address it serves (a web page elsewhere cannot reach it by DNS
rebinding) and actions from another origin (it cannot move the robot from another site). Bound to
any other address (``--host``), every request needs the one-time token printed at the start (in the
page's address once; then a cookie).
"""

from __future__ import annotations

import asyncio
import importlib
import ipaddress
import json
import secrets
import signal
import socket
import struct
import webbrowser
from importlib.resources import files
from pathlib import Path
from typing import Any

from ...errors import HandEyeError
from .capture import LiveCapture

__all__ = ["LiveServer", "serve", "require_web", "STATIC", "TOKEN_COOKIE", "is_loopback"]

#: The page's files, in the package.
STATIC = files("handeye.workflows.live") / "static"
#: The cookie that carries the token after the first request.
TOKEN_COOKIE = "handeye_live_token"
_TYPES = {".html": "text/html", ".js": "text/javascript", ".css": "text/css"}
#: Seconds an action may take before the page is told it did not answer.
ACTION_TIMEOUT = 120.0


def require_web():
    """aiohttp's web module, or a clear error naming the extra to install."""
    try:
        return importlib.import_module("aiohttp.web")
    except ImportError:
        raise HandEyeError("handeye live needs aiohttp: pip install 'handeye[live]'") from None


def is_loopback(host: str) -> bool:
    """Whether ``host`` is a loopback address (or ``localhost``)."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


class LiveServer:
    """The page's server for one :class:`LiveCapture` (see the module's text). ``token``: required of
    every request when not None."""

    def __init__(self, capture: LiveCapture, token: str | None = None) -> None:
        self.web = require_web()
        self.capture, self.token = capture, token
        self.loop: asyncio.AbstractEventLoop | None = None
        self.clients: dict[Any, asyncio.Event] = {}  #: each websocket and the event that wakes its sender
        self.frame: bytes | None = None
        self.seq = 0  #: the newest frame's number
        self.version = 0  #: counts the state's changes
        self.port: int | None = None
        self.hosts: set[str] = set()
        capture.on_change = self._from_thread(self._state_changed)
        capture.on_frame = self._from_thread(self._new_frame)

    def _from_thread(self, func):
        def call(*args) -> None:
            loop = self.loop
            if loop is not None and not loop.is_closed():
                try:
                    loop.call_soon_threadsafe(func, *args)
                except RuntimeError:  # the loop closed meanwhile: the server is stopping
                    pass
        return call

    def _wake(self) -> None:
        for event in self.clients.values():
            event.set()

    def _state_changed(self) -> None:
        self.version += 1
        self._wake()

    def _new_frame(self, header: dict[str, Any], jpeg: bytes) -> None:
        self.seq += 1
        head = json.dumps({**header, "seq": self.seq}).encode()
        self.frame = struct.pack(">I", len(head)) + head + jpeg
        self._wake()

    # -- the app ---------------------------------------------------------------------------------------------
    def app(self):
        """The aiohttp application."""
        web = self.web
        guard = self._guard

        async def guarded(request, handler):
            return await guard(request, handler)

        app = web.Application(middlewares=[web.middleware(guarded)], client_max_size=64 * 1024)
        app.router.add_get("/", self._page)
        app.router.add_get("/static/{name}", self._static)
        app.router.add_get("/ws", self._socket)
        app.router.add_get("/state", self._state)
        app.router.add_post("/api/{action}", self._action)
        app.router.add_get("/views/{name}.jpg", self._thumb)
        app.router.add_get("/results/{name}", self._result)
        return app

    async def _guard(self, request, handler):
        """The token (when bound beyond loopback), the Host (on loopback) and, for actions and the
        websocket, the Origin: a request that fails one is refused with the reason."""
        web = self.web
        if self.token is not None:
            given = request.query.get("token") or request.cookies.get(TOKEN_COOKIE)
            if not (given and secrets.compare_digest(given, self.token)):
                return web.Response(status=403, text="handeye live: this page needs the token printed when the server "
                                    "started (open the address it printed, with ?token=...)")
        elif self.hosts and request.host not in self.hosts:
            return web.Response(status=403, text=f"handeye live: unknown host {request.host!r}")
        origin = request.headers.get("Origin")
        if (request.method == "POST" or request.path == "/ws") and origin is not None:
            if origin.split("://", 1)[-1] != request.host:
                return web.Response(status=403, text="handeye live: actions only from the page this server serves")
        response = await handler(request)
        if self.token is not None and request.query.get("token") and not isinstance(response, web.WebSocketResponse):
            response.set_cookie(TOKEN_COOKIE, self.token, httponly=True, samesite="Strict")
        return response

    async def _page(self, request):
        return self._file("index.html")

    async def _static(self, request):
        name = request.match_info["name"]
        if name not in ("live.js", "live.css"):
            raise self.web.HTTPNotFound(text=f"no file {name}")
        return self._file(name)

    def _file(self, name: str):
        text = (STATIC / name).read_text(encoding="utf-8")
        return self.web.Response(text=text, content_type=_TYPES[Path(name).suffix], headers={"Cache-Control": "no-store"})

    async def _state(self, request):
        return self.web.json_response(self.capture.snapshot())

    async def _action(self, request):
        web = self.web
        action = request.match_info["action"]
        try:
            body = await request.json() if request.can_read_body else {}
        except (ValueError, UnicodeDecodeError):
            return web.json_response({"ok": False, "message": "the request's body is not JSON"}, status=400)
        if action == "take":
            future = self.capture.take()
        elif action == "move":
            future = self.capture.move_next()
        elif action == "finish":
            future = self.capture.finish()
        elif action == "remove" and isinstance(body, dict) and isinstance(body.get("name"), str):
            future = self.capture.remove(body["name"])
        else:
            return web.json_response({"ok": False, "message": f"unknown action {action!r}"}, status=404)
        try:
            answer = await asyncio.wait_for(asyncio.wrap_future(future), ACTION_TIMEOUT)
        except asyncio.TimeoutError:
            answer = {"ok": False, "message": f"no answer within {ACTION_TIMEOUT:g} s (the camera or the robot does not "
                      "answer?); the action may still complete"}
        return web.json_response(answer)

    async def _thumb(self, request):
        data = await asyncio.get_running_loop().run_in_executor(None, self.capture.thumbnail, request.match_info["name"])
        if data is None:
            raise self.web.HTTPNotFound(text="no such view")
        return self.web.Response(body=data, content_type="image/jpeg", headers={"Cache-Control": "max-age=3600"})

    async def _result(self, request):
        name = request.match_info["name"]
        done = self.capture.snapshot()["finished"]
        if done is None or name not in done["files"]:
            raise self.web.HTTPNotFound(text=f"no result file {name} (press Finish first)")
        return self.web.FileResponse(Path(done["folder"]) / name, headers={"Cache-Control": "no-store"})

    async def _socket(self, request):
        web = self.web
        # no per-message deflate: the frames are JPEG (nothing to gain), and aiohttp sends a compressed frame
        # from a task of its own whose "Cannot write to closing transport", when the page goes away mid-frame,
        # nobody retrieves ("Task exception was never retrieved" and a traceback in the server's log)
        ws = web.WebSocketResponse(heartbeat=10.0, max_msg_size=64 * 1024, compress=False)
        await ws.prepare(request)
        wake = asyncio.Event()
        self.clients[ws] = wake
        sender = asyncio.create_task(self._send_loop(ws, wake))
        try:
            async for _ in ws:  # the page sends nothing that matters; this waits for the close
                pass
        except (ConnectionError, asyncio.CancelledError):
            pass
        finally:
            self.clients.pop(ws, None)
            sender.cancel()
            await asyncio.gather(sender, return_exceptions=True)
        return ws

    async def _send_loop(self, ws, wake: asyncio.Event) -> None:
        """The state now, then the state after every change and the newest frame, until the socket closes."""
        version, seq = None, 0
        try:
            while not ws.closed:
                if self.version != version:
                    version = self.version
                    await ws.send_str(json.dumps(self.capture.snapshot()))
                if self.frame is not None and self.seq != seq:
                    seq = self.seq
                    await ws.send_bytes(self.frame)
                if self.version == version and self.seq == seq:
                    wake.clear()
                    try:
                        await asyncio.wait_for(wake.wait(), 5.0)
                    except asyncio.TimeoutError:
                        pass
        except (ConnectionError, RuntimeError):  # the page went away: nothing to send to
            return

    async def run(self, host: str = "127.0.0.1", port: int = 8765, open_browser: bool = True,
                  ready=None, stop: asyncio.Event | None = None, move_first: bool = False) -> None:
        """Serve until ``stop`` is set (or SIGINT / SIGTERM). ``ready(url)`` is called once listening;
        ``move_first``: as :meth:`LiveCapture.start`."""
        web = self.web
        self.loop = asyncio.get_running_loop()
        stop = stop or asyncio.Event()
        for sig in (signal.SIGINT, signal.SIGTERM):
            try:
                self.loop.add_signal_handler(sig, stop.set)
            except (NotImplementedError, RuntimeError, ValueError):  # not the main thread, or not on this platform
                pass
        runner = web.AppRunner(self.app(), access_log=None, handle_signals=False)
        await runner.setup()
        site = web.TCPSite(runner, host, port)
        try:
            await site.start()
        except OSError as exc:
            await runner.cleanup()
            raise HandEyeError(f"cannot serve on {host}:{port} ({exc.strerror or exc}): choose another --port") from None
        self.port = runner.addresses[0][1]
        if host in ("0.0.0.0", "::", ""):  # every address: the address others type is this machine's name
            host_shown = socket.gethostname()
        else:
            host_shown = host
        shown = f"[{host_shown}]" if ":" in host_shown else host_shown
        self.hosts = {f"{shown}:{self.port}", f"localhost:{self.port}"} if is_loopback(host) else set()
        url = f"http://{shown}:{self.port}/" + (f"?token={self.token}" if self.token else "")
        try:
            await self.loop.run_in_executor(None, self.capture.start, move_first)
            if ready is not None:
                ready(url)
            if open_browser:
                await self.loop.run_in_executor(None, webbrowser.open, url)
            await stop.wait()
        finally:
            for ws in list(self.clients):
                await ws.close(message=b"the handeye live server stopped")
            await runner.cleanup()
            await self.loop.run_in_executor(None, self.capture.stop)


def serve(capture: LiveCapture, host: str = "127.0.0.1", port: int = 8765, open_browser: bool = True,
          ready=None, move_first: bool = False) -> None:
    """Serve ``capture``'s page until Ctrl-C: on 127.0.0.1 without a token; on any other ``host`` with
    a one-time token that ``ready(url)`` gets in the address (print it)."""
    token = None if is_loopback(host) else secrets.token_urlsafe(18)
    server = LiveServer(capture, token)
    asyncio.run(server.run(host, port, open_browser, ready, move_first=move_first))
