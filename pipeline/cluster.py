"""The Dask backend: evaluate designs on a ``dask.distributed`` cluster.

dask.distributed is the well-kept way to spread Python work over many machines: a scheduler, any
number of ``dask worker`` processes, a nanny that restarts a worker that dies and reschedules its
tasks, and plain TCP. flexopt needs nothing else from it: the design problem goes to every worker
once, as a worker plugin (re-installed on a worker the nanny restarts, which a scattered object is
not), and tasks carry only chunks of design vectors.

Connecting: distributed's ``Client(address, timeout=...)`` bounds only the TCP connect; it then
waits without a limit for the peer's handshake (a listener that never answers blocks for minutes)
and trusts the peer's first 8 bytes as a frame length (a web server's ``HTTP/1.0`` asks for an
allocation of exabytes: ``MemoryError``). So the address is first checked with a plain socket,
which reads the handshake every Dask server sends first and refuses anything else, and the whole
connection runs under one hard deadline (:data:`CONNECT_TIMEOUT_S`); whatever goes wrong is one
:class:`BackendError`.

Fault handling: a design that raises is a failed Evaluation (inside the task, like everywhere); a
worker that dies has its tasks rescheduled by the scheduler; a chunk that keeps killing workers
(``KilledWorker``) is split into single designs, a single design that does is tried once more
alone at the end of the batch (the scheduler also blames tasks merely queued on a dying worker),
and if it kills workers even then it is a failed row (``WorkerDied``). The time limit runs each
design in a thread and stops waiting for it after the limit: Dask cannot kill a running task, so
the stuck thread runs on until its solve returns (run the workers with ``--lifetime`` to recycle
them if that happens often). No wait is unbounded: a cluster left without any worker (or a
scheduler that stops answering) for :data:`NO_WORKER_TIMEOUT_S` is a :class:`BackendError`, since
the scheduler would otherwise keep the tasks queued for ever.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import os
import pickle
import queue
import socket
import struct
import threading
import time
import uuid
from collections.abc import Callable
from typing import Any, TypeVar

import numpy as np
from distributed import Client, KilledWorker, get_worker
from distributed.comm import connect as dask_connect
from distributed.comm.addressing import parse_address, parse_host_port
from distributed.diagnostics.plugin import WorkerPlugin
from distributed.protocol import loads as dask_loads
from distributed.protocol.utils import unpack_frames
from flexopt.optimise.evaluation import Evaluation
from flexopt.optimise.problem import DesignProblem
from flexopt.pipeline.errors import FlexoptError
from flexopt.pipeline.parallel import (
    DASK_CHUNKS_PER_WORKER,
    BackendError,
    chunk_rows,
    evaluate_one,
    one_line,
    timeout_reason,
)

__all__ = ["DaskBackend", "connect_limit_s"]

log = logging.getLogger(__name__)

T = TypeVar("T")

#: Seconds for the whole connection to the scheduler (TCP connect, handshake, registration), and
#: again for a first worker to join. ``FLEXOPT_DASK_CONNECT_TIMEOUT_S`` overrides it.
CONNECT_TIMEOUT_S = 20.0
CONNECT_TIMEOUT_ENV = "FLEXOPT_DASK_CONNECT_TIMEOUT_S"

#: Seconds the workers may take to load the problem (they import flexopt to unpickle it, which
#: takes seconds on a loaded machine; a worker that needs longer is stuck).
PLUGIN_TIMEOUT_S = 120.0

#: Seconds a batch waits while the cluster has no worker (or the scheduler does not answer)
#: before it gives up: long enough for nannies to restart killed workers on a loaded machine.
#: ``FLEXOPT_DASK_NO_WORKER_TIMEOUT_S`` overrides it.
NO_WORKER_TIMEOUT_S = 120.0
NO_WORKER_TIMEOUT_ENV = "FLEXOPT_DASK_NO_WORKER_TIMEOUT_S"

#: Seconds between checks of the cluster while no task finishes, and the limit of one such check.
POLL_S = 2.0

#: Seconds to wait for the client to disconnect and for a plugin or tasks to be dropped on close.
CLOSE_TIMEOUT_S = 10.0

#: The largest first frame accepted as a Dask handshake (a real one is about 100 bytes); more is
#: what HTTP or random bytes read as a length give.
MAX_HANDSHAKE_BYTES = 64 * 1024


def _seconds_from_env(name: str, default: float) -> float:
    """A positive number of seconds from the environment variable ``name`` (``default`` unset)."""
    text = os.environ.get(name, "").strip()
    if not text:
        return default
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise BackendError(f"{name}={text!r} is not a positive number of seconds")
    return value


def connect_limit_s() -> float:
    """The connect limit: ``FLEXOPT_DASK_CONNECT_TIMEOUT_S``, else :data:`CONNECT_TIMEOUT_S`."""
    return _seconds_from_env(CONNECT_TIMEOUT_ENV, CONNECT_TIMEOUT_S)


def _bounded(call: Callable[[], T], timeout_s: float) -> T:
    """``call()`` in a daemon thread; ``TimeoutError`` if it has not returned after ``timeout_s``.

    For distributed's blocking calls that take no timeout of their own: a call given up on runs on
    in its thread until the cluster answers or the client closes, holding nothing the run needs.
    """
    box: list[Any] = []
    errors: list[BaseException] = []

    def target() -> None:
        try:
            box.append(call())
        except BaseException as exc:  # handed to the caller's thread
            errors.append(exc)

    thread = threading.Thread(target=target, daemon=True, name="flexopt-dask-call")
    thread.start()
    thread.join(timeout_s)
    if thread.is_alive():
        raise TimeoutError(f"no answer within {timeout_s:g} s")
    if errors:
        raise errors[0]
    return box[0]


class Unreachable(FlexoptError):
    """The check of an address failed in a known way; the message says how, in plain words."""


def _recv_exactly(sock: socket.socket, n: int, deadline: float, what: str) -> bytes:
    """``n`` bytes from ``sock`` before ``deadline`` (``time.monotonic``)."""
    data = bytearray()
    while len(data) < n:
        left = deadline - time.monotonic()
        if left <= 0:
            raise TimeoutError(what)
        sock.settimeout(left)
        try:
            chunk = sock.recv(min(n - len(data), 65536))
        except TimeoutError:
            raise TimeoutError(what) from None
        if not chunk:
            if data:
                raise Unreachable(
                    f"it closed the connection after {len(data)} bytes of {n}: not a Dask scheduler"
                )
            raise Unreachable("it closed the connection without a Dask handshake")
        data += chunk
    return bytes(data)


def _check_handshake(address: str, deadline: float) -> None:
    """Connect to ``address`` with a plain socket and read the handshake a Dask server sends.

    Every Dask TCP server writes its handshake as soon as it accepts (before it reads anything):
    an 8-byte length, then that many bytes of frames (an 8-byte frame count, the
    frame lengths, msgpack). Anything else is refused here, before distributed would trust the
    length. Only ``tcp://`` (and a bare ``host:port``) is checked; other schemes (``tls://``)
    go straight to distributed, still under the deadline.
    """
    scheme, location = parse_address(address)
    if scheme != "tcp":
        return
    host, port = parse_host_port(location)
    try:
        infos = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
    except socket.gaierror as exc:
        raise Unreachable(f"host '{host}' not found: {exc.strerror or exc}") from None
    sock: socket.socket | None = None
    error: OSError | None = None
    for family, kind, proto, _name, sockaddr in infos:
        left = deadline - time.monotonic()
        if left <= 0:
            break
        candidate = socket.socket(family, kind, proto)
        candidate.settimeout(left)
        try:
            candidate.connect(sockaddr)
        except OSError as exc:
            candidate.close()
            error = exc
            continue
        sock = candidate
        break
    if sock is None:
        if isinstance(error, ConnectionRefusedError):
            raise Unreachable(f"connection refused: nothing listens at port {port}")
        raise error or TimeoutError("no TCP connection")
    with sock:
        silent = "connected, but no Dask handshake came"
        head = _recv_exactly(sock, 8, deadline, silent)
        if head.startswith(b"HTTP/"):
            raise Unreachable("it answered in HTTP: a web server, not a Dask scheduler")
        # distributed packs lengths in the native byte order ("Q"; little-endian on x86, ARM)
        (size,) = struct.unpack("Q", head)
        if not 16 <= size <= MAX_HANDSHAKE_BYTES:
            raise Unreachable(
                f"not a Dask scheduler: what it sent first is no Dask handshake (read as one, it "
                f"announces a message of {size:,} bytes)"
            )
        body = _recv_exactly(sock, size, deadline, silent)
        try:
            (n_frames,) = struct.unpack_from("Q", body)
            if not 1 <= n_frames <= 16 or 8 * (1 + n_frames) > size:
                raise ValueError(f"{n_frames:,} frames")
            message = dask_loads(unpack_frames(body), deserialize=False)
        except Exception as exc:
            raise Unreachable(
                f"not a Dask scheduler: its first message is no Dask handshake ({exc})"
            ) from None
        if not isinstance(message, dict) or "pickle-protocol" not in message:
            raise Unreachable("not a Dask scheduler: its first message is no Dask handshake")
    # A Dask worker's or nanny's address passes the handshake, and distributed's Client then
    # fails with a TypeError that does not say what is wrong: ask what the server is first.
    kind = asyncio.run(_server_type(address, deadline))
    if kind in ("Worker", "Nanny"):
        raise Unreachable(
            f"a Dask {kind.lower()} answers there, not the scheduler: give the address that "
            "`dask scheduler` prints"
        )


async def _server_type(address: str, deadline: float) -> str:
    """What the Dask server at ``address`` calls itself (its ``identity``: Scheduler, Worker)."""
    left = max(0.1, deadline - time.monotonic())
    comm = await asyncio.wait_for(dask_connect(address, timeout=left), left)
    try:
        await comm.write({"op": "identity", "reply": True})
        reply = await asyncio.wait_for(comm.read(), max(0.1, deadline - time.monotonic()))
    finally:
        comm.abort()
    return str(reply.get("type", "")) if isinstance(reply, dict) else ""


class FlexoptClient(Client):
    """A distributed Client that closes itself when its constructor fails.

    distributed leaves a client that failed to connect half-built, its event loop and periodic
    callbacks running; collected at interpreter exit, it blocks the exit for seconds and prints
    a traceback under the one-line error.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        try:
            super().__init__(*args, **kwargs)
        except BaseException:
            with contextlib.suppress(Exception):
                self.close(timeout=CLOSE_TIMEOUT_S)
            raise


def _connect(address: str, timeout_s: float) -> Client:
    """A client of the scheduler at ``address``, all of it within ``timeout_s``.

    Raises
    ------
    BackendError
        Whatever went wrong (no answer, refused, not Dask, any exception of distributed's), as
        the one-line "cannot reach" message.
    """
    deadline = time.monotonic() + timeout_s
    lock = threading.Lock()
    box: dict[str, Any] = {}

    def attempt() -> None:
        try:
            _check_handshake(address, deadline)
            client = FlexoptClient(
                address,
                timeout=max(0.5, deadline - time.monotonic()),
                set_as_default=False,  # flexopt submits through this client only
            )
        except BaseException as exc:  # worded here, for the waiting thread
            box["error"] = _what_happened(exc, timeout_s)
            return
        with lock:
            if not box.get("abandoned"):
                box["client"] = client
                return
        client.close(timeout=CLOSE_TIMEOUT_S)  # connected after the caller gave up

    # distributed waits for parts of the handshake without a limit: the attempt runs in a thread
    # that is given up on at the deadline (a moment later, so that its own timeouts speak first)
    thread = threading.Thread(target=attempt, daemon=True, name="flexopt-dask-connect")
    thread.start()
    thread.join(timeout_s + 0.5)
    with lock:
        box["abandoned"] = True
        if "client" in box:
            return box["client"]
    what = box.get("error") or f"no answer within {timeout_s:g} s"
    raise BackendError(
        f"cannot reach the Dask scheduler at {address} ({what}); check the address and that "
        "`dask scheduler` runs there"
    )


def _what_happened(exc: BaseException, timeout_s: float) -> str:
    """What went wrong connecting, in one line for the "cannot reach" message."""
    if isinstance(exc, TimeoutError):
        return one_line(f"no answer within {timeout_s:g} s: {exc}")
    if isinstance(exc, Unreachable):
        return one_line(str(exc))
    return one_line(f"{type(exc).__name__}: {exc}")


class ProblemPlugin(WorkerPlugin):
    """Holds the unpickled design problem on each worker (set up once per worker).

    Parameters
    ----------
    payload : bytes
        The pickled problem; unpickled in :meth:`setup`, on the worker.
    """

    def __init__(self, payload: bytes) -> None:
        self.payload = payload
        self.problem: DesignProblem | None = None

    def setup(self, worker: Any) -> None:
        self.problem = pickle.loads(self.payload)

    def teardown(self, worker: Any) -> None:
        self.problem = None


def _evaluate_with_limit(
    problem: DesignProblem, x: np.ndarray, timeout_s: float | None
) -> Evaluation:
    """:func:`evaluate_one` in a thread, abandoned after ``timeout_s`` (a task cannot be killed)."""
    if timeout_s is None:
        return evaluate_one(problem, x)
    box: list[Evaluation] = []
    thread = threading.Thread(
        target=lambda: box.append(evaluate_one(problem, x)), daemon=True, name="flexopt-eval"
    )
    thread.start()
    thread.join(timeout_s)
    if box:
        return box[0]
    n_obj, n_con = len(problem.objective_names), len(problem.constraint_names)
    return Evaluation.failed(x, n_obj, n_con, timeout_reason(timeout_s), timeout_s)


def evaluate_chunk(
    plugin: str, rows: list[int], X: np.ndarray, timeout_s: float | None
) -> list[tuple[int, Evaluation]]:
    """The Dask task: evaluate a chunk of designs with the worker's copy of the problem."""
    problem = get_worker().plugins[plugin].problem
    if problem is None:
        raise RuntimeError(f"worker plugin {plugin} holds no problem")
    pairs = zip(rows, X, strict=True)
    return [(row, _evaluate_with_limit(problem, x, timeout_s)) for row, x in pairs]


class DaskBackend:
    """Evaluate on the Dask cluster at ``address`` (or through an existing client).

    Parameters
    ----------
    problem : DesignProblem
        Sent once to every worker (a worker plugin).
    address : str
        Scheduler address, ``tcp://host:8786``.
    timeout_s : float, s, optional
        Time limit of one design.
    chunk_size : int, optional
        Designs per task (default: about four tasks per worker thread and batch).
    client : distributed.Client, optional
        Use this client instead of connecting to ``address`` (it is not closed here).
    connect_timeout_s : float, s, optional
        Limit of the connection, and of the wait for a first worker (default:
        :func:`connect_limit_s`).
    no_worker_timeout_s : float, s, optional
        How long a batch waits while the cluster has no worker (default:
        ``FLEXOPT_DASK_NO_WORKER_TIMEOUT_S``, else :data:`NO_WORKER_TIMEOUT_S`).

    Raises
    ------
    BackendError
        When the problem cannot be pickled, the scheduler cannot be reached, no worker joins,
        or the workers cannot load the problem (flexopt not installed there).
    """

    def __init__(
        self,
        problem: DesignProblem,
        address: str,
        timeout_s: float | None = None,
        chunk_size: int | None = None,
        client: Client | None = None,
        connect_timeout_s: float | None = None,
        no_worker_timeout_s: float | None = None,
    ) -> None:
        try:
            payload = pickle.dumps(problem, protocol=pickle.HIGHEST_PROTOCOL)
        except Exception as exc:
            raise BackendError(
                f"the design problem cannot be sent to Dask workers ({type(exc).__name__}: {exc})"
            ) from exc
        limit = connect_timeout_s if connect_timeout_s is not None else connect_limit_s()
        self.address = address
        self.timeout_s = timeout_s
        self.chunk_size = chunk_size
        self.no_worker_timeout_s = (
            no_worker_timeout_s
            if no_worker_timeout_s is not None
            else _seconds_from_env(NO_WORKER_TIMEOUT_ENV, NO_WORKER_TIMEOUT_S)
        )
        self.token = uuid.uuid4().hex[:12]
        self.plugin = f"flexopt-problem-{self.token}"
        self.n_batches = 0
        self._own_client = client is None
        self._n_threads = 1
        self._no_worker_since: float | None = None
        self.client = client or _connect(address, limit)
        try:
            _bounded(lambda: self.client.wait_for_workers(1, timeout=limit), limit + POLL_S)
        except TimeoutError:
            self.close()
            raise BackendError(
                f"no Dask worker joined the scheduler at '{address}' within "
                f"{limit:g} s; start workers with `dask worker {address}`"
            ) from None
        except Exception as exc:
            self.close()
            raise BackendError(
                f"the Dask scheduler at {address} failed while flexopt waited for a worker "
                f"({type(exc).__name__}: {one_line(str(exc))})"
            ) from None
        try:
            _bounded(
                lambda: self.client.register_plugin(ProblemPlugin(payload), name=self.plugin),
                PLUGIN_TIMEOUT_S,
            )
        except TimeoutError:
            self.close()
            raise BackendError(
                f"Dask workers did not load the design problem within {PLUGIN_TIMEOUT_S:g} s; "
                "check that they run and have flexopt (same version) installed"
            ) from None
        except Exception as exc:
            self.close()
            raise BackendError(
                f"Dask workers cannot load the design problem ({type(exc).__name__}: {exc}); "
                "install flexopt (same version) on every worker"
            ) from None

    def _workers(self) -> dict[str, Any] | None:
        """The scheduler's workers now, or None when it does not answer within :data:`POLL_S`."""
        try:
            info = _bounded(self.client.scheduler_info, POLL_S)
        except Exception:  # no answer, or the client lost the scheduler: the caller counts time
            log.debug("the Dask scheduler did not answer", exc_info=True)
            return None
        return dict(info.get("workers", {}))

    @property
    def n_threads(self) -> int:
        """Worker threads in the cluster now (at least 1; the last count if no answer)."""
        workers = self._workers()
        if workers:
            self._n_threads = max(1, sum(int(w.get("nthreads", 1)) for w in workers.values()))
        return self._n_threads

    def _check_cluster(self) -> None:
        """Raise BackendError when the cluster has had no worker for the no-worker limit.

        The scheduler keeps the tasks of a cluster without workers queued for ever (workers may
        join later), so this is the only thing that ends such a wait.
        """
        workers = self._workers()
        now = time.monotonic()
        if workers:
            self._no_worker_since = None
            return
        if self._no_worker_since is None:
            self._no_worker_since = now
            log.warning("the Dask cluster at %s has no worker; waiting for one", self.address)
        elif now - self._no_worker_since >= self.no_worker_timeout_s:
            why = "no worker" if workers is not None else "no answer from the scheduler"
            raise BackendError(
                f"the Dask cluster at {self.address} has had {why} for "
                f"{self.no_worker_timeout_s:g} s (workers died or left); start workers and "
                "resume the run"
            )

    def _next_done(self, finished: queue.SimpleQueue[Any]) -> Any:
        """The next future that finished (or erred, or was cancelled), checking the cluster."""
        while True:
            try:
                future = finished.get(timeout=POLL_S)
            except queue.Empty:
                self._check_cluster()
                continue
            self._no_worker_since = None
            return future

    def _result(self, future: Any) -> list[tuple[int, Evaluation]]:
        """The result of a finished task; fetching it may mean recomputing it (its worker died)."""
        while True:
            try:
                return future.result(timeout=POLL_S)
            except TimeoutError:
                if future.status == "error":  # the task itself raised TimeoutError
                    raise
                self._check_cluster()

    def close(self) -> None:
        """Remove the problem from the workers and disconnect (an own client only)."""
        client = getattr(self, "client", None)
        if client is None:
            return
        try:
            if client.status == "running":
                _bounded(lambda: client.unregister_worker_plugin(self.plugin), CLOSE_TIMEOUT_S)
        except Exception:  # the plugin may not exist (failed set-up); closing must go on
            log.debug("unregistering %s failed", self.plugin, exc_info=True)
        if self._own_client:
            try:
                client.close(timeout=CLOSE_TIMEOUT_S)
            except Exception:  # a scheduler gone or stuck: the client's threads end with us
                log.debug("closing the Dask client failed", exc_info=True)

    def __call__(
        self,
        problem: DesignProblem,
        X: np.ndarray,
        on_result: Callable[[int, Evaluation], None] | None = None,
    ) -> list[Evaluation]:
        """Evaluate (m, n_var) designs on the cluster; returns m Evaluations in order.

        Raises
        ------
        BackendError
            When the cluster has no worker for the no-worker limit, or a task is lost
            (cancelled: the scheduler went away) or fails outside the design's evaluation.
        """
        X = np.atleast_2d(np.asarray(X, dtype=float))
        n_obj, n_con = len(problem.objective_names), len(problem.constraint_names)
        results: list[Evaluation | None] = [None] * len(X)
        size = chunk_rows(len(X), self.n_threads, self.chunk_size, DASK_CHUNKS_PER_WORKER)
        self.n_batches += 1
        self._no_worker_since = None
        tasks: dict[Any, list[int]] = {}
        # done callbacks feed this queue: a wait on it can time out and check the cluster,
        # where as_completed or Future.result would wait for ever on a cluster without workers
        finished: queue.SimpleQueue[Any] = queue.SimpleQueue()
        n_tasks = 0

        def submit(rows: list[int]) -> Any:
            nonlocal n_tasks
            n_tasks += 1
            future = self.client.submit(
                evaluate_chunk,
                self.plugin,
                rows,
                X[rows],
                self.timeout_s,
                pure=False,
                key=f"flexopt-{self.token}-{self.n_batches}-{n_tasks}",
            )
            tasks[future] = rows
            future.add_done_callback(finished.put)
            return future

        def record(done: list[tuple[int, Evaluation]]) -> None:
            for row, evaluation in done:
                if results[row] is None:
                    results[row] = evaluation
                    if on_result is not None:
                        on_result(row, evaluation)

        def collect(future: Any) -> bool:
            """Record a finished task; False when it killed workers (KilledWorker)."""
            try:
                record(self._result(future))
            except KilledWorker:
                return False
            except BackendError:
                raise
            except Exception as exc:  # cancelled (the scheduler went away) or a broken worker
                raise BackendError(
                    f"the Dask cluster at {self.address} lost a task "
                    f"({type(exc).__name__}: {one_line(str(exc))}); check the scheduler and "
                    "the workers, then resume the run"
                ) from None
            return True

        for start in range(0, len(X), size):
            submit(list(range(start, min(start + size, len(X)))))
        suspects: list[int] = []
        try:
            while tasks:
                future = self._next_done(finished)
                rows = tasks.pop(future)
                if collect(future):
                    continue
                # The scheduler blames every task on a worker that dies, also those only
                # queued there: split a chunk into single designs, and try a single one
                # again alone at the end, where only the design that kills is blamed.
                if len(rows) > 1:
                    log.warning("a chunk kept killing Dask workers; resubmitting its designs")
                    for row in rows:
                        submit([row])
                else:
                    suspects.append(rows[0])
            for row in suspects:
                submit([row])
                future = self._next_done(finished)
                tasks.pop(future)
                if not collect(future):
                    failed = Evaluation.failed(
                        X[row],
                        n_obj,
                        n_con,
                        "WorkerDied: Dask workers died while evaluating this design alone "
                        "(KilledWorker)",
                    )
                    record([(row, failed)])
        except BaseException:
            # Ctrl-C or a broken cluster: stop what is queued (bounded: the scheduler may be gone)
            pending = list(tasks)
            try:
                _bounded(lambda: self.client.cancel(pending), CLOSE_TIMEOUT_S)
            except Exception:
                log.debug("cancelling the Dask tasks failed", exc_info=True)
            raise
        missing = [row for row, ev in enumerate(results) if ev is None]
        if missing:
            raise BackendError(f"the Dask cluster returned no result for designs {missing}")
        return [ev for ev in results if ev is not None]
