"""The station view's web server: aiohttp on its own thread and event loop.

The station's real-time loop is single-threaded and must never wait for the web
(DESIGN.md, "The runtime loop"), so the server runs apart, on a thread of its own with
its own :mod:`asyncio` loop, and the two meet at two points only:

- **snapshots in** (:meth:`ViewServer.publish`, called on the loop's thread): the newest
  snapshot replaces the previous one in a slot under a lock, its new track points,
  photos and log lines are added to bounded lists, and the server's loop is woken with
  :meth:`asyncio.AbstractEventLoop.call_soon_threadsafe` (once per batch, never once
  per snapshot while a wake-up is pending). Nothing waits.
- **commands out** (the ``on_command`` callback, called on the server's thread): every
  command the page sends is checked here (every string from a browser is hostile:
  bounded, known agents and modes only) and handed on as a
  :class:`~clark_engine.station.view_commands.CommandRequest`; :mod:`clark_engine.station.live_view`
  queues it for the loop and wakes the loop through a pipe.

Each WebSocket client has one sender task that sends ``hello``, then the newest state
whenever there is a newer one: a slow client skips the states it had no time for
rather than queueing them (newest wins), and is sent the track points, photos and log
lines it has not had yet (each has a sequence number) from bounded histories
(:data:`MAX_TRACK_POINTS`, :data:`MAX_PHOTOS`, :data:`MAX_LOG_LINES`).

In replay mode (``clark replay``, :mod:`clark_engine.station.replay`) the server is given a
:class:`ReplaySource` instead of snapshots: each client has its own time, which its page
moves with ``seek``, ``play``, ``pause`` and ``speed`` messages (:func:`parse_replay_control`);
its sender sends what the source builds for that time (a ``reset`` when the page jumps,
then ``state`` messages, at the update rate while it plays). Commands are refused.

The server applies the view's guards (docs/station-view.md, "Security"):

- With a token (:mod:`clark_engine.station.access`), every request (the page, the static
  files, the WebSocket) must carry it: ``?token=`` once (the page's URL; the server
  answers with a cookie for this port and redirects to the URL without the token), then
  the cookie, or an ``X-Clark-Token`` header or ``Authorization: Bearer``. Anything else
  gets 403. Tokens are compared in constant time.
- On a loopback bind the ``Host`` header must name the loopback address and port
  served (``127.0.0.1:P``, ``localhost:P``, ``[::1]:P``): a page of another site whose
  name was made to resolve to 127.0.0.1 (DNS rebinding) is refused.
- The WebSocket's ``Origin``, when a browser sends one, must be this server's own
  (``http://`` + the request's ``Host``), so a page of another site cannot open the
  WebSocket with the operator's cookie (cross-site WebSocket hijacking). Clients that
  are not browsers send no Origin and pass this check (they still need the token).
- The page is served with a strict Content-Security-Policy (its own scripts and styles
  only), ``X-Frame-Options: DENY``, ``nosniff`` and ``Referrer-Policy: no-referrer``.
- Connections are bounded before aiohttp sees them
  (:mod:`clark_engine.station.connections`), and floods of errors (accept() out of
  descriptors, aiohttp's bad requests) are one counted line per interval
  (:mod:`clark_engine.station.log_throttle`). What a page sends is checked by
  :mod:`clark_engine.station.page_messages`.
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import hmac
import itertools
import json
import logging
import resource
import socket
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final, Protocol
from urllib.parse import quote

from aiohttp import WSMsgType, web
from aiohttp.typedefs import Handler

from clark_engine.errors import UsageError
from clark_engine.station.access import MAX_TOKEN_CHARS, TOKEN_HEADER, check_token, is_loopback_host
from clark_engine.station.connections import Admitted, ConnectionCaps, ViewLimits, view_limits
from clark_engine.station.log_throttle import Throttle, ThrottledLogger
from clark_engine.station.page_messages import (
    COMMAND_BURST,
    COMMANDS_PER_S,
    CONTROLS_BURST,
    CONTROLS_PER_S,
    MAX_MESSAGE_BYTES,
    CommandRejected,
    RateBucket,
    parse_command,
    parse_replay_control,
)
from clark_engine.station.view_commands import CommandRequest
from clark_engine.station.view_model import Snapshot
from clark_engine.station.view_protocol import MAX_LOG_LINES, Json, page_json

STATIC_DIR: Final = Path(__file__).resolve().parent / "static"
"""The page, its script and style, and the vendored Leaflet."""

DEFAULT_PORT: Final = 8080
"""The port a :class:`ViewServer` serves when none is given."""

MAX_TRACK_POINTS: Final = 20_000
"""Track points kept for clients that connect later (all agents together)."""

MAX_PHOTOS: Final = 2_000
"""Photo positions kept for clients that connect later."""

MAX_CLIENTS: Final = 32
"""WebSocket clients served at once; more are closed at once (code 1013)."""

STOP_FLUSH_S: Final = 1.0
"""How long the server, when it stops, gives its clients to receive the last state."""

LISTEN_BACKLOG: Final = 128

_NO_RESOURCE: Final = frozenset({errno.EMFILE, errno.ENFILE, errno.ENOBUFS, errno.ENOMEM})

_LOG = logging.getLogger(__name__)


@dataclass(eq=False)
class _Client:
    """One WebSocket client: what it has been sent, and its sender's wake-up.

    In replay mode, also its own time (``replay_t``), whether it plays and how fast, and
    the time up to which it has every track point, photo and log line (``sent_t``, None
    before its first reset).
    """

    ws: web.WebSocketResponse
    address: str
    wake: asyncio.Event = field(default_factory=asyncio.Event)
    replies: deque[str] = field(default_factory=lambda: deque(maxlen=64))
    version: int = 0
    track_seq: int = 0
    photo_seq: int = 0
    log_seq: int = 0
    commands: RateBucket = field(default_factory=lambda: RateBucket(COMMANDS_PER_S, COMMAND_BURST))
    controls: RateBucket = field(default_factory=lambda: RateBucket(CONTROLS_PER_S, CONTROLS_BURST))
    replay_t: float = 0.0
    sent_t: float | None = None
    playing: bool = False
    speed: float = 1.0
    moved: bool = True

    def allow_command(self) -> bool:
        """Whether one more command fits this client's rate (:data:`COMMANDS_PER_S`)."""
        return self.commands.allow()


class ReplaySource(Protocol):
    """What the server needs of a replay (:class:`clark_engine.station.replay_frames.Replay`).

    Attributes:
        start_s: The earliest mission time of the run.
        end_s: The latest.
    """

    start_s: float
    end_s: float

    def clamp(self, t_s: float) -> float:
        """``t_s`` within the run's span."""
        ...

    def frame(self, t_s: float, after_s: float | None) -> list[Json]:
        """The messages that bring a page that has everything up to ``after_s`` to ``t_s``."""
        ...


@dataclass
class _Pending:
    """What the loop published since the server's loop last took it."""

    state: Json | None = None
    track: deque[Json] = field(default_factory=lambda: deque(maxlen=MAX_TRACK_POINTS))
    photos: deque[Json] = field(default_factory=lambda: deque(maxlen=MAX_PHOTOS))
    log: deque[Json] = field(default_factory=lambda: deque(maxlen=MAX_LOG_LINES))


class ViewServer:
    """The station view's HTTP and WebSocket server, on a thread of its own.

    Args:
        hello: The ``hello`` message (:func:`~clark_engine.station.view_hello.build_hello`); the
            agents and modes a command may name come from it.
        on_command: Called on the server's thread with each checked command; it must
            not block (:class:`~clark_engine.station.live_view.StationViewLink.submit` queues
            it for the loop).
        host: The address to bind (127.0.0.1 by default).
        port: The port (0 picks a free one; :attr:`port` then says which).
        token: The token every request must carry; required when ``host`` is not
            loopback.
        static_dir: The page's folder (the package's by default).
        replay: Serve this finished run instead of snapshots (``clark replay``): each
            client moves through it at its own time, and commands are refused.
        limits: Timeouts and connection caps (:class:`ViewLimits`); caps left out are
            derived from the file limit when the server starts (:func:`view_limits`).

    Raises:
        UsageError: A non-loopback ``host`` without a token, or a token that is too
            short, too long or not printable ASCII.
    """

    def __init__(
        self,
        hello: Json,
        on_command: Callable[[CommandRequest], None],
        *,
        host: str = "127.0.0.1",
        port: int = DEFAULT_PORT,
        token: str | None = None,
        static_dir: Path = STATIC_DIR,
        replay: ReplaySource | None = None,
        limits: ViewLimits | None = None,
    ) -> None:
        loopback = is_loopback_host(host)
        if token is None and not loopback:
            raise UsageError(
                f"the view would be served on {host}, beyond this machine: give a token "
                "(--view-token-file FILE or --view-token TOKEN), or bind 127.0.0.1"
            )
        self.token = check_token(token) if token is not None else None
        self.hello = hello
        self.on_command = on_command
        self.host = host
        self.requested_port = port
        self.port = port
        self.loopback = loopback
        self.static_dir = static_dir
        self.replay = replay
        replay_info = hello.get("replay") or {}
        self._speeds = tuple(float(x) for x in replay_info.get("speeds", (1,)))
        self._replay_period_s = 1.0 / float(hello.get("update_hz") or 5.0)
        self._hello_text = json.dumps(hello, separators=(",", ":"))
        self._lock = threading.Lock()
        self._pending = _Pending()
        self._scheduled = False
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._stopping: asyncio.Event | None = None
        self._sock: socket.socket | None = None
        self._clients: set[_Client] = set()
        self._ids = itertools.count(1)
        # What clients are sent (touched on the server's loop only).
        self._state: Json | None = None
        self._version = 0
        self._track: deque[Json] = deque(maxlen=MAX_TRACK_POINTS)
        self._photos: deque[Json] = deque(maxlen=MAX_PHOTOS)
        self._log: deque[Json] = deque(maxlen=MAX_LOG_LINES)
        self.limits = limits or ViewLimits()
        """The view's timeouts and caps (the caps filled in by :meth:`start`)."""
        self._throttle = Throttle(_LOG, self.limits.log_interval_s)
        self.stats = {
            "connections": 0,
            "refused": 0,
            "commands": 0,
            "rejected": 0,
            "timed_out": 0,
            "shed": 0,
            "full": 0,
            "accept_errors": 0,
        }
        """Counts since the start: WebSocket connections, requests refused (403),
        commands handed on, messages rejected; TCP connections closed for sending no
        valid request in time (``timed_out``), closed to make room for a newer one
        (``shed``), refused because every place was taken by proven ones (``full``),
        and accept() failures for want of a file descriptor (``accept_errors``)."""
        self._caps = ConnectionCaps(self.limits, self.stats, self._throttle)

    # -- addresses -----------------------------------------------------------------------

    @property
    def open_connections(self) -> int:
        """TCP connections held now (read on the server's thread, or as an estimate)."""
        return len(self._caps.open)

    @property
    def cookie_name(self) -> str:
        """The token's cookie, one per port: a browser sends a host's cookies to all ports."""
        return f"clark_view_{self.port}"

    def _netloc(self, host: str) -> str:
        return f"[{host}]:{self.port}" if ":" in host else f"{host}:{self.port}"

    @property
    def url(self) -> str:
        """The page's address, with the token when there is one (print it for the operator)."""
        host = self.host
        if host in ("0.0.0.0", "::"):
            host = socket.gethostname()
        base = f"http://{self._netloc(host)}/"
        return base + (f"?token={quote(self.token, safe='')}" if self.token else "")

    def _allowed_hosts(self) -> set[str] | None:
        """Host headers accepted; None for any (a token guards a non-loopback bind)."""
        if not self.loopback:
            return None
        names = {self.host, "127.0.0.1", "localhost", "::1"}
        return {self._netloc(name).lower() for name in names}

    # -- life ----------------------------------------------------------------------------

    def start(self, timeout_s: float = 10.0) -> None:
        """Bind, start the server's thread and wait until it serves.

        Raises:
            UsageError: The address cannot be bound (in use, not this machine's).
        """
        try:
            infos = socket.getaddrinfo(
                self.host, self.requested_port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE
            )
            family, kind, proto, _, address = infos[0]
            sock = socket.socket(family, kind, proto)
        except OSError as exc:
            raise UsageError(f"--view: cannot use {self.host}: {exc.strerror or exc}") from None
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            sock.bind(address)
            sock.listen(LISTEN_BACKLOG)
            sock.setblocking(False)
        except OSError as exc:
            sock.close()
            raise UsageError(
                f"--view: cannot serve on {self._netloc(self.host)}: {exc.strerror or exc}"
            ) from None
        self._sock = sock
        self.port = int(sock.getsockname()[1])
        self.limits = view_limits(self.limits)
        self._caps.limits = self.limits
        self._thread = threading.Thread(target=self._main, name="clark-view", daemon=True)
        self._thread.start()
        if not self._ready.wait(timeout_s) or self._error is not None:
            self.stop()
            raise UsageError(f"--view: the server did not start: {self._error}")

    def stop(self, timeout_s: float = 5.0) -> None:
        """Send every client the last state, close them and the server; wait for the thread."""
        loop, stopping = self._loop, self._stopping
        if loop is not None and stopping is not None:
            with contextlib.suppress(RuntimeError):  # its loop already ended
                loop.call_soon_threadsafe(stopping.set)
        if self._thread is not None:
            self._thread.join(timeout_s)
            self._thread = None
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def _main(self) -> None:
        loop = asyncio.new_event_loop()
        loop.set_exception_handler(self._loop_error)
        self._loop = loop
        try:
            loop.run_until_complete(self._serve())
        except BaseException as exc:  # reported to start(); the station flies on without it
            self._error = exc
            self._ready.set()
            _LOG.error("station view server stopped: %s", exc)
        finally:
            with contextlib.suppress(Exception):
                loop.run_until_complete(loop.shutdown_asyncgens())
            loop.close()

    async def _serve(self) -> None:
        self._stopping = asyncio.Event()
        app = web.Application(middlewares=[self._guard], client_max_size=64 * 1024)
        app.router.add_get("/", self._page)
        app.router.add_get("/ws", self._websocket)
        app.router.add_static("/static/", self.static_dir, follow_symlinks=False)
        limits = self.limits
        runner = web.AppRunner(
            app,
            handle_signals=False,
            access_log=None,
            shutdown_timeout=STOP_FLUSH_S,
            keepalive_timeout=limits.idle_timeout_s,
            lingering_time=min(limits.header_timeout_s, 10.0),
            logger=ThrottledLogger(logging.getLogger("aiohttp.server"), self._throttle),
        )
        await runner.setup()
        assert self._sock is not None and runner.server is not None
        handlers = runner.server
        # Not a SockSite: each connection goes through Admitted, which applies the caps.
        listener = await asyncio.get_running_loop().create_server(
            lambda: Admitted(self._caps, handlers), sock=self._sock, backlog=LISTEN_BACKLOG
        )
        self._ready.set()
        try:
            await self._stopping.wait()
            self._take()
            await self._close_clients()
        finally:
            listener.close()
            await runner.cleanup()
            self._throttle.flush()

    # -- errors of the server's loop -----------------------------------------------------

    def _loop_error(self, loop: asyncio.AbstractEventLoop, context: dict[str, Any]) -> None:
        """The server loop's exception handler: no traceback floods.

        asyncio reports each failed accept() (no file descriptor left: the engine's or
        the view's) with a traceback, once a second while it lasts; here it is one line
        per :data:`LOG_INTERVAL_S` with the count, and the oldest unproven connections
        are closed to give the operator (and the engine) room. Anything else is logged
        in full the first time, then counted.
        """
        exc = context.get("exception")
        if isinstance(exc, OSError) and exc.errno in _NO_RESOURCE:
            self.stats["accept_errors"] += 1
            nofile = resource.getrlimit(resource.RLIMIT_NOFILE)[0]
            self._throttle.note(
                "accept",
                "station view: could not accept connections (%d failures): "
                f"{exc.strerror} "
                f"(file limit {nofile}, {len(self._caps.open)} view connections open); "
                "retrying every second",
            )
            for victim in list(self._caps.unproven)[:8]:
                self._caps.shed(victim)
            return
        if isinstance(exc, (OSError, ValueError)) and "_start_serving" in str(
            context.get("message", "")
        ):
            self._accept_rearm_failed(exc)
            return
        kind = f"loop:{context.get('message')}"
        first = kind not in self._throttle.total
        count = self._throttle.admit(kind)
        if count is None:
            return
        if first:
            loop.default_exception_handler(context)
        else:
            _LOG.error(
                "station view: %s: %s (%d like it in the last %g s)",
                context.get("message"),
                exc,
                count,
                self._throttle.interval_s,
            )

    def _accept_rearm_failed(self, exc: BaseException) -> None:
        """When asyncio's own retry of accept() fails: one line, never a traceback.

        After accept() runs out of file descriptors, asyncio (3.11) stops listening and
        schedules ``_start_serving`` a second later to listen again, once per failed
        accept of that tick. When the view stops within that second, the listening
        socket is closed before the retry runs, and the retry raises on its file
        descriptor (-1). That is the expected end of a flood, not an error: it is noted
        at debug level. While the view serves, a failed retry would mean it no longer
        accepts at all: that is said once a log interval.
        """
        serving = self._stopping is not None and not self._stopping.is_set()
        if not serving:
            _LOG.debug("station view: asyncio's accept retry ran after the view closed: %s", exc)
            return
        self._throttle.note(
            "rearm",
            "station view: could not listen again after running out of files "
            "(%d failures): " + str(exc).replace("%", "%%"),
        )

    async def _close_clients(self) -> None:
        clients = list(self._clients)
        for client in clients:
            client.wake.set()
        await asyncio.sleep(0)
        deadline = time.monotonic() + STOP_FLUSH_S
        while any(c.version < self._version for c in clients if not c.ws.closed):
            if time.monotonic() > deadline:
                break
            await asyncio.sleep(0.02)
        for client in clients:
            with contextlib.suppress(Exception):
                await asyncio.wait_for(
                    client.ws.close(code=1001, message=b"the station stopped"), STOP_FLUSH_S
                )

    # -- snapshots in (any thread) -------------------------------------------------------

    def publish(self, snapshot: Snapshot) -> None:
        """Hand the server the newest snapshot; never blocks (called from the station loop)."""
        with self._lock:
            pending = self._pending
            pending.state = snapshot.state
            pending.track.extend(snapshot.track)
            pending.photos.extend(snapshot.photos)
            pending.log.extend(snapshot.log)
            schedule = not self._scheduled
            self._scheduled = True
        loop = self._loop
        if schedule and loop is not None:
            try:
                loop.call_soon_threadsafe(self._take)
            except RuntimeError:  # the server's loop has ended: nobody to tell
                with self._lock:
                    self._scheduled = False

    def _take(self) -> None:
        """On the server's loop: move what was published to the clients' histories."""
        with self._lock:
            pending, self._pending = self._pending, _Pending()
            self._scheduled = False
        if pending.state is None:
            return
        self._state = pending.state
        self._track.extend(pending.track)
        self._photos.extend(pending.photos)
        self._log.extend(pending.log)
        self._version += 1
        for client in self._clients:
            client.wake.set()

    # -- HTTP ----------------------------------------------------------------------------

    def _supplied_token(self, request: web.Request) -> tuple[str | None, bool]:
        """The token the request carries, and whether it came in the query string."""
        query = request.query.get("token")
        if query is not None:
            return query, True
        header = request.headers.get(TOKEN_HEADER)
        if header is not None:
            return header, False
        authorization = request.headers.get("Authorization", "")
        if authorization.startswith("Bearer "):
            return authorization[len("Bearer ") :], False
        return request.cookies.get(self.cookie_name), False

    def _token_ok(self, supplied: str | None) -> bool:
        if self.token is None:
            return True
        if supplied is None or len(supplied) > MAX_TOKEN_CHARS:
            return False
        return hmac.compare_digest(supplied.encode(), self.token.encode())

    def _forbidden(self, why: str) -> web.Response:
        self.stats["refused"] += 1
        return web.Response(
            status=403,
            text=f"403 Forbidden: {why}\n",
            headers={"Cache-Control": "no-store", "X-Content-Type-Options": "nosniff"},
        )

    @web.middleware
    async def _guard(
        self,
        request: web.Request,
        handler: Handler,
    ) -> web.StreamResponse:
        allowed = self._allowed_hosts()
        if allowed is not None and request.host.lower() not in allowed:
            return self._forbidden("this view answers to its own address only")
        supplied, in_query = self._supplied_token(request)
        if not self._token_ok(supplied):
            return self._forbidden("a valid token is required (the URL clark run printed)")
        self._caps.prove(request.transport)
        upgrade = request.headers.get("Upgrade", "").lower() == "websocket"
        if self.token is not None and in_query and request.method == "GET" and not upgrade:
            # The token moves from the URL to a cookie, and the URL is shown without it.
            query = {k: v for k, v in request.query.items() if k != "token"}
            target = request.rel_url.with_query(query)
            moved = web.Response(
                status=303, headers={"Location": str(target), "Cache-Control": "no-store"}
            )
            moved.set_cookie(
                self.cookie_name, self.token, httponly=True, samesite="Strict", path="/"
            )
            return moved
        response = await handler(request)
        if not response.prepared:
            headers = response.headers
            headers.setdefault("X-Content-Type-Options", "nosniff")
            headers.setdefault("Referrer-Policy", "no-referrer")
            headers.setdefault("X-Frame-Options", "DENY")
            headers.setdefault("Cache-Control", "no-store")
        return response

    async def _page(self, request: web.Request) -> web.StreamResponse:
        host = request.host
        csp = (
            "default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self' data:; "
            f"connect-src 'self' ws://{host} wss://{host}; base-uri 'none'; "
            "form-action 'none'; frame-ancestors 'none'"
        )
        return web.FileResponse(
            self.static_dir / "index.html", headers={"Content-Security-Policy": csp}
        )

    # -- the WebSocket -------------------------------------------------------------------

    def _origin_ok(self, request: web.Request) -> bool:
        origin = request.headers.get("Origin")
        if origin is None:
            return True  # not a browser: the token (when set) is its guard
        return origin.lower() in (
            f"http://{request.host}".lower(),
            f"https://{request.host}".lower(),
        )

    async def _websocket(self, request: web.Request) -> web.StreamResponse:
        if not self._origin_ok(request):
            return self._forbidden("the WebSocket must be opened by this view's own page")
        ws = web.WebSocketResponse(heartbeat=20.0, max_msg_size=MAX_MESSAGE_BYTES, compress=False)
        await ws.prepare(request)
        if len(self._clients) >= MAX_CLIENTS:
            await ws.close(code=1013, message=b"too many clients")
            return ws
        client = _Client(ws, request.remote or "")
        self._clients.add(client)
        self.stats["connections"] += 1
        sender = asyncio.create_task(self._send(client))
        try:
            async for message in ws:
                if message.type == WSMsgType.TEXT:
                    self._received(client, message.data)
                elif message.type == WSMsgType.BINARY:
                    self._reply(client, {"type": "error", "ref": None, "error": "text only"})
                else:
                    break
        finally:
            self._clients.discard(client)
            sender.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await sender
        return ws

    def _reply(self, client: _Client, message: Json) -> None:
        client.replies.append(json.dumps(message, separators=(",", ":")))
        client.wake.set()

    def _received(self, client: _Client, text: str) -> None:
        """One message from a page: a checked command handed on, or an error sent back."""
        if self.replay is not None:
            self._replay_control(client, self.replay, text)
            return
        if not client.allow_command():
            self.stats["rejected"] += 1
            self._reply(client, {"type": "error", "ref": None, "error": "too many commands"})
            return
        try:
            request, ref = parse_command(
                text, self.hello, command_id=next(self._ids), address=client.address
            )
        except CommandRejected as exc:
            self.stats["rejected"] += 1
            self._reply(client, {"type": "error", "ref": exc.ref, "error": str(exc)})
            return
        self.stats["commands"] += 1
        try:
            self.on_command(request)
        except Exception as exc:  # the station could not take it (it has stopped)
            self._reply(client, {"type": "error", "ref": ref, "error": f"not sent: {exc}"})
            return
        self._reply(client, {"type": "accepted", "ref": ref, "id": request.id})

    def _replay_control(self, client: _Client, source: ReplaySource, text: str) -> None:
        """A replay page's seek, play, pause or speed, applied to its own time."""
        if not client.controls.allow():
            self.stats["rejected"] += 1
            self._reply(client, {"type": "error", "ref": None, "error": "too many messages"})
            return
        try:
            action, value, _ref = parse_replay_control(text, self._speeds)
        except CommandRejected as exc:
            self.stats["rejected"] += 1
            self._reply(client, {"type": "error", "ref": exc.ref, "error": str(exc)})
            return
        if action == "seek" and value is not None:
            client.replay_t = source.clamp(value)
        elif action == "play":
            if client.replay_t >= source.end_s:
                client.replay_t = source.start_s  # at the end: play from the start
            client.playing = True
        elif action == "pause":
            client.playing = False
        elif action == "speed" and value is not None:
            client.speed = value
        client.moved = True
        client.wake.set()

    async def _send_replay(self, client: _Client, source: ReplaySource) -> None:
        """A replay client's sender: hello, then its time's state whenever it moves.

        While the page plays, its time advances by its speed times the wall-clock time
        elapsed, and a state goes out at the update rate; at the end of the run it stops.
        """
        ws = client.ws
        client.replay_t = source.start_s
        await ws.send_str(self._hello_text)
        last_s = time.monotonic()
        while not ws.closed:
            if not client.moved and not client.replies:
                timeout = self._replay_period_s if client.playing else None
                with contextlib.suppress(TimeoutError):
                    await asyncio.wait_for(client.wake.wait(), timeout)
            client.wake.clear()
            while client.replies and not ws.closed:
                await ws.send_str(client.replies.popleft())
            now_s = time.monotonic()
            if client.playing:
                client.replay_t = min(
                    source.end_s, client.replay_t + client.speed * (now_s - last_s)
                )
                if client.replay_t >= source.end_s:
                    client.playing = False
                client.moved = True
            last_s = now_s
            if not client.moved or ws.closed:
                continue
            client.moved = False
            for message in source.frame(client.replay_t, client.sent_t):
                if message.get("type") == "state":
                    message["replay"] = {
                        **message.get("replay", {}),
                        "playing": client.playing,
                        "speed": client.speed,
                    }
                await ws.send_str(page_json(message))
            client.sent_t = client.replay_t

    async def _send(self, client: _Client) -> None:
        """The client's one sender: hello, then replies and the newest state as they come."""
        ws = client.ws
        if self.replay is not None:
            # ConnectionError, RuntimeError: the client went away; its handler cleans up.
            with contextlib.suppress(ConnectionError, RuntimeError):
                await self._send_replay(client, self.replay)
            return
        try:
            await ws.send_str(self._hello_text)
            client.wake.set()
            while not ws.closed:
                await client.wake.wait()
                client.wake.clear()
                while client.replies and not ws.closed:
                    await ws.send_str(client.replies.popleft())
                if self._state is not None and client.version < self._version and not ws.closed:
                    client.version = self._version
                    await ws.send_str(self._state_for(client))
        except (ConnectionError, RuntimeError):
            return  # the client went away; its handler cleans up

    def _state_for(self, client: _Client) -> str:
        """The newest state with the track points, photos and log lines the client lacks."""
        assert self._state is not None
        message = dict(self._state)
        message["track"] = _after(self._track, client.track_seq)
        message["photos"] = _after(self._photos, client.photo_seq)
        message["log"] = _after(self._log, client.log_seq)
        if self._track:
            client.track_seq = int(self._track[-1]["seq"])
        if self._photos:
            client.photo_seq = int(self._photos[-1]["seq"])
        if self._log:
            client.log_seq = int(self._log[-1]["seq"])
        return page_json(message)


def _after(items: deque[Json], seq: int) -> list[Json]:
    """The items with a sequence number above ``seq`` (they are in order), oldest first."""
    out: list[Json] = []
    for item in reversed(items):
        if int(item["seq"]) <= seq:
            break
        out.append(item)
    out.reverse()
    return out


__all__ = [
    "DEFAULT_PORT",
    "STATIC_DIR",
    "ReplaySource",
    "ViewServer",
]
