"""The station's page under a connection flood: does its operator still get it, how fast?

Issue 18, item 2. Three processes on loopback:

- **The view**: a :class:`~clark_engine.station.server.ViewServer` (cooperative_follow's
  station's ``hello``, a token, 127.0.0.1) in a child process whose soft file limit is
  set to ``--nofile`` (1024, a common default), publishing a small state at 5 Hz as a
  station's loop does. Its stderr goes to a file, to count what a flood writes there.
  ``--tree DIR`` runs the view from another checkout (``/work/main`` for the code
  before the limits), to compare.
- **The attacker**: this file with ``--attack``, another process: it keeps
  ``--hostile`` TCP connections open to the view from ``--addresses`` source
  addresses (127.0.1.1, 127.0.1.2, ...; Linux routes all of 127/8 to loopback), and
  opens a new one as soon as the view closes one, as fast as it can: it holds the
  maximum the view allows, and more wait in the backlog. ``idle`` connections send
  nothing; ``slowloris`` ones send a request header one byte per connection a second,
  never finishing it.
- **The operator** (this process): from 127.0.0.2, with the token, loads the page as a
  browser does (``/?token=`` answered with a cookie and a redirect, then ``/`` and its
  four static files over up to six connections), then opens the WebSocket and waits for
  its first frame (``hello``) and its first ``state``. ``--rounds`` times, one after
  another; a round that takes longer than ``--timeout-s`` (10) fails.

Printed per phase (no attack, idle flood, slowloris flood): the page load and the
WebSocket's first frame and first state (median, 95th percentile, worst), the failed
rounds, the hostile connections the attacker held open (sampled), how many it opened,
the view's counts (closed at the header timeout, shed to make room, refused, accept
failures) and the bytes its process wrote to stderr.

Run: ``python benchmarks/bench_station_flood.py`` (about 2 minutes);
``--tree /work/main`` for the code before the limits.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import os
import resource
import select
import socket
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
TOKEN = "bench-token-0123456789abcdef"
OPERATOR = "127.0.0.2"

VIEW = textwrap.dedent(
    """
    import json, logging, resource, sys, threading, time
    from pathlib import Path
    nofile = int(sys.argv[1])
    hard = resource.getrlimit(resource.RLIMIT_NOFILE)[1]
    resource.setrlimit(resource.RLIMIT_NOFILE, (nofile, hard))
    logging.basicConfig(stream=sys.stderr, level=logging.INFO)
    from clark_engine.station.view_hello import build_hello
    from clark_engine.station.view_model import Snapshot
    from clark_engine.station.server import ViewServer
    from clark_engine.mission.compiler import agent_config
    from clark_engine.runtime.config import config_from_dict
    from clark_engine.validation import validate_file
    mission = validate_file(Path(sys.argv[2])).mission
    hello = build_hello(config_from_dict(agent_config(mission, mission.agents["mcs"])))
    server = ViewServer(hello, lambda r: None, port=0, token=sys.argv[3])
    server.start()
    limits = getattr(server, "limits", None)
    print(json.dumps({"port": server.port, "limits": str(limits)}), flush=True)
    stop = threading.Event()
    def publish():
        k = 0
        while not stop.wait(0.2):
            k += 1
            server.publish(Snapshot({"type": "state", "t": k * 0.2}, [], [], []))
    threading.Thread(target=publish, daemon=True).start()
    for line in sys.stdin:
        if line.strip() == "stats":
            stats = dict(server.stats)
            stats["open"] = getattr(server, "open_connections", None)
            print(json.dumps(stats), flush=True)
    stop.set()
    server.stop()
    """
)


# -- the attacker ------------------------------------------------------------------------


def attack(port: int, hostile: int, addresses: int, mode: str) -> None:
    """Hold ``hostile`` connections to ``port`` until stdin closes; report each second."""
    hard = resource.getrlimit(resource.RLIMIT_NOFILE)[1]
    resource.setrlimit(resource.RLIMIT_NOFILE, (hard, hard))
    sources = [f"127.0.1.{1 + k}" for k in range(addresses)]
    poller = select.epoll()
    open_socks: dict[int, tuple[socket.socket, int]] = {}
    opened = closed = failed = 0
    header = b"GET / HTTP/1.1\r\nHost: 127.0.0.1\r\n" + b"X-a: b\r\n" * 10_000
    slot = 0
    started = last_report = last_trickle = time.monotonic()
    os.set_blocking(sys.stdin.fileno(), False)
    while True:
        with contextlib.suppress(BlockingIOError):
            if sys.stdin.buffer.read() == b"":
                break
        while len(open_socks) < hostile:
            sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            sock.setsockopt(
                socket.SOL_SOCKET, socket.SO_LINGER, b"\x01\x00\x00\x00\x00\x00\x00\x00"
            )
            sock.bind((sources[slot % addresses], 0))
            slot += 1
            sock.settimeout(0.5)
            try:
                sock.connect(("127.0.0.1", port))
            except OSError:
                sock.close()
                failed += 1
                break  # the backlog is full: the view is not accepting
            sock.setblocking(False)
            open_socks[sock.fileno()] = (sock, 0)
            poller.register(sock.fileno(), select.EPOLLIN | select.EPOLLRDHUP)
            opened += 1
        for fd, _event in poller.poll(0.05):
            sock, _sent = open_socks[fd]
            try:
                data = sock.recv(65536)
            except BlockingIOError:
                continue
            except OSError:
                data = b""
            if not data:
                poller.unregister(fd)
                del open_socks[fd]
                sock.close()
                closed += 1
        now = time.monotonic()
        if mode == "slowloris" and now - last_trickle >= 1.0:
            last_trickle = now
            for fd, (sock, sent) in list(open_socks.items()):
                with contextlib.suppress(OSError):
                    sock.send(header[sent : sent + 1])
                    open_socks[fd] = (sock, sent + 1)
        if now - last_report >= 1.0:
            last_report = now
            report = {"open": len(open_socks), "opened": opened, "closed": closed}
            report["failed"] = failed
            report["elapsed_ms"] = round(1000 * (now - started))
            print(json.dumps(report), flush=True)
    for sock, _sent in open_socks.values():
        sock.close()


# -- the operator ------------------------------------------------------------------------


async def operator_round(port: int, timeout_s: float) -> tuple[float, float, float]:
    """One page load, then the WebSocket's first frame and first state: seconds each."""
    import aiohttp

    base = f"http://127.0.0.1:{port}"
    connector = aiohttp.TCPConnector(local_addr=(OPERATOR, 0), limit=6)
    timeout = aiohttp.ClientTimeout(total=timeout_s)
    jar = aiohttp.CookieJar(unsafe=True)  # keep the view's cookie for an IP address
    async with aiohttp.ClientSession(
        connector=connector, timeout=timeout, cookie_jar=jar
    ) as session:
        start = time.perf_counter()
        async with session.get(f"{base}/?token={TOKEN}") as page:  # 303, cookie, then /
            assert page.status == 200, page.status
            await page.read()
        files = [
            "static/vendor/leaflet/leaflet.css",
            "static/style.css",
            "static/vendor/leaflet/leaflet.js",
            "static/app.js",
        ]

        async def fetch(path: str) -> None:
            async with session.get(f"{base}/{path}") as response:
                assert response.status == 200, (path, response.status)
                await response.read()

        await asyncio.gather(*(fetch(path) for path in files))
        page_s = time.perf_counter() - start
        start = time.perf_counter()
        async with session.ws_connect(f"{base}/ws") as ws:
            first = await ws.receive(timeout=timeout_s)
            assert json.loads(first.data)["type"] == "hello"
            hello_s = time.perf_counter() - start
            while json.loads((await ws.receive(timeout=timeout_s)).data)["type"] != "state":
                pass
            state_s = time.perf_counter() - start
    return page_s, hello_s, state_s


def figures(values: list[float]) -> str:
    if not values:
        return "-"
    ordered = sorted(values)
    p95 = ordered[min(len(ordered) - 1, round(0.95 * (len(ordered) - 1)))]
    return (
        f"median {1000 * statistics.median(ordered):.1f} ms, p95 {1000 * p95:.1f} ms, "
        f"worst {1000 * ordered[-1]:.1f} ms"
    )


def phase(
    name: str,
    view: subprocess.Popen[str],
    port: int,
    args: argparse.Namespace,
    mode: str | None,
    stderr_path: Path,
) -> None:
    """Run the operator's rounds with (or without) an attacker; print the figures."""
    attacker: subprocess.Popen[str] | None = None
    samples: list[dict[str, int]] = []
    if mode is not None:
        attacker = subprocess.Popen(
            [
                *(sys.executable, __file__, "--attack", str(port)),
                *("--hostile", str(args.hostile), "--addresses", str(args.addresses)),
                *("--mode", mode),
            ],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )
        assert attacker.stdout is not None
        for _ in range(int(args.settle_s)):  # let it fill the view
            samples.append(json.loads(attacker.stdout.readline()))
    before = stderr_path.stat().st_size
    pages: list[float] = []
    hellos: list[float] = []
    states: list[float] = []
    failures: list[str] = []
    for _ in range(args.rounds):
        try:
            page_s, hello_s, state_s = asyncio.run(operator_round(port, args.timeout_s))
        except Exception as exc:
            failures.append(type(exc).__name__)
        else:
            pages.append(page_s)
            hellos.append(hello_s)
            states.append(state_s)
        if attacker is not None and attacker.stdout is not None:
            readable, _, _ = select.select([attacker.stdout], [], [], 0)
            if readable:
                samples.append(json.loads(attacker.stdout.readline()))
    assert view.stdin is not None and view.stdout is not None
    view.stdin.write("stats\n")
    view.stdin.flush()
    stats = json.loads(view.stdout.readline())
    if attacker is not None:
        assert attacker.stdin is not None and attacker.stdout is not None
        attacker.stdin.close()
        attacker.wait(30)
        attacker.stdout.close()
    grown = stderr_path.stat().st_size - before
    print(f"\n{name}:")
    print(f"  page load (/, 4 files): {figures(pages)}")
    print(f"  WebSocket first frame:  {figures(hellos)}")
    print(f"  WebSocket first state:  {figures(states)}")
    print(f"  rounds failed: {len(failures)} of {args.rounds} {sorted(set(failures))}")
    if samples:
        held = [s["open"] for s in samples]
        last = samples[-1]
        print(
            f"  attacker: held {min(held)}-{max(held)} connections open "
            f"(median {statistics.median(held):.0f}), opened {last['opened']}, "
            f"closed by the view {last['closed']}, connects that failed {last['failed']}; "
            f"{1000 * last['opened'] / max(1, last['elapsed_ms']):.0f} opened a second"
        )
    print(f"  view: {stats}")
    print(f"  view's stderr during the operator's rounds: {grown} bytes")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--attack", type=int, help=argparse.SUPPRESS)
    parser.add_argument("--mode", default="idle", help=argparse.SUPPRESS)
    parser.add_argument("--nofile", type=int, default=1024)
    parser.add_argument("--hostile", type=int, default=2000, help="connections to hold")
    parser.add_argument("--addresses", type=int, default=64, help="attacker's addresses")
    parser.add_argument("--rounds", type=int, default=30)
    parser.add_argument("--timeout-s", type=float, default=10.0)
    parser.add_argument("--settle-s", type=float, default=5.0)
    parser.add_argument("--phases", default="none,idle,slowloris")
    parser.add_argument("--tree", type=Path, default=ROOT, help="the checkout to serve from")
    args = parser.parse_args()
    if args.attack is not None:
        attack(args.attack, args.hostile, args.addresses, args.mode)
        return 0
    env = {**os.environ, "PYTHONPATH": str(args.tree)}
    with tempfile.TemporaryDirectory() as folder:
        stderr_path = Path(folder) / "view.stderr"
        with stderr_path.open("w") as stderr:
            view = subprocess.Popen(
                [
                    *(sys.executable, "-c", VIEW, str(args.nofile)),
                    *(str(ROOT / "missions" / "cooperative_follow.yaml"), TOKEN),
                ],
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=stderr,
                text=True,
                env=env,
                cwd=args.tree,  # `python -c` puts the working folder first on the path
            )
        assert view.stdin is not None and view.stdout is not None
        started = json.loads(view.stdout.readline())
        print(f"view from {args.tree}: file limit {args.nofile}, {started['limits']}")
        print(
            f"attacker: {args.hostile} connections from {args.addresses} addresses; "
            f"operator: {args.rounds} rounds from {OPERATOR}"
        )
        try:
            for name in args.phases.split(","):
                mode = None if name == "none" else name
                title = "no attack" if mode is None else f"{mode} flood"
                phase(title, view, int(started["port"]), args, mode, stderr_path)
        finally:
            view.stdin.close()
            view.wait(30)
            view.stdout.close()
        text = stderr_path.read_text(errors="replace")
        print(
            f"\nview's stderr in all: {len(text)} bytes, {text.count(chr(10))} lines, "
            f"{text.count('Traceback')} tracebacks"
        )
        for line in text.splitlines()[:12]:
            print(f"  {line[:200]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
