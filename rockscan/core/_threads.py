"""One BLAS thread inside rockscan's numeric entry points, so results never depend on it.

A multi-threaded BLAS splits a matrix product into blocks whose partial sums
are added in an order that depends on the thread count: ``vectors.T @ centered``
of the eigenface fit, for one, differs in the last bits at 1 and 2 OpenBLAS
threads, and those bits reach ``classify --json``. rockscan's matrices are small
and it runs photos in parallel itself, so one BLAS thread costs nothing and
makes every number the same at any ``OPENBLAS_NUM_THREADS``, in a subprocess or
in a process that loaded numpy long before.

:func:`one_blas_thread` limits every BLAS library threadpoolctl knows while any
thread is inside a decorated function (nested and concurrent calls share one
limit, counted under a lock) and puts the user's setting back when the last one
leaves; a library whose count belongs to each thread (OpenMP's) is limited in
each calling thread. The libraries are found once per process (about a
millisecond); entering and leaving costs some 20 microseconds, under a
thousandth of a photo (scripts/bench_blas_limit.py).
"""

from __future__ import annotations

import functools
import threading
from collections.abc import Callable
from typing import Any, TypeVar

F = TypeVar("F", bound=Callable[..., Any])

_lock = threading.Lock()
_shared_depth = 0
_shared_saved: list[tuple[Any, int]] = []
_local = threading.local()
_libraries: tuple[list[Any], list[Any]] | None = None


def _blas() -> tuple[list[Any], list[Any]]:
    """The BLAS libraries of this process: those with one process-wide thread count,
    and those whose count belongs to each calling thread (OpenMP's)."""
    global _libraries
    if _libraries is None:
        # Load the BLAS libraries rockscan calls before looking them up: numpy's and
        # SciPy's (scipy.special links SciPy's own OpenBLAS).
        import numpy  # noqa: F401
        import scipy.special  # noqa: F401
        from threadpoolctl import ThreadpoolController

        found = ThreadpoolController().select(user_api="blas").lib_controllers
        per_thread = [lib for lib in found if getattr(lib, "threading_layer", None) == "openmp"]
        _libraries = ([lib for lib in found if lib not in per_thread], per_thread)
    return _libraries


def _set(lib: Any, count: int) -> None:
    # threadpoolctl lets only the first Python thread that limits OpenBLAS change it
    # later; rockscan counts its own callers under a lock, so it sets the count itself.
    getattr(lib, "_real_set_num_threads", lib.set_num_threads)(count)


def _limit(libraries: list[Any]) -> list[tuple[Any, int]]:
    saved = [(lib, lib.get_num_threads() or 1) for lib in libraries]
    for lib, count in saved:
        if count != 1:
            _set(lib, 1)
    return saved


def _restore(saved: list[tuple[Any, int]]) -> None:
    for lib, count in saved:
        if count != 1:
            _set(lib, count)


def _enter() -> None:
    global _shared_depth, _shared_saved
    depth = getattr(_local, "depth", 0)
    if depth == 0:
        shared, per_thread = _blas()
        _local.saved = _limit(per_thread)
        with _lock:
            if _shared_depth == 0:
                _shared_saved = _limit(shared)
            _shared_depth += 1
    _local.depth = depth + 1


def _leave() -> None:
    global _shared_depth, _shared_saved
    _local.depth -= 1
    if _local.depth == 0:
        with _lock:
            _shared_depth -= 1
            if _shared_depth == 0:
                _restore(_shared_saved)
                _shared_saved = []
        _restore(_local.saved)


def one_blas_thread(func: F) -> F:
    """Run ``func`` with every BLAS library limited to one thread (see the module's notes)."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        _enter()
        try:
            return func(*args, **kwargs)
        finally:
            _leave()

    return wrapper  # type: ignore[return-value]


def blas_threads() -> int:
    """The largest thread count among the BLAS libraries now (1 inside a decorated call).

    The largest, because a library built for one thread reports 1 whatever it is told.
    """
    shared, per_thread = _blas()
    counts = [lib.get_num_threads() or 1 for lib in (*shared, *per_thread)]
    return max(counts) if counts else 1
