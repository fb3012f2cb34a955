"""`flexopt run --dask ADDRESS` against addresses where no Dask scheduler answers.

Whatever listens there (a web server, Python's http.server, a listener that never answers, one
that sends random bytes) or does not (a closed port, a host that does not resolve), the run must
end with the documented line, exit code 2, within the connect limit and before anything is
written: distributed itself would raise MemoryError on an HTTP reply (it reads b'HTTP/1.0' as a
frame length of exabytes) and wait for minutes on a silent listener.

Every server listens on 127.0.0.1 only, in a daemon thread that polls a stop event (so its loop
is bounded by the test's lifetime), and is closed in the fixture's teardown.
"""

from __future__ import annotations

import contextlib
import http.server
import json
import random
import socket
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import flexopt_toys  # registers the toy_faults kind
import pytest
from flexopt.pipeline.cli import main

pytest.importorskip("distributed")

#: The connect limit for these tests (FLEXOPT_DASK_CONNECT_TIMEOUT_S), s.
LIMIT_S = 2.0
#: Room over the limit for a loaded machine (thread start, the CLI's own set-up), s.
SLACK_S = 8.0
#: Seconds a server thread waits in accept() between looks at its stop event.
POLL_S = 0.2

HTTP_REPLY = b"HTTP/1.0 200 OK\r\nContent-Type: text/html\r\nContent-Length: 2\r\n\r\nok"


@contextlib.contextmanager
def tcp_server(on_accept: Callable[[socket.socket], None]) -> Iterator[str]:
    """A listener on 127.0.0.1 that calls ``on_accept`` with each connection; yields its address.

    Connections are kept open until teardown (a peer that closes would be another case).
    """
    listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    listener.bind(("127.0.0.1", 0))
    listener.listen(8)
    listener.settimeout(POLL_S)
    stop = threading.Event()
    conns: list[socket.socket] = []

    def serve() -> None:
        while not stop.is_set():
            try:
                conn, _ = listener.accept()
            except (TimeoutError, OSError):
                continue
            conns.append(conn)
            with contextlib.suppress(OSError):
                on_accept(conn)

    thread = threading.Thread(target=serve, daemon=True, name="hostile-server")
    thread.start()
    try:
        yield f"tcp://127.0.0.1:{listener.getsockname()[1]}"
    finally:
        stop.set()
        thread.join(5 * POLL_S + 5.0)
        for conn in conns:
            conn.close()
        listener.close()


@contextlib.contextmanager
def python_http_server() -> Iterator[str]:
    """Python's own http.server on 127.0.0.1 (it waits for a request line before it answers)."""

    class Quiet(http.server.BaseHTTPRequestHandler):
        timeout = 30  # a handler blocked on a client that sends nothing ends at last

        def do_GET(self) -> None:
            self.send_response(200)
            self.end_headers()

        def log_message(self, *args: object) -> None:
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Quiet)
    server.daemon_threads = True
    thread = threading.Thread(
        target=server.serve_forever, kwargs={"poll_interval": POLL_S}, daemon=True
    )
    thread.start()
    try:
        yield f"tcp://127.0.0.1:{server.server_address[1]}"
    finally:
        server.shutdown()
        server.server_close()
        thread.join(5.0)


@contextlib.contextmanager
def closed_port() -> Iterator[str]:
    """An address on 127.0.0.1 where nothing listens (a port just bound and released)."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    yield f"tcp://127.0.0.1:{port}"


def answers_http(conn: socket.socket) -> None:
    conn.sendall(HTTP_REPLY)


def sends_garbage(conn: socket.socket) -> None:
    conn.sendall(random.Random(11).randbytes(4096))


def never_answers(conn: socket.socket) -> None:
    pass


SERVERS: dict[str, Callable[[], contextlib.AbstractContextManager[str]]] = {
    "http-reply": lambda: tcp_server(answers_http),
    "python-http.server": python_http_server,
    "silent": lambda: tcp_server(never_answers),
    "garbage": lambda: tcp_server(sends_garbage),
    "closed-port": closed_port,
}

#: What the line says happened, per server.
WHAT = {
    "http-reply": "answered in HTTP",
    "python-http.server": f"no answer within {LIMIT_S:g} s",
    "silent": f"no answer within {LIMIT_S:g} s",
    "garbage": "not a Dask scheduler",
    "closed-port": "connection refused",
}


@pytest.fixture(params=list(SERVERS))
def hostile(request) -> Iterator[tuple[str, str]]:
    """(name, address) of one hostile listener, closed after the test."""
    with SERVERS[request.param]() as address:
        yield request.param, address


@pytest.fixture
def toy_study(tmp_path: Path) -> Path:
    path = tmp_path / "toy.yaml"
    path.write_text(json.dumps(flexopt_toys.study()))
    return path


@pytest.fixture(autouse=True)
def short_connect_limit(monkeypatch) -> None:
    monkeypatch.setenv("FLEXOPT_DASK_CONNECT_TIMEOUT_S", str(LIMIT_S))


def run_against(address: str, study: Path, out: Path, capsys) -> tuple[int, str, float]:
    """``flexopt run STUDY --dask ADDRESS --out OUT``: (exit code, stderr, seconds)."""
    capsys.readouterr()
    started = time.monotonic()
    code = main(["run", str(study), "--dask", address, "--out", str(out)])
    elapsed = time.monotonic() - started
    return code, capsys.readouterr().err, elapsed


def assert_refused(code: int, err: str, address: str, what: str) -> None:
    assert code == 2, err
    assert "Traceback" not in err
    assert err.count("\n") == 1 and err.endswith("\n"), err
    assert err.startswith(
        f"flexopt run: error: --dask: cannot reach the Dask scheduler at {address} ("
    ), err
    assert what in err, err
    assert err.rstrip("\n").endswith("check the address and that `dask scheduler` runs there")


def test_a_hostile_address_is_the_documented_line_within_the_limit(
    hostile, toy_study, tmp_path, capsys
):
    name, address = hostile
    out = tmp_path / "r"
    code, err, elapsed = run_against(address, toy_study, out, capsys)
    assert_refused(code, err, address, WHAT[name])
    assert elapsed < LIMIT_S + SLACK_S, elapsed
    assert not out.exists()


def test_a_host_that_does_not_resolve_is_the_documented_line(
    toy_study, tmp_path, capsys, monkeypatch
):
    # No name server is asked (the test may not use the network): resolving fails as it does
    # for a name that does not exist.
    def no_such_host(*args, **kwargs):
        raise socket.gaierror(socket.EAI_NONAME, "Name or service not known")

    monkeypatch.setattr(socket, "getaddrinfo", no_such_host)
    address = "tcp://no-such-host.invalid:8786"
    out = tmp_path / "r"
    code, err, elapsed = run_against(address, toy_study, out, capsys)
    assert_refused(code, err, address, "host 'no-such-host.invalid' not found")
    assert elapsed < LIMIT_S + SLACK_S, elapsed
    assert not out.exists()


def test_an_invalid_connect_limit_is_one_line(toy_study, tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("FLEXOPT_DASK_CONNECT_TIMEOUT_S", "soon")
    with closed_port() as address:
        code, err, _ = run_against(address, toy_study, tmp_path / "r", capsys)
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err
    assert "FLEXOPT_DASK_CONNECT_TIMEOUT_S='soon' is not a positive number of seconds" in err
    assert not (tmp_path / "r").exists()
