"""Where a triage's photos are classified: worker processes on this machine or a
Dask distributed cluster, with at most a window of photos in flight.

A worker that dies takes no photo with it: the photos it may have held are
tried again one at a time, and the one that kills a worker again gets an
error row. Workers end with the process that started them.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import logging
import os
import signal
import sys
import threading
import time
from collections import deque
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, Any

from rockscan.core.errors import ParameterError
from rockscan.run.pipeline import ClassifyConfig

if TYPE_CHECKING:
    from rockscan.core.library import Library

from rockscan.run.photo import PhotoOutcome, photo_outcome

_WORKER: dict[str, Any] = {}


def _die_with_parent(parent: int | None) -> None:
    """End this worker when the process that started the pool ends (kill -9 included)."""
    if sys.platform.startswith("linux"):
        import ctypes

        # Sent when the process that forked this one ends: the triage itself, or
        # the fork server, which ends with the triage.
        with contextlib.suppress(OSError, AttributeError):
            pr_set_pdeathsig = 1
            ctypes.CDLL(None, use_errno=True).prctl(pr_set_pdeathsig, int(signal.SIGKILL), 0, 0, 0)
    if parent is None:
        return
    # The parent may have died before the signal was asked for.
    if not _alive(parent):
        os._exit(1)
    if not sys.platform.startswith("linux"):
        import threading

        def watch() -> None:
            while _alive(parent):
                time.sleep(1.0)
            os._exit(1)

        threading.Thread(target=watch, daemon=True, name="rockscan-parent-watch").start()


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # another user's process of that number: it exists
        return True
    return True


def _init_worker(
    library: Library, config: ClassifyConfig, thumbnail_size: int, all_rocks: bool, parent: int | None
) -> None:
    _die_with_parent(parent)
    # Ctrl-C is the parent's to handle: it finishes the report, then stops.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _WORKER.update(library=library, config=config, thumbnail_size=thumbnail_size, all_rocks=all_rocks)


def _pool_work(path: str) -> PhotoOutcome:
    return photo_outcome(
        path, _WORKER["library"], _WORKER["config"], _WORKER["thumbnail_size"], _WORKER["all_rocks"]
    )


class _ProcessBackend:
    """Worker processes on this machine; restartable after a worker dies.

    Workers are forked where that is safe (Linux, and no other thread in this
    process): they start at once, sharing the library already in memory.
    Elsewhere they start from a fork server that has rockscan loaded. Each
    worker ends with the process that started it (a parent-death signal on
    Linux, a watch of the parent elsewhere), so a killed triage leaves no
    orphans.
    """

    def __init__(
        self,
        n_workers: int,
        fn: Callable[[str], PhotoOutcome],
        initializer: Callable[..., None] | None,
        initargs: tuple[Any, ...],
        context: str | None = None,
    ) -> None:
        import multiprocessing
        import threading

        if context is None:
            safe_fork = sys.platform.startswith("linux") and threading.active_count() == 1
            context = "fork" if safe_fork else "forkserver"
        self.slots = n_workers
        self._args = (fn, initializer, initargs)
        self._context = multiprocessing.get_context(context)
        if context == "forkserver":
            self._context.set_forkserver_preload(["rockscan.run.triage"])
        self._executor = self._start()

    def _start(self) -> cf.ProcessPoolExecutor:
        _, initializer, initargs = self._args
        return cf.ProcessPoolExecutor(
            self.slots, mp_context=self._context, initializer=initializer, initargs=initargs
        )

    def submit(self, path: str) -> cf.Future[PhotoOutcome]:
        return self._executor.submit(self._args[0], path)

    def restart(self) -> None:
        self._executor.shutdown(wait=False, cancel_futures=True)
        self._executor = self._start()

    def check(self) -> None:
        """Local workers cannot go away unnoticed (the pool breaks)."""

    def close(self) -> None:
        self._executor.shutdown(wait=True, cancel_futures=True)


#: Address schemes a Dask scheduler on another process can be reached by.
_DASK_SCHEMES = ("tcp", "tls", "ws", "wss", "ucx")


def check_scheduler_address(address: str) -> None:
    """Refuse an address that cannot work before any connection is tried
    (distributed would fail late, and leave a half-made client behind)."""
    scheme, sep, rest = address.partition("://")
    if not sep:
        scheme, rest = "tcp", address
    scheme = scheme.lower()
    hint = "give the scheduler's address, such as tcp://host:8786"
    if scheme == "inproc":
        # inproc://host/pid/n: a scheduler of this very process (a LocalCluster without processes).
        parts = rest.split("/")
        if len(parts) == 3 and parts[1] == str(os.getpid()):
            return
        raise ParameterError(
            f"--scheduler {address}: inproc:// reaches only a scheduler inside this process; {hint}"
        )
    if scheme not in _DASK_SCHEMES:
        raise ParameterError(
            f"--scheduler {address}: unknown address scheme {scheme!r} "
            f"(known: {', '.join(s + '://' for s in _DASK_SCHEMES)}); {hint}"
        )
    if not rest or rest.startswith(":"):
        raise ParameterError(f"--scheduler {address}: no host in the address; {hint}")
    host, colon, port = rest.rstrip("/").rpartition(":")
    if scheme in ("tcp", "tls") and not (colon and host and port.isdigit() and 0 < int(port) < 65536):
        # distributed says so only after a client is half made, whose
        # clean-up then waits out its timeout (a minute) as the command ends.
        raise ParameterError(f"--scheduler {address}: no port in the address; {hint}")
    if scheme in ("tls", "wss"):
        from distributed.security import Security

        if Security().get_connection_args("client").get("ssl_context") is None:
            raise ParameterError(
                f"--scheduler {address}: {scheme}:// needs TLS certificates; set them in the Dask "
                "configuration (distributed.comm.tls.ca-file, .client.cert, .client.key)"
            )


class _DaskBackend:
    """Workers of a Dask distributed cluster.

    A worker lost mid-run costs nothing: the scheduler runs its photos again
    on another. A lost scheduler ends the run at once with a clear error (the
    rows so far are kept), never a hang.
    """

    def __init__(
        self,
        address: str,
        library: Library,
        config: ClassifyConfig,
        thumbnail_size: int,
        timeout_s: float,
        all_rocks: bool = False,
    ) -> None:
        try:
            from distributed import Client
        except ImportError:
            raise ParameterError("--scheduler needs dask.distributed: pip install 'rockscan[dask]'") from None
        check_scheduler_address(address)
        self.address = address
        # distributed logs a traceback for every failed reconnection: the run says it once.
        self._quiet = _QuietLogger("distributed")
        try:
            self._client = Client(address, timeout=f"{timeout_s}s", set_as_default=False)
        except (OSError, TimeoutError, ValueError, TypeError) as exc:
            self._quiet.restore()
            raise ParameterError(f"cannot reach the Dask scheduler at {address} ({exc})") from None
        # The library travels to each worker once, not with every photo.
        library_future = self._client.scatter(library, broadcast=True, hash=False)
        self._executor = self._client.get_executor(pure=False)
        self._args = (library_future, config, thumbnail_size, all_rocks)
        self.slots = max(1, sum(self._client.nthreads().values()))

    def submit(self, path: str) -> cf.Future[PhotoOutcome]:
        self.check()
        return self._executor.submit(photo_outcome, path, *self._args)

    def check(self) -> None:
        """Raise if the scheduler is gone."""
        status = getattr(self._client.status, "value", self._client.status)
        if status != "running":
            raise ParameterError(
                f"lost the Dask scheduler at {self.address} (client {status}); the rows so far are kept: "
                "run again with --resume"
            )

    def restart(self) -> None:
        """A Dask cluster replaces lost workers itself; futures are cancelled
        only when the scheduler is lost."""
        self.check()

    def close(self) -> None:
        with contextlib.suppress(Exception):
            self._executor.shutdown(wait=False)
        with contextlib.suppress(Exception):
            self._client.close(timeout=2)
        self._quiet.restore()


class _QuietLogger:
    """Silence a library's loggers (the named one and its children) for a while,
    then put their levels back."""

    def __init__(self, name: str) -> None:
        names = [name, *(n for n in logging.root.manager.loggerDict if n.startswith(name + "."))]
        self._levels = {n: logging.getLogger(n).level for n in names}
        for n in names:
            logging.getLogger(n).setLevel(logging.CRITICAL + 1)

    def restore(self) -> None:
        for n, level in self._levels.items():
            logging.getLogger(n).setLevel(level)


#: How long to wait for a photo before asking the backend whether it is alive, seconds.
_POLL_S = 2.0

#: How often a run waiting on its photos looks for a held Ctrl-C, seconds.
_WAKE_S = 0.2


@contextlib.contextmanager
def held_interrupts() -> Iterator[threading.Event]:
    """Hold Ctrl-C (and a SIGTERM that a handler turns into one) until a safe point.

    A ``KeyboardInterrupt`` raised inside the executor's own bookkeeping
    (``submit``, ``wait``) can leave its shutdown waiting forever. While this
    context is open, the first signal only sets the event it yields; the run
    raises ``KeyboardInterrupt`` itself at its next check. A second signal
    raises at once, for a user who will not wait. Outside the main thread
    (where signals cannot be handled) the event is never set.

    Yields
    ------
    threading.Event
        Set when a signal has been held.
    """
    held = threading.Event()
    if threading.current_thread() is not threading.main_thread():
        yield held
        return

    def hold(signum: int, frame: Any) -> None:
        if held.is_set():
            raise KeyboardInterrupt
        held.set()

    previous = {}
    # Only signals that would raise KeyboardInterrupt are held: an ignored
    # Ctrl-C stays ignored, and a SIGTERM without a handler still ends the process.
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        previous[signal.SIGINT] = signal.signal(signal.SIGINT, hold)
    if callable(signal.getsignal(signal.SIGTERM)):
        previous[signal.SIGTERM] = signal.signal(signal.SIGTERM, hold)
    try:
        yield held
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)


def _run_backend(
    paths: list[str],
    backend: Any,
    window: int,
    *,
    ordered: bool,
    stop: threading.Event | None = None,
) -> Iterator[tuple[int, PhotoOutcome]]:
    """Outcomes of ``paths`` as (index, outcome): as they finish, or in order.

    At most ``window`` photos are in flight or waiting their turn, so memory
    stays flat however many photos there are. If a worker process dies (the
    pool breaks), the photos it may have been working on are tried again one
    at a time in a new pool: the one that breaks it again gets an error row.
    A backend that cannot go on (a lost scheduler) raises from ``check`` or
    ``restart``. When ``stop`` is set (:func:`held_interrupts`), the run
    raises ``KeyboardInterrupt`` between photos, outside the backend's calls.
    """
    pending: dict[cf.Future[PhotoOutcome], int] = {}
    ready: dict[int, PhotoOutcome] = {}
    suspects: deque[int] = deque()
    isolating = False
    next_new = next_out = 0

    def fill() -> None:
        nonlocal next_new
        if suspects:
            if not pending:
                i = suspects.popleft()
                pending[backend.submit(paths[i])] = i
            return
        while next_new < len(paths) and len(pending) + len(ready) < window:
            pending[backend.submit(paths[next_new])] = next_new
            next_new += 1

    def held() -> None:
        if stop is not None and stop.is_set():
            raise KeyboardInterrupt

    held()
    fill()
    idle_since = time.monotonic()
    while pending:
        held()
        done, _ = cf.wait(pending, timeout=_WAKE_S, return_when=cf.FIRST_COMPLETED)
        if not done:
            if time.monotonic() - idle_since >= _POLL_S:
                backend.check()
                idle_since = time.monotonic()
            continue
        idle_since = time.monotonic()
        broken = []
        finished: list[tuple[int, PhotoOutcome]] = []
        for future in done:
            i = pending.pop(future)
            try:
                finished.append((i, future.result()))
            except (cf.BrokenExecutor, cf.CancelledError):
                broken.append(i)
            except Exception as exc:  # a worker lost by the cluster, an unpicklable result, ...
                finished.append((i, PhotoOutcome({"path": paths[i], "error": f"worker failed: {exc}"})))
        if broken:
            lost = sorted(broken + list(pending.values()))
            pending.clear()
            backend.restart()
            if isolating:
                # Alone in the pool, this photo is what kills the worker.
                (culprit,) = broken
                message = (
                    "the worker process died on this photo (out of memory, or a crash while decoding it)"
                )
                finished.append((culprit, PhotoOutcome({"path": paths[culprit], "error": message})))
                lost = [i for i in lost if i != culprit]
            suspects.extend(i for i in lost if i not in suspects)
        isolating = bool(suspects)
        for i, outcome in sorted(finished, key=lambda item: item[0]):
            if ordered:
                ready[i] = outcome
            else:
                yield i, outcome
        while ordered and next_out in ready:
            yield next_out, ready.pop(next_out)
            next_out += 1
        fill()
