"""simrun serve is safe from web pages: other origins, DNS rebinding and simple (preflight-free) requests are refused.

Every state-changing route is taken from the server's own ``/openapi.json`` (so a new route is attacked too)
and sent the ways a page can send it without asking: empty bodies, ``text/plain``, forms, beacons; then the
stream and the Foxglove port are opened. The attacks come from plain HTTP here and from pages in headless
Chromium (Playwright driving Debian's /usr/bin/chromium): one served on another origin, one whose name is
rebound to the server. Ground truth that nothing changed: the world's time, steps, rate, pause, poses and
recording through a legitimate client, and the ``.simlog`` written at shutdown, whose commands are the
legitimate one only.
"""

from __future__ import annotations

import asyncio
import base64
import contextlib
import http.client
import json
import os
import shutil
import socket
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any
from urllib.parse import quote

import pytest
from serve_helpers import SCENES, Server, serve

from simrun.client import Client

BOEBOT = SCENES / "boebot.toml"
DRIVE = "/api/services/DriveService/boebot"
#: A token with spaces, URL and shell specials and letters beyond latin-1.
TOKEN = 'p+a&s=s%w#o?r/d; "quoted" é€ ключ 密钥'


def _port(url: str) -> int:
    return int(url.rstrip("/").rsplit(":", 1)[1])


def _send(port: int, method: str, path: str, headers: dict[str, str], body: bytes = b"") -> tuple[int, Any]:
    """One raw HTTP/1.1 request to 127.0.0.1:port with exactly these headers (values sent as UTF-8)."""
    lines = [f"{method} {path} HTTP/1.1", *(f"{k}: {v}" for k, v in headers.items())]
    if body or method == "POST":
        lines.append(f"Content-Length: {len(body)}")
    lines.append("Connection: close")
    with socket.create_connection(("127.0.0.1", port), timeout=30) as sock:
        sock.sendall(("\r\n".join(lines) + "\r\n\r\n").encode("utf-8") + body)
        chunks = []
        while chunk := sock.recv(65536):
            chunks.append(chunk)
    head, _, payload = b"".join(chunks).partition(b"\r\n\r\n")
    status = int(head.split(b" ", 2)[1])
    try:
        return status, json.loads(payload)
    except ValueError:
        return status, payload


def _handshake(port: int, path: str = "/", headers: dict[str, str] | None = None) -> int:
    """The status of a WebSocket handshake to 127.0.0.1:port (101: accepted)."""
    sent = {
        "Host": f"127.0.0.1:{port}",
        "Upgrade": "websocket",
        "Connection": "Upgrade",
        "Sec-WebSocket-Key": base64.b64encode(os.urandom(16)).decode(),
        "Sec-WebSocket-Version": "13",
        "Sec-WebSocket-Protocol": "foxglove.sdk.v1",
    }
    sent.update(headers or {})
    request = f"GET {path} HTTP/1.1\r\n" + "".join(f"{k}: {v}\r\n" for k, v in sent.items()) + "\r\n"
    with socket.create_connection(("127.0.0.1", port), timeout=30) as sock:
        sock.sendall(request.encode("utf-8"))
        head = b""
        while b"\r\n" not in head:
            chunk = sock.recv(4096)
            if not chunk:
                break
            head += chunk
    return int(head.split(b" ", 2)[1])


def _snapshot(server: Server) -> dict[str, Any]:
    """What an attack could change, read by a legitimate client."""
    state = server.get("/api/state")
    keep = {k: state[k] for k in ("time", "steps", "paused", "rate", "recording", "poses", "mode")}
    keep["drive"] = server.get(DRIVE)["state"]
    return keep


def _state_changing(server: Server) -> list[str]:
    paths = [p for p, ops in server.get("/openapi.json")["paths"].items() if "post" in ops]
    assert {"/api/pause", "/api/step", "/api/reset", "/api/recording/stop", f"{DRIVE}/all_stop"} <= set(paths)
    return paths


@contextlib.contextmanager
def _attacked_server(tmp_path: Path, *args: str) -> Iterator[tuple[Server, int]]:
    """A lockstep, recording server with a Foxglove port, one legitimate command applied: (server, Foxglove port)."""
    record = tmp_path / "run.simlog"
    with serve(BOEBOT, "--lockstep", "--record", str(record), "--foxglove-port", "0", *args) as server:
        line = server.process.stdout.readline()
        assert line.startswith("foxglove ws://127.0.0.1:")
        assert server.post(f"{DRIVE}/cmd_vel", {"args": [0.1, 0.2]})["applied"]
        server.post("/api/step", {"steps": 25})
        yield server, _port(line.split()[1])
    assert record.is_file()


def _only_the_legitimate_command_was_recorded(tmp_path: Path) -> None:
    from simrun.record.simlog import Simlog

    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.simlog"]  # no other recording was started
    log = Simlog(tmp_path / "run.simlog")
    try:
        assert [(c.call, c.args) for c in log.commands()] == [("cmd_vel", (0.1, 0.2))]
    finally:
        log.close()


# -- plain HTTP: every state-changing call, the ways a page can send it ----------------------------------------


def test_foreign_origins_rebound_hosts_and_simple_requests_change_nothing(tmp_path):
    with _attacked_server(tmp_path) as (server, fox):
        port = _port(server.url)
        before = _snapshot(server)
        own = {"Host": f"127.0.0.1:{port}"}
        rebound = {"Host": f"rebind.example:{port}", "Origin": f"http://rebind.example:{port}"}
        json_type = {"Content-Type": "application/json"}
        attacks = [
            ("rebound-host", {**rebound, **json_type}, b"{}", 403, "host"),
            ("rebound-host-empty", rebound, b"", 403, "host"),
            ("other-origin", {**own, "Origin": "http://evil.example", **json_type}, b"{}", 403, "origin"),
            ("other-port", {**own, "Origin": "http://127.0.0.1:1", **json_type}, b"{}", 403, "origin"),
            ("null-origin", {**own, "Origin": "null", **json_type}, b"{}", 403, "origin"),
            ("other-origin-empty", {**own, "Origin": "http://evil.example"}, b"", 403, "origin"),
            ("empty-no-type", own, b"", 415, "content-type"),
            ("empty-text", {**own, "Content-Type": "text/plain"}, b"", 415, "content-type"),
            ("text-json", {**own, "Content-Type": "text/plain"}, b"{}", 415, "content-type"),
            ("form", {**own, "Content-Type": "application/x-www-form-urlencoded"}, b"args=1", 415, "content-type"),
            ("multipart", {**own, "Content-Type": "multipart/form-data; boundary=x"}, b"--x--", 415, "content-type"),
        ]
        problems = []
        paths = _state_changing(server)
        for path in paths:
            for name, headers, body, status, field in attacks:
                got, answer = _send(port, "POST", path, headers, body)
                if got != status or not isinstance(answer, dict) or answer["field"] != field:
                    problems.append(f"{name} {path}: {got} {answer}")
        for name, headers in [
            ("other-origin", {"Origin": "http://evil.example"}),
            ("rebound-host", {"Host": f"rebind.example:{port}"}),
        ]:
            if (got := _handshake(port, "/api/stream", headers)) != 403:
                problems.append(f"stream {name}: {got}")
            if (got := _handshake(fox, "/", {**headers, "Host": headers.get("Host", f"127.0.0.1:{fox}")})) != 403:
                problems.append(f"foxglove {name}: {got}")
        assert not problems, "\n".join(problems)
        assert len(paths) >= 18  # 7 world routes and the 11 DriveService commands
        assert _snapshot(server) == before
        assert _handshake(port, "/api/stream") == 101 and _handshake(fox) == 101  # clients without Origin
        assert server.post("/api/step", {"steps": 1})["steps"] == before["steps"] + 1
    _only_the_legitimate_command_was_recorded(tmp_path)
    assert "Traceback" not in server.output[1]


def test_the_own_origin_and_allowed_origins_are_answered(tmp_path):
    allowed = "http://tools.example:3000"
    with _attacked_server(tmp_path, "--allow-origin", allowed, "--allow-origin", "HTTPS://App.Example/") as (
        server,
        fox,
    ):
        port = _port(server.url)
        json_type = {"Content-Type": "application/json"}
        for origin in (f"http://127.0.0.1:{port}", allowed, "https://app.example"):
            got, answer = _send(
                port, "POST", "/api/pause", {"Host": f"127.0.0.1:{port}", "Origin": origin, **json_type}
            )
            assert got == 200 and answer["paused"], (origin, answer)
        got, _ = _send(port, "GET", "/api/state", {"Host": f"localhost:{port}", "Origin": f"http://localhost:{port}"})
        assert got == 200
        assert _handshake(port, "/api/stream", {"Origin": allowed}) == 101
        assert _handshake(fox, "/", {"Origin": allowed}) == 101
        assert _handshake(fox, "/", {"Origin": f"http://127.0.0.1:{fox}", "Host": f"localhost:{fox}"}) == 403
        assert _handshake(fox, "/", {"Origin": "http://tools.example:3001"}) == 403


# -- the token ------------------------------------------------------------------------------------------------


def test_any_printable_token_works_on_every_port_and_is_required_there(tmp_path):
    from websockets.sync.client import connect

    with serve(BOEBOT, "--lockstep", "--token", TOKEN, "--foxglove-port", "0") as server:
        fox = _port(server.process.stdout.readline().split()[1])
        port = _port(server.url)
        host = {"Host": f"127.0.0.1:{port}"}
        assert _send(port, "GET", "/api/state", host)[0] == 401
        assert _send(port, "GET", "/api/state", {**host, "Authorization": "Bearer " + TOKEN[:-1]})[0] == 401
        assert _send(port, "GET", "/api/state", {**host, "Authorization": "Bearer " + TOKEN})[0] == 200  # UTF-8
        assert _send(port, "GET", "/api/state", {**host, "Authorization": "Bearer " + quote(TOKEN, safe="")})[0] == 200
        assert _send(port, "GET", "/api/state?token=" + quote(TOKEN, safe=""), host)[0] == 200
        assert _send(port, "GET", "/api/state?token=" + quote(TOKEN[1:], safe=""), host)[0] == 401
        latin = http.client.HTTPConnection("127.0.0.1", port, timeout=30)  # what curl or requests send: latin-1
        with pytest.raises(UnicodeEncodeError):
            latin.request("GET", "/api/state", headers={"Authorization": "Bearer " + TOKEN})
        latin.close()
        sim = Client(server.url, token=TOKEN)
        assert sim.step(steps=3)["steps"] == 3
        hello = next(sim.stream())
        assert hello["type"] == "hello"
        assert _handshake(port, "/api/stream") == 401
        assert _handshake(fox) == 401 and _handshake(fox, "/?token=" + quote(TOKEN[:5], safe="")) == 401
        url = f"ws://127.0.0.1:{fox}/?token={quote(TOKEN, safe='')}"
        with connect(url, subprotocols=["foxglove.sdk.v1"], open_timeout=10) as ws:
            assert json.loads(ws.recv(timeout=10))["op"] == "serverInfo"


def test_tokens_and_origins_that_cannot_work_are_refused_before_listening():
    import subprocess

    from serve_helpers import SIMRUN

    from simrun.errors import UsageError
    from simrun.serve.server import check_access

    for token in ("x" * 16 + "\n", " " + "x" * 16, "x" * 16 + " ", "x" * 16 + "\x00"):
        with pytest.raises(UsageError, match="--token"):
            check_access("127.0.0.1", token)
    check_access("0.0.0.0", TOKEN, ("https://app.foxglove.dev", "http://[::1]:3000"))
    for origin in ("*", "null", "app.example", "http://app.example/path", "http://user@app.example", "http://a:99999"):
        with pytest.raises(UsageError, match="--allow-origin"):
            check_access("127.0.0.1", None, (origin,))
    done = subprocess.run([SIMRUN, "serve", str(BOEBOT), "--port", "0", "--allow-origin", "*"],
                          capture_output=True, text=True, timeout=60)  # fmt: skip
    assert done.returncode == 2 and "error: --allow-origin '*'" in done.stderr and "serving" not in done.stdout


def test_host_rules_by_bind_address():
    from simrun.serve.access import Access, normalise_origin, split_host

    loop = Access.bound("127.0.0.1", 8765)
    assert all(loop.host_ok(h) for h in ("127.0.0.1:8765", "localhost:8765", "[::1]:8765", "LOCALHOST:8765"))
    assert not any(
        loop.host_ok(h)
        for h in ("127.0.0.1:8766", "127.0.0.1", "rebind.example:8765", "[::1:8765", "127.0.0.1:8765, x", "", "a b:1")
    )
    wild = Access.bound("0.0.0.0", 80, token="x" * 16)
    assert wild.host_ok("192.168.1.20") and wild.host_ok("[fe80::1]:80") and not wild.host_ok("rebind.example")
    named = Access.bound("192.168.1.20", 9000, token="x" * 16)
    assert named.host_ok("192.168.1.20:9000") and not named.host_ok("10.0.0.1:9000")
    assert split_host("[::1]:80") == ("::1", 80) and split_host("Example.COM") == ("example.com", None)
    assert normalise_origin("HTTPS://App.Example:443/") == "https://app.example"
    assert normalise_origin("http://[::1]:3000") == "http://[::1]:3000"


# -- pages in headless Chromium -------------------------------------------------------------------------------

ARGS = ["--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--hide-scrollbars", "--mute-audio",
        "--host-resolver-rules=MAP rebind.test 127.0.0.2"]  # fmt: skip

#: The attacking page: every way a page sends a request without asking first, then the WebSockets.
ATTACK = """<!doctype html><html><body><script>
window.attack = async (base, routes, sockets) => {
  const out = [];
  for (const route of routes) {
    const url = base + route;
    const ways = [
      ["empty", {method: "POST", mode: "no-cors"}],
      ["text", {method: "POST", mode: "no-cors", body: "{}", headers: {"Content-Type": "text/plain"}}],
      ["form", {method: "POST", mode: "no-cors", body: new URLSearchParams({args: "[]"})}],
      ["json", {method: "POST", body: "{}", headers: {"Content-Type": "application/json"}}],
      ["json-empty", {method: "POST", headers: {"Content-Type": "application/json"}}],
    ];
    for (const [name, init] of ways) {
      try {
        const answer = await fetch(url, init);
        out.push([name, route, answer.type === "opaque" ? "opaque" : answer.status]);
      } catch (error) {
        out.push([name, route, "failed"]);
      }
    }
    out.push(["beacon", route, navigator.sendBeacon(url) ? "queued" : "not queued"]);
    await new Promise((resolve) => {
      const frame = document.createElement("iframe");
      frame.name = "f" + out.length;
      frame.onload = resolve;
      document.body.appendChild(frame);
      const form = document.createElement("form");
      Object.assign(form, {method: "POST", action: url, enctype: "text/plain", target: frame.name});
      form.innerHTML = '<input name="{}" value="">';
      document.body.appendChild(form);
      form.submit();
    });
    out.push(["html-form", route, "sent"]);
  }
  for (const url of sockets) {
    out.push(["websocket", url, await new Promise((resolve) => {
      const ws = new WebSocket(url, url.includes("/api/") ? [] : ["foxglove.websocket.v1", "foxglove.sdk.v1"]);
      ws.onopen = () => { ws.close(); resolve("open"); };
      ws.onerror = () => resolve("error");
    })]);
  }
  return out;
};
</script></body></html>"""


class Pages:
    """HTTP servers for the attacking pages: one on 127.0.0.1 (another origin: its own port), and a rebinding one.

    The rebinding one listens on 127.0.0.2 at the simrun server's ports (Chromium resolves ``rebind.test`` there):
    it answers ``GET /attack.html`` itself and relays everything else to 127.0.0.1 at the same port, as a
    name rebound from the attacker's address to the server's would.
    """

    def __init__(self, relayed: list[int]) -> None:
        self.loop = asyncio.new_event_loop()
        self.servers: list[asyncio.Server] = []
        self.ready = threading.Event()
        self.relayed = relayed
        self.thread = threading.Thread(target=self._main, daemon=True)
        self.thread.start()
        assert self.ready.wait(10)

    def _main(self) -> None:
        asyncio.set_event_loop(self.loop)
        other = self.loop.run_until_complete(asyncio.start_server(self._page, "127.0.0.1", 0))
        self.other_origin = f"http://127.0.0.1:{other.sockets[0].getsockname()[1]}"
        self.servers.append(other)
        for port in self.relayed:
            handler = lambda r, w, port=port: self._relay(r, w, port)  # noqa: E731
            self.servers.append(self.loop.run_until_complete(asyncio.start_server(handler, "127.0.0.2", port)))
        self.ready.set()
        self.loop.run_forever()

    async def _page(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        await reader.readuntil(b"\r\n\r\n")
        await self._answer_page(writer)

    async def _relay(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter, port: int) -> None:
        head = await reader.readuntil(b"\r\n\r\n")
        if head.startswith(b"GET /attack.html "):
            await self._answer_page(writer)
            return
        up_reader, up_writer = await asyncio.open_connection("127.0.0.1", port)
        up_writer.write(head)

        async def pump(source: asyncio.StreamReader, sink: asyncio.StreamWriter) -> None:
            with contextlib.suppress(OSError):
                while chunk := await source.read(65536):
                    sink.write(chunk)
                    await sink.drain()
            sink.close()

        await asyncio.gather(pump(reader, up_writer), pump(up_reader, writer))

    async def _answer_page(self, writer: asyncio.StreamWriter) -> None:
        body = ATTACK.encode()
        writer.write(b"HTTP/1.1 200 OK\r\nContent-Type: text/html\r\nContent-Length: %d\r\nConnection: close\r\n\r\n"
                     % len(body) + body)  # fmt: skip
        await writer.drain()
        writer.close()

    def close(self) -> None:
        for server in self.servers:
            self.loop.call_soon_threadsafe(server.close)
        self.loop.call_soon_threadsafe(self.loop.stop)
        self.thread.join(10)


def _chromium() -> str:
    for name in ("/usr/bin/chromium", "chromium", "chromium-browser", "google-chrome"):
        found = shutil.which(name)
        if found:
            return found
    pytest.skip("Chromium is not installed (apt-get install chromium)")


def _run_attack(browser: Any, page_url: str, base: str, routes: list[str], sockets: list[str], origin: str):
    """Open ``page_url`` and attack: (what the page saw, statuses the server answered, WebSocket errors)."""
    page = browser.new_page()
    answered: list[tuple[str, str, int]] = []
    socket_errors: dict[str, str] = {}
    cdp = page.context.new_cdp_session(page)
    cdp.send("Network.enable")

    def response(event: dict[str, Any]) -> None:
        if event["response"]["url"].startswith(origin + "/api/"):
            answered.append((event["type"], event["response"]["url"], event["response"]["status"]))

    cdp.on("Network.responseReceived", response)
    page.on("websocket", lambda ws: ws.on("socketerror", lambda error: socket_errors.__setitem__(ws.url, error)))
    page.goto(page_url)
    seen = page.evaluate("([b, r, s]) => window.attack(b, r, s)", [base, routes, sockets])
    expected = 7 * len(routes)  # 5 fetches or preflights, a beacon and a form per route
    page.wait_for_timeout(200)
    deadline = 0
    while len(answered) < expected and deadline < 100:
        page.wait_for_timeout(100)
        deadline += 1
    page.close()
    return seen, answered, socket_errors


def test_pages_of_another_origin_and_rebound_pages_are_refused_in_chromium(tmp_path):
    sync_api = pytest.importorskip("playwright.sync_api", reason="pip install playwright (no browser download needed)")
    from simrun.serve.gate import BROWSER_BLOCKED_PORTS

    with _attacked_server(tmp_path) as (server, fox), sync_api.sync_playwright() as playwright:
        port = _port(server.url)
        routes = _state_changing(server)
        before = _snapshot(server)
        pages = Pages([port, fox])
        browser = playwright.chromium.launch(executable_path=_chromium(), args=ARGS, headless=True)
        try:
            # a page of another origin (another port of this machine) calls the server and opens its sockets
            target = f"http://127.0.0.1:{port}"
            blocked = [f"ws://127.0.0.1:{p}/" for p in BROWSER_BLOCKED_PORTS]  # the SDK's own port is one
            sockets = [f"ws://127.0.0.1:{port}/api/stream", f"ws://127.0.0.1:{fox}/", *blocked]
            seen, answered, errors = _run_attack(
                browser, pages.other_origin + "/attack.html", target, routes, sockets, target
            )
            assert {status for _, _, status in answered} == {403}, answered
            kinds = {kind for kind, _, _ in answered}
            assert {"Fetch", "Preflight", "Ping", "Document"} <= kinds, kinds
            assert len(answered) >= 7 * len(routes)
            assert all(result in ("opaque", "failed", "queued", "sent", "error") for _, _, result in seen), seen
            sockets_seen = {url: result for kind, url, result in seen if kind == "websocket"}
            assert set(sockets_seen.values()) == {"error"}
            assert "403" in errors[sockets[0]] and "403" in errors[sockets[1]], errors
            assert all("ERR_UNSAFE_PORT" in errors[url] for url in blocked), errors

            # a page whose name now resolves to this machine: same origin as the server, readable answers
            rebound = f"http://rebind.test:{port}"
            sockets = [f"ws://rebind.test:{port}/api/stream", f"ws://rebind.test:{fox}/"]
            seen, answered, errors = _run_attack(browser, rebound + "/attack.html", "", routes, sockets, rebound)
            fetched = [result for kind, _, result in seen if kind not in ("websocket", "beacon", "html-form")]
            assert set(fetched) == {403} and len(fetched) == 5 * len(routes), seen
            assert {status for _, _, status in answered} == {403} and len(answered) >= 7 * len(routes), answered
            assert [result for kind, _, result in seen if kind == "websocket"] == ["error", "error"]
            assert all("403" in errors[url] for url in sockets), errors
        finally:
            browser.close()
            pages.close()
        assert _snapshot(server) == before  # a legitimate client: nothing changed
    _only_the_legitimate_command_was_recorded(tmp_path)
