"""The live Rerun view (`mechsim run ... --viewer`), looked at in a real browser: headless
Chromium (Debian's ``chromium``, unpacked into the checkout by tools/test_tools.py, which `make
test` runs; else a ``chromium`` on PATH) opens the printed
URL, and the test checks that the web viewer started, holds the whole run (read back from the
viewer itself, ``WebHandle.save_recording``, and compared with the .rrd the same run wrote),
applies the blueprint, and draws it (a screenshot with several distinct regions). The servers
must listen on 127.0.0.1 only, and Ctrl-C after the run ends stops them.

``MECHSIM_LIVE_VIEWER_SCREENSHOT=docs/images/rerun_pendulum.png`` also saves the screenshot (the
README's picture). Chromium is driven over its DevTools protocol on a pipe
(``--remote-debugging-pipe``: JSON messages ending in NUL on file descriptors 3 and 4), so no
WebDriver or websocket client is needed."""

from __future__ import annotations

import base64
import contextlib
import io
import json
import os
import re
import select
import shutil
import signal
import subprocess
import sys
import threading
import time
import urllib.parse
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

MECHSIM = [sys.executable, "-m", "mechsim.cli"]
ROOT = Path(__file__).resolve().parents[1]
#: Where tools/test_tools.py says it unpacked Chromium (executable, library path).
CHROMIUM_INFO = ROOT / ".cache" / "test-tools" / "chromium.json"
DEADLINE = 180.0  # generous: a cold Chromium renders the viewer with a software rasterizer
DURATION, RATE = 3.0, 50.0


def find_chromium() -> tuple[str | None, dict[str, str]]:
    """(executable, extra environment) of the Chromium to drive: the checkout's (with its
    libraries on LD_LIBRARY_PATH), else one on PATH; (None, {}) if there is none."""
    try:
        info = json.loads(CHROMIUM_INFO.read_text())
        exe = ROOT / info["executable"]
        if os.access(exe, os.X_OK):
            libs = [str(ROOT / d) for d in info["library_path"]]
            old = os.environ.get("LD_LIBRARY_PATH")
            return str(exe), {"LD_LIBRARY_PATH": os.pathsep.join([*libs, *([old] if old
                                                                           else [])])}
    except (OSError, ValueError, KeyError, TypeError):
        pass
    return shutil.which("chromium"), {}


CHROMIUM, CHROMIUM_ENV = find_chromium()

needs_chromium = pytest.mark.skipif(
    CHROMIUM is None,
    reason="no Chromium: `make test` unpacks Debian's chromium into the checkout where apt-get "
           "can download it (see the output of tools/test_tools.py), else install `chromium`")


def wait_until(what: str, check: Callable[[], Any], timeout: float = DEADLINE) -> Any:
    """Poll ``check`` until it returns something truthy; fail naming ``what`` at timeout."""
    deadline = time.monotonic() + timeout
    while True:
        value = check()
        if value:
            return value
        if time.monotonic() > deadline:
            pytest.fail(f"timed out after {timeout:g} s waiting for {what}")
        time.sleep(0.2)


class Lines:
    """A child's text stream read by a thread, so polling never blocks on it."""

    def __init__(self, stream: Any) -> None:
        self.lines: list[str] = []
        self._t = threading.Thread(target=self._read, args=(stream,), daemon=True)
        self._t.start()

    def _read(self, stream: Any) -> None:
        for line in stream:
            self.lines.append(line.rstrip("\n"))

    def find(self, pattern: str) -> re.Match[str] | None:
        for line in list(self.lines):
            m = re.search(pattern, line)
            if m:
                return m
        return None

    def text(self) -> str:
        return "\n".join(self.lines)


class Chromium:
    """Headless Chromium driven over the DevTools protocol on a pipe."""

    def __init__(self, profile: Path, size: tuple[int, int] = (1280, 800)) -> None:
        to_child, self._out = os.pipe()
        self._in, from_child = os.pipe()

        def pipes() -> None:  # in the child: the protocol's file descriptors 3 and 4
            os.dup2(to_child, 3)
            os.dup2(from_child, 4)

        assert CHROMIUM is not None
        self.proc = subprocess.Popen(
            [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader",
             "--disable-quic", "--no-first-run", "--disable-background-networking",
             "--disable-component-update", "--disable-sync", "--disable-extensions",
             f"--user-data-dir={profile}", f"--window-size={size[0]},{size[1]}",
             "--remote-debugging-pipe", "about:blank"],
            preexec_fn=pipes, close_fds=False, start_new_session=True,
            env={**os.environ, **CHROMIUM_ENV},
            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
            stderr=open(profile.parent / "chromium.log", "wb"))  # noqa: SIM115
        os.close(to_child)
        os.close(from_child)
        self._id = 0
        self._buf = b""
        self.events: list[dict[str, Any]] = []

    def _receive(self, deadline: float) -> dict[str, Any]:
        while b"\0" not in self._buf:
            left = deadline - time.monotonic()
            if left <= 0:
                raise TimeoutError("no answer from Chromium")
            ready, _, _ = select.select([self._in], [], [], left)
            if ready:
                chunk = os.read(self._in, 1 << 20)
                if not chunk:
                    raise EOFError("Chromium closed its DevTools pipe")
                self._buf += chunk
        message, _, self._buf = self._buf.partition(b"\0")
        return json.loads(message)

    def call(self, method: str, session: str | None = None, timeout: float = 60.0,
             **params: Any) -> dict[str, Any]:
        self._id += 1
        request: dict[str, Any] = {"id": self._id, "method": method, "params": params}
        if session:
            request["sessionId"] = session
        os.write(self._out, json.dumps(request).encode() + b"\0")
        deadline = time.monotonic() + timeout
        while True:
            answer = self._receive(deadline)
            if answer.get("id") == self._id:
                if "error" in answer:
                    raise RuntimeError(f"{method}: {answer['error']}")
                return answer["result"]
            self.events.append(answer)

    def open(self, url: str) -> str:
        """A new page at ``url``; returns its session id."""
        target = self.call("Target.createTarget", url=url)["targetId"]
        return self.call("Target.attachToTarget", targetId=target, flatten=True)["sessionId"]

    def evaluate(self, session: str, expression: str) -> Any:
        """The value of a JavaScript expression (awaited); an exception's text as an Exception."""
        r = self.call("Runtime.evaluate", session=session, expression=expression,
                      returnByValue=True, awaitPromise=True)
        if "exceptionDetails" in r:
            return Exception(r["exceptionDetails"].get("exception", {}).get("value")
                             or r["exceptionDetails"].get("text"))
        return r["result"].get("value")

    def screenshot(self, session: str) -> bytes:
        return base64.b64decode(self.call("Page.captureScreenshot", session=session,
                                          format="png")["data"])

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self.call("Browser.close", timeout=10.0)
        try:
            self.proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait()
        os.close(self._in)
        os.close(self._out)


def listeners(port: int) -> list[str]:
    """Local addresses of the TCP sockets listening on ``port`` (/proc/net/tcp and tcp6)."""
    found = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        with contextlib.suppress(FileNotFoundError), open(table) as f:
            for row in f.read().splitlines()[1:]:
                local, state = row.split()[1], row.split()[3]
                addr, _, p = local.partition(":")
                if state == "0A" and int(p, 16) == port:  # 0A: LISTEN
                    if len(addr) == 8:  # IPv4, little-endian hex
                        found.append(".".join(str(int(addr[i:i + 2], 16))
                                              for i in (6, 4, 2, 0)))
                    else:
                        found.append(f"ipv6:{addr}")
    return found


JS_BYTES = """(() => {{
  const b = window._handle.{method}();
  let s = '';
  for (let i = 0; i < b.length; i += 0x8000)
    s += String.fromCharCode.apply(null, b.subarray(i, i + 0x8000));
  return btoa(s);
}})()"""


def read_entities(path: Path, blueprint: bool = False) -> dict[str, dict[str, Any]]:
    """entity -> {"rows": temporal rows, "last": last sim_time [ns], "static": column names,
    "values": every cell as text} of the recording (or blueprint) in an .rrd / .rbl file;
    empty if the file holds none (yet)."""
    import pyarrow as pa
    from rerun.chunk import RrdReader

    reader = RrdReader(path)
    stores = reader.blueprints() if blueprint else reader.recordings()
    out: dict[str, dict[str, Any]] = {}
    if not stores:
        return out
    for chunk in reader.stream(store=stores[0]).to_chunks():
        batch = chunk.to_record_batch()
        e = out.setdefault(chunk.entity_path, {"rows": 0, "last": None, "static": set(),
                                               "values": []})
        names = [n for n in batch.schema.names if n != "rerun.controls.RowId"]
        e["values"].extend(batch.column(n).to_string(window=100, container_window=100)
                           for n in names)
        if chunk.is_static:
            e["static"].update(names)
            continue
        e["rows"] += batch.num_rows
        if "sim_time" in batch.schema.names:
            last = max(batch.column("sim_time").cast(pa.int64()).to_pylist())
            e["last"] = last if e["last"] is None else max(e["last"], last)
    return out


def distinct_regions(png: bytes) -> tuple[int, float]:
    """(colours covering at least 0.1 % of the picture, share of the commonest colour). The
    page before the viewer draws is one colour; the drawn viewer (background, panels, text,
    the pendulum, the plots' lines) has many."""
    from PIL import Image

    img = Image.open(io.BytesIO(png)).convert("RGB")
    counts = img.getcolors(maxcolors=img.width * img.height) or []
    total = img.width * img.height
    return (sum(1 for n, _ in counts if n >= total / 1000),
            max(n for n, _ in counts) / total)


class ViewerRun:
    """``mechsim run ... --viewer`` as a child process: its output, the printed URL and ports;
    :meth:`close` kills whatever is left (the run, its browser)."""

    def __init__(self, args: list[str], env: dict[str, str], tmp_path: Path) -> None:
        self.tmp_path = tmp_path
        self.run = subprocess.Popen(
            [*MECHSIM, "run", *args, "--viewer"], env=env, stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
        self.out, self.err = Lines(self.run.stdout), Lines(self.run.stderr)
        self.browser: Chromium | None = None
        m = wait_until("the live view's URL", lambda: self.err.find(
            r"live view: open (http://127\.0\.0\.1:(\d+)/\?url=(\S+))") or self.exited())
        self.url, self.web_port = m.group(1), int(m.group(2))
        grpc_url = urllib.parse.unquote(m.group(3))
        grpc = re.fullmatch(r"rerun\+http://127\.0\.0\.1:(\d+)/proxy", grpc_url)
        assert grpc, grpc_url
        self.grpc_port = int(grpc.group(1))

    def exited(self) -> bool:
        """False while the run goes on; fails the test with its messages once it exited."""
        if self.run.poll() is not None:
            pytest.fail(f"mechsim exited ({self.run.returncode}): {self.err.text()}")
        return False

    def open_page(self) -> str:
        """Chromium showing the printed URL, once the web viewer started; the page's session."""
        self.browser = Chromium(self.tmp_path / "profile")
        page = self.browser.open(self.url)
        wait_until("the web viewer to start", lambda: self.browser.evaluate(  # type: ignore[union-attr]
            page, "window._handle !== undefined") is True)
        assert self.browser.evaluate(page, "window._handle.has_panicked()") is False
        return page

    def recording(self, page: str, path: Path) -> dict[str, dict[str, Any]]:
        """What the viewer holds now (``read_entities``; empty until the stream arrives)."""
        assert self.browser is not None
        data = self.browser.evaluate(page, JS_BYTES.format(method="save_recording"))
        if not isinstance(data, str):
            return {}  # "No active recording to save" until the stream arrives
        path.write_bytes(base64.b64decode(data))
        return read_entities(path)

    def close(self) -> None:
        if self.browser is not None:
            self.browser.close()
            self.browser = None
        if self.run.poll() is None:
            os.killpg(self.run.pid, signal.SIGKILL)
            self.run.wait()


@needs_chromium
def test_live_viewer_renders_the_run(ros_env: dict[str, str], tmp_path: Path) -> None:
    rrd = tmp_path / "run.rrd"
    v = ViewerRun(["pendulum", "--fast", "--duration", str(DURATION), "--publish-rate", str(RATE),
                   "--rrd", str(rrd)], ros_env, tmp_path)
    run, out, err, web_port, grpc_port = v.run, v.out, v.err, v.web_port, v.grpc_port
    try:
        # Both servers listen on loopback only (never 0.0.0.0, never IPv6 any).
        assert listeners(web_port) == ["127.0.0.1"], listeners(web_port)
        assert listeners(grpc_port) == ["127.0.0.1"], listeners(grpc_port)

        # The run ends; the view stays up (until Ctrl-C).
        wait_until("the end of the run", lambda: err.find("the live view stays at")
                   or v.exited())
        assert "Conservation results" in out.text()
        assert rrd.is_file()

        page = v.open_page()
        browser = v.browser
        assert browser is not None

        # The viewer holds the whole run: the same entities and rows as the .rrd written by
        # the same run, up to the run's duration.
        expected = {e: v for e, v in read_entities(rrd).items() if v["rows"]}
        live_rrd = tmp_path / "live.rrd"

        def whole_run() -> bool:
            got = v.recording(page, live_rrd)
            return all(e in got and got[e]["rows"] == x["rows"] for e, x in expected.items())

        wait_until("the viewer to hold every row of the run", whole_run)
        got = read_entities(live_rrd)
        energy = got["/plots/pendulum/energy/total"]
        assert energy["rows"] == round(DURATION * RATE) + 1
        assert energy["last"] == round(DURATION * 1e9)
        assert any(e.startswith("/world/pendulum/") for e in got)
        assert "SeriesLines:names" in " ".join(got["/plots/pendulum/energy/total"]["static"])

        # The blueprint the viewer uses is the .rrd's: the run's views by name.
        rbl = tmp_path / "live.rbl"
        rbl.write_bytes(base64.b64decode(browser.evaluate(page, JS_BYTES.format(
            method="save_blueprint"))))
        names = " ".join(v for e in read_entities(rbl, blueprint=True).values()
                         for v in e["values"])
        for view in ("pendulum: energy [J]", "pendulum: balance residual", "world"):
            assert view in names, view

        # It is drawn: the picture settles (the run is over) with many distinct regions.
        shots: list[bytes] = []

        def settled() -> bool:
            shots.append(browser.screenshot(page))
            if len(shots) < 2 or shots[-1] != shots[-2]:
                return False
            colours, commonest = distinct_regions(shots[-1])
            return colours >= 8 and commonest < 0.95

        wait_until("a settled picture of the viewer", settled)
        colours, commonest = distinct_regions(shots[-1])
        assert colours >= 8 and commonest < 0.95, (colours, commonest)
        if os.environ.get("MECHSIM_LIVE_VIEWER_SCREENSHOT"):
            Path(os.environ["MECHSIM_LIVE_VIEWER_SCREENSHOT"]).write_bytes(shots[-1])
        (tmp_path / "live_viewer.png").write_bytes(shots[-1])

        # Ctrl-C ends the view: exit status of the (successful) run, both ports closed.
        run.send_signal(signal.SIGINT)
        assert run.wait(timeout=60) == 0, err.text()
        assert listeners(web_port) == [] and listeners(grpc_port) == []
    finally:
        v.close()


@needs_chromium
def test_live_viewer_shows_a_real_time_run_as_it_happens(ros_env: dict[str, str],
                                                         tmp_path: Path) -> None:
    """A run in real time, far from its end: the viewer receives rows while it runs, a few at a
    time (not in the batches of ``FLUSH_ROWS`` rows a recording is written in), and more
    later; Ctrl-C then stops the run and the view together."""
    from mechsim.outputs.rerun.series import FLUSH_ROWS

    v = ViewerRun(["pendulum", "--duration", "3600", "--publish-rate", str(RATE)], ros_env,
                  tmp_path)
    try:
        page = v.open_page()
        entity = "/plots/pendulum/energy/total"

        def rows() -> int:
            return int(v.recording(page, tmp_path / "live.rrd").get(entity, {}).get("rows", 0))

        first = wait_until("rows in the viewer, fewer than a whole batch",
                           lambda: (n := rows()) % FLUSH_ROWS and n)
        wait_until("more rows in the viewer", lambda: rows() > first)
        assert v.run.poll() is None and not v.err.find("the run has ended")
        v.run.send_signal(signal.SIGINT)
        assert v.run.wait(timeout=60) in (0, 130), v.err.text()  # an interrupted run
        assert listeners(v.web_port) == [] and listeners(v.grpc_port) == []
    finally:
        v.close()


def run_cli(args: list[str], env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*MECHSIM, *args], env=env, capture_output=True, text=True,
                          timeout=120)


def test_viewer_port_taken_is_refused(ros_env: dict[str, str]) -> None:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        r = run_cli(["run", "pendulum", "--viewer", "--viewer-port", str(port),
                     "--duration", "0.1"], ros_env)
    assert r.returncode == 2, r.stderr
    assert r.stderr.strip().splitlines()[-1] == (
        f"mechsim: error: --viewer-port: port {port} on 127.0.0.1 is taken (Address already "
        "in use); choose another")


@pytest.mark.parametrize("url, reason", [
    ("http://127.0.0.1:9876/proxy", "is not a Rerun gRPC URL"),
    ("rerun+http://127.0.0.1:9876/other", "is not a Rerun gRPC URL"),
    ("rerun+http://127.0.0.1:notaport/proxy", "bad port"),
])
def test_connect_url_is_checked(ros_env: dict[str, str], url: str, reason: str) -> None:
    r = run_cli(["run", "pendulum", "--connect", url, "--duration", "0.1"], ros_env)
    assert r.returncode == 2, r.stderr
    last = r.stderr.strip().splitlines()[-1]
    assert last.startswith("mechsim: error: --connect: ") and reason in last, last


def test_connect_to_nothing_is_refused(ros_env: dict[str, str]) -> None:
    import socket

    with socket.socket() as s:  # a port known to be free: bound, never listening
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
        r = run_cli(["run", "pendulum", "--connect", f"rerun+http://127.0.0.1:{port}/proxy",
                     "--duration", "0.1"], ros_env)
    assert r.returncode == 2, r.stderr
    assert r.stderr.strip().splitlines()[-1].startswith(
        f"mechsim: error: --connect: 127.0.0.1:{port}: nothing listens there")


class MutePeer:
    """A TCP listener on a free loopback port that never says anything (``handshake``
    False: the kernel completes connections, nobody reads), or that answers the HTTP/2
    handshake with its SETTINGS frame and then reads everything and never answers
    (``handshake`` True: a gRPC server that stalls)."""

    def __init__(self, handshake: bool) -> None:
        import socket

        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(16)
        self.port = self.sock.getsockname()[1]
        self.url = f"rerun+http://127.0.0.1:{self.port}/proxy"
        self.conns: list[Any] = []
        self.received = 0  # bytes read from every connection
        if handshake:
            threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self) -> None:
        with contextlib.suppress(OSError):
            while True:
                conn, _ = self.sock.accept()
                self.conns.append(conn)
                threading.Thread(target=self._mute, args=(conn,), daemon=True).start()

    def _mute(self, conn: Any) -> None:
        with contextlib.suppress(OSError):
            self.received += len(conn.recv(24))  # the client's preface
            conn.sendall(bytes([0, 0, 0, 4, 0, 0, 0, 0, 0]))  # SETTINGS, then silence
            while data := conn.recv(65536):
                self.received += len(data)

    def close(self) -> None:
        import socket

        with contextlib.suppress(OSError):
            self.sock.shutdown(socket.SHUT_RDWR)
        self.sock.close()
        for conn in self.conns:
            conn.close()


def test_connect_to_a_listener_that_never_speaks_is_refused(ros_env: dict[str, str]) -> None:
    """Something listens at the URL but never answers the HTTP/2 handshake: one line, before
    the run, naming the deadline (rerun_live.HANDSHAKE_TIMEOUT)."""
    from mechsim.outputs.rerun_live import HANDSHAKE_TIMEOUT

    peer = MutePeer(handshake=False)
    try:
        r = run_cli(["run", "pendulum", "--connect", peer.url, "--fast", "--duration", "0.2"],
                    ros_env)
    finally:
        peer.close()
    assert r.returncode == 2, r.stderr
    lines = [ln for ln in r.stderr.splitlines() if ln.startswith("mechsim: error")]
    assert lines == [f"mechsim: error: --connect: 127.0.0.1:{peer.port}: it did not answer "
                     f"the HTTP/2 handshake within {HANDSHAKE_TIMEOUT:g} s; start a viewer "
                     "first (`rerun`)"], r.stderr
    assert "Traceback" not in r.stderr


def test_a_viewer_that_stalls_costs_a_bounded_close(ros_env: dict[str, str]) -> None:
    """A gRPC peer that completes the handshake and then never answers: the run ends with
    one line naming the bound it waited (LIVE_CLOSE_TIMEOUT), exit 2, none of Rerun's own
    log lines."""
    from mechsim.outputs.rerun.sink import LIVE_CLOSE_TIMEOUT

    peer = MutePeer(handshake=True)
    try:
        r = run_cli(["run", "pendulum", "--connect", peer.url, "--fast", "--duration", "0.2"],
                    ros_env)
    finally:
        peer.close()
    assert r.returncode == 2, r.stderr
    assert r.stderr.splitlines()[-1] == (
        f"mechsim: error: live view {peer.url}: the viewer did not take the rest of the run "
        f"within {LIVE_CLOSE_TIMEOUT:g} s (it does not answer); what it took is kept"), r.stderr
    assert "re_grpc_client" not in r.stderr and "Traceback" not in r.stderr


def test_ctrl_c_with_a_stalled_viewer_exits_130(ros_env: dict[str, str]) -> None:
    """Ctrl-C during a real-time run streaming to a peer that stalls: exit 130, and the
    stream is given up after the short bound of a stopped run (INTERRUPTED_CLOSE_TIMEOUT),
    said in one line."""
    from mechsim.outputs.rerun.sink import INTERRUPTED_CLOSE_TIMEOUT

    peer = MutePeer(handshake=True)
    proc = subprocess.Popen([*MECHSIM, "run", "pendulum", "--connect", peer.url, "--duration",
                             "600"], env=ros_env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        # Until HTTP/2's initial flow-control window (65535 bytes, never opened by the peer)
        # is full: what the run sends from then on cannot be taken.
        wait_until("a full window of the run's stream", lambda: peer.received >= 65535 + 24 or (
            proc.poll() is not None and pytest.fail(proc.stderr.read())))
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
        peer.close()
    assert proc.returncode == 130, err
    assert err.splitlines()[-1] == (
        f"mechsim: live view {peer.url}: the viewer did not take the rest of the run within "
        f"{INTERRUPTED_CLOSE_TIMEOUT:g} s (it does not answer); what it took is kept"), err


@pytest.mark.filterwarnings("ignore:RRD file has no footer")  # Rerun stopped by Ctrl-C
def test_connect_streams_the_run_to_a_running_viewer(ros_env: dict[str, str],
                                                      tmp_path: Path) -> None:
    """`--connect URL` sends the run to a Rerun server already running (here Rerun's own,
    saving what it receives): it gets every row the run's .rrd holds."""
    import socket

    from mechsim.outputs.rerun_live import rerun_executable

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    saved, rrd = tmp_path / "received.rrd", tmp_path / "run.rrd"
    server = subprocess.Popen([rerun_executable(), "--bind", "127.0.0.1", "--port", str(port),
                               "--save", str(saved)], stdin=subprocess.DEVNULL,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                              start_new_session=True)
    try:
        wait_until("Rerun's server to listen", lambda: listeners(port) == ["127.0.0.1"] or (
            server.poll() is not None and pytest.fail("rerun exited")))
        r = run_cli(["run", "pendulum", "--connect", f"rerun+http://127.0.0.1:{port}/proxy",
                     "--fast", "--duration", str(DURATION), "--publish-rate", str(RATE),
                     "--rrd", str(rrd)], ros_env)
        assert r.returncode == 0, r.stderr
        assert f"live view rerun+http://127.0.0.1:{port}/proxy: " in r.stdout
    finally:
        server.send_signal(signal.SIGINT)  # Rerun completes the file on Ctrl-C
        try:
            server.wait(timeout=60)
        except subprocess.TimeoutExpired:
            os.killpg(server.pid, signal.SIGKILL)
            server.wait()
    expected = {e: v["rows"] for e, v in read_entities(rrd).items() if v["rows"]}
    got = {e: v["rows"] for e, v in read_entities(saved).items() if v["rows"]}
    assert got == expected
    assert expected["/plots/pendulum/energy/total"] == round(DURATION * RATE) + 1


def test_view_hint_serves_on_loopback_only(ros_env: dict[str, str], tmp_path: Path) -> None:
    """Without a display `mechsim view` suggests a command for a browser: run as printed (on
    free ports), its servers listen on 127.0.0.1 only."""
    import shlex
    import socket

    rrd = tmp_path / "run.rrd"
    r = run_cli(["run", "pendulum", "--fast", "--duration", "0.2", "--rrd", str(rrd)], ros_env)
    assert r.returncode == 0, r.stderr
    env = {k: v for k, v in ros_env.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    hint = run_cli(["view", str(rrd)], env)
    assert hint.returncode == 0, hint.stderr
    m = re.search(r"`(rerun [^`]*--web-viewer[^`]*)`", hint.stdout)
    assert m, hint.stdout
    ports = []
    for _ in range(2):
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            ports.append(s.getsockname()[1])
    from mechsim.outputs.rerun_live import rerun_executable

    cmd = shlex.split(m.group(1))
    server = subprocess.Popen([rerun_executable(), *cmd[1:], "--port", str(ports[0]),
                               "--web-viewer-port", str(ports[1])], env=env,
                              stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        wait_until("the hinted command's servers", lambda: all(listeners(p) for p in ports)
                   or (server.poll() is not None and pytest.fail("rerun exited")))
        assert [listeners(p) for p in ports] == [["127.0.0.1"], ["127.0.0.1"]]
    finally:
        os.killpg(server.pid, signal.SIGKILL)
        server.wait()
