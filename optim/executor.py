"""Where design points are evaluated: behind :class:`concurrent.futures.Executor`.

* ``"local"`` (default): a :class:`~concurrent.futures.ProcessPoolExecutor` on this machine —
  no server, lowest overhead for independent evaluations;
* ``"inline"``: in the calling thread (tests, benchmarks, debugging);
* ``"tcp://host:port"``: a Dask cluster, through ``Client(address).get_executor()``.

The results do not depend on the choice: each evaluation is a pure function of its task.
Dask's LocalCluster needs the ``if __name__ == "__main__":`` guard that ``optim/cli/__init__.py`` has.
"""

from __future__ import annotations

import atexit
import contextlib
import multiprocessing
import os
import re
import sys
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import Executor, Future, ProcessPoolExecutor
from typing import Any

from hapticopt.analysis.compute import Compute
from hapticopt.design.errors import InvalidInput, short


class InlineExecutor(Executor):
    """Runs each submitted call at once in the caller's thread (an Executor with no workers)."""

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future:
        future: Future = Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except BaseException as exc:  # noqa: BLE001 - delivered through the future
            future.set_exception(exc)
        return future


def watch_parent(parent_pid: int, period_s: float = 0.5) -> None:
    """In a child process: exit at once when ``parent_pid`` is gone (even after a SIGKILL).

    A daemon thread polls the parent id (re-parenting is how Linux reports the parent's death);
    pool workers and the verification child call it first, so none outlives its run by more
    than ``period_s``.
    """

    def watch() -> None:
        while True:
            if os.getppid() != parent_pid:
                os._exit(70)  # EX_SOFTWARE: the run that owned this process is gone
            time.sleep(period_s)

    threading.Thread(target=watch, name="hapticopt-watch-parent", daemon=True).start()


def end_process(code: int) -> None:
    """End this process with status ``code`` without the interpreter's module teardown: flush
    stdout and stderr, then ``os._exit``. Call it from an exit handler registered first (it then runs
    after every other one: pool joins, log flushes) — :func:`skip_teardown_at_exit`.

    The teardown frees every module's objects one by one, which takes seconds with build123d (OpenCASCADE)
    or jax loaded (docs/performance.md). Nothing of ours needs it: files and databases are closed by then.
    """
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except Exception:  # noqa: BLE001 - a closed or broken stream: nothing left to flush
            pass
    os._exit(code)


def skip_teardown_at_exit(status: Callable[[], int | None]) -> None:
    """Register :func:`end_process` as this process's exit handler, ending with ``status()``; where that
    is None the interpreter ends as usual. Register it before anything else: exit handlers run in
    reverse order, so the others (joins, flushes) still run first, and only the module teardown
    is skipped."""

    def end() -> None:
        code = status()
        if code is not None:
            end_process(code)

    atexit.register(end)


def start_child(parent_pid: int) -> None:
    """First call in every child process of a run (pool workers, the side process, the verification
    worker): :func:`watch_parent`, and an end without the module teardown (:func:`skip_teardown_at_exit`,
    status 0: a child reaches its exit handlers only when its loop has returned — the stdlib pool's
    worker loop and :func:`hapticopt.optim.worker._serve` — since a crash by a signal runs none). How
    many kernel threads its work uses is the :class:`Compute` the work is handed (:func:`worker_compute`)."""
    watch_parent(parent_pid)
    skip_teardown_at_exit(lambda: 0)


def worker_compute(executor: Any, compute: Compute) -> Compute:
    """The :class:`Compute` for work handed to ``executor``: the caller's own where the work runs in the
    calling thread (:class:`InlineExecutor`), else one kernel thread with the caller's backend (a pool's
    workers, local or Dask, and a run's other child processes share the CPUs among themselves)."""
    if isinstance(executor, InlineExecutor):
        return compute
    return Compute(backend=compute.backend, threads=1)


def default_workers() -> int:
    return max(1, min(4, os.cpu_count() or 1))


def worker_count(executor: Executor) -> int:
    """How many evaluations ``executor`` can run at once (1 for inline)."""
    if isinstance(executor, InlineExecutor):
        return 1
    n = getattr(executor, "_max_workers", None)
    if isinstance(n, int):
        return n
    client = getattr(executor, "_client", None)
    if client is not None:
        try:
            return max(1, sum(w.get("nthreads", 1) for w in client.scheduler_info()["workers"].values()))
        except Exception:  # noqa: BLE001 - a count is only a hint
            return 2
    return 2


_ADDRESS_RE = re.compile(r"^(tcp|tls|inproc|ucx)://[A-Za-z0-9_.\-\[\]:]{1,253}:[0-9]{1,5}$")


def check_scheduler(scheduler: str) -> None:
    """Raise one line unless ``scheduler`` is local, inline or a Dask address SCHEME://HOST:PORT."""
    if scheduler in ("local", "inline"):
        return
    if not isinstance(scheduler, str) or not _ADDRESS_RE.match(scheduler):
        raise InvalidInput(f"--scheduler = {short(scheduler)} is not allowed: use local, inline or a Dask address "
                           "tcp://HOST:PORT")


@contextlib.contextmanager
def make_executor(scheduler: str = "local", *, workers: int | None = None) -> Iterator[Executor]:
    """An executor for ``scheduler`` ("local", "inline" or a Dask address ``tcp://…``), closed on exit."""
    check_scheduler(scheduler)
    if scheduler == "inline":
        yield InlineExecutor()
        return
    if scheduler == "local":
        # forkserver/spawn: a forked jax runtime is not safe
        ctx = multiprocessing.get_context("spawn")
        pool = ProcessPoolExecutor(max_workers=workers or default_workers(), mp_context=ctx,
                                   initializer=start_child, initargs=(os.getpid(),))
        try:
            yield pool
        finally:
            pool.shutdown(wait=True, cancel_futures=True)
        return
    if "://" in scheduler:
        try:
            from distributed import Client
        except ImportError:  # pragma: no cover - dask[distributed] is a dependency
            raise InvalidInput("--scheduler: dask.distributed is not installed") from None
        try:
            client = Client(scheduler, timeout="10s")
        except (OSError, TimeoutError, ValueError) as exc:
            raise InvalidInput(f"--scheduler = {scheduler!r}: cannot reach the Dask scheduler: {exc}") from None
        try:
            executor = client.get_executor()
            executor._client = client  # type: ignore[attr-defined]  # for worker_count
            yield executor
        finally:
            client.close()
        return
    raise InvalidInput(f"--scheduler = {scheduler!r} is not allowed: use local, inline or a Dask address tcp://HOST:PORT")
