"""One long-lived child process that runs calls one after another, each under a time limit.

The pipeline's verify stage ran each scene in a process of its own so that a scene that hangs,
segfaults or exhausts memory could not take the run down; every scene then paid a process
start-up (seconds of imports, against milliseconds of simulation). :class:`SupervisedWorker` keeps that
safety with one process: it runs the calls in turn; a call that outlives its limit gets the
process killed, a process that dies (a signal, ``os._exit``, the OOM killer) is noticed at once
(its sentinel), and either way the call is reported as a value (:class:`Outcome`) and the next
call starts a fresh process. The process starts with :meth:`SupervisedWorker.start` — the pipeline
starts it before the optimisation so that its imports overlap with it — and dies with its parent
(:func:`hapticopt.optim.executor.watch_parent`, and the run's reaper while it imports).
"""

from __future__ import annotations

import multiprocessing
import os
import signal
from collections.abc import Callable
from multiprocessing.connection import wait
from typing import Any, NamedTuple

from hapticopt.optim.executor import start_child


class Outcome(NamedTuple):
    """What became of one call: ``kind`` "ok" (``value`` is its return value), "error" (it raised:
    ``message`` is ``Type: message``), "timeout" (killed after the limit) or "crashed" (the process died)."""

    kind: str
    value: Any
    message: str


def _serve(conn: Any, parent_pid: int, warm: Callable[[], Any] | None) -> None:
    """Child process: run ``(fn, args)`` messages until ``None`` (or the parent is gone)."""
    start_child(parent_pid)
    if warm is not None:
        warm()
    conn.send(("ready", None, ""))
    while True:
        try:
            msg = conn.recv()
        except (EOFError, OSError):
            return
        if msg is None:
            return
        fn, args = msg
        try:
            out = ("ok", fn(*args), "")
        except Exception as exc:  # noqa: BLE001 - sent to the parent as a value
            out = ("error", None, f"{type(exc).__name__}: {exc}")
        try:
            conn.send(out)
        except Exception as exc:  # noqa: BLE001 - e.g. an unpicklable result
            conn.send(("error", None, f"the result could not be sent back: {type(exc).__name__}: {exc}"))


def describe_exit(code: int | None) -> str:
    """``exit code 3`` / ``killed by SIGSEGV`` for a process's exit code."""
    if code is None:
        return "no exit code"
    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit code {code}"


#: how long a process may take to start (imports, ``warm``) before it counts as crashed [s]
STARTUP_TIMEOUT_S = 300.0


class SupervisedWorker:
    """A single child process (spawned: a forked jax runtime is not safe) that runs calls in turn.

    ``warm``: a picklable function the process runs once at start (imports, caches), before any call.
    A call's time limit starts once the process is ready: start-up (at most ``startup_timeout_s``) is
    not charged to the call. Use as a context manager or call :meth:`close`. Not thread-safe.
    """

    def __init__(self, *, warm: Callable[[], Any] | None = None, startup_timeout_s: float = STARTUP_TIMEOUT_S) -> None:
        self._warm = warm
        self._startup_timeout_s = startup_timeout_s
        self._ready = False
        self._ctx = multiprocessing.get_context("spawn")
        self._proc: Any = None
        self._conn: Any = None
        self.starts = 0  # processes started (a restart after a timeout or crash counts)
        self.last_exitcode: int | None = None  # of the last process that ended

    def start(self) -> "SupervisedWorker":
        """Start the process now (no-op while one runs)."""
        if self._proc is None:
            parent, child = self._ctx.Pipe()
            self._proc = self._ctx.Process(target=_serve, args=(child, os.getpid(), self._warm), daemon=True,
                                           name="hapticopt-worker")
            self._proc.start()
            child.close()
            self._conn = parent
            self.starts += 1
        return self

    def call(self, fn: Callable[..., Any], args: tuple[Any, ...], *, timeout_s: float) -> Outcome:
        """Run ``fn(*args)`` in the process, at most ``timeout_s`` [s] once the process is ready."""
        if self._proc is not None and not self._proc.is_alive():  # it died between calls: start afresh
            self._discard()
        self.start()
        if not self._ready:
            started = self._answer(self._startup_timeout_s, "start-up")
            if started.kind != "ready":
                return started
            self._ready = True
        try:
            self._conn.send((fn, args))
        except (BrokenPipeError, ConnectionError, OSError):  # it died since the last call
            return self._answer(0.0, "call")
        return self._answer(timeout_s, "call")

    def _answer(self, timeout_s: float, what: str) -> Outcome:
        """The next message from the process, or what became of it within ``timeout_s``."""
        ready = wait([self._conn, self._proc.sentinel], timeout=timeout_s)
        if self._conn in ready:
            try:
                kind, value, message = self._conn.recv()
                return Outcome(kind, value, message)
            except (EOFError, OSError):
                pass  # the process died while answering
        if not ready:
            self._discard()
            return Outcome("timeout", None, f"no result within {timeout_s:g} s: the worker process was killed"
                           + (" during its start-up" if what == "start-up" else ""))
        self._proc.join(1.0)
        why = describe_exit(self._proc.exitcode)
        self._discard()
        return Outcome("crashed", None, f"the worker process died ({why})"
                       + (" during its start-up" if what == "start-up" else ""))

    def _discard(self) -> None:
        proc, conn = self._proc, self._conn
        self._proc = self._conn = None
        self._ready = False
        if proc is not None:
            if proc.is_alive():
                proc.kill()
            proc.join(5.0)
            self.last_exitcode = proc.exitcode
            proc.close()
        if conn is not None:
            conn.close()

    def close(self) -> None:
        """Ask the process to finish (it is killed if it does not within 2 s)."""
        if self._proc is not None:
            try:
                self._conn.send(None)
            except (BrokenPipeError, ConnectionError, OSError):
                pass
            self._proc.join(2.0)
        self._discard()

    def __enter__(self) -> "SupervisedWorker":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()
