"""A live Rerun view of a run: Rerun's web viewer served on this machine's loopback only, or a
connection to a Rerun viewer already running.

``LiveViewer.start()`` runs Rerun's own server (the ``rerun`` executable of rerun-sdk, ``rerun
--serve-web --bind 127.0.0.1``) as a child process: a gRPC proxy that keeps everything it was
sent, so a browser opened late still gets the whole run, and an HTTP server for the web viewer's
page. The SDK's in-process ``serve_grpc``/``serve_web_viewer`` would listen on 0.0.0.0 (every
interface) with no way to narrow it; the executable's ``--bind`` does. Both ports are free
loopback ports chosen here unless given; a port that is taken is refused in one line. The
server is stopped by :meth:`LiveViewer.stop`, and by the kernel when this process dies
(``PR_SET_PDEATHSIG``), so a killed run leaves no server behind.

``check_url`` validates a ``--connect`` URL (``rerun+http://HOST:PORT/proxy``, Rerun's default
``DEFAULT_CONNECT``) and that a gRPC server answers there: the HTTP/2 handshake (the client's
preface, the server's SETTINGS frame) must complete within ``HANDSHAKE_TIMEOUT``, so a typo, or
a port that listens but never speaks, is a one-line error instead of a run streaming into
nowhere (for TLS URLs only the TCP connection is checked). ``LiveViewer.start`` checks its own
server the same way.
"""

from __future__ import annotations

import contextlib
import importlib.util
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.parse
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mechsim.errors import MechsimError, ParameterError

HOST = "127.0.0.1"
#: Rerun's own default for a viewer's gRPC server (``rerun`` with no arguments listens there).
DEFAULT_CONNECT = f"rerun+http://{HOST}:9876/proxy"
#: How long the server may take to listen on both ports [s] (a cold start reads ~40 MB).
START_TIMEOUT = 60.0
_SCHEMES = {"rerun": 443, "rerun+http": 80, "rerun+https": 443}
#: How long a gRPC server may take to answer the HTTP/2 handshake [s].
HANDSHAKE_TIMEOUT = 5.0
#: The HTTP/2 client connection preface and an empty SETTINGS frame (RFC 9113, 3.4 and 6.5).
_H2_PREFACE = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n" + bytes([0, 0, 0, 4, 0, 0, 0, 0, 0])
_H2_SETTINGS = 4


def handshake(host: str, port: int, timeout: float = HANDSHAKE_TIMEOUT) -> str | None:
    """Why ``host:port`` is not a gRPC (HTTP/2 cleartext) server answering within ``timeout``
    seconds in total, or None: it answered the client preface with a SETTINGS frame."""
    deadline = time.monotonic() + timeout
    try:
        with socket.create_connection((host, port), timeout=timeout) as s:
            s.sendall(_H2_PREFACE)
            head = b""
            while len(head) < 9:
                s.settimeout(max(deadline - time.monotonic(), 0.001))
                part = s.recv(9 - len(head))
                if not part:
                    return "it closed the connection without an HTTP/2 answer"
                head += part
    except TimeoutError:
        return f"it did not answer the HTTP/2 handshake within {timeout:g} s"
    except OSError as e:
        return f"nothing listens there ({e.strerror or e})"
    if head[3] != _H2_SETTINGS:
        return "it does not speak HTTP/2 (not a gRPC server)"
    return None


def rerun_executable() -> str:
    """The Rerun executable shipped with rerun-sdk (``rerun_cli/rerun``; not the ``rerun``
    Python wrapper, so the child process is the server itself), else ``rerun`` on PATH."""
    spec = importlib.util.find_spec("rerun_cli")
    if spec is not None and spec.origin is not None:
        exe = Path(spec.origin).parent / "rerun"
        if exe.is_file() and os.access(exe, os.X_OK):
            return str(exe)
    exe = Path(sys.executable).parent / "rerun"
    return str(exe) if exe.exists() else "rerun"


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((HOST, 0))
        return int(s.getsockname()[1])


def _check_free(field: str, port: int) -> int:
    if not 1 <= port <= 65535:
        raise ParameterError(field, f"{port} is not a TCP port (1..65535)")
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        try:
            s.bind((HOST, port))
        except OSError as e:
            raise ParameterError(field, f"port {port} on {HOST} is taken "
                                 f"({e.strerror or e}); choose another") from None
    return port


def _listening(port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.settimeout(1.0)
        return s.connect_ex((HOST, port)) == 0


def _die_with_parent() -> None:
    """In the child before exec: SIGTERM when the parent dies (Linux ``prctl``)."""
    with contextlib.suppress(Exception):
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG


@dataclass
class LiveViewer:
    """Rerun's web viewer and gRPC proxy served on ``127.0.0.1`` by a child process."""

    process: subprocess.Popen[bytes]
    web_port: int
    grpc_port: int
    log: Any  # the server's stderr (a temporary file: a pipe left unread could fill)

    @property
    def grpc_url(self) -> str:
        """Where a RerunSink sends (``RerunSink.live``) and a native viewer connects."""
        return f"rerun+http://{HOST}:{self.grpc_port}/proxy"

    @property
    def web_url(self) -> str:
        """The page to open in a browser: the web viewer, connected to the gRPC proxy."""
        return (f"http://{HOST}:{self.web_port}/?url="
                f"{urllib.parse.quote(self.grpc_url, safe='')}")

    @classmethod
    def start(cls, web_port: int | None = None) -> LiveViewer:
        """Start the server; ``web_port`` None: a free port. Returns once both ports listen.
        MechsimError in one line if a port is taken or the server does not come up."""
        web = _check_free("--viewer-port", web_port) if web_port is not None else _free_port()
        grpc = _free_port()
        while grpc == web:
            grpc = _free_port()
        args = [rerun_executable(), "--serve-web", "--bind", HOST, "--port", str(grpc),
                "--web-viewer-port", str(web)]
        log = tempfile.TemporaryFile()
        try:
            # Its own session: Ctrl-C reaches mechsim only, which stops the server last.
            proc = subprocess.Popen(args, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                    stderr=log, start_new_session=True,
                                    preexec_fn=_die_with_parent)
        except OSError as e:
            log.close()
            raise MechsimError(f"--viewer: cannot start Rerun's server {args[0]} "
                               f"({e.strerror or e})") from None
        viewer = cls(proc, web, grpc, log)
        deadline = time.monotonic() + START_TIMEOUT
        try:
            while not (_listening(grpc) and _listening(web)):
                if proc.poll() is not None:
                    raise MechsimError(f"--viewer: Rerun's server exited ({viewer._reason()})")
                if time.monotonic() > deadline:
                    raise MechsimError(f"--viewer: Rerun's server did not listen on {HOST}:"
                                       f"{grpc} and :{web} within {START_TIMEOUT:g} s")
                with contextlib.suppress(subprocess.TimeoutExpired):
                    proc.wait(timeout=0.05)
            why = handshake(HOST, grpc, min(HANDSHAKE_TIMEOUT,
                                            max(deadline - time.monotonic(), 1.0)))
            if why is not None:
                raise MechsimError(f"--viewer: Rerun's server on {HOST}:{grpc}: {why}")
        except BaseException:
            viewer.stop()
            raise
        return viewer

    def _reason(self) -> str:
        """The last line the server wrote on stderr (its error), without terminal colours."""
        import re

        self.log.seek(0)
        err = self.log.read().decode(errors="replace")
        lines = [re.sub(r"\x1b\[[0-9;]*m", "", ln).strip() for ln in err.splitlines()]
        lines = [ln for ln in lines if ln]
        return lines[-1][:300] if lines else f"status {self.process.returncode}"

    def alive(self) -> bool:
        return self.process.poll() is None

    def wait(self) -> None:
        """Until the server ends (or KeyboardInterrupt: Ctrl-C, or SIGTERM via
        ``stop_on_sigterm``)."""
        while self.process.poll() is None:
            with contextlib.suppress(subprocess.TimeoutExpired):
                self.process.wait(timeout=0.5)

    def stop(self) -> None:
        """Stop the server (SIGTERM, then SIGKILL after 5 s). Idempotent."""
        p = self.process
        if p.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                p.terminate()
            try:
                p.wait(timeout=5.0)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    p.kill()
                p.wait()
        self.log.close()


def check_url(url: str) -> str:
    """A ``--connect`` URL: scheme rerun://, rerun+http:// or rerun+https://, path /proxy,
    and a server listening there (a one-line error otherwise)."""
    parts = urllib.parse.urlsplit(url)
    if parts.scheme not in _SCHEMES or parts.path != "/proxy" or not parts.hostname:
        raise ParameterError("--connect", f"{url!r} is not a Rerun gRPC URL (like "
                             f"{DEFAULT_CONNECT})")
    try:
        port = parts.port or _SCHEMES[parts.scheme]
    except ValueError:
        raise ParameterError("--connect", f"{url!r}: bad port") from None
    if parts.scheme == "rerun+http":
        why = handshake(parts.hostname, port)
        if why is not None:
            raise ParameterError("--connect", f"{parts.hostname}:{port}: {why}; start a viewer "
                                 "first (`rerun`)")
        return url
    try:
        with socket.create_connection((parts.hostname, port), timeout=HANDSHAKE_TIMEOUT):
            pass
    except OSError as e:
        raise ParameterError("--connect", f"nothing listens at {parts.hostname}:{port} "
                             f"({e.strerror or e}); start a viewer first (`rerun`)") from None
    return url
